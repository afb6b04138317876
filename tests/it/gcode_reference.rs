//! The G-code line parser as it was before the allocation-free rewrite
//! (generic nom combinators, one alternative tried after the other, a
//! `String` per address), kept as the oracle of the differential tests in
//! `tests/it/gcode_differential.rs`. Its only change: an `=` address longer
//! than 31 bytes is not read as an address (`Address::MAX_LEN`).

#![allow(dead_code)]

/// What an item is, with the word's value as bits (exact comparison).
#[derive(Debug, Clone, PartialEq)]
pub enum RefKind {
    Bom,
    Space,
    EndOfLine,
    Percent,
    BlockDelete,
    Comment,
    Checksum(u32),
    Word {
        address: String,
        value_bits: u64,
        value_start: usize,
        value_end: usize,
        assign: bool,
    },
    Keyword(String),
    Opaque,
}

/// An item: byte range and kind.
#[derive(Debug, Clone, PartialEq)]
pub struct RefItem {
    pub start: usize,
    pub end: usize,
    pub kind: RefKind,
}

use nom::{
    IResult, Offset, Parser,
    branch::alt,
    bytes::complete::{tag, take_till, take_while, take_while1},
    character::complete::{char, digit0, digit1, one_of, satisfy},
    combinator::{opt, recognize},
};

type In<'a> = &'a [u8];
type PResult<'a, O> = IResult<In<'a>, O, ()>;

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Keywords that, after an o-word number, make the line LinuxCNC
/// subroutine / flow control (kept [`RefKind::Opaque`]).
const OWORD_KEYWORDS: &[&str] = &[
    "sub",
    "endsub",
    "call",
    "return",
    "if",
    "elseif",
    "else",
    "endif",
    "do",
    "while",
    "endwhile",
    "repeat",
    "endrepeat",
    "break",
    "continue",
];

/// Spellings that must never be read as numbers, even as a keyword's tail
/// (`XNAN`, `Xinf`).
const NON_FINITE: &[&str] = &["nan", "inf", "infinity"];

/// A blank: a space, a tab, or a page layout byte of old listings (a form
/// feed, a vertical tab), which separates like a space.
fn is_blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | 0x0b | 0x0c)
}

/// `blank = ( " " | tab | vt | ff ), { " " | tab | vt | ff }`
fn blank(i: In) -> PResult<In> {
    take_while1(is_blank).parse_complete(i)
}

fn blank0(i: In) -> PResult<In> {
    take_while(is_blank).parse_complete(i)
}

/// `paren_comment = "(", { any byte - ")" }, ")"`
fn paren_comment(i: In) -> PResult<In> {
    recognize((char('('), take_till(|b| b == b')'), char(')'))).parse_complete(i)
}

/// `semicolon_comment = ";", { any byte }` (to the end of the line body)
fn semicolon_comment(i: In) -> PResult<In> {
    recognize((char(';'), take_while(|_| true))).parse_complete(i)
}

fn comment(i: In) -> PResult<In> {
    alt((paren_comment, semicolon_comment)).parse_complete(i)
}

/// Does `rest` (what follows an item) allow the item to end here?
///
/// After a plain word: the end of the line, a blank, the next word's letter,
/// a comment or a checksum.
fn ends_plain_word(rest: In) -> bool {
    match rest.first() {
        None => true,
        Some(&b) => is_blank(b) || b.is_ascii_alphabetic() || matches!(b, b'(' | b';' | b'*'),
    }
}

/// After an `=` word, a keyword or a checksum: the end of the line, a blank
/// or a `;` comment (Siemens puts arguments and expressions right after
/// these, so anything else is not understood).
fn ends_separated(rest: In) -> bool {
    match rest.first() {
        None => true,
        Some(&b) => is_blank(b) || b == b';',
    }
}

/// After a checksum: as [`ends_separated`], or a `(` comment.
fn ends_checksum(rest: In) -> bool {
    ends_separated(rest) || rest.first() == Some(&b'(')
}

/// `unsigned = digit, { digit }, [ ".", { digit } ] | ".", digit, { digit }`
fn unsigned(i: In) -> PResult<In> {
    alt((
        recognize((digit1, opt((char('.'), digit0)))),
        recognize((char('.'), digit1)),
    ))
    .parse_complete(i)
}

/// `number = [ sign, { blank } ], unsigned`, returned as its source text.
/// No exponent: in G-code `E` is an address (`X1E5` is `X1 E5`).
fn number_text(i: In) -> PResult<In> {
    recognize((opt((one_of("+-"), blank0)), unsigned)).parse_complete(i)
}

