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

/// The terms, spline basis and arc of an error motion of `axis` from its
/// named parameters (model file or `--inject`): `EXC_cos1_mm`,
/// `ECC_sin2_urad`, `EZX_b3_mm`, `from_mm`/`to_mm`/`basis`,
/// `from_deg`/`to_deg`; peaks are ignored (they follow from the terms).
/// Errors are plain messages; callers add the location.
pub(crate) fn motion_from_parameters(
    axis: &str,
    params: &std::collections::BTreeMap<String, f64>,
) -> Result<(Vec<MotionTerm>, Option<MotionSpan>, TurnArc), String> {
    let mut terms: Vec<MotionTerm> = Vec::new();
    let span = match (
        params.get("from_mm"),
        params.get("to_mm"),
        params.get("basis"),
    ) {
        (Some(&lo), Some(&hi), Some(&n)) => Some(
            MotionSpan::new(lo, hi, n as usize)
                .ok_or("error_motion: from_mm < to_mm and at least 4 basis functions are needed")?,
        ),
        (None, None, None) => None,
        _ => return Err("error_motion: a spline needs from_mm, to_mm and basis".into()),
    };
    let arc = match (params.get("from_deg"), params.get("to_deg")) {
        (Some(&lo), Some(&hi)) => {
            if !(lo < hi && hi - lo < 360.0 && lo.is_finite() && hi.is_finite()) {
                return Err("error_motion: an arc needs from_deg < to_deg < from_deg + 360".into());
            }
            Some([lo.to_radians(), hi.to_radians()])
        }
        (None, None) => None,
        _ => return Err("error_motion: an arc needs both from_deg and to_deg".into()),
    };
    if arc.is_some() && span.is_some() {
        return Err(
            "error_motion: from_deg/to_deg are for a rotary axis's series, not a spline".into(),
        );
    }
    for (key, v) in params {
        if key.starts_with("peak")
            || matches!(
                key.as_str(),
                "value" | "from_mm" | "to_mm" | "basis" | "from_deg" | "to_deg"
            )
        {
            continue;
        }
        let (c, k, is_sin, scale, spline) = parse_term_key(key, axis).ok_or_else(|| {
            format!(
                "error_motion: `{key}` is not a term such as E{}{axis}_cos1_mm",
                "X"
            )
        })?;
        if !v.is_finite() {
            return Err(format!("error_motion: `{key}` must be a finite number"));
        }
        if spline != span.is_some() {
            return Err(format!(
                "error_motion: `{key}` does not fit the other terms (cosK/sinK terms for a rotary axis; bM terms with from_mm, to_mm and basis for a linear one)"
            ));
        }
        let slot = match terms.iter().position(|t| t.0 == c && t.1 == k) {
            Some(i) => i,
            None => {
                terms.push((c, k, 0.0, 0.0));
                terms.len() - 1
            }
        };
        if is_sin {
            terms[slot].3 = v * scale;
        } else {
            terms[slot].2 = v * scale;
        }
    }
    if terms.is_empty() {
        return Err("error_motion needs at least one term such as EXC_cos1_mm".into());
    }
    terms.sort_by_key(|t| (t.0, t.1));
    Ok((terms, span, arc))
}

/// The arc of a turn a rotary axis's error motion was found over, rad
/// (`lo < hi < lo + 2π`): outside it the motion is held at the nearer end,
/// as a linear axis's is beyond its travel. `None`: the whole turn.
pub type TurnArc = Option<[f64; 2]>;

/// The angle equivalent to `q` (mod 2π) in `arc`, or the nearer end of it
/// (rad).
pub fn onto_arc(q: f64, arc: TurnArc) -> f64 {
    let Some([lo, hi]) = arc else { return q };
    if !q.is_finite() || (lo..=hi).contains(&q) {
        return q;
    }
    let tau = std::f64::consts::TAU;
    let p = q - tau * ((q - lo) / tau).floor(); // in [lo, lo + 2π)
    if p <= hi {
        return p;
    }
    // Beyond hi: the nearer end, going on or going back round.
    if p - hi <= lo + tau - p { hi } else { lo }
}

