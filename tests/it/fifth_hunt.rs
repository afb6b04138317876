//! The fifth hunt for real-world input (docs/robustness.md, "Fifth hunt"):
//! constructs of real five-axis Sinumerik, Fanuc and Okuma programs, of
//! LinuxCNC's interpreter tests and of CATIA and Creo CL data that kinpost
//! converted or followed wrongly with exit 0. Each case failed before its
//! fix.

use crate::cl_support::kinpost;

/// `kinpost args` on `text` written to `dir/name` (the file's path is the
/// last argument): exit code, standard output, standard error.
pub(crate) fn run(
    dir: &std::path::Path,
    name: &str,
    text: &str,
    args: &[&str],
) -> (i32, String, String) {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    let mut all = args.to_vec();
    all.push(path.to_str().unwrap());
    let out = kinpost(&all);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `post` on a Sinumerik or Fanuc pose program: exit code, output, errors.
fn post(dir: &std::path::Path, name: &str, text: &str, extra: &[&str]) -> (i32, String, String) {
    let mut args = vec!["post", "-m", "xyzbc-trt"];
    args.extend_from_slice(extra);
    run(dir, name, text, &args)
}

/// `post` on `text` must refuse it (exit 1) with `want` in its message.
pub(crate) fn post_refuses(
    dir: &std::path::Path,
    name: &str,
    text: &str,
    extra: &[&str],
    want: &str,
) {
    let (code, _, err) = post(dir, name, text, extra);
    assert_eq!(code, 1, "{name}: {err}");
    assert!(err.contains(want), "{name}: {err}");
}

/// `post` on `text` must convert it; its output.
pub(crate) fn post_converts(
    dir: &std::path::Path,
    name: &str,
    text: &str,
    extra: &[&str],
) -> String {
    let (code, out, err) = post(dir, name, text, extra);
    assert_eq!(code, 0, "{name}: {err}");
    out
}

const TRAORI: &str = "G0 X0 Y0 Z100 B0 C0\nTRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";

/// On a Sinumerik, `TRAFOOF` (which kinpost writes for `TRAORI`) leaves
/// the tool offset `D1` on: with the tool in kinpost's chain the controller
/// added its length a second time (`Z55` for a tip at Z5 with a 50 mm
/// tool). Refused now at the `D` word, as Fanuc's `G43` is; `D0` before,
/// or no tool in the chain, converts.
#[test]
fn a_sinumerik_tool_offset_left_on_is_refused_with_a_tool_in_the_chain() {
    let dir = tempfile::tempdir().unwrap();
    let d1 = format!("T1 D1 M6\n{TRAORI}TRAFOOF\nM30\n");
    post_refuses(
        dir.path(),
        "d1.mpf",
        &d1,
        &["--tool-length", "50"],
        "d1.mpf:1:4: a Sinumerik tool offset",
    );
    // A tool change alone selects D1.
    let t = format!("T1 M6\n{TRAORI}TRAFOOF\nM30\n");
    post_refuses(
        dir.path(),
        "t.mpf",
        &t,
        &["--tool-length", "50"],
        "t.mpf:1:1: a Sinumerik tool offset",
    );
    // D0 switches it off; without a tool in the chain the controller's D1
    // is the tool length.
    let d0 = format!("T1 D1 M6\nD0\n{TRAORI}TRAFOOF\nM30\n");
    let out = post_converts(dir.path(), "d0.mpf", &d0, &["--tool-length", "50"]);
    assert!(out.contains("Z55.0000"), "{out}");
    let out = post_converts(dir.path(), "d1.mpf", &d1, &[]);
    assert!(out.contains("G1 X10.0000 Y0.0000 Z5.0000"), "{out}");
}

/// Sinumerik constructs of five-axis posts that pose mode converted as if
/// they were not there.
#[test]
fn sinumerik_frames_orientation_and_corner_words_are_refused_in_pose_mode() {
    let dir = tempfile::tempdir().unwrap();
    for (name, block, want) in [
        // Frames that turn the coordinates to the tool or the part.
        ("toframe.mpf", "TOFRAME", "toframe.mpf:4:1: a frame"),
        ("torot.mpf", "TOROT", "torot.mpf:4:1: a frame"),
        ("parot.mpf", "PAROT", "parot.mpf:4:1: a frame"),
        // A rotation in the plane has no X Y Z: it was read as deleting the
        // frame.
        ("rotrpl.mpf", "ROT RPL=90", "rotrpl.mpf:4:1: a frame"),
        // Words that insert motion at the corner, or the retract direction.
        ("rnd.mpf", "G1 X12 RND=2", "rnd.mpf:4:8: `RND=`"),
        ("chf.mpf", "G1 X12 CHF=1", "chf.mpf:4:8: `CHF=`"),
        ("a8.mpf", "G1 X12 A8=0 B8=0 C8=1", "a8.mpf:4:8: `A8`"),
        (
            "diamon.mpf",
            "DIAMON",
            "diamon.mpf:4:1: DIAMON is Sinumerik diameter",
        ),
        // A keyword kinpost does not read is named as one.
        (
            "orivirt.mpf",
            "ORIVIRT1",
            "orivirt.mpf:4:1: `ORIVIRT1` is a keyword",
        ),
    ] {
        let text = format!("{TRAORI}{block}\nG1 X11 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        post_refuses(dir.path(), name, &text, &[], want);
    }
    // `TRAORI(1,0,1,0)`: the tool along Y, which kinpost does not apply.
    let text = "G0 X0 Y0 Z100 B0 C0\nTRAORI(1,0,1,0)\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    post_refuses(
        dir.path(),
        "traori.mpf",
        text,
        &[],
        "traori.mpf:2:1: TRAORI with arguments after the transformation",
    );
    // Fanuc's corner rounding is named as such.
    let text = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG1 X12 ,R2.\nG49\nM30\n";
    post_refuses(
        dir.path(),
        "r.nc",
        text,
        &[],
        "r.nc:3:8: `,R2.`: a corner rounding",
    );
}

/// Sinumerik's continuous-path modes with corner rounding (`G641`–`G645`,
/// set by high-speed five-axis posts next to `CYCLE832`) were refused in
/// pose mode as codes kinpost does not know; like `G64` they leave the
/// axis words alone. A `TOROT` set and deleted before the poses lets pose
/// mode start.
#[test]
fn sinumerik_path_modes_and_deleted_frames_pass() {
    let dir = tempfile::tempdir().unwrap();
    for (name, before, block) in [
        ("g642.mpf", "", "G642"),
        ("g645.mpf", "", "G645 G601"),
        ("torotof.mpf", "TOROT\nTOROTOF\n", "G64"),
    ] {
        let text = format!("{before}{TRAORI}{block}\nG1 X11 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        let out = post_converts(dir.path(), name, &text, &[]);
        assert!(out.contains(&format!("\n{block}\n")), "{name}: {out}");
        assert!(out.contains("G1 X11.0000 Y0.0000 Z5.0000"), "{name}: {out}");
    }
}

/// `SUPA` (and `G153`) is Sinumerik's `G53`: in pose mode `SUPA G0 Z0 D0`
/// was converted as a pose (X and Y written in machine coordinates); before
/// the poses it was followed as program Z0. Now it passes through and the
/// next pose must give X, Y and Z.
#[test]
fn supa_and_g153_are_machine_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    for block in ["SUPA G0 Z0 D0", "G153 G0 Z0"] {
        let text = format!("{TRAORI}{block}\nG0 X12 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        let out = post_converts(dir.path(), "supa.mpf", &text, &[]);
        assert!(out.contains(&format!("\n{block}\n")), "{block}: {out}");
        // Without Z the next pose's tip is not known.
        let text = format!("{TRAORI}{block}\nG0 X12 Y0 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        post_refuses(
            dir.path(),
            "supa.mpf",
            &text,
            &[],
            "the tool tip Z is not known",
        );
    }
}

/// Modes that change what axis words mean, set before the poses start,
/// stayed on under the converted poses: Fanuc polar coordinate (`G12.1`)
/// and cylindrical interpolation (`G7.1 C57.3`), the controller's own tool
/// centre point control (Okuma `G169`, Heidenhain ISO `M128`). Pose mode
/// may not start under them now; their cancels let it. Where a program in
/// machine axes is followed, `M128` is refused as `G43.4` is.
#[test]
fn pose_mode_does_not_start_under_an_interpolation_mode() {
    let dir = tempfile::tempdir().unwrap();
    let poses = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG49\nM30\n";
    for (on, off) in [
        ("G12.1", "G13.1"),
        ("G7.1 C57.3", "G7.1 C0"),
        ("G169 H1", "G168"),
        ("M128", "M129"),
    ] {
        let text = format!("G0 X0 Y0 Z100 B0 C0\n{on}\n{poses}");
        post_refuses(
            dir.path(),
            "mode.nc",
            &text,
            &[],
            "pose mode starts while an interpolation mode",
        );
        let text = format!("G0 X0 Y0 Z100 B0 C0\n{on}\n{off}\n{poses}");
        post_converts(dir.path(), "mode.nc", &text, &[]);
    }
    refused_where_followed(
        dir.path(),
        &format!("{START}M128\nG1 X10 Y0 Z5 A10\nM129\nM2\n"),
        "m.ngc:3:1: tool centre point control",
    );
}

/// The commands that follow a program in machine axes (`linkage`,
/// `simulate`, `analyze --nonlinear`), on `text` (a machine-axis program
/// for xyzac-trt): with `want`, each must refuse it (exit 1, no output)
/// with `want` in its message; without, each must succeed.
pub(crate) fn follow(dir: &std::path::Path, text: &str, want: Option<&str>) {
    let out = dir.join("out");
    let o = out.to_str().unwrap();
    for args in [
        vec!["linkage", "-m", "xyzac-trt", "-o", o],
        vec!["simulate", "-m", "xyzac-trt", "-o", o, "-p"],
        vec!["analyze", "-m", "xyzac-trt", "--nonlinear"],
    ] {
        let (code, _, err) = run(dir, "m.ngc", text, &args);
        match want {
            Some(want) => {
                assert_eq!(code, 1, "{args:?} on {text}: {err}");
                assert!(err.contains(want), "{args:?} on {text}: {err}");
                assert!(!out.exists(), "{args:?} wrote an output");
            }
            None => assert_eq!(code, 0, "{args:?} on {text}: {err}"),
        }
        let _ = std::fs::remove_file(&out);
    }
}

/// [`follow`] refusing `text` with `want` in the message.
fn refused_where_followed(dir: &std::path::Path, text: &str, want: &str) {
    follow(dir, text, Some(want));
}

/// [`follow`] succeeding on `text`.
fn followed(dir: &std::path::Path, text: &str) {
    follow(dir, text, None);
}

const START: &str = "G21 G90 G94 G17\nG1 X0 Y0 Z0 A0 C0 F1000\n";
const NEXT: &str = "G1 X10 A30 C40\nM2\n";

/// Loops, jumps and conditions were followed once, top to bottom
/// (a `WHILE` body once, a `GOTO`'s skipped blocks run), with exit 0.
#[test]
fn flow_control_is_refused_where_motion_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    for (block, at, name) in [
        (
            "#1=0\nWHILE [#1 LT 3] DO1\nG91 G1 X10\n#1=#1+1\nEND1\nG90",
            "m.ngc:4:1:",
            "WHILE",
        ),
        ("GOTO 20\nG1 Y50\nN20 G1 X5", "m.ngc:3:1:", "GOTO"),
        (
            "o100 repeat [3]\nG91 G1 X10\no100 endrepeat\nG90",
            "m.ngc:3:1:",
            "o100 repeat",
        ),
        ("o200 sub\nG1 Y50\no200 endsub", "m.ngc:3:1:", "o200 sub"),
        ("LOOP\nG91 G1 X10\nENDLOOP\nG90", "m.ngc:3:1:", "LOOP"),
        ("IF R1==1 GOTOF END\nG1 Y50", "m.ngc:3:1:", "IF"),
    ] {
        let text = format!("{START}{block}\n{NEXT}");
        refused_where_followed(dir.path(), &text, at);
        refused_where_followed(dir.path(), &text, &format!("flow control (`{name}`"));
    }
}

/// A move whose value kinpost cannot read, when the text does not start at
/// the axis letter, was skipped or half followed (`G1 Y #1` left out, `Y 50
/// 0` followed as Y50); Fanuc's `,R` corner, polar words and Sinumerik's
/// rounding words were followed as sharp straight moves. Found on
/// LinuxCNC's own interpreter tests (`g1 y sqrt[2]`).
#[test]
fn motion_kinpost_cannot_read_is_refused_where_it_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    for (block, at) in [
        ("#1 = 50\nG1 Y #1", "m.ngc:4:4: this move holds syntax"),
        ("g1 y sqrt[2]", "m.ngc:3:4: this move holds syntax"),
        ("G1 Y 50 0", "m.ngc:3:9: this move holds syntax"),
        ("G1 Y5O", "m.ngc:3:6: this move holds syntax"),
        ("G1 Y50 Z sin[0]", "m.ngc:3:8: this move holds syntax"),
        ("G1 X50 Y0 ,R5", "m.ngc:3:11: `,R5`: a corner rounding"),
        ("G1 @50 ^90", "m.ngc:3:4: polar coordinates (`@50"),
        (
            "G111 X0 Y0\nG1 AP=90 RP=50",
            "m.ngc:4:4: `AP=` is a polar coordinate",
        ),
        (
            "G1 X10 RND=2",
            "m.ngc:3:8: `RND=` makes the controller insert",
        ),
    ] {
        refused_where_followed(dir.path(), &format!("{START}{block}\n{NEXT}"), at);
    }
    // Plain words, and a parameter set but not used, are followed.
    followed(dir.path(), &format!("{START}#1 = 50\nG1 Y50\n{NEXT}"));
}

