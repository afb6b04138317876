//! APT CL data (NX CLSF, APT source): a streaming statement reader.
//!
//! A CL file is a sequence of statements, one per line, `MAJOR/args` or a
//! bare `MAJOR`; a line ending in `$` continues on the next line, and `$$`
//! starts a comment that runs to the end of the line. The accepted syntax is
//! written down in `grammar/apt-cl.ebnf`.
//!
//! [`lower`] turns the constructs CAM systems write (`CIRCLE`, `CYCLE`,
//! `CSYS`, `CUTCOM`, `LOAD/TOOL`, ...) into these plain statements; see
//! docs/programs.md.
//!
//! Statements the converter needs (`GOTO`, `FEDRAT`, `RAPID`, `TLAXIS`,
//! `MULTAX`, `LOADTL`, `SPINDL`, `COOLNT`, `UNITS`, `FINI`/`END`) are
//! interpreted; every other statement is kept as [`ClStatement::Other`].
//! A statement that moves the tool or sets units or the tool and cannot be
//! read (`GOTO/1,2`, `GOTO/1,2,nan`, `UNITS/FEET`) is an error naming the
//! file, line and column, and showing the text.
//!
//! ```
//! use kinpost::cl::{ClReader, ClStatement};
//!
//! let text = "MULTAX/ON\nGOTO/1.0,2.0,3.0,$\n 0.0,0.0,1.0\n";
//! let records: Vec<_> = ClReader::new(text.as_bytes(), "op.cls")
//!     .collect::<Result<_, _>>()
//!     .unwrap();
//! assert_eq!(records[1].line, 2);
//! assert_eq!(
//!     records[1].statement,
//!     ClStatement::Goto { tip: [1.0, 2.0, 3.0], axis: Some([0.0, 0.0, 1.0]) }
//! );
//! ```

use std::io::BufRead;

use nom::{
    IResult, Parser,
    bytes::complete::{take_while, take_while1},
    character::complete::one_of,
    combinator::recognize,
};

use crate::error::{Error, Location};

mod arc;
mod cycle;
mod insert;
mod lower;
mod state;
mod statement;
use statement::parse_statement;
mod vec3;
pub use arc::ArcMove;
pub use cycle::HoleMove;
pub use lower::{DEFAULT_ARC_TOLERANCE_MM, FLOW_MAJORS, Lowered, MOTION_MAJORS, lower};

/// Feed rate units of `FEDRAT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedUnit {
    /// Millimetres per minute (`MMPM`).
    Mmpm,
    /// Inches per minute (`IPM`).
    Ipm,
    /// Millimetres per revolution (`MMPR`).
    Mmpr,
    /// Inches per revolution (`IPR`).
    Ipr,
    /// Not given: per minute, in the program's units.
    Unspecified,
}

/// Spindle direction of `SPINDL`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpindleDir {
    /// Clockwise (`CLW`, M3).
    Clockwise,
    /// Counter-clockwise (`CCLW`, M4).
    CounterClockwise,
}

/// Units of `UNITS/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClUnits {
    /// `UNITS/MM`.
    Mm,
    /// `UNITS/INCHES` (or `INCH`).
    Inches,
}

