//! Exact nonlinear error of a linearly interpolated block.
//!
//! While the controller interpolates every axis linearly from `qa` to `qb`
//! (`q(t) = qa + t·(qb − qa)`, `0 ≤ t ≤ 1`), the tool tip follows
//! `p(t) = FK(q(t))`, which leaves the straight line between the programmed
//! points `p(0)` and `p(1)` whenever a rotary axis moves. The nonlinear error
//! of the block is `max_t dist(p(t), [p(0), p(1)])`. It is computed here from
//! the chain itself (dense sampling, then golden-section refinement of every
//! candidate peak), not from the `r·Δθ²/8` estimate, which is also reported
//! for comparison.

use crate::machine::chain::{Chain, JointErrors, JointKind};
use nalgebra::Vector3;

/// The nonlinear error of one block.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NonlinearError {
    /// Largest distance of the tool tip from the straight segment, mm.
    pub max_mm: f64,
    /// Interpolation parameter (0…1) where the largest distance occurs.
    pub t_at_max: f64,
    /// The textbook estimate `sqrt(Σ (r_k·Δθ_k²/8)²)` over the rotary axes,
    /// with `r_k` the distance of the tool tip from rotary `k`'s axis line at
    /// mid-block, mm. Shown beside the exact value, never instead of it.
    pub estimate_mm: f64,
}

/// Distance from point `p` to the segment `[a, b]` (to `a` if the segment is degenerate).
pub fn point_segment_distance(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let d = b - a;
    let len2 = d.norm_squared();
    if len2 <= f64::MIN_POSITIVE {
        return (p - a).norm();
    }
    let t = ((p - a).dot(&d) / len2).clamp(0.0, 1.0);
    (a + d * t - p).norm()
}

/// Number of samples of the first pass. Two rotaries moving a few degrees
/// give at most a couple of peaks; 48 samples bracket each of them.
const SAMPLES: usize = 48;

/// Exact nonlinear error of the block `qa → qb` (chain order, internal units)
/// on the machine `chain` with `errors`.
pub fn nonlinear_error(
    chain: &Chain,
    errors: &dyn JointErrors,
    qa: &[f64],
    qb: &[f64],
) -> NonlinearError {
    let n = qa.len();
    let mut q = vec![0.0; n];
    let eval_q = |t: f64, q: &mut Vec<f64>| {
        for k in 0..n {
            q[k] = qa[k] + t * (qb[k] - qa[k]);
        }
    };
    let pa = chain.pose(qa, errors).tip;
    let pb = chain.pose(qb, errors).tip;
    let mut dist = |t: f64| {
        eval_q(t, &mut q);
        point_segment_distance(&chain.pose(&q, errors).tip, &pa, &pb)
    };

    let rotary_moves = chain
        .joints()
        .iter()
        .enumerate()
        .any(|(k, j)| j.kind == JointKind::Revolute && qa[k] != qb[k]);
    let estimate_mm = estimate(chain, errors, qa, qb);
    if !rotary_moves && errors_are_linear_free(errors) {
        // Only linear axes move on an error-free chain: the tip moves on a line.
        return NonlinearError {
            max_mm: 0.0,
            t_at_max: 0.5,
            estimate_mm,
        };
    }

    let samples: Vec<f64> = (0..=SAMPLES)
        .map(|i| dist(i as f64 / SAMPLES as f64))
        .collect();
    let mut best = (0.0, 0.5);
    for i in 1..SAMPLES {
        // Refine every local maximum of the samples.
        if samples[i] >= samples[i - 1] && samples[i] >= samples[i + 1] {
            let lo = (i - 1) as f64 / SAMPLES as f64;
            let hi = (i + 1) as f64 / SAMPLES as f64;
            // 55 steps shrink the bracket (1/24 wide) below 1e-12 in t.
            let (t, d) = crate::numeric::golden_section_max(&mut dist, lo, hi, 55);
            if d > best.0 {
                best = (d, t);
            }
        }
    }
    NonlinearError {
        max_mm: best.0,
        t_at_max: best.1,
        estimate_mm,
    }
}

fn errors_are_linear_free(errors: &dyn JointErrors) -> bool {
    errors.is_empty()
}

/// The `r·Δθ²/8` estimate (seed 003, Eqs. 26–27), combined over rotaries as
/// the root of the sum of squares.
fn estimate(chain: &Chain, errors: &dyn JointErrors, qa: &[f64], qb: &[f64]) -> f64 {
    let qm: Vec<f64> = qa.iter().zip(qb).map(|(a, b)| 0.5 * (a + b)).collect();
    let mut sum = 0.0;
    for (k, joint) in chain.joints().iter().enumerate() {
        if joint.kind != JointKind::Revolute || qa[k] == qb[k] {
            continue;
        }
        let r = tip_distance_from_axis(chain, errors, &qm, k);
        let dtheta = qb[k] - qa[k];
        let e = r * dtheta * dtheta / 8.0;
        sum += e * e;
    }
    sum.sqrt()
}

/// Distance of the tool tip from the axis line of revolute joint `k`, both in
/// the workpiece frame, at joint values `q`.
fn tip_distance_from_axis(chain: &Chain, errors: &dyn JointErrors, q: &[f64], k: usize) -> f64 {
    // The tip's motion under joint k alone: its velocity is ω × r, |ω| = 1,
    // so |d tip / d q_k| = distance from the axis line.
    let (_, jac) = chain.pose_and_jacobian(q, errors);
    Vector3::new(jac[(0, k)], jac[(1, k)], jac[(2, k)]).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::NoErrors;

    /// wang2023-xyzab exactly as kinematics.md gives it (the embedded fixture).
    fn wang() -> Chain {
        crate::machine::Machine::embedded("wang2023-xyzab")
            .expect("embedded machine")
            .chain
    }

    #[test]
    fn pure_head_swing_matches_circle_sagitta() {
        // Only B moves by Δ: the tip runs on a circle of radius L = 265 mm;
        // the chord's sagitta is L·(1 − cos(Δ/2)).
        let c = wang();
        let d = 2f64.to_radians();
        let e = nonlinear_error(
            &c,
            &NoErrors,
            &[0.0, 0.0, 0.0, 0.0, 0.0],
            &[0.0, 0.0, 0.0, 0.0, d],
        );
        let sagitta = 265.0 * (1.0 - (d / 2.0).cos());
        assert!(
            (e.max_mm - sagitta).abs() < 1e-12,
            "{} vs {}",
            e.max_mm,
            sagitta
        );
        assert!((e.t_at_max - 0.5).abs() < 1e-6);
        // The textbook estimate is the small-angle form of the same sagitta.
        assert!((e.estimate_mm - 265.0 * d * d / 8.0).abs() < 1e-9);
    }

    #[test]
    fn linear_only_block_has_no_nonlinear_error() {
        let c = wang();
        let e = nonlinear_error(
            &c,
            &NoErrors,
            &[0.1, 0.0, 0.0, 0.0, 0.2],
            &[0.1, 10.0, 5.0, -3.0, 0.2],
        );
        assert_eq!(e.max_mm, 0.0);
    }
}
