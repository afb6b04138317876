//! What a program holds, counted line by line (for `kinpost parse`).

use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, BufRead};

use serde::Serialize;

use super::address::Address;
use super::block::{ItemKind, Line};
use super::reader::LineReader;

/// Counts of what the lines of a program hold.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Summary {
    /// Physical lines.
    pub lines: usize,
    /// Bytes read, line endings included.
    pub bytes: u64,
    /// Lines holding only blanks and a line ending.
    pub blank_lines: usize,
    /// Lines holding at least one word.
    pub blocks_with_words: usize,
    /// Words in all lines.
    pub words: usize,
    /// Comments (`( )` and `;`).
    pub comments: usize,
    /// Keyword items in all lines.
    pub keyword_items: usize,
    /// Lines with something the parser did not understand.
    pub opaque_lines: usize,
    /// The first such line, if any.
    pub first_opaque_line: Option<usize>,
    /// `%` lines.
    pub percent_lines: usize,
    /// Lines starting with a block delete `/`.
    pub block_delete_lines: usize,
    /// RepRap `*` checksums.
    pub checksums: usize,
    /// Lines ending in `\r\n`.
    pub crlf_lines: usize,
    /// Lines that are not valid UTF-8.
    pub non_utf8_lines: usize,
    /// `false` if the last line has no line ending.
    pub final_newline: bool,
    /// How many words have each address (`"G"`, `"X"`, `"A3"`).
    pub addresses: BTreeMap<String, usize>,
    /// How often each keyword occurs (`"TRAORI"`).
    pub keywords: BTreeMap<String, usize>,
}

impl Summary {
    /// Count one more line.
    pub fn add(&mut self, line: &Line) {
        self.add_counting(line, None);
    }

    /// [`Summary::add`], with the words' addresses counted in `tally` (to be
    /// merged into [`Summary::addresses`] at the end) when given.
    fn add_counting(&mut self, line: &Line, mut tally: Option<&mut AddressTally>) {
        self.lines += 1;
        self.bytes += line.bytes.len() as u64;
        if line.is_blank() {
            self.blank_lines += 1;
        }
        let mut words_here = 0;
        for item in &line.items {
            match &item.kind {
                ItemKind::Word(w) => {
                    words_here += 1;
                    match tally.as_deref_mut() {
                        Some(t) => t.add(w.address),
                        None => count(&mut self.addresses, &w.address),
                    }
                }
                ItemKind::Keyword(k) => {
                    self.keyword_items += 1;
                    count(&mut self.keywords, k);
                }
                ItemKind::Comment => self.comments += 1,
                ItemKind::Checksum(_) => self.checksums += 1,
                _ => {}
            }
        }
        self.words += words_here;
        if words_here > 0 {
            self.blocks_with_words += 1;
        }
        if line.has_opaque() {
            self.opaque_lines += 1;
            self.first_opaque_line.get_or_insert(line.number);
        }
        if line.is_percent() {
            self.percent_lines += 1;
        }
        if line.has_block_delete() {
            self.block_delete_lines += 1;
        }
        let ending = line.line_ending();
        if ending.len() >= 2 && ending.ends_with(b"\n") {
            self.crlf_lines += 1;
        }
        if std::str::from_utf8(&line.bytes).is_err() {
            self.non_utf8_lines += 1;
        }
        self.final_newline = ending.ends_with(b"\n");
    }
}

/// Word counts per address while a program streams through: one-letter
/// addresses in an array, others in a map keyed by [`Address`] (no lookup
/// of a `String` key per word).
#[derive(Default)]
struct AddressTally {
    letters: [usize; 26],
    others: BTreeMap<Address, usize>,
}

impl AddressTally {
    fn add(&mut self, a: Address) {
        match a.as_bytes() {
            [l @ b'A'..=b'Z'] => self.letters[usize::from(l - b'A')] += 1,
            _ => *self.others.entry(a).or_default() += 1,
        }
    }

    /// Adds the counts to `map`.
    fn merge_into(self, map: &mut BTreeMap<String, usize>) {
        let letters = (b'A'..=b'Z').zip(self.letters).filter(|&(_, n)| n > 0);
        for (l, n) in letters {
            *map.entry(char::from(l).to_string()).or_default() += n;
        }
        for (a, n) in self.others {
            *map.entry(a.to_string()).or_default() += n;
        }
    }
}

/// Add one to `key`'s count (allocating the key only the first time).
fn count(map: &mut BTreeMap<String, usize>, key: &str) {
    match map.get_mut(key) {
        Some(n) => *n += 1,
        None => {
            map.insert(key.to_string(), 1);
        }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "lines:             {}", self.lines)?;
        writeln!(f, "bytes:             {}", self.bytes)?;
        writeln!(f, "blank lines:       {}", self.blank_lines)?;
        writeln!(f, "blocks with words: {}", self.blocks_with_words)?;
        writeln!(f, "words:             {}", self.words)?;
        writeln!(f, "comments:          {}", self.comments)?;
        writeln!(f, "keywords:          {}", self.keyword_items)?;
        match self.first_opaque_line {
            Some(l) => writeln!(
                f,
                "opaque lines:      {} (first: line {l})",
                self.opaque_lines
            )?,
            None => writeln!(f, "opaque lines:      0")?,
        }
        writeln!(f, "% lines:           {}", self.percent_lines)?;
        writeln!(f, "block deletes:     {}", self.block_delete_lines)?;
        writeln!(f, "checksums:         {}", self.checksums)?;
        writeln!(f, "CRLF lines:        {}", self.crlf_lines)?;
        writeln!(f, "non-UTF-8 lines:   {}", self.non_utf8_lines)?;
        writeln!(
            f,
            "final newline:     {}",
            if self.final_newline || self.lines == 0 {
                "yes"
            } else {
                "no"
            }
        )?;
        let join = |m: &BTreeMap<String, usize>| {
            m.iter()
                .map(|(k, n)| format!("{k}:{n}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        writeln!(f, "addresses:         {}", join(&self.addresses))?;
        write!(f, "keyword counts:    {}", join(&self.keywords))
    }
}

/// Read a whole program from `reader` and count what its lines hold.
/// Streams: memory does not grow with the number of lines.
pub fn summarize<R: BufRead>(reader: R) -> io::Result<Summary> {
    let mut s = Summary::default();
    let mut tally = AddressTally::default();
    let mut lines = LineReader::new(reader);
    while let Some(line) = lines.next_line() {
        s.add_counting(line?, Some(&mut tally));
    }
    tally.merge_into(&mut s.addresses);
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Streaming with the tally counts what adding line by line counts.
    #[test]
    fn summarize_counts_as_add_does() {
        let src = b"G1 X1 y2 A3=4 R12=1 AP=3\nTRAORI\nx5 z6 ; c\n(only)\n#1=2\nG0 X7\n";
        let mut by_line = Summary::default();
        for line in LineReader::new(&src[..]) {
            by_line.add(&line.unwrap());
        }
        let streamed = summarize(&src[..]).unwrap();
        assert_eq!(streamed, by_line);
        assert_eq!(streamed.addresses.get("X"), Some(&3));
        assert_eq!(streamed.addresses.get("A3"), Some(&1));
        assert_eq!(streamed.addresses.get("R12"), Some(&1));
    }
}