/// One CL statement, interpreted.
#[derive(Debug, Clone, PartialEq)]
pub enum ClStatement {
    /// `GOTO/x,y,z[,i,j,k]`: tool tip, and tool axis when given.
    Goto {
        /// Tool tip position.
        tip: [f64; 3],
        /// Tool axis direction (not normalised; never zero).
        axis: Option<[f64; 3]>,
    },
    /// `FEDRAT/[unit,]f` or `FEDRAT/f[,unit]`.
    Fedrat {
        /// The feed rate (not negative).
        value: f64,
        /// Its unit.
        unit: FeedUnit,
    },
    /// `RAPID`: the next motion is a rapid move.
    Rapid,
    /// `TLAXIS/i,j,k`: tool axis for the following motions (never zero).
    TlAxis([f64; 3]),
    /// `MULTAX`, `MULTAX/ON` (true) or `MULTAX/OFF` (false).
    Multax(bool),
    /// `LOADTL/n[,...]`: tool number, and the length offset register an
    /// `ADJUST,h` among the other words names.
    LoadTl {
        /// The tool number.
        tool: u32,
        /// `ADJUST,h`: the register h.
        adjust: Option<u32>,
    },
    /// `SPINDL/[RPM,]s[,CLW|CCLW]`, `SPINDL/ON`, `SPINDL/OFF`.
    Spindle {
        /// Speed in revolutions per minute, if given.
        rpm: Option<f64>,
        /// Direction, if given.
        dir: Option<SpindleDir>,
        /// `true` for `SPINDL/OFF`.
        off: bool,
    },
    /// `COOLNT/ON|FLOOD|MIST|THRU|AIR|TAPKUL` (true) or `COOLNT/OFF` (false).
    Coolant(bool),
    /// `UNITS/MM` or `UNITS/INCHES`.
    Units(ClUnits),
    /// A `$$` comment line (the text after `$$`, trimmed).
    Comment(String),
    /// `FINI` or `END`: end of the program.
    End,
    /// A literal G-code block to write as it is: made by [`lower`]
    /// (`G41 D1`, `T3 M6`, `G4 P0.5`, ...), or the NC code of an
    /// `INSERT/` that only switches the spindle or coolant, stops or ends
    /// (`M8`, `S1200 M3`; `cl/insert.rs`).
    Block(String),
    /// Cutter compensation (made by [`lower`], never by the reader):
    /// `CUTCOM/LEFT|RIGHT` (`on`) or `CUTCOM/OFF`, with the block that
    /// writes it (`G41 D3`, `G42`, `G40`). The moves while it is on must
    /// keep the tool along the machine's Z axis and the rotary axes still
    /// (docs/programs.md, "APT CL data").
    CutterCompensation {
        /// The block to write.
        block: String,
        /// Compensation is on after it.
        on: bool,
    },
    /// A warning for stderr (made by [`lower`], never by the reader).
    Warning(String),
    /// An arc (made by [`lower`], never by the reader): `G2`/`G3` when it
    /// lies in a plane of the machine, else its linearised moves.
    Arc(Box<ArcMove>),
    /// A hole of a canned cycle (made by [`lower`], never by the reader):
    /// `G81`…`G89` when the tool is along the machine's Z axis, else its
    /// moves.
    Hole(Box<HoleMove>),
    /// Any other statement: `PARTNO`, `TOOL PATH`, `TLDATA`, `MSYS`, `PAINT`,
    /// `END-OF-PATH`, `CUTTER`, ... and `SPINDL`/`COOLNT` forms not
    /// interpreted above (`SPINDL/SFM,..`).
    Other {
        /// The major word, uppercased, inner blanks collapsed (`"TOOL PATH"`).
        major: String,
        /// The text after the `/` (or after the major word when there is
        /// no `/`), trimmed, continuations joined, inline comment removed.
        text: String,
    },
}

/// A statement with where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct ClRecord {
    /// 1-based number of the statement's first physical line.
    pub line: usize,
    /// 1-based column where the statement starts on that line.
    pub col: usize,
    /// The original bytes of all the statement's physical lines, line
    /// endings included.
    pub text: Vec<u8>,
    /// What the statement says.
    pub statement: ClStatement,
}

/// Reads CL statements one at a time from any [`BufRead`].
///
/// An [`Iterator`] of `Result<ClRecord, Error>`. Blank lines are skipped.
/// After a statement error the reader goes on with the next statement; after
/// an I/O error it stops. Memory depends on the longest statement, not on
/// the length of the file; the text of a record done with can be given back
/// ([`ClReader::recycle`]) for a record to come, so that reading allocates
/// nothing.
#[derive(Debug)]
pub struct ClReader<R: BufRead> {
    reader: R,
    file: String,
    line: usize,
    buf: Vec<u8>,
    /// A statement continued on other lines, joined (kept for its memory).
    logical: Logical,
    /// Texts of records given back, for the next records' texts.
    spare: Vec<Vec<u8>>,
    /// A line read ahead (after a comment that may go on) and not taken:
    /// the next physical line (`line` counts it already).
    ahead: Option<Vec<u8>>,
    done: bool,
}

