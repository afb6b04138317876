//! Property tests of the inverse kinematics on every fixture machine:
//! FK(IK(pose)) = pose for poses generated from random axis values within
//! the limits; the branch nearest the previous block is the generating one;
//! four-axis and three-axis machines meet the tip exactly and report the
//! true angular distance to the reachable tool axes; chains no analytic
//! solver recognises go through the damped-Newton fallback.

use crate::util::zhao_machine;
use kinpost::machine::rotary::angle_diff;
use kinpost::machine::{
    AxisSpec, Family, IkSolver, JointKind, Machine, NoErrors, Pose, RotaryMode,
};
use nalgebra::Vector3;
use proptest::prelude::*;

const TOL_MM: f64 = 1e-9;
const TOL_RAD: f64 = 1e-9;

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

/// Axis value (file units) for a uniform sample `u` in [0, 1): within the
/// limits (the middle 80 % of linear travel), ±720° for continuous axes,
/// [0, 360) for modulo axes.
fn axis_value(a: &AxisSpec, u: f64) -> f64 {
    match (a.kind, a.rotary, a.min, a.max) {
        (JointKind::Revolute, RotaryMode::Continuous, _, _) => -720.0 + 1440.0 * u,
        (JointKind::Revolute, RotaryMode::Modulo, _, _) => 360.0 * u,
        (JointKind::Revolute, _, Some(lo), Some(hi)) => lo + (hi - lo) * u,
        (JointKind::Prismatic, _, Some(lo), Some(hi)) => lo + (hi - lo) * (0.1 + 0.8 * u),
        _ => -100.0 + 200.0 * u,
    }
}

fn random_q(m: &Machine, u: &[f64]) -> Vec<f64> {
    let values: Vec<f64> = m
        .axes
        .iter()
        .zip(u)
        .map(|(a, u)| axis_value(a, *u))
        .collect();
    m.to_internal(&values).to_vec()
}

fn same_joint(m: &Machine, j: usize, a: f64, b: f64) -> bool {
    let axis = m.axis_of_joint(j).unwrap();
    let d = if axis.rotary == RotaryMode::Modulo {
        angle_diff(a, b)
    } else {
        a - b
    };
    d.abs() < 1e-9
}

fn assert_lands(m: &Machine, q: &[f64], pose: &Pose) -> Result<(), TestCaseError> {
    let p = m.chain.pose(q, &NoErrors);
    prop_assert!(
        p.tip_distance(pose) < TOL_MM,
        "{}: tip off by {}",
        m.name,
        p.tip_distance(pose)
    );
    prop_assert!(
        p.axis_angle(pose) < TOL_RAD,
        "{}: axis off by {}",
        m.name,
        p.axis_angle(pose)
    );
    Ok(())
}

/// Below this smallest singular value of the tool axis's Jacobian with
/// respect to the rotaries (rad/rad), a pose counts as singular in the tests.
/// The solver's own tolerance is 1e-9 rad; this is well above it, so the
/// poses tested as regular are regular for the solver too.
const SINGULAR_CONDITIONING: f64 = 1e-4;

/// Smallest singular value of d(tool axis)/d(rotary joints) at `q`, by
/// central differences of the chain: 0 where a rotary no longer turns the
/// tool (the tool along its axis, or a nutating head at full tilt). Machines
/// without rotaries give infinity. An evaluation independent of the solver.
fn orientation_conditioning(m: &Machine, q: &[f64]) -> f64 {
    const H: f64 = 1e-6;
    let rotaries: Vec<usize> = (0..q.len())
        .filter(|&j| m.chain.joints()[j].kind == JointKind::Revolute)
        .collect();
    if rotaries.is_empty() {
        return f64::INFINITY;
    }
    let columns: Vec<Vector3<f64>> = rotaries
        .iter()
        .map(|&j| {
            let mut plus = q.to_vec();
            let mut minus = q.to_vec();
            plus[j] += H;
            minus[j] -= H;
            (m.chain.pose(&plus, &NoErrors).axis - m.chain.pose(&minus, &NoErrors).axis) / (2.0 * H)
        })
        .collect();
    nalgebra::Matrix3xX::from_columns(&columns)
        .singular_values()
        .min()
}

