//! The stage of `post` whose solver comes in two parts
//! ([`super::SplitSolver`]: the analytic IK): the first pass only reads the
//! program, the branches of each pose are found in parallel, and the last
//! pass chooses among them in order (branch and turn) and writes the pose.
//! The part that must see the poses in order is then a few comparisons per
//! pose, and the IK's trigonometry and linear solves use every core.
//!
//! A unit that needs what is written before it (a G-code block in machine
//! coordinates, an APT CL arc or hole planned with the solver:
//! [`super::pipeline::Format::needs_committed`]) makes the first pass
//! wait; after a wait the stage solves the next poses whole in the first
//! pass, as [`super::pipeline::Whole`] does, and lends the format its
//! solver to plan with ([`Stage::planner`]).

use super::pipeline::{Stage, Step};
use super::{PoseSolver, SolvedPose, SplitSolver};
use crate::machine::{Pose, PreparedPose};

/// Poses solved whole in the first pass after the first pass had to wait
/// for the last ([`Stage::waited`]): where such units come often, each
/// wait would stall the pipeline; one chunk's worth of poses solved in
/// order costs less than the two rounds of a wait.
pub const IN_ORDER_AFTER_WAIT: usize = super::pipeline::CHUNK_UNITS;

/// A pose between the passes.
pub struct Choice {
    /// The line of the pose (the solver of a job whose tool changes
    /// switches by line).
    line: usize,
    /// Its branches, found between the passes.
    prepared: Option<PreparedPose>,
}

/// A [`SplitSolver`] as a [`PoseSolver`]: both parts at once.
pub struct Joined<'s>(&'s dyn SplitSolver);

impl PoseSolver for Joined<'_> {
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<SolvedPose, String> {
        self.0
            .choose(pose, &self.0.prepare(pose, line), previous, line)
    }
}

/// The first half of the stage.
pub struct Front<'s> {
    solver: Joined<'s>,
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
                solver: Joined(solver),
                in_order: 0,
            },
            solver,
        }
    }

    /// The work between the passes: the branches of the pose.
    pub fn work(solver: &dyn SplitSolver, pose: &Pose, job: &mut Choice) {
        job.prepared = Some(solver.prepare(pose, job.line));
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
        // After a wait everything before is written, and stays so while
        // poses are solved (and written) here.
        if front.in_order > 0 {
            front.in_order -= 1;
            return front.solver.solve(pose, previous, line).map(Step::Done);
        }
        Ok(Step::Later(Choice {
            line,
            prepared: None,
        }))
    }
    fn planner<'f>(front: &'f mut Front<'s>) -> Option<&'f mut dyn PoseSolver> {
        if front.in_order > 0 {
            Some(&mut front.solver)
        } else {
            None
        }
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