/// The value of a number's source text; `None` if it does not fit in an
/// f64 (400 digits), so that an overflow never turns silently into `inf`.
fn number_value(text: In) -> Option<f64> {
    let v: f64 = if text.iter().any(|&b| is_blank(b)) {
        let s: String = text
            .iter()
            .filter(|&&b| !is_blank(b))
            .map(|&b| char::from(b))
            .collect();
        s.parse().ok()?
    } else {
        // Sign, digits and point only: always ASCII.
        std::str::from_utf8(text).ok()?.parse().ok()?
    };
    v.is_finite().then_some(v)
}

/// A number with its value: `(rest, (text, value))`.
fn number(i: In) -> PResult<(In, f64)> {
    let (rest, text) = number_text(i)?;
    match number_value(text) {
        Some(v) => Ok((rest, (text, v))),
        None => Err(nom::Err::Error(())),
    }
}

/// A word as parsed: address text, number text, value, `=`?
struct RawWord<'a> {
    address: In<'a>,
    value_text: In<'a>,
    value: f64,
    assign: bool,
}

/// `assign_word = address_name, { blank }, "=", { blank }, number`
/// where `address_name = letter, { letter }, { digit }` (`A3`, `R1`, `X`, `AP`).
fn assign_word(i: In) -> PResult<RawWord> {
    let (rest, (address, _, _, _, (value_text, value))) = (
        recognize((
            take_while1(|b: u8| b.is_ascii_alphabetic()),
            take_while(|b: u8| b.is_ascii_digit()),
        )),
        blank0,
        char('='),
        blank0,
        number,
    )
        .parse_complete(i)?;
    if !ends_separated(rest) || address.len() > 31 {
        return Err(nom::Err::Error(()));
    }
    Ok((
        rest,
        RawWord {
            address,
            value_text,
            value,
            assign: true,
        },
    ))
}

/// `word = letter, { blank }, number` (`G1`, `X-1.5`, `x.5`, `G 1`, `X - 3`).
fn plain_word(i: In) -> PResult<RawWord> {
    let (rest, (address, _, (value_text, value))) = (
        recognize(satisfy(|c| c.is_ascii_alphabetic())),
        blank0,
        number,
    )
        .parse_complete(i)?;
    if !ends_plain_word(rest) {
        return Err(nom::Err::Error(()));
    }
    Ok((
        rest,
        RawWord {
            address,
            value_text,
            value,
            assign: false,
        },
    ))
}

/// `keyword = letter, letter, { letter }` in any case (since session 29:
/// Sinumerik reads `Traori` as `TRAORI`), followed by the end of the line,
/// a blank or `;`; not an address letter followed by a spelling of NaN or
/// infinity.
fn keyword(i: In) -> PResult<In> {
    let (rest, name) = take_while1(|b: u8| b.is_ascii_alphabetic()).parse_complete(i)?;
    let tail = &name[1..];
    let non_finite = NON_FINITE
        .iter()
        .any(|s| tail.eq_ignore_ascii_case(s.as_bytes()));
    if name.len() >= 2 && !non_finite && ends_separated(rest) {
        Ok((rest, name))
    } else {
        Err(nom::Err::Error(()))
    }
}

/// `checksum = "*", digit, { digit }` (value fits in 32 bits).
fn checksum(i: In) -> PResult<u32> {
    let (rest, (_, digits)) = (char('*'), digit1).parse_complete(i)?;
    let value = std::str::from_utf8(digits)
        .ok()
        .and_then(|s| s.parse::<u32>().ok());
    match value {
        Some(v) if ends_checksum(rest) => Ok((rest, v)),
        _ => Err(nom::Err::Error(())),
    }
}

/// `oword_flow = ( "o" | "O" ), { blank }, digit, { digit }, { blank }, oword_keyword`
/// (LinuxCNC `o100 sub`, `o100 if [..]`). Recognised only so that it is
/// kept opaque rather than read as an `O` word and a keyword.
fn oword_flow(i: In) -> PResult<In> {
    let (rest, (_, _, _, _, kw)) = (
        one_of("oO"),
        blank0,
        digit1,
        blank0,
        take_while1(|b: u8| b.is_ascii_alphabetic()),
    )
        .parse_complete(i)?;
    if OWORD_KEYWORDS
        .iter()
        .any(|k| kw.eq_ignore_ascii_case(k.as_bytes()))
    {
        Ok((rest, kw))
    } else {
        Err(nom::Err::Error(()))
    }
}

/// `block_delete = "/", [ digit - "0" ]` (a digit is taken only if no
/// further digit or point follows it).
fn block_delete(i: In) -> PResult<In> {
    let with_digit: PResult<In> =
        recognize((char('/'), satisfy(|c| ('1'..='9').contains(&c)))).parse_complete(i);
    match with_digit {
        Ok((rest, text)) if !matches!(rest.first(), Some(b'0'..=b'9' | b'.')) => Ok((rest, text)),
        _ => tag(&b"/"[..]).parse_complete(i),
    }
}

