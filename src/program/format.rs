//! Number formatting for emitted axis words.

use std::fmt::Write;

/// Appends `value` with exactly `decimals` decimals to `out`, never writing
/// a negative zero (`-0.0000` becomes `0.0000`).
pub fn push_fixed(out: &mut String, value: f64, decimals: usize) {
    let start = out.len();
    let _ = write!(out, "{value:.decimals$}");
    let written = &out[start..];
    if written.starts_with('-') && written[1..].bytes().all(|b| b == b'0' || b == b'.') {
        out.remove(start);
    }
}

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
}
