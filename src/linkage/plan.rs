//! Planning the points inserted into one block.
//!
//! Every inserted point has its tool tip on the straight line between the
//! programmed tips of the block, and chosen rotary values; its linear axes
//! come from the machine's inverse kinematics for those rotary values
//! ([`solve_linears`], on the same chain evaluator).
//!
//! Patterns:
//! - **Staggered** (five-axis block to four-axis linkage): the *split* rotary
//!   (by default the one nearer the workpiece, seed 003's table axis A) moves
//!   in two half steps around full steps of the *held* rotary (seed 003's B):
//!   `a+Δa/2m, b+Δb/m, a+Δa/m, …, b+Δb/m, a+Δa/2m` — `2m+1` segments, each
//!   moving one rotary only. `m = 1` is seed 003's Equations (17)–(18) and the
//!   order of its Table 3. Tool tips are evenly spaced: `i / (2m+1)`.
//! - **Even** (linearisation): `k` segments, every axis at fraction `i/k`.

use super::nonlinear::{NonlinearError, nonlinear_error};
use crate::machine::chain::{Chain, JointErrors, JointKind};
use nalgebra::{DMatrix, DVector, Vector3};

/// How a block is divided.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Staggered rotary moves with `m` steps of the held rotary (`2m` inserted points).
    Staggered {
        /// Steps of the held rotary.
        m: usize,
    },
    /// `k` equal segments (`k − 1` inserted points).
    Even {
        /// Segments.
        k: usize,
    },
}

impl Pattern {
    /// Number of inserted points.
    pub fn inserted(&self) -> usize {
        match *self {
            Pattern::Staggered { m } => 2 * m,
            Pattern::Even { k } => k.saturating_sub(1),
        }
    }
}

/// The two rotaries of a five-axis staggered pattern (joint indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RotaryPair {
    /// Moves in halves at both ends (seed 003's A).
    pub split: usize,
    /// Held at first, then moved in full steps (seed 003's B).
    pub held: usize,
}

impl RotaryPair {
    /// The default pair of a chain with two revolute joints: the one nearer
    /// the workpiece is split, the one nearer the tool is held.
    pub fn default_for(chain: &Chain) -> Option<RotaryPair> {
        let r: Vec<usize> = (0..chain.dof())
            .filter(|&j| chain.joints()[j].kind == JointKind::Revolute)
            .collect();
        (r.len() == 2).then(|| RotaryPair {
            split: r[0],
            held: r[1],
        })
    }
}

/// Solves the linear axes of `q` (rotaries kept) so that the tool tip lands
/// on `tip`, by Newton steps on the prismatic columns of the Jacobian
/// (exact after one step on an error-free chain, where the tip is affine in
/// the linear axes).
///
/// A machine with fewer than three linear axes (a lens machine's X Z B C)
/// cannot place the tip with its linear axes alone: there every joint takes
/// part, and the step is the least-norm change from the values given.
pub fn solve_linears(
    chain: &Chain,
    errors: &dyn JointErrors,
    q: &mut [f64],
    tip: &Vector3<f64>,
) -> Result<(), String> {
    let mut lin: Vec<usize> = (0..chain.dof())
        .filter(|&j| chain.joints()[j].kind == JointKind::Prismatic)
        .collect();
    if lin.is_empty() {
        return Err("the machine has no linear axis to place the tool tip".into());
    }
    // With the rotaries taking part the tip is no longer affine in the
    // unknowns: more Newton steps.
    let mut steps = 8;
    if lin.len() < 3 {
        lin = (0..chain.dof()).collect();
        steps = 40;
    }
    for _ in 0..steps {
        let (pose, jac) = chain.pose_and_jacobian(q, errors);
        let r = tip - pose.tip;
        if r.norm() < 1e-13 {
            return Ok(());
        }
        let j = DMatrix::from_fn(3, lin.len(), |row, c| jac[(row, lin[c])]);
        let rhs = DVector::from_column_slice(r.as_slice());
        let svd = j.svd(true, true);
        let d = svd
            .solve(&rhs, crate::linalg::rank::TIP_SYSTEM_MM)
            .map_err(|e| format!("linear axes cannot be solved: {e}"))?;
        for (k, &jn) in lin.iter().enumerate() {
            q[jn] += d[k];
        }
    }
    let r = (tip - chain.pose(q, errors).tip).norm();
    if r < 1e-9 {
        Ok(())
    } else {
        Err(format!(
            "the linear axes cannot reach the interpolated tool tip (miss {:.3} µm): the rotary values chosen leave it out of the linear axes' span",
            r * 1e3
        ))
    }
}

