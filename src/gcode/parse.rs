//! The nom parser for one physical line of G-code.
//!
//! The grammar is written down in `grammar/gcode.ebnf`; `tests/it/grammar.rs`
//! checks the examples given there against this parser.
//!
//! The parser never fails. It recognises items from the start of the line
//! for as long as it understands them; the first thing it does not
//! understand, and everything after it up to the line ending, becomes one
//! [`ItemKind::Opaque`] item. This keeps a later stage from misreading the
//! tail of a line it cannot interpret (`X1.2.3 Y5` must not look like a move
//! to `Y5`).
//!
//! Every production is a nom parser (`&[u8]` in, [`IResult`] out). The rare
//! ones are composed from nom's combinators as the grammar reads; the ones
//! every block is made of (words and their numbers) are written out byte by
//! byte, because they run millions of times on a long program: the item
//! alternatives are chosen by the item's first byte (each alternative of
//! `item` starts with a byte of its own), the letters of an address are
//! scanned once for `assign_word`, `keyword` and `word` together, and a
//! number's value is computed while its digits are scanned. Words do not
//! allocate (a word's address is an inline [`Address`]; only a keyword's
//! name and a number of more than 19 digits do), and the items go into a
//! vector the caller may reuse ([`parse_line_into`]).
//! `tests/it/gcode_differential.rs` checks that every line is read exactly as
//! the plainly composed parser of the grammar reads it.

use nom::{
    IResult, Offset, Parser,
    bytes::complete::{tag, take_till, take_while, take_while1},
    character::complete::{char, digit1, one_of, satisfy},
    combinator::recognize,
};

use super::address::Address;
use super::block::{Item, ItemKind, Line, Word};

type In<'a> = &'a [u8];
type PResult<'a, O> = IResult<In<'a>, O, ()>;

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Keywords that, after an o-word number, make the line LinuxCNC
/// subroutine / flow control (kept [`ItemKind::Opaque`]).
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

fn fail<O>() -> PResult<'static, O> {
    Err(nom::Err::Error(()))
}

/// A blank: a space, a tab, or a page layout byte of old listings (a form
/// feed, a vertical tab), which separates like a space.
fn is_blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | 0x0b | 0x0c)
}

/// `blank = ( " " | tab | vt | ff ), { " " | tab | vt | ff }`
fn blank(i: In) -> PResult<In> {
    take_while1(is_blank).parse_complete(i)
}

/// `{ blank }`: the input after any blanks at its start.
fn skip_blanks(i: In) -> In {
    let n = i.iter().take_while(|&&b| is_blank(b)).count();
    &i[n..]
}

/// `paren_comment = "(", { any byte - ")" }, ")"`
fn paren_comment(i: In) -> PResult<In> {
    recognize((char('('), take_till(|b| b == b')'), char(')'))).parse_complete(i)
}

/// `semicolon_comment = ";", { any byte }` (to the end of the line body)
fn semicolon_comment(i: In) -> PResult<In> {
    recognize((char(';'), take_while(|_| true))).parse_complete(i)
}

/// `comment = paren_comment | semicolon_comment`
fn comment(i: In) -> PResult<In> {
    match i.first() {
        Some(b'(') => paren_comment(i),
        Some(b';') => semicolon_comment(i),
        _ => fail(),
    }
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

/// `number = [ sign, { blank } ], unsigned` with
/// `unsigned = digit, { digit }, [ ".", { digit } ] | ".", digit, { digit }`;
/// returns the number's source text and its value. No exponent: in G-code
/// `E` is an address (`X1E5` is `X1 E5`).
///
/// The value is the f64 nearest to the decimal number, as [`str::parse`]
/// gives it: computed here when there are at most 19 digits and their
/// integer is at most 2^53 (an exact integer divided by an exact power of
/// ten, rounded once, is the nearest f64), else by `str::parse`. A number
/// that does not fit in an f64 (400 digits) is not a number, so that an
/// overflow never turns silently into `inf`.
fn number(i: In) -> PResult<(In, f64)> {
    use crate::numeric::Digits;
    let (negative, unsigned) = match i.first() {
        Some(b'-') => (true, skip_blanks(&i[1..])),
        Some(b'+') => (false, skip_blanks(&i[1..])),
        _ => (false, i),
    };
    let mut digits = Digits::default();
    let int_digits = digits.scan(unsigned);
    let (frac_digits, len) = if unsigned.get(int_digits) == Some(&b'.') {
        let n = digits.scan(&unsigned[int_digits + 1..]);
        (n, int_digits + 1 + n)
    } else {
        (0, int_digits)
    };
    if int_digits + frac_digits == 0 {
        return fail();
    }
    let rest = &unsigned[len..];
    let text = &i[..i.len() - rest.len()];
    let value = match digits.exact(frac_digits) {
        Some(v) => {
            if negative {
                -v
            } else {
                v
            }
        }
        None => match slow_value(text) {
            Some(v) => v,
            None => return fail(),
        },
    };
    Ok((rest, (text, value)))
}

/// The value of a number's source text by the standard library's parser
/// (blanks after the sign removed); `None` if it is not finite.
fn slow_value(text: In) -> Option<f64> {
    let s: String = text
        .iter()
        .filter(|&&b| !is_blank(b))
        .map(|&b| char::from(b))
        .collect();
    let v: f64 = s.parse().ok()?;
    v.is_finite().then_some(v)
}

/// A word as parsed: address, number text, value, `=`?
struct RawWord<'a> {
    address: Address,
    value_text: In<'a>,
    value: f64,
    assign: bool,
}

