//! Tool length compensation a program switches on by itself (`G43 Hn`,
//! `G43.1`, `G44`): where the machine's chain already ends at the tool's
//! tip (`--tool-length`, `--tool-table`, a machine file's `tool_length`),
//! the axis words of a converted pose include the tool, and the controller
//! would add its length a second time. `G43.4`/`G43.5` are tool centre
//! point control, which kinpost writes as `G49`; `G49` ends it.

use super::modal::WordRef;
use crate::gcode::Line;

/// Where plain tool length compensation was switched on, if it is on.
#[derive(Debug, Clone, Default)]
pub struct LengthCompensation {
    on: Option<Place>,
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
    pub fn block(&mut self, words: &[WordRef<'_>], line: &Line) {
        for w in words.iter().filter(|w| w.address == "G") {
            if w.value == 43.0 || w.value == 43.1 || w.value == 44.0 {
                self.on = Some(Place {
                    line: line.number,
                    col: line.items.get(w.item).map_or(0, |i| i.start + 1),
                    text: line.text_lossy(),
                });
            } else if w.value == 49.0 || w.value == 43.4 || w.value == 43.5 {
                self.on = None;
            }
        }
    }

    /// The word that switched plain tool length compensation on, while it
    /// is on.
    pub fn on(&self) -> Option<&Place> {
        self.on.as_ref()
    }
}
