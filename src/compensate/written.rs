//! The errors of the axis words as written: the actual machine's tool-tip
//! and tool-axis errors at the joint values rounded to the words' decimals,
//! evaluated exactly, or bounded from above by a first-order estimate where
//! only the largest of them is wanted.
//!
//! The bound: with the pose `p*` and the Jacobian `J` a converged exact
//! refinement leaves ([`Linearization`], `J` evaluated at offsets `d_J`
//! from the theoretical solution, the result at `d`), the written joint
//! values differ from the result by the rounding `δ`, and
//! `p(q* + δ) = p* + J δ + ρ`. The remainder `ρ` is the change of the
//! Jacobian between where it was evaluated and the segment `q* … q* + δ`,
//! applied to `δ`:
//!
//! - the geometry: the chain's second derivatives are at most `R` (mm per
//!   rad²) between revolute joints, where `R` bounds the distance of the
//!   tip from their axes (the revolute columns' lengths), at most 1 between
//!   a revolute and a prismatic joint, and zero between prismatic joints;
//!   for the tool axis, a unit vector, at most 1 between revolute joints.
//!   With `A` the joint offsets along the way (`|d − d_J| + |δ|`) and
//!   `B = |δ|`, split into revolute (rad) and prismatic (mm) sums,
//!   `|ρ_geometric| ≤ R·A_r·B_r + A_r·B_p + A_p·B_r` (tool axis: `A_r·B_r`);
//! - the error motions: their slopes are at most `s_t` (translations) and
//!   `s_r` (rotations) per mm or rad ([`JointErrors::slope_bounds`]), so a
//!   Jacobian column's error term changes by at most `2 (s_r·S + s_t)`,
//!   `S` the chain's reach ([`Chain::frame_reach`]), and the error motions'
//!   own change along the way turns and shifts the chain's geometry by at
//!   most `s_r·A` and `s_t·A`.
//!
//! The upper bound is then `|target − (p* + J δ)| + |ρ|` (with a margin of
//! 10 % on the geometric terms and a floor for the floating-point
//! evaluation of both), the same for the tool axis. Where the estimate
//! cannot be bounded (no slope bounds from the error source, a rotary whose
//! error table wraps between the points, a joint without an output axis),
//! there is none and the caller evaluates.

use super::refine::Linearization;
use crate::geometric::axis_errors::wrap_angle;
use crate::machine::AxisSpec;
use crate::machine::chain::{
    Chain, JointErrors, JointKind, MAX_JOINTS, NearTrig, Pose, SlopeBounds,
};
use crate::machine::output_value;
use crate::machine::rotary::input_value;
use nalgebra::Vector3;

/// A block's tool-tip (mm) and tool-axis (rad) errors as written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Written {
    /// Evaluated at the written joint values.
    Exact(f64, f64),
    /// Upper bounds from a first-order estimate ([`written_bound`]).
    Bound(f64, f64),
}

/// The tool-tip (mm) and tool-axis (rad) errors of the actual machine
/// (`chain` with `errors`) at the axes as written: `q` (chain order, with
/// the backlash pre-compensation `lag` added) rounded to `decimals` (per
/// axis of `machine`), the lag taken off again (the machine's play takes
/// it back). A joint beyond the end of `lag` has none (`&[]`: no lag).
/// `near`: the revolute joints' sines and cosines at joint values near `q`
/// ([`Chain::trig_at`] of the theoretical solution), when the caller has
/// them.
#[allow(clippy::too_many_arguments)]
pub fn written_residual(
    machine: &crate::machine::Machine,
    chain: &Chain,
    errors: &dyn JointErrors,
    decimals: &[u32],
    pose: &Pose,
    q: &[f64],
    lag: &[f64],
    near: Option<&NearTrig>,
) -> (f64, f64) {
    let mut ext = machine.to_external(q);
    for (v, &d) in ext.iter_mut().zip(decimals) {
        let scale = crate::numeric::pow10(d);
        if let Some(i) = crate::numeric::round_half_away(*v * scale) {
            *v = i as f64 / scale;
        }
    }
    let mut written = machine.to_internal(&ext);
    for (w, l) in written.iter_mut().zip(lag) {
        *w -= l;
    }
    let p = match near {
        Some(near) => chain.pose_near(&written, errors, near),
        None => chain.pose(&written, errors),
    };
    (p.tip_distance(pose), p.axis_angle(pose))
}