/// Length of the line body: everything before the line ending.
fn body_len(bytes: &[u8]) -> usize {
    let mut n = bytes.len();
    if bytes.last() == Some(&b'\n') {
        n -= 1;
    }
    while n > 0 && bytes[n - 1] == b'\r' {
        n -= 1;
    }
    n
}

/// Builds the items of one line, tracking offsets.
struct Builder<'a> {
    body: &'a [u8],
    items: Vec<RefItem>,
}

impl<'a> Builder<'a> {
    fn offset(&self, rest: In<'a>) -> usize {
        self.body.len() - rest.len()
    }

    /// Push an item that covers `body[offset(before) .. offset(after)]`.
    fn push(&mut self, before: In<'a>, after: In<'a>, kind: RefKind) {
        let start = self.offset(before);
        let end = self.offset(after);
        if end > start {
            self.items.push(RefItem { start, end, kind });
        }
    }

    fn push_word(&mut self, before: In<'a>, after: In<'a>, raw: RawWord<'a>) {
        let address = String::from_utf8_lossy(raw.address).to_ascii_uppercase();
        // `value_text` is a sub-slice of `body`: its offset is a pointer difference.
        let value_start = self.body.offset(raw.value_text);
        let value_end = value_start + raw.value_text.len();
        let word = RefKind::Word {
            address,
            value_bits: raw.value.to_bits(),
            value_start,
            value_end,
            assign: raw.assign,
        };
        self.push(before, after, word);
    }

    /// The rest of the body is not understood.
    fn opaque(&mut self, rest: In<'a>) {
        self.push(rest, &rest[rest.len()..], RefKind::Opaque);
    }

    /// After `%`: blanks and comments, anything else opaque.
    fn percent_tail(&mut self, mut rest: In<'a>) {
        loop {
            if rest.is_empty() {
                return;
            }
            if let Ok((r, _)) = blank(rest) {
                self.push(rest, r, RefKind::Space);
                rest = r;
            } else if let Ok((r, _)) = comment(rest) {
                self.push(rest, r, RefKind::Comment);
                rest = r;
            } else {
                self.opaque(rest);
                return;
            }
        }
    }

    /// The items of a block, after any block delete.
    fn block_items(&mut self, mut rest: In<'a>) {
        while !rest.is_empty() {
            let before = rest;
            if let Ok((r, _)) = blank(rest) {
                self.push(before, r, RefKind::Space);
                rest = r;
            } else if let Ok((r, _)) = comment(rest) {
                self.push(before, r, RefKind::Comment);
                rest = r;
            } else if let Ok((r, v)) = checksum(rest) {
                self.push(before, r, RefKind::Checksum(v));
                rest = r;
            } else if oword_flow(rest).is_ok() {
                self.opaque(rest);
                return;
            } else if let Ok((r, raw)) = assign_word(rest) {
                self.push_word(before, r, raw);
                rest = r;
            } else if let Ok((r, name)) = keyword(rest) {
                let name = String::from_utf8_lossy(name).to_ascii_uppercase();
                self.push(before, r, RefKind::Keyword(name));
                rest = r;
            } else if let Ok((r, raw)) = plain_word(rest) {
                self.push_word(before, r, raw);
                rest = r;
            } else {
                self.opaque(rest);
                return;
            }
        }
    }
}

/// The items of one physical line, as the parser read it before the
/// allocation-free rewrite.
pub fn parse_line(bytes: &[u8], number: usize) -> Vec<RefItem> {
    let body_end = body_len(bytes);
    let body = &bytes[..body_end];
    let mut b = Builder {
        body,
        items: Vec::with_capacity(16),
    };
    let mut rest = body;

    if number == 1
        && let Ok((r, _)) = tag::<_, _, ()>(BOM).parse_complete(rest)
    {
        b.push(rest, r, RefKind::Bom);
        rest = r;
    }
    if let Ok((r, _)) = blank(rest) {
        b.push(rest, r, RefKind::Space);
        rest = r;
    }
    if let Ok((r, _)) = tag::<_, _, ()>(&b"%"[..]).parse_complete(rest) {
        b.push(rest, r, RefKind::Percent);
        b.percent_tail(r);
    } else {
        if let Ok((r, _)) = block_delete(rest) {
            b.push(rest, r, RefKind::BlockDelete);
            rest = r;
        }
        b.block_items(rest);
    }

    let mut items = b.items;
    if body_end < bytes.len() {
        items.push(RefItem {
            start: body_end,
            end: bytes.len(),
            kind: RefKind::EndOfLine,
        });
    }
    items
}
