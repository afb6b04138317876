//! Poses oriented by rotary axis positions: Fanuc `G43.4` (tool centre
//! point control type 1), Haas `G234` and Sinumerik `TRAORI` with `X Y Z`
//! and `A B C` words, the most common five-axis TCP form. Before session
//! 34 every such block was refused at its first rotary word.

use crate::util::{BIN, letter_words as words, repo_file, run_on};
use kinpost::machine::{Machine, NoErrors};

/// Runs `kinpost args… program`: (exit code, stdout, stderr).
fn kinpost(args: &[&str], program: &std::path::Path) -> (i32, String, String) {
    let out = std::process::Command::new(BIN)
        .args(args)
        .arg(program)
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The fixture program of `machine` (poses with I J K under `G43.5`)
/// rewritten with the rotary positions of `converted` (its `post` output)
/// instead of I J K, under `tcp_on` (`G43.4 H1`, `G234 H1`, `TRAORI`).
fn as_rotary_positions(program: &str, converted: &str, machine: &Machine, tcp_on: &str) -> String {
    let rotaries: Vec<char> = machine
        .axes
        .iter()
        .filter(|a| a.kind == kinpost::machine::JointKind::Revolute)
        .map(|a| a.name.chars().next().unwrap())
        .collect();
    let mut out = String::new();
    for (a, b) in program.lines().zip(converted.lines()) {
        if a.starts_with("G43.5") {
            out.push_str(tcp_on);
        } else if a.contains(" I") && a.starts_with("G1 ") {
            out.push_str("G1");
            for (letter, v) in words(a) {
                if "XYZ".contains(letter) {
                    out.push_str(&format!(" {letter}{v}"));
                }
            }
            for (letter, v) in words(b) {
                if rotaries.contains(&letter) {
                    out.push_str(&format!(" {letter}{v}"));
                }
            }
            if let Some(f) = a.split_whitespace().find(|w| w.starts_with('F')) {
                out.push_str(&format!(" {f}"));
            }
        } else {
            out.push_str(a);
        }
        out.push('\n');
    }
    out
}

/// The largest difference between the numbers of the words of two
/// outputs, line by line (the lines must hold the same words).
fn largest_difference(a: &str, b: &str) -> f64 {
    assert_eq!(a.lines().count(), b.lines().count());
    let mut largest = 0.0f64;
    for (x, y) in a.lines().zip(b.lines()) {
        let (wx, wy) = (words(x), words(y));
        assert_eq!(wx.len(), wy.len(), "{x}\n{y}");
        for ((lx, vx), (ly, vy)) in wx.iter().zip(&wy) {
            assert_eq!(lx, ly, "{x}\n{y}");
            largest = largest.max((vx - vy).abs());
        }
    }
    largest
}

/// The same poses given by rotary positions (the ones `post` wrote for
/// them, to 9 decimals) instead of tool vectors convert to the same axis
/// values on every five- and four-axis fixture machine, through every
/// turn and the singular pose; `compensate` too on the two seed machines.
/// The rotary words come out as programmed.
#[test]
fn rotary_positions_convert_as_the_same_poses_given_as_tool_vectors() {
    let dir = tempfile::tempdir().unwrap();
    let machines = [
        ("xyzac-trt", None),
        ("xyzbc-trt", None),
        ("xyzac-head", None),
        ("xyzbc-nutating", None),
        ("xyza-4axis", None),
        ("wang2023-xyzab", Some("fixtures/errors/wang2023-xyzab.csv")),
        ("zhao2022-xzbc", Some("fixtures/errors/zhao2022-xzbc.csv")),
    ];
    for (name, table) in machines {
        let machine = Machine::load(std::path::Path::new(&repo_file(&format!(
            "fixtures/machines/{name}.json"
        ))))
        .unwrap();
        let machine_file = repo_file(&format!("fixtures/machines/{name}.json"));
        let vectors = repo_file(&format!("fixtures/programs/{name}.ngc"));
        let post = ["post", "--machine", &machine_file, "--decimals", "9"];
        let (code, converted, err) = kinpost(&post, std::path::Path::new(&vectors));
        assert_eq!(code, 0, "{name}: {err}");
        let program = std::fs::read_to_string(&vectors).unwrap();
        for tcp_on in ["G43.4 H1", "G234 H1", "TRAORI"] {
            let text = as_rotary_positions(&program, &converted, &machine, tcp_on);
            assert!(
                !text
                    .lines()
                    .any(|l| l.starts_with("G1") && l.contains(" I"))
            );
            let path = dir.path().join(format!("{name}.ngc"));
            std::fs::write(&path, &text).unwrap();
            let (code, again, err) = kinpost(&post, &path);
            assert_eq!(code, 0, "{name} {tcp_on}: {err}");
            let d = largest_difference(&converted, &again.replace("TRAFOOF", "G49"));
            // The rotary words carry 9 decimals of a degree: 1e-11 rad, 2 nm
            // at a 200 mm lever; a wrong branch or turn would be millimetres.
            assert!(d <= 1e-8, "{name} {tcp_on}: {d}");
            // The rotary words as programmed.
            for (p, o) in text.lines().zip(again.lines()) {
                for (letter, v) in words(p).into_iter().filter(|(l, _)| "ABC".contains(*l)) {
                    let got = words(o).into_iter().find(|(l, _)| *l == letter);
                    assert_eq!(got, Some((letter, v)), "{name}: {p}\n{o}");
                }
            }
            if let Some(table) = table
                && tcp_on == "G43.4 H1"
            {
                let table = repo_file(table);
                let comp = [
                    "compensate",
                    "--machine",
                    &machine_file,
                    "--errors",
                    &table,
                    "--decimals",
                    "9",
                ];
                let (c1, by_vector, e1) = kinpost(&comp, std::path::Path::new(&vectors));
                let (c2, by_rotaries, e2) = kinpost(&comp, &path);
                assert_eq!((c1, c2), (0, 0), "{name}: {e1}{e2}");
                let d = largest_difference(&by_vector, &by_rotaries);
                assert!(d <= 1e-8, "{name} compensate: {d}");
            }
        }
    }
}

/// A block that gives only some rotary axes keeps the others, one that
/// gives none keeps them all, the tip stays where the program left it,
/// `G91` turns by increments, and a continuous axis takes thousands of
/// degrees as written. Checked by the forward chain of the written axes.
#[test]
fn rotary_positions_are_modal_and_hold_the_tip() {
    let program = "G21 G90 G94\nG0 X0 Y0 Z100 A0 C0\nG43.4 H1\nG0 X10 Y10 Z50\n\
                   G1 Z5 C30 F100\nG1 A20\nG1 X20\nG91 G1 C10\nG90 G1 C3600\n\
                   G1 X-15 Y4 Z2 A-25.5 C-3610.25\nG49\nM30\n";
    // (tip X Y Z mm, A C degrees) of each pose, in order.
    let want = [
        ([10.0, 10.0, 50.0], [0.0, 0.0]),
        ([10.0, 10.0, 5.0], [0.0, 30.0]),
        ([10.0, 10.0, 5.0], [20.0, 30.0]),
        ([20.0, 10.0, 5.0], [20.0, 30.0]),
        ([20.0, 10.0, 5.0], [20.0, 40.0]),
        ([20.0, 10.0, 5.0], [20.0, 3600.0]),
        ([-15.0, 4.0, 2.0], [-25.5, -3610.25]),
    ];
    let args = ["post", "--machine", "xyzac-trt", "--decimals", "9"];
    let (code, out, err) = run_on(&args, "modal.ngc", program);
    assert_eq!(code, 0, "{err}");
    let machine = Machine::embedded("xyzac-trt").unwrap();
    let mut poses = out.lines().skip(3).take(want.len());
    let mut position = [0.0; 5];
    for (tip, rotaries) in want {
        let line = poses.next().unwrap();
        // X Y Z A C, absolute or (G91) incremental.
        let incremental = line.starts_with("G91");
        for (letter, v) in words(line) {
            if let Some(k) = "XYZAC".find(letter) {
                position[k] = if incremental { position[k] + v } else { v };
            }
        }
        assert!((position[3] - rotaries[0]).abs() < 1e-9, "{line}");
        assert!((position[4] - rotaries[1]).abs() < 1e-9, "{line}");
        let q = machine.to_internal(&position);
        let pose = machine.chain.pose(&q, &NoErrors);
        for (got, want) in pose.tip.iter().zip(tip) {
            assert!((got - want).abs() < 1e-6, "{line}: {:?}", pose.tip);
        }
    }
    // Inch lengths, degrees still.
    let inch = "G20 G90\nG43.4 H1\nG0 X1 Y0.5 Z2 A20 C30\nG49\nM30\n";
    let (code, out, err) = run_on(&["post", "--machine", "xyzac-trt"], "inch.ngc", inch);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains(" A20.0000 C30.0000"), "{out}");
}

