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

/// `10^d`: from a table up to 10^19 (exact), else by `powi` (the same
/// numbers: 10^d is exact up to 10^22 either way).
pub fn pow10(d: u32) -> f64 {
    POW10
        .get(d as usize)
        .copied()
        .unwrap_or_else(|| 10f64.powi(d as i32))
}

/// Powers of ten up to 10^19, all exact in an f64.
const POW10: [f64; 20] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19,
];

/// The digits of a decimal number as they are scanned (by the G-code and
/// the APT CL readers): how many, and the integer they spell (exact while
/// there are at most [`Digits::EXACT`], so that it fits in a u64).
#[derive(Default)]
pub struct Digits {
    /// The integer the digits spell (wrapped past [`Digits::EXACT`] digits).
    pub value: u64,
    /// How many digits were scanned.
    pub count: usize,
}

impl Digits {
    /// The most digits whose integer is exact.
    pub const EXACT: usize = 19;

    /// Scans the digits `i` starts with, appending them; returns how many
    /// there are.
    pub fn scan(&mut self, i: &[u8]) -> usize {
        let mut n = 0;
        let mut value = self.value;
        for &b in i {
            let d = b.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            // Wraps only past 19 digits, when the count says it is not exact.
            value = value.wrapping_mul(10).wrapping_add(u64::from(d));
            n += 1;
        }
        self.value = value;
        self.count += n;
        n
    }

    /// The value of the digits scanned, the last `frac_digits` of them after
    /// the decimal point, when it is computed exactly here: at most 19
    /// digits whose integer is at most 2^53 (an exact integer divided by an
    /// exact power of ten, rounded once, is the nearest f64, as
    /// [`str::parse`] gives it). `None`: use [`str::parse`].
    pub fn exact(&self, frac_digits: usize) -> Option<f64> {
        (self.count <= Self::EXACT && self.value <= 1 << 53 && frac_digits < POW10.len())
            .then(|| self.value as f64 / POW10[frac_digits])
    }
}

/// The value of `text` when it is a plain decimal — an optional sign,
/// digits, a point and digits (either side may be empty, not both), nothing
/// else — that [`Digits::exact`] computes exactly; `None` otherwise (an
/// exponent, blanks, more than 19 digits: use [`str::parse`]).
pub fn plain_decimal(text: &[u8]) -> Option<f64> {
    let (negative, unsigned) = match text.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, text),
    };
    let mut digits = Digits::default();
    let int_digits = digits.scan(unsigned);
    let point = unsigned.get(int_digits) == Some(&b'.');
    let frac_digits = if point {
        digits.scan(&unsigned[int_digits + 1..])
    } else {
        0
    };
    let plain = int_digits + frac_digits > 0
        && unsigned.len() == int_digits + usize::from(point) + frac_digits;
    let v = digits.exact(frac_digits).filter(|_| plain)?;
    Some(if negative { -v } else { v })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digit_runs() {
        let mut text = Vec::new();
        for (head, n) in [
            (&b"12345678x"[..], 8),
            (b"1234567x9", 7),
            (b"x2345678", 0),
            (b"123/5678", 3),
            (b"123:5678", 3),
            (b"\xff\xff1234567", 0),
            (b"1234\xfa\xfa78", 4),
            (b"1234567890123456789012", 22),
            (b"12", 2),
            (b"", 0),
            (b"1234567890123456789 ", 19),
            (b"12345678901234567890123", 23),
            (b"0000000000000000000000001", 25),
        ] {
            // With the bytes after it of every kind, and near the end of the input.
            for tail in [&b""[..], b"\n", b" X1.5 Y-2.25 Z3\r\n", b"99999999"] {
                text.clear();
                text.extend_from_slice(head);
                text.extend_from_slice(tail);
                let mut d = Digits::default();
                let got = d.scan(&text);
                let want = text.iter().take_while(|b| b.is_ascii_digit()).count();
                assert!(
                    got == want && (tail.first() == Some(&b'9') || got == n),
                    "{text:?}"
                );
                if want <= Digits::EXACT {
                    let s = std::str::from_utf8(&text[..want]).unwrap();
                    assert_eq!(d.value, s.parse::<u64>().unwrap_or(0), "{s}");
                }
                assert_eq!(d.count, want);
            }
        }
    }

    /// A plain decimal is what the standard parser reads; anything else is
    /// left to it.
    #[test]
    fn plain_decimals() {
        for t in ["0", "-0", "+5.", "-.5", "45.994517200", "-100.00", "007"] {
            assert_eq!(
                plain_decimal(t.as_bytes()),
                Some(t.parse::<f64>().unwrap()),
                "{t}"
            );
            assert_eq!(
                plain_decimal(t.as_bytes()).map(f64::is_sign_negative),
                Some(t.starts_with('-')),
                "{t}"
            );
        }
        for t in [
            "",
            ".",
            "-",
            "1e5",
            "1.5E-3",
            " 1",
            "1 ",
            "1.2.3",
            "--1",
            "nan",
            "12345678901234567890",
        ] {
            assert_eq!(plain_decimal(t.as_bytes()), None, "{t}");
        }
    }

    /// The table of powers of ten gives what `powi` gives (and the parser:
    /// the exact decimal), over the table's end too.
    #[test]
    fn pow10_is_the_exact_power() {
        for d in 0..=25u32 {
            assert_eq!(pow10(d), 10f64.powi(d as i32), "10^{d}");
            assert_eq!(pow10(d), format!("1e{d}").parse::<f64>().unwrap(), "10^{d}");
        }
    }

    /// The exact path gives what the standard parser gives.
    #[test]
    fn exact_matches_parse() {
        for text in [
            "0",
            "1",
            "5.",
            ".5",
            "45.994517200",
            "0.000000001",
            "9007199254740992",
            "900719925474099.3",
            "123456789.0123456789",
            "3.14159265358979",
        ] {
            let mut d = Digits::default();
            let int = d.scan(text.as_bytes());
            let rest = &text.as_bytes()[int..];
            let frac = if rest.first() == Some(&b'.') {
                d.scan(&rest[1..])
            } else {
                0
            };
            if let Some(v) = d.exact(frac) {
                assert_eq!(v, text.parse::<f64>().unwrap(), "{text}");
            }
        }
    }

    #[test]
    fn finds_the_peak_of_a_parabola() {
        let (x, y) = golden_section_max(&mut |x| 1.0 - (x - 0.3) * (x - 0.3), 0.0, 1.0, 60);
        assert!((x - 0.3).abs() < 1e-7 && (y - 1.0).abs() < 1e-14);
    }
}

/// `v` for a message: as a plain decimal where that is short (0, and
/// 1e-4 ≤ |v| < 1e9), else in scientific notation (`1e-320`, not 320
/// digits).
pub fn readable(v: f64) -> String {
    if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod readable_tests {
    #[test]
    fn short_either_way() {
        assert_eq!(super::readable(0.5), "0.5");
        assert_eq!(super::readable(0.0), "0");
        assert_eq!(super::readable(1e-320), "1e-320");
        assert_eq!(super::readable(-2.5e12), "-2.5e12");
    }
}
