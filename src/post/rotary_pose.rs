//! Poses whose tool orientation is given by rotary axis positions: Fanuc
//! `G43.4` (tool centre point control type 1), Haas `G234` and Sinumerik
//! `TRAORI` with `A B C` words. The tool tip is `X Y Z` in the workpiece
//! frame, as with a tool vector; the orientation is where the nominal
//! chain points the tool at those rotary positions (the linear axes turn
//! nothing). The pose is then solved like any other, but with the
//! programmed rotary positions as the reference the solution is chosen
//! nearest to, so that the branch and the turn are the program's; the
//! solution is checked to have them ([`check_pinned`]).

use crate::machine::{JointKind, JointValues, Machine, NoErrors, RotaryMode};
use crate::program::RotaryWords;
use nalgebra::Vector3;

/// Largest difference between a programmed rotary position and the one
/// the theoretical solution has, rad: the solver's rounding near a
/// singular pose stays far below it, another branch or turn far above.
pub const PIN_TOLERANCE_RAD: f64 = 1e-6;

/// The rotary axis positions the poses are oriented by, as far as the
/// program says: per machine axis (output order), degrees as written on
/// the machine, `None` for a linear axis or a position not known.
#[derive(Debug, Clone)]
pub struct RotaryPositions {
    at: Vec<Option<f64>>,
}

/// A rotary-oriented pose made ready to solve.
#[derive(Debug, Clone)]
pub struct PinnedPose {
    /// The tool axis of the nominal chain at the rotary positions.
    pub axis: Vector3<f64>,
    /// The joint values to solve from (chain order, mm / rad): the rotary
    /// joints at the programmed positions, the linear ones at `previous`'s
    /// (or 0).
    pub reference: JointValues,
}

/// A rotary word that cannot orient the pose: its item and why.
pub type Refusal = (Option<usize>, String);

impl RotaryPositions {
    /// No position known, for `machine`.
    pub fn new(machine: &Machine) -> Self {
        RotaryPositions {
            at: vec![None; machine.axes.len()],
        }
    }

    /// The positions are no longer known (a pose oriented by a tool
    /// vector, a tool change, a move home).
    pub fn forget(&mut self) {
        self.at.iter_mut().for_each(|a| *a = None);
    }

    /// A block in machine coordinates left the axes at `ext` (output
    /// order, mm / deg); bit k of `known` says whether axis k's position is
    /// known.
    pub fn followed(&mut self, machine: &Machine, ext: &[f64], known: u64) {
        for (k, axis) in machine.axes.iter().enumerate() {
            let bit = k < 64 && known & (1 << k) != 0;
            self.at[k] = (axis.kind == JointKind::Revolute && bit)
                .then(|| ext.get(k).copied())
                .flatten();
        }
    }

    /// The pose of a block whose rotary words are `words` (`absolute`:
    /// under `G90`): the positions it gives, the others kept. `chain`: the
    /// machine's chain where the block runs; `previous`: the joint values
    /// the program continues from, if known.
    pub fn pose(
        &mut self,
        machine: &Machine,
        chain: &crate::machine::Chain,
        words: &RotaryWords,
        absolute: bool,
        previous: Option<&[f64]>,
    ) -> Result<PinnedPose, Refusal> {
        for w in words {
            let Some(k) = machine
                .axes
                .iter()
                .position(|a| a.name == w.address && a.kind == JointKind::Revolute)
            else {
                let rotaries: Vec<&str> = (machine.axes.iter())
                    .filter(|a| a.kind == JointKind::Revolute)
                    .map(|a| a.name.as_str())
                    .collect();
                return Err((
                    Some(w.item),
                    format!(
                        "`{}{}`: machine {} has no rotary axis {} (its rotary axes: {}); the program is for another machine",
                        w.address,
                        w.value,
                        machine.name,
                        w.address,
                        if rotaries.is_empty() {
                            "none".to_string()
                        } else {
                            rotaries.join(", ")
                        }
                    ),
                ));
            };
            let axis = &machine.axes[k];
            let current = self.at[k];
            if !absolute && current.is_none() {
                return Err((
                    Some(w.item),
                    format!(
                        "incremental {} move (G91) but the position of the {} axis is not known here: give an absolute position first",
                        w.address, w.address
                    ),
                ));
            }
            let at = crate::machine::rotary::follow_word(
                axis,
                w.value,
                1.0,
                absolute,
                current.unwrap_or(w.value),
            )
            .ok_or_else(|| {
                (
                    Some(w.item),
                    crate::machine::wrapped::word_too_large(w.address, w.value),
                )
            })?;
            if !at.is_finite() {
                return Err((
                    Some(w.item),
                    format!(
                        "`{}{}`: the {} axis's position is out of range ({at}°); expected degrees",
                        w.address, w.value, w.address
                    ),
                ));
            }
            if !crate::machine::rotary::within_limits(axis, at.to_radians()) {
                return Err((
                    Some(w.item),
                    format!(
                        "`{}{}` puts the {} axis at {at}°, beyond its travel ({}…{}°)",
                        w.address,
                        w.value,
                        w.address,
                        axis.min.unwrap_or(f64::NEG_INFINITY),
                        axis.max.unwrap_or(f64::INFINITY)
                    ),
                ));
            }
            self.at[k] = Some(at);
        }
        let mut reference: JointValues = match previous {
            Some(q) => q.iter().copied().collect(),
            None => std::iter::repeat_n(0.0, chain.dof()).collect(),
        };
        for (k, axis) in machine.axes.iter().enumerate() {
            if axis.kind != JointKind::Revolute {
                continue;
            }
            let Some(at) = self.at[k] else {
                return Err((
                    words.first().map(|w| w.item),
                    format!(
                        "the position of the {} axis is not known here (never programmed, or lost by a tool change, a move home, a call or a pose given by a tool vector): a pose oriented by rotary axis positions needs them all; give {} in this block",
                        axis.name, axis.name
                    ),
                ));
            };
            if let Some(slot) = reference.get_mut(axis.joint) {
                *slot = at.to_radians();
            }
        }
        let mut at_rotaries = reference.clone();
        for axis in machine
            .axes
            .iter()
            .filter(|a| a.kind == JointKind::Prismatic)
        {
            if let Some(slot) = at_rotaries.get_mut(axis.joint) {
                *slot = 0.0;
            }
        }
        let axis = chain.pose(&at_rotaries, &NoErrors).axis;
        Ok(PinnedPose { axis, reference })
    }
}

