//! Number formatting for emitted axis words.

use std::fmt::Write;

/// Appends `value` with exactly `decimals` decimals to `out`, never writing
/// a negative zero (`-0.0000` becomes `0.0000`).
///
/// The text is exactly that of `format!("{value:.decimals$}")` (correctly
/// rounded, ties to even), produced without the formatting machinery for the
/// values an axis word holds (|value| < 1e15, at most 17 decimals): the
/// exact binary value times 10^decimals is rounded in 128-bit integers.
pub fn push_fixed(out: &mut String, value: f64, decimals: usize) {
    if write_fixed_fast(out, value, decimals) {
        return;
    }
    let start = out.len();
    let _ = write!(out, "{value:.decimals$}");
    let written = &out[start..];
    if written.starts_with('-') && written[1..].bytes().all(|b| b == b'0' || b == b'.') {
        out.remove(start);
    }
}

/// Powers of ten up to 10^17.
const POW10: [u64; 18] = {
    let mut p = [1u64; 18];
    let mut i = 1;
    while i < 18 {
        p[i] = p[i - 1] * 10;
        i += 1;
    }
    p
};

/// Writes `value` with `decimals` decimals like `format!` does, but never
/// a negative zero; `false` (nothing written) outside the fast path's range.
fn write_fixed_fast(out: &mut String, value: f64, decimals: usize) -> bool {
    if !value.is_finite() || value.abs() >= 1e15 || decimals >= POW10.len() {
        return false;
    }
    let bits = value.to_bits();
    let negative = bits >> 63 == 1;
    let exp = ((bits >> 52) & 0x7ff) as i32;
    let frac = bits & ((1u64 << 52) - 1);
    // value = m · 2^e exactly.
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), exp - 1075)
    };
    let scale = POW10[decimals] as u128;
    // n = round(m · 2^e · 10^decimals), ties to even.
    let n: u128 = if e >= 0 {
        ((m as u128) << e) * scale
    } else {
        let shift = (-e) as u32;
        let p = m as u128 * scale; // < 2^53 · 10^17 < 2^110
        if shift >= 112 {
            0 // below 2^-2: rounds to 0
        } else {
            let q = p >> shift;
            let r = p & ((1u128 << shift) - 1);
            let half = 1u128 << (shift - 1);
            if r > half || (r == half && q & 1 == 1) {
                q + 1
            } else {
                q
            }
        }
    };
    // n < 10^15 · 10^17 needs 128 bits in general; most words fit in 64.
    let (int, frac) = match u64::try_from(n) {
        Ok(n) => (n / POW10[decimals], n % POW10[decimals]),
        Err(_) => ((n / scale) as u64, (n % scale) as u64),
    };
    // Sign, up to 16 integer digits (|value| < 1e15 rounds to at most 1e15),
    // the point and up to 17 decimals, in one buffer.
    let mut buf = [b'0'; 40];
    let mut len = 0;
    // `-0.000` is written `0.000`.
    if negative && (int != 0 || frac != 0) {
        buf[0] = b'-';
        len = 1;
    }
    let digits = int.checked_ilog10().unwrap_or(0) as usize + 1;
    let mut v = int;
    for k in (len..len + digits).rev() {
        buf[k] = b'0' + (v % 10) as u8;
        v /= 10;
    }
    len += digits;
    if decimals > 0 {
        buf[len] = b'.';
        let mut v = frac;
        for k in (len + 1..=len + decimals).rev() {
            buf[k] = b'0' + (v % 10) as u8;
            v /= 10;
        }
        len += 1 + decimals;
    }
    // Digits, sign and point only: ASCII.
    out.push_str(std::str::from_utf8(&buf[..len]).unwrap_or_default());
    true
}

/// Largest magnitude of a scaled integer that [`scaled_integer`] hands out:
/// below 2^50 the nearest double to `n / 10^d` prints back as `n` exactly
/// (its rounding error times 10^d is below |n| · 2^-53 < 1/8).
const SCALED_LIMIT: f64 = (1u64 << 50) as f64;

/// `x` rounded half away from zero (as [`f64::round`]) as an integer, if
/// |x| < 2^50 ([`crate::numeric::round_half_away`] within the range where
/// [`push_scaled`] prints the nearest double's text); `None` otherwise (and
/// for NaN).
#[inline]
pub fn scaled_integer(x: f64) -> Option<i64> {
    if x.abs() >= SCALED_LIMIT {
        return None;
    }
    crate::numeric::round_half_away(x)
}

/// Appends the integer `n` read as `n / 10^decimals`, with exactly `decimals`
/// decimals and never a negative zero: the text [`push_fixed`] writes for
/// the double nearest `n / 10^decimals` when |n| < 2^50 (see
/// [`scaled_integer`]), without going through floating point.
pub fn push_scaled(out: &mut Vec<u8>, n: i64, decimals: usize) {
    // A sign, up to 20 digits, a point and zeros padding small values,
    // written right to left into the first `len` bytes.
    let mut buf = [b'0'; 48];
    let decimals = decimals.min(24);
    let mut v = n.unsigned_abs();
    let digits = (v.checked_ilog10().unwrap_or(0) as usize + 1).max(decimals + 1);
    let len = usize::from(n < 0) + digits + usize::from(decimals > 0);
    let mut pos = len;
    // Exactly `decimals` fractional digits, two at a time.
    let mut left = decimals;
    while left >= 2 {
        let r = 2 * (v % 100) as usize;
        v /= 100;
        pos -= 2;
        buf[pos..pos + 2].copy_from_slice(&DIGIT_PAIRS[r..r + 2]);
        left -= 2;
    }
    if left == 1 {
        pos -= 1;
        buf[pos] = b'0' + (v % 10) as u8;
        v /= 10;
    }
    if decimals > 0 {
        pos -= 1;
        buf[pos] = b'.';
    }
    // The integer part, at least one digit.
    while v >= 100 {
        let r = 2 * (v % 100) as usize;
        v /= 100;
        pos -= 2;
        buf[pos..pos + 2].copy_from_slice(&DIGIT_PAIRS[r..r + 2]);
    }
    if v >= 10 {
        let r = 2 * v as usize;
        pos -= 2;
        buf[pos..pos + 2].copy_from_slice(&DIGIT_PAIRS[r..r + 2]);
    } else {
        pos -= 1;
        buf[pos] = b'0' + v as u8;
    }
    if n < 0 {
        pos -= 1;
        buf[pos] = b'-';
    }
    debug_assert_eq!(pos, 0);
    // A copy of fixed size is a few moves; the bytes past `len` are cut off.
    const COPY: usize = 32;
    if len <= COPY {
        let start = out.len();
        out.extend_from_slice(&buf[..COPY]);
        out.truncate(start + len);
    } else {
        out.extend_from_slice(&buf[..len]);
    }
}