/// Moves under a rotation, scaling, mirroring or polar mode were followed
/// as if no frame were on (`G68 R90` then `G1 X50 Y10`: recorded at X50 Y10,
/// where the controller goes to X−10 Y50). Refused now until cancelled;
/// a translation (`TRANS`), which a work offset is, still passes.
#[test]
fn moves_under_a_frame_are_refused_where_they_are_followed() {
    let dir = tempfile::tempdir().unwrap();
    for (frame, what) in [
        ("G68 X0 Y0 R90.", "a move under a frame (G68"),
        ("G51 X0 Y0 P2000", "a move under a frame"),
        ("G51.1 X0", "a move under a frame"),
        ("G16", "a move under a frame"),
        ("ROT RPL=90", "a move under the Sinumerik frame ROT"),
        ("AROT Z30", "a move under the Sinumerik frame AROT"),
        ("SCALE X2", "a move under the Sinumerik frame SCALE"),
        ("G10 L2 P1 R90", "a move under a rotated coordinate system"),
    ] {
        let text = format!("{START}{frame}\nG1 X50 Y10\n{NEXT}");
        refused_where_followed(dir.path(), &text, "m.ngc:4:4:");
        refused_where_followed(dir.path(), &text, what);
    }
    for (frame, cancel) in [
        ("G68 X0 Y0 R90.", "G69"),
        ("G51 X0 Y0 P2000", "G50"),
        ("ROT RPL=90", "ROT"),
        ("G10 L2 P1 R90", "G10 L2 P1 R0"),
        ("TRANS X10", ""),
    ] {
        followed(
            dir.path(),
            &format!("{START}{frame}\n{cancel}\nG1 X50 Y10\n{NEXT}"),
        );
    }
}

