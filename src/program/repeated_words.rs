//! A word given twice in a pose block (`X1 … X5`, `I` with `A3` for the
//! same tool-axis component, `C10 … C20`) is refused, as LinuxCNC and
//! Fanuc refuse it: which one a controller would take is not for kinpost
//! to guess.

/// The slot of a pose block's word: words for the same thing share one.
fn slot_of(address: &str) -> Option<usize> {
    match address {
        "X" => Some(0),
        "Y" => Some(1),
        "Z" => Some(2),
        "I" | "A3" => Some(3),
        "J" | "B3" => Some(4),
        "K" | "C3" => Some(5),
        "F" => Some(6),
        "A" => Some(7),
        "B" => Some(8),
        "C" => Some(9),
        _ => None,
    }
}

/// A pose block's word: its address, value and item.
pub type Word<'a> = (&'a str, f64, usize);

/// The second of two `words` (a pose block's) that give the same thing:
/// its item and the message.
pub fn second<'a>(words: impl IntoIterator<Item = Word<'a>>) -> Option<(usize, String)> {
    let mut seen: [Option<(&str, f64)>; 10] = [None; 10];
    for (address, value, item) in words {
        let Some(k) = slot_of(address) else {
            continue;
        };
        if let Some(first) = seen[k] {
            return Some((
                item,
                format!(
                    "{} is given twice in this block ({}{} and {}{}): the block is ambiguous (LinuxCNC and Fanuc refuse it too)",
                    if first.0 == address {
                        format!("word {address}")
                    } else {
                        format!("the same tool-axis component ({} and {address})", first.0)
                    },
                    first.0,
                    first.1,
                    address,
                    value
                ),
            ));
        }
        seen[k] = Some((address, value));
    }
    None
}
