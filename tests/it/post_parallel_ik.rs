//! `post` on G-code and on APT CL finds the branches of its poses in
//! parallel and chooses among them in order (`post::choose_in_order`): its
//! output, warnings and errors are those of the solver that solves each
//! pose whole, in order, also where a unit makes the first pass wait for
//! the poses before it to be written, at any place in a chunk of the
//! driver: a G-code block in machine coordinates, an APT CL arc or hole
//! (planned with the solver as `G2`/`G3` or a canned cycle).

use kinpost::machine::{IkSolver, Machine, NoErrors, Pose};
use kinpost::post::{PoseSolver, PostOptions, SolvedPose, post_cl, post_gcode};

use crate::util::pose_block;

/// The in-order solver: the analytic IK without its two parts, so that
/// `post` solves each pose whole in its first pass.
struct Whole(IkSolver);

impl PoseSolver for Whole {
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> Result<SolvedPose, String> {
        PoseSolver::solve(&mut self.0, pose, previous, line)
    }
}

/// Output (or the error's text), warnings and poses written.
type Run = (Result<Vec<u8>, String>, Vec<String>, usize);

fn run(solver: &mut (dyn PoseSolver + Send), machine: &Machine, text: &str) -> Run {
    let cl = text.starts_with("UNITS/");
    let opts = PostOptions {
        decimals: Some(6),
        file_name: if cl { "p.cls" } else { "p.nc" }.into(),
        ..PostOptions::default()
    };
    let mut out = Vec::new();
    let posted = if cl {
        post_cl(machine, solver, text.as_bytes(), &mut out, &opts, |_| {})
    } else {
        post_gcode(machine, solver, text.as_bytes(), &mut out, &opts, |_| {})
    };
    match posted {
        Ok(stats) => (Ok(out), stats.warnings, stats.poses),
        // What was written before the error stays compared.
        Err(e) => (
            Err(format!("{e}\n{}", String::from_utf8_lossy(&out))),
            Vec::new(),
            0,
        ),
    }
}

/// Pose blocks of a smooth joint path whose rotaries turn several times
/// and whose tilt passes through 0 (a singular pose on both machines).
fn pose_lines(machine: &Machine, n: usize) -> Vec<String> {
    let joints = machine.chain.joints();
    (0..n)
        .map(|i| {
            let t = i as f64 / n as f64;
            let mut tilts = 0;
            let q: Vec<f64> = joints
                .iter()
                .enumerate()
                .map(|(k, j)| match j.kind {
                    kinpost::machine::JointKind::Prismatic => {
                        40.0 * (7.0 * t + k as f64).sin() + 5.0
                    }
                    kinpost::machine::JointKind::Revolute => {
                        tilts += 1;
                        if tilts == 1 {
                            // The rotary nearer the base: three turns.
                            6.0 * std::f64::consts::PI * t
                        } else {
                            // The tilt: through 0 twice.
                            0.5 * (9.0 * t).sin()
                        }
                    }
                })
                .collect();
            pose_block(&machine.chain.pose(&q, &NoErrors))
        })
        .collect()
}

/// A program of `n` poses with, before the lines at `breaks`, a section in
/// machine coordinates: pose mode off, moves of some axes (absolute and
/// incremental), pose mode on again, and a pose that gives only Z (the
/// rest from where the machine stands).
fn program(machine: &Machine, n: usize, breaks: &[usize]) -> String {
    let lines = pose_lines(machine, n);
    let axis = |k: usize| machine.axes[k % machine.axes.len()].name.clone();
    // Every axis at a known position first: a pose giving only Z before
    // any other continues from there.
    let home: Vec<String> = machine
        .axes
        .iter()
        .map(|a| format!("{}0", a.name))
        .collect();
    let mut text = format!(
        "G21 G90 G94\nG49\nG0 {}\nG43.4 H1\nG1 F500.\n",
        home.join(" ")
    );
    for (i, l) in lines.iter().enumerate() {
        if breaks.contains(&i) {
            text.push_str("G49\n");
            text.push_str(&format!("G0 {}12.5\n", axis(i)));
            text.push_str(&format!("G91 G0 {}-2.5\nG90\n", axis(i + 1)));
            text.push_str("G43.4 H1\n");
            text.push_str("Z30.\n");
        }
        text.push_str(l);
        text.push('\n');
    }
    text.push_str("M30\n");
    text
}