/// Cycle and subprogram calls by name were skipped (`CYCLE81(…)` drills,
/// `L100` calls subprogram L100); the settings cycle `CYCLE832` and
/// messages move nothing and pass. A Fanuc lathe's `G50 X Z` sets the
/// coordinate system, as `G92`: it was followed as a rapid move.
#[test]
fn calls_and_lathe_coordinate_settings_where_motion_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    for (block, at) in [
        (
            "CYCLE81(10,0,2,-5)",
            "m.ngc:3:1: a subprogram or macro call (CYCLE81(…))",
        ),
        ("N10 L100", "m.ngc:3:5: a subprogram or macro call (L100)"),
    ] {
        refused_where_followed(dir.path(), &format!("{START}{block}\n{NEXT}"), at);
    }
    followed(
        dir.path(),
        &format!("{START}CYCLE832(0.01,_ORI_FINISH,1)\nMSG(\"hi\")\n{NEXT}"),
    );
    // `G50 X200 Z150`: the machine stays; the next move starts there in
    // the new coordinates (as after G92: from X200 to X10).
    let text = "G21 G18 G90\nG0 X0 Y0 Z0\nG50 X200. Z150.\nG1 X10. F1000.\nM30\n";
    let csv = dir.path().join("r.csv");
    let (code, _, err) = run(
        dir.path(),
        "lathe.ngc",
        text,
        &[
            "simulate",
            "-m",
            "xyz-3axis",
            "--noise",
            "0",
            "-o",
            csv.to_str().unwrap(),
            "-p",
        ],
    );
    assert_eq!(code, 0, "{err}");
    // Before, the G50 block was a rapid move that drove X to 200.
    let recording = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = recording.lines().next().unwrap().split(',').collect();
    let x = header.iter().position(|h| *h == "X").unwrap();
    let max_x = recording
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(x)?.parse::<f64>().ok())
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(max_x < 100.0, "X went to {max_x} mm: {err}");
}

