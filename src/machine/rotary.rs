//! Rotary axis behaviour: limited, continuous (unwound) and modulo axes,
//! unwinding to the value nearest a reference, and output conversion.
//!
//! Internally every rotary value is in radians; machine files and NC
//! programs use degrees. A rotary joint's angle is only defined modulo 2π by
//! the pose, so every value the inverse kinematics returns is a choice among
//! `θ + 2πk`; the functions here make that choice.

use super::axis::{AxisSpec, RotaryMode};
use super::chain::JointKind;
use std::f64::consts::{PI, TAU};

/// Slack allowed when comparing a value with an axis limit, in file units
/// (mm or degrees): values computed exactly at a limit may land a few ulps
/// outside it.
pub const LIMIT_SLACK: f64 = 1e-9;

/// `angle` (rad) moved by a multiple of 2π to lie within π of `reference`
/// (ties resolve towards the lower value).
pub fn unwind_near(angle: f64, reference: f64) -> f64 {
    if !angle.is_finite() || !reference.is_finite() {
        return angle;
    }
    let k = round_half_away((reference - angle) / TAU);
    let v = angle + k * TAU;
    // Guard against rounding at exactly ±π.
    if v - reference > PI {
        v - TAU
    } else if reference - v > PI {
        v + TAU
    } else {
        v
    }
}

/// `angle` (rad) wrapped into `[0, 2π)`.
pub fn wrap_positive(angle: f64) -> f64 {
    if (0.0..TAU).contains(&angle) {
        return angle;
    }
    let v = angle.rem_euclid(TAU);
    // rem_euclid can return exactly TAU for tiny negative inputs.
    if v >= TAU { 0.0 } else { v }
}

/// `value` (deg) moved by a multiple of 360° to lie within 180° of
/// `reference`; exactly `value` when it does already. The position a
/// modulo axis reaches from `reference` when commanded to `value`: the
/// short way.
pub fn unwind_near_degrees(value: f64, reference: f64) -> f64 {
    let d = value - reference;
    if d.abs() <= 180.0 {
        value
    } else {
        value - 360.0 * (d / 360.0).round()
    }
}

/// `degrees` wrapped into `[0, 360)`.
pub fn wrap_degrees(degrees: f64) -> f64 {
    if (0.0..360.0).contains(&degrees) {
        return degrees;
    }
    let v = degrees.rem_euclid(360.0);
    if v >= 360.0 { 0.0 } else { v }
}

/// The value an axis is written with: mm for linear axes, degrees for rotary
/// axes, wrapped to `[0, 360)` for modulo axes.
pub fn output_value(axis: &AxisSpec, q_internal: f64) -> f64 {
    match axis.kind {
        JointKind::Prismatic => q_internal,
        JointKind::Revolute => {
            let d = q_internal.to_degrees();
            if axis.rotary == RotaryMode::Modulo {
                wrap_degrees(d)
            } else {
                d
            }
        }
    }
}

/// Converts a value in file units (mm or degrees) to internal units.
pub fn input_value(axis: &AxisSpec, file_value: f64) -> f64 {
    match axis.kind {
        JointKind::Prismatic => file_value,
        JointKind::Revolute => file_value.to_radians(),
    }
}

/// Whether `q_internal` lies within the axis limits (with [`LIMIT_SLACK`]).
/// Axes without limits (and modulo axes) always do.
pub fn within_limits(axis: &AxisSpec, q_internal: f64) -> bool {
    let v = match axis.kind {
        JointKind::Prismatic => q_internal,
        JointKind::Revolute => q_internal.to_degrees(),
    };
    if !v.is_finite() {
        return false;
    }
    if axis.rotary == RotaryMode::Modulo {
        return true;
    }
    let lo_ok = axis.min.is_none_or(|m| v >= m - LIMIT_SLACK);
    let hi_ok = axis.max.is_none_or(|m| v <= m + LIMIT_SLACK);
    lo_ok && hi_ok
}

/// `x` rounded half away from zero, as [`f64::round`] (but `+0.0` for a
/// negative `x` that rounds to zero), without its library call where
/// [`crate::numeric::round_half_away`] applies.
#[inline]
fn round_half_away(x: f64) -> f64 {
    crate::numeric::round_half_away(x).map_or_else(|| x.round(), |i| i as f64)
}

/// Chooses the representative `angle + 2πk` of a rotary axis value.
///
/// - modulo axes: wrapped into `[0, 2π)` (the controller takes the shortest way);
/// - other axes: the representative nearest `reference`; when the axis has
///   limits, the nearest one *within* the limits if there is one (a limited
///   axis with more than one turn of travel keeps to the side nearest the
///   previous block), otherwise the nearest one (which then fails the limit
///   check).
pub fn choose_turn(axis: &AxisSpec, angle: f64, reference: f64) -> f64 {
    if axis.rotary == RotaryMode::Modulo {
        return wrap_positive(angle);
    }
    let nearest = unwind_near(angle, reference);
    if axis.min.is_none() && axis.max.is_none() {
        return nearest;
    }
    if within_limits(axis, nearest) {
        return nearest;
    }
    // Look a few turns either side for a representative within the limits.
    let mut best: Option<f64> = None;
    for k in -4i32..=4 {
        let v = nearest + f64::from(k) * TAU;
        if within_limits(axis, v)
            && best.is_none_or(|b| (v - reference).abs() < (b - reference).abs())
        {
            best = Some(v);
        }
    }
    best.unwrap_or(nearest)
}

