//! IK continuity and limits: rotaries unwound through 360°, the free rotary
//! kept at singular poses, the other branch taken when the nearest one
//! violates a limit, and errors when no branch is within the limits.

use crate::util::{wang_machine, zhao_machine};
use kinpost::machine::rotary::angle_diff;
use kinpost::machine::{IkError, IkSolver, Machine, NoErrors, Pose, RotaryMode, output_value};

/// Solves a sequence of poses block by block, each from the previous
/// solution (the first from `first_previous`).
fn sweep(
    m: &Machine,
    poses: &[Pose],
    first_previous: Option<Vec<f64>>,
) -> Vec<kinpost::machine::IkSolution> {
    let s = IkSolver::new(m);
    let mut prev = first_previous;
    poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let sol = s
                .solve(p, prev.as_deref())
                .unwrap_or_else(|e| panic!("{} block {k}: {e}", m.name));
            let reached = m.chain.pose(&sol.q, &NoErrors);
            assert!(
                reached.tip_distance(p) < 1e-9 && reached.axis_angle(p) < 1e-9,
                "{} block {k}",
                m.name
            );
            prev = Some(sol.q.to_vec());
            sol
        })
        .collect()
}

/// Poses of axis values (output order, file units).
fn poses(m: &Machine, values: &[Vec<f64>]) -> Vec<Pose> {
    values
        .iter()
        .map(|v| m.chain.pose(&m.to_internal(v), &NoErrors))
        .collect()
}

fn joint(m: &Machine, name: &str) -> usize {
    m.chain.joint_index(name).unwrap()
}

#[test]
fn continuous_c_is_unwound_through_360() {
    let m = Machine::embedded("xyzac-trt").unwrap();
    let values: Vec<Vec<f64>> = (0..=240)
        .map(|k| vec![30.0, -20.0, 10.0, 35.0, 300.0 + 0.5 * k as f64])
        .collect();
    let c = joint(&m, "C");
    // Continuing a program that is at C = 300°: the output runs on to 420°.
    let start = m.to_internal(&values[0]);
    let sols = sweep(&m, &poses(&m, &values), Some(start.to_vec()));
    for (k, s) in sols.iter().enumerate() {
        assert!(
            (s.q[c].to_degrees() - (300.0 + 0.5 * k as f64)).abs() < 1e-9,
            "block {k}"
        );
    }
    // From scratch the first block takes the principal value (−60°) and the
    // output is unwound from there: −60° … 60°, no jump anywhere.
    let sols = sweep(&m, &poses(&m, &values), None);
    assert!((sols[0].q[c].to_degrees() + 60.0).abs() < 1e-9);
    assert!((sols[240].q[c].to_degrees() - 60.0).abs() < 1e-9);
    for w in sols.windows(2) {
        assert!((w[1].q[c] - w[0].q[c]).abs() < 0.5f64.to_radians() + 1e-9);
    }
}

#[test]
fn continuous_a_of_wang2023_is_unwound_past_two_turns() {
    let m = wang_machine();
    let values: Vec<Vec<f64>> = (0..=400)
        .map(|k| vec![100.0, 5.0, -30.0, 20.0, 330.0 + 1.0 * k as f64])
        .collect();
    let a = joint(&m, "A");
    let sols = sweep(
        &m,
        &poses(&m, &values),
        Some(m.to_internal(&values[0]).to_vec()),
    );
    assert!((sols[400].q[a].to_degrees() - 730.0).abs() < 1e-9);
    for w in sols.windows(2) {
        assert!((w[1].q[a] - w[0].q[a] - 1f64.to_radians()).abs() < 1e-9);
    }
}

#[test]
fn modulo_c_takes_the_shortest_way_and_wraps_its_output() {
    let m = Machine::embedded("xyzbc-trt").unwrap();
    let values: Vec<Vec<f64>> = (0..=120)
        .map(|k| vec![10.0, 5.0, 0.0, 25.0, 330.0 + 0.5 * k as f64])
        .collect();
    let c = joint(&m, "C");
    let c_axis = m.axis("C").unwrap();
    assert_eq!(c_axis.rotary, RotaryMode::Modulo);
    let sols = sweep(&m, &poses(&m, &values), None);
    for (k, s) in sols.iter().enumerate() {
        let out = output_value(c_axis, s.q[c]);
        let want = (330.0 + 0.5 * k as f64) % 360.0;
        assert!((0.0..360.0).contains(&out));
        assert!((out - want).abs() < 1e-9, "block {k}: {out} vs {want}");
        assert_eq!(m.to_external(&s.q)[4], out);
    }
    for w in sols.windows(2) {
        assert!(angle_diff(w[1].q[c], w[0].q[c]).abs() < 0.5f64.to_radians() + 1e-9);
    }
}

