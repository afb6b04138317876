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
            ItemKind::Keyword(k) => keywords.push((i, k.as_str())),
            ItemKind::BlockDelete => keywords.push((i, "/")),
            ItemKind::Opaque => {
                let text = String::from_utf8_lossy(line.item_bytes(item));
                if let Some(k) =
                    super::opaque::known_call(&text).or_else(|| super::fagor::instruction(&text))
                {
                    keywords.push((i, k));
                }
            }
            _ => {}
        }
    }
}
