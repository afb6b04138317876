//! LinuxCNC's wrapped rotary axis ([`super::RotaryMode::Wrapped`],
//! `WRAPPED_ROTARY = 1`): how its absolute words are written and read.
//!
//! LinuxCNC's interpreter (`unwrap_rotary`) reads an absolute word `w` of
//! such an axis as the position `|w|` in `[0, 360)`, reached in the
//! direction of `w`'s sign, less than a turn from where the axis stands:
//! after `C10`, `C350` turns +340° and `C-350` −20°; `C-0` turns
//! negative to 0°. A word of 360° or more is an error there. Incremental
//! words (`G91`) are plain increments.
//!
//! kinpost follows such an axis unwound (as a continuous one) and writes
//! each absolute word from the turn of its block ([`wrapped_word`]);
//! programs in machine axes are read back by LinuxCNC's rule
//! ([`unwrap_wrapped`]).

/// Why a block's turn cannot be written as one wrapped word.
pub const FULL_TURN: &str = "a wrapped rotary axis (LinuxCNC WRAPPED_ROTARY) turns less than a full turn per block, and this block would turn it a full turn or more: split the move";

/// Why the absolute word `address``value` of a wrapped rotary is refused
/// (`|value| ≥ 360`, which LinuxCNC refuses: where it would take the axis
/// is not defined).
pub fn word_too_large(address: &str, value: f64) -> String {
    format!(
        "{address}{value}: a wrapped rotary axis (LinuxCNC WRAPPED_ROTARY) takes an absolute position below 360° in size, its sign the direction (LinuxCNC refuses this word)"
    )
}

/// The absolute word of a wrapped rotary for a move from `from` to `to`,
/// both unwound and in units of the written resolution (degrees times
/// `10^decimals`, as written), where `turn` is 360° in those units:
/// `(negative, magnitude)`, the magnitude `to` wrapped into `[0, turn)`
/// and the sign that of the move (a move of zero positive). A first word,
/// `from` not known, turns from 0° (a homed table) the way `to` lies: a
/// table that stands at 0° goes to `to` itself, one that stands elsewhere
/// to the same angle. A move of a full turn or more has no such word:
/// `Err` ([`FULL_TURN`]).
pub fn wrapped_word(from: Option<i64>, to: i64, turn: i64) -> Result<(bool, i64), &'static str> {
    let magnitude = to.rem_euclid(turn);
    match from {
        None => Ok((to < 0, magnitude)),
        Some(from) => {
            let step = i128::from(to) - i128::from(from);
            if step.abs() >= i128::from(turn) {
                Err(FULL_TURN)
            } else {
                Ok((step < 0, magnitude))
            }
        }
    }
}

/// Where LinuxCNC's interpreter takes a wrapped rotary standing at
/// `current` (deg, unwound) for the absolute word `word` (deg): the
/// position `|word|` plus whole turns, at or after `current` in the
/// direction of `word`'s sign (a negative zero counts as negative).
/// `None` for `|word| ≥ 360`, which LinuxCNC refuses.
pub fn unwrap_wrapped(word: f64, current: f64) -> Option<f64> {
    if word.is_nan() || word.abs() >= 360.0 || !current.is_finite() {
        return None;
    }
    let base = 360.0 * (current / 360.0).floor();
    let mut r = word.abs() + base;
    if word.is_sign_negative() {
        if r > current {
            r -= 360.0;
        }
    } else if r < current {
        r += 360.0;
    }
    Some(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_read_back_as_linuxcnc_reads_them() {
        // LinuxCNC's own examples of the sign's meaning.
        assert_eq!(unwrap_wrapped(350.0, 10.0), Some(350.0));
        assert_eq!(unwrap_wrapped(-350.0, 10.0), Some(-10.0));
        assert_eq!(unwrap_wrapped(-0.0, 10.0), Some(0.0));
        assert_eq!(unwrap_wrapped(0.0, 10.0), Some(360.0));
        assert_eq!(unwrap_wrapped(360.0, 10.0), None);
        // Every move of less than a turn, at 3 decimals, written and read
        // back from where the axis stood: the same position, also many
        // turns out.
        let turn = 360_000i64;
        for from in [-7_200_123i64, -1, 0, 1, 359_999, 360_000, 2_520_000_017] {
            for step in [-359_999i64, -180_000, -10, -1, 0, 1, 77, 180_000, 359_999] {
                let to = from + step;
                let (negative, m) = wrapped_word(Some(from), to, turn).unwrap();
                assert!((0..turn).contains(&m));
                let word = if negative { -(m as f64) } else { m as f64 } / 1000.0;
                let back = unwrap_wrapped(word, from as f64 / 1000.0).unwrap();
                assert!(
                    (back * 1000.0 - to as f64).abs() < 1e-3,
                    "{from} + {step}: word {word}, read {back}"
                );
            }
        }
        assert_eq!(wrapped_word(Some(0), turn, turn), Err(FULL_TURN));
        assert_eq!(wrapped_word(Some(0), -turn, turn), Err(FULL_TURN));
        assert_eq!(wrapped_word(None, -90_000, turn), Ok((true, 270_000)));
        assert_eq!(wrapped_word(None, 90_000, turn), Ok((false, 90_000)));
        assert_eq!(wrapped_word(Some(10_000), 0, turn), Ok((true, 0)));
    }
}