/// `Err` with a message when the theoretical joint values `q` (chain
/// order, mm / rad) do not have the rotary positions of `pinned` (as
/// [`PinnedPose::reference`]): the machine reaches the pose only with
/// another branch or turn, the programmed one needing an axis beyond its
/// travel, or the tip does not fit the rotary positions (a four-axis
/// machine whose rotaries the tip decides).
pub fn check_pinned(machine: &Machine, pinned: &[f64], q: &[f64]) -> Result<(), String> {
    let revolute = || {
        machine
            .axes
            .iter()
            .filter(|a| a.kind == JointKind::Revolute)
    };
    let off = revolute().any(|a| {
        let (p, v) = (pinned[a.joint], q[a.joint]);
        let d = match a.rotary {
            RotaryMode::Modulo => crate::machine::rotary::angle_diff(v, p),
            _ => v - p,
        };
        d.is_nan() || d.abs() > PIN_TOLERANCE_RAD
    });
    if !off {
        return Ok(());
    }
    let list = |v: &[f64]| {
        revolute()
            .map(|a| format!("{}{:.4}", a.name, v[a.joint].to_degrees()))
            .collect::<Vec<_>>()
            .join(" ")
    };
    Err(format!(
        "the programmed rotary positions ({}) do not reach this pose on machine {}: within the axes' travel the pose needs {}; with the programmed ones a linear axis would leave its travel, or the tool tip does not fit them (a machine whose rotaries the tip decides); not converted",
        list(pinned),
        machine.name,
        list(q)
    ))
}

/// The tool axis of the pose `meaning` describes at `line` (`axis`: the
/// programmed tool vector, or the one kept) and, for a pose oriented by
/// rotary positions, the joint values to solve it from
/// ([`PinnedPose::reference`]). A block that gives a tool vector makes
/// the rotary positions unknown (the solution decides them).
pub fn orientation(
    rotaries: &mut RotaryPositions,
    machine: &Machine,
    chain: &crate::machine::Chain,
    line: &crate::gcode::Line,
    meaning: &crate::program::BlockMeaning,
    axis: Vector3<f64>,
    previous: Option<&[f64]>,
) -> Result<(Vector3<f64>, Option<JointValues>), Refusal> {
    match &meaning.rotaries {
        Some(words) => {
            let pinned = rotaries.pose(machine, chain, words, meaning.absolute, previous)?;
            Ok((pinned.axis, Some(pinned.reference)))
        }
        None => {
            let known = rotaries.at.iter().any(Option::is_some);
            let gives_vector = known
                && meaning.pose_items.iter().any(|&i| {
                    matches!(&line.items[i].kind, crate::gcode::ItemKind::Word(w)
                    if matches!(w.address.as_str(), "I" | "J" | "K" | "A3" | "B3" | "C3"))
                });
            if gives_vector {
                rotaries.forget();
            }
            Ok((axis, None))
        }
    }
}
