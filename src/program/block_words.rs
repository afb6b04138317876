//! The words and keywords of a block, as the modal state reads them.

use super::modal::WordRef;
use crate::gcode::{ItemKind, Line};

/// Appends the words of `line` to `words` and its keywords to `keywords`
/// (with their item indices): a block delete `/` as the pseudo-keyword
/// `/`, a Sinumerik call kinpost knows in text it does not parse
/// (`TRAORI`, `CYCLE800(…)`) as its name, and a Fagor instruction
/// (`#RTCP ON`) as its pseudo-keyword ([`super::fagor`]).
#[inline]
pub fn block_words<'l>(
    line: &'l Line,
    words: &mut Vec<WordRef<'l>>,
    keywords: &mut Vec<(usize, &'l str)>,
) {
    for (i, item) in line.items.iter().enumerate() {
        match &item.kind {
            ItemKind::Word(w) => words.push(WordRef {
                address: w.address.as_str(),
                value: w.value,
                item: i,
            }),
            // `TRAORI (1,0,1,0)`: a blank between the call and its
            // arguments, which the parser reads as a comment.
            ItemKind::Keyword(k) if k == "TRAORI" => keywords.push((
                i,
                match spaced_arguments(line, i) {
                    Some(args) if args.contains(',') => "TRAORI(…)",
                    _ => "TRAORI",
                },
            )),
            ItemKind::Keyword(k) => keywords.push((i, k.as_str())),
            ItemKind::BlockDelete => keywords.push((i, "/")),
            ItemKind::Opaque => {
                let text = String::from_utf8_lossy(line.item_bytes(item));
                if let Some(k) = super::opaque::known_call(&text)
                    .or_else(|| super::fagor::instruction(&text))
                    .or_else(|| super::frames::frame_variable(&text))
                {
                    keywords.push((i, k));
                }
            }
            _ => {}
        }
    }
}

/// The argument list of the keyword at item `i` of `line` where it follows
/// the keyword after blanks, as Sinumerik allows (`TRAORI (1)`), and the
/// parser has read it as a comment: its text (with the parentheses) when
/// it holds numbers only (digits, signs, points, commas and blanks), else
/// `None` (a comment, `TRAORI (tcp on)`).
pub fn spaced_arguments(line: &Line, i: usize) -> Option<String> {
    let next = line.items[i + 1..]
        .iter()
        .find(|it| !matches!(it.kind, ItemKind::Space))?;
    if !matches!(next.kind, ItemKind::Comment) {
        return None;
    }
    let text = String::from_utf8_lossy(line.item_bytes(next));
    let inner = text.strip_prefix('(')?.strip_suffix(')')?;
    let numeric = !inner.trim().is_empty()
        && inner
            .chars()
            .all(|c| c.is_ascii_digit() || " \t,.+-".contains(c));
    numeric.then(|| text.into_owned())
}
