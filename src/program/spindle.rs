//! The spindle's speed as a program sets it, for the commands that time a
//! program's moves (`simulate`, `analyze`): a feed per revolution (`G95`,
//! APT `FEDRAT/…,MMPR`) is a feed per minute of F × the spindle's speed.
//!
//! Followed: `S` (revolutions a minute under `G97`, the default; a
//! surface speed under `G96`), `M3`/`M4` (and Fanuc's `M13`/`M14`, the
//! spindle with coolant) turning it, `M5`, `M19` (orientation), `M2` and
//! `M30` stopping it. An `S` in a block with `G50` or `G92` is a speed
//! clamp (Fanuc and Haas lathes), not a speed. Under a constant surface
//! speed (`G96`) the speed follows the tool's radius, which kinpost does
//! not follow: no speed, as when the spindle stands or no `S` was given.

use super::{FeedMode, Units};
use crate::gcode::Line;

/// What the program set of the spindle so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Spindle {
    /// The last `S` given under `G97`, rev/min.
    rpm: Option<f64>,
    /// Constant surface speed (`G96`) on.
    css: bool,
    /// Turning (`M3`, `M4`, `M13`, `M14` since the last stop).
    turning: bool,
}

impl Spindle {
    /// Follows the spindle words of `line`.
    pub fn line(&mut self, line: &Line) {
        let has_g = |v: f64| {
            line.words()
                .any(|w| w.address == "G" && (w.value - v).abs() < 1e-9)
        };
        // The mode first: `G97 S1000` is a speed, `G96 S200` a surface speed.
        if has_g(96.0) {
            self.css = true;
        }
        if has_g(97.0) && self.css {
            self.css = false;
            // The speed the surface speed left: not known.
            self.rpm = None;
        }
        let clamp = has_g(50.0) || has_g(92.0);
        for w in line.words() {
            match w.address.as_str() {
                "S" if !clamp && !self.css => self.rpm = Some(w.value),
                "M" if [3.0, 4.0, 13.0, 14.0].contains(&w.value) => self.turning = true,
                "M" if [5.0, 19.0, 2.0, 30.0].contains(&w.value) => self.turning = false,
                _ => {}
            }
        }
    }

    /// APT CL's `SPINDL/n,RPM` (`rpm`: n, if given; its surface-speed
    /// forms are lowered to `G96 S…` blocks, [`Spindle::line`]) or
    /// `SPINDL/OFF` (`off`).
    pub fn apt(&mut self, rpm: Option<f64>, off: bool) {
        if let Some(n) = rpm {
            (self.rpm, self.css) = (Some(n), false);
        }
        self.turning = !off;
    }

    /// The spindle's speed, rev/min, when it turns at a known one.
    pub fn rpm(&self) -> Option<f64> {
        self.rpm
            .filter(|n| self.turning && !self.css && n.is_finite() && *n > 0.0)
    }

    /// A block's feed `feed` in `mode` and `units` in mm/min: a feed per
    /// minute as given, a feed per revolution times the spindle's speed
    /// ([`Spindle::rpm`]); `None` where there is none (no F, inverse time,
    /// per revolution without a speed).
    pub fn feed_mm_min(&self, mode: FeedMode, feed: Option<f64>, units: Units) -> Option<f64> {
        let per_unit = units.mm_per_unit();
        match mode {
            FeedMode::PerMinute => feed.map(|f| f * per_unit),
            FeedMode::PerRevolution => Some(feed? * per_unit * self.rpm()?),
            FeedMode::InverseTime => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn after(lines: &[&str]) -> Spindle {
        let mut s = Spindle::default();
        for (n, l) in lines.iter().enumerate() {
            s.line(&crate::gcode::parse_line(l.as_bytes(), n + 1));
        }
        s
    }

    #[test]
    fn speeds_follow_the_spindle_words() {
        assert_eq!(after(&["S1000 M3"]).rpm(), Some(1000.0));
        assert_eq!(after(&["M3", "S800"]).rpm(), Some(800.0));
        // Not turning, stopped, or no speed given.
        assert_eq!(after(&["S1000"]).rpm(), None);
        assert_eq!(after(&["S1000 M3", "M5"]).rpm(), None);
        assert_eq!(after(&["M4"]).rpm(), None);
        // A clamp is no speed; a surface speed gives none, and G97 after
        // it needs a new S.
        assert_eq!(after(&["S500 M3", "G50 S3000"]).rpm(), Some(500.0));
        assert_eq!(after(&["G96 S200 M3"]).rpm(), None);
        assert_eq!(after(&["S500 M3", "G96 S200", "G97"]).rpm(), None);
        assert_eq!(after(&["G96 S200 M3", "G97 S1200"]).rpm(), Some(1200.0));
        // G97 while already in G97 keeps the speed.
        assert_eq!(after(&["S500 M3", "G97 G95 G1 X1"]).rpm(), Some(500.0));
    }

    #[test]
    fn feeds_per_revolution_become_feeds_per_minute() {
        let s = after(&["S500 M3"]);
        let mm = Some(0.1);
        assert_eq!(
            s.feed_mm_min(FeedMode::PerRevolution, mm, Units::Mm),
            Some(50.0)
        );
        // 0.004 in/rev at 500 rev/min: 2 in/min, 50.8 mm/min.
        let inch = s.feed_mm_min(FeedMode::PerRevolution, Some(0.004), Units::Inch);
        assert!((inch.unwrap() - 50.8).abs() < 1e-12);
        assert_eq!(
            s.feed_mm_min(FeedMode::PerMinute, Some(600.0), Units::Mm),
            Some(600.0)
        );
        assert_eq!(
            s.feed_mm_min(FeedMode::InverseTime, Some(2.0), Units::Mm),
            None
        );
        assert_eq!(
            s.feed_mm_min(FeedMode::PerRevolution, None, Units::Mm),
            None
        );
        // APT: SPINDL/n,RPM sets the speed and turns; SPINDL/OFF stops;
        // SPINDL/ON turns at the last speed.
        let mut apt = Spindle::default();
        apt.apt(Some(800.0), false);
        assert_eq!(apt.rpm(), Some(800.0));
        apt.apt(None, true);
        assert_eq!(apt.rpm(), None);
        apt.apt(None, false);
        assert_eq!(apt.rpm(), Some(800.0));
        assert_eq!(
            apt.feed_mm_min(FeedMode::PerRevolution, mm, Units::Mm),
            Some(80.0)
        );
    }
}