/// What [`WrittenBounds::bound`] needs of the machine and the error
/// source, worked out once for a run.
#[derive(Debug, Clone)]
pub struct WrittenBounds {
    n: usize,
    /// Per joint: the decimals' scale of the axis writing it, and that
    /// axis (how its value is written: `output_value`).
    scale: [f64; MAX_JOINTS],
    axes: Vec<AxisSpec>,
    revolute: [bool; MAX_JOINTS],
    slopes: [SlopeBounds; MAX_JOINTS],
    /// The fixed part of the chain's reach ([`Chain::frame_reach`] with
    /// the prismatic joints at 0).
    fixed_reach: f64,
}

impl WrittenBounds {
    /// The plan for `machine`'s axes written to `decimals` (per axis of
    /// `machine`) on `chain` with `errors`; `None` where the estimate
    /// cannot be bounded: a joint no axis writes (it is written as 0),
    /// an error source without slope bounds.
    pub fn new(
        machine: &crate::machine::Machine,
        chain: &Chain,
        errors: &dyn JointErrors,
        decimals: &[u32],
    ) -> Option<WrittenBounds> {
        let n = chain.dof();
        if n > MAX_JOINTS || machine.axes.len() != decimals.len() {
            return None;
        }
        // Each joint written by exactly one axis, of its kind.
        let mut writer: Vec<Option<(&AxisSpec, u32)>> = vec![None; n];
        for (axis, &dec) in machine.axes.iter().zip(decimals) {
            let slot = writer.get_mut(axis.joint)?;
            if slot.is_some() {
                return None;
            }
            *slot = Some((axis, dec));
        }
        let mut plan = WrittenBounds {
            n,
            scale: [f64::NAN; MAX_JOINTS],
            axes: Vec::with_capacity(n),
            revolute: [false; MAX_JOINTS],
            slopes: [SlopeBounds::default(); MAX_JOINTS],
            fixed_reach: chain.frame_reach(&[0.0; MAX_JOINTS][..n]),
        };
        for (j, w) in writer.into_iter().enumerate() {
            let (axis, dec) = w?;
            plan.revolute[j] = axis.kind == JointKind::Revolute;
            if (chain.joints()[j].kind == JointKind::Revolute) != plan.revolute[j] {
                return None;
            }
            plan.scale[j] = crate::numeric::pow10(dec);
            plan.axes.push(axis.clone());
            plan.slopes[j] = errors.slope_bounds(j)?;
        }
        Some(plan)
    }

