//! Lines that must not pass: a NUL byte (a damaged or binary file), a
//! last line cut short while in pose mode (`X12.3` of `X12.345`), and a
//! Heidenhain conversational block that gives tool poses
//! ([`super::heidenhain`]).

use crate::error::{Error, Location, Result};
use crate::gcode::Line;

/// Whether `line` ends the program (`M2`, `M30`, `M99`, `%`): such a last
/// line is whole even without a line end.
pub fn ends_program(line: &Line) -> bool {
    line.bytes.trim_ascii() == b"%"
        || line
            .words()
            .any(|w| w.address == "M" && [2.0, 30.0, 99.0].contains(&w.value))
}

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
        return Err(Error::input_with(
            Location::new(file, line.number, at + 1),
            "a NUL byte: the file is damaged or not a text NC program",
            String::from_utf8_lossy(&line.bytes),
        ));
    }
    super::heidenhain::check_block(&line.bytes, file, line.number)
}