/// The most texts given back that a reader keeps.
const MAX_SPARE: usize = 16;

/// A piece of a logical statement that came from one physical line:
/// `logical[offset..]` starts at `line`, `col`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    offset: usize,
    line: usize,
    col: usize,
}

/// A statement joined from its physical lines.
#[derive(Debug, Default)]
struct Logical {
    /// The statement text, continuations joined, `$$` comments and the
    /// continuation `$` removed.
    text: Vec<u8>,
    segments: Vec<Segment>,
}

impl Logical {
    /// Line and column of byte `offset` of the logical text.
    fn position(&self, offset: usize) -> (usize, usize) {
        let seg = self
            .segments
            .iter()
            .rev()
            .find(|s| s.offset <= offset)
            .or(self.segments.first());
        match seg {
            Some(s) => (s.line, s.col + (offset - s.offset.min(offset))),
            None => (0, 0),
        }
    }
}

impl<R: BufRead> ClReader<R> {
    /// A reader of `reader`; `file` names it in error messages.
    pub fn new(reader: R, file: impl Into<String>) -> Self {
        ClReader {
            reader,
            file: file.into(),
            line: 0,
            buf: Vec::with_capacity(256),
            logical: Logical::default(),
            spare: Vec::new(),
            ahead: None,
            done: false,
        }
    }

    /// Takes back the text of a record done with: a record read later
    /// reuses its memory.
    pub fn recycle(&mut self, mut text: Vec<u8>) {
        if self.spare.len() < MAX_SPARE && text.capacity() > 0 {
            text.clear();
            self.spare.push(text);
        }
    }

    /// An empty text for a record: one given back if there is one.
    pub(crate) fn text_buffer(&mut self) -> Vec<u8> {
        self.spare.pop().unwrap_or_default()
    }

    /// Read one physical line into `self.buf`; `Ok(false)` at end of file.
    fn read_physical(&mut self) -> Result<bool, Error> {
        if let Some(line) = self.ahead.take() {
            self.buf = line;
            return Ok(true);
        }
        self.buf.clear();
        match self.reader.read_until(b'\n', &mut self.buf) {
            Ok(0) => Ok(false),
            Ok(_) => {
                self.line += 1;
                // A byte-order mark before the first statement (a file
                // saved by a Windows editor) is no part of it.
                if self.line == 1 && self.buf.starts_with(BOM) {
                    self.buf.drain(..BOM.len());
                }
                // A carriage return that does not end the line: CR-only
                // line endings, which would hide the statements after it
                // in a comment or a statement kept as one.
                let body = self.buf.strip_suffix(b"\n").unwrap_or(&self.buf);
                let body = body.strip_suffix(b"\r").unwrap_or(body);
                if let Some(at) = body.iter().position(|&b| b == b'\r') {
                    let message = cr_inside(body).unwrap_or_default();
                    return Err(self.error(self.line, at + 1, message, strip_eol(body)));
                }
                Ok(true)
            }
            Err(e) => Err(Error::io(self.file.clone(), e)),
        }
    }

    fn error(&self, line: usize, col: usize, message: String, text: &[u8]) -> Error {
        Error::input_with(
            Location::new(self.file.clone(), line, col),
            message,
            String::from_utf8_lossy(text).into_owned(),
        )
    }

