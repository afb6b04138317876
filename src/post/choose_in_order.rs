//! The stage of `post` on G-code whose solver comes in two parts
//! ([`super::SplitSolver`]: the analytic IK): the first pass only reads the
//! program, the branches of each pose are found in parallel, and the last
//! pass chooses among them in order (branch and turn) and writes the pose.
//! The part that must see the poses in order is then a few comparisons per
//! pose, and the IK's trigonometry and linear solves use every core.

use super::pipeline::{Stage, Step};
use super::{SolvedPose, SplitSolver};
use crate::machine::{Pose, PreparedPose};

/// Poses solved whole in the first pass after the first pass had to wait
/// for the last (a block in machine coordinates, [`Stage::waited`]): where
/// such blocks come often, each wait would stall the pipeline; one chunk's
/// worth of poses solved in order costs less than the two rounds of a wait.
pub const IN_ORDER_AFTER_WAIT: usize = super::pipeline::CHUNK_UNITS;

/// A pose between the passes.
pub struct Choice {
    /// The line of the pose (the solver of a job whose tool changes
    /// switches by line).
    line: usize,
    /// Its branches, found between the passes.
    prepared: Option<PreparedPose>,
    /// Solved whole in the first pass (after a wait).
    solved: Option<SolvedPose>,
}

/// The first half of the stage.
pub struct Front<'s> {
    solver: &'s dyn SplitSolver,
    /// Poses still to solve whole in the first pass.
    in_order: usize,
}

/// The stage ([`Stage::DEFERS`]).
pub struct ChooseInOrder<'s> {
    front: Front<'s>,
    solver: &'s dyn SplitSolver,
}

impl<'s> ChooseInOrder<'s> {
    /// The stage of `solver`.
    pub fn new(solver: &'s dyn SplitSolver) -> Self {
        ChooseInOrder {
            front: Front {
                solver,
                in_order: 0,
            },
            solver,
        }
    }

    /// The work between the passes: the branches of the pose (unless it
    /// was solved whole).
    pub fn work(solver: &dyn SplitSolver, pose: &Pose, job: &mut Choice) {
        if job.solved.is_none() {
            job.prepared = Some(solver.prepare(pose, job.line));
        }
    }
}

impl<'s> Stage for ChooseInOrder<'s> {
    type Job = Choice;
    type Front = Front<'s>;
    type Back = &'s dyn SplitSolver;
    const DEFERS: bool = true;
    fn halves(&mut self) -> (&mut Front<'s>, &mut &'s dyn SplitSolver) {
        (&mut self.front, &mut self.solver)
    }
    fn first(
        front: &mut Front<'s>,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<Step<Choice>, String> {
        // After a wait the joint values before are known, and stay known
        // while poses are solved here.
        let solved = if front.in_order > 0 {
            front.in_order -= 1;
            let s = front.solver;
            Some(s.choose(pose, &s.prepare(pose, line), previous, line)?)
        } else {
            None
        };
        Ok(Step::Later(Choice {
            line,
            prepared: None,
            solved,
        }))
    }
    fn waited(front: &mut Front<'s>) {
        front.in_order = IN_ORDER_AFTER_WAIT;
    }
    fn commit(
        solver: &mut &'s dyn SplitSolver,
        pose: &Pose,
        job: &Choice,
        line: usize,
        previous: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String> {
        if let Some(s) = &job.solved {
            return Ok(s.clone());
        }
        match &job.prepared {
            Some(p) => solver.choose(pose, p, previous, line),
            // (The driver works on every job; this is what it would give.)
            None => solver.choose(pose, &solver.prepare(pose, line), previous, line),
        }
    }
    fn joints(job: &Choice) -> Option<&[f64]> {
        job.solved.as_ref().map(|s| s.q.as_slice())
    }
}