/// APT CL of `n` poses (the path of [`pose_lines`]) with, before the
/// poses at `arcs`, an arc, and before those at `holes`, a drilled hole
/// (each with the tool along Z, after a rapid move above it, so that
/// both are planned: `G2`/`G3` and `G81`), and a hole at the start, before
/// any pose (planned without a position before it). A hole right after
/// a tilted pose is positioned first (a rapid move, then the cycle).
fn cl_program(machine: &Machine, n: usize, arcs: &[usize], holes: &[usize]) -> String {
    let lines = pose_lines(machine, n);
    let mut text = String::from("UNITS/MM\nFEDRAT/MMPM,500\n");
    let hole = |text: &mut String, x: f64| {
        text.push_str(&format!(
            "CYCLE/DRILL,FEDTO,-1,RAPTO,2,RTRCTO,10\nGOTO/{x:.3},5,0,0,0,1\nCYCLE/OFF\n"
        ));
    };
    hole(&mut text, 1.0);
    for (i, l) in lines.iter().enumerate() {
        let x = 0.001 * i as f64;
        if arcs.contains(&i) {
            text.push_str(&format!(
                "RAPID\nGOTO/{:.3},0,5,0,0,1\nGOTO/{:.3},0,5,0,0,1\nCIRCLE/{x:.3},0,5,0,0,1,10\nGOTO/{x:.3},10,5\n",
                x + 10.0,
                x + 10.0,
            ));
        }
        if holes.contains(&i) {
            hole(&mut text, x);
        }
        // `G1 X.. Y.. Z.. I.. J.. K..` as a GOTO.
        let v: Vec<&str> = l.split(' ').skip(1).map(|w| &w[1..]).collect();
        text.push_str(&format!("GOTO/{}\n", v.join(",")));
    }
    text.push_str("FINI\n");
    text
}

fn compare(machine: &Machine, text: &str) -> Run {
    let mut split = IkSolver::new(machine);
    assert!(
        split.split().is_some(),
        "the analytic IK comes in two parts"
    );
    let parallel = run(&mut split, machine, text);
    let whole = run(&mut Whole(IkSolver::new(machine)), machine, text);
    assert_eq!(parallel.0, whole.0, "{}", machine.name);
    assert_eq!(parallel.1, whole.1, "{}: warnings", machine.name);
    assert_eq!(parallel.2, whole.2, "{}: poses", machine.name);
    parallel
}

#[test]
fn branches_found_in_parallel_give_the_in_order_solution() {
    for name in [
        "zhao2022-xzbc",
        "wang2023-xyzab",
        "xyzac-trt",
        "xyzbc-nutating",
    ] {
        let machine = Machine::embedded(name).unwrap();
        // Machine blocks (5 lines, after the 5 of the header) before
        // poses 0, 100, at the start of the driver's third chunk of 512
        // lines, a run of them close together, and two more. The first
        // pass waits at 100, 1004, 2200 and 2999 (at 0 no pose came
        // before); after each wait it solves the next 512 poses itself
        // (`IN_ORDER_AFTER_WAIT`), so that the blocks at 1500–1503 are
        // read with their joint values known.
        let breaks = [0, 100, 1024 - 5 - 15, 1500, 1501, 1503, 2200, 2999];
        let (out, _, poses) = compare(&machine, &program(&machine, 3000, &breaks));
        assert_eq!(poses, 3000 + breaks.len(), "{name}");
        assert!(out.is_ok(), "{name}: {out:?}");
    }
}

#[test]
fn a_pose_that_fails_in_the_last_pass_fails_as_in_order() {
    let machine = Machine::embedded("wang2023-xyzab").unwrap();
    let mut text = program(&machine, 2000, &[700, 1300]);
    // A tool tip beyond X's travel (±1000 mm; A turns about X, so no
    // branch helps) in the middle of the second chunk.
    let lines: Vec<&str> = text.lines().collect();
    let at = 800;
    let mut bad = lines[..at].join("\n");
    bad.push_str("\nX5000. Y10. Z10. I0. J0. K1.\n");
    bad.push_str(&lines[at..].join("\n"));
    bad.push('\n');
    text = bad;
    let (out, _, _) = compare(&machine, &text);
    let Err(e) = out else {
        panic!("X5000 was converted")
    };
    assert!(e.starts_with(&format!("p.nc:{}:", at + 1)), "{e}");
}

#[test]
fn cl_arcs_and_holes_wait_and_are_planned_as_in_order() {
    for name in ["xyzac-trt", "zhao2022-xzbc", "xyzbc-nutating"] {
        let machine = Machine::embedded(name).unwrap();
        // Arcs (5 statements each) and holes (3) before poses 0, 100, at
        // and near the start of the driver's third chunk of 512
        // statements, a run of them close together (solved in order after
        // the first wait, each one renewing that), and two more; a hole
        // before the first pose.
        let arcs = [0, 100, 1000, 1003, 1500, 1501, 1502, 2999];
        let holes = [300, 1000, 1501, 2200, 2600];
        let (out, _, _) = compare(&machine, &cl_program(&machine, 3000, &arcs, &holes));
        let out = String::from_utf8(out.unwrap_or_else(|e| panic!("{name}: {e}"))).unwrap();
        if name == "xyzac-trt" {
            // Planned, not given as moves.
            assert_eq!(out.matches("G3 ").count(), arcs.len(), "{out}");
            assert_eq!(out.matches("G81 ").count(), holes.len() + 1, "{out}");
        }
    }
}
