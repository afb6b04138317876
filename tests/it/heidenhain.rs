//! Heidenhain conversational (Klartext) programs: kinpost converts none of
//! their blocks, so one that gives tool poses (TCPM on by `M128` or
//! `FUNCTION TCPM`, an `LN` block with a tool vector TX TY TZ) is refused at
//! its column by every command that converts poses, and any Klartext move
//! by the readers of programs in machine axes; one without poses passes a
//! filter byte for byte. (Before: every such line was opaque text, passed
//! through with exit 0 and "0 poses converted".)

use std::process::Command;

/// A five-axis Klartext program in the shape TNC controls read; the block
/// `tcp` switches TCPM on, block 6 is a pose with a tool vector.
fn program(tcp: &str) -> String {
    format!(
        "0 BEGIN PGM IMPELLER MM\n\
         1 BLK FORM 0.1 Z X-50 Y-50 Z-40\n\
         2 BLK FORM 0.2 X+50 Y+50 Z+0\n\
         3 TOOL CALL 5 Z S12000\n\
         4 L Z+100 R0 FMAX M3\n\
         5 {tcp}\n\
         6 LN X+12.5 Y+3.25 Z-1 TX+0 TY+0.5 TZ+0.866025 F1000\n\
         7 L X+20 B+30 C+45 F500\n\
         8 END PGM IMPELLER MM\n"
    )
}

fn run(args: &[&str], file: &std::path::Path) -> (i32, Vec<u8>, String) {
    let out = Command::new(crate::util::BIN)
        .args(args)
        .arg(file)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        out.stdout,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn klartext_poses_are_refused_by_the_converting_commands() {
    let dir = tempfile::tempdir().unwrap();
    let errors = crate::util::repo_file("fixtures/errors/zhao2022-xzbc.csv");
    for (tcp, col, what) in [
        ("M128", 3, "with `M128`"),
        ("L Z+100 R0 FMAX M128", 19, "with `M128`"),
        (
            "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS",
            3,
            "with `FUNCTION TCPM`",
        ),
        ("FUNCTION RESET TCPM", 0, "with a tool vector (`TX+0`)"),
    ] {
        let path = dir.path().join("p.h");
        std::fs::write(&path, program(tcp)).unwrap();
        // TCPM off: the LN block with its tool vector is refused instead.
        let at = if col == 0 {
            "p.h:7:24".to_string()
        } else {
            format!("p.h:6:{col}")
        };
        for args in [
            &["post", "--machine", "xyzbc-trt"][..],
            &["compensate", "--errors", &errors][..],
        ] {
            let (code, stdout, stderr) = run(args, &path);
            assert_eq!(code, 1, "{args:?} {tcp}: {stderr}");
            assert!(stdout.is_empty(), "{args:?} {tcp}");
            assert!(
                stderr.contains(&format!("{at}: a Heidenhain conversational block {what}")),
                "{args:?} {tcp}: {stderr}"
            );
            assert!(
                stderr.contains("kinpost does not convert Heidenhain"),
                "{stderr}"
            );
        }
    }
}

#[test]
fn klartext_without_poses_passes_a_filter_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("three-axis.h");
    let text = "0 BEGIN PGM POCKET MM\n\
                1 TOOL CALL 2 Z S8000\n\
                2 L X+10 Y+5 Z+20 R0 FMAX M3\n\
                3 L Z-2 F200\n\
                4 CC X+10 Y+10\n\
                5 C X+10 Y+5 DR+\n\
                6 L Z+100 R0 FMAX M129\n\
                7 FUNCTION RESET TCPM\n\
                8 END PGM POCKET MM\n";
    std::fs::write(&path, text).unwrap();
    let (code, stdout, stderr) = run(&["post", "--machine", "xyzbc-trt"], &path);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(String::from_utf8(stdout).unwrap(), text);
    // The readers of programs in machine axes refuse its first move.
    for args in [
        &["linkage", "--machine", "xyzbc-trt"][..],
        &["analyze", "--nonlinear", "--machine", "xyzbc-trt"][..],
    ] {
        let (code, _, stderr) = run(args, &path);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(
            stderr.contains("three-axis.h:3:3: a Heidenhain conversational move (`L`)"),
            "{args:?}: {stderr}"
        );
    }
}