/// What cannot be converted is refused at the word, by every command that
/// reads poses: a rotary position not known, beyond the axis's travel, of
/// an axis the machine lacks, given beside a tool vector, in a
/// block-delete block, under G43.5; and programmed positions the pose
/// needs another branch for (the machine's travel) are not changed into it.
#[test]
fn rotary_positions_that_cannot_be_converted_are_refused_at_the_word() {
    let start = "G21 G90\nG0 X0 Y0 Z100 A0 C0\n";
    for (name, program, at, says) in [
        (
            "unknown.ngc",
            "G21 G90\nG43.4 H1\nG0 X10 Y10 Z50 C30\nM30\n",
            "unknown.ngc:3:16:",
            "position of the A axis is not known",
        ),
        (
            "increment.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 I0 J0 K1\nG91 G1 C10\nM30\n"),
            "increment.ngc:5:8:",
            "incremental C move (G91) but the position of the C axis is not known",
        ),
        (
            "travel.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 A120 C30\nM30\n"),
            "travel.ngc:4:16:",
            "beyond its travel",
        ),
        (
            "axis.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 B20 C30\nM30\n"),
            "axis.ngc:4:16:",
            "has no rotary axis B",
        ),
        (
            "both.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 I0 J0 K1 C30\nM30\n"),
            "both.ngc:4:25:",
            "ambiguous",
        ),
        (
            "slash.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 C30\n/G1 C40\nM30\n"),
            "slash.ngc:5:1:",
            "block-delete",
        ),
        (
            "type2.ngc",
            &format!("{start}G43.5 H1\nG0 X10 Y10 Z50 A20 C30\nM30\n"),
            "type2.ngc:4:16:",
            "G43.5",
        ),
        (
            "toolchange.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 A20 C30\nT2 M6\nG1 X5 Y5 Z5 C40\nM30\n"),
            "toolchange.ngc:6:13:",
            "position of the A axis is not known",
        ),
        (
            "vector.ngc",
            &format!("{start}G43.4 H1\nG0 X10 Y10 Z50 I0 J0 K1\nG1 C40\nM30\n"),
            "vector.ngc:5:4:",
            "position of the A axis is not known",
        ),
    ] {
        for command in [
            vec!["post", "--machine", "xyzac-trt"],
            vec!["simulate", "--machine", "xyzac-trt", "--program"],
        ] {
            let (code, _, err) = run_on(&command, name, program);
            assert_eq!(code, 1, "{name} {command:?}: {err}");
            assert!(err.contains(at) && err.contains(says), "{name}: {err}");
        }
    }
    // A table whose Y travel ends at 300 mm: A-20 C0 would put Y at
    // 302.4; the other branch (A20 C180) stays within, but it is not what
    // the program asks for.
    let dir = tempfile::tempdir().unwrap();
    let file = std::fs::read_to_string(repo_file("fixtures/machines/xyzac-trt.json"))
        .unwrap()
        .replace(
            r#""Y": {"min": -400, "max": 400}"#,
            r#""Y": {"min": -400, "max": 300}"#,
        );
    assert!(file.contains(r#""max": 300}"#));
    let machine = dir.path().join("short-y.json");
    std::fs::write(&machine, file).unwrap();
    let machine = machine.to_str().unwrap();
    let program = "G43.4 H1\nG0 X0 Y300 Z0 A-20 C0\nM30\n";
    let (code, out, err) = run_on(&["post", "--machine", machine], "branch.ngc", program);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        err.contains("branch.ngc:2:4:") && err.contains("A20.0000 C-180.0000"),
        "{err}"
    );
}
