//! Heidenhain conversational (Klartext) blocks: kinpost does not convert
//! them, and refuses the ones that give tool poses.
//!
//! A Klartext block starts with its block number and a blank (`6 LN X+12.5
//! Y+3.25 Z-1 TX+0 TY+0.5 TZ+0.866 F1000`); no G-code block starts with a
//! bare number, so the G-code parser keeps such a line as opaque text and it
//! passes through unchanged. That is right for a program that only moves
//! the machine axes (a three-axis program through a filter), but not for
//! one that gives tool poses, which kinpost would leave for the control to
//! transform a second time, or not at all:
//!
//! - `M128` and `FUNCTION TCPM` switch the control's tool centre point
//!   management on (Heidenhain's `G43.4` / `TRAORI`); after them the
//!   blocks are tool-tip positions with a tool orientation;
//! - an `LN` block with a tool vector `TX TY TZ` is a pose by itself, as a
//!   G-code straight move with `I J K` is.
//!
//! Both are refused at their column; `FUNCTION RESET TCPM` and `M129`
//! (TCPM off) pass. The readers of programs in machine axes (`linkage`,
//! `analyze --nonlinear`) refuse every Klartext move
//! ([`check_machine_block`]): its axis words are the blocks they exist to
//! read.

use crate::error::{Error, Location, Result};

/// The block number of a Klartext line and the offset of its first word,
/// or `None` when `bytes` does not start (after blanks) with a number, a
/// blank and a word.
fn block_body(bytes: &[u8]) -> Option<usize> {
    let start = bytes.iter().position(|b| !matches!(b, b' ' | b'\t'))?;
    let digits = bytes[start..]
        .iter()
        .take_while(|b| b.is_ascii_digit())
        .count();
    if digits == 0 {
        return None;
    }
    let after = start + digits;
    let blanks = bytes[after..]
        .iter()
        .take_while(|b| matches!(b, b' ' | b'\t'))
        .count();
    let body = after + blanks;
    (blanks > 0 && bytes.get(body).is_some_and(u8::is_ascii_alphabetic)).then_some(body)
}

/// The words of a block (split at blanks, before a `;` comment), with their
/// byte offsets in `bytes`.
fn words(bytes: &[u8], body: usize) -> impl Iterator<Item = (usize, &[u8])> {
    let end = bytes[body..]
        .iter()
        .position(|b| *b == b';')
        .map_or(bytes.len(), |p| body + p);
    let text = &bytes[body..end];
    text.split(|b| b.is_ascii_whitespace())
        .filter(|w| !w.is_empty())
        .map(move |w| (body + (w.as_ptr() as usize - text.as_ptr() as usize), w))
}

/// Refuses `bytes` (line `number` of `file`) when it is a Klartext block
/// that switches TCPM on or gives a tool vector (see the module docs).
/// Any other line passes.
pub fn check_block(bytes: &[u8], file: &str, number: usize) -> Result<()> {
    let Some(body) = block_body(bytes) else {
        return Ok(());
    };
    let refuse = |at: usize, what: String| {
        Err(Error::input_with(
            Location::new(file, number, at + 1),
            format!(
                "a Heidenhain conversational block {what}: kinpost does not convert Heidenhain (Klartext) programs; post the CAM system's CL data or a G-code program for this machine instead, or run this one with the control's own TCPM, without kinpost"
            ),
            String::from_utf8_lossy(bytes),
        ))
    };
    let ws: smallvec::SmallVec<[(usize, &[u8]); 16]> = words(bytes, body).collect();
    let is = |w: &[u8], s: &str| w.eq_ignore_ascii_case(s.as_bytes());
    for (k, &(at, w)) in ws.iter().enumerate() {
        if is(w, "M128") {
            return refuse(
                at,
                "with `M128` (tool centre point management on: the blocks after it are tool-tip positions with a tool orientation)".into(),
            );
        }
        if is(w, "TCPM")
            && k > 0
            && is(ws[k - 1].1, "FUNCTION")
            && ws[..k].iter().all(|(_, w)| !is(w, "RESET"))
        {
            let at = ws[k - 1].0;
            return refuse(
                at,
                "with `FUNCTION TCPM` (tool centre point management on: the blocks after it are tool-tip positions with a tool orientation)".into(),
            );
        }
    }
    if let Some(&(_, first)) = ws.first()
        && is(first, "LN")
        && let Some(&(at, w)) = ws.iter().find(|(_, w)| {
            w.len() > 2
                && (is(&w[..2], "TX") || is(&w[..2], "TY") || is(&w[..2], "TZ"))
                && matches!(w[2], b'+' | b'-' | b'0'..=b'9' | b'.')
        })
    {
        return refuse(
            at,
            format!(
                "with a tool vector (`{}`): an `LN` block with TX TY TZ is a tool pose",
                String::from_utf8_lossy(w)
            ),
        );
    }
    Ok(())
}

