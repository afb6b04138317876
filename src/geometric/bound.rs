//! An [`ErrorModel`](super::ErrorModel) bound to a chain: the chain
//! evaluator's error source ([`JointErrors`]), by joint index.

use super::axis_errors::AxisErrors;
use super::effects::StaticTerm;
use super::merged::MergedAxis;
use crate::machine::chain::{ErrorMotion, JointErrors, SlopeBounds};

/// An [`ErrorModel`](super::ErrorModel) bound to a chain's joint indices: the chain evaluator's
/// error source, with analytic derivatives.
#[derive(Debug, Clone)]
pub struct BoundErrors<'a> {
    per_joint: Vec<Option<&'a AxisErrors>>,
    /// Per joint, its axis's errors merged into one piecewise cubic (when
    /// they can be).
    merged: Vec<Option<MergedAxis>>,
    /// Static diagnosed effects in error-motion form.
    terms: Vec<StaticTerm>,
    /// No joint has errors ([`JointErrors::is_empty`], asked at every
    /// evaluation of the chain: kept, not recounted).
    empty: bool,
    /// Per joint, the slope bounds of its merged motions in position units
    /// (mm or degrees; [`MergedAxis::slope_bounds`]).
    slopes: Vec<Option<(f64, f64)>>,
}

impl<'a> BoundErrors<'a> {
    /// The axes' errors by joint index (`per_joint`), merged where they can
    /// be, with the static diagnosed effects `terms`.
    pub(super) fn new(per_joint: Vec<Option<&'a AxisErrors>>, terms: Vec<StaticTerm>) -> Self {
        let merged: Vec<Option<MergedAxis>> = per_joint
            .iter()
            .map(|a| a.and_then(MergedAxis::new))
            .collect();
        let slopes = merged
            .iter()
            .map(|m| m.as_ref().map(MergedAxis::slope_bounds))
            .collect();
        let empty = per_joint.iter().all(Option::is_none) && terms.is_empty();
        BoundErrors {
            per_joint,
            merged,
            terms,
            empty,
            slopes,
        }
    }
}

impl BoundErrors<'_> {
    /// The modelled axis at joint index `joint`, if any.
    pub fn axis_of(&self, joint: usize) -> Option<&AxisErrors> {
        self.per_joint.get(joint).copied().flatten()
    }
}

impl BoundErrors<'_> {
    /// Error motions of `joint` at `q` and their derivatives (per mm or rad).
    fn evaluate(&self, joint: usize, q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
        let base = self.per_joint.get(joint).copied().flatten().map(|a| {
            let merged = self.merged[joint].as_ref();
            let at = |pos: f64| match merged {
                Some(m) => m.error_at(pos),
                None => a.error_at(pos),
            };
            if a.rotary {
                // The chain works in rad, the splines in degrees.
                let (e, d) = at(q.to_degrees());
                (e, d * (180.0 / std::f64::consts::PI))
            } else {
                at(q)
            }
        });
        if self.terms.is_empty() {
            return base;
        }
        let mut extra: Option<(ErrorMotion, ErrorMotion)> = None;
        for t in self.terms.iter().filter(|t| t.joint == joint) {
            let h = 1e-6 * (1.0 + q.abs());
            let e = t.error_motion(q);
            let d = (t.error_motion(q + h) - t.error_motion(q - h)) / (2.0 * h);
            let acc = extra.get_or_insert((ErrorMotion::zeros(), ErrorMotion::zeros()));
            acc.0 += e;
            acc.1 += d;
        }
        match (base, extra) {
            (None, None) => None,
            (Some(b), None) => Some(b),
            (None, Some(x)) => Some(x),
            (Some(b), Some(x)) => Some((b.0 + x.0, b.1 + x.1)),
        }
    }
}

impl JointErrors for BoundErrors<'_> {
    fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
        // The merged splines without their derivatives, where nothing else
        // adds to this joint (the common case).
        if self.terms.is_empty()
            && let Some(m) = self.merged.get(joint).and_then(Option::as_ref)
        {
            // (A merged axis is one of `per_joint`'s.)
            let pos = if m.is_rotary() { q.to_degrees() } else { q };
            return Some(m.value_at(pos));
        }
        self.evaluate(joint, q).map(|(e, _)| e)
    }

    fn error_and_derivative(&self, joint: usize, q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
        self.evaluate(joint, q)
    }

    fn is_empty(&self) -> bool {
        self.empty
    }

    /// The merged splines' bounds ([`MergedAxis::slope_bounds`]) in chain
    /// units (per rad for a rotary, whose table is wrapped into its
    /// travel); `None` where a joint's errors are not merged, or where
    /// static diagnosed effects add to the joints (their slopes are not
    /// bounded here).
    fn slope_bounds(&self, joint: usize) -> Option<SlopeBounds> {
        if !self.terms.is_empty() {
            return None;
        }
        let Some(axis) = self.per_joint.get(joint).copied().flatten() else {
            return Some(SlopeBounds::default());
        };
        let (translation, rotation) = (*self.slopes.get(joint)?)?;
        if !axis.rotary {
            return Some(SlopeBounds {
                translation,
                rotation,
                wrap: None,
            });
        }
        // Per degree → per rad.
        let per_rad = 180.0 / std::f64::consts::PI;
        Some(SlopeBounds {
            translation: translation * per_rad,
            rotation: rotation * per_rad,
            wrap: Some(self.merged[joint].as_ref()?.range()),
        })
    }
}
