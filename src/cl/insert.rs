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

/// One word of NC code: its letter and number, and its offset in the text.
struct Word<'a> {
    letter: char,
    number: &'a str,
    at: usize,
}

/// The NC words of `text` (parenthesised comments and a `;` comment
/// skipped); `Err(offset)` at the first byte that is not part of a word.
fn words(text: &str) -> Result<Vec<Word<'_>>, usize> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b' ' | b'\t' => i += 1,
            b'(' => match text[i..].find(')') {
                Some(end) => i += end + 1,
                None => return Err(i),
            },
            b';' => break,
            c if c.is_ascii_alphabetic() => {
                let start = i + 1;
                let mut j = start;
                if j < b.len() && matches!(b[j], b'+' | b'-') {
                    j += 1;
                }
                let digits = j;
                while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                    j += 1;
                }
                let number = &text[start..j];
                if j == digits || number.parse::<f64>().is_err() {
                    return Err(i);
                }
                out.push(Word {
                    letter: c.to_ascii_uppercase() as char,
                    number,
                    at: i,
                });
                i = j;
            }
            _ => return Err(i),
        }
    }
    Ok(out)
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
    let ws = words(body).map_err(|at| {
        refuse(
            at,
            format!(
                "`{}` is not an NC word (a letter and a number)",
                body[at..].split_whitespace().next().unwrap_or("")
            ),
        )
    })?;
    for w in &ws {
        let passed = match w.letter {
            'M' => w
                .number
                .parse::<f64>()
                .ok()
                .filter(|v| v.fract() == 0.0 && *v >= 0.0)
                .is_some_and(|v| PASSED_M.contains(&(v as u32))),
            'S' | 'N' => true,
            _ => false,
        };
        if !passed {
            return Err(refuse(
                w.at,
                format!(
                    "`{}{}` is not passed through (only M0, M1, M2, M3, M4, M5, M7, M8, M9, M30, S and N words are)",
                    w.letter, w.number
                ),
            ));
        }
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