/// "00" to "99".
const DIGIT_PAIRS: [u8; 200] = {
    let mut t = [0u8; 200];
    let mut i = 0;
    while i < 100 {
        t[2 * i] = b'0' + (i / 10) as u8;
        t[2 * i + 1] = b'0' + (i % 10) as u8;
        i += 1;
    }
    t
};

/// `value` with exactly `decimals` decimals, without a negative zero.
pub fn fixed(value: f64, decimals: usize) -> String {
    let mut s = String::new();
    push_fixed(&mut s, value, decimals);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_negative_zero() {
        assert_eq!(fixed(-0.00001, 4), "0.0000");
        assert_eq!(fixed(-1.5, 3), "-1.500");
        assert_eq!(fixed(2.0, 0), "2");
        assert_eq!(fixed(-0.0, 2), "0.00");
    }

    /// Integers written with a decimal point read exactly as the nearest
    /// double formatted with `push_fixed`.
    #[test]
    fn scaled_integers_print_as_their_nearest_double() {
        let check = |n: i64, d: usize| {
            let mut a = Vec::new();
            push_scaled(&mut a, n, d);
            let b = fixed(n as f64 / 10f64.powi(d as i32), d);
            assert_eq!(String::from_utf8(a).unwrap(), b, "{n} with {d} decimals");
        };
        for d in 0..10 {
            for n in [
                0,
                1,
                -1,
                9,
                -9,
                10,
                99,
                100,
                12345,
                -12345,
                1 << 40,
                -(1 << 49),
            ] {
                check(n, d);
            }
        }
        let mut rng = crate::test_support::Lcg(7);
        for _ in 0..200_000 {
            let s = rng.next_u64();
            let bits = (s >> 33) % 50;
            let n = ((s >> 11) & ((1u64 << bits) - 1)) as i64;
            let n = if s & 1 == 1 { -n } else { n };
            check(n, (s >> 5) as usize % 10);
        }
    }

    /// `scaled_integer` rounds as `f64::round` does.
    #[test]
    fn scaled_integer_rounds_half_away_from_zero() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            1e15 + 0.5,
            4503599627370495.5 / 4.0,
        ] {
            assert_eq!(scaled_integer(x), Some(x.round() as i64), "{x}");
        }
        assert_eq!(scaled_integer(f64::NAN), None);
        assert_eq!(scaled_integer(1e16), None);
        let mut rng = crate::test_support::Lcg(11);
        for _ in 0..200_000 {
            let s = rng.next_u64();
            let x = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 10f64.powi((s % 16) as i32);
            assert_eq!(scaled_integer(x), Some(x.round() as i64), "{x}");
        }
    }

    /// The fast path writes exactly what `format!` writes.
    #[test]
    fn fast_path_matches_format() {
        let check = |v: f64, d: usize| {
            let mut s = String::new();
            if write_fixed_fast(&mut s, v, d) {
                let mut want = format!("{v:.d$}");
                if want.starts_with('-') && want[1..].bytes().all(|b| b == b'0' || b == b'.') {
                    want.remove(0);
                }
                assert_eq!(s, want, "{v:e} with {d} decimals");
            }
        };
        // Ties (exact halves), zeros, tiny and large values, every decimal count.
        for d in 0..18 {
            for v in [
                0.0,
                -0.0,
                0.5,
                1.5,
                2.5,
                -2.5,
                0.125,
                0.375,
                -0.625,
                1e-300,
                5e-324,
                123.456,
                -99999.99995,
                0.00005,
                1e14,
                999999999999999.9,
                4503599627370495.5,
            ] {
                check(v, d);
            }
        }
        // Pseudo-random values of every magnitude (SplitMix64).
        let mut s: u64 = 2024;
        let mut next = || {
            s = s.wrapping_add(0x9E3779B97F4A7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
            z ^ (z >> 31)
        };
        // KINPOST_FORMAT_CASES=5000000 for a longer run.
        let cases = std::env::var("KINPOST_FORMAT_CASES")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(200_000);
        for _ in 0..cases {
            let r = next();
            let mag = (r % 40) as i32 - 25;
            let mant = (next() >> 11) as f64 / (1u64 << 53) as f64;
            let sign = if r & (1 << 40) != 0 { -1.0 } else { 1.0 };
            check(sign * mant * 10f64.powi(mag), (r >> 50) as usize % 13);
            // Values on a decimal grid (ties in the decimal sense).
            let grid = (next() % 2_000_000_000) as f64 / 10f64.powi((r % 12) as i32) - 1e3;
            check(grid, (r >> 45) as usize % 10);
        }
    }
}
