//! When the `I J K` of a straight move are not a tool vector.
//!
//! kinpost reads `I J K` on a `G0`/`G1` block as the tool axis, and such a
//! block starts pose mode by itself. Dialects give `I J K` other meanings,
//! which must neither start pose mode nor be converted (docs/programs.md,
//! "Which blocks are poses"):
//!
//! - motion modes whose `I J K` are a pitch, a taper, a centre or control
//!   points: threads and tapping (Fanuc `G32`, `G34`–`G36`; Sinumerik
//!   `G331`, `G332`, `G34`, `G35`, `G335`, `G336`; `G33`, `G33.1`, `G76`),
//!   splines (`G5`, `G5.1`, `G5.2`, `G6.2`) and the lathe cycles `G73`,
//!   `G74`. A pitch of 1 mm (`G32 Z-20. K1.`) is a unit vector: before,
//!   such a lathe thread was converted into machine axis words with its
//!   pitch dropped;
//! - words that belong to another code of the block: the exit or entry
//!   direction of cutter radius compensation (Fanuc `G40 G1 X-10 Y-10 I1
//!   J0`, `G41 … I J`), the index of a work offset (MillPlus `G54 I1`), the
//!   arguments of a macro call (`G65 P9810 X Y Z I J K`).
//!
//! Fanuc's `G05 P10000` (high-precision contour control) and `G05.1 Q1`
//! (AI contour control) are mode switches with no axis words, not
//! LinuxCNC's spline moves `G5 X Y I J P Q` / `G5.1 X Y I J`: they leave
//! the motion mode as it is.

/// A block's words as (upper-case address, value) pairs.
pub trait Words<'a>: IntoIterator<Item = (&'a str, f64)> + Clone {}
impl<'a, T: IntoIterator<Item = (&'a str, f64)> + Clone> Words<'a> for T {}

/// G codes, ×10 as `modal.rs` matches them, of motion modes whose `I J K`
/// are not a tool vector (threads, tapping, splines, lathe cycles).
pub const OTHER_MOTION: [i64; 17] = [
    320, 330, 331, 340, 350, 360, 3310, 3320, 3350, 3360, 760, 50, 51, 52, 62, 730, 740,
];

/// Whether the `G5` / `G5.1` of `words` (code ×10: 50, 51) is Fanuc's mode
/// switch (`G05 P10000`, `G05.1 Q1`): no axis, centre or vector word.
pub fn fanuc_mode_switch<'a>(code: i64, words: impl Words<'a>) -> bool {
    matches!(code, 50 | 51)
        && !words.into_iter().any(|(a, _)| {
            matches!(
                a,
                "X" | "Y" | "Z" | "I" | "J" | "K" | "A" | "B" | "C" | "U" | "V" | "W"
            )
        })
}

/// Whether `code` (a G code ×10) is a motion mode whose `I J K` are not a
/// tool vector ([`OTHER_MOTION`]), Fanuc's mode switches aside.
pub fn other_motion<'a>(code: i64, words: impl Words<'a>) -> bool {
    OTHER_MOTION.contains(&code) && !fanuc_mode_switch(code, words)
}

/// The G code of the block whose words its `I J K` are, when they are not
/// a tool vector: cutter radius compensation (`G40`–`G42.2`: an exit or
/// entry direction), a work offset (`G54`–`G59.9`, `G54.1`: MillPlus
/// `G54 I1`), a macro call (`G65`, `G66`, `G66.1`: its arguments).
pub fn owner<'a>(words: impl Words<'a>) -> Option<f64> {
    words
        .into_iter()
        .filter(|(a, _)| *a == "G")
        .map(|(_, v)| v)
        .find(|&g| {
            let c = (g * 10.0).round() as i64;
            matches!(c, 400..=423 | 540..=599 | 650 | 660 | 661)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(address: &'static str, value: f64) -> (&'static str, f64) {
        (address, value)
    }

    #[test]
    fn fanuc_modes_are_not_splines() {
        assert!(fanuc_mode_switch(50, [w("G", 5.0), w("P", 10000.0)]));
        assert!(fanuc_mode_switch(
            51,
            [w("G", 5.1), w("Q", 1.0), w("R", 5.0)]
        ));
        // LinuxCNC's cubic spline has its end point and control points.
        let spline = [
            w("G", 5.0),
            w("X", 1.0),
            w("Y", 2.0),
            w("P", 1.0),
            w("Q", 0.5),
        ];
        assert!(!fanuc_mode_switch(50, spline));
        assert!(other_motion(50, spline));
        assert!(other_motion(
            320,
            [w("G", 32.0), w("Z", -20.0), w("K", 1.0)]
        ));
    }

    #[test]
    fn owners() {
        assert_eq!(owner([w("G", 40.0), w("G", 1.0), w("I", 1.0)]), Some(40.0));
        assert_eq!(owner([w("G", 54.0), w("I", 1.0)]), Some(54.0));
        assert_eq!(owner([w("G", 54.1), w("P", 2.0)]), Some(54.1));
        assert_eq!(owner([w("G", 65.0), w("P", 9810.0)]), Some(65.0));
        assert_eq!(owner([w("G", 1.0), w("I", 0.0), w("K", 1.0)]), None);
        assert_eq!(owner([w("G", 43.4), w("H", 1.0)]), None);
    }
}