/// The Klartext path functions: straight lines (`L`, `LN`, polar `LP`),
/// circles (`C`, `CR`, `CT`, polar `CP`, `CTP`) and corner blocks (`RND`,
/// `CHF`).
const MOVES: [&str; 10] = ["L", "LN", "LP", "C", "CR", "CT", "CP", "CTP", "RND", "CHF"];

/// [`check_block`], and besides it refuses every Klartext move (see
/// `MOVES`): for the readers of programs in machine axes, whose
/// blocks these are.
pub fn check_machine_block(bytes: &[u8], file: &str, number: usize) -> Result<()> {
    check_block(bytes, file, number)?;
    let Some(body) = block_body(bytes) else {
        return Ok(());
    };
    let Some((at, first)) = words(bytes, body).next() else {
        return Ok(());
    };
    let name = String::from_utf8_lossy(first).to_ascii_uppercase();
    if MOVES.contains(&name.as_str()) {
        return Err(Error::input_with(
            Location::new(file, number, at + 1),
            format!(
                "a Heidenhain conversational move (`{name}`): kinpost reads programs in machine axes as G-code only; have the CAM system or the control write this program as G-code"
            ),
            String::from_utf8_lossy(bytes),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn col(line: &str) -> Option<usize> {
        check_block(line.as_bytes(), "p.h", 7).err().map(|e| {
            let s = e.to_string();
            let rest = s.strip_prefix("p.h:7:").unwrap_or_else(|| panic!("{s}"));
            rest.split(':').next().unwrap().parse().unwrap()
        })
    }

    #[test]
    fn tcpm_and_tool_vectors_are_refused_at_their_column() {
        assert_eq!(col("4 M128\n"), Some(3));
        assert_eq!(col("  12 L Z+100 R0 FMAX m128 ; TCPM on\n"), Some(22));
        assert_eq!(
            col("5 FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS\n"),
            Some(3)
        );
        assert_eq!(
            col("6 LN X+12.5 Y+3.25 Z-1 TX+0 TY+0.5 TZ+0.866025 F1000\n"),
            Some(24)
        );
        assert_eq!(col("6 LN X+1 Y+2 Z+3 TX-.5 TY+0 TZ+.866\r\n"), Some(18));
    }

    #[test]
    fn other_lines_pass() {
        for line in [
            "0 BEGIN PGM TEST MM\n",
            "5 L X+10 Y+5 Z+20 R0 FMAX\n",
            "7 FUNCTION RESET TCPM\n",
            "8 L Z+100 R0 FMAX M129\n",
            "9 LN X+1 Y+2 Z+3 NX+0 NY+0 NZ+1\n",
            "10 TOOL CALL 1 Z S5000 ; M128 in a comment\n",
            "G1 X1 Y2 Z3 I0 J0 K1\n",
            "N10 G1 X1 M128\n",
            "128\n",
            "%\n",
            "",
        ] {
            assert_eq!(col(line), None, "{line:?}");
        }
    }

    #[test]
    fn machine_axis_readers_refuse_every_klartext_move() {
        let col = |line: &str| {
            check_machine_block(line.as_bytes(), "p.h", 3)
                .err()
                .map(|e| e.to_string())
        };
        let e = col("7 L X+20 B+30 C+45 F500\n").unwrap();
        assert!(
            e.starts_with("p.h:3:3: a Heidenhain conversational move (`L`)"),
            "{e}"
        );
        assert!(col("12 cr x+5 y+5 r+10 dr+\n").unwrap().contains("(`CR`)"));
        assert!(col("4 M128\n").unwrap().contains("M128"));
        for line in ["3 TOOL CALL 1 Z S5000\n", "G1 X1 B2\n", "8 END PGM T MM\n"] {
            assert_eq!(col(line), None, "{line:?}");
        }
    }
}
