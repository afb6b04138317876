//! Writes the pose programs under `fixtures/programs/`.
//!
//! ```text
//! cargo run --example make_fixture_programs
//! ```
//!
//! For every fixture machine a smooth axis trajectory within the machine's
//! limits is sampled, put through the machine's chain (`Chain::pose`, the
//! one evaluator) and written as tool poses: tool tip X Y Z (mm) and tool
//! axis I J K in the workpiece frame, 9 decimals each. The trajectories pass
//! through tilt 0 (the singular pose of table-table and head-head machines)
//! and through C = 360° (or A = 360°) where the family allows. Because the
//! poses are generated from axes, the four-axis machines' poses lie exactly
//! on what they can reach (up to the 9-decimal rounding).
//!
//! Output is deterministic: running the generator again rewrites the same
//! bytes.

use kinpost::machine::{Machine, NoErrors, Pose};
use std::f64::consts::TAU;
use std::fmt::Write;
use std::path::Path;

/// Axis values (output order, mm and degrees) for sample `k` of `n`.
type Trajectory = fn(usize, usize) -> Vec<f64>;

struct Program {
    machine: &'static str,
    blocks: usize,
    feed: f64,
    trajectory: Trajectory,
    about: &'static str,
}

fn programs() -> Vec<Program> {
    vec![
        Program {
            machine: "zhao2022-xzbc",
            blocks: 180,
            feed: 200.0,
            // Tip radius r = 37.5 − 0.25k crosses the C axis at k = 150 (with
            // B = 30°: C there comes from the tool axis); B passes 0 at k = 0,
            // 60, 120; C runs −30° … 417.5° through 0 (k = 12) and 360° (k = 156).
            trajectory: |k, _| {
                let kf = k as f64;
                let r = 0.25 * (150.0 - kf);
                let b: f64 = 30.0 * (TAU * kf / 120.0).sin();
                let ztip = -5.0 + 3.0 * (TAU * kf / 90.0).cos() - 0.002 * r * r;
                let br = b.to_radians();
                let x = r + 20.0 * br.sin();
                let z = ztip + 20.0 * br.cos();
                let c = -30.0 + 2.5 * kf;
                vec![x, z, b, c]
            },
            about: "lens-like spiral: tip radius 37.5 mm down through the C axis at block 151 to -7.25 mm; B swings +-30 deg through 0; C from -30 to 417.5 deg through 360",
        },
        Program {
            machine: "wang2023-xyzab",
            blocks: 150,
            feed: 800.0,
            // A 250° … 548° through 360° (k = 55) and 540° (k = 145); B 40° … −34.5° through 0 (k = 80).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    150.0 - 0.6 * kf + 10.0 * (TAU * kf / 75.0).sin(),
                    -2.0 + 15.0 * (TAU * kf / 150.0).sin(),
                    -38.0 + 0.3 * kf,
                    40.0 - 0.5 * kf,
                    250.0 + 2.0 * kf,
                ]
            },
            about: "sweep starting near the paper's Table 2: B from 40 to -34.5 deg through 0, A from 250 to 548 deg through 360 and 540",
        },
        Program {
            machine: "xyzac-trt",
            blocks: 160,
            feed: 1000.0,
            // C 270° … 588° through 360° (k = 45) and 540° (k = 135); A 40° … −23.6° through 0 (k = 100).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    60.0 * (TAU * kf / 160.0).cos(),
                    40.0 * (TAU * kf / 160.0).sin(),
                    20.0 + 5.0 * (TAU * kf / 40.0).sin(),
                    40.0 - 0.4 * kf,
                    270.0 + 2.0 * kf,
                ]
            },
            about: "A from 40 to -23.6 deg through 0 at block 101 where the tool axis is along C, the singular pose; C from 270 to 588 deg through 360 and 540",
        },
        Program {
            machine: "xyzbc-trt",
            blocks: 160,
            feed: 1000.0,
            // B 30° … −33.6° through 0 (k = 75); C 300° … 459° through 360 (k = 60).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    -50.0 + 0.6 * kf,
                    30.0 * (TAU * kf / 80.0).sin(),
                    15.0 + 0.05 * kf,
                    30.0 - 0.4 * kf,
                    300.0 + kf,
                ]
            },
            about: "B from 30 to -33.6 deg through 0 at block 76, singular; modulo C from 300 to 459 deg through 360",
        },
        Program {
            machine: "xyzac-head",
            blocks: 111,
            feed: 1500.0,
            // C 250° … 360° (its limit); A 30° … −25° through 0 (k = 60).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    100.0 * (TAU * kf / 222.0).cos(),
                    80.0 * (TAU * kf / 222.0).sin(),
                    10.0 + 0.1 * kf,
                    30.0 - 0.5 * kf,
                    250.0 + kf,
                ]
            },
            about: "fork head: A from 30 to -25 deg through 0 at block 61, singular; C from 250 to 360 deg, its limit",
        },
        Program {
            machine: "xyzbc-nutating",
            blocks: 150,
            feed: 1000.0,
            // B −30° … 148.8° through 0 (k = 25); C 300° … 598° through 360° (k = 30) and 540° (k = 120).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    40.0 * (TAU * kf / 150.0).sin(),
                    -20.0 + 0.2 * kf,
                    30.0 + 10.0 * (TAU * kf / 50.0).cos(),
                    -30.0 + 1.2 * kf,
                    300.0 + 2.0 * kf,
                ]
            },
            about: "nutating table: B from -30 to 148.8 deg through 0 at block 26, singular; C from 300 to 598 deg through 360 and 540",
        },
        Program {
            machine: "xyza-4axis",
            blocks: 150,
            feed: 600.0,
            // A −60° … 387° through 0 (k = 20) and 360° (k = 140).
            trajectory: |k, _| {
                let kf = k as f64;
                vec![
                    -100.0 + 1.3 * kf,
                    5.0 * (TAU * kf / 50.0).sin(),
                    25.0,
                    -60.0 + 3.0 * kf,
                ]
            },
            about: "wrapping a cylinder of radius 25 mm: A from -60 to 387 deg through 0 and 360",
        },
        Program {
            machine: "xyz-3axis",
            blocks: 60,
            feed: 1200.0,
            trajectory: |k, _| {
                let t = TAU * k as f64 / 59.0;
                vec![50.0 * t.cos(), 30.0 * t.sin(), -2.0 + 0.01 * k as f64]
            },
            about: "an ellipse with the tool along +Z",
        },
    ]
}