/// Tilt sweeps through 0 on every machine whose singular pose is tilt 0:
/// the free rotary keeps its value exactly, the tilt runs on continuously
/// (changing sign: the nearest branch), and the singular block is flagged.
#[test]
fn tilt_through_zero_keeps_the_free_rotary() {
    for (name, tilt, free) in [
        ("xyzac-trt", "A", "C"),
        ("xyzbc-trt", "B", "C"),
        ("xyzac-head", "A", "C"),
        ("xyzbc-nutating", "B", "C"),
    ] {
        let m = Machine::embedded(name).unwrap();
        let (t_out, f_out) = (
            m.axes.iter().position(|a| a.name == tilt).unwrap(),
            m.axes.iter().position(|a| a.name == free).unwrap(),
        );
        let values: Vec<Vec<f64>> = (0..=64)
            .map(|k| {
                let mut v = vec![20.0, -10.0, 15.0, 0.0, 0.0];
                v[t_out] = 8.0 - 0.25 * k as f64; // exactly 0 at k = 32
                v[f_out] = 70.0;
                v
            })
            .collect();
        let sols = sweep(&m, &poses(&m, &values), None);
        let (tj, fj) = (joint(&m, tilt), joint(&m, free));
        for (k, s) in sols.iter().enumerate() {
            assert!(
                angle_diff(s.q[fj], 70f64.to_radians()).abs() < 1e-9,
                "{name} block {k}: {free} = {}",
                s.q[fj].to_degrees()
            );
            assert!(
                (s.q[tj].to_degrees() - (8.0 - 0.25 * k as f64)).abs() < 1e-9,
                "{name} block {k}: {tilt}"
            );
            assert_eq!(s.singular, k == 32, "{name} block {k}");
        }
    }
}

/// The same crossing with the free rotary moving: it holds its value at the
/// singular block and catches up at the next; nothing jumps by more than
/// two steps.
#[test]
fn tilt_through_zero_with_a_moving_rotary_does_not_jump() {
    let m = Machine::embedded("xyzac-head").unwrap();
    let values: Vec<Vec<f64>> = (0..=64)
        .map(|k| {
            vec![
                20.0,
                -10.0,
                15.0,
                8.0 - 0.25 * k as f64,
                40.0 + 0.5 * k as f64,
            ]
        })
        .collect();
    let sols = sweep(&m, &poses(&m, &values), None);
    let (a, c) = (joint(&m, "A"), joint(&m, "C"));
    assert!(
        (sols[32].q[c] - sols[31].q[c]).abs() < 1e-12,
        "C kept at the singular block"
    );
    for w in sols.windows(2) {
        assert!((w[1].q[c] - w[0].q[c]).abs() <= 1f64.to_radians() + 1e-9);
        assert!((w[1].q[a] - w[0].q[a]).abs() <= 0.25f64.to_radians() + 1e-9);
    }
    assert!((sols[64].q[c].to_degrees() - 72.0).abs() < 1e-9);
}

/// zhao2022: the tip crossing the C axis with the tool vertical (B = 0) is
/// the singular pose: C keeps its value; on either side the branch nearest
/// the previous block keeps C and lets X change sign.
#[test]
fn zhao_tip_crossing_the_c_axis_keeps_c() {
    let m = zhao_machine();
    let values: Vec<Vec<f64>> = (0..=40)
        .map(|k| vec![10.0 - 0.5 * k as f64, -3.0, 0.0, 50.0])
        .collect();
    let sols = sweep(&m, &poses(&m, &values), None);
    let (x, c) = (joint(&m, "X"), joint(&m, "C"));
    for (k, s) in sols.iter().enumerate() {
        assert!(
            (s.q[c].to_degrees() - 50.0).abs() < 1e-9,
            "block {k}: C = {}",
            s.q[c].to_degrees()
        );
        assert!((s.q[x] - (10.0 - 0.5 * k as f64)).abs() < 1e-9);
        assert_eq!(s.singular, k == 20);
    }
}

