//! Errors with a location: every problem with an input names the file, the
//! line and the column, what was expected, and the offending text.

use std::fmt;

/// Where in an input file something was found (1-based line and column).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Location {
    /// File name as given on the command line (`-` or `<stdin>` for standard input).
    pub file: String,
    /// 1-based line number; 0 when the problem concerns the whole file.
    pub line: usize,
    /// 1-based column (byte offset within the line + 1); 0 when unknown.
    pub col: usize,
}

impl Location {
    /// A location in `file` at `line`, `col`.
    pub fn new(file: impl Into<String>, line: usize, col: usize) -> Self {
        Location {
            file: file.into(),
            line,
            col,
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.col) {
            (0, _) => write!(f, "{}", self.file),
            (l, 0) => write!(f, "{}:{}", self.file, l),
            (l, c) => write!(f, "{}:{}:{}", self.file, l, c),
        }
    }
}

/// Process exit codes (documented in `docs/cli.md`).
pub mod exit {
    /// Success.
    pub const OK: i32 = 0;
    /// Bad input: a malformed or unconvertible program, machine file, table or recording.
    pub const INPUT: i32 = 1;
    /// Bad command line (clap's own code).
    pub const USAGE: i32 = 2;
    /// An input or output file could not be read or written.
    pub const IO: i32 = 3;
}

/// The library's error type.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Something wrong with an input, at a known place.
    #[error("{loc}: {message}{}", snippet_suffix(.snippet))]
    Input {
        /// Where.
        loc: Location,
        /// What is wrong and what was expected.
        message: String,
        /// The offending text, if any.
        snippet: Option<String>,
    },
    /// An I/O failure on a named path.
    #[error("{path}: {source}")]
    Io {
        /// The path involved.
        path: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A bad combination of command-line options.
    #[error("{0}")]
    Usage(String),
}

/// Longest quoted line, in characters.
const SNIPPET_MAX: usize = 200;

fn snippet_suffix(s: &Option<String>) -> String {
    match s {
        Some(t) if !t.is_empty() => {
            let shown = visible(t.trim_end_matches(['\r', '\n']));
            if shown.chars().count() > SNIPPET_MAX {
                let head: String = shown.chars().take(SNIPPET_MAX).collect();
                format!("\n  | {head}…")
            } else {
                format!("\n  | {shown}")
            }
        }
        _ => String::new(),
    }
}

/// `text` with control characters shown: NUL as `\0`, a carriage return
/// as `\r`, other controls as `\xNN` (tabs stay). A quoted line must show
/// what is in it, and a raw control character would be invisible or move
/// the terminal's cursor.
pub fn visible(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\0' => out.push_str("\\0"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push('\t'),
            c if c.is_control() => out.push_str(&format!("\\x{:02X}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

impl Error {
    /// An input error at `loc`.
    pub fn input(loc: Location, message: impl Into<String>) -> Self {
        Error::Input {
            loc,
            message: message.into(),
            snippet: None,
        }
    }

    /// An input error at `loc` showing the offending text.
    pub fn input_with(
        loc: Location,
        message: impl Into<String>,
        snippet: impl Into<String>,
    ) -> Self {
        Error::Input {
            loc,
            message: message.into(),
            snippet: Some(snippet.into()),
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// True for a write to a pipe whose reader has gone (`| head`).
    pub fn is_broken_pipe(&self) -> bool {
        matches!(self, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::BrokenPipe)
    }

    /// The process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } => exit::INPUT,
            Error::Io { .. } => exit::IO,
            Error::Usage(_) => exit::USAGE,
        }
    }
}

/// Result alias.
pub type Result<T, E = Error> = std::result::Result<T, E>;
