//! Streaming: one [`Line`] at a time from any [`BufRead`], and an echo that
//! re-emits a program from its parse tree.

use std::io::{self, BufRead, Write};

use super::block::Line;
use super::parse::parse_line;

/// Reads a program one physical line at a time and parses each line.
///
/// An [`Iterator`] of `io::Result<Line>`. It reads with
/// [`BufRead::read_until`]`(b'\n')` into one reused buffer, so memory depends
/// on the longest line, not on the length of the file. After an I/O error
/// the iterator ends.
#[derive(Debug)]
pub struct LineReader<R: BufRead> {
    reader: R,
    buf: Vec<u8>,
    number: usize,
    done: bool,
}

impl<R: BufRead> LineReader<R> {
    /// A reader whose first line is line 1.
    pub fn new(reader: R) -> Self {
        LineReader {
            reader,
            buf: Vec::with_capacity(256),
            number: 0,
            done: false,
        }
    }

    /// The number of the last line returned (0 before the first).
    pub fn line_number(&self) -> usize {
        self.number
    }

    /// The underlying reader.
    pub fn into_inner(self) -> R {
        self.reader
    }
}

impl<R: BufRead> Iterator for LineReader<R> {
    type Item = io::Result<Line>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        self.buf.clear();
        match self.reader.read_until(b'\n', &mut self.buf) {
            Ok(0) => {
                self.done = true;
                None
            }
            Ok(_) => {
                self.number += 1;
                Some(Ok(parse_line(&self.buf, self.number)))
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}

/// Parse `r` line by line and write every line back from its parse tree
/// ([`Line::write_to`]), not by copying the input. The output is byte for
/// byte the input.
pub fn echo<R: BufRead, W: Write>(r: R, mut w: W) -> io::Result<()> {
    for line in LineReader::new(r) {
        line?.write_to(&mut w)?;
    }
    w.flush()
}