    fn next_record(&mut self) -> Option<Result<ClRecord, Error>> {
        // Skip blank lines; the first non-blank one starts a statement.
        let (first, col) = loop {
            match self.read_physical() {
                Ok(true) => {}
                Ok(false) => return None,
                Err(e) => return Some(Err(e)),
            }
            if let Some(col) = first_non_blank(&self.buf) {
                break (self.line, col);
            }
        };
        // DOS's end-of-file mark (`^Z`, 0x1A) ends the data; only blanks
        // and more marks may follow it.
        if self.buf[col - 1] == DOS_EOF {
            loop {
                let rest = strip_eol(&self.buf);
                if let Some(k) = rest.iter().position(|&b| !is_blank(b) && b != DOS_EOF) {
                    return Some(Err(self.error(
                        self.line,
                        k + 1,
                        "text after DOS's end-of-file mark (^Z, byte 0x1A): the data ends at the mark; a file joined from several?".into(),
                        rest,
                    )));
                }
                match self.read_physical() {
                    Ok(true) => {}
                    Ok(false) => return None,
                    Err(e) => return Some(Err(e)),
                }
            }
        }
        let mut text = self.text_buffer();
        text.extend_from_slice(&self.buf);

        // A whole-line `$$` comment.
        let start = &self.buf[col - 1..];
        if start.starts_with(b"$$") {
            let mut comment = String::from_utf8_lossy(strip_eol(&start[2..]))
                .trim()
                .to_string();
            // Creo comments a statement out over several lines, each ended
            // with the continuation `$` inside the comment (`$$-> CSYS / 1,
            // 0, 0, 0,  $`, then lines of numbers). A line that cannot start
            // a statement (it starts with a number or a comma) after such a
            // line goes on with the comment; any other is read next.
            while comment.ends_with('$') {
                match self.read_physical() {
                    Ok(true) => {}
                    Ok(false) => break,
                    Err(e) => return Some(Err(e)),
                }
                let goes_on = first_non_blank(&self.buf).is_some_and(|c| {
                    matches!(self.buf[c - 1], b'0'..=b'9' | b'+' | b'-' | b'.' | b',')
                });
                if !goes_on {
                    self.ahead = Some(std::mem::take(&mut self.buf));
                    break;
                }
                text.extend_from_slice(&self.buf);
                comment.pop();
                comment = format!(
                    "{} {}",
                    comment.trim_end(),
                    String::from_utf8_lossy(strip_eol(&self.buf)).trim()
                );
            }
            return Some(Ok(ClRecord {
                line: first,
                col,
                text,
                statement: ClStatement::Comment(comment),
            }));
        }

        // A statement on one line (most are): read from the line itself;
        // a byte at offset k of it is at column `col + k`.
        let (piece, continued) = statement_piece(start);
        // The text of PPRINT, PARTNO, INSERT and the like is literal: a `$`
        // at its end is text where a statement follows, a continuation
        // (CATIA wraps them at 72 columns) where text does.
        if continued && literal_text(start) {
            let own = start[..piece.len() + 1].to_vec();
            return Some(self.literal_statement(first, col, own, text));
        }
        if !continued {
            return Some(match parse_statement(piece) {
                Ok(statement) => Ok(ClRecord {
                    line: first,
                    col,
                    text,
                    statement,
                }),
                Err(e) => Err(self.error(
                    first,
                    col + e.offset,
                    cr_inside(strip_eol(&text)).unwrap_or(e.message),
                    strip_eol(&text),
                )),
            });
        }

        // Each physical line from its first non-blank byte (the first line
        // from the statement's start) is read from `self.buf`.
        self.logical.text.clear();
        self.logical.segments.clear();
        let mut seg_col = col;
        loop {
            let (piece, continued) = statement_piece(&self.buf[seg_col - 1..]);
            let logical = &mut self.logical;
            logical.segments.push(Segment {
                offset: logical.text.len(),
                line: self.line,
                col: seg_col,
            });
            logical.text.extend_from_slice(piece);
            if !continued {
                break;
            }
            match self.read_physical() {
                Ok(true) => {}
                Ok(false) => {
                    return Some(Err(self.error(
                        first,
                        col,
                        "statement continued with `$` but the file ends; expected a continuation line".into(),
                        &text,
                    )));
                }
                Err(e) => return Some(Err(e)),
            }
            text.extend_from_slice(&self.buf);
            seg_col = first_non_blank(&self.buf).unwrap_or(1);
            // A continuation line that starts a statement of its own
            // (`PAINT/COLOR,31 $` before a `GOTO/`): no CAM system writes
            // that as one statement; taken as one, the move would be lost
            // in a statement kept as a comment.
            if let Some(word) = starts_statement(&self.buf[seg_col - 1..]) {
                return Some(Err(self.error(
                    self.line,
                    seg_col,
                    format!("the statement before ends with the continuation `$`, but this line starts a statement of its own ({word}/): a `$` where none belongs, or a line missing; refused rather than reading the {word} as part of the statement before"),
                    strip_eol(&self.buf),
                )));
            }
        }

        let statement = match parse_statement(&self.logical.text) {
            Ok(s) => s,
            Err(e) => {
                let (line, col) = self.logical.position(e.offset);
                let snippet = physical_line(&text, line.saturating_sub(first));
                let message = cr_inside(snippet).unwrap_or(e.message);
                return Some(Err(self.error(line, col, message, snippet)));
            }
        };
        Some(Ok(ClRecord {
            line: first,
            col,
            text,
            statement,
        }))
    }
}

