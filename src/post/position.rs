//! Where the machine is in program coordinates, as far as a program's
//! blocks in machine axes say: the codes and statements after which the
//! [`super::BlockReader`] no longer knows it, so that the next pose must
//! give X, Y and Z.

use crate::gcode::{ItemKind, Line};
use crate::machine::Machine;
use crate::program::BlockMeaning;
use crate::program::modal::Motion;
use nalgebra::Vector3;

/// How a line loses the machine's position ([`loses_position`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Lost {
    /// Before its own words: a tool change (`M6`), a new work offset
    /// (`G54`–`G59.3`, `G54.1`, Sinumerik `G500`, `G505`–`G599`), offsets
    /// set (`G10 L2`, `L20`).
    Before,
    /// A subprogram or macro call (`M98`, `M97`, `M198`, `G65`, `G66`,
    /// `G66.1`, `o100 call`, Sinumerik `L100`, `CALL`, `PCALL`, `EXTCALL`, a cycle):
    /// its words are arguments, not a move.
    Call,
}

/// Whether `line` moves the machine, or changes the program's coordinates,
/// in a way its axis words do not say (besides [`goes_where_not_known`]).
/// `new_offset`: the line selects a work offset other than the one in
/// force (selecting that one again changes nothing).
pub(super) fn loses_position(line: &Line, new_offset: bool) -> Option<Lost> {
    let g = |v: f64| {
        line.words()
            .any(|w| w.address == "G" && (w.value - v).abs() < 1e-9)
    };
    let m = |v: f64| line.words().any(|w| w.address == "M" && w.value == v);
    use crate::program::unfollowed::{CALL_KEYWORDS, call_word};
    let calls_word = line.words().any(|w| call_word(&w.address, w.value));
    let calls_keyword = line.keywords().any(|k| CALL_KEYWORDS.contains(&k));
    let calls_opaque = line.items.iter().any(|it| {
        matches!(it.kind, ItemKind::Opaque) && {
            let text = String::from_utf8_lossy(line.item_bytes(it));
            crate::program::opaque::call_name(&text).is_some()
                && !crate::program::opaque::harmless_call(&text)
                && crate::program::opaque::known_call(&text).is_none()
        }
    });
    // Sinumerik `L100`: a subprogram call when the block has no other word
    // (`G10 L2`, a cycle's repeat count `L` go with other words).
    let sinumerik_l = line.words().any(|w| w.address == "L")
        && line
            .words()
            .all(|w| matches!(w.address.as_ref(), "L" | "N" | "P"));
    if calls_word || calls_keyword || calls_opaque || sinumerik_l {
        return Some(Lost::Call);
    }
    let offset = new_offset
        && ([
            54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 54.1, 59.1, 59.2, 59.3, 500.0,
        ]
        .iter()
        .any(|&v| g(v))
            || line
                .words()
                .any(|w| w.address == "G" && (505.0..=599.0).contains(&w.value)));
    let set_offsets = g(10.0)
        && line
            .words()
            .any(|w| w.address == "L" && (w.value == 2.0 || w.value == 20.0));
    (m(6.0) || offset || set_offsets).then_some(Lost::Before)
}

/// Whether `line`, a block outside pose mode that kinpost passes on as
/// it is, may leave the machine where its axis words do not say, so that
/// the position followed through it is not known after it: what the
/// commands that follow motion refuse in such a block (docs/programs.md)
/// — a code not followed (`meaning.unfollowed`: a probing move, a
/// special interpolation, a code kinpost does not know), a
/// transformation, a value kinpost does not evaluate where an axis goes
/// (`A#1`, `Z=R1`, `A[30]`, `Z 5 0 0`), an axis named by its number
/// (`AX4=30`) or a path word, and a move in a motion mode that goes
/// elsewhere than its words (a canned cycle ends at its clearance level,
/// a tapping or threading move returns, a spline passes its points
/// otherwise). `Some(true)` where the rotaries may have turned too (the
/// next pose must then give its orientation besides X, Y and Z): always
/// but for a cycle or a probing move without a rotary word of `machine`.
pub(super) fn not_followed(line: &Line, meaning: &BlockMeaning, machine: &Machine) -> Option<bool> {
    use crate::program::{opaque, unfollowed};
    let rotary_word = || line.words().any(|w| is_rotary(machine, &w.address));
    let probe = line
        .words()
        .any(|w| w.address == "G" && unfollowed::is_probe((w.value * 10.0).round() as i64));
    if meaning.unfollowed.is_some() || unfollowed::in_line(line, None).is_some() {
        return Some(!probe || rotary_word());
    }
    let axis_word = |a: &str| crate::program::modal::is_axis_address(a);
    if meaning.motion == Motion::Other && line.words().any(|w| axis_word(&w.address)) {
        return Some(rotary_word());
    }
    let unread = line
        .items
        .iter()
        .enumerate()
        .any(|(index, item)| match &item.kind {
            ItemKind::Word(w) => {
                unfollowed::numbered_axis(&w.address)
                    || (unfollowed::PATH_WORDS.contains(&w.address.as_str())
                        && !matches!(w.address.as_str(), "CR" | "AR"))
            }
            ItemKind::Opaque => opaque::unreadable_motion_at(line, index),
            _ => false,
        });
    unread.then_some(true)
}

