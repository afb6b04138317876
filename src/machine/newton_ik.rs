//! Damped-Newton (Levenberg–Marquardt) inverse kinematics for chains no
//! analytic solver recognises.
//!
//! Works on [`Chain::pose_and_jacobian`], the same evaluator as everything
//! else:
//!
//! 1. Levenberg–Marquardt on the weighted residual
//!    `[tip* − tip; w · (axis* − axis)]` with `w` = [`NewtonOptions::axis_weight_mm`]
//!    (mm per unit of axis-vector difference, small: the tip counts much more
//!    than the axis). Each step solves the damped least-squares problem on
//!    the augmented matrix `[J_w; √μ·D]` (no normal equations) by a
//!    rank-revealing orthogonal factorisation (`linalg::MinNorm`).
//! 2. Every trial point (and the start) first has its tip restored by a few
//!    minimum-norm Newton steps on the tip alone. The tip is thus met
//!    exactly even when the tool axis cannot be, and the steps follow the
//!    curved set of tip-exact joint values (plain LM with such unequal
//!    weights crawls along it).
//!
//! Joint limits are kept: a step that would cross a bound moves that joint
//! onto it and is recomputed for the others.
//!
//! It starts from the previous block's solution (or a neutral guess) and so
//! finds the solution nearest to it; it does not enumerate branches.

use super::chain::{Chain, NoErrors, Pose};
use super::ik_error::IkError;
use crate::linalg::{MinNorm, RankCut};
use nalgebra::{DMatrix, DVector};

/// Settings of the damped-Newton solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOptions {
    /// Largest number of Levenberg–Marquardt iterations.
    pub max_iterations: usize,
    /// Weight of the tool-axis residual, mm per unit of axis-vector difference
    /// (1e-3: an axis error of 1 rad counts like a tip error of 1 µm).
    pub axis_weight_mm: f64,
    /// Largest tip residual accepted, mm; beyond it the solve fails with
    /// [`IkError::NotConverged`].
    pub tip_tolerance_mm: f64,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        NewtonOptions {
            max_iterations: 200,
            axis_weight_mm: 1e-3,
            tip_tolerance_mm: 1e-8,
        }
    }
}

/// Result of a damped-Newton solve.
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonResult {
    /// Joint values, chain order, mm and rad.
    pub q: Vec<f64>,
    /// Iterations used (both phases).
    pub iterations: usize,
    /// Remaining tip distance, mm.
    pub tip_residual_mm: f64,
    /// Remaining angle between the tool axes, rad.
    pub axis_residual_rad: f64,
}

fn residual(chain: &Chain, q: &[f64], target: &Pose, w: f64) -> (DVector<f64>, DMatrix<f64>) {
    let (p, j) = chain.pose_and_jacobian(q, &NoErrors);
    let n = q.len();
    let mut r = DVector::zeros(6);
    let mut jw = DMatrix::zeros(6, n);
    for i in 0..3 {
        r[i] = target.tip[i] - p.tip[i];
        r[i + 3] = w * (target.axis[i] - p.axis[i]);
        for k in 0..n {
            jw[(i, k)] = j[(i, k)];
            jw[(i + 3, k)] = w * j[(i + 3, k)];
        }
    }
    (r, jw)
}

/// Clamps every joint of `q` into its bounds.
fn project(q: &mut DVector<f64>, bounds: &[(f64, f64)]) {
    for (v, (lo, hi)) in q.iter_mut().zip(bounds) {
        if lo <= hi {
            *v = v.clamp(*lo, *hi);
        }
    }
}