    /// Upper bounds of [`written_residual`] (no lag) at the result of a
    /// refinement from `q0` to `target` on `chain` that left `lin`, without
    /// evaluating the chain there (see the module); `None` where they
    /// cannot be had (a rotary's error table wrapped differently along the
    /// way, or numbers that are not finite).
    pub fn bound(&self, target: &Pose, q0: &[f64], lin: &Linearization) -> Option<(f64, f64)> {
        let n = self.n;
        if q0.len() != n || lin.d.len() != n || lin.d_jacobian.len() != n {
            return None;
        }
        let mut tip = lin.pose.tip;
        let mut axis = lin.pose.axis;
        // The offsets along the way `a` and the roundings `b` summed over the
        // revolute (rad) and prismatic (mm) joints, the revolute columns'
        // largest length, the chain's reach, and the slope-weighted sums of
        // the error terms (the module's bound, term by term).
        let (mut a_r, mut a_p, mut b_r, mut b_p, mut column) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
        let mut reach = self.fixed_reach + 1.0;
        let (mut b_sr, mut b_st, mut a_sr, mut a_st) = (0.0, 0.0, 0.0, 0.0);
        for (j, &q0_j) in q0.iter().enumerate().take(n) {
            let q = q0_j + lin.d[j];
            // The word's rounding, as `written_residual` rounds it.
            let v = output_value(&self.axes[j], q);
            let delta = match crate::numeric::round_half_away(v * self.scale[j]) {
                Some(i) => input_value(&self.axes[j], i as f64 / self.scale[j] - v),
                None => 0.0,
            };
            let c = &lin.jacobian[j];
            tip += Vector3::new(c[0], c[1], c[2]) * delta;
            axis += Vector3::new(c[3], c[4], c[5]) * delta;
            // The conversion to degrees and back costs a few ulps of the angle.
            let b = delta.abs() + 4e-16 * (q.abs() + 10.0);
            let a = (lin.d[j] - lin.d_jacobian[j]).abs() + b;
            let SlopeBounds {
                translation: s_t,
                rotation: s_r,
                wrap,
            } = self.slopes[j];
            (b_sr, b_st, a_sr, a_st) = (
                b_sr + b * s_r,
                b_st + b * s_t,
                a_sr + a * s_r,
                a_st + a * s_t,
            );
            if self.revolute[j] {
                a_r += a;
                b_r += b;
                column = column.max((c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt());
                if let Some(range) = wrap
                    && !same_turn(q, [q0_j + lin.d_jacobian[j], q + delta], range)
                {
                    return None;
                }
            } else {
                a_p += a;
                b_p += b;
                reach += q.abs();
            }
        }
        let estimate = Pose { tip, axis };
        let r = (column + a_p) * (1.01 + a_r) + 1e-6;
        let b_all = b_r + b_p;
        let error_tip = 2.0 * (b_sr * reach + b_st) + b_all * (a_sr * (r + reach) + a_st);
        let error_axis = 2.0 * (b_sr + b_all * a_sr);
        let tip_remainder = 1.1 * (r * a_r * b_r + a_r * b_p + a_p * b_r)
            + error_tip
            + 1e-11
            + 1e-13 * target.tip.amax();
        let axis_remainder = 1.1 * a_r * b_r + error_axis + 1e-13;
        let axis_norm = estimate.axis.norm();
        // (Also false for a NaN.)
        let axis_ok = axis_norm > 2.0 * axis_remainder;
        if !axis_ok {
            return None;
        }
        let bounds = (
            estimate.tip_distance(target) + tip_remainder,
            estimate.axis_angle(target) + axis_remainder / (axis_norm - axis_remainder),
        );
        (bounds.0.is_finite() && bounds.1.is_finite()).then_some(bounds)
    }
}

/// Whether the angles `ends` (rad) lie on the same turn of the wrap into
/// `range` (degrees) as `at`: the error table is then looked up without a
/// seam between them.
fn same_turn(at: f64, ends: [f64; 2], range: (f64, f64)) -> bool {
    let deg = at.to_degrees();
    let turn = wrap_angle(deg, range) - deg;
    ends.iter().all(|e| {
        let d = e.to_degrees();
        ((wrap_angle(d, range) - d) - turn).abs() <= 1e-6
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compensate::refine::refine_near_linearized;
    use crate::compensate::step::Options;
    use crate::machine::Machine;
    use crate::machine::chain::{ErrorMotion, NoErrors};
    use crate::test_support::Lcg;

    /// Large, smooth error motions with honest slope bounds: waves of
    /// `amp` mm (and `amp / 100` rad) over a 20 mm or 0.3 rad period.
    struct Waves {
        amp: f64,
        revolute: Vec<bool>,
    }

    impl Waves {
        /// Wave number per mm, or per rad: whole for the revolute joints,
        /// whose errors repeat every turn (a modulo axis is written wrapped).
        fn k(&self, joint: usize) -> f64 {
            if self.revolute[joint] {
                1.0 + joint as f64
            } else {
                0.3 + 0.1 * joint as f64
            }
        }
    }

    impl JointErrors for Waves {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            self.error_and_derivative(joint, q).map(|(e, _)| e)
        }
        fn error_and_derivative(&self, joint: usize, q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
            let (a, k) = (self.amp, self.k(joint));
            let (s, c) = (k * q).sin_cos();
            Some((
                ErrorMotion::new(
                    a * s,
                    a * c,
                    -a * s,
                    1e-2 * a * c,
                    1e-2 * a * s,
                    -1e-2 * a * c,
                ),
                ErrorMotion::new(
                    a * k * c,
                    -a * k * s,
                    -a * k * c,
                    -1e-2 * a * k * s,
                    1e-2 * a * k * c,
                    1e-2 * a * k * s,
                ),
            ))
        }
        fn slope_bounds(&self, joint: usize) -> Option<SlopeBounds> {
            let (a, k) = (self.amp, self.k(joint));
            Some(SlopeBounds {
                translation: 3.0 * a * k,
                rotation: 3e-2 * a * k,
                wrap: None,
            })
        }
    }

    /// Checks the bound against the evaluation at the written values on
    /// `count` random poses of `machine` (joint values from `joint`), every
    /// decimals count in `decimals`; returns the largest slack (bound −
    /// value) of the tip, mm.
    fn check(
        machine: &Machine,
        chain: &Chain,
        errors: &dyn JointErrors,
        decimals: &[u32],
        count: usize,
        joint: &mut dyn FnMut(usize) -> f64,
    ) -> (f64, usize) {
        let mut slack: f64 = 0.0;
        let mut bounded = 0;
        for &dec in decimals {
            let decs = vec![dec; machine.axes.len()];
            let plan = WrittenBounds::new(machine, chain, errors, &decs).expect("a plan");
            for _ in 0..count {
                let th: Vec<f64> = (0..chain.dof()).map(&mut *joint).collect();
                let target = machine.chain.pose(&th, &NoErrors);
                let near = chain.trig_at(&th);
                let opts = Options::default();
                let (r, bound) =
                    refine_near_linearized(chain, errors, &target, &th, &opts, &near, |lin| {
                        plan.bound(&target, &th, lin)
                    });
                let exact = written_residual(
                    machine,
                    chain,
                    errors,
                    &decs,
                    &target,
                    &r.q,
                    &[],
                    Some(&near),
                );
                let Some(bound) = bound.flatten() else {
                    continue;
                };
                bounded += 1;
                assert!(
                    exact.0 <= bound.0 && exact.1 <= bound.1,
                    "{} decimals {dec}: q {th:?}: evaluated {exact:?}, bound {bound:?}",
                    machine.name
                );
                slack = slack.max(bound.0 - exact.0);
            }
        }
        (slack, bounded)
    }

    /// The bound holds on the seed machines with their measured error
    /// tables, rotaries at thousands of degrees and a modulo axis among
    /// them, for coarse and fine decimals; at four decimals it is within
    /// 1 µm of the value (so that it rules out nearly every block).
    #[test]
    fn the_bound_holds_on_the_seed_machines() {
        for (name, table) in [
            (
                "zhao2022-xzbc",
                include_str!("../../fixtures/errors/zhao2022-xzbc.csv"),
            ),
            (
                "wang2023-xyzab",
                include_str!("../../fixtures/errors/wang2023-xyzab.csv"),
            ),
        ] {
            let machine = Machine::embedded(name).unwrap();
            let model = crate::geometric::ErrorModel::from_str_auto(table, "t.csv").unwrap();
            let chain = model.apply_fixed(&machine.chain).unwrap();
            let bound = model.bind(&chain).unwrap();
            let mut rng = Lcg(11);
            let joints = chain.joints().to_vec();
            let mut joint = |j: usize| match joints[j].kind {
                JointKind::Revolute => {
                    let turns = if rng.unit() < 0.3 {
                        20.0 * rng.signed()
                    } else {
                        0.0
                    };
                    (60.0 * rng.signed() + 360.0 * turns.round()).to_radians()
                }
                JointKind::Prismatic => 5.0 + 60.0 * rng.unit(),
            };
            let (slack, bounded) = check(&machine, &chain, &bound, &[4], 300, &mut joint);
            eprintln!("{name}: {bounded} of 300 bounded, slack {slack:.2e} mm");
            assert!(bounded >= 250, "{name}: {bounded} bounded");
            assert!(slack < 1e-6, "{name}: slack {slack} mm");
            check(&machine, &chain, &bound, &[0, 1, 2, 6, 9], 60, &mut joint);
        }
    }

    /// Error motions of millimetres with steep slopes (far beyond a real
    /// machine's) on every embedded machine family: the bound still holds.
    #[test]
    fn the_bound_holds_for_large_steep_errors() {
        for name in [
            "xyzac-trt",
            "xyzbc-trt",
            "xyzac-head",
            "xyzbc-nutating",
            "zhao2022-xzbc",
        ] {
            let machine = Machine::embedded(name).unwrap();
            for amp in [1e-3, 0.05] {
                let revolute = machine
                    .chain
                    .joints()
                    .iter()
                    .map(|j| j.kind == JointKind::Revolute)
                    .collect();
                let errors = Waves { amp, revolute };
                let mut rng = Lcg(5);
                let joints = machine.chain.joints().to_vec();
                let mut joint = |j: usize| match joints[j].kind {
                    JointKind::Revolute => (40.0 * rng.signed()).to_radians(),
                    JointKind::Prismatic => 30.0 * rng.signed(),
                };
                let (slack, bounded) = check(
                    &machine,
                    &machine.chain,
                    &errors,
                    &[2, 3, 4],
                    100,
                    &mut joint,
                );
                eprintln!("{name} amp {amp} mm: {bounded} of 300 bounded, slack {slack:.2e} mm");
                assert!(bounded >= 30, "{name} amp {amp}: {bounded} bounded");
            }
        }
    }

    /// A joint no axis writes, or an error source without slope bounds:
    /// no plan (the caller evaluates).
    #[test]
    fn no_plan_without_bounds_or_axes() {
        struct Unknown;
        impl JointErrors for Unknown {
            fn error(&self, _: usize, _: f64) -> Option<ErrorMotion> {
                None
            }
        }
        let machine = Machine::embedded("zhao2022-xzbc").unwrap();
        let decs = vec![4; machine.axes.len()];
        assert!(WrittenBounds::new(&machine, &machine.chain, &Unknown, &decs).is_none());
        assert!(WrittenBounds::new(&machine, &machine.chain, &NoErrors, &decs).is_some());
        assert!(WrittenBounds::new(&machine, &machine.chain, &NoErrors, &decs[1..]).is_none());
        let mut fewer = machine.clone();
        fewer.axes.pop();
        assert!(WrittenBounds::new(&fewer, &machine.chain, &NoErrors, &decs[1..]).is_none());
    }

    /// A rotary's error table looked up across its seam: the turn of the
    /// wrap differs, and the bound is refused.
    #[test]
    fn the_seam_of_a_wrapped_table_is_seen() {
        let range = (0.0, 360.0);
        let at = 359.9999f64.to_radians();
        assert!(same_turn(at, [at, 359.99995f64.to_radians()], range));
        assert!(!same_turn(at, [at, 360.00005f64.to_radians()], range));
        let range = (-90.0, 90.0);
        let at = 179.9999f64.to_radians();
        assert!(!same_turn(at, [at, 180.0001f64.to_radians()], range));
    }
}
