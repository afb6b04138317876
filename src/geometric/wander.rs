//! A wander of the measurement in time (`diagnose`'s `wander`): a cubic
//! B-spline per workpiece coordinate, its value and its range.

use super::error_motion::MotionSpan;

/// The offset of the measured tip a wander gives at `t` (s), mm.
pub fn wander_at(span: &MotionSpan, coef_mm: &[[f64; 3]], t: f64) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (w, c) in span.values(t).iter().zip(coef_mm) {
        for k in 0..3 {
            out[k] += w * c[k];
        }
    }
    out
}

/// Peak-to-peak of a wander's x, y and z over its span (sampled at 400
/// points; a cubic between knots at least a thirteenth of the span
/// apart), mm.
pub fn wander_range(span: &MotionSpan, coef_mm: &[[f64; 3]]) -> [f64; 3] {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for i in 0..=400 {
        let t = span.lo + (span.hi - span.lo) * i as f64 / 400.0;
        let w = wander_at(span, coef_mm, t);
        for k in 0..3 {
            lo[k] = lo[k].min(w[k]);
            hi[k] = hi[k].max(w[k]);
        }
    }
    [0, 1, 2].map(|k| (hi[k] - lo[k]).max(0.0))
}

/// The spacing of a wander's knots in time, s.
pub fn wander_knot_spacing(span: &MotionSpan) -> f64 {
    (span.hi - span.lo) / (span.basis.len().saturating_sub(3).max(1)) as f64
}
