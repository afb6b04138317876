//! RS-274 / ISO 6983 G-code: a lossless nom parser and its block model.
//!
//! Programs are read one physical line at a time ([`LineReader`]); each line
//! becomes a [`Line`] whose [`Item`]s tile its bytes exactly, so a line
//! written back from its parse tree ([`Line::write_to`]) is byte for byte
//! the line that was read, whatever it holds: CRLF, tabs, non-UTF-8 bytes in
//! comments, LinuxCNC expressions, Siemens keywords.
//!
//! The accepted syntax is written down in `grammar/gcode.ebnf`.
//!
//! ```
//! use kinpost::gcode::{parse_line, ItemKind};
//!
//! let line = parse_line(b"N10 G1X10 y-.5 (cut)\r\n", 1);
//! let words: Vec<_> = line.words().map(|w| (w.address.as_str(), w.value)).collect();
//! assert_eq!(words, [("N", 10.0), ("G", 1.0), ("X", 10.0), ("Y", -0.5)]);
//! assert!(!line.has_opaque());
//! let mut out = Vec::new();
//! line.write_to(&mut out).unwrap();
//! assert_eq!(out, line.bytes);
//! ```

mod address;
mod block;
mod parse;
mod reader;
mod summary;

pub use address::Address;
pub use block::{Item, ItemKind, Line, Word};
pub use parse::{parse_line, parse_line_into, parse_line_swap};
pub use reader::{LineReader, echo};
pub use summary::{Summary, summarize};