/// `assign_word = address_name, { blank }, "=", { blank }, number`
/// where `address_name = letter, { letter }, { digit }` (`A3`, `R1`, `X`,
/// `AP`) of at most [`Address::MAX_LEN`] bytes; `letters` is the length of
/// the run of letters `i` starts with.
fn assign_word(i: In, letters: usize) -> PResult<RawWord> {
    let name_len = letters
        + i[letters..]
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .count();
    let after_name = skip_blanks(&i[name_len..]);
    if after_name.first() != Some(&b'=') {
        return fail();
    }
    let (rest, (value_text, value)) = number(skip_blanks(&after_name[1..]))?;
    match Address::from_ascii(&i[..name_len]) {
        Some(address) if ends_separated(rest) => Ok((
            rest,
            RawWord {
                address,
                value_text,
                value,
                assign: true,
            },
        )),
        _ => fail(),
    }
}

/// `word = letter, { blank }, number` (`G1`, `X-1.5`, `x.5`, `G 1`, `X - 3`).
fn plain_word(i: In) -> PResult<RawWord> {
    let address = match i.first() {
        Some(&b) if b.is_ascii_alphabetic() => Address::letter(b),
        _ => return fail(),
    };
    let (rest, (value_text, value)) = number(skip_blanks(&i[1..]))?;
    if !ends_plain_word(rest) {
        return fail();
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

/// `keyword = letter, letter, { letter }` in any case (Sinumerik reads
/// `Traori` as `TRAORI`), followed by the end of the line, a blank or `;`;
/// not an address letter followed by a spelling of NaN or infinity.
/// `letters` is the length of the run of letters `i` starts with.
fn keyword(i: In, letters: usize) -> PResult<In> {
    let (name, rest) = i.split_at(letters);
    let tail = name.get(1..).unwrap_or_default();
    let non_finite = NON_FINITE
        .iter()
        .any(|s| tail.eq_ignore_ascii_case(s.as_bytes()));
    if name.len() >= 2 && !non_finite && ends_separated(rest) {
        Ok((rest, name))
    } else {
        fail()
    }
}

/// What an item that starts with a letter is.
enum Lettered<'a> {
    Word(RawWord<'a>),
    Keyword(In<'a>),
}

/// `assign_word | keyword | word`, tried in this order (as `item` lists
/// them), on input that starts with a letter. The run of letters is
/// scanned once for all three; a plain word has a single letter.
fn lettered(i: In) -> PResult<Lettered> {
    let letters = i.iter().take_while(|b| b.is_ascii_alphabetic()).count();
    if letters == 0 {
        return fail();
    }
    if let Ok((rest, w)) = assign_word(i, letters) {
        return Ok((rest, Lettered::Word(w)));
    }
    if letters > 1 {
        let (rest, name) = keyword(i, letters)?;
        return Ok((rest, Lettered::Keyword(name)));
    }
    let (rest, w) = plain_word(i)?;
    Ok((rest, Lettered::Word(w)))
}

/// `checksum = "*", digit, { digit }` (value fits in 32 bits).
fn checksum(i: In) -> PResult<u32> {
    let (rest, (_, digits)) = (char('*'), digit1).parse_complete(i)?;
    let value = std::str::from_utf8(digits)
        .ok()
        .and_then(|s| s.parse::<u32>().ok());
    match value {
        Some(v) if ends_checksum(rest) => Ok((rest, v)),
        _ => fail(),
    }
}

/// `oword_flow = ( "o" | "O" ), { blank }, digit, { digit }, { blank }, oword_keyword`
/// (LinuxCNC `o100 sub`, `o100 if [..]`). Recognised only so that it is
/// kept opaque rather than read as an `O` word and a keyword.
fn oword_flow(i: In) -> PResult<In> {
    let (rest, (_, _, _, _, kw)) = (
        one_of("oO"),
        take_while(is_blank),
        digit1,
        take_while(is_blank),
        take_while1(|b: u8| b.is_ascii_alphabetic()),
    )
        .parse_complete(i)?;
    if OWORD_KEYWORDS
        .iter()
        .any(|k| kw.eq_ignore_ascii_case(k.as_bytes()))
    {
        Ok((rest, kw))
    } else {
        fail()
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
struct Builder<'a, 'v> {
    body: &'a [u8],
    items: &'v mut Vec<Item>,
}

impl<'a> Builder<'a, '_> {
    fn offset(&self, rest: In<'a>) -> usize {
        self.body.len() - rest.len()
    }

    /// Push an item that covers `body[offset(before) .. offset(after)]`.
    fn push(&mut self, before: In<'a>, after: In<'a>, kind: ItemKind) {
        let start = self.offset(before);
        let end = self.offset(after);
        if end > start {
            self.items.push(Item { start, end, kind });
        }
    }

    fn push_word(&mut self, before: In<'a>, after: In<'a>, raw: RawWord<'a>) {
        // `value_text` is a sub-slice of `body`: its offset is a pointer difference.
        let value_start = self.body.offset(raw.value_text);
        let value_end = value_start + raw.value_text.len();
        let word = Word {
            address: raw.address,
            value: raw.value,
            value_start,
            value_end,
            assign: raw.assign,
        };
        self.push(before, after, ItemKind::Word(word));
    }

    /// The rest of the body is not understood.
    fn opaque(&mut self, rest: In<'a>) {
        self.push(rest, &rest[rest.len()..], ItemKind::Opaque);
    }

    /// After `%`: blanks and comments, anything else opaque.
    fn percent_tail(&mut self, mut rest: In<'a>) {
        loop {
            if rest.is_empty() {
                return;
            }
            if let Ok((r, _)) = blank(rest) {
                self.push(rest, r, ItemKind::Space);
                rest = r;
            } else if let Ok((r, _)) = comment(rest) {
                self.push(rest, r, ItemKind::Comment);
                rest = r;
            } else {
                self.opaque(rest);
                return;
            }
        }
    }

    /// The items of a block, after any block delete. Each alternative of
    /// `item` (blank, comment, checksum, assign_word, keyword, word) and
    /// `oword_flow` begins with a byte no other begins with, so the first
    /// byte picks the one that can match.
    fn block_items(&mut self, mut rest: In<'a>) {
        while let Some(&first) = rest.first() {
            let before = rest;
            let parsed = match first {
                b' ' | b'\t' | 0x0b | 0x0c => blank(rest).map(|(r, _)| (r, ItemKind::Space)),
                b'(' | b';' => comment(rest).map(|(r, _)| (r, ItemKind::Comment)),
                b'*' => checksum(rest).map(|(r, v)| (r, ItemKind::Checksum(v))),
                b'o' | b'O' if oword_flow(rest).is_ok() => fail(),
                b if b.is_ascii_alphabetic() => match lettered(rest) {
                    Ok((r, Lettered::Word(raw))) => {
                        self.push_word(before, r, raw);
                        rest = r;
                        continue;
                    }
                    Ok((r, Lettered::Keyword(name))) => {
                        let name = String::from_utf8_lossy(name).to_ascii_uppercase();
                        Ok((r, ItemKind::Keyword(name)))
                    }
                    Err(e) => Err(e),
                },
                _ => fail(),
            };
            match parsed {
                Ok((r, kind)) => {
                    self.push(before, r, kind);
                    rest = r;
                }
                Err(_) => {
                    self.opaque(rest);
                    return;
                }
            }
        }
    }
}

/// Parse one physical line (with its line ending, if any) into a [`Line`].
///
/// Never fails and never panics: whatever is not understood becomes an
/// [`ItemKind::Opaque`] item. `number` is the 1-based line number; on line 1
/// a leading UTF-8 byte order mark becomes an [`ItemKind::Bom`] item.
pub fn parse_line(bytes: &[u8], number: usize) -> Line {
    let mut items = Vec::with_capacity(16);
    parse_items(bytes, number, &mut items);
    let line = Line {
        number,
        bytes: bytes.to_vec(),
        items,
    };
    debug_assert!(line.is_tiled(), "items do not tile line {number}");
    line
}

/// Parse one physical line into `line`, reusing its buffers: after the
/// first few lines, parsing allocates nothing. `line` then holds exactly
/// what [`parse_line`]`(bytes, number)` returns.
///
/// ```
/// use kinpost::gcode::{parse_line, parse_line_into, Line};
///
/// let mut line = Line::default();
/// for (n, text) in ["G1 X1\n", "Y2 (two)\n"].iter().enumerate() {
///     parse_line_into(text.as_bytes(), n + 1, &mut line);
///     assert_eq!(line, parse_line(text.as_bytes(), n + 1));
/// }
/// ```
pub fn parse_line_into(bytes: &[u8], number: usize, line: &mut Line) {
    line.number = number;
    line.bytes.clear();
    line.bytes.extend_from_slice(bytes);
    parse_items(bytes, number, &mut line.items);
    debug_assert!(line.is_tiled(), "items do not tile line {number}");
}

/// [`parse_line_into`] taking the line's bytes from `bytes` by exchanging
/// buffers instead of copying: `bytes` receives the line's previous buffer
/// (its contents unspecified), for the caller to reuse.
pub fn parse_line_swap(bytes: &mut Vec<u8>, number: usize, line: &mut Line) {
    line.number = number;
    std::mem::swap(&mut line.bytes, bytes);
    parse_items(&line.bytes, number, &mut line.items);
    debug_assert!(line.is_tiled(), "items do not tile line {number}");
}

/// The items of one physical line (`bytes`, line `number`), written to
/// `items` (cleared first).
pub(crate) fn parse_items(bytes: &[u8], number: usize, items: &mut Vec<Item>) {
    items.clear();
    let body_end = body_len(bytes);
    let body = &bytes[..body_end];
    let mut b = Builder { body, items };
    let mut rest = body;

    if number == 1
        && let Ok((r, _)) = tag::<_, _, ()>(BOM).parse_complete(rest)
    {
        b.push(rest, r, ItemKind::Bom);
        rest = r;
    }
    if let Ok((r, _)) = blank(rest) {
        b.push(rest, r, ItemKind::Space);
        rest = r;
    }
    if let Ok((r, _)) = tag::<_, _, ()>(&b"%"[..]).parse_complete(rest) {
        b.push(rest, r, ItemKind::Percent);
        b.percent_tail(r);
    } else {
        if rest.first() == Some(&b'/')
            && let Ok((r, _)) = block_delete(rest)
        {
            b.push(rest, r, ItemKind::BlockDelete);
            rest = r;
        }
        b.block_items(rest);
    }

    if body_end < bytes.len() {
        items.push(Item {
            start: body_end,
            end: bytes.len(),
            kind: ItemKind::EndOfLine,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &[u8]) -> Vec<ItemKind> {
        parse_line(s, 2).items.into_iter().map(|i| i.kind).collect()
    }

    #[test]
    fn swapping_parse_is_the_copying_parse() {
        let mut line = Line::default();
        for (n, text) in ["G1 X1\n", "Y2 (two)\r\n", "%", "N10 G0 X-1.5 Y2\n"]
            .iter()
            .enumerate()
        {
            let mut bytes = text.as_bytes().to_vec();
            parse_line_swap(&mut bytes, n + 1, &mut line);
            assert_eq!(line, parse_line(text.as_bytes(), n + 1));
        }
    }

    #[test]
    fn number_forms() {
        for (text, v) in [
            ("5", 5.0),
            ("5.", 5.0),
            (".5", 0.5),
            ("+5", 5.0),
            ("-.5", -0.5),
            ("- 3", -3.0),
            ("007", 7.0),
        ] {
            let (rest, (t, val)) = number(text.as_bytes()).unwrap();
            assert!(rest.is_empty(), "{text}");
            assert_eq!(t, text.as_bytes());
            assert_eq!(val, v, "{text}");
        }
        assert!(number(b".").is_err());
        assert!(number(b"-").is_err());
        assert!(number(b"nan").is_err());
        assert!(number(b"inf").is_err());
        assert!(number("9".repeat(400).as_bytes()).is_err());
    }

    #[test]
    fn body_len_variants() {
        assert_eq!(body_len(b"G1\n"), 2);
        assert_eq!(body_len(b"G1\r\n"), 2);
        assert_eq!(body_len(b"G1\r\r\n"), 2);
        assert_eq!(body_len(b"G1"), 2);
        assert_eq!(body_len(b"G1\r"), 2);
        assert_eq!(body_len(b"\n"), 0);
        assert_eq!(body_len(b""), 0);
    }

    #[test]
    fn bom_only_on_line_one() {
        let l = parse_line(b"\xEF\xBB\xBF%\n", 1);
        assert_eq!(l.items[0].kind, ItemKind::Bom);
        assert_eq!(l.items[1].kind, ItemKind::Percent);
        assert_eq!(kinds(b"\xEF\xBB\xBF%\n")[0], ItemKind::Opaque);
    }
}