impl<R: BufRead> Iterator for ClReader<R> {
    type Item = Result<ClRecord, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let r = self.next_record();
        match &r {
            None | Some(Err(Error::Io { .. })) => self.done = true,
            _ => {}
        }
        r
    }
}

/// The message for a statement that cannot be read and holds a carriage
/// return inside its line: the file's lines most likely end in CR alone.
fn cr_inside(line: &[u8]) -> Option<String> {
    line.contains(&b'\r').then(|| {
        "a carriage return (CR) inside the line: the file seems to use CR-only (old Mac) line endings, which are not line breaks here; convert them to LF or CR LF (e.g. `tr '\\r' '\\n'`)".into()
    })
}

/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// DOS's end-of-file mark, `^Z`.
const DOS_EOF: u8 = 0x1A;

fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

/// The line without its line ending.
fn strip_eol(line: &[u8]) -> &[u8] {
    let mut n = line.len();
    while n > 0 && matches!(line[n - 1], b'\n' | b'\r') {
        n -= 1;
    }
    &line[..n]
}

/// The `k`-th (0-based) physical line of a statement's text, without its
/// line ending.
fn physical_line(text: &[u8], k: usize) -> &[u8] {
    let line = text.split_inclusive(|&b| b == b'\n').nth(k).unwrap_or(text);
    strip_eol(line)
}

/// 1-based column of the first byte that is not a blank or line ending.
fn first_non_blank(line: &[u8]) -> Option<usize> {
    strip_eol(line)
        .iter()
        .position(|&b| !is_blank(b))
        .map(|p| p + 1)
}

