//! The lossless block model: one [`Line`] per physical line of a program,
//! split into [`Item`]s that tile the line's bytes exactly.

use std::io::{self, Write};

use super::address::Address;

/// One physical line of an NC program, exactly as read, with its parse.
///
/// The items tile [`Line::bytes`]: the first starts at 0, each one starts
/// where the previous one ended, the last one ends at `bytes.len()`, and none
/// is empty. Writing every item's bytes in order therefore reproduces the
/// line byte for byte ([`Line::write_to`]).
///
/// The default is an empty line numbered 0, a buffer for
/// [`parse_line_into`](super::parse_line_into).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Line {
    /// 1-based line number in the file.
    pub number: usize,
    /// The whole line, including its line ending (if it has one).
    pub bytes: Vec<u8>,
    /// The items, in order, tiling `bytes`.
    pub items: Vec<Item>,
}

/// A piece of a [`Line`]: a byte range and what it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// Byte offset of the first byte in [`Line::bytes`].
    pub start: usize,
    /// Byte offset one past the last byte in [`Line::bytes`].
    pub end: usize,
    /// What the bytes are.
    pub kind: ItemKind,
}

/// What an [`Item`] is.
#[derive(Debug, Clone, PartialEq)]
pub enum ItemKind {
    /// A UTF-8 byte order mark (`EF BB BF`) at the very start of line 1.
    Bom,
    /// A run of spaces and tabs between items.
    Space,
    /// The line ending: `\n`, `\r\n` (any number of `\r` before the `\n`),
    /// or trailing `\r` bytes on a last line without `\n`. Absent on a last
    /// line that ends without a newline.
    EndOfLine,
    /// The `%` program delimiter (first thing on its line).
    Percent,
    /// Block delete: `/` or `/1` .. `/9` at the start of a block.
    BlockDelete,
    /// `( ... )` or `; ...` to the end of the line; may hold any bytes.
    Comment,
    /// A RepRap checksum `*71` (the value after the `*`).
    Checksum(u32),
    /// An address with a number: `G1`, `X-1.5`, `N10`, `A3=0.5`.
    Word(Word),
    /// A bare alphabetic identifier of two or more letters, uppercased:
    /// `TRAORI`, `TRAFOOF`, `SUPA`.
    Keyword(String),
    /// Anything the parser does not understand, kept verbatim: expressions,
    /// parameters, o-word flow, macro calls, malformed numbers. Once a line
    /// holds something not understood, the rest of the line (up to its line
    /// ending) is one `Opaque` item.
    Opaque,
}

/// An address and its number.
#[derive(Debug, Clone, PartialEq)]
pub struct Word {
    /// The address, uppercased: `"X"`, `"G"`, `"A3"`, `"R1"`, `"AP"`
    /// (inline, no allocation; compares with `&str`).
    pub address: Address,
    /// The value of the number.
    pub value: f64,
    /// Byte offset in [`Line::bytes`] where the number's text starts (at its
    /// sign if it has one).
    pub value_start: usize,
    /// Byte offset one past the number's last digit or point.
    pub value_end: usize,
    /// `true` when written with `=` (`A3=0.5`, `X=10`).
    pub assign: bool,
}

impl Word {
    /// `true` if the address is `address` (compared case-insensitively).
    pub fn is(&self, address: &str) -> bool {
        self.address.is(address)
    }
}

impl Item {
    /// Length in bytes.
    pub fn len(&self) -> usize {
        self.end.saturating_sub(self.start)
    }

    /// `true` if the item covers no bytes (never the case for parsed lines).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The 1-based column of the item's first byte.
    pub fn col(&self) -> usize {
        self.start + 1
    }
}

impl Line {
    /// The bytes of `item` (empty if its range does not lie in this line).
    pub fn item_bytes(&self, item: &Item) -> &[u8] {
        self.bytes.get(item.start..item.end).unwrap_or(&[])
    }

    /// The source text of a word's number (`"-1.5"`, `"5."`, `"- 3"`).
    pub fn value_text(&self, word: &Word) -> &[u8] {
        self.bytes
            .get(word.value_start..word.value_end)
            .unwrap_or(&[])
    }

    /// Re-emit from the parse tree: the concatenation of every item's bytes.
    pub fn write_to<W: Write>(&self, w: &mut W) -> io::Result<()> {
        for item in &self.items {
            w.write_all(self.item_bytes(item))?;
        }
        Ok(())
    }

    /// The words, in order.
    pub fn words(&self) -> impl Iterator<Item = &Word> {
        self.items.iter().filter_map(|it| match &it.kind {
            ItemKind::Word(w) => Some(w),
            _ => None,
        })
    }

    /// The first word with address `address` (case-insensitive), if any.
    pub fn word(&self, address: &str) -> Option<&Word> {
        self.words().find(|w| w.is(address))
    }

    /// The keywords (uppercased), in order.
    pub fn keywords(&self) -> impl Iterator<Item = &str> {
        self.items.iter().filter_map(|it| match &it.kind {
            ItemKind::Keyword(k) => Some(k.as_str()),
            _ => None,
        })
    }

    /// The comments' bytes, delimiters included (`(...)` or `;...`).
    pub fn comments(&self) -> impl Iterator<Item = &[u8]> {
        self.items
            .iter()
            .filter(|it| it.kind == ItemKind::Comment)
            .map(|it| self.item_bytes(it))
    }

    /// The first opaque item, if any.
    pub fn opaque(&self) -> Option<&Item> {
        self.items.iter().find(|it| it.kind == ItemKind::Opaque)
    }

    /// `true` if part of the line was not understood.
    pub fn has_opaque(&self) -> bool {
        self.opaque().is_some()
    }

    /// `true` if the block starts with a block delete (`/`).
    pub fn has_block_delete(&self) -> bool {
        self.items.iter().any(|it| it.kind == ItemKind::BlockDelete)
    }

    /// `true` if the line is a `%` program delimiter line.
    pub fn is_percent(&self) -> bool {
        self.items.iter().any(|it| it.kind == ItemKind::Percent)
    }

    /// `true` if the line holds nothing but spaces and its line ending.
    pub fn is_blank(&self) -> bool {
        self.items
            .iter()
            .all(|it| matches!(it.kind, ItemKind::Space | ItemKind::EndOfLine))
    }

    /// The line ending's bytes (empty on a last line without a newline).
    pub fn line_ending(&self) -> &[u8] {
        match self.items.last() {
            Some(it) if it.kind == ItemKind::EndOfLine => self.item_bytes(it),
            _ => &[],
        }
    }

    /// The line without its line ending.
    pub fn content(&self) -> &[u8] {
        let end = self.bytes.len() - self.line_ending().len();
        &self.bytes[..end]
    }

    /// The line without its line ending, as text (invalid UTF-8 replaced),
    /// for messages.
    pub fn text_lossy(&self) -> String {
        String::from_utf8_lossy(self.content()).into_owned()
    }

    /// `true` if the items tile [`Line::bytes`] exactly: contiguous, no
    /// gaps, no overlaps, none empty, and every word's number inside its item.
    pub fn is_tiled(&self) -> bool {
        let mut pos = 0;
        for it in &self.items {
            if it.start != pos || it.end <= it.start {
                return false;
            }
            if let ItemKind::Word(w) = &it.kind
                && !(it.start <= w.value_start
                    && w.value_start < w.value_end
                    && w.value_end <= it.end)
            {
                return false;
            }
            pos = it.end;
        }
        pos == self.bytes.len()
    }
}
