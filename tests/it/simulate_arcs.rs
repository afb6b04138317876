//! Circular moves in machine axes through `simulate` and `analyze`
//! (docs/robustness.md, "Circular moves in simulate"). `simulate` used to
//! skip every `G2`/`G3` block and run the block after it straight from
//! where the arc began: the recording of a LinuxCNC program cut its arcs
//! as chords (exit 0). The references here are the circles the blocks
//! describe, worked out in the test from their words.

use crate::cl_support::kinpost;

/// Runs `kinpost simulate --noise 0 --sample-interval 0.01 extra…` on
/// `program` (text) for `machine`, which must succeed; returns the
/// recording (CSV text) and standard error.
pub fn simulate_with(machine: &str, program: &str, extra: &[&str]) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("p.ngc");
    std::fs::write(&prog, program).unwrap();
    let rec = dir.path().join("rec.csv");
    let mut args = vec![
        "simulate",
        "-m",
        machine,
        "--noise",
        "0",
        "--sample-interval",
        "0.01",
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&[
        "--program",
        prog.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    let out = kinpost(&args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    (std::fs::read_to_string(&rec).unwrap(), stderr)
}

/// [`simulate_with`] with no extra options: the recording's rows as
/// (block, commanded X, Y, Z), and standard error.
fn simulate(machine: &str, program: &str) -> (Vec<(u64, [f64; 3])>, String) {
    let (text, stderr) = simulate_with(machine, program, &[]);
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (b, x, y, z) = (col("block"), col("X"), col("Y"), col("Z"));
    let rows = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let f = |i: usize| v[i].parse::<f64>().unwrap();
            (v[b].parse().unwrap(), [f(x), f(y), f(z)])
        })
        .collect();
    (rows, stderr)
}

/// A LinuxCNC-style program in machine axes: a line, a clockwise
/// three-quarter arc about (10, 10) of radius 10 from (10, 0) to (20, 10),
/// a counter-clockwise full circle given by its centre alone (`G3 I-10`)
/// and a line. Every sample of the arc blocks lies on its circle, the
/// clockwise arc passes (0, 10) and (10, 20) (not the chord), and the
/// full circle goes round (it reaches X = 0).
#[test]
fn simulate_follows_arcs_in_machine_axes() {
    let program =
        "G21 G90 G17\nG0 X0 Y0 Z5\nG1 X10 Y0 F600\nG2 X20 Y10 I0 J10\nG3 I-10\nG1 X30 Y10\nM2\n";
    let (rows, _) = simulate("xyz-3axis", program);
    let on = |block: u64| rows.iter().filter(move |r| r.0 == block).map(|r| r.1);
    let arc: Vec<[f64; 3]> = on(4).collect();
    assert!(arc.len() > 100, "{} samples on the arc", arc.len());
    for p in &arc {
        let r = (p[0] - 10.0).hypot(p[1] - 10.0);
        // The pieces stand within 0.1 µm of the arc.
        assert!((r - 10.0).abs() < 2e-4, "{p:?} is {r} mm from the centre");
    }
    assert!(arc.iter().any(|p| p[0] < 0.5), "the arc passes X0 Y10");
    assert!(arc.iter().any(|p| p[1] > 19.5), "the arc passes X10 Y20");
    let circle: Vec<[f64; 3]> = on(5).collect();
    assert!(circle.len() > 100, "{} samples on the circle", circle.len());
    for p in &circle {
        let r = (p[0] - 10.0).hypot(p[1] - 10.0);
        assert!((r - 10.0).abs() < 2e-4, "{p:?} is {r} mm from the centre");
    }
    assert!(
        circle.iter().any(|p| p[0] < 0.5),
        "the full circle goes round"
    );
    // The line after the arcs runs from their end, (20, 10): Y stays 10.
    for p in on(6) {
        assert!((p[1] - 10.0).abs() < 1e-9 && p[0] >= 20.0 - 1e-9, "{p:?}");
    }
}

/// A pose program that leaves pose mode for an arc in machine axes
/// (`G49`, `G2 X30 Y10 I10 J0` about (30, 0)) and comes back: the
/// recording follows the quarter arc from (20, 0) to (30, 10), and the
/// next pose's block starts at its end.
#[test]
fn simulate_follows_an_arc_between_poses() {
    let program = "G21 G90 G94\nG43.4 H1\nG1 X10 Y0 Z20 I0 J0 K1 F600\nG1 X20 Y0 Z20 I0 J0 K1\nG49\nG2 X30 Y10 I10 J0 F600\nG43.4 H1\nG1 X40 Y10 Z20 I0 J0 K1\nM2\n";
    let (rows, _) = simulate("xyzac-trt", program);
    let arc: Vec<[f64; 3]> = rows.iter().filter(|r| r.0 == 6).map(|r| r.1).collect();
    assert!(arc.len() > 20, "{} samples on the arc", arc.len());
    for p in &arc {
        let r = (p[0] - 30.0).hypot(p[1]);
        assert!((r - 10.0).abs() < 2e-4, "{p:?} is {r} mm from the centre");
        assert!(p[0] >= 20.0 - 1e-9 && p[0] <= 30.0 + 1e-9, "{p:?}");
    }
    for p in rows.iter().filter(|r| r.0 == 8).map(|r| r.1) {
        assert!((p[1] - 10.0).abs() < 1e-9 && p[0] >= 30.0 - 1e-9, "{p:?}");
    }
}

