//! The Newton refinement of one pose: trust region, backtracking,
//! simplified Newton with a kept Jacobian, offsets from the theoretical
//! solution, and the best compensation within bounds at a singularity.

use super::step::{Factored, Method, Options, STEP_LINEAR_MM, STEP_ROTARY_RAD, residual, step_svd};
use crate::linalg::{MinNorm, RankCut};
use crate::machine::chain::{
    Chain, JacobianColumns, JointErrors, JointValues, MAX_JOINTS, NearTrig, NoErrors, Pose,
};
use nalgebra::{DMatrix, DVector, Vector3};

/// The result of refining one pose.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Refined {
    /// Joint values (chain order, mm / rad).
    pub q: JointValues,
    /// Newton iterations taken.
    pub iterations: usize,
    /// Remaining tool-tip error on the actual machine, mm.
    pub tip_residual_mm: f64,
    /// Remaining tool-axis error on the actual machine, rad.
    pub axis_residual_rad: f64,
    /// Whether the tip tolerance was reached (or the step became negligible).
    pub converged: bool,
    /// Not converged, but no move within the bounds reduces the tool-tip
    /// residual to first order: the pose is at (or next to) a singularity
    /// of the machine, where part of the error lies across every direction
    /// the machine can move the tip, and `q` is the best there is.
    pub best_within_bounds: bool,
    /// Tool-tip error at `q0` (where the refinement started), mm.
    pub start_tip_mm: f64,
    /// Tool-axis error at `q0`, rad.
    pub start_axis_rad: f64,
}

/// What a converged exact refinement leaves for a first-order estimate of
/// the pose near its result ([`super::written`]): the pose at the result,
/// and the Jacobian kept by the last steps with where it was evaluated.
#[derive(Debug, Clone, Copy)]
pub struct Linearization<'a> {
    /// The pose of the actual machine at `q0 + d`.
    pub pose: &'a Pose,
    /// The result's offsets from `q0` (mm / rad, chain order).
    pub d: &'a [f64],
    /// The Jacobian (tip rows mm, axis rows unit vector, per mm or per rad)
    /// the steps used.
    pub jacobian: &'a JacobianColumns,
    /// The offsets from `q0` where `jacobian` was evaluated.
    pub d_jacobian: &'a [f64],
}

/// The exact method keeps its Jacobian while every step shrinks the tool-tip
/// residual at least this many times: see [`refine`].
pub(super) const CHORD_GAIN: f64 = 1e3;

/// Steps on the joints not held back by their bounds after a refinement
/// that did not converge (see the end of [`refine`]).
pub(super) const POLISH_STEPS: usize = 8;

/// A step no larger than this (relative to `1 + |q|`, mm or rad) is taken to
/// be the last: see [`refine`].
pub(super) const FINAL_STEP: f64 = 1e-6;

/// Largest total compensation of a linear axis, mm: far above any geometric
/// error compensation (micrometres), low enough to stop a wandering iteration.
pub const MAX_COMPENSATION_MM: f64 = 0.5;
/// Largest total compensation of a rotary axis, rad (0.29°).
pub const MAX_COMPENSATION_RAD: f64 = 5e-3;

