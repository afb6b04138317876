//! The `%` lines that delimit a program on tape (Fanuc, Haas, LinuxCNC):
//! a `%` after the program's first block ends it, and a controller reads
//! nothing after that line. CAM systems write text there (NX: "Tool Path
//! Listing has 3 lines."), often without a line end; it is no block, and
//! every command passes it through as it is, unread.

use crate::gcode::Line;

/// Follows a program's lines to the `%` that ends it.
#[derive(Debug, Clone, Default)]
pub struct TapeEnd {
    /// A line other than a blank one or a `%` has been read.
    content: bool,
    /// The ending `%` has been read.
    ended: bool,
}

impl TapeEnd {
    /// Reads `line`, the next of the program; whether it lies after the
    /// `%` that ends the program (the `%` itself does not). A `%` before
    /// the first block opens the program.
    pub fn after_end(&mut self, line: &Line) -> bool {
        if self.ended {
            return true;
        }
        if line.is_percent() {
            self.ended = self.content;
        } else if !line.is_blank() {
            self.content = true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_line;

    fn after(text: &str) -> Vec<bool> {
        let mut tape = TapeEnd::default();
        text.split_inclusive('\n')
            .enumerate()
            .map(|(i, l)| tape.after_end(&parse_line(l.as_bytes(), i + 1)))
            .collect()
    }

    #[test]
    fn text_after_the_closing_percent_is_not_read() {
        let t = "\n%\nO1000\nG1 X1\nM30\n%\nTool Path Listing has 3 lines.";
        assert_eq!(after(t), [false, false, false, false, false, false, true]);
        // No opening `%`: the first `%` after a block ends the program.
        assert_eq!(after("G1 X1\n%\nG1 X2\n"), [false, false, true]);
        // Only an opening `%`, or none: every line is read.
        assert_eq!(after("%\nG1 X1\nG1 X2\n"), [false, false, false]);
        assert_eq!(after("G1 X1\nG1 X2\n"), [false, false]);
    }
}
