//! `compensate` through the driver of `post` ([`crate::post::pipeline`]):
//! the analytic IK in order, the Newton refinements in parallel, the failure
//! policy, backlash and records in order.

use super::refine::{Refined, refine_near_linearized};
use super::solver::{BlockRecord, CompensatingSolver};
use super::written::{Written, WrittenBounds, written_residual};
use crate::machine::chain::{JointValues, Pose};
use crate::post::pipeline::{Stage, Step};
use crate::post::{PostOptions, PostStats, SolvedPose};
use std::io::{BufRead, Write};

/// A pose's work between the passes: the theoretical joint values and,
/// once refined, the refinement.
struct Job {
    th: JointValues,
    refined: Option<Refined>,
    /// The tool-tip and axis errors as written, when worked out (or bounded)
    /// beside the refinement (no backlash pre-compensation; used where the
    /// failure policy keeps the refined axes).
    written: Option<Written>,
}

/// The first half of [`Compensating`]: the analytic IK, in order.
struct Theoretical<'m> {
    /// The solver's IK (a copy: the solver is the other half).
    ik: crate::machine::IkSolver,
    machine: &'m crate::machine::Machine,
    axis_tolerance_rad: f64,
    /// The theoretical joint values of the previous pose.
    previous_th: Option<JointValues>,
}

/// The stage of `compensate`: [`CompensatingSolver`] split around the
/// refinement; its analytic IK is the first half ([`Theoretical`]), the
/// solver's failure policy, backlash and records the second.
struct Compensating<'s, 'm> {
    front: Theoretical<'m>,
    solver: &'s mut CompensatingSolver<'m>,
}

impl<'s, 'm> Stage for Compensating<'s, 'm> {
    type Job = Job;
    type Front = Theoretical<'m>;
    type Back = &'s mut CompensatingSolver<'m>;
    fn halves(&mut self) -> (&mut Theoretical<'m>, &mut &'s mut CompensatingSolver<'m>) {
        (&mut self.front, &mut self.solver)
    }
    fn first(
        front: &mut Theoretical<'m>,
        pose: &Pose,
        _: Option<&[f64]>,
        _: usize,
    ) -> std::result::Result<Step<Job>, String> {
        let th = super::solver::theoretical(
            &front.ik,
            front.machine,
            front.axis_tolerance_rad,
            pose,
            front.previous_th.as_deref(),
        )?;
        front.previous_th = Some(th.clone());
        Ok(Step::Later(Job {
            th,
            refined: None,
            written: None,
        }))
    }
    fn commit(
        solver: &mut &'s mut CompensatingSolver<'m>,
        pose: &Pose,
        job: &Job,
        line: usize,
        _: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String> {
        let refined = job.refined.as_ref().expect("refined in parallel");
        solver.commit(pose, &job.th, refined, job.written, line)
    }
    fn joints(job: &Job) -> Option<&[f64]> {
        Some(&job.th)
    }
}

/// Which program format [`compensate`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// A G-code pose program.
    Gcode,
    /// APT CL.
    Cl,
}

/// Compensates a G-code pose program, writing the machine program to `out`,
/// on every core: the result is the same for any number of threads. As
/// [`compensate`] with [`Input::Gcode`].
pub fn compensate_gcode<R: BufRead, W: Write + ?Sized>(
    machine: &crate::machine::Machine,
    solver: &mut CompensatingSolver<'_>,
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
    records: impl FnMut(&mut Vec<BlockRecord>) -> crate::error::Result<()>,
) -> crate::error::Result<PostStats> {
    compensate(
        Input::Gcode,
        machine,
        solver,
        input,
        out,
        opts,
        progress,
        records,
    )
}

/// Compensates a pose program (G-code or APT CL), writing the machine
/// program to `out`, on every core: the result is the same for any number
/// of threads.
///
/// Through [`crate::post::pipeline::drive`]: the analytic IK of each pose in
/// order, continuing from the previous pose's theoretical solution (branch
/// choice and rotary unwinding need the order); the Newton refinements,
/// independent per pose, in parallel; the failure policy, backlash
/// pre-compensation and records in order as the poses are written.
/// `records` receives the per-block records after each chunk (memory stays
/// flat).
///
/// Unlike [`crate::post::post_gcode`] / [`crate::post::post_cl`] with the
/// solver's [`crate::post::PoseSolver`] interface, which continue each IK
/// from the previous block's *compensated* axes, the IK continues from the
/// previous *theoretical* solution, on G-code and APT CL alike: the two
/// differ by the compensation (micrometres, microradians), which changes
/// neither the branch nor the turn of a rotary except at an exact tie, and
/// at a singular pose the value a free rotary keeps is the theoretical one
/// (continuing from compensated values there let a free rotary drift by
/// the compensation bound and sent a later pose of a SolidWorks program
/// out of the machine's Y travel, where `post` converts it). Arcs and holes
/// of APT CL are their moves ([`crate::post::convert_cl`]).
#[allow(clippy::too_many_arguments)]
pub fn compensate<R: BufRead, W: Write + ?Sized>(
    kind: Input,
    machine: &crate::machine::Machine,
    solver: &mut CompensatingSolver<'_>,
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
    mut records: impl FnMut(&mut Vec<BlockRecord>) -> crate::error::Result<()>,
) -> crate::error::Result<PostStats> {
    // What the refinements need, apart from the solver's in-order state.
    let chain = solver.actual_chain.clone();
    let errors = solver.errors;
    let options = solver.options;
    // Backlash pre-compensation depends on the order: the written errors
    // are then worked out in order, else here, beside the refinement.
    let decimals = solver.decimals.clone();
    let written_here = solver.backlash.is_empty() && !decimals.is_empty();
    // Without a report only the largest errors as written are wanted: a
    // block's upper bounds, which cost no evaluation of the chain, then
    // stand in where they lie below the largest so far (the in-order
    // commit evaluates the others).
    let bounds = (!solver.written_per_block && written_here)
        .then(|| WrittenBounds::new(machine, &chain, errors, &decimals))
        .flatten();
    let work = |pose: &Pose, job: &mut Job| {
        // The sines and cosines at the theoretical solution serve the
        // refinement and the axes as written, both near it.
        let near = chain.trig_at(&job.th);
        let (r, bound) =
            refine_near_linearized(&chain, errors, pose, &job.th, &options, &near, |lin| {
                bounds.as_ref().and_then(|b| b.bound(pose, &job.th, lin))
            });
        if written_here {
            job.written = Some(match bound.flatten() {
                Some((tip, axis)) => Written::Bound(tip, axis),
                None => {
                    let (tip, axis) = written_residual(
                        machine,
                        &chain,
                        errors,
                        &decimals,
                        pose,
                        &r.q,
                        &[],
                        Some(&near),
                    );
                    Written::Exact(tip, axis)
                }
            });
        }
        job.refined = Some(r);
    };
    let mut stage = Compensating {
        front: Theoretical {
            ik: solver.ik.clone(),
            machine: solver.machine,
            axis_tolerance_rad: solver.axis_tolerance_rad,
            previous_th: None,
        },
        solver,
    };
    // The records go on after each chunk, on this thread.
    let after = |s: &mut Compensating<'_, '_>| records(&mut s.solver.records);
    match kind {
        Input::Gcode => crate::post::convert_gcode(
            machine, &mut stage, &work, after, input, out, opts, progress,
        ),
        Input::Cl => crate::post::convert_cl(
            machine, &mut stage, &work, after, input, out, opts, progress,
        ),
    }
}
