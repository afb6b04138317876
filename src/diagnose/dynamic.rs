//! The model's dynamic effects (backlash, servo lag, thermal drift) as
//! joint offsets along a trajectory: to evaluate the chain at one point
//! with its direction, speed and time known ([`DynamicErrors`]), and to
//! pre-compensate a commanded trajectory ([`compensate_dynamic`]).

use super::simulate;
use super::timeline::TrajPoint;
use crate::error::Result;
use crate::geometric::ErrorModel;
use crate::geometric::effects::BoundEffect;
use crate::machine::chain::{Chain, ErrorMotion, JointErrors, JointKind};

/// Dynamic offsets of a model's dynamic effects (backlash, servo lag,
/// thermal drift) along a trajectory: Δq per point (mm, deg), chain order.
/// Directions are tracked along `traj`; thermal drift runs from the first
/// point (or from its `from_block`).
pub fn dynamic_offsets(
    chain: &Chain,
    model: &ErrorModel,
    traj: &[TrajPoint],
) -> Result<Vec<Vec<f64>>> {
    let n = chain.dof();
    let mut effects: Vec<BoundEffect> = model
        .effects
        .iter()
        .filter(|e| e.effect.kind().is_dynamic())
        .map(|e| BoundEffect::new(e, chain))
        .collect::<Result<_>>()?;
    let mut walker = simulate::TrajectoryWalker::new(n, effects.len());
    let mut out = Vec::with_capacity(traj.len());
    for p in traj {
        let (st, active) = walker.step(p, &mut effects)?;
        let mut dq = vec![0.0; n];
        for (e, _) in effects.iter().zip(active).filter(|(_, a)| **a) {
            if let Some(j) = e.joint {
                dq[j] += e.delta_q(&st);
            }
        }
        out.push(dq);
    }
    Ok(out)
}

/// Pre-compensates a commanded trajectory for the model's dynamic effects:
/// each point's command becomes `q − Δq` (backlash: half the reversal value
/// in the direction of motion; servo lag: `+τ·v` feed-forward; thermal
/// drift: minus the drift at that time). Static effects are compensated by
/// the Newton refinement on the model's chain (`crate::compensate`).
pub fn compensate_dynamic(
    chain: &Chain,
    model: &ErrorModel,
    traj: &[TrajPoint],
) -> Result<Vec<TrajPoint>> {
    let dq = dynamic_offsets(chain, model, traj)?;
    Ok(traj
        .iter()
        .zip(dq)
        .map(|(p, d)| TrajPoint {
            t: p.t,
            block: p.block,
            q: p.q.iter().zip(&d).map(|(q, d)| q - d).collect(),
            v: p.v.clone(),
        })
        .collect())
}

/// A [`JointErrors`] source that adds known dynamic joint offsets (from
/// [`dynamic_offsets`], in file units) to a base error source: evaluate the
/// chain at one trajectory point with the direction, speed and time known.
pub struct DynamicErrors<'a> {
    base: &'a dyn JointErrors,
    kinds: Vec<JointKind>,
    axes: Vec<nalgebra::Vector3<f64>>,
    dq: Vec<f64>,
}

impl<'a> DynamicErrors<'a> {
    /// Wraps `base` for `chain` with zero offsets.
    pub fn new(chain: &Chain, base: &'a dyn JointErrors) -> Self {
        DynamicErrors {
            base,
            kinds: chain.joints().iter().map(|j| j.kind).collect(),
            axes: chain.joints().iter().map(|j| j.axis.into_inner()).collect(),
            dq: vec![0.0; chain.dof()],
        }
    }

    /// Sets the offsets of the current point (mm, deg; chain order).
    pub fn set_offsets(&mut self, dq: &[f64]) {
        for (a, b) in self.dq.iter_mut().zip(dq) {
            *a = *b;
        }
    }
}

impl JointErrors for DynamicErrors<'_> {
    fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
        self.error_and_derivative(joint, q).map(|(e, _)| e)
    }

    fn error_and_derivative(&self, joint: usize, q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
        let base = self.base.error_and_derivative(joint, q);
        let d = *self.dq.get(joint)?;
        if d == 0.0 {
            return base;
        }
        let u = self.axes[joint];
        let mut e = ErrorMotion::zeros();
        if self.kinds[joint] == JointKind::Revolute {
            let r = d.to_radians();
            e[3] = r * u.x;
            e[4] = r * u.y;
            e[5] = r * u.z;
        } else {
            e[0] = d * u.x;
            e[1] = d * u.y;
            e[2] = d * u.z;
        }
        Some(match base {
            Some((b, db)) => (b + e, db),
            None => (e, ErrorMotion::zeros()),
        })
    }

    fn is_empty(&self) -> bool {
        self.base.is_empty() && self.dq.iter().all(|d| *d == 0.0)
    }
}