/// zhao2022 with the tool tilted: crossing the C axis, C comes from the tool
/// axis and does not jump.
#[test]
fn zhao_tilted_crossing_takes_c_from_the_tool_axis() {
    let m = zhao_machine();
    let b = 25f64;
    let values: Vec<Vec<f64>> = (0..=40)
        .map(|k| {
            let r = 10.0 - 0.5 * k as f64; // tip radius, 0 at k = 20
            vec![
                r + 20.0 * b.to_radians().sin(),
                -3.0,
                b,
                130.0 + 0.25 * k as f64,
            ]
        })
        .collect();
    let sols = sweep(
        &m,
        &poses(&m, &values),
        Some(m.to_internal(&values[0]).to_vec()),
    );
    let c = joint(&m, "C");
    for (k, s) in sols.iter().enumerate() {
        assert!(
            (s.q[c].to_degrees() - (130.0 + 0.25 * k as f64)).abs() < 1e-7,
            "block {k}: C = {}",
            s.q[c].to_degrees()
        );
        assert!(!s.singular);
    }
}

#[test]
fn nearest_branch_beyond_a_limit_takes_the_other_branch() {
    let m = Machine::embedded("xyzac-trt").unwrap(); // A −30 … 110
    let s = IkSolver::new(&m);
    let pose = m
        .chain
        .pose(&m.to_internal(&[10.0, 20.0, 5.0, 60.0, 0.0]), &NoErrors);
    let br = s.branches(&pose, None);
    assert_eq!(br.len(), 2);
    let (a, c) = (joint(&m, "A"), joint(&m, "C"));
    // The other branch tilts the other way: A = −60°, C = 180°.
    assert!(br.iter().any(|b| (b.q[a].to_degrees() + 60.0).abs() < 1e-9));
    // Previous block next to that branch: it is the nearest, but A = −60° is
    // beyond −30°, so the solver takes A = 60°, C = 0°.
    let prev = m.to_internal(&[10.0, 20.0, 5.0, -25.0, 175.0]);
    let sol = s.solve(&pose, Some(&prev)).unwrap();
    assert!((sol.q[a].to_degrees() - 60.0).abs() < 1e-9);
    assert!(angle_diff(sol.q[c], 0.0).abs() < 1e-9);
    // Within the limits the nearest branch wins: the same pose from a
    // previous block at A = 20°, C = 170° on a machine whose A allows −60°.
    let wide = Machine::from_json_str(
        &include_str!("../../fixtures/machines/xyzac-trt.json")
            .replace("\"min\": -30, \"max\": 110", "\"min\": -110, \"max\": 110"),
        "wide.json",
    )
    .unwrap();
    let sol = IkSolver::new(&wide)
        .solve(
            &pose,
            Some(&m.to_internal(&[10.0, 20.0, 5.0, -20.0, 170.0])),
        )
        .unwrap();
    assert!((sol.q[a].to_degrees() + 60.0).abs() < 1e-9);
    assert!((sol.q[c].to_degrees() - 180.0).abs() < 1e-9);
}

#[test]
fn wang2023_branch_beyond_b_limit_is_never_taken() {
    let m = wang_machine(); // B −90 … 90
    let s = IkSolver::new(&m);
    let q = m.to_internal(&[120.0, -5.0, -30.0, 40.0, 336.0]);
    let pose = m.chain.pose(&q, &NoErrors);
    // The other branch is (A + 180°, 180° − B) = B 140°.
    let b = joint(&m, "B");
    assert!(
        s.branches(&pose, None)
            .iter()
            .any(|x| (x.q[b].to_degrees() - 140.0).abs() < 1e-9)
    );
    let prev = m.to_internal(&[120.0, -5.0, -30.0, 89.0, 156.0]);
    let sol = s.solve(&pose, Some(&prev)).unwrap();
    assert!((sol.q[b].to_degrees() - 40.0).abs() < 1e-9);
}