/// CL data: `LOADTL/4,OFFSET,9` (NCL) and `LOADTL/5,OSETNO,7` (Creo) name
/// the length-offset register; `G43 H4`/`H5` was written. CATIA's
/// `LOOP/START,n … LOOP/END` and `INVERSE/ON` were kept as comments (the
/// loop body cut once, inverse-time feeds written as mm/min).
#[test]
fn cl_length_registers_loops_and_inverse_time_words() {
    let dir = tempfile::tempdir().unwrap();
    let cl = "UNITS/MM\nLOADTL/4,OFFSET,9\nFEDRAT/100,MMPM\nGOTO/10,0,5\nLOADTL / 5,  OSETNO,  7\nGOTO/20,0,5\nLOADTL/6,ADJUST,8\nGOTO/30,0,5\nFINI\n";
    let (code, out, err) = run(dir.path(), "t.apt", cl, &["post", "-m", "xyz-3axis"]);
    assert_eq!(code, 0, "{err}");
    let h: Vec<&str> = out.lines().filter(|l| l.starts_with("G43")).collect();
    assert_eq!(h, ["G43 H9", "G43 H7", "G43 H8"], "{out}");
    for (body, at, said) in [
        (
            "LOOP/START,15\nGOTO/10,0,0\nLOOP/END\n",
            "t.apt:4:1:",
            "LOOP changes which statements run",
        ),
        (
            "INVERSE/ON\nGOTO/10,0,0\nINVERSE/OFF\n",
            "t.apt:4:1:",
            "INVERSE/ON: inverse-time feeds",
        ),
    ] {
        let cl = format!("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,10\n{body}FINI\n");
        let (code, _, err) = run(dir.path(), "t.apt", &cl, &["post", "-m", "xyz-3axis"]);
        assert_eq!(code, 1, "{body}: {err}");
        assert!(err.contains(at) && err.contains(said), "{body}: {err}");
    }
}

