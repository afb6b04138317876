//! The `%` lines that delimit a program on tape (Fanuc, Haas, LinuxCNC).
//! A controller loading a file reads from the opening `%` to the closing
//! one. Which bare `%` is which: the first one opens the program, whatever
//! stands before it (a DNC header, a comment, NX's "Information listing";
//! kinpost reads those lines as blocks, so that nothing that moves the tool
//! passes unread); a later one, after a block, closes it, and so does a
//! `%` after the main program's end (`M2`, `M30`) in a file that has no
//! opening one. CAM systems write text after the closing `%` (NX: "Tool
//! Path Listing has 3 lines.", often without a line end); it is no block,
//! and every command passes it through as it is, unread. A `%` with a
//! name (Sinumerik `%_N_MAIN_MPF`) starts a program and ends none.

use crate::gcode::Line;

/// Whether `line` is a bare `%` (blanks around it allowed): the mark that
/// opens and ends a program on tape.
pub fn is_tape_mark(line: &Line) -> bool {
    line.bytes.trim_ascii() == b"%"
}

/// Whether `line` ends the main program (`M2`, `M30`): what follows it
/// in the file runs only when called.
pub fn ends_main_program(line: &Line) -> bool {
    line.words()
        .any(|w| w.address == "M" && (w.value == 2.0 || w.value == 30.0))
}

/// Follows a program's lines to the `%` that ends it.
#[derive(Debug, Clone, Default)]
pub struct TapeEnd {
    /// The opening `%` has been read.
    opened: bool,
    /// A line other than a blank one or a bare `%` has been read since the
    /// opening `%` (since the start where none was).
    content: bool,
    /// The main program's end (`M2`, `M30`) has been read.
    main_ended: bool,
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
    /// Reads `line`, the next of the program: where it stands.
    pub fn read(&mut self, line: &Line) -> TapeLine {
        if let Some(at) = self.ended_at {
            if self.text_after || line.is_blank() {
                return TapeLine::After;
            }
            self.text_after = true;
            return TapeLine::FirstText(at);
        }
        if is_tape_mark(line) {
            if self.content && (self.opened || self.main_ended) {
                self.ended_at = Some(line.number);
            } else if !self.opened {
                // The opening `%`: what stood before it was a leader.
                *self = TapeEnd {
                    opened: true,
                    ..TapeEnd::default()
                };
            }
        } else if !line.is_blank() {
            self.content = true;
            // Only a file without an opening `%` needs to know.
            if !self.opened && !self.main_ended {
                self.main_ended = ends_main_program(line);
            }
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
        // No opening `%`: a `%` after the main program's end closes it.
        assert_eq!(
            read("G1 X1\nM30\n %\nG1 X2\n"),
            [Program, Program, Program, FirstText(3)]
        );
        // Before it, a `%` after a block is the opening one (a header, a
        // comment or a listing before it), and the second one closes.
        let t = "(JOB 42)\n%\nO1000\nG1 X1\n%\nG1 X2\n";
        assert_eq!(
            read(t),
            [Program, Program, Program, Program, Program, FirstText(5)]
        );
        assert_eq!(read("G1 X1\n%\nG1 X2\n"), [Program; 3]);
        // Two opening marks in a row: the second closes nothing.
        assert_eq!(read("%\n%\nG1 X1\nM30\n"), [Program; 4]);
        // Only an opening `%`, or none: every line is read.
        assert_eq!(read("%\nG1 X1\nG1 X2\n"), [Program; 3]);
        assert_eq!(read("G1 X1\nG1 X2\n"), [Program; 2]);
        // Sinumerik's named programs, one after another, are all read.
        let t = "%_N_SUB_SPF\nG1 X1\nM17\n%_N_MAIN_MPF\nG1 X2\nM30\n";
        assert_eq!(read(t), [Program; 6]);
    }
}
