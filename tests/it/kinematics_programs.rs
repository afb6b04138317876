//! The committed fixture programs (`fixtures/programs/`) against the
//! inverse kinematics: every pose converts, the machine lands on it, the
//! rotaries move continuously (unwound through 360°, kept at the singular
//! poses), and the files are what the generator writes.

use crate::util::zhao_machine;
use kinpost::machine::{IkSolver, JointKind, Machine, NoErrors, Pose, RotaryMode};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

#[path = "../../examples/make_fixture_programs.rs"]
mod generator;

const MACHINES: [&str; 8] = [
    "zhao2022-xzbc",
    "wang2023-xyzab",
    "xyzac-trt",
    "xyzbc-trt",
    "xyzac-head",
    "xyzbc-nutating",
    "xyza-4axis",
    "xyz-3axis",
];

fn programs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/programs")
}

/// Poses of a G-code fixture: `G1 X.. Y.. Z.. I.. J.. K..` lines.
fn gcode_poses(text: &str) -> Vec<Pose> {
    let mut out = Vec::new();
    for line in text.lines().filter(|l| l.starts_with("G1 ")) {
        let mut v = [0.0; 6];
        for word in line.split_whitespace().skip(1) {
            let (letter, num) = word.split_at(1);
            if let Some(i) = "XYZIJK".find(letter) {
                v[i] = num.parse().unwrap();
            }
        }
        out.push(Pose::new(
            Vector3::new(v[0], v[1], v[2]),
            Vector3::new(v[3], v[4], v[5]),
        ));
    }
    out
}

/// Poses of an APT CL fixture: `GOTO/x,y,z,i,j,k` lines.
fn cl_poses(text: &str) -> Vec<Pose> {
    text.lines()
        .filter_map(|l| l.strip_prefix("GOTO/"))
        .map(|args| {
            let v: Vec<f64> = args.split(',').map(|s| s.trim().parse().unwrap()).collect();
            Pose::new(
                Vector3::new(v[0], v[1], v[2]),
                Vector3::new(v[3], v[4], v[5]),
            )
        })
        .collect()
}

/// Converts `poses` block by block; checks landing and continuity; returns
/// the joint values and the indices of singular blocks.
fn convert(machine: &Machine, poses: &[Pose]) -> (Vec<Vec<f64>>, Vec<usize>) {
    let solver = IkSolver::new(machine);
    let mut previous: Option<Vec<f64>> = None;
    let mut all = Vec::new();
    let mut singular = Vec::new();
    for (k, pose) in poses.iter().enumerate() {
        let sol = solver
            .solve(pose, previous.as_deref())
            .unwrap_or_else(|e| panic!("{} block {k}: {e}", machine.name));
        let reached = machine.chain.pose(&sol.q, &NoErrors);
        assert!(
            reached.tip_distance(pose) < 1e-9,
            "{} block {k}: tip off by {}",
            machine.name,
            reached.tip_distance(pose)
        );
        // Five-axis machines meet the axis; the others miss it by no more
        // than the 9-decimal rounding of the file (or everything, for the
        // three-axis machine, whose programs keep the axis along +Z).
        assert!(
            sol.axis_miss_rad < 1e-8,
            "{} block {k}: axis miss {}",
            machine.name,
            sol.axis_miss_rad
        );
        if let Some(prev) = &previous {
            for a in &machine.axes {
                let step = (sol.q[a.joint] - prev[a.joint]).abs();
                let step = match (a.kind, a.rotary) {
                    (JointKind::Revolute, RotaryMode::Modulo) => {
                        kinpost::machine::rotary::angle_diff(sol.q[a.joint], prev[a.joint]).abs()
                    }
                    _ => step,
                };
                let bound = if a.kind == JointKind::Revolute {
                    7f64.to_radians()
                } else {
                    25.0
                };
                assert!(
                    step < bound,
                    "{} block {k}: axis {} jumps by {step}",
                    machine.name,
                    a.name
                );
            }
        }
        if sol.singular {
            singular.push(k);
        }
        previous = Some(sol.q.to_vec());
        all.push(sol.q.to_vec());
    }
    (all, singular)
}

