//! The error motion of an axis: for a rotary axis a Fourier series over
//! one turn, for a linear axis a cubic B-spline over its travel; its terms,
//! their ISO 230-1 names, its value and peaks.

use super::bspline::{BSpline, Extrapolation, uniform_knots};
use crate::machine::chain::ErrorMotion;

/// The B-spline basis of a linear axis's error motion: `basis.len()` cubic
/// functions with uniform knots over `[lo, hi]` (mm), held at the ends.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionSpan {
    /// Start of the travel, mm.
    pub lo: f64,
    /// End of the travel, mm.
    pub hi: f64,
    /// The basis functions.
    pub basis: Vec<BSpline>,
}

impl MotionSpan {
    /// `count` (≥ 4) cubic basis functions over `[lo, hi]` (`lo < hi`).
    pub fn new(lo: f64, hi: f64, count: usize) -> Option<MotionSpan> {
        if !(lo < hi && lo.is_finite() && hi.is_finite()) || count < 4 {
            return None;
        }
        let knots = uniform_knots(lo, hi, 3, count - 4);
        let basis = (0..count)
            .map(|m| {
                let mut coef = vec![0.0; count];
                coef[m] = 1.0;
                BSpline::new(3, knots.clone(), coef, Extrapolation::Hold).ok()
            })
            .collect::<Option<Vec<_>>>()?;
        Some(MotionSpan { lo, hi, basis })
    }

    /// The basis values at `q` (mm).
    pub fn values(&self, q: f64) -> Vec<f64> {
        self.basis.iter().map(|b| b.value(q)).collect()
    }
}

/// One term of an error motion: (component 0…5, harmonic k ≥ 1 or, with a
/// [`MotionSpan`], basis function index, cos (or spline) coefficient, sin
/// coefficient), in mm or rad.
pub type MotionTerm = (usize, u32, f64, f64);

/// ISO 230-1 name of error-motion component `c` (0…5) of `axis`: `EXC`,
/// `EYC`, `EZC`, `EAC`, `EBC`, `ECC` for axis C.
pub fn component_name(c: usize, axis: &str) -> String {
    format!("E{}{axis}", ["X", "Y", "Z", "A", "B", "C"][c.min(5)])
}

/// Reads a term key `EXC_cos1_mm` / `EAC_sin2_urad` / `EYX_b3_mm` of
/// `axis`: (component, harmonic or basis index, is it the sine, factor to
/// internal units, is it a spline term).
pub(crate) fn parse_term_key(key: &str, axis: &str) -> Option<(usize, u32, bool, f64, bool)> {
    let (name, rest) = key.split_once('_')?;
    let c = (0..6).find(|&c| component_name(c, axis).eq_ignore_ascii_case(name))?;
    let (wave, unit) = match rest.rsplit_once('_') {
        Some((w, u)) => (w, Some(u)),
        None => (rest, None),
    };
    let (is_sin, k, spline) = if let Some(k) = wave.strip_prefix("cos") {
        (false, k, false)
    } else if let Some(k) = wave.strip_prefix("sin") {
        (true, k, false)
    } else {
        (false, wave.strip_prefix('b')?, true)
    };
    let k: u32 = k.parse().ok().filter(|k| spline || *k >= 1)?;
    let scale = match (c < 3, unit) {
        (true, None | Some("mm")) => 1.0,
        (false, None | Some("urad")) => 1e-6,
        _ => return None,
    };
    Some((c, k, is_sin, scale, spline))
}

/// The error motion at joint position `q` (rad for a Fourier series, mm
/// with a [`MotionSpan`]).
pub fn error_motion_at(terms: &[MotionTerm], span: Option<&MotionSpan>, q: f64) -> ErrorMotion {
    let mut e = ErrorMotion::zeros();
    match span {
        None => {
            for &(c, k, a, b) in terms {
                let (s, co) = (k as f64 * q).sin_cos();
                e[c.min(5)] += a * co + b * s;
            }
        }
        Some(sp) => {
            let v = sp.values(q);
            for &(c, m, a, _) in terms {
                e[c.min(5)] += a * v.get(m as usize).copied().unwrap_or(0.0);
            }
        }
    }
    e
}

/// Positions at which peaks are taken: every degree of a turn (rad), or
/// 200 steps over the span (mm).
fn grid(span: Option<&MotionSpan>) -> Vec<f64> {
    match span {
        None => (0..360).map(|d| (d as f64).to_radians()).collect(),
        Some(sp) => (0..=200)
            .map(|i| sp.lo + (sp.hi - sp.lo) * i as f64 / 200.0)
            .collect(),
    }
}

/// Each component of an error motion with its peak (mm for translations,
/// rad for tilts), in component order.
pub fn error_motion_components(
    terms: &[MotionTerm],
    span: Option<&MotionSpan>,
) -> Vec<(usize, f64)> {
    let mut comps: Vec<usize> = terms.iter().map(|t| t.0).collect();
    comps.sort_unstable();
    comps.dedup();
    let g = grid(span);
    comps
        .into_iter()
        .map(|c| {
            let own: Vec<MotionTerm> = terms.iter().copied().filter(|t| t.0 == c).collect();
            let peak = g
                .iter()
                .map(|&q| error_motion_at(&own, span, q)[c].abs())
                .fold(0.0, f64::max);
            (c, peak)
        })
        .collect()
}

/// The largest translation (mm) and rotation (rad) of an error motion over
/// a turn or the span.
pub fn error_motion_peaks(terms: &[MotionTerm], span: Option<&MotionSpan>) -> (f64, f64) {
    grid(span).iter().fold((0.0f64, 0.0f64), |(t, r), &q| {
        let e = error_motion_at(terms, span, q);
        (
            t.max((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()),
            r.max((e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt()),
        )
    })
}