/// After a move whose path is not known (`G28` in the middle), the
/// recording does not make one up: no sample lies between where the block
/// before ended and where the block after begins, and standard error says
/// which line. Before, it went straight across.
#[test]
fn simulate_leaves_out_a_move_it_does_not_know() {
    let program = "G21 G90\nG1 X0 Y0 Z0 F600\nG1 X10\nG91 G28 Z0\nG90 G1 X20 Y0 Z-5\nG1 X30\nM2\n";
    let (rows, stderr) = simulate("xyz-3axis", program);
    assert!(
        stderr.contains("line 5") && stderr.contains("G28"),
        "{stderr}"
    );
    // The block after the G28 (line 5) runs from where it starts, X20
    // Z-5, to its end: nothing between X10 and X20.
    assert!(
        rows.iter()
            .all(|r| !(r.1[0] > 10.0 + 1e-9 && r.1[0] < 20.0 - 1e-9)),
        "a sample between the blocks around the G28"
    );
}

/// An arc whose centre does not fit its end, or a form not followed, is
/// refused at its line and word (exit 1), not replaced by another path.
#[test]
fn arcs_simulate_cannot_follow_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (body, col, says) in [
        ("G2 X20 Y10 I0 J9", 12, "radius"),
        ("G2 X20 Y10 R2", 12, "shorter"),
        ("G2 X20 Y10 CR=-10 AR=270", 19, "AR"),
    ] {
        let prog = dir.path().join("bad.ngc");
        std::fs::write(
            &prog,
            format!("G21 G90 G17\nG1 X10 Y0 F600\n{body}\nG1 X30\n"),
        )
        .unwrap();
        let out = kinpost(&[
            "simulate",
            "-m",
            "xyz-3axis",
            "--program",
            prog.to_str().unwrap(),
            "-o",
            dir.path().join("r.csv").to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{body}: {stderr}");
        assert!(
            stderr.contains(&format!("bad.ngc:3:{col}")),
            "{body}: {stderr}"
        );
        assert!(stderr.contains(says), "{body}: {stderr}");
        assert!(
            !dir.path().join("r.csv").exists(),
            "{body}: a recording was written"
        );
    }
}

/// `analyze --nonlinear` on a program in machine axes: an arc is not a
/// straight move of the joints and is not measured, and the block after it
/// is measured from the arc's end. Before, the arc was skipped and the
/// next block measured from where the arc began (here: from X10 Y0 A0, a
/// segment the program never runs).
#[test]
fn analyze_measures_the_block_after_an_arc_from_its_end() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("p.ngc");
    // After the arc the tool is at X0 Y10; the last block turns A by 30°
    // standing still in X Y: its tip moves on a circle about the A axis,
    // so a measurement from X10 Y0 would differ from one from X0 Y10.
    std::fs::write(
        &prog,
        "G21 G90 G17\nG1 X10 Y0 Z0 A0 C0 F600\nG3 X0 Y10 I-10 J0\nG1 X0 Y10 Z0 A30 C0\nM2\n",
    )
    .unwrap();
    let json = |p: &std::path::Path| -> serde_json::Value {
        let out = kinpost(&[
            "analyze",
            "-m",
            "xyzac-trt",
            "--nonlinear",
            "--json",
            p.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let got = json(&prog);
    let blocks = got["nonlinear"]["blocks"].as_array().unwrap();
    let lines: Vec<u64> = blocks.iter().map(|b| b["line"].as_u64().unwrap()).collect();
    assert!(!lines.contains(&3), "the arc is measured: {lines:?}");
    let after = blocks
        .iter()
        .find(|b| b["line"] == 4)
        .expect("the block after the arc");
    // The same block after a straight move to the arc's end is the reference.
    let straight = dir.path().join("s.ngc");
    std::fs::write(
        &straight,
        "G21 G90 G17\nG1 X10 Y0 Z0 A0 C0 F600\nG1 X0 Y10\nG1 X0 Y10 Z0 A30 C0\nM2\n",
    )
    .unwrap();
    let reference = json(&straight);
    let want = reference["nonlinear"]["blocks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|b| b["line"] == 4)
        .unwrap()
        .clone();
    assert_eq!(after, &want);
}

/// An arc in a plane whose axes the machine lacks (`G17` on the X Z B C
/// lens machine) is refused with file:line:col, the column of the block.
/// Before, the message named no column. (With a `Y` word the block is
/// refused at that word first: the machine has no Y axis.)
#[test]
fn an_arc_in_a_plane_the_machine_lacks_is_refused_at_its_block() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("xy.ngc");
    std::fs::write(&prog, "G21 G90 G17\nG1 X10 Z0 F600\nG2 X20 I5 J0\n").unwrap();
    let out = kinpost(&[
        "simulate",
        "-m",
        "zhao2022-xzbc",
        "--program",
        prog.to_str().unwrap(),
        "-o",
        dir.path().join("r.csv").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("xy.ngc:3:1: the arc in G17 moves X and Y"),
        "{stderr}"
    );
}
