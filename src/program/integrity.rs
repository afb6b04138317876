//! Lines that must not pass: a NUL byte (a damaged or binary file), a
//! last line cut short while in pose mode (`X12.3` of `X12.345`), and a
//! Heidenhain conversational block that gives tool poses
//! ([`super::heidenhain`]).

use crate::error::{Error, Location, Result};
use crate::gcode::Line;

/// Whether `line` ends the program (`M2`, `M30`, `M99`, `%`): such a last
/// line is whole even without a line end.
pub fn ends_program(line: &Line) -> bool {
    super::tape::is_tape_mark(line)
        || ends_main_program(line)
        || line.words().any(|w| w.address == "M" && w.value == 99.0)
}

pub use super::tape::ends_main_program;

/// Refuses `line` of `file` when it holds a NUL byte (a text NC program
/// never does), or when it is the last line, lacks its line end, does not
/// end the program and pose mode is on (the rest of it may have been a
/// pose), or when it is a Heidenhain conversational block that switches
/// TCPM on or gives a tool vector ([`super::heidenhain::check_block`]).
pub fn check_line(line: &Line, file: &str, pose_mode: bool) -> Result<()> {
    // Only the last line of a file can lack its line end.
    if pose_mode
        && !line.bytes.ends_with(b"\n")
        && !line.bytes.iter().all(|b| b.is_ascii_whitespace())
        && !ends_program(line)
    {
        return Err(Error::input_with(
            Location::new(file, line.number, line.bytes.len() + 1),
            "the file ends without a line end while in pose mode: a truncated file? The rest of the block may have been a pose; if the program is complete, end it with a line break (and M30)",
            String::from_utf8_lossy(&line.bytes),
        ));
    }
    // `contains` on bytes is a vectorised search; the position only then.
    if line.bytes.contains(&0)
        && let Some(at) = line.bytes.iter().position(|b| *b == 0)
    {
        let message = if looks_like_utf16(&line.bytes) {
            "the file is UTF-16 text (what a Windows editor saves as \"Unicode\"), which no controller reads: save it as ASCII or UTF-8"
        } else {
            "a NUL byte: the file is damaged or not a text NC program"
        };
        return Err(Error::input_with(
            Location::new(file, line.number, at + 1),
            message,
            String::from_utf8_lossy(&line.bytes),
        ));
    }
    super::heidenhain::check_block(&line.bytes, file, line.number)
}

/// Whether `bytes` (a line holding NUL bytes) look like UTF-16 text: a
/// byte order mark (`FF FE`, `FE FF`), or ASCII with a NUL beside each
/// character (every other byte NUL; the line was cut at an LF, whose own
/// NUL may come after it).
pub fn looks_like_utf16(bytes: &[u8]) -> bool {
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return true;
    }
    let body = bytes.strip_suffix(b"\n").unwrap_or(bytes);
    let every_other_nul = |parity: usize| {
        body.len() >= 4
            && body
                .iter()
                .enumerate()
                .all(|(i, b)| i % 2 != parity || *b == 0)
    };
    every_other_nul(0) || every_other_nul(1)
}