/// Minimum-norm Newton steps on the tip alone (at most 10): brings the tip
/// onto the target with the smallest joint motion, within `bounds`.
fn restore_tip(
    chain: &Chain,
    target: &Pose,
    mut q: DVector<f64>,
    bounds: &[(f64, f64)],
    iterations: &mut usize,
) -> DVector<f64> {
    let n = q.len();
    for _ in 0..10 {
        let (p, j) = chain.pose_and_jacobian(q.as_slice(), &NoErrors);
        let rt = target.tip - p.tip;
        if rt.norm() < 1e-13 {
            break;
        }
        *iterations += 1;
        let jt = DMatrix::from_fn(3, n, |i, k| j[(i, k)]);
        let rt = DVector::from_column_slice(rt.as_slice());
        let Some(step) = bounded_step(
            &jt,
            &rt,
            &vec![0.0; n],
            &q,
            bounds,
            crate::linalg::rank::TIP_SYSTEM_MM,
        ) else {
            break;
        };
        let mut q_new = &q + &step;
        project(&mut q_new, bounds);
        let p_new = chain.pose(q_new.as_slice(), &NoErrors);
        if (target.tip - p_new.tip).norm() >= rt.norm() {
            break;
        }
        q = q_new;
    }
    q
}

/// One damped least-squares step `min |J·δ − r|² + Σ (d_k δ_k)²` that keeps
/// `q + δ` within `bounds`: a joint whose step would cross its bound is
/// moved exactly onto it and the step is recomputed for the others (a small
/// active-set loop). Solved as the minimum-norm least squares of the
/// augmented matrix by a rank-revealing orthogonal factorisation
/// ([`MinNorm`]); what is left below `eps` counts as zero (minimum-norm
/// steps for redundant chains).
fn bounded_step(
    jac: &DMatrix<f64>,
    rhs: &DVector<f64>,
    damping: &[f64],
    q: &DVector<f64>,
    bounds: &[(f64, f64)],
    eps: f64,
) -> Option<DVector<f64>> {
    let (m, n) = jac.shape();
    let mut pinned: Vec<Option<f64>> = vec![None; n];
    for _ in 0..=n {
        let mut a = DMatrix::zeros(m + n, n);
        let mut b = DVector::zeros(m + n);
        b.rows_mut(0, m).copy_from(rhs);
        for k in 0..n {
            match pinned[k] {
                None => {
                    a.view_mut((0, k), (m, 1)).copy_from(&jac.column(k));
                    a[(m + k, k)] = damping[k];
                }
                Some(delta) => {
                    let col = jac.column(k) * delta;
                    let mut top = b.rows_mut(0, m);
                    top -= col;
                    a[(m + k, k)] = 1.0;
                    b[m + k] = delta;
                }
            }
        }
        // Not nalgebra's SVD: with zero damping the augmented matrix is
        // rank-deficient, where its solve can miss by per cents
        // (`linalg::MinNorm`).
        let step = MinNorm::new(&a, RankCut::Absolute(eps))?.solve(&b);
        let mut changed = false;
        for k in 0..n {
            let Some(&(lo, hi)) = bounds.get(k) else {
                continue;
            };
            let v = q[k] + step[k];
            if pinned[k].is_none() && lo <= hi && (v < lo || v > hi) {
                pinned[k] = Some(v.clamp(lo, hi) - q[k]);
                changed = true;
            }
        }
        if !changed {
            return Some(step);
        }
    }
    None
}