/// A unit vector from three samples in [0, 1).
fn unit(u: &[f64]) -> Vector3<f64> {
    let z = 2.0 * u[0] - 1.0;
    let phi = std::f64::consts::TAU * u[1];
    let r = (1.0 - z * z).sqrt();
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// FK(IK(pose)) = pose without a previous block, on every machine.
    #[test]
    fn ik_round_trips_on_every_machine(u in prop::collection::vec(0.0f64..1.0, 7)) {
        for name in MACHINES {
            let m = Machine::embedded(name).unwrap();
            let s = IkSolver::new(&m);
            let q = random_q(&m, &u);
            let pose = m.chain.pose(&q, &NoErrors);
            let sol = s.solve(&pose, None).map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            assert_lands(&m, &sol.q, &pose)?;
            // Every enumerated branch lands too.
            for b in s.branches(&pose, None) {
                assert_lands(&m, &b.q, &pose)?;
            }
        }
    }

    /// With the generating joints (slightly disturbed) as the previous block,
    /// the solver returns exactly the generating joints: the nearest branch,
    /// rotaries unwound to the generating turn. At a singular pose (judged
    /// from the chain, not by the solver) other joints land as well; there
    /// only landing is asserted.
    #[test]
    fn nearest_branch_is_the_generating_one(
        u in prop::collection::vec(0.0f64..1.0, 7),
        jitter in prop::collection::vec(-1.0f64..1.0, 7),
    ) {
        for name in MACHINES {
            let m = Machine::embedded(name).unwrap();
            let s = IkSolver::new(&m);
            let q = random_q(&m, &u);
            let pose = m.chain.pose(&q, &NoErrors);
            let prev: Vec<f64> = q
                .iter()
                .zip(&jitter)
                .enumerate()
                .map(|(j, (v, d))| match m.chain.joints()[j].kind {
                    JointKind::Revolute => v + d * 3f64.to_radians(),
                    JointKind::Prismatic => v + d * 2.0,
                })
                .collect();
            let sol = s.solve(&pose, Some(&prev)).map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            assert_lands(&m, &sol.q, &pose)?;
            let conditioning = orientation_conditioning(&m, &q);
            if conditioning < SINGULAR_CONDITIONING {
                // Singular (the tool along a rotary axis, or a nutating head
                // at its largest tilt): the generating joints are not the
                // only ones that land, and landing is checked above.
                continue;
            }
            for (j, (got, want)) in sol.q.iter().zip(&q).enumerate() {
                prop_assert!(
                    same_joint(&m, j, *got, *want),
                    "{name}: joint {} = {got} instead of {want}",
                    m.chain.joints()[j].name
                );
            }
            prop_assert!(!sol.singular, "{name}: regular pose (conditioning {conditioning:.2e}) reported singular");
        }
    }

    /// zhao2022 (RTTR): a tool axis off the machine's reachable set. The tip
    /// is met exactly and the reported miss is the true angular distance to
    /// the reachable axes (the half plane through the C axis and the tip,
    /// tilted towards +z).
    #[test]
    fn zhao_off_cone_poses_report_the_true_miss(
        x in -60.0f64..60.0, z in -80.0f64..80.0, b in -80.0f64..80.0, c in -720.0f64..720.0,
        du in prop::collection::vec(0.0f64..1.0, 3), size in 0.0f64..0.6,
    ) {
        let m = zhao_machine();
        let s = IkSolver::new(&m);
        let q = m.to_internal(&[x, z, b, c]);
        let on = m.chain.pose(&q, &NoErrors);
        let rho = on.tip.xy().norm();
        prop_assume!(rho > 1.0);
        let axis = (on.axis + unit(&du) * size).normalize();
        prop_assume!(axis.z > 0.1);
        let pose = Pose::new(on.tip, axis);
        let sol = s.solve(&pose, Some(&q)).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let reached = m.chain.pose(&sol.q, &NoErrors);
        prop_assert!(reached.tip_distance(&pose) < TOL_MM, "tip off by {}", reached.tip_distance(&pose));
        let e_r = Vector3::new(on.tip.x, on.tip.y, 0.0) / rho;
        let e_t = Vector3::z().cross(&e_r);
        let expected = axis.dot(&e_t).abs().asin();
        prop_assert!((sol.axis_miss_rad - expected).abs() < TOL_RAD, "miss {} expected {}", sol.axis_miss_rad, expected);
        prop_assert!((reached.axis_angle(&pose) - sol.axis_miss_rad).abs() < 1e-12);
    }

    /// xyza (1R3T): reachable tool axes are those perpendicular to X.
    #[test]
    fn xyza_off_axis_poses_report_the_true_miss(
        u in prop::collection::vec(0.0f64..1.0, 4), du in prop::collection::vec(0.0f64..1.0, 3),
    ) {
        let m = Machine::embedded("xyza-4axis").unwrap();
        let s = IkSolver::new(&m);
        // Middle of the travel: turning A to the closest axis moves Y and Z.
        let u: Vec<f64> = u.iter().map(|v| 0.3 + 0.4 * v).collect();
        let q = random_q(&m, &u);
        let on = m.chain.pose(&q, &NoErrors);
        let axis = unit(&du);
        prop_assume!(axis.x.abs() < 0.99);
        let pose = Pose::new(on.tip, axis);
        let sol = s.solve(&pose, None).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let reached = m.chain.pose(&sol.q, &NoErrors);
        prop_assert!(reached.tip_distance(&pose) < TOL_MM);
        prop_assert!((sol.axis_miss_rad - axis.x.abs().asin()).abs() < TOL_RAD);
    }

    /// xyz (3 axes): the tip is met, the miss is the tilt from +Z.
    #[test]
    fn three_axis_reports_the_tilt(u in prop::collection::vec(0.0f64..1.0, 3), du in prop::collection::vec(0.0f64..1.0, 3)) {
        let m = Machine::embedded("xyz-3axis").unwrap();
        let s = IkSolver::new(&m);
        let q = random_q(&m, &u);
        let on = m.chain.pose(&q, &NoErrors);
        let axis = unit(&du);
        let sol = s.solve(&Pose::new(on.tip, axis), None).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!(m.chain.pose(&sol.q, &NoErrors).tip_distance(&on) < TOL_MM);
        prop_assert!((sol.axis_miss_rad - axis.z.clamp(-1.0, 1.0).acos()).abs() < TOL_RAD);
    }

    /// Chains outside the analytic families: damped Newton from a nearby
    /// previous block lands on the pose.
    #[test]
    fn generic_chains_go_through_newton(
        u in prop::collection::vec(0.0f64..1.0, 7),
        jitter in prop::collection::vec(-1.0f64..1.0, 7),
    ) {
        for m in generic_machines() {
            let s = IkSolver::new(&m);
            prop_assert_eq!(s.family(), Family::Generic);
            let q = random_q(&m, &u);
            let pose = m.chain.pose(&q, &NoErrors);
            let prev: Vec<f64> = q.iter().zip(&jitter).map(|(v, d)| v + d * 0.02).collect();
            let sol = s.solve(&pose, Some(&prev)).map_err(|e| TestCaseError::fail(format!("{}: {e}", m.name)))?;
            assert_lands(&m, &sol.q, &pose)?;
        }
    }
}

