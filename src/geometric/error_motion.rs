//! The error motion of a rotary axis as a Fourier series over one turn:
//! its terms, their ISO 230-1 names, its value and peaks.

use crate::machine::chain::ErrorMotion;

/// One Fourier term of an error motion: (component 0…5, harmonic k ≥ 1,
/// cos coefficient, sin coefficient), in mm or rad.
pub type MotionTerm = (usize, u32, f64, f64);

/// ISO 230-1 name of error-motion component `c` (0…5) of `axis`: `EXC`,
/// `EYC`, `EZC`, `EAC`, `EBC`, `ECC` for axis C.
pub fn component_name(c: usize, axis: &str) -> String {
    format!("E{}{axis}", ["X", "Y", "Z", "A", "B", "C"][c.min(5)])
}

/// Reads a term key `EXC_cos1_mm` / `EAC_sin2_urad` of `axis`: (component,
/// harmonic, is it the sine, factor to internal units).
pub(crate) fn parse_term_key(key: &str, axis: &str) -> Option<(usize, u32, bool, f64)> {
    let (name, rest) = key.split_once('_')?;
    let c = (0..6).find(|&c| component_name(c, axis).eq_ignore_ascii_case(name))?;
    let (wave, unit) = match rest.rsplit_once('_') {
        Some((w, u)) => (w, Some(u)),
        None => (rest, None),
    };
    let (is_sin, k) = if let Some(k) = wave.strip_prefix("cos") {
        (false, k)
    } else {
        (true, wave.strip_prefix("sin")?)
    };
    let k: u32 = k.parse().ok().filter(|k| *k >= 1)?;
    let scale = match (c < 3, unit) {
        (true, None | Some("mm")) => 1.0,
        (false, None | Some("urad")) => 1e-6,
        _ => return None,
    };
    Some((c, k, is_sin, scale))
}

/// The error motion of a Fourier series at joint angle `q` (rad).
pub fn error_motion_at(terms: &[MotionTerm], q: f64) -> ErrorMotion {
    let mut e = ErrorMotion::zeros();
    for &(c, k, a, b) in terms {
        let (s, co) = (k as f64 * q).sin_cos();
        e[c.min(5)] += a * co + b * s;
    }
    e
}

/// Each component of an error motion with its peak over one turn (mm for
/// translations, rad for tilts), in component order.
pub fn error_motion_components(terms: &[MotionTerm]) -> Vec<(usize, f64)> {
    let mut comps: Vec<usize> = terms.iter().map(|t| t.0).collect();
    comps.sort_unstable();
    comps.dedup();
    comps
        .into_iter()
        .map(|c| {
            let own: Vec<MotionTerm> = terms.iter().copied().filter(|t| t.0 == c).collect();
            let peak = (0..360)
                .map(|d| error_motion_at(&own, (d as f64).to_radians())[c].abs())
                .fold(0.0, f64::max);
            (c, peak)
        })
        .collect()
}

/// The largest translation (mm) and rotation (rad) of an error motion over
/// one turn (sampled every degree).
pub fn error_motion_peaks(terms: &[MotionTerm]) -> (f64, f64) {
    (0..360).fold((0.0f64, 0.0f64), |(t, r), d| {
        let e = error_motion_at(terms, (d as f64).to_radians());
        (
            t.max((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()),
            r.max((e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt()),
        )
    })
}