#[test]
fn every_gcode_fixture_converts_continuously() {
    for name in MACHINES {
        let machine = Machine::embedded(name).unwrap();
        let text = std::fs::read_to_string(programs_dir().join(format!("{name}.ngc"))).unwrap();
        let poses = gcode_poses(&text);
        assert!(
            (50..=300).contains(&poses.len()),
            "{name}: {} blocks",
            poses.len()
        );
        let (q, singular) = convert(&machine, &poses);
        // Continuous rotaries are unwound: starting from their principal
        // value at the first block, they run past ±180° without a jump
        // (the continuity check above) instead of wrapping.
        for a in machine
            .axes
            .iter()
            .filter(|a| a.rotary == RotaryMode::Continuous)
        {
            let deg: Vec<f64> = q.iter().map(|v| v[a.joint].to_degrees()).collect();
            let (lo, hi) = deg
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
            assert!(
                hi > 180.0 || lo < -180.0,
                "{name}: {} stays within {lo} … {hi}",
                a.name
            );
            assert!(hi - lo > 200.0, "{name}: {} spans only {lo} … {hi}", a.name);
        }
        // The tilt-0 blocks of the table-table, head-head and nutating machines
        // are singular: exactly one block each, where the generator put it.
        let expected: &[usize] = match name {
            "xyzac-trt" => &[100],
            "xyzbc-trt" => &[75],
            "xyzac-head" => &[60],
            "xyzbc-nutating" => &[25],
            _ => &[],
        };
        assert_eq!(singular, expected, "{name}: singular blocks");
    }
}

#[test]
fn apt_fixtures_convert_continuously() {
    for name in ["zhao2022-xzbc", "wang2023-xyzab"] {
        let machine = Machine::embedded(name).unwrap();
        let text = std::fs::read_to_string(programs_dir().join(format!("{name}.cls"))).unwrap();
        let poses = cl_poses(&text);
        assert!(poses.len() > 50);
        // The first and last GOTO are the rapid approach and retract.
        convert(&machine, &poses[1..poses.len() - 1]);
    }
}

#[test]
fn zhao_program_crosses_the_c_axis_with_c_from_the_tool_axis() {
    let machine = zhao_machine();
    let text = std::fs::read_to_string(programs_dir().join("zhao2022-xzbc.ngc")).unwrap();
    let poses = gcode_poses(&text);
    // Block 150 (0-based) has its tip on the C axis, tilted 30°.
    assert!(poses[150].tip.xy().norm() < 1e-9);
    let (q, _) = convert(&machine, &poses);
    let c = machine.chain.joint_index("C").unwrap();
    let b = machine.chain.joint_index("B").unwrap();
    // The generator's C there is −30 + 2.5·150 = 345°, B = 30°.
    assert!(
        (q[150][c].to_degrees() - 345.0).abs() < 1e-6,
        "C = {}",
        q[150][c].to_degrees()
    );
    assert!((q[150][b].to_degrees() - 30.0).abs() < 1e-6);
}

#[test]
fn fixture_programs_are_what_the_generator_writes() {
    let rendered = generator::render_all();
    assert_eq!(rendered.len(), 10);
    for (name, text) in rendered {
        let committed = std::fs::read_to_string(programs_dir().join(&name)).unwrap_or_default();
        assert!(
            committed == text,
            "fixtures/programs/{name} is not what the generator writes; run `cargo run --example make_fixture_programs`"
        );
        if name.ends_with(".ngc") {
            let lines: Vec<&str> = text.lines().collect();
            assert!(
                lines.contains(&"G21 G90 G94") && lines.contains(&"G43.5 H1"),
                "{name}"
            );
            assert_eq!(&lines[lines.len() - 2..], ["G49", "M30"], "{name}");
            for l in lines.iter().filter(|l| l.starts_with("G1 ")) {
                for w in l.split_whitespace().skip(1).filter(|w| !w.starts_with('F')) {
                    let decimals = w.split('.').nth(1).map_or(0, str::len);
                    assert_eq!(decimals, 9, "{name}: {w}");
                    assert!(
                        !w[1..].starts_with("-0.000000000"),
                        "{name}: negative zero {w}"
                    );
                }
            }
        } else {
            assert!(
                text.contains("FEDRAT/MMPM,") && text.contains("RAPID") && text.contains("$$"),
                "{name}"
            );
        }
    }
}
