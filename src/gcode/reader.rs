//! Streaming: one [`Line`] at a time from any [`BufRead`], and an echo that
//! re-emits a program from its parse tree.

use std::io::{self, BufRead, Write};

use super::block::Line;
use super::parse::parse_items;

/// Reads a program one physical line at a time and parses each line.
///
/// Two ways to read:
///
/// - [`LineReader::next_line`] lends out the reader's own [`Line`], read
///   and parsed in place: its byte and item buffers are reused from line to
///   line, so after the first lines reading allocates nothing. The way to
///   stream a long program.
/// - As an [`Iterator`] of `io::Result<Line>`, each line an owned copy.
///
/// Lines are read with [`BufRead::read_until`]`(b'\n')`, so memory depends
/// on the longest line, not on the length of the file. After an I/O error
/// the reader ends.
///
/// ```
/// use kinpost::gcode::LineReader;
///
/// let mut reader = LineReader::new(&b"G1 X1\nY2\n"[..]);
/// let mut words = 0;
/// while let Some(line) = reader.next_line() {
///     words += line.unwrap().words().count();
/// }
/// assert_eq!(words, 3);
/// ```
#[derive(Debug)]
pub struct LineReader<R: BufRead> {
    reader: R,
    line: Line,
    done: bool,
}

impl<R: BufRead> LineReader<R> {
    /// A reader whose first line is line 1.
    pub fn new(reader: R) -> Self {
        let mut line = Line::default();
        line.bytes.reserve(256);
        line.items.reserve(32);
        LineReader {
            reader,
            line,
            done: false,
        }
    }

    /// The number of the last line returned (0 before the first).
    pub fn line_number(&self) -> usize {
        self.line.number
    }

    /// The underlying reader.
    pub fn into_inner(self) -> R {
        self.reader
    }

    /// Reads and parses the next line into the reader's own [`Line`] and
    /// lends it out until the next call; `None` at the end of the input
    /// (and after an I/O error has been returned).
    pub fn next_line(&mut self) -> Option<io::Result<&Line>> {
        if self.done {
            return None;
        }
        self.line.bytes.clear();
        match self.reader.read_until(b'\n', &mut self.line.bytes) {
            Ok(0) => {
                self.done = true;
                self.line.items.clear();
                None
            }
            Ok(_) => {
                let line = &mut self.line;
                line.number += 1;
                parse_items(&line.bytes, line.number, &mut line.items);
                debug_assert!(line.is_tiled(), "items do not tile line {}", line.number);
                Some(Ok(&self.line))
            }
            Err(e) => {
                self.done = true;
                self.line.items.clear();
                Some(Err(e))
            }
        }
    }
}

impl<R: BufRead> Iterator for LineReader<R> {
    type Item = io::Result<Line>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_line().map(|r| r.cloned())
    }
}

/// Parse `r` line by line and write every line back from its parse tree
/// ([`Line::write_to`]), not by copying the input. The output is byte for
/// byte the input.
pub fn echo<R: BufRead, W: Write>(r: R, mut w: W) -> io::Result<()> {
    let mut reader = LineReader::new(r);
    while let Some(line) = reader.next_line() {
        line?.write_to(&mut w)?;
    }
    w.flush()
}
