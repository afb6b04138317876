//! `INSERT/text`: text a CAM system passes to the NC program as it is.
//!
//! CAM systems use it two ways. SolidWorks CAM writes tool descriptions
//! and notes (`INSERT/5MM CRB 4FL 16 LOC`, `INSERT/Stock Size X85. Y38.
//! Z48.`), which stay comments. Other systems and hand-edited CL pass NC
//! code (`INSERT/M8`, `INSERT/G0 X10 Y20`). Code that only switches the
//! spindle or the coolant, stops, or ends the program is written as it is;
//! code that moves the tool or changes what the axis words mean (an axis,
//! feed, tool or G word) would bypass the conversion, and is refused at
//! the word. Before, every INSERT was a comment: `M8` was lost, and
//! `G0 X10 Y20` dropped a move with exit 0.

/// M codes passed through: program stop and optional stop, spindle,
/// coolant, end of program.
const PASSED_M: &[u32] = &[0, 1, 2, 3, 4, 5, 7, 8, 9, 30];

/// What an INSERT's text (after the `/`) is.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Inserted {
    /// Text, not NC code: kept as a comment.
    Text,
    /// NC code to write as it is (trimmed).
    Code(String),
}

/// Reads an INSERT's text: NC code where it starts with a word (a letter
/// and a number: `G0`, `M8`); `Err((offset in text, message))` for code
/// that is not passed through.
pub(super) fn inserted(text: &str) -> Result<Inserted, (usize, String)> {
    let lead = text.len() - text.trim_start().len();
    let body = text.trim();
    let starts_with_word = {
        let b = body.as_bytes();
        b.len() >= 2
            && b[0].is_ascii_alphabetic()
            && (b[1].is_ascii_digit() || matches!(b[1], b'.' | b'+' | b'-'))
    };
    if !starts_with_word {
        return Ok(Inserted::Text);
    }
    let refuse = |at: usize, what: String| {
        (
            lead + at,
            format!(
                "INSERT passes `{body}` to the NC program, and {what}: it would bypass the conversion to this machine's axes; write the motion as CL statements (GOTO, FEDRAT, LOADTL, …), or leave it out"
            ),
        )
    };
    // The text read by the G-code lexer: words, comments and blanks pass
    // the check below; anything else (a keyword, an expression) is refused.
    use crate::gcode::ItemKind;
    let line = crate::gcode::parse_line(body.as_bytes(), 1);
    for item in &line.items {
        let text = &body[item.start..item.end.min(body.len())];
        let passed = match &item.kind {
            ItemKind::Space | ItemKind::Comment | ItemKind::EndOfLine => true,
            ItemKind::Word(w) if w.is("M") => {
                w.value.fract() == 0.0 && w.value >= 0.0 && PASSED_M.contains(&(w.value as u32))
            }
            ItemKind::Word(w) => w.is("S") || w.is("N"),
            _ => false,
        };
        if passed {
            continue;
        }
        return Err(refuse(
            item.start,
            if matches!(item.kind, ItemKind::Word(_)) {
                format!(
                    "`{text}` is not passed through (only M0, M1, M2, M3, M4, M5, M7, M8, M9, M30, S and N words are)"
                )
            } else {
                format!(
                    "`{}` is not an NC word (a letter and a number)",
                    text.split_whitespace().next().unwrap_or("")
                )
            },
        ));
    }
    Ok(Inserted::Code(body.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_are_text_and_plain_codes_pass() {
        for t in [
            "5MM CRB 4FL 16 LOC",
            "Stock Size X85. Y38. Z48.",
            "STOP  change fixture",
            "",
        ] {
            assert_eq!(inserted(t), Ok(Inserted::Text), "{t}");
        }
        assert_eq!(inserted(" M8"), Ok(Inserted::Code("M8".into())));
        assert_eq!(
            inserted("S1200 M3 (spindle on)"),
            Ok(Inserted::Code("S1200 M3 (spindle on)".into()))
        );
        assert_eq!(inserted("m09;off"), Ok(Inserted::Code("m09;off".into())));
    }

    #[test]
    fn code_that_moves_or_changes_the_axes_is_refused_at_its_word() {
        for (t, at, word) in [
            ("G0 X10 Y20", 0, "`G0`"),
            ("M8 X10", 3, "`X10`"),
            (" T2 M6", 1, "`T2`"),
            ("M8 F500", 3, "`F500`"),
            ("M98 P100", 0, "`M98`"),
            ("M8 coolant on", 3, "`coolant`"),
            ("M8 (open", 3, "`(open`"),
        ] {
            let (off, msg) = inserted(t).unwrap_err();
            assert_eq!(off, at, "{t}: {msg}");
            assert!(msg.contains(word), "{t}: {msg}");
        }
    }
}
