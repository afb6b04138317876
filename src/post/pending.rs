//! A pose block between reading and writing ([`PendingPose`]), and the
//! joint values it continues from ([`Continuation`]).

use crate::machine::chain::JointValues;
use crate::machine::{Machine, Pose};
use nalgebra::Vector3;

/// A pose block between [`super::BlockReader::begin`] and
/// [`super::BlockWriter::finish`].
#[derive(Debug, Clone)]
pub struct PendingPose {
    /// Lines with words passed through since the pose before, or that pose
    /// was a block-delete one: with `--modal-axes` every axis word is
    /// written (the machine may not stand where kinpost's last words put it).
    pub after_other: bool,
    /// Blocks passed through since the pose before moved the machine (to
    /// `from`): the base of this block's increments (G91).
    pub moved: bool,
    /// The tool pose to solve.
    pub pose: Pose,
    /// For a pose oriented by rotary positions, the joint values to solve
    /// from instead of [`PendingPose::continues`] (the programmed rotary
    /// positions), which the solution must have
    /// ([`PendingPose::solve_from`]).
    pub pinned: Option<JointValues>,
    /// The joint values the block continues from: the pose before's or
    /// the machine position followed since (what a solver continues from).
    pub continues: Continuation,
    /// Where the machine stands before the block is known: not after
    /// `G28`, `G53`, … ([`PendingPose::from`]).
    pub start_known: bool,
    /// The tool tip before the block, mm, when known.
    pub start_tip: Option<Vector3<f64>>,
    /// What the block means.
    pub meaning: crate::program::BlockMeaning,
    /// Which point of a circular move the pose is, if one.
    pub arc: ArcPart,
}

/// Which point of a circular move (`G2`/`G3` in pose mode) a pose is:
/// `post` and `compensate` write an arc as straight moves through its
/// points, the tool axis held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ArcPart {
    /// Not an arc's: the block's own pose.
    #[default]
    None,
    /// The first point after the arc's start: written in the arc's block,
    /// whose `G2`/`G3` becomes `G1` and whose centre or radius words go.
    First,
    /// A later point: a block of its own, `G1` and the axis words.
    Later,
}

impl PendingPose {
    /// The joint values to solve the pose from: `previous` (what the
    /// program continues from), or the programmed rotary positions of a
    /// pose oriented by them.
    pub fn solve_from<'a>(&'a self, previous: Option<&'a [f64]>) -> Option<&'a [f64]> {
        self.pinned.as_deref().or(previous)
    }

    /// `Err` with a message when the theoretical solution `q` lacks the
    /// programmed rotary positions of a pose oriented by them.
    pub fn check_pinned(&self, machine: &Machine, q: &[f64]) -> std::result::Result<(), String> {
        match &self.pinned {
            Some(p) => super::rotary_pose::check_pinned(machine, p, q),
            None => Ok(()),
        }
    }

    /// The joint values the block starts from, where that is known (not
    /// after `G28`, `G53`, …); `last`: the joint values of the pose before
    /// as written, for a pose begun before it was solved.
    pub fn from<'a>(&'a self, last: Option<&'a [f64]>) -> Option<&'a [f64]> {
        if self.start_known {
            self.continues.resolve(last)
        } else {
            None
        }
    }
}

/// The joint values a block continues from.
#[derive(Debug, Clone, PartialEq)]
pub enum Continuation {
    /// None: no pose or machine position came yet.
    Nowhere,
    /// These (chain order, mm / rad).
    At(JointValues),
    /// The last pose's, solved after the block was read
    /// ([`super::BlockReader::deferred`]).
    LastPose,
}

impl Continuation {
    /// The joint values, `last` standing for the last pose's.
    pub fn resolve<'a>(&'a self, last: Option<&'a [f64]>) -> Option<&'a [f64]> {
        match self {
            Continuation::Nowhere => None,
            Continuation::At(q) => Some(q),
            Continuation::LastPose => last,
        }
    }
}