/// `v` with 9 decimals, never `-0.000000000`.
fn f9(v: f64) -> String {
    let s = format!("{v:.9}");
    match s.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|c| c == b'0' || c == b'.') => rest.to_string(),
        _ => s,
    }
}

fn poses(p: &Program, machine: &Machine) -> Vec<Pose> {
    (0..p.blocks)
        .map(|k| {
            let values = (p.trajectory)(k, p.blocks);
            for (a, v) in machine.axes.iter().zip(&values) {
                let lo = a.min.unwrap_or(f64::NEG_INFINITY);
                let hi = a.max.unwrap_or(f64::INFINITY);
                assert!(
                    *v >= lo - 1e-9 && *v <= hi + 1e-9,
                    "{} block {k}: {} = {v} outside limits",
                    p.machine,
                    a.name
                );
            }
            machine.chain.pose(&machine.to_internal(&values), &NoErrors)
        })
        .collect()
}

fn gcode(p: &Program, machine: &Machine) -> String {
    assert!(!p.about.contains(['(', ')']), "G-code comments cannot nest");
    let mut s = String::new();
    let _ = writeln!(s, "(kinpost fixture program for machine {})", p.machine);
    let _ = writeln!(
        s,
        "(generated by examples/make_fixture_programs.rs - do not edit)"
    );
    let _ = writeln!(s, "({})", p.about);
    let _ = writeln!(
        s,
        "(poses: tool tip X Y Z in mm, tool axis I J K, workpiece frame)"
    );
    let _ = writeln!(s, "G21 G90 G94");
    let _ = writeln!(s, "G43.5 H1");
    for (k, pose) in poses(p, machine).iter().enumerate() {
        let feed = if k == 0 {
            format!(" F{:.1}", p.feed)
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "G1 X{} Y{} Z{} I{} J{} K{}{feed}",
            f9(pose.tip.x),
            f9(pose.tip.y),
            f9(pose.tip.z),
            f9(pose.axis.x),
            f9(pose.axis.y),
            f9(pose.axis.z)
        );
    }
    let _ = writeln!(s, "G49");
    let _ = writeln!(s, "M30");
    s
}

fn apt(p: &Program, machine: &Machine) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "$$ kinpost fixture CL file for machine {}", p.machine);
    let _ = writeln!(
        s,
        "$$ generated by examples/make_fixture_programs.rs - do not edit"
    );
    let _ = writeln!(s, "$$ {}", p.about);
    let _ = writeln!(
        s,
        "$$ GOTO/x,y,z,i,j,k: tool tip in mm and tool axis, workpiece frame"
    );
    let _ = writeln!(s, "PARTNO/{}", p.machine.to_uppercase());
    let _ = writeln!(s, "UNITS/MM");
    let _ = writeln!(s, "MULTAX");
    let goto = |pose: &Pose| {
        format!(
            "GOTO/{},{},{},{},{},{}",
            f9(pose.tip.x),
            f9(pose.tip.y),
            f9(pose.tip.z),
            f9(pose.axis.x),
            f9(pose.axis.y),
            f9(pose.axis.z)
        )
    };
    let all = poses(p, machine);
    // Approach: rapid to 50 mm above the first pose along the tool axis.
    let first = all[0];
    let above = Pose::new(first.tip + first.axis * 50.0, first.axis);
    let _ = writeln!(s, "RAPID");
    let _ = writeln!(s, "{}", goto(&above));
    let _ = writeln!(s, "FEDRAT/MMPM,{:.3}", p.feed);
    for (k, pose) in all.iter().enumerate() {
        if k == all.len() / 2 {
            let _ = writeln!(s, "$$ second half at a lower feed");
            let _ = writeln!(s, "FEDRAT/MMPM,{:.3}", p.feed / 2.0);
        }
        let _ = writeln!(s, "{}", goto(pose));
    }
    let last = all[all.len() - 1];
    let _ = writeln!(s, "RAPID");
    let _ = writeln!(
        s,
        "{}",
        goto(&Pose::new(last.tip + last.axis * 50.0, last.axis))
    );
    let _ = writeln!(s, "FINI");
    s
}

/// Every fixture program: file name and content.
pub fn render_all() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for p in programs() {
        let machine = Machine::embedded(p.machine).expect("fixture machines are embedded");
        out.push((format!("{}.ngc", p.machine), gcode(&p, &machine)));
        if matches!(p.machine, "zhao2022-xzbc" | "wang2023-xyzab") {
            out.push((format!("{}.cls", p.machine), apt(&p, &machine)));
        }
    }
    out
}

#[allow(dead_code)] // unused when the tests include this file
fn main() -> std::io::Result<()> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/programs");
    std::fs::create_dir_all(&dir)?;
    for (name, text) in render_all() {
        let path = dir.join(name);
        std::fs::write(&path, text)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