impl<R: BufRead> ClReader<R> {
    /// The literal-text statement `own` (line `first`, column `col`, raw
    /// `text`) that ends with `$`: the `$` is text where the next line
    /// starts a statement (`GOTO/…`) or there is none; where the next line
    /// is text, it continues the statement (CATIA wraps `PPRINT` at 72
    /// columns), and so on while it ends with `$`. A next line of one bare
    /// word (`END`, `STOP`, `RAPID`) could be either, and is refused.
    fn literal_statement(
        &mut self,
        first: usize,
        col: usize,
        mut own: Vec<u8>,
        mut text: Vec<u8>,
    ) -> Result<ClRecord, Error> {
        loop {
            if !self.read_physical()? {
                break;
            }
            let Some(c) = first_non_blank(&self.buf) else {
                self.ahead = Some(std::mem::take(&mut self.buf));
                break;
            };
            let line = strip_eol(&self.buf[c - 1..]);
            let word = leading_letters(line);
            let after_word = &line[word.len()..];
            let statement =
                !word.is_empty() && after_word.iter().find(|&&b| !is_blank(b)) == Some(&b'/');
            if statement || line.starts_with(b"$$") {
                self.ahead = Some(std::mem::take(&mut self.buf));
                break;
            }
            if !word.is_empty() && after_word.iter().all(|&b| is_blank(b)) {
                return Err(self.error(
                    self.line,
                    c,
                    format!("the statement at line {first} holds text and ends with `$`, and this line is the bare word {}: a continuation of the text (CATIA wraps long PPRINT lines with `$`) or a statement of its own? Refused rather than guessed; join the text into one line, or remove the `$`", String::from_utf8_lossy(word)),
                    line,
                ));
            }
            // Text: the statement goes on (without its `$`).
            own.pop();
            let (piece, continued) = statement_piece(&self.buf[c - 1..]);
            own.extend_from_slice(piece);
            text.extend_from_slice(&self.buf);
            if !continued {
                break;
            }
            own.push(b'$');
        }
        match parse_statement(&own) {
            Ok(statement) => Ok(ClRecord {
                line: first,
                col,
                text,
                statement,
            }),
            Err(e) => Err(self.error(first, col, e.message, strip_eol(&text))),
        }
    }
}

/// Whether the statement at the start of `line` holds literal text, in
/// which a `$` is text (`PPRINT/`, `PARTNO`, `INSERT/`, `REMARK/`,
/// `TPRINT/`, `OPNAME/`).
fn literal_text(line: &[u8]) -> bool {
    let word = leading_letters(line);
    ["PPRINT", "PARTNO", "INSERT", "REMARK", "TPRINT", "OPNAME"]
        .iter()
        .any(|w| word.eq_ignore_ascii_case(w.as_bytes()))
}

/// The run of letters `line` starts with.
fn leading_letters(line: &[u8]) -> &[u8] {
    &line[..line.iter().take_while(|b| b.is_ascii_alphabetic()).count()]
}

/// The statement word a continuation line starts with, when it starts a
/// statement of motion of its own (`GOTO/…`, `FEDRAT/…`, `CIRCLE/…`).
fn starts_statement(line: &[u8]) -> Option<&'static str> {
    const STARTS: [&str; 10] = [
        "GOTO", "GODLTA", "FROM", "CIRCLE", "MOVARC", "CYCLE", "FEDRAT", "LOADTL", "TLAXIS",
        "RAPID",
    ];
    let word = leading_letters(line);
    let rest = &line[word.len()..];
    let rest = &rest[rest.iter().take_while(|&&b| is_blank(b)).count()..];
    let start = STARTS
        .iter()
        .find(|s| word.eq_ignore_ascii_case(s.as_bytes()))
        .copied()?;
    (rest.first() == Some(&b'/') || (start == "RAPID" && strip_eol(rest).is_empty()))
        .then_some(start)
}

/// The statement part of one physical line (from the statement's start):
/// without line ending, `$$` comment and trailing blanks; and whether it is
/// continued (ends in a single `$`, which is removed).
fn statement_piece(content: &[u8]) -> (&[u8], bool) {
    let mut s = strip_eol(content);
    let mut from = 0;
    while let Some(p) = s[from..].iter().position(|&b| b == b'$') {
        if s.get(from + p + 1) == Some(&b'$') {
            s = &s[..from + p];
            break;
        }
        from += p + 1;
    }
    while let Some((&last, init)) = s.split_last() {
        if is_blank(last) {
            s = init;
        } else {
            break;
        }
    }
    match s.split_last() {
        Some((b'$', init)) => (init, true),
        _ => (s, false),
    }
}

/// A statement error at a byte offset of the logical text.
#[derive(Debug)]
struct StatementError {
    offset: usize,
    message: String,
}

type In<'a> = &'a [u8];
type PResult<'a, O> = IResult<In<'a>, O, ()>;