/// Where a word of `axis` in machine coordinates takes it from `current`
/// (mm / deg): `word` in program units (`mm_per_unit` turns a linear
/// axis's into mm), absolute or an increment. An absolute word takes a
/// modulo axis the short way (a roll-over axis set to the shortest path)
/// and a wrapped rotary the way its sign says (LinuxCNC); `None` for a
/// wrapped word of 360° or more, which LinuxCNC refuses.
pub fn follow_word(
    axis: &AxisSpec,
    word: f64,
    mm_per_unit: f64,
    absolute: bool,
    current: f64,
) -> Option<f64> {
    let v = match axis.kind {
        JointKind::Prismatic => word * mm_per_unit,
        JointKind::Revolute => word,
    };
    Some(match (absolute, axis.rotary) {
        (false, _) => current + v,
        (true, RotaryMode::Modulo) => unwind_near_degrees(v, current),
        (true, RotaryMode::Wrapped) => super::wrapped::unwrap_wrapped(v, current)?,
        (true, _) => v,
    })
}

/// Signed smallest difference `a − b` between two angles (rad), in `(−π, π]`.
pub fn angle_diff(a: f64, b: f64) -> f64 {
    unwind_near(a, b) - b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_and_wrapping_match_the_library() {
        let mut rng = crate::test_support::Lcg(3);
        for _ in 0..100_000 {
            let s = rng.next_u64();
            let x = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 10f64.powi((s % 7) as i32);
            assert_eq!(round_half_away(x), x.round(), "{x}");
            let d = x * 100.0;
            assert_eq!(
                wrap_degrees(d).to_bits(),
                {
                    let v = d.rem_euclid(360.0);
                    if v >= 360.0 { 0.0f64 } else { v }
                }
                .to_bits(),
                "{d}"
            );
        }
        for x in [
            0.5,
            -0.5,
            1.5,
            -2.5,
            0.49999999999999994,
            4503599627370495.5,
            1e300,
        ] {
            assert_eq!(round_half_away(x), x.round(), "{x}");
        }
        assert!(round_half_away(f64::NAN).is_nan());
    }

    fn rot(mode: RotaryMode, min: Option<f64>, max: Option<f64>) -> AxisSpec {
        AxisSpec {
            name: "C".into(),
            joint: 0,
            kind: JointKind::Revolute,
            min,
            max,
            rotary: mode,
            decimals: 4,
        }
    }

    #[test]
    fn a_machine_word_is_followed_as_the_controller_moves() {
        let mut x = rot(RotaryMode::Limited, None, None);
        x.kind = JointKind::Prismatic;
        // Inches to mm; an increment adds.
        assert_eq!(follow_word(&x, 2.0, 25.4, true, 7.0), Some(50.8));
        assert_eq!(follow_word(&x, 2.0, 25.4, false, 7.0), Some(57.8));
        // A rotary's word is in degrees whatever the units.
        let c = rot(RotaryMode::Continuous, None, None);
        assert_eq!(follow_word(&c, 10.0, 25.4, true, 715.0), Some(10.0));
        // A modulo axis the short way: from 350° to 10° is +20°.
        let m = rot(RotaryMode::Modulo, None, None);
        assert_eq!(follow_word(&m, 10.0, 1.0, true, 350.0), Some(370.0));
        // A wrapped rotary the way the sign says: from 10° to −0 turns
        // back to 0°; 360° is refused.
        let w = rot(RotaryMode::Wrapped, None, None);
        assert_eq!(follow_word(&w, -0.0, 1.0, true, 10.0), Some(0.0));
        assert_eq!(follow_word(&w, 20.0, 1.0, true, 10.0), Some(20.0));
        assert_eq!(follow_word(&w, 360.0, 1.0, true, 10.0), None);
    }

    #[test]
    fn unwind_comes_nearest_the_reference() {
        let r = 350f64.to_radians();
        let v = unwind_near(5f64.to_radians(), r);
        assert!((v.to_degrees() - 365.0).abs() < 1e-9);
        let v = unwind_near(
            -170f64.to_radians(),
            720f64.to_radians() + 175f64.to_radians(),
        );
        assert!((v.to_degrees() - (720.0 + 190.0)).abs() < 1e-9);
        assert_eq!(unwind_near(0.3, 0.3), 0.3);
    }

    #[test]
    fn modulo_wraps_and_limited_picks_a_turn_within_limits() {
        let m = rot(RotaryMode::Modulo, None, None);
        assert!((output_value(&m, (-10f64).to_radians()) - 350.0).abs() < 1e-9);
        assert!((output_value(&m, 725f64.to_radians()) - 5.0).abs() < 1e-9);
        assert_eq!(wrap_degrees(-1e-18), 0.0);
        let l = rot(RotaryMode::Limited, Some(-30.0), Some(400.0));
        // Nearest to 0 is −20°, inside the limits.
        let v = choose_turn(&l, (-20f64).to_radians(), 0.0);
        assert!((v.to_degrees() + 20.0).abs() < 1e-9);
        // Nearest to 0 is −40°, outside: the turn within limits is 320°.
        let v = choose_turn(&l, (-40f64).to_radians(), 0.0);
        assert!((v.to_degrees() - 320.0).abs() < 1e-9);
        // Nothing fits: the nearest is returned (and fails the limit check).
        let b = rot(RotaryMode::Limited, Some(-90.0), Some(90.0));
        let v = choose_turn(&b, 120f64.to_radians(), 0.0);
        assert!(!within_limits(&b, v));
    }
}