/// Refines joint values `q0` so that the actual machine (`chain` with
/// `errors`) puts the tool on `target`.
///
/// Safeguards: each step is scaled into a trust region (0.05 mm, 0.5 mrad
/// per axis), the axis part of the step is backtracked until it does not
/// make things worse, and the total compensation is bounded (0.5 mm, 5 mrad):
/// near the singular poses of a four-axis machine (the tool tip on the C
/// axis) a tangential tip error would need an unbounded turn of C, and the
/// refinement then stops with the best compensation within bounds
/// (`converged == false`).
///
/// The steps are computed on the stack (`Factored`: a closed-form Gram
/// solve for three or four joints, Householder QR of the 3×n and 6×n
/// problems otherwise, chains of at most [`MAX_JOINTS`] joints); a problem
/// whose matrices are ill-conditioned is solved with SVD pseudo-inverses
/// instead. With [`Method::Exact`] the Jacobian and its factorisation are
/// kept from step to step while each step shrinks the tool-tip residual at
/// least `CHORD_GAIN` times (simplified Newton; the trial points are then
/// evaluated without a Jacobian), and evaluated again where a step gains
/// less or fails; the other methods evaluate theirs at every step.
pub fn refine(
    chain: &Chain,
    errors: &dyn JointErrors,
    target: &Pose,
    q0: &[f64],
    opts: &Options,
) -> Refined {
    let near = (opts.method == Method::Exact).then(|| chain.trig_at(q0));
    FACTORS.with_borrow_mut(|factors| {
        refine_with(
            chain,
            errors,
            target,
            q0,
            opts,
            near.as_ref(),
            factors,
            None::<fn(&Linearization<'_>)>,
        )
        .0
    })
}

/// [`refine`] with the sines and cosines of the revolute joints at `q0`
/// given (`chain.trig_at(q0)`), for a caller that evaluates the chain near
/// `q0` again afterwards ([`super::written::written_residual`]; only the
/// exact method uses them); with the exact method, where it converged in
/// its Newton steps, `visit` is given what a first-order estimate near the
/// result needs ([`Linearization`]) and its answer returned.
pub fn refine_near_linearized<T>(
    chain: &Chain,
    errors: &dyn JointErrors,
    target: &Pose,
    q0: &[f64],
    opts: &Options,
    near: &NearTrig,
    visit: impl FnOnce(&Linearization<'_>) -> T,
) -> (Refined, Option<T>) {
    let near = (opts.method == Method::Exact).then_some(near);
    FACTORS.with_borrow_mut(|factors| {
        refine_with(chain, errors, target, q0, opts, near, factors, Some(visit))
    })
}

thread_local! {
    /// The factorisations of [`refine`], kept per thread (a few kB that
    /// would otherwise be cleared for every pose).
    static FACTORS: std::cell::RefCell<Factored> =
        const { std::cell::RefCell::new(Factored::EMPTY) };
}

/// [`refine`] with the caller's factorisation space, and `visit` given the
/// [`Linearization`] where the refinement converged in its steps.
#[allow(clippy::too_many_arguments)]
fn refine_with<T>(
    chain: &Chain,
    errors: &dyn JointErrors,
    target: &Pose,
    q0: &[f64],
    opts: &Options,
    near: Option<&NearTrig>,
    factors: &mut Factored,
    visit: Option<impl FnOnce(&Linearization<'_>) -> T>,
) -> (Refined, Option<T>) {
    let n = q0.len();
    assert!(
        n <= MAX_JOINTS && n == chain.dof(),
        "refine: {n} joint values for a chain of {} joints (at most {MAX_JOINTS})",
        chain.dof()
    );
    let mut step_cap = [0.0; MAX_JOINTS];
    let mut total_cap = [0.0; MAX_JOINTS];
    for (k, j) in chain.joints().iter().enumerate() {
        let revolute = j.kind == crate::machine::chain::JointKind::Revolute;
        step_cap[k] = if revolute {
            STEP_ROTARY_RAD
        } else {
            STEP_LINEAR_MM
        };
        total_cap[k] = if revolute {
            MAX_COMPENSATION_RAD
        } else {
            MAX_COMPENSATION_MM
        };
    }
    // The iteration moves the offsets `d` from `q0`, not the joint values
    // themselves: a rotary at thousands of degrees resolves its value to
    // 1e-14 rad or so, its offset to far below that. The exact method
    // takes its rotaries' sines and cosines at `q0 + d` from those at `q0`
    // by the addition theorem with the exact offsets
    // (`Chain::pose_at_offsets`), so large angles cost no precision; the
    // other methods evaluate at the rounded values, as printed.
    let at = |d: &[f64]| -> [f64; MAX_JOINTS] {
        let mut q = [0.0; MAX_JOINTS];
        for k in 0..n {
            q[k] = q0[k] + d[k];
        }
        q
    };
    let eval = |d: &[f64], jac: &mut JacobianColumns| -> Pose {
        let q = at(d);
        match (opts.method, near) {
            (Method::Exact, Some(near)) => {
                chain.pose_and_jacobian_at_offsets(&q[..n], errors, jac, near, d)
            }
            (Method::Exact, None) => chain.pose_and_jacobian_into(&q[..n], errors, jac),
            (Method::Theoretical | Method::Paper, _) => {
                chain.pose_and_jacobian_into(&q[..n], &NoErrors, jac);
                chain.pose(&q[..n], errors)
            }
        }
    };
    // The pose alone, where the Jacobian is not needed.
    let eval_pose = |d: &[f64]| -> Pose {
        let q = at(d);
        match near {
            Some(near) => chain.pose_at_offsets(&q[..n], errors, near, d),
            None => chain.pose(&q[..n], errors),
        }
    };
    // Offsets from q0 (mm / rad).
    let mut d = [0.0; MAX_JOINTS];
    let mut iterations = 0;
    let mut converged = false;
    let mut jac = [[0.0; 6]; MAX_JOINTS];
    let mut pose = eval(&d[..n], &mut jac);
    // Where `jac` was evaluated.
    let mut d_jac = d;
    // The residuals of `pose`, carried from step to step.
    let mut tip = pose.tip_distance(target);
    let mut ax = pose.axis_angle(target);
    let (start_tip, start_ax) = (tip, ax);
    factors.factor(&jac, n, opts, &step_cap);
    let mut trial = [0.0; MAX_JOINTS];
    let mut jac2 = [[0.0; 6]; MAX_JOINTS];
    // The exact method keeps its Jacobian while the steps contract fast
    // (simplified Newton): every trial is then evaluated without one.
    let chord = opts.method == Method::Exact;
    // The Jacobian was evaluated at the current joint values.
    let mut fresh = true;
    loop {
        let (rp, ro) = residual(target, &pose);
        if iterations >= opts.max_iterations {
            break;
        }
        let (d1, d2) = if factors.usable {
            factors.step(&rp, &ro)
        } else {
            step_svd(&jac, n, &rp, &ro, opts, &step_cap[..n])
        };
        // Trust region: scale the whole step so no axis moves too far.
        let mut scale = 1.0f64;
        for k in 0..n {
            let s = (d1[k] + d2[k]).abs();
            if s > step_cap[k] {
                scale = scale.min(step_cap[k] / s);
            }
        }
        // Already there: the tip is met and the step is at floating-point level.
        let negligible =
            (0..n).all(|k| (scale * (d1[k] + d2[k])).abs() <= 1e-14 * (1.0 + d[k].abs()));
        if negligible && (tip <= opts.tip_tolerance_mm || opts.method == Method::Paper) {
            converged = true;
            break;
        }
        // Backtrack the axis part until the move is no worse (tip first).
        let mut accepted = None;
        let mut s2 = 1.0;
        for _ in 0..12 {
            for k in 0..n {
                trial[k] = d[k] + scale * (d1[k] + s2 * d2[k]);
            }
            let within = (0..n).all(|k| trial[k].abs() <= total_cap[k]);
            if within {
                // After a step this small the next one is at floating-point
                // level (Newton: the residual goes with the step squared), so
                // the trial is most likely the result: its Jacobian is only
                // computed if another step turns out to be needed.
                let final_guess = (0..n)
                    .all(|k| (trial[k] - d[k]).abs() <= FINAL_STEP * (1.0 + (q0[k] + d[k]).abs()));
                let p2 = if chord || final_guess {
                    eval_pose(&trial[..n])
                } else {
                    eval(&trial[..n], &mut jac2)
                };
                let tip2 = p2.tip_distance(target);
                let ax2 = p2.axis_angle(target);
                // The paper's step is taken as printed (no safeguard but the bounds).
                let tip_ok = opts.method == Method::Paper
                    || tip2 <= tip.max(opts.tip_tolerance_mm) * (1.0 + 1e-9) + 1e-15;
                let ax_ok = opts.method == Method::Paper || ax2 <= ax + 1e-15 || tip2 < 0.5 * tip;
                if tip_ok && ax_ok {
                    accepted = Some((p2, tip2, ax2, !chord && !final_guess));
                    break;
                }
            }
            s2 *= 0.5;
        }
        let Some((p2, tip2, ax2, with_jacobian)) = accepted else {
            if chord && !fresh {
                // The kept Jacobian may be what fails: evaluate it here
                // and try again before giving up.
                pose = eval(&d[..n], &mut jac);
                d_jac = d;
                (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
                factors.factor(&jac, n, opts, &step_cap);
                fresh = true;
                continue;
            }
            // No step improves within the bounds: this is the best there is.
            converged = tip <= opts.tip_tolerance_mm;
            break;
        };
        iterations += 1;
        d[..n].copy_from_slice(&trial[..n]);
        pose = p2;
        if with_jacobian {
            std::mem::swap(&mut jac, &mut jac2);
            d_jac = d;
            factors.factor(&jac, n, opts, &step_cap);
        }
        let (last_tip, last_ax) = (tip, ax);
        (tip, ax) = (tip2, ax2);
        // Converged when the tip is met and neither the tip nor the axis
        // improves any more at floating-point level: the tip is at that
        // level, or it stopped improving.
        // Floating-point floor of the tip: a few ulps of the coordinates.
        let floor = 1e-14 * (1.0 + target.tip.amax());
        let tip_settled = tip2 <= opts.tip_tolerance_mm
            && (tip2 <= floor || last_tip - tip2 <= floor + 1e-9 * last_tip);
        let ax_settled = last_ax - ax2 <= 1e-15 + 1e-9 * last_ax;
        if opts.method == Method::Paper {
            if (last_tip - tip2).abs() <= floor + 1e-9 * last_tip
                && (last_ax - ax2).abs() <= 1e-15 + 1e-9 * last_ax
            {
                converged = true;
                break;
            }
        } else if tip_settled && ax_settled {
            converged = true;
            break;
        }
        if chord {
            // Keep the Jacobian while a step gains at least CHORD_GAIN on
            // the tip (or the tip is at its floor); otherwise evaluate it
            // where the iteration stands.
            fresh = false;
            if tip2 > floor && tip2 * CHORD_GAIN > last_tip {
                pose = eval(&d[..n], &mut jac);
                d_jac = d;
                (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
                factors.factor(&jac, n, opts, &step_cap);
                fresh = true;
            }
        } else if !with_jacobian {
            pose = eval(&d[..n], &mut jac);
            d_jac = d;
            (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
            factors.factor(&jac, n, opts, &step_cap);
        }
    }
    // Where it did not converge, the step was held back by the bounds of a
    // joint that would need an unbounded move (a four-axis machine's C with
    // the tip on or next to its axis). One last step on the other joints
    // removes what they can still remove of the tip residual. Where no
    // admissible move can then reduce it by more than the tip tolerance (to
    // first order), or removing it would take moves beyond the
    // compensation bounds (millimetres and radians for micrometres), this
    // is the best the machine can do here (`best_within_bounds`).
    // The pose and Jacobian describe the result only where the steps
    // converged on the actual machine (the polish below moves on without
    // them; the other methods' Jacobians are the theoretical machine's).
    let visited = match visit {
        Some(visit) if converged && opts.method == Method::Exact => Some(visit(&Linearization {
            pose: &pose,
            d: &d[..n],
            jacobian: &jac,
            d_jacobian: &d_jac[..n],
        })),
        _ => None,
    };
    let mut best_within_bounds = false;
    if !converged {
        let mut j = [[0.0; 6]; MAX_JOINTS];
        for pass in 0..POLISH_STEPS + 1 {
            let p = eval(&d[..n], &mut j);
            let r = target.tip - p.tip;
            let rn = r.norm();
            let column = |k: usize| Vector3::new(j[k][0], j[k][1], j[k][2]);
            // Joints that can still help: they move the tip, and removing
            // the residual's component along them fits within their bound.
            let free: Vec<usize> = (0..n)
                .filter(|&k| {
                    let c = column(k);
                    let cn2 = c.norm_squared();
                    cn2 > 0.0 && c.dot(&r).abs() / cn2 <= total_cap[k] - d[k].abs()
                })
                .collect();
            // What the free joints can still remove, to first order: the
            // residual's projection on the directions they move the tip.
            let jf = DMatrix::from_fn(3, free.len(), |row, c| j[free[c]][row]);
            let rv = DVector::from_column_slice(r.as_slice());
            let step = if free.is_empty() {
                None
            } else {
                polish_step(&jf, &rv)
            };
            let removable = step.as_ref().map_or(0.0, |s| (&jf * s).norm());
            let gain = rn - (rn * rn - removable * removable).max(0.0).sqrt();
            // Stuck when no admissible move gains the tip tolerance.
            let stuck = gain <= opts.tip_tolerance_mm.max(1e-14 * (1.0 + target.tip.amax()));
            let Some(step) = step.filter(|_| !stuck && pass < POLISH_STEPS) else {
                best_within_bounds = stuck;
                break;
            };
            let mut trial = d;
            for (c, &k) in free.iter().enumerate() {
                trial[k] += step[c];
            }
            // A step beyond the bounds (millimetres and radians for a few
            // micrometres: the machine is singular there), or one that
            // gains nothing, leaves this the best there is.
            if (0..n).any(|k| trial[k].abs() > total_cap[k]) {
                best_within_bounds = true;
                break;
            }
            let p2 = eval_pose(&trial[..n]);
            let tip2 = p2.tip_distance(target);
            if tip2 >= tip {
                best_within_bounds = true;
                break;
            }
            d = trial;
            (tip, ax) = (tip2, p2.axis_angle(target));
            converged = tip <= opts.tip_tolerance_mm;
            if converged {
                break;
            }
        }
    }
    let q = at(&d[..n]);
    let refined = Refined {
        tip_residual_mm: tip,
        axis_residual_rad: ax,
        start_tip_mm: start_tip,
        start_axis_rad: start_ax,
        q: q[..n].iter().copied().collect(),
        iterations,
        converged,
        best_within_bounds,
    };
    (refined, visited)
}

/// The polish step: the minimum-norm least-squares solution of `jf δ = r`
/// (`jf` the tip columns of the free joints, mm per mm or rad; `r` the tip
/// residual, mm), with what is left below [`rank::TIP_SYSTEM_MM`] counted
/// as zero. `jf` is typically rank-deficient here (the non-convergence
/// comes from a singular pose), so not by nalgebra's SVD, whose solve can
/// then miss by per cents ([`MinNorm`]): `|jf δ|` decides whether the
/// result is reported as the best within bounds.
///
/// [`rank::TIP_SYSTEM_MM`]: crate::linalg::rank::TIP_SYSTEM_MM
fn polish_step(jf: &DMatrix<f64>, r: &DVector<f64>) -> Option<DVector<f64>> {
    let cut = RankCut::Absolute(crate::linalg::rank::TIP_SYSTEM_MM);
    Some(MinNorm::new(jf, cut)?.solve(r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::ErrorMotion;

    /// The polish step on rank-2 tip columns of four free joints `jf = B C`
    /// (a singular pose): the minimum-norm least-squares step `jf⁺ r`, and
    /// what it removes of the residual, `|jf δ|` = the length of the
    /// projection of `r` on the range of `B`. nalgebra's SVD solve missed
    /// the step by 2.7 % here. The references come from the factors (LU of
    /// the 2 × 2 Gram matrices).
    #[test]
    fn polish_step_at_a_singular_pose_is_the_minimum_norm_step() {
        let b = DMatrix::from_row_slice(3, 2, &[-1.0, 1.0, -4.0, 0.0, 5.0, -6.0]);
        let c = DMatrix::from_row_slice(2, 4, &[0.2, -0.4, 0.1, -0.3, 0.1, -0.4, 0.3, -0.2]);
        let jf = &b * &c;
        let r = DVector::from_vec(vec![1e-3, -2e-3, 5e-4]);
        let step = polish_step(&jf, &r).unwrap();
        let b_pinv = crate::test_support::left_inverse(&b);
        let reference = crate::test_support::right_inverse(&c) * &b_pinv * &r;
        let miss = (&step - &reference).norm() / reference.norm();
        assert!(miss < 1e-12, "the step misses jf⁺ r by {miss:e}");
        let removable = (&b * &b_pinv * &r).norm();
        assert!(((&jf * &step).norm() - removable).abs() < 1e-12 * removable);
    }

    fn zhao() -> Chain {
        crate::machine::Machine::embedded("zhao2022-xzbc")
            .expect("embedded fixture")
            .chain
    }

    /// Micrometre-sized smooth errors on X, Z and B (C unmeasured).
    struct Small;
    impl JointErrors for Small {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            match joint {
                1 | 2 => Some(ErrorMotion::new(
                    2e-3 * (q / 60.0).sin(),
                    1e-3 * (q / 40.0).cos(),
                    1.5e-3 * (q / 50.0).sin(),
                    0.0,
                    3e-6 * (q / 70.0).cos(),
                    2e-6 * (q / 30.0).sin(),
                )),
                3 => Some(ErrorMotion::new(
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    5e-6 * (2.0 * q).sin(),
                    0.0,
                )),
                _ => None,
            }
        }
    }

    #[test]
    fn tip_met_exactly_and_axis_optimal_on_four_axis_machine() {
        let c = zhao();
        // A pose on the theoretical machine's cone.
        let q_th = [0.7, 35.0, -12.0, 0.4];
        let target = c.pose(&q_th, &NoErrors);
        let before = c.pose(&q_th, &Small);
        assert!(before.tip_distance(&target) > 1e-3);
        let exact = refine(&c, &Small, &target, &q_th, &Options::default());
        let theo = refine(
            &c,
            &Small,
            &target,
            &q_th,
            &Options {
                method: Method::Theoretical,
                ..Options::default()
            },
        );
        for r in [&exact, &theo] {
            assert!(r.converged);
            assert!(r.tip_residual_mm < 1e-12, "{}", r.tip_residual_mm);
        }
        assert!((exact.axis_residual_rad - theo.axis_residual_rad).abs() < 1e-12);
        assert!(exact.iterations <= theo.iterations);
        // The axis is optimal along the one-parameter family of joint values
        // that meet the tip: fix B a little off and re-meet the tip with X, Z, C.
        for db in [-1e-4, -1e-5, 1e-5, 1e-4] {
            let mut q = exact.q.clone();
            q[3] += db;
            for _ in 0..20 {
                let (p, j) = c.pose_and_jacobian(&q, &Small);
                let r = target.tip - p.tip;
                let m = nalgebra::Matrix3::from_fn(|row, col| j[(row, [0, 1, 2][col])]);
                let d = m.lu().solve(&r).unwrap();
                for (k, dk) in [0, 1, 2].iter().zip(d.iter()) {
                    q[*k] += dk;
                }
            }
            let p = c.pose(&q, &Small);
            assert!(p.tip_distance(&target) < 1e-12);
            assert!(
                p.axis_angle(&target) >= exact.axis_residual_rad - 1e-13,
                "db {db}"
            );
        }
    }

    #[test]
    fn paper_method_trades_tip_for_axis_when_axis_unreachable() {
        let c = zhao();
        let q_th = [0.7, 35.0, -12.0, 0.4];
        let target = c.pose(&q_th, &NoErrors);
        let paper = refine(
            &c,
            &Small,
            &target,
            &q_th,
            &Options {
                method: Method::Paper,
                ..Options::default()
            },
        );
        // Least squares on mixed mm and rad: the tip is not met to nanometres.
        assert!(paper.tip_residual_mm > 1e-7, "{}", paper.tip_residual_mm);
        assert!(paper.tip_residual_mm < 1e-3);
    }
}