/// NX writes `TRANS X0 Y0 Z0` inside `TRAORI` (the programmable frame
/// replaced by the identity). It was refused as a frame, although it moves
/// nothing. Now `TRANS`/`ROT` of all 0 and `SCALE` of all 1 delete the
/// programmable frame, and `ATRANS`/`AROT` of all 0 and `ASCALE` of all 1
/// keep it as it is: in pose mode they pass, their X Y Z no pose. A frame
/// that moves anything is still refused at its keyword, a mirror too
/// (`MIRROR X0` mirrors X).
#[test]
fn identity_frames_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let plain = format!("{TRAORI}G1 X20 Y5 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
    let want = post_converts(dir.path(), "plain.mpf", &plain, &[]);
    for frame in [
        "TRANS X0 Y0 Z0",
        "ATRANS X0",
        "ROT RPL=0",
        "AROT Z0",
        "SCALE X1 Y1 Z1",
        "ASCALE Z1",
    ] {
        let text = format!("{TRAORI}{frame}\nG1 X20 Y5 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        let out = post_converts(dir.path(), "id.mpf", &text, &[]);
        // The frame's line as written, the rest as without it.
        assert!(out.contains(&format!("\n{frame}\n")), "{frame}: {out}");
        assert_eq!(out.replace(&format!("{frame}\n"), ""), want, "{frame}");
    }
    for (frame, col) in [
        ("TRANS X0 Y0 Z0.001", 1),
        ("ATRANS X0 Y1", 1),
        ("SCALE X1 Y0", 1),
        ("MIRROR X0", 1),
        ("N5 AROT RPL=0.5", 4),
    ] {
        let text = format!("{TRAORI}{frame}\nG1 X20 Y5 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n");
        post_refuses(
            dir.path(),
            "id.mpf",
            &text,
            &[],
            &format!("id.mpf:4:{col}: a frame"),
        );
    }
    // Where motion in machine axes is followed: `TRANS X0 Y0 Z0` replaces
    // a rotation, `AROT Z0` leaves it on.
    followed(
        dir.path(),
        &format!("{START}AROT Z30\nTRANS X0 Y0 Z0\nG1 X50 Y10\n{NEXT}"),
    );
    refused_where_followed(
        dir.path(),
        &format!("{START}AROT Z30\nAROT Z0\nG1 X50 Y10\n{NEXT}"),
        "m.ngc:5:4: a move under the Sinumerik frame AROT",
    );
}
