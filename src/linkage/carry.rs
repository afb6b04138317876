//! What happens to the words of a block that `linkage` divides.
//!
//! A divided block becomes inserted blocks followed by the block's own line
//! (its end point). The controller runs a block's modal codes, spindle,
//! coolant and tool words where the block starts, before its motion, and
//! its program stops where it ends (LinuxCNC's order of execution; Fanuc
//! issues M codes at the start of the block too). So those words go to the
//! first inserted block: left on the block's own line, `G91` would come
//! after increments the controller then reads as absolute positions, `G93`
//! after inverse-time feeds read as mm/min, `M3` after the cut it should
//! have started the spindle for. A block-delete `/` goes on every inserted
//! block, so the switch skips the whole block or none of it.

use crate::gcode::{ItemKind, Line};

/// M codes that act when their block ends: program stops and end, the
/// pallet change stop, subprogram call and return.
const AFTER_MOTION_M: [f64; 8] = [0.0, 1.0, 2.0, 30.0, 60.0, 98.0, 99.0, 198.0];

/// Axis-like addresses: a word of one the machine does not have moves
/// something (an extruder, a quill, a second slide) that kinpost cannot
/// divide between the inserted blocks.
const AXIS_LIKE: [&str; 10] = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W", "E"];

/// How the words of a block to be divided are shared out.
#[derive(Debug, Default, PartialEq)]
pub struct Carried {
    /// Items that move to the first inserted block, in line order.
    pub to_first: Vec<usize>,
    /// The block-delete prefix (`/`, `/1` … `/9`), written on every
    /// inserted block.
    pub block_delete: Option<Vec<u8>>,
}

/// Shares out the words of `line`, a `G1` block that is divided;
/// `axis_items` are its machine-axis words and `feed_item` its `F` (both
/// handled by the caller). Everything but `N`, `O`, the motion code `G0`/
/// `G1` and the stops (`M0`, `M1`, `M2`, `M30`, `M60`, `M98`, `M99`,
/// `M198`, with their `P`, `L`, `Q`) moves to the first inserted block.
///
/// An error names a word that cannot be shared out: an axis the machine
/// does not have (`E`, `W`, …), whose motion would land in one segment.
pub fn share_out(
    line: &Line,
    axis_items: &[usize],
    feed_item: Option<usize>,
) -> Result<Carried, (usize, String)> {
    let mut carried = Carried::default();
    let stop_here = line
        .words()
        .any(|w| w.address == "M" && AFTER_MOTION_M.iter().any(|m| (w.value - m).abs() < 1e-9));
    for (i, item) in line.items.iter().enumerate() {
        let w = match &item.kind {
            ItemKind::BlockDelete => {
                carried.block_delete = Some(line.item_bytes(item).to_vec());
                continue;
            }
            ItemKind::Word(w) => w,
            _ => continue,
        };
        if axis_items.contains(&i) || Some(i) == feed_item {
            continue;
        }
        let a = w.address.as_str();
        if AXIS_LIKE.contains(&a) {
            return Err((
                i,
                format!(
                    "this block must be divided, but it also carries `{a}`, an axis word the machine file does not have: kinpost cannot share that axis's motion out between the inserted blocks; program it in a block of its own"
                ),
            ));
        }
        let keep = match a {
            "N" | "O" => true,
            "G" => w.value == 0.0 || w.value == 1.0,
            "M" => AFTER_MOTION_M.iter().any(|m| (w.value - m).abs() < 1e-9),
            "P" | "L" | "Q" => stop_here,
            _ => false,
        };
        if !keep {
            carried.to_first.push(i);
        }
    }
    Ok(carried)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_line;

    fn items_text(line: &Line, items: &[usize]) -> Vec<String> {
        items
            .iter()
            .map(|&i| String::from_utf8_lossy(line.item_bytes(&line.items[i])).into_owned())
            .collect()
    }

    fn axes(line: &Line) -> Vec<usize> {
        line.items
            .iter()
            .enumerate()
            .filter_map(|(i, it)| match &it.kind {
                ItemKind::Word(w) if matches!(w.address.as_str(), "X" | "Y" | "Z" | "B" | "C") => {
                    Some(i)
                }
                _ => None,
            })
            .collect()
    }

    #[test]
    fn modal_codes_spindle_and_coolant_go_first_stops_stay() {
        let l = parse_line(b"N40 G91 G1 X1 Y2 Z3 B4 C5 S2000 M3 M8 F500", 1);
        let c = share_out(&l, &axes(&l), None).unwrap();
        assert_eq!(
            items_text(&l, &c.to_first),
            ["G91", "S2000", "M3", "M8", "F500"]
        );
        let l = parse_line(b"G1 X1 B4 M98 P100 L2", 1);
        let c = share_out(&l, &axes(&l), None).unwrap();
        assert!(c.to_first.is_empty(), "{:?}", items_text(&l, &c.to_first));
        let l = parse_line(b"G64 P0.01 G1 X1 B4", 1);
        let c = share_out(&l, &axes(&l), None).unwrap();
        assert_eq!(items_text(&l, &c.to_first), ["G64", "P0.01"]);
    }

    #[test]
    fn block_delete_and_foreign_axes() {
        let l = parse_line(b"/2 G1 X1 B4", 1);
        let c = share_out(&l, &axes(&l), None).unwrap();
        assert_eq!(c.block_delete.as_deref(), Some(&b"/2"[..]));
        let l = parse_line(b"G1 X1 B4 E0.25", 1);
        let (item, msg) = share_out(&l, &axes(&l), None).unwrap_err();
        assert_eq!(items_text(&l, &[item]), ["E0.25"]);
        assert!(msg.contains("`E`"), "{msg}");
    }
}
