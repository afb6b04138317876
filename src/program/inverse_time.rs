//! `post --feed inverse-time`: inverse-time feeds (G93) on the pose blocks
//! that move a rotary axis, so that the tool tip keeps the programmed feed.
//!
//! Once TCP is off, a controller in G94 applies F to the path of the
//! machine axes, not to the tool tip: a block that turns a rotary axis
//! moves the tip at another speed than programmed. In G93 the controller
//! takes `F` as 1 / (the block's time in minutes) and moves all axes so the
//! block lasts that long. The block's time is the tool tip's path length
//! over the programmed feed: `t = L / F` (mm, mm/min), so `F93 = F / L`.
//! `L` is the straight distance between the block's programmed tool tips,
//! the path the CAM system meant.
//!
//! Converted: straight feed moves (`G1`) in pose mode, in G94, with a feed,
//! whose tip moves (L > 1e-9 mm) and whose written axes turn a rotary axis.
//! Every other block keeps the programmed feed: the first such block after
//! converted ones gets `G94 F<programmed>` (on a line of its own before a
//! block that is not a pose, appended to a pose block), so the controller
//! is back in G94 with the programmed feed. At the end of the program, if
//! still in G93, a last `G94` line.

use super::modal::{FeedMode, Motion};
use super::{BlockMeaning, format::push_fixed};
use nalgebra::Vector3;

/// Shortest tip path converted, mm: a block below it only turns the tool.
pub const MIN_TIP_PATH_MM: f64 = 1e-9;

/// What to do with one pose block's feed.
#[derive(Debug, Clone, PartialEq)]
pub enum PoseFeed {
    /// Leave the block's words as they are.
    Keep,
    /// Drop the block's `F`, `G93` and `G94` words and append these words
    /// (with a leading space).
    Append(String),
}

/// The feed mode written so far.
#[derive(Debug, Clone, Default)]
pub struct InverseTime {
    /// The output is in G93 (a block was converted and not yet restored).
    active: bool,
    /// Blocks converted.
    pub converted: usize,
}

/// `value` with enough decimals for 9 significant digits (3 to 12), no
/// trailing zeros.
pub fn feed_text(value: f64) -> String {
    let digits = if value > 0.0 {
        (8 - value.log10().floor() as i32).clamp(3, 12) as usize
    } else {
        3
    };
    let mut s = String::new();
    push_fixed(&mut s, value, digits);
    if s.contains('.') {
        let t = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(t);
    }
    s
}

impl InverseTime {
    /// The feed words of a pose block from `start` (the tip before it, mm,
    /// if known) to `tip` (mm); `rotary_moved` when a written rotary axis
    /// changes.
    pub fn pose_block(
        &mut self,
        meaning: &BlockMeaning,
        start: Option<Vector3<f64>>,
        tip: Vector3<f64>,
        rotary_moved: bool,
    ) -> PoseFeed {
        let feed_mm_min = meaning
            .feed
            .map(|f| f * meaning.feed_units.mm_per_unit())
            .filter(|f| *f > 0.0 && f.is_finite());
        let length = start.map(|s| (tip - s).norm());
        let convert = meaning.motion == Motion::Linear
            && meaning.feed_mode == FeedMode::PerMinute
            && rotary_moved;
        match (convert, feed_mm_min, length) {
            (true, Some(f), Some(l)) if l > MIN_TIP_PATH_MM => {
                let g = if self.active { "" } else { " G93" };
                self.active = true;
                self.converted += 1;
                PoseFeed::Append(format!("{g} F{}", feed_text(f / l)))
            }
            // The block sets G93 or G95 itself: its own words stand.
            _ if self.active && meaning.feed_mode != FeedMode::PerMinute => {
                self.active = false;
                PoseFeed::Keep
            }
            _ if self.active => {
                self.active = false;
                PoseFeed::Append(self.restore_words(meaning))
            }
            _ => PoseFeed::Keep,
        }
    }

    /// `G94` and the programmed feed (in program units) as words.
    fn restore_words(&self, meaning: &BlockMeaning) -> String {
        match meaning
            .feed
            .filter(|_| meaning.feed_mode == FeedMode::PerMinute)
        {
            Some(f) => format!(" G94 F{}", feed_text(f)),
            None => " G94".to_string(),
        }
    }

    /// A line that is not a pose block, with words (`has_words`): the line
    /// to write before it to be back in G94, if needed (`meaning` is the
    /// state before the line).
    pub fn before_other(
        &mut self,
        has_words: bool,
        feed: Option<f64>,
        crlf: bool,
    ) -> Option<String> {
        if !(self.active && has_words) {
            return None;
        }
        self.active = false;
        let mut s = "G94".to_string();
        if let Some(f) = feed {
            s.push_str(" F");
            s.push_str(&feed_text(f));
        }
        s.push_str(if crlf { "\r\n" } else { "\n" });
        Some(s)
    }

    /// The end of the program: a last `G94` line if still in G93.
    pub fn end(&mut self) -> Option<&'static str> {
        std::mem::take(&mut self.active).then_some("G94\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feed_text_keeps_nine_significant_digits() {
        assert_eq!(feed_text(12.5), "12.5");
        assert_eq!(feed_text(1.0 / 3.0), "0.333333333");
        assert_eq!(feed_text(12345.678912), "12345.6789");
        assert_eq!(feed_text(0.000123456789), "0.000123456789");
    }
}