/// `major = letter, { letter | digit | "-" | "_" }`
fn major_word(i: In) -> PResult<In> {
    recognize((
        one_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"),
        take_while(|b: u8| b.is_ascii_alphanumeric() || b == b'-' || b == b'_'),
    ))
    .parse_complete(i)
}

/// `major_words = major, { blank, major }` (`TOOL PATH`).
fn major_words(i: In) -> PResult<In> {
    recognize((
        major_word,
        nom::multi::fold_many0((take_while1(is_blank), major_word), || (), |(), _| ()),
    ))
    .parse_complete(i)
}

/// `number = [ sign ], ( digits, [ ".", { digit } ] | ".", digits ),
///  [ ( "e" | "E" ), [ sign ], digits ]`: the grammar `Arg::number`
/// reads (by the standard parser, which the test
/// `number_agrees_with_grammar` holds to it).
#[cfg(test)]
fn number_text(i: In) -> PResult<In> {
    use nom::branch::alt;
    use nom::character::complete::{char, digit0, digit1};
    use nom::combinator::opt;
    recognize((
        opt(one_of("+-")),
        alt((
            recognize((digit1, opt((char('.'), digit0)))),
            recognize((char('.'), digit1)),
        )),
        opt((one_of("eE"), opt(one_of("+-")), digit1)),
    ))
    .parse_complete(i)
}

/// An argument: its text (trimmed) and its offset in the logical text.
#[derive(Debug, Clone, Copy)]
struct Arg<'a> {
    text: &'a [u8],
    offset: usize,
}

impl Arg<'_> {
    fn upper(&self) -> String {
        String::from_utf8_lossy(self.text).to_ascii_uppercase()
    }

    fn is(&self, word: &str) -> bool {
        self.text.eq_ignore_ascii_case(word.as_bytes())
    }

    /// The argument as a finite number (`number_text`).
    ///
    /// Read by the standard library's `f64` parser, whose grammar for
    /// numbers is `number_text`'s exactly (sign, digits with an optional
    /// point or a point and digits, an optional exponent; case-insensitive
    /// `e`); the words it reads besides (`inf`, `infinity`, `nan`) are not
    /// finite and refused here, like an overflow (`1e999`). A unit test
    /// checks the two agree.
    fn number(&self) -> Option<f64> {
        // Plain decimals (`-45.9945172`, most of them) exactly here.
        if let Some(v) = crate::numeric::plain_decimal(self.text) {
            return Some(v);
        }
        let v: f64 = std::str::from_utf8(self.text).ok()?.parse().ok()?;
        v.is_finite().then_some(v)
    }

    fn err(&self, message: impl Into<String>) -> StatementError {
        StatementError {
            offset: self.offset,
            message: message.into(),
        }
    }

    fn expect_number(&self, what: &str) -> Result<f64, StatementError> {
        self.number().ok_or_else(|| {
            self.err(format!(
                "expected {what} (a finite number), found `{}`",
                String::from_utf8_lossy(self.text)
            ))
        })
    }
}

/// The arguments of a statement: those of the statements read most (up to
/// 8: `GOTO` has 6) without an allocation.
type Args<'a> = smallvec::SmallVec<[Arg<'a>; 8]>;

/// Split `args` (starting at `offset` of the logical text) at commas.
fn split_args(args: &[u8], offset: usize) -> Args<'_> {
    let mut out = Args::new();
    let mut start = 0;
    for piece in args.split(|&b| b == b',') {
        let lead = piece
            .iter()
            .position(|&b| !is_blank(b))
            .unwrap_or(piece.len());
        let end = piece
            .iter()
            .rposition(|&b| !is_blank(b))
            .map_or(lead, |p| p + 1);
        out.push(Arg {
            text: &piece[lead..end],
            offset: offset + start + lead,
        });
        start += piece.len() + 1;
    }
    // Nothing but blanks: no argument.
    if let [only] = out.as_slice()
        && only.text.is_empty()
    {
        out.clear();
    }
    out
}

