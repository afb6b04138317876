//! The lines of a recording's CSV up to its first sample, shared by the
//! tool-tip recordings (`formats.md` §2) and the joint-feedback traces
//! (§2b): comment and blank lines, the header line (or a header written
//! as a comment, `# t,block,…`, as NumPy's `savetxt` writes one) and a
//! units row under it (`s,,mm,deg,…`, as many exports write one).

use std::io::BufRead;

use super::csv::{Dialect, column_name};
use crate::error::{Error, Location, Result};

/// Whether a line is skipped: blank, or a comment (`#`, `//`).
pub(crate) fn is_skippable(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#') || t.starts_with("//")
}

/// Removes the line end (LF, CRLF) of `line`.
pub(crate) fn strip_eol(line: &mut String) {
    while line.ends_with(['\n', '\r']) {
        line.pop();
    }
}

/// A CSV read line by line: the current line checked to be UTF-8, its
/// line end removed, and its number.
pub(crate) struct Lines<R: BufRead> {
    input: R,
    /// The file's name, for messages.
    pub file: String,
    /// Number of the current line (1-based; 0 before the first).
    pub line_no: usize,
    /// The raw bytes of the current line.
    bytes: Vec<u8>,
    /// The current line.
    pub buf: String,
}

impl<R: BufRead> Lines<R> {
    /// Lines of `input`, named `file` in messages.
    pub fn new(input: R, file: &str) -> Self {
        Lines {
            input,
            file: file.to_string(),
            line_no: 0,
            bytes: Vec::new(),
            buf: String::new(),
        }
    }

    /// Reads the next line into `buf`; `false` at the end of the input.
    pub fn next(&mut self) -> Result<bool> {
        self.bytes.clear();
        let n = self
            .input
            .read_until(b'\n', &mut self.bytes)
            .map_err(|e| Error::io(self.file.clone(), e))?;
        if n == 0 {
            return Ok(false);
        }
        self.line_no += 1;
        self.buf.clear();
        self.buf.push_str(crate::text::line_utf8(
            &self.bytes,
            &self.file,
            self.line_no,
        )?);
        strip_eol(&mut self.buf);
        if self.line_no == 1 && self.buf.starts_with('\u{feff}') {
            self.buf.drain(..3);
        }
        Ok(true)
    }

    /// Reads the next line that is not skipped; `false` at the end.
    pub fn next_data(&mut self) -> Result<bool> {
        while self.next()? {
            if !is_skippable(&self.buf) {
                return Ok(true);
            }
        }
        Ok(false)
    }
}

/// Whether every field of `line` (in its own dialect) is a number.
fn numbers_only(line: &str) -> bool {
    let d = Dialect::of_header(line);
    d.fields(line).iter().all(|(_, f)| d.number(f).is_some())
}

/// Whether `line` names a recording's columns: no field is a number, and
/// one is the time `t` (with or without a unit), a measured coordinate
/// `meas_…` or a fed-back axis `fb_…`.
fn names_columns(line: &str) -> bool {
    let d = Dialect::of_header(line);
    let fields = d.fields(line);
    !fields.is_empty()
        && fields.iter().all(|(_, f)| d.number(f).is_none())
        && fields.iter().any(|(_, f)| {
            let name = column_name(f).0;
            name == "t" || name.starts_with("meas_") || name.starts_with("fb_")
        })
}

/// A recording's header line.
#[derive(Debug, Clone)]
pub(crate) struct Header {
    /// Its line number.
    pub line: usize,
    /// Its text (of a header written as a comment, from the first name on).
    pub text: String,
    /// Columns before `text` in its line (`# ` of a comment header).
    pub shift: usize,
    /// The first sample's line was read with the header: it is the
    /// reader's current line.
    pub pending: bool,
}

impl Header {
    /// The header's fields in `dialect`, with their columns in the line.
    pub fn fields(&self, dialect: Dialect) -> Vec<(usize, &str)> {
        dialect
            .fields(&self.text)
            .into_iter()
            .map(|(c, f)| (c + self.shift, f))
            .collect()
    }
}