/// Two chains no analytic solver takes: an RTTR machine whose B axis is
/// tilted out of the XZ plane (four axes, tool axis and tip coupled), and a
/// six-axis head (X Y Z + C B A, orientation redundant).
fn generic_machines() -> Vec<Machine> {
    let tilted = r#"{"name": "tilted-rttr", "chain": [
        {"revolute": {"name": "C", "axis": [0, 0, -1]}},
        {"prismatic": {"name": "X", "axis": [1, 0, 0]}},
        {"prismatic": {"name": "Z", "axis": [0, 0, 1]}},
        {"revolute": {"name": "B", "axis": [0, 1, 0.2]}},
        {"translate": [0, 0, -20]}],
        "axes": {"X": {"min": -100, "max": 100}, "Z": {"min": -100, "max": 100},
                 "B": {"min": -60, "max": 60}, "C": {"rotary": "continuous"}}}"#;
    let six = r#"{"name": "six-axis-head", "chain": [
        {"prismatic": {"name": "X", "axis": [1, 0, 0]}},
        {"prismatic": {"name": "Y", "axis": [0, 1, 0]}},
        {"prismatic": {"name": "Z", "axis": [0, 0, 1]}},
        {"translate": [0, 0, 120]},
        {"revolute": {"name": "C", "axis": [0, 0, 1]}},
        {"revolute": {"name": "B", "axis": [0, 1, 0]}},
        {"revolute": {"name": "A", "axis": [1, 0, 0]}},
        {"translate": [0, 0, -120]}],
        "axes": {"X": {"min": -300, "max": 300}, "Y": {"min": -300, "max": 300}, "Z": {"min": -300, "max": 300},
                 "A": {"min": -60, "max": 60}, "B": {"min": -60, "max": 60}, "C": {"rotary": "continuous"}}}"#;
    vec![
        Machine::from_json_str(tilted, "tilted.json").unwrap(),
        Machine::from_json_str(six, "six.json").unwrap(),
    ]
}
