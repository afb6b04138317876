//! wang2023-xyzab (seed 003) against the paper: the relations of its
//! Section 2 (Eqs 3–10) and its Tables 2 and 3, which pin the pivot length
//! L = 265 mm and the signs of both rotary axes.

use crate::seed003_tables::TABLE3;

use kinpost::machine::rotary::angle_diff;
use kinpost::machine::{Family, IkSolver, Machine, NoErrors, Pose};
use nalgebra::Vector3;

const L: f64 = 265.0;

/// Table 2: machine coordinates X, Y, Z (mm), B, A (deg) before interpolation.
const TABLE2: [[f64; 5]; 5] = [
    [150.891, -1.827, -38.483, 40.823, 336.463],
    [149.828, -1.885, -37.6, 40.5, 336.789],
    [148.746, -1.942, -36.712, 40.173, 337.115],
    [147.649, -1.998, -35.824, 39.844, 337.438],
    [146.552, -2.048, -34.946, 39.516, 337.756],
];

use crate::util::wang_machine;

fn pose_of(m: &Machine, row: &[f64; 5]) -> Pose {
    m.chain.pose(&m.to_internal(row), &NoErrors)
}

#[test]
fn the_chain_gives_the_papers_relations() {
    let m = wang_machine();
    assert_eq!(IkSolver::new(&m).family(), Family::FiveAxis2R3T);
    for k in 0..200 {
        let t = k as f64;
        let (x_ax, y_ax, z_ax) = (
            100.0 * (0.37 * t).sin(),
            80.0 * (0.91 * t).cos(),
            -50.0 + 40.0 * (0.23 * t).sin(),
        );
        let b_deg = 85.0 * (0.53 * t).sin();
        let a_deg = 400.0 * (0.17 * t).cos();
        let pose = m
            .chain
            .pose(&m.to_internal(&[x_ax, y_ax, z_ax, b_deg, a_deg]), &NoErrors);
        let (a, b) = (a_deg.to_radians(), b_deg.to_radians());
        // Eq (3): i = sin B, j = sin A cos B, k = cos A cos B.
        let axis = Vector3::new(b.sin(), a.sin() * b.cos(), a.cos() * b.cos());
        assert!((pose.axis - axis).norm() < 1e-14, "axis at {k}");
        let (x, y, z) = (pose.tip.x, pose.tip.y, pose.tip.z);
        // Eqs (8)–(10) with m_y = m_z = 0.
        assert!((x_ax - (x + b.sin() * L)).abs() < 1e-10, "X at {k}");
        assert!(
            (y_ax - (a.cos() * y - a.sin() * z)).abs() < 1e-10,
            "Y at {k}"
        );
        assert!(
            (z_ax - (-L * (1.0 - b.cos()) + a.sin() * y + a.cos() * z)).abs() < 1e-10,
            "Z at {k}"
        );
    }
}

#[test]
fn ik_gives_the_papers_angles() {
    // Eqs (6)–(7): B = arctan(i / √(j² + k²)), A = atan2-quadrant of j / k
    // in [0, 2π). Within B's ±90° the IK's branch is that one (A modulo 360°).
    let m = wang_machine();
    let s = IkSolver::new(&m);
    for row in TABLE2 {
        let pose = pose_of(&m, &row);
        let (i, j, k) = (pose.axis.x, pose.axis.y, pose.axis.z);
        let b = (i / j.hypot(k)).atan();
        let a = j.atan2(k).rem_euclid(std::f64::consts::TAU);
        assert!((b.to_degrees() - row[3]).abs() < 1e-9 && (a.to_degrees() - row[4]).abs() < 1e-9);
        let sol = s.solve(&pose, None).unwrap();
        let (bj, aj) = (
            m.chain.joint_index("B").unwrap(),
            m.chain.joint_index("A").unwrap(),
        );
        assert!((sol.q[bj] - b).abs() < 1e-12);
        assert!(angle_diff(sol.q[aj], a).abs() < 1e-12);
    }
}

#[test]
fn table2_rows_round_trip_through_ik() {
    let m = wang_machine();
    let s = IkSolver::new(&m);
    let mut prev: Option<Vec<f64>> = None;
    for row in TABLE3 {
        let q = m.to_internal(&row);
        let sol = s
            .solve(&pose_of(&m, &row), prev.as_deref().or(Some(&q)))
            .unwrap();
        for (got, want) in m.to_external(&sol.q).iter().zip(row) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        prev = Some(sol.q.to_vec());
    }
}

#[test]
fn table3_holds_table2_rows() {
    for (k, row) in TABLE2.iter().enumerate() {
        assert_eq!(&TABLE3[3 * k], row);
    }
}

/// Largest distance of the inserted points' tips (Table 3) from the thirds
/// of the line between their neighbours' tips (Eqs 11–16), mm.
fn insertion_residual(m: &Machine) -> f64 {
    let mut worst: f64 = 0.0;
    for k in 0..4 {
        let pm = pose_of(m, &TABLE2[k]).tip;
        let pn = pose_of(m, &TABLE2[k + 1]).tip;
        let c1 = pose_of(m, &TABLE3[3 * k + 1]).tip;
        let c2 = pose_of(m, &TABLE3[3 * k + 2]).tip;
        worst = worst
            .max((c1 - (pm + (pn - pm) / 3.0)).norm())
            .max((c2 - (pm + (pn - pm) * 2.0 / 3.0)).norm());
    }
    worst
}

#[test]
fn table3_insertions_agree_with_the_chain() {
    // Angles of the inserted points follow Eqs (17)–(18): C11 = (B0, mid A),
    // C21 = (B1, mid A), to the table's 0.001° rounding.
    for k in 0..4 {
        let (m0, m1) = (TABLE2[k], TABLE2[k + 1]);
        let mid = 0.5 * (m0[4] + m1[4]);
        let (c1, c2) = (TABLE3[3 * k + 1], TABLE3[3 * k + 2]);
        assert_eq!(c1[3], m0[3]);
        assert_eq!(c2[3], m1[3]);
        assert!(
            (c1[4] - mid).abs() <= 0.0015 && (c2[4] - mid).abs() <= 0.0015,
            "{k}"
        );
    }
    // With L = 265 mm the inserted tips lie on the thirds to within the
    // tables' rounding (0.001 mm, 0.001°: about 2 µm at 265 mm).
    let r = insertion_residual(&wang_machine());
    assert!(r < 0.0015, "residual {r} mm");
}

fn variant(from: &str, to: &str) -> Machine {
    let text = include_str!("../../fixtures/machines/wang2023-xyzab.json");
    assert!(text.contains(from));
    Machine::from_json_str(&text.replace(from, to), "variant.json").unwrap()
}

#[test]
fn tables_pin_the_pivot_length_and_the_signs() {
    let best = insertion_residual(&wang_machine());
    // Another pivot length: the residual grows well beyond the rounding.
    for l in ["255", "275"] {
        let m = variant("265", l);
        let r = insertion_residual(&m);
        assert!(r > 10.0 * best && r > 0.015, "L = {l}: {r}");
    }
    // Either rotary turned the other way contradicts the tables.
    let flipped_a = variant("\"axis\": [-1, 0, 0]", "\"axis\": [1, 0, 0]");
    let flipped_b = variant(
        "\"name\": \"B\", \"axis\": [0, 1, 0]",
        "\"name\": \"B\", \"axis\": [0, -1, 0]",
    );
    assert!(insertion_residual(&flipped_a) > 0.04, "A flipped");
    assert!(insertion_residual(&flipped_b) > 0.5, "B flipped");
}
