//! The `%` lines that delimit a program on tape (Fanuc, Haas, LinuxCNC):
//! a bare `%` after the program's first block ends it, and a controller
//! reads nothing after that line. CAM systems write text there (NX: "Tool
//! Path Listing has 3 lines.", often without a line end); it is no block,
//! and every command passes it through as it is, unread. A `%` with a
//! name (Sinumerik `%_N_MAIN_MPF`) starts a program and ends none.

use crate::gcode::Line;

/// Follows a program's lines to the `%` that ends it.
#[derive(Debug, Clone, Default)]
pub struct TapeEnd {
    /// A line other than a blank one or a bare `%` has been read.
    content: bool,
    /// The line of the ending `%`, once read.
    ended_at: Option<usize>,
    /// Text after it has been met.
    text_after: bool,
}

/// Where a line stands ([`TapeEnd::read`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TapeLine {
    /// Part of the program (the ending `%` too).
    Program,
    /// After the ending `%`: not read.
    After,
    /// The first line after it that holds text: not read, worth a word
    /// to the user; the line of the `%`.
    FirstText(usize),
}

impl TapeEnd {
    /// Reads `line`, the next of the program: where it stands. A bare `%`
    /// before the first block opens the program.
    pub fn read(&mut self, line: &Line) -> TapeLine {
        if let Some(at) = self.ended_at {
            if self.text_after || line.is_blank() {
                return TapeLine::After;
            }
            self.text_after = true;
            return TapeLine::FirstText(at);
        }
        if line.bytes.trim_ascii() == b"%" {
            if self.content {
                self.ended_at = Some(line.number);
            }
        } else if !line.is_blank() {
            self.content = true;
        }
        TapeLine::Program
    }

    /// Reads `line` ([`TapeEnd::read`]): whether it lies after the end.
    pub fn after_end(&mut self, line: &Line) -> bool {
        self.read(line) != TapeLine::Program
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_line;

    fn read(text: &str) -> Vec<TapeLine> {
        let mut tape = TapeEnd::default();
        text.split_inclusive('\n')
            .enumerate()
            .map(|(i, l)| tape.read(&parse_line(l.as_bytes(), i + 1)))
            .collect()
    }

    #[test]
    fn text_after_the_closing_percent_is_not_read() {
        use TapeLine::{After, FirstText, Program};
        let t = "\n%\nO1000\nG1 X1\nM30\n%\n\nTool Path Listing has 3 lines.\nG1 X2";
        let want = [
            Program,
            Program,
            Program,
            Program,
            Program,
            Program,
            After,
            FirstText(6),
            After,
        ];
        assert_eq!(read(t), want);
        // No opening `%`: the first `%` after a block ends the program.
        assert_eq!(read("G1 X1\n %\nG1 X2\n"), [Program, Program, FirstText(2)]);
        // Only an opening `%`, or none: every line is read.
        assert_eq!(read("%\nG1 X1\nG1 X2\n"), [Program; 3]);
        assert_eq!(read("G1 X1\nG1 X2\n"), [Program; 2]);
        // Sinumerik's named programs, one after another, are all read.
        let t = "%_N_SUB_SPF\nG1 X1\nM17\n%_N_MAIN_MPF\nG1 X2\nM30\n";
        assert_eq!(read(t), [Program; 6]);
    }
}
