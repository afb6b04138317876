//! Compensation stays well-behaved everywhere in the work space, including
//! near the singular poses of a four-axis machine (tool tip on the C axis,
//! tool axis along C): it converges, meets the tip, and the compensation
//! stays of the size of the errors.

use crate::util::zhao_machine;
use kinpost::compensate::{Method, Options, refine};
use kinpost::geometric::model::ErrorModel;
use kinpost::geometric::synth::SplitMix64;
use kinpost::machine::{IkSolver, Machine, NoErrors};
use std::path::Path;

fn check_machine(name: &str, errors: &str, sample: impl Fn(&mut SplitMix64) -> Vec<f64>) {
    let machine = Machine::embedded(name).unwrap();
    let model = ErrorModel::load(Path::new(&format!(
        "{}/fixtures/errors/{errors}",
        env!("CARGO_MANIFEST_DIR")
    )))
    .unwrap();
    let bound = model.bind(&machine.chain).unwrap();
    let actual = model.apply_fixed(&machine.chain).unwrap();
    let ik = IkSolver::new(&machine);
    let mut rng = SplitMix64::new(7);
    let mut worst_iter = 0;
    let mut near_singular = 0;
    for i in 0..400 {
        let ext = sample(&mut rng);
        let q0 = machine.to_internal(&ext);
        let target = machine.chain.pose(&q0, &NoErrors);
        let q_th = ik.solve(&target, Some(&q0)).unwrap().q;
        let before = actual.pose(&q_th, &bound).tip_distance(&target);
        // Distance of the tool tip from the first rotary's axis line (the C
        // axis of a lens machine): near it a four-axis machine cannot move the
        // tip sideways without an unbounded turn.
        let (_, j) = machine.chain.pose_and_jacobian(&q_th, &NoErrors);
        let lever = nalgebra::Vector3::new(j[(0, 0)], j[(1, 0)], j[(2, 0)]).norm();
        for method in [Method::Exact, Method::Theoretical] {
            let r = refine(
                &actual,
                &bound,
                &target,
                &q_th,
                &Options {
                    method,
                    ..Options::default()
                },
            );
            if r.converged {
                assert!(
                    r.tip_residual_mm < 1e-10,
                    "{name} sample {i} {ext:?}: tip {:e}",
                    r.tip_residual_mm
                );
                worst_iter = worst_iter.max(r.iterations);
            } else {
                // Only where the machine is near singular, and never worse.
                assert!(
                    lever < 1.0,
                    "{name} sample {i} {ext:?} {method:?}: not converged ({} it, tip {:e}), lever {lever} mm",
                    r.iterations,
                    r.tip_residual_mm
                );
                assert!(
                    r.tip_residual_mm <= before,
                    "{name} sample {i}: worse than uncompensated"
                );
                // And the refinement knows it stopped at the best there is.
                assert!(
                    r.best_within_bounds,
                    "{name} sample {i} {ext:?} {method:?}: not converged (tip {:e}, lever {lever} mm) but not at its best",
                    r.tip_residual_mm
                );
                near_singular += 1;
            }
            for (k, (a, b)) in r.q.iter().zip(&q_th).enumerate() {
                assert!(
                    (a - b).abs() < 0.05,
                    "{name} sample {i} {ext:?}: joint {k} moved {} from the IK",
                    a - b
                );
            }
        }
    }
    eprintln!(
        "{name}: worst iterations {worst_iter}; {near_singular} near-singular runs left a tangential residual"
    );
}

#[test]
fn zhao2022_everywhere_including_the_c_axis() {
    check_machine("zhao2022-xzbc", "zhao2022-xzbc.csv", |rng| {
        let b = -60.0 + 120.0 * rng.uniform();
        // Half of the samples put the tool tip within 0.5 mm of the C axis.
        let x = if rng.uniform() < 0.5 {
            20.0 * b.to_radians().sin() + (rng.uniform() - 0.5)
        } else {
            -80.0 + 160.0 * rng.uniform()
        };
        let b = if rng.uniform() < 0.1 { 0.0 } else { b };
        vec![
            x,
            -50.0 + 100.0 * rng.uniform(),
            b,
            -180.0 + 360.0 * rng.uniform(),
        ]
    });
}

#[test]
fn wang2023_everywhere_including_tilt_zero() {
    check_machine("wang2023-xyzab", "wang2023-xyzab.csv", |rng| {
        let b = if rng.uniform() < 0.2 {
            0.0
        } else {
            -80.0 + 160.0 * rng.uniform()
        };
        vec![
            100.0 + 800.0 * rng.uniform(),
            -250.0 + 500.0 * rng.uniform(),
            -450.0 + 400.0 * rng.uniform(),
            b,
            -180.0 + 360.0 * rng.uniform(),
        ]
    });
}

/// A rotary that keeps turning one way: the compensation of a pose at C +
/// k·360° is that of the pose at C, to floating-point level, for thousands
/// of turns. Before, the refinement iterated on the joint values, whose
/// resolution at C = 7,350° (1e-14 rad, 1e-12 mm at 80 mm) is coarser than
/// its convergence floor: `compensate` failed there with a 1e-12 mm residual.
#[test]
fn many_turns_one_way_cost_no_precision() {
    let machine = zhao_machine();
    let model = ErrorModel::load(Path::new(&format!(
        "{}/fixtures/errors/zhao2022-xzbc.csv",
        env!("CARGO_MANIFEST_DIR")
    )))
    .unwrap();
    let bound = model.bind(&machine.chain).unwrap();
    let actual = model.apply_fixed(&machine.chain).unwrap();
    let c = machine.chain.joints().len() - 1; // X Z B C: C is the last joint
    let mut rng = SplitMix64::new(11);
    for i in 0..60 {
        let ext = [
            40.0 + 40.0 * rng.uniform(),
            -20.0 + 40.0 * rng.uniform(),
            -40.0 + 80.0 * rng.uniform(),
            -180.0 + 360.0 * rng.uniform(),
        ];
        let q_base = machine.to_internal(&ext);
        let target = machine.chain.pose(&q_base, &NoErrors);
        let base = refine(&actual, &bound, &target, &q_base, &Options::default());
        assert!(base.converged, "sample {i}");
        for turns in [20.0, -20.0, 300.0, -1000.0] {
            let mut q_th = q_base.clone();
            q_th[c] += turns * std::f64::consts::TAU;
            let r = refine(&actual, &bound, &target, &q_th, &Options::default());
            assert!(
                r.converged,
                "sample {i}, {turns} turns: tip {:e}",
                r.tip_residual_mm
            );
            assert!(
                r.tip_residual_mm < 1e-12,
                "sample {i}, {turns} turns: tip {:e}",
                r.tip_residual_mm
            );
            for k in 0..q_th.len() {
                let (a, b) = (r.q[k] - q_th[k], base.q[k] - q_base[k]);
                // The offsets agree to the resolution of the written values.
                let resolution = 4.0 * f64::EPSILON * q_th[k].abs().max(1.0);
                assert!(
                    (a - b).abs() <= resolution + 1e-13,
                    "sample {i}, {turns} turns, joint {k}: offset {a:e} against {b:e}"
                );
            }
        }
    }
}