fn trim(s: &[u8]) -> &[u8] {
    let lead = s.iter().take_while(|&&b| is_blank(b)).count();
    let trail = s[lead..].iter().rev().take_while(|&&b| is_blank(b)).count();
    &s[lead..s.len() - trail]
}

/// Three finite numbers and nothing else, as a vector that is not zero.
fn vector(args: &[Arg], what: &str) -> Result<[f64; 3], StatementError> {
    let mut v = [0.0; 3];
    for (k, slot) in v.iter_mut().enumerate() {
        *slot = args[k].expect_number(what)?;
    }
    Ok(v)
}

fn non_zero(v: [f64; 3], at: &Arg, what: &str) -> Result<[f64; 3], StatementError> {
    if v.iter().map(|x| x * x).sum::<f64>() > 1e-24 {
        Ok(v)
    } else {
        Err(at.err(format!("{what} has zero length; expected a direction")))
    }
}

/// Statement majors that mark CL data at the start of a line.
const CL_MARKERS: &[&str] = &[
    "GOTO/",
    "TOOL PATH/",
    "PARTNO",
    "FEDRAT/",
    "TLDATA/",
    "MSYS/",
    "LOADTL/",
    "PAINT/",
    "UNITS/",
    "MULTAX",
    "SPINDL/",
    "TLAXIS/",
    "COOLNT/",
    "CUTTER/",
    "PPRINT",
    "END-OF-PATH",
    "FINI",
    "MODE/",
    "FROM/",
    "LOAD/",
    "CSYS/",
    "TRNTYP/",
    "UNIT/",
];

/// A GRBL system command line: `$` then `$`, `#`, letters, digits or a
/// `=value` (`$$`, `$I`, `$G`, `$#`, `$X`, `$10=255`, `$J=G91 X1 F100`),
/// and at most a `;` comment after; `$$` followed by other text is an APT
/// comment.
fn is_grbl_command(line: &[u8]) -> bool {
    let Some(rest) = line.strip_prefix(b"$") else {
        return false;
    };
    let code_end = rest
        .iter()
        .position(|&b| !(b.is_ascii_alphanumeric() || b == b'$' || b == b'#'))
        .unwrap_or(rest.len());
    let after = trim(&rest[code_end..]);
    after.is_empty() || after.starts_with(b";") || after.starts_with(b"=")
}

/// `true` if the start of a file looks like APT CL data rather than G-code:
/// a CL statement (`GOTO/`, `TOOL PATH/`, `$$`, `PARTNO`, `FEDRAT/`, ...)
/// starts a line before any line that holds a G-code word.
pub fn looks_like_cl(first_bytes: &[u8]) -> bool {
    let first_bytes = first_bytes.strip_prefix(BOM).unwrap_or(first_bytes);
    for (k, raw) in first_bytes.split(|&b| b == b'\n').enumerate() {
        let line = trim(strip_eol(raw));
        if line.is_empty() {
            continue;
        }
        // GRBL's system commands (`$$` alone or with a `;` comment, `$I`,
        // `$G`, `$#`, `$10=255`) decide nothing; `$$` with text is an APT
        // comment. Before, a GRBL program starting with `$$` was read as
        // CL and every move kept as a comment.
        if is_grbl_command(line) {
            continue;
        }
        if line.starts_with(b"$$") {
            return true;
        }
        // Blanks before `/` (`GOTO / 10 , 20 , 5`) do not count.
        let mut upper = Vec::with_capacity(line.len());
        for &b in line {
            if b == b'/' {
                while upper.last().is_some_and(|&c| is_blank(c)) {
                    upper.pop();
                }
            }
            upper.push(b.to_ascii_uppercase());
        }
        if CL_MARKERS.iter().any(|m| upper.starts_with(m.as_bytes())) || upper == b"RAPID" {
            return true;
        }
        if crate::gcode::parse_line(raw, k + 1)
            .words()
            .next()
            .is_some()
        {
            return false;
        }
    }
    false
}

#[cfg(test)]
mod tests;