#[test]
fn limited_multi_turn_rotary_picks_the_turn_within_limits() {
    let m = Machine::embedded("xyzac-head").unwrap(); // C −360 … 360
    let s = IkSolver::new(&m);
    let pose = m
        .chain
        .pose(&m.to_internal(&[0.0, 0.0, 0.0, 30.0, 10.0]), &NoErrors);
    let c = joint(&m, "C");
    let a = joint(&m, "A");
    // From C = 350° the nearest turn of this branch would be 370°, beyond
    // 360°; its turn within the limits, 10°, is 340° away, so the other
    // branch (A = −30°, C = 190°: 160° of C and 60° of A) is nearer.
    let from = m.to_internal(&[0.0, 0.0, 0.0, 30.0, 350.0]);
    let sol = s.solve(&pose, Some(&from)).unwrap();
    assert!(
        (sol.q[c].to_degrees() - 190.0).abs() < 1e-9 && (sol.q[a].to_degrees() + 30.0).abs() < 1e-9
    );
    let ten = s
        .branches(&pose, Some(&from))
        .into_iter()
        .find(|b| (b.q[a].to_degrees() - 30.0).abs() < 1e-9)
        .unwrap();
    assert!(
        (ten.q[c].to_degrees() - 10.0).abs() < 1e-9,
        "turn within the limits: {}",
        ten.q[c].to_degrees()
    );
    // From C = −340° the nearest turn −350° is within the limits.
    let sol = s
        .solve(&pose, Some(&m.to_internal(&[0.0, 0.0, 0.0, 30.0, -340.0])))
        .unwrap();
    assert!((sol.q[c].to_degrees() + 350.0).abs() < 1e-9);
}

#[test]
fn no_branch_within_limits_is_an_error_naming_the_axis() {
    let m = Machine::embedded("xyzac-trt").unwrap();
    let s = IkSolver::new(&m);
    // Tool axis tilted 120° from the table normal: A = ±120° both beyond −30 … 110.
    let a = 120f64.to_radians();
    let pose = Pose::new(
        nalgebra::Vector3::new(0.0, 0.0, 0.0),
        nalgebra::Vector3::new(0.0, a.sin(), a.cos()),
    );
    let err = s.solve(&pose, None).unwrap_err();
    match &err {
        IkError::Limit {
            axis,
            value,
            min,
            max,
            unit,
        } => {
            assert_eq!(axis, "A");
            assert!((value.abs() - 120.0).abs() < 1e-9, "{value}");
            assert_eq!((*min, *max, *unit), (-30.0, 110.0, "deg"));
        }
        e => panic!("unexpected {e:?}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("axis A") && msg.contains("deg") && msg.contains("-30 … 110"),
        "{msg}"
    );

    // A linear limit: zhao2022's X travel is ±100 mm.
    let m = zhao_machine();
    let pose = Pose::new(
        nalgebra::Vector3::new(150.0, 0.0, 0.0),
        nalgebra::Vector3::z(),
    );
    let err = IkSolver::new(&m).solve(&pose, None).unwrap_err();
    assert!(
        matches!(&err, IkError::Limit { axis, unit: "mm", .. } if axis == "X"),
        "{err}"
    );
    assert!(err.to_string().contains("150.000000 mm"), "{err}");
}

#[test]
fn malformed_poses_are_unreachable_not_panics() {
    for name in Machine::embedded_names() {
        let m = Machine::embedded(name).unwrap();
        let s = IkSolver::new(&m);
        for pose in [
            Pose {
                tip: nalgebra::Vector3::new(f64::NAN, 0.0, 0.0),
                axis: nalgebra::Vector3::z(),
            },
            Pose {
                tip: nalgebra::Vector3::zeros(),
                axis: nalgebra::Vector3::zeros(),
            },
            Pose {
                tip: nalgebra::Vector3::zeros(),
                axis: nalgebra::Vector3::new(f64::INFINITY, 0.0, 0.0),
            },
        ] {
            assert!(
                matches!(s.solve(&pose, None), Err(IkError::Unreachable { .. })),
                "{name}"
            );
            assert!(s.branches(&pose, None).is_empty());
        }
        // A previous block of the wrong length or with NaN is ignored.
        let pose = m.chain.pose(&vec![0.1; m.chain.dof()], &NoErrors);
        assert!(s.solve(&pose, Some(&[1.0])).is_ok(), "{name}");
        assert!(
            s.solve(&pose, Some(&vec![f64::NAN; m.chain.dof()])).is_ok(),
            "{name}"
        );
    }
}