/// The joint vectors of the points inserted into block `qa → qb` by `pattern`
/// (endpoints excluded), with tips on the straight line between the block's tips.
pub fn insert_points(
    chain: &Chain,
    errors: &dyn JointErrors,
    qa: &[f64],
    qb: &[f64],
    pattern: Pattern,
    pair: Option<RotaryPair>,
) -> Result<Vec<Vec<f64>>, String> {
    let pa = chain.pose(qa, errors).tip;
    let pb = chain.pose(qb, errors).tip;
    let mut out = Vec::with_capacity(pattern.inserted());
    match pattern {
        Pattern::Even { k } => {
            for i in 1..k {
                let f = i as f64 / k as f64;
                let mut q: Vec<f64> = qa.iter().zip(qb).map(|(a, b)| a + f * (b - a)).collect();
                solve_linears(chain, errors, &mut q, &(pa + (pb - pa) * f))?;
                out.push(q);
            }
        }
        Pattern::Staggered { m } => {
            let pair = pair.ok_or("the staggered pattern needs a machine with two rotary axes")?;
            let (sa, ha) = (pair.split, pair.held);
            let segments = 2 * m + 1;
            // The value a fraction of the way from `from` to `to`: the end
            // itself at the end, so that a rotary that has arrived rounds
            // like its target (an accumulated sum 1e-14 off rounds to the
            // other side of a half at 6 decimals, and the segment then
            // seems to move one axis more).
            let at = |from: f64, to: f64, num: usize, den: usize| {
                if num == den {
                    to
                } else {
                    from + (to - from) * (num as f64 / den as f64)
                }
            };
            let (mut a_steps, mut b_steps) = (0usize, 0usize);
            for i in 1..segments {
                // Odd segments move the split rotary (by half steps in
                // units of 1/2m: 1, then 2, …), even ones the held rotary.
                if i % 2 == 1 {
                    a_steps += if i == 1 { 1 } else { 2 };
                } else {
                    b_steps += 1;
                }
                let a = at(qa[sa], qb[sa], a_steps, 2 * m);
                let b = at(qa[ha], qb[ha], b_steps, m);
                let f = i as f64 / segments as f64;
                let mut q: Vec<f64> = qa.iter().zip(qb).map(|(x, y)| x + f * (y - x)).collect();
                q[sa] = a;
                q[ha] = b;
                solve_linears(chain, errors, &mut q, &(pa + (pb - pa) * f))?;
                out.push(q);
            }
        }
    }
    Ok(out)
}

/// The largest exact nonlinear error over the segments of `qa → points → qb`.
pub fn worst_segment(
    chain: &Chain,
    errors: &dyn JointErrors,
    qa: &[f64],
    points: &[Vec<f64>],
    qb: &[f64],
) -> NonlinearError {
    let mut worst: Option<NonlinearError> = None;
    let mut prev = qa;
    for q in points
        .iter()
        .map(|v| v.as_slice())
        .chain(std::iter::once(qb))
    {
        let e = nonlinear_error(chain, errors, prev, q);
        if worst.is_none_or(|w| e.max_mm > w.max_mm) {
            worst = Some(e);
        }
        prev = q;
    }
    worst.unwrap_or(NonlinearError {
        max_mm: 0.0,
        t_at_max: 0.5,
        estimate_mm: 0.0,
    })
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

    /// Table 2 row → chain order [A, X, Y, Z, B] in mm / rad.
    fn row(x: f64, y: f64, z: f64, b: f64, a: f64) -> Vec<f64> {
        vec![a.to_radians(), x, y, z, b.to_radians()]
    }

    #[test]
    fn seed_pattern_reproduces_table3_first_block() {
        let c = wang();
        let pair = RotaryPair::default_for(&c).unwrap();
        assert_eq!(pair, RotaryPair { split: 0, held: 4 });
        let qa = row(150.891, -1.827, -38.483, 40.823, 336.463);
        let qb = row(149.828, -1.885, -37.6, 40.5, 336.789);
        let pts = insert_points(
            &c,
            &NoErrors,
            &qa,
            &qb,
            Pattern::Staggered { m: 1 },
            Some(pair),
        )
        .unwrap();
        // Table 3 rows 2 and 3 (printed to 0.001 mm / 0.001°).
        let expect = [
            [150.915, -1.871, -38.515, 40.823, 336.626],
            [149.805, -1.841, -37.568, 40.5, 336.626],
        ];
        for (p, e) in pts.iter().zip(expect) {
            let got = [p[1], p[2], p[3], p[4].to_degrees(), p[0].to_degrees()];
            for k in 0..5 {
                assert!((got[k] - e[k]).abs() <= 1.5e-3, "{got:?} vs {e:?}");
            }
        }
    }
}
