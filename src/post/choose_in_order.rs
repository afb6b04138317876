//! The stage of `post` on G-code whose solver comes in two parts
//! ([`super::SplitSolver`]: the analytic IK): the first pass only reads the
//! program, the branches of each pose are found in parallel, and the last
//! pass chooses among them in order (branch and turn) and writes the pose.
//! The part that must see the poses in order is then a few comparisons per
//! pose, and the IK's trigonometry and linear solves use every core.

use super::pipeline::{Stage, Step};
use super::{SolvedPose, SplitSolver};
use crate::machine::{Pose, PreparedPose};

/// A pose between the passes.
pub struct Choice {
    /// The line of the pose (the solver of a job whose tool changes
    /// switches by line).
    line: usize,
    /// Its branches, found between the passes.
    prepared: Option<PreparedPose>,
}

/// The stage ([`Stage::DEFERS`]).
pub struct ChooseInOrder<'s> {
    /// The first half: nothing (the first pass only reads).
    front: (),
    solver: &'s dyn SplitSolver,
}

impl<'s> ChooseInOrder<'s> {
    /// The stage of `solver`.
    pub fn new(solver: &'s dyn SplitSolver) -> Self {
        ChooseInOrder { front: (), solver }
    }

    /// The work between the passes: the branches of the pose.
    pub fn work(solver: &dyn SplitSolver, pose: &Pose, job: &mut Choice) {
        job.prepared = Some(solver.prepare(pose, job.line));
    }
}

impl<'s> Stage for ChooseInOrder<'s> {
    type Job = Choice;
    type Front = ();
    type Back = &'s dyn SplitSolver;
    const DEFERS: bool = true;
    fn halves(&mut self) -> (&mut (), &mut &'s dyn SplitSolver) {
        (&mut self.front, &mut self.solver)
    }
    fn first(
        _: &mut (),
        _: &Pose,
        _: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<Step<Choice>, String> {
        Ok(Step::Later(Choice {
            line,
            prepared: None,
        }))
    }
    fn commit(
        solver: &mut &'s dyn SplitSolver,
        pose: &Pose,
        job: &Choice,
        line: usize,
        previous: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String> {
        match &job.prepared {
            Some(p) => solver.choose(pose, p, previous, line),
            // (The driver works on every job; this is what it would give.)
            None => solver.choose(pose, &solver.prepare(pose, line), previous, line),
        }
    }
    fn joints(_: &Choice) -> Option<&[f64]> {
        None
    }
}
