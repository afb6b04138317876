//! Fanuc and Sinumerik program flow (jumps, branches, loops, labels):
//! kinpost does not evaluate it, so in pose mode it cannot know which pose
//! blocks run, or how often, or from where. LinuxCNC's o-word flow is
//! [`super::opaque::o_word_statement`].

use crate::gcode::{ItemKind, Line};

/// Words that jump, branch or loop: Sinumerik `GOTOF`, `GOTOB`, `GOTOC`,
/// `GOTO`, `IF`, `ELSE`, `ENDIF`, `WHILE`, `ENDWHILE`, `REPEAT`,
/// `REPEATB`, `UNTIL`, `LOOP`, `ENDLOOP`, `FOR`, `ENDFOR`, `CASE`; Fanuc
/// custom macro B `GOTO`, `IF`, `WHILE` with `DO1`–`DO3` and `END1`–`END3`.
const FLOW_WORDS: &[&str] = &[
    "GOTO", "GOTOF", "GOTOB", "GOTOC", "IF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "REPEAT",
    "REPEATB", "UNTIL", "LOOP", "ENDLOOP", "FOR", "ENDFOR", "CASE", "DO1", "DO2", "DO3", "END1",
    "END2", "END3",
];

/// The byte offset in `line` and the text of a flow statement: a flow
/// word (`GOTOF`, `IF`, `WHILE`, `DO1`, …) outside comments, a Sinumerik
/// label (`LBL1:` first on the line, after its block number), or Fanuc's
/// `M99 P` (a return or a jump to a block number). `None` when the line
/// has none.
pub fn flow_statement(line: &Line) -> Option<(usize, String)> {
    // A plain block of words (every pose block) holds none: only a keyword,
    // text the parser does not read, a label's colon or an M word can.
    let maybe = line.items.iter().any(|it| match &it.kind {
        ItemKind::Keyword(_) | ItemKind::Opaque => true,
        ItemKind::Word(w) => w.address == "M",
        _ => false,
    }) || line.bytes.contains(&b':');
    if !maybe {
        return None;
    }
    // The line's text with its comments blanked out, offsets kept.
    let mut text = line.bytes.clone();
    for it in &line.items {
        if it.kind == ItemKind::Comment {
            text[it.start..it.end].fill(b' ');
        }
    }
    let mut first = true;
    let mut at = 0;
    while at < text.len() {
        if !text[at].is_ascii_alphanumeric() && text[at] != b'_' {
            at += 1;
            continue;
        }
        let start = at;
        while at < text.len() && (text[at].is_ascii_alphanumeric() || text[at] == b'_') {
            at += 1;
        }
        let token = String::from_utf8_lossy(&text[start..at]).to_ascii_uppercase();
        if FLOW_WORDS.contains(&token.as_str()) {
            return Some((start, token));
        }
        let block_number = token.starts_with('N') && token[1..].bytes().all(|b| b.is_ascii_digit());
        if first && !block_number {
            if text.get(at) == Some(&b':')
                && token
                    .bytes()
                    .next()
                    .is_some_and(|b| b.is_ascii_alphabetic())
            {
                return Some((start, format!("{token}:")));
            }
            first = false;
        }
    }
    let m99 = line.words().any(|w| w.address == "M" && w.value == 99.0);
    let p = line
        .items
        .iter()
        .find(|it| matches!(&it.kind, ItemKind::Word(w) if w.address == "P"));
    match (m99, p) {
        (true, Some(p)) => Some((p.start, "M99 P".to_string())),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flow(text: &str) -> Option<String> {
        flow_statement(&crate::gcode::parse_line(text.as_bytes(), 1)).map(|(_, t)| t)
    }

    #[test]
    fn jumps_loops_and_labels_are_found_and_moves_are_not() {
        for (text, want) in [
            ("N40 GOTOF LBL1", "GOTOF"),
            ("LBL1:", "LBL1:"),
            ("N50 LBL_2: G1 X1", "LBL_2:"),
            ("GOTO 100", "GOTO"),
            ("IF [#1 GT 2] GOTO 100", "IF"),
            ("WHILE [#1 LT 3] DO1", "WHILE"),
            ("END1", "END1"),
            ("M99 P10", "M99 P"),
            ("REPEAT LBL1 P=2", "REPEAT"),
            ("IF R1>2 GOTOB LBL1", "IF"),
            ("endif", "ENDIF"),
        ] {
            assert_eq!(flow(text).as_deref(), Some(want), "{text}");
        }
        for text in [
            "G1 X10 Y20 Z30 I0 J0 K1 F500",
            "N10 G0 X0 (GOTO here IF needed)",
            "; WHILE in a comment",
            "M99",
            "TRAORI",
            "G1 X1 A3=0 B3=0 C3=1",
            ":10 G1 X1",
        ] {
            assert_eq!(flow(text), None, "{text}");
        }
    }
}
