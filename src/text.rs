//! Reading text inputs (machine files, error tables, models, recordings)
//! with errors that say where: a directory or an empty file is named as
//! such, and bytes that are not UTF-8 are an input error at their
//! file:line:col instead of an anonymous I/O failure.
//!
//! Programs are not read through here: G-code and APT CL are read as bytes,
//! and non-UTF-8 bytes in their comments pass through unchanged.

use crate::error::{Error, Location, Result};
use std::path::Path;

/// Fails with an I/O error (exit 3) if `path` is a directory: opening one
/// succeeds on Unix, and reading it then fails with a bare `os error 21`.
pub fn check_not_dir(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::io(
            path.display().to_string(),
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "is a directory; expected a file",
            ),
        ));
    }
    Ok(())
}

/// Reads the whole file at `path` as UTF-8 text.
///
/// A missing or unreadable file and a directory are I/O errors (exit 3);
/// bytes that are not UTF-8 are an input error (exit 1) at the line and
/// column of the first bad byte, showing that line.
pub fn read_text_file(path: &Path) -> Result<String> {
    let name = path.display().to_string();
    check_not_dir(path)?;
    let mut bytes = Vec::new();
    crate::output::open_input(path)
        .and_then(|mut f| std::io::Read::read_to_end(&mut f, &mut bytes))
        .map_err(|e| Error::io(&name, e))?;
    into_utf8(bytes, &name, 1)
}

/// `bytes` as a `String`, or an input error at the first byte that is not
/// UTF-8 (`first_line` is the number of the first line in `bytes`).
pub fn into_utf8(bytes: Vec<u8>, file: &str, first_line: usize) -> Result<String> {
    match String::from_utf8(bytes) {
        Ok(s) => Ok(s),
        Err(e) => {
            let bytes = e.as_bytes();
            let at = e.utf8_error().valid_up_to();
            Err(not_utf8(bytes, at, file, first_line))
        }
    }
}

/// The error for a byte at offset `at` of `bytes` that is not UTF-8.
fn not_utf8(bytes: &[u8], at: usize, file: &str, first_line: usize) -> Error {
    let before = &bytes[..at.min(bytes.len())];
    let line_start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let line = first_line + before.iter().filter(|&&b| b == b'\n').count();
    let col = at - line_start + 1;
    let line_end = bytes[line_start..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |i| line_start + i);
    let byte = bytes.get(at).copied().unwrap_or(0);
    Error::input_with(
        Location::new(file, line, col),
        format!("byte 0x{byte:02X} is not UTF-8: expected UTF-8 text (save the file as UTF-8)"),
        String::from_utf8_lossy(&bytes[line_start..line_end]).into_owned(),
    )
}

/// One line of bytes as UTF-8 text, or an input error at `file:line:col`.
pub fn line_utf8<'a>(bytes: &'a [u8], file: &str, line: usize) -> Result<&'a str> {
    std::str::from_utf8(bytes).map_err(|e| not_utf8(bytes, e.valid_up_to(), file, line))
}

/// An input error for an empty (or blank) file: `what` says what was expected.
pub fn empty_file(file: &str, what: &str) -> Error {
    Error::input(
        Location::new(file, 1, 0),
        format!("the file is empty: expected {what}"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locates_the_first_bad_byte() {
        let e = into_utf8(b"ok\nab\xFFcd\nmore".to_vec(), "f.csv", 1).unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("f.csv:2:3: byte 0xFF is not UTF-8"), "{s}");
        assert!(s.contains("| ab\u{FFFD}cd"), "{s}");
        assert_eq!(e.exit_code(), crate::error::exit::INPUT);
        let e = line_utf8(b"x\xC3", "r.csv", 7).unwrap_err().to_string();
        assert!(e.starts_with("r.csv:7:2: byte 0xC3"), "{e}");
        assert_eq!(into_utf8(b"fine".to_vec(), "f", 1).unwrap(), "fine");
    }

    #[test]
    fn directory_is_an_io_error() {
        let d = tempfile::tempdir().unwrap();
        let e = read_text_file(d.path()).unwrap_err();
        assert_eq!(e.exit_code(), crate::error::exit::IO);
        assert!(e.to_string().contains("is a directory"), "{e}");
    }
}