/// Reads up to the header of a recording; `example` shows a header in
/// the messages (`t,block,<axes>,meas_x,meas_y,meas_z`).
pub(crate) fn read_header<R: BufRead>(lines: &mut Lines<R>, example: &str) -> Result<Header> {
    // The last comment line before the header: its number, its text, and
    // where its content starts after `#` or `//`.
    let mut last_comment: Option<(usize, String, usize)> = None;
    loop {
        if !lines.next()? {
            return Err(Error::input(
                Location::new(lines.file.clone(), lines.line_no.max(1), 0),
                format!("empty recording: expected a header line `{example}`"),
            ));
        }
        if !is_skippable(&lines.buf) {
            break;
        }
        let buf = &lines.buf;
        let rest = buf.trim_start();
        if let Some(body) = rest.strip_prefix('#').or_else(|| rest.strip_prefix("//")) {
            let at = buf.len() - body.trim_start().len();
            last_comment = Some((lines.line_no, buf.clone(), at));
        }
    }
    if !numbers_only(&lines.buf) {
        return Ok(Header {
            line: lines.line_no,
            text: lines.buf.clone(),
            shift: 0,
            pending: false,
        });
    }
    // A header written as a comment: the first line that is not a comment
    // holds numbers only, and the comment before it names the columns.
    match last_comment.filter(|(_, c, at)| names_columns(&c[*at..])) {
        Some((line, c, at)) => Ok(Header {
            line,
            text: c[at..].to_string(),
            shift: at,
            pending: true,
        }),
        None => Err(Error::input_with(
            Location::new(lines.file.clone(), lines.line_no, 1),
            format!(
                "this line holds numbers only: a recording starts with a header line naming its columns (`{example}`; a header written as a comment, `# t,block,…`, is read where it is the comment line just before the samples)"
            ),
            lines.buf.clone(),
        )),
    }
}

/// Reads a units row under `header` where there is one (after a header
/// read with its first sample, there is none): `factor` (each column's
/// factor from its name) takes the row's units. Returns whether the line
/// read is a sample (then it is the reader's current line). `t_index` is
/// the time column, if any.
pub(crate) fn read_units_row<R: BufRead>(
    lines: &mut Lines<R>,
    header: &Header,
    dialect: Dialect,
    factor: &mut Vec<f64>,
    t_index: Option<usize>,
) -> Result<bool> {
    if header.pending {
        return Ok(true);
    }
    if !lines.next_data()? {
        return Ok(false);
    }
    let row = dialect.fields(&lines.buf);
    match super::csv::units_row(dialect, &header.fields(dialect), factor, &row, t_index) {
        Some(Ok(f)) => {
            *factor = f;
            Ok(false)
        }
        Some(Err((i, msg))) => {
            let col = row.get(i).map_or(1, |f| f.0);
            Err(Error::input_with(
                Location::new(lines.file.clone(), lines.line_no, col),
                msg,
                lines.buf.clone(),
            ))
        }
        None => Ok(true),
    }
}

/// The message for a value beyond the header's `n` fields (`f`, the
/// first): a row with a field too many is refused as one with a field too
/// few is (empty fields there, a trailing separator, are no values).
pub fn beyond_header(n: usize, f: &str) -> String {
    format!(
        "a value beyond the header's {n} fields: `{}` (a column missing from the header, or a separator too many in this row?)",
        f.trim()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_commented_header_names_the_columns_of_the_samples_after_it() {
        let text = "# exported 2026-11-28\n# t,block,X,fb_x\n0,1,2,3\n";
        let mut lines = Lines::new(text.as_bytes(), "r.csv");
        let h = read_header(&mut lines, "t,…").unwrap();
        assert_eq!(
            (h.line, h.text.as_str(), h.shift, h.pending),
            (2, "t,block,X,fb_x", 2, true)
        );
        assert_eq!(lines.buf, "0,1,2,3");
        let mut lines = Lines::new("# 1,2\n0,1\n".as_bytes(), "r.csv");
        let e = read_header(&mut lines, "t,…").unwrap_err().to_string();
        assert!(e.contains("r.csv:2:1") && e.contains("numbers only"), "{e}");
    }

    #[test]
    fn a_units_row_is_read_and_a_sample_is_left_for_the_reader() {
        let text = "\u{feff}t;X;fb_x\ns;µm;mm\n0;1;2\n";
        let mut lines = Lines::new(text.as_bytes(), "r.csv");
        let h = read_header(&mut lines, "t,…").unwrap();
        let d = Dialect::of_header(&h.text);
        let mut factor = vec![1.0; 3];
        assert!(!read_units_row(&mut lines, &h, d, &mut factor, Some(0)).unwrap());
        assert_eq!(factor, vec![1.0, 1e-3, 1.0]);
        let mut lines = Lines::new("t,X\n0,1\n".as_bytes(), "r.csv");
        let h = read_header(&mut lines, "t,…").unwrap();
        let d = Dialect::of_header(&h.text);
        assert!(read_units_row(&mut lines, &h, d, &mut factor, Some(0)).unwrap());
        assert_eq!(lines.buf, "0,1");
    }
}
