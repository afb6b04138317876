//! The FreeCAD post wrapper (`docs/integration/kinpost_post.py`) on a job
//! shaped like FreeCAD's output: the objects FreeCAD 1.x hands to
//! `export(objects, "-", args)` — a fixture (`G54`, then a clearance move
//! that gives only Z), a tool controller (`M6 T1`, `M3 S12000`) and an
//! operation whose first moves give only some of X, Y and Z. Stub classes
//! shaped like FreeCAD's `Path.Command` (`Name`, `Parameters` dict) stand in
//! for FreeCAD's modules. Nothing may be dropped: on the three-axis machine
//! the axis words are the tool tip, so every move of the job is checked
//! against the tip the job asks for, written out by hand below.

use std::path::Path;
use std::process::{Command, Stdio};

use crate::util::BIN;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn python() -> Option<&'static str> {
    ["python3", "python"].into_iter().find(|p| {
        Command::new(p)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

/// Runs `body` after the stubs and the job in Python; its standard output.
fn run_python(body: &str) -> Option<String> {
    let Some(py) = python() else {
        eprintln!("skipped: no python3 on this machine, the FreeCAD wrapper is not checked");
        return None;
    };
    let script = format!(
        r#"
import sys
sys.path.insert(0, {docs:?})
import kinpost_post as k

class Command:  # shaped like FreeCAD's Path.Command
    def __init__(self, name, parameters=None):
        self.Name = name
        self.Parameters = dict(parameters or {{}})

class PathObj:  # shaped like Path.Path
    def __init__(self, commands): self.Commands = commands

class Obj:  # a document object with a Path (fixture, tool controller, operation)
    def __init__(self, label, commands): self.Label = label; self.Path = PathObj(commands)

C = Command
job = [
    Obj("Fixture", [C("G54"), C("G0", {{"Z": 15.0}})]),
    Obj("TC: Endmill 6mm", [C("(TC: Endmill 6mm)"), C("M6", {{"T": 1.0}}), C("M3", {{"S": 12000.0}})]),
    Obj("Profile", [
        C("(Profile)"),
        C("G0", {{"Z": 15.0}}),
        C("G0", {{"X": 10.0, "Y": 10.0}}),
        C("G0", {{"Z": 5.0}}),
        C("G1", {{"Z": -1.0, "F": 5.0}}),
        C("G1", {{"X": 30.0, "F": 10.0}}),
        C("G01", {{"Y": 20.0}}),
        C("G00", {{"Z": 15.0}}),
        C("G4", {{"P": 0.5}}),
        C("M5"),
    ]),
]
{body}
"#,
        docs = root().join("docs/integration").display().to_string(),
    );
    let out = Command::new(py).arg("-c").arg(&script).output().unwrap();
    assert!(
        out.status.success(),
        "python failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    Some(String::from_utf8(out.stdout).unwrap())
}

fn word(block: &str, letter: char) -> Option<f64> {
    block
        .split_whitespace()
        .find(|w| w.starts_with(letter) && w[1..].parse::<f64>().is_ok())
        .map(|w| w[1..].parse().unwrap())
}

#[test]
fn freecad_1x_job_keeps_every_move_and_word() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("never-written.ngc");
    let Some(out) = run_python(&format!(
        r#"
args = "--machine xyz-3axis --kinpost '" + {bin:?} + "' --decimals 3"
text = k.export(job, "-", args)
import os
assert not os.path.exists({target:?})
sys.stdout.write(text)
"#,
        bin = BIN,
        target = target.display().to_string(),
    )) else {
        return;
    };
    // The tip of every move, as the job asks for it (mm). The first two
    // moves give only Z: X and Y are those of the next move that gives them.
    let expected: [(f64, f64, f64); 8] = [
        (10.0, 10.0, 15.0), // fixture clearance G0 Z15
        (10.0, 10.0, 15.0), // G0 Z15
        (10.0, 10.0, 15.0), // G0 X10 Y10
        (10.0, 10.0, 5.0),
        (10.0, 10.0, -1.0),
        (30.0, 10.0, -1.0),
        (30.0, 20.0, -1.0),
        (30.0, 20.0, 15.0),
    ];
    let moves: Vec<(f64, f64, f64)> = out
        .lines()
        .filter(|l| !l.starts_with('('))
        .filter_map(|l| Some((word(l, 'X')?, word(l, 'Y')?, word(l, 'Z')?)))
        .collect();
    assert_eq!(moves.len(), expected.len(), "{out}");
    for (got, want) in moves.iter().zip(&expected) {
        assert!(
            (got.0 - want.0).abs() < 1e-9
                && (got.1 - want.1).abs() < 1e-9
                && (got.2 - want.2).abs() < 1e-9,
            "{got:?} != {want:?}\n{out}"
        );
    }
    // Feeds: FreeCAD's mm/s become mm/min.
    assert!(out.contains("F300"), "{out}");
    assert!(out.contains("F600"), "{out}");
    // Tool change, spindle, dwell keep their words; the fixture stays.
    for w in ["M6 T1", "M3 S12000", "G4 P0.5", "M5", "G54"] {
        assert!(out.lines().any(|l| l.trim() == w), "{w} missing:\n{out}");
    }
    // The filled coordinates are said in the program, once: after the
    // first move the tool is there.
    assert_eq!(
        out.matches("(kinpost_post: XY from the next move that gives them)")
            .count(),
        1,
        "{out}"
    );
    assert!(!out.contains(" I0"), "tool vectors replaced: {out}");
}

#[test]
fn freecad_wrapper_refuses_what_it_does_not_convert() {
    let Some(out) = run_python(
        r#"
for cmd in [C("G81", {"X": 1.0, "Y": 2.0, "Z": -3.0, "R": 2.0}), C("G91"), C("G28"),
            C("G2", {"X": 2.0, "Y": 0.0, "R": 1.0})]:
    try:
        k.pose_program([C("G0", {"X": 0.0, "Y": 0.0, "Z": 5.0}), cmd], k.parse_args("--machine m"))
        print("NOT REFUSED", cmd.Name)
    except ValueError as e:
        print("REFUSED", e)
for plane in ["G18", "G19"]:
    try:
        k.pose_program([C("G0", {"X": 0.0, "Y": 0.0, "Z": 5.0}), C(plane),
                        C("G2", {"X": 2.0, "Z": 5.0, "I": 1.0, "K": 0.0})], k.parse_args("--machine m"))
        print("NOT REFUSED", cmd.Name)
    except ValueError as e:
        print("REFUSED", e)
try:
    k.pose_program([C("G0", {"Z": 5.0})], k.parse_args("--machine m"))
    print("NOT REFUSED partial")
except ValueError as e:
    print("REFUSED", e)
"#,
    ) else {
        return;
    };
    assert!(!out.contains("NOT REFUSED"), "{out}");
    assert!(
        out.contains("REFUSED kinpost_post: G81 is a canned cycle"),
        "{out}"
    );
    assert!(
        out.contains("REFUSED kinpost_post: G91 is incremental"),
        "{out}"
    );
    assert!(out.contains("REFUSED kinpost_post: G28"), "{out}");
    assert!(out.contains("REFUSED kinpost_post: G2 with R"), "{out}");
    assert!(out.contains("REFUSED kinpost_post: G2 in G18"), "{out}");
    assert!(out.contains("REFUSED kinpost_post: G2 in G19"), "{out}");
    assert!(
        out.contains("REFUSED kinpost_post: the job never gives XY"),
        "{out}"
    );
}

#[test]
fn freecad_wrapper_hands_the_job_set_up_to_kinpost() {
    let Some(out) = run_python(&format!(
        r#"
args = "--machine xyz-3axis --kinpost '" + {bin:?} + "' --decimals 3 --work-offset 100,-50,2"
sys.stdout.write(k.export(job, "-", args))
"#,
        bin = BIN,
    )) else {
        return;
    };
    // The first cutting move X10 Y10 Z-1 of the job, moved by the offset.
    assert!(out.contains("X110.000 Y-40.000 Z1.000"), "{out}");
}