/// The error motion at joint position `q` (rad for a Fourier series, held
/// outside `arc`; mm with a [`MotionSpan`]).
pub fn error_motion_at(
    terms: &[MotionTerm],
    span: Option<&MotionSpan>,
    arc: TurnArc,
    q: f64,
) -> ErrorMotion {
    let mut e = ErrorMotion::zeros();
    match span {
        None => {
            let q = onto_arc(q, arc);
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

/// Positions at which peaks are taken: every degree of a turn (rad), 360
/// steps over the arc, or 200 steps over the span (mm).
fn grid(span: Option<&MotionSpan>, arc: TurnArc) -> Vec<f64> {
    match (span, arc) {
        (None, None) => (0..360).map(|d| (d as f64).to_radians()).collect(),
        (None, Some([lo, hi])) => (0..=360)
            .map(|i| lo + (hi - lo) * i as f64 / 360.0)
            .collect(),
        (Some(sp), _) => (0..=200)
            .map(|i| sp.lo + (sp.hi - sp.lo) * i as f64 / 200.0)
            .collect(),
    }
}

/// Each component of an error motion with its peak (mm for translations,
/// rad for tilts), in component order.
pub fn error_motion_components(
    terms: &[MotionTerm],
    span: Option<&MotionSpan>,
    arc: TurnArc,
) -> Vec<(usize, f64)> {
    let mut comps: Vec<usize> = terms.iter().map(|t| t.0).collect();
    comps.sort_unstable();
    comps.dedup();
    let g = grid(span, arc);
    comps
        .into_iter()
        .map(|c| {
            let own: Vec<MotionTerm> = terms.iter().copied().filter(|t| t.0 == c).collect();
            let peak = g
                .iter()
                .map(|&q| error_motion_at(&own, span, arc, q)[c].abs())
                .fold(0.0, f64::max);
            (c, peak)
        })
        .collect()
}

/// The largest translation (mm) and rotation (rad) of an error motion over
/// a turn, the arc or the span.
pub fn error_motion_peaks(
    terms: &[MotionTerm],
    span: Option<&MotionSpan>,
    arc: TurnArc,
) -> (f64, f64) {
    grid(span, arc).iter().fold((0.0f64, 0.0f64), |(t, r), &q| {
        let e = error_motion_at(terms, span, arc, q);
        (
            t.max((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()),
            r.max((e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_angle_goes_onto_the_arc_or_its_nearer_end() {
        let arc = Some([-1.5, 1.5]);
        let tau = std::f64::consts::TAU;
        assert_eq!(onto_arc(0.3, arc), 0.3);
        assert!((onto_arc(0.3 + 3.0 * tau, arc) - 0.3).abs() < 1e-12);
        // 2.0 rad is 0.5 past hi, and 2π − 2 − 1.5 = 2.78 short of lo.
        assert_eq!(onto_arc(2.0, arc), 1.5);
        assert_eq!(onto_arc(-2.0, arc), -1.5);
        assert_eq!(onto_arc(-2.0 - 7.0 * tau, arc), -1.5);
        assert_eq!(onto_arc(5.0, None), 5.0);
    }

    #[test]
    fn an_arc_is_read_and_checked() {
        let p = |kv: &[(&str, f64)]| -> std::collections::BTreeMap<String, f64> {
            kv.iter().map(|(k, v)| (k.to_string(), *v)).collect()
        };
        let (terms, span, arc) = motion_from_parameters(
            "A",
            &p(&[
                ("EAA_cos1_urad", 20.0),
                ("from_deg", -90.0),
                ("to_deg", 90.0),
            ]),
        )
        .unwrap();
        assert_eq!(terms.len(), 1);
        assert_eq!((terms[0].0, terms[0].1, terms[0].3), (3, 1, 0.0));
        assert!((terms[0].2 - 20e-6).abs() < 1e-18);
        assert!(span.is_none());
        let [lo, hi] = arc.unwrap();
        assert!(
            (lo + std::f64::consts::FRAC_PI_2).abs() < 1e-15
                && (hi - std::f64::consts::FRAC_PI_2).abs() < 1e-15
        );
        for bad in [
            p(&[("EAA_cos1_urad", 1.0), ("from_deg", 10.0)]),
            p(&[("EAA_cos1_urad", 1.0), ("from_deg", 10.0), ("to_deg", 5.0)]),
            p(&[("EAA_cos1_urad", 1.0), ("from_deg", 0.0), ("to_deg", 360.0)]),
        ] {
            assert!(motion_from_parameters("A", &bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn peaks_over_an_arc_see_only_the_arc() {
        // EXC = cos q: 1 over the whole turn, cos(1) = 0.54 at most on [1, 2].
        let terms = [(0usize, 1u32, 1.0, 0.0)];
        assert!((error_motion_peaks(&terms, None, None).0 - 1.0).abs() < 1e-12);
        let on_arc = error_motion_peaks(&terms, None, Some([1.0, 2.0])).0;
        assert!((on_arc - 1f64.cos()).abs() < 1e-12, "{on_arc}");
        // Held beyond the arc.
        let e = error_motion_at(&terms, None, Some([1.0, 2.0]), 3.0)[0];
        assert!((e - 2f64.cos()).abs() < 1e-12);
    }
}
