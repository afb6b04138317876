//! Tool length compensation a program switches on by itself (`G43 Hn`,
//! `G43.1`, `G43.2`, `G44`): where the machine's chain already ends at the tool's
//! tip (`--tool-length`, `--tool-table`, a machine file's `tool_length`),
//! the axis words of a converted pose include the tool, and the controller
//! would add its length a second time. `G43.4`/`G43.5` are tool centre
//! point control, which kinpost writes as `G49`; `G49` ends it.
//!
//! On a Sinumerik the tool offset `D` (`D1`, and `D1` by default after a
//! tool change) stays on through `TRAFOOF`, which kinpost writes for
//! `TRAORI`: only `D0` switches it off. Under `TRAORI` a `D` other than 0
//! counts as the compensation being on.

use super::modal::WordRef;
use crate::gcode::Line;

/// Where plain tool length compensation was switched on, if it is on.
#[derive(Debug, Clone, Default)]
pub struct LengthCompensation {
    on: Option<Place>,
    /// The Sinumerik `D` or tool change that put a tool offset on, until `D0`.
    sinumerik_d: Option<Place>,
    /// Pose mode was last switched on by `TRAORI` (not `G43.4`/`G43.5`).
    traori: bool,
}

/// The `G43`/`G44` word that switched it on.
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    /// 1-based line.
    pub line: usize,
    /// 1-based column of the word.
    pub col: usize,
    /// The line's text.
    pub text: String,
}

impl LengthCompensation {
    /// Follows the G words of a block (`words`, of `line`).
    /// `traori`: the block switches pose mode on with `TRAORI`.
    pub fn block(&mut self, words: &[WordRef<'_>], line: &Line, traori: bool) {
        let place = |w: &WordRef<'_>| Place {
            line: line.number,
            col: line.items.get(w.item).map_or(0, |i| i.start + 1),
            text: line.text_lossy(),
        };
        self.traori |= traori;
        let d0 = words.iter().any(|w| w.address == "D" && w.value == 0.0);
        for w in words {
            match w.address {
                // LinuxCNC's G43.2 adds another tool's length on top.
                "G" if [43.0, 43.1, 43.2, 44.0].contains(&w.value) => {
                    self.on = Some(place(w));
                }
                "G" if w.value == 49.0 => self.on = None,
                // Tool centre point control (Haas G234 in G43's group too).
                "G" if w.value == 43.4 || w.value == 43.5 || w.value == 234.0 => {
                    self.on = None;
                    self.traori = false;
                }
                "D" if w.value != 0.0 => self.sinumerik_d = Some(place(w)),
                "T" if !d0 && self.sinumerik_d.is_none() => self.sinumerik_d = Some(place(w)),
                _ => {}
            }
        }
        if d0 {
            self.sinumerik_d = None;
        }
    }

    /// Whether plain tool length compensation (`G43`, `G43.1`, `G43.2`,
    /// `G44`) is on: the controller then moves the tool's tip, not the
    /// gauge line, to a block's machine axis words.
    pub fn plain_on(&self) -> bool {
        self.on.is_some()
    }

    /// The word that switched tool length compensation on, while it is on,
    /// and what it is: plain `G43`/`G43.1`/`G44`, or under `TRAORI` a
    /// Sinumerik tool offset `D` (or a tool change, which selects `D1`).
    pub fn on(&self) -> Option<(&Place, &'static str)> {
        match (&self.on, &self.sinumerik_d) {
            (Some(p), _) => Some((p, "tool length compensation (G43/G43.1/G43.2/G44) is on")),
            (None, Some(p)) if self.traori => Some((
                p,
                "a Sinumerik tool offset (D other than 0, or D1 selected by a tool change) is on, and TRAFOOF (which kinpost writes for TRAORI) leaves it on",
            )),
            _ => None,
        }
    }
}