/// Solves `chain.pose(q) = target` from `start` (chain order, internal
/// units), keeping every joint within `bounds` (`(lo, hi)` per joint,
/// internal units; infinite for none): each step is projected onto them.
pub fn solve(
    chain: &Chain,
    target: &Pose,
    start: &[f64],
    bounds: &[(f64, f64)],
    opts: &NewtonOptions,
) -> Result<NewtonResult, IkError> {
    let n = chain.dof();
    if start.len() != n || start.iter().any(|v| !v.is_finite()) {
        return Err(IkError::Unreachable {
            reason: format!("Newton start must have {n} finite joint values"),
        });
    }
    let target = Pose::new(target.tip, target.axis);
    let w = opts.axis_weight_mm;
    let mut iterations = 0;
    let mut q = DVector::from_column_slice(start);
    project(&mut q, bounds);
    let mut q = restore_tip(chain, &target, q, bounds, &mut iterations);
    let (mut r, mut jw) = residual(chain, q.as_slice(), &target, w);
    let mut cost = r.norm_squared();
    let mut mu: f64 = 1e-3;
    // Levenberg–Marquardt on the weighted residual; every trial point has its
    // tip restored before it is judged, so that the steps follow the curved
    // set of tip-exact joint values instead of crawling along it.
    let mut lm_iterations = 0;
    while lm_iterations < opts.max_iterations {
        lm_iterations += 1;
        // Marquardt scaling: column norms of J_w (floored so that a joint
        // that does nothing at this pose still gets some damping).
        let damping: Vec<f64> = (0..n)
            .map(|k| mu.sqrt() * jw.column(k).norm().max(1e-9))
            .collect();
        let Some(step) = bounded_step(
            &jw,
            &r,
            &damping,
            &q,
            bounds,
            crate::linalg::rank::DAMPED_FLOOR,
        ) else {
            break;
        };
        let mut trial = &q + &step;
        project(&mut trial, bounds);
        let trial = restore_tip(chain, &target, trial, bounds, &mut iterations);
        let (r_new, jw_new) = residual(chain, trial.as_slice(), &target, w);
        let cost_new = r_new.norm_squared();
        if cost_new.is_finite() && cost_new <= cost {
            let moved = (&trial - &q).norm();
            let small_step = moved <= 1e-15 * (1.0 + q.norm());
            let small_gain = cost - cost_new <= 1e-30 + 1e-16 * cost;
            q = trial;
            r = r_new;
            jw = jw_new;
            cost = cost_new;
            mu = (mu / 3.0).max(1e-12);
            if small_step || small_gain || cost < 1e-30 {
                break;
            }
        } else {
            mu *= 4.0;
            if mu > 1e12 {
                break;
            }
        }
    }
    iterations += lm_iterations;
    let p = chain.pose(q.as_slice(), &NoErrors);
    let tip_residual_mm = p.tip_distance(&target);
    let axis_residual_rad = p.axis_angle(&target);
    if tip_residual_mm.is_nan() || tip_residual_mm > opts.tip_tolerance_mm {
        return Err(IkError::NotConverged {
            iterations,
            tip_residual_mm,
            axis_residual_rad,
        });
    }
    Ok(NewtonResult {
        q: q.as_slice().to_vec(),
        iterations,
        tip_residual_mm,
        axis_residual_rad,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tip step of `restore_tip` (no damping, no bound reached) on a
    /// rank-2 tip Jacobian `J = B C` (a singular pose of a three-joint
    /// chain): the minimum-norm least-squares step `J⁺ r`. nalgebra's SVD
    /// solve missed it by 6 % here; the reference is `C⁺ B⁺ r` from the
    /// factors (LU of the 2 × 2 Gram matrices).
    #[test]
    fn undamped_step_at_a_singular_pose_is_the_minimum_norm_step() {
        let b = DMatrix::from_row_slice(3, 2, &[-7.0, 7.0, -3.0, -7.0, -7.0, -6.0]);
        let c = DMatrix::from_row_slice(2, 3, &[0.6, -0.9, -0.1, -0.4, -0.1, 0.8]);
        let jac = &b * &c;
        let r = DVector::from_vec(vec![1.0, -2.0, 0.5]);
        let free = [(f64::NEG_INFINITY, f64::INFINITY); 3];
        let q = DVector::zeros(3);
        let step = bounded_step(
            &jac,
            &r,
            &[0.0; 3],
            &q,
            &free,
            crate::linalg::rank::TIP_SYSTEM_MM,
        )
        .unwrap();
        let reference =
            crate::test_support::right_inverse(&c) * crate::test_support::left_inverse(&b) * &r;
        let miss = (&step - &reference).norm() / reference.norm();
        assert!(miss < 1e-12, "the step misses J⁺ r by {miss:e}");
    }
}