/// Whether `line` sends the machine somewhere its program coordinates do
/// not say: home (`G28`, `G30`), machine coordinates (`G53`, Sinumerik
/// `G153`, `SUPA`), the offsets reset (`G92.1`–`G92.3`), Fanuc's tool
/// axis direction control (`G53.1`: the rotaries turn), Sinumerik's
/// reference and fixed point approaches (`G74`, `G75` with `X1=`…).
pub(super) fn goes_where_not_known(line: &Line) -> bool {
    let indexed = || {
        line.words()
            .any(|w| crate::program::modal::point_approach_word(&w.address))
    };
    // `G53`, `G153`, `SUPA` apply to their block's axis words: alone
    // (the line an NX post starts each operation with) they move nothing.
    let moves = || {
        line.words()
            .any(|w| crate::program::modal::is_axis_address(&w.address))
    };
    (line.keywords().any(|k| k == "SUPA") && moves())
        || line.words().any(|w| {
            w.address == "G"
                && ([28.0, 30.0, 92.1, 92.2, 92.3, 53.1]
                    .iter()
                    .any(|v| (w.value - v).abs() < 1e-9)
                    || ((w.value == 53.0 || w.value == 153.0) && moves())
                    || ((w.value == 74.0 || w.value == 75.0) && indexed()))
        })
}

/// Whether `line`, a block that [`goes_where_not_known`], may turn the
/// rotaries of `machine` too: it names one (`G28 G91 A0 C0`, `G53 C0`),
/// or it is a move home without axis words (LinuxCNC's `G28` alone sends
/// every axis home). `G28 G91 Z0` leaves the tool's orientation as it was.
pub(super) fn turns_rotaries(line: &Line, machine: &Machine) -> bool {
    if machine
        .axes
        .iter()
        .all(|x| x.kind != crate::machine::JointKind::Revolute)
    {
        return false;
    }
    let axis_words = line
        .words()
        .filter(|w| crate::program::modal::is_axis_address(&w.address))
        .count();
    line.words().any(|w| is_rotary(machine, &w.address))
        || (axis_words == 0
            && line
                .words()
                .any(|w| w.address == "G" && [28.0, 30.0].contains(&w.value)))
}

/// Whether `name` is a rotary axis of `machine`.
fn is_rotary(machine: &Machine, name: &str) -> bool {
    machine
        .axes
        .iter()
        .any(|a| a.kind == crate::machine::JointKind::Revolute && a.name == name)
}

/// The coordinates of the tool tip `tip` (at joint values `q` of `chain`,
/// `machine`'s rotary axes known) that no linear axis outside `known_axes`
/// (bit k: axis k) moves; the others are `None`.
pub(super) fn tip_known(
    machine: &Machine,
    known_axes: u64,
    chain: &crate::machine::chain::Chain,
    q: &[f64],
    tip: Vector3<f64>,
) -> [Option<f64>; 3] {
    let mut out = [Some(tip.x), Some(tip.y), Some(tip.z)];
    for (k, axis) in machine.axes.iter().enumerate() {
        if k < 64 && known_axes & (1 << k) != 0 {
            continue;
        }
        let mut moved = q.to_vec();
        if let Some(v) = moved.get_mut(axis.joint) {
            *v += 1.0;
        }
        let d = chain.pose(&moved, &crate::machine::NoErrors).tip - tip;
        for i in 0..3 {
            if d[i].abs() > 1e-9 {
                out[i] = None;
            }
        }
    }
    out
}
