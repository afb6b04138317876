//! Block delete (`/`) in pose mode: what a block the controller may skip
//! leaves behind for the blocks after it. The modes a `/` block changes
//! and the position a `/` move leaves: `block_delete_switch.rs`.

use nalgebra::Vector3;

/// The tip coordinates (X, Y, Z; `None` until known) and tool vector of the
/// modal state at one moment.
pub type TipAndAxis = ([Option<f64>; 3], Vector3<f64>);

/// Why a block-delete pose block under `G91` is refused.
pub const UNDER_G91: &str = "a block-delete (`/`) pose block under G91 (incremental) is not converted: with the block delete switch on the controller skips it, and the machine-axis increments kinpost writes for the blocks after it (computed from this pose, its rotary axes turned) would no longer add up to the programmed poses; program the poses in G90 (absolute), or without `/`";

/// Why a block-delete pose block that gives a rotary axis position (the
/// orientation under `G43.4`, `G234`, `TRAORI`) is refused.
pub const TURNS_A_ROTARY: &str = "a block-delete (`/`) pose block that turns a rotary axis (A B C under G43.4 / G234 / TRAORI): whether the controller skips it decides the orientation of every pose after it; not converted (give the rotary positions in the blocks after it too, without `/`)";

/// What one pose block gives: each of X, Y, Z, any and all three
/// components of the tool vector.
#[derive(Debug, Clone, Copy)]
pub struct Given {
    /// X, Y, Z given.
    pub tip: [bool; 3],
    /// Some component of the tool vector given.
    pub axis_any: bool,
    /// All three components of the tool vector given.
    pub axis_all: bool,
}

/// The values that block-delete (`/`) pose blocks gave and later blocks
/// would take over.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SkippableCarry {
    /// X, Y, Z and the tool vector were last given by a `/` pose block.
    from_skippable: [bool; 4],
    /// The tip and tool vector before the first `/` pose block whose
    /// values are still carried.
    before: Option<TipAndAxis>,
}

impl SkippableCarry {
    /// Nothing carried (the position is known anew, e.g. from the machine).
    pub fn reset(&mut self) {
        *self = SkippableCarry::default();
    }

    /// A `/` pose block (`skippable`) marks the coordinates and tool vector
    /// it gives (`before`: the modal tip and vector before the block); a
    /// later pose block without `/` that takes one of them over (does not
    /// give it itself; the whole tool vector for the axis) while `now`
    /// differs from its value before the first such block is refused, with
    /// the message: with the block delete switch on the controller skipped
    /// the `/` block and has the earlier value, with it off the `/` block's,
    /// and kinpost cannot write both.
    pub fn check(
        &mut self,
        skippable: bool,
        given: Given,
        before: TipAndAxis,
        now: TipAndAxis,
    ) -> Result<(), String> {
        if skippable {
            if given.tip.iter().any(|t| *t) || given.axis_any {
                self.before.get_or_insert(before);
            }
            for i in 0..3 {
                self.from_skippable[i] |= given.tip[i];
            }
            self.from_skippable[3] |= given.axis_any;
            return Ok(());
        }
        let Some((tip0, axis0)) = self.before else {
            return Ok(());
        };
        let names = ["X", "Y", "Z", "the tool vector (I J K)"];
        for i in 0..4 {
            let (here, same) = if i < 3 {
                (given.tip[i], now.0[i] == tip0[i])
            } else {
                (given.axis_all, now.1 == axis0)
            };
            if here || same {
                self.from_skippable[i] = false;
            } else if self.from_skippable[i] {
                return Err(format!(
                    "{} is taken over from a block-delete (`/`) block: with the block delete switch on the controller skips that block and keeps the earlier value, with it off it takes the skipped block's, and kinpost cannot write both; give {} in this block",
                    names[i], names[i]
                ));
            }
        }
        if self.from_skippable == [false; 4] {
            self.before = None;
        }
        Ok(())
    }
}
