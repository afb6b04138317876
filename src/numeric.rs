//! Small numerical building blocks shared by several features.

/// Golden-section search for the maximum of a unimodal `f` on `[lo, hi]`:
/// `iters` steps (each shrinks the bracket by 0.618); returns the better of
/// the two final interior points and its value.
pub fn golden_section_max(
    f: &mut dyn FnMut(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    iters: usize,
) -> (f64, f64) {
    let g = 0.618_033_988_749_894_9;
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let mut f1 = f(x1);
    let mut f2 = f(x2);
    for _ in 0..iters {
        if f1 < f2 {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        } else {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        }
    }
    if f1 > f2 { (x1, f1) } else { (x2, f2) }
}

/// `x` rounded half away from zero (as [`f64::round`]) as an integer, when
/// |x| < 2^52; `None` beyond (and for NaN).
///
/// Without SSE4.1 `f64::round` is a library call; the conversion to an
/// integer truncates in one instruction, and below 2^52 the fraction
/// `x − trunc(x)` is exact.
#[inline]
pub fn round_half_away(x: f64) -> Option<i64> {
    if x.is_nan() || x.abs() >= 4_503_599_627_370_496.0 {
        return None;
    }
    let t = x as i64;
    let f = x - t as f64;
    Some(if f >= 0.5 {
        t + 1
    } else if f <= -0.5 {
        t - 1
    } else {
        t
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_peak_of_a_parabola() {
        let (x, y) = golden_section_max(&mut |x| 1.0 - (x - 0.3) * (x - 0.3), 0.0, 1.0, 60);
        assert!((x - 0.3).abs() < 1e-7 && (y - 1.0).abs() < 1e-14);
    }
}
