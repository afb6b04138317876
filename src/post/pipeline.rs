//! The one driver of `post` and `compensate`: a program goes through in
//! chunks, its units (G-code lines, APT CL statements) prepared on the pool,
//! converted in order, the per-pose work that needs no order done in
//! parallel, and the result written in order, so memory stays flat and
//! every core works.
//!
//! What is converted is a [`Format`] (G-code: [`super::GcodeConverter`];
//! APT CL: the CL format of `post/cl.rs`, its statements read and lowered
//! on the calling thread); what is done with each pose is a [`Stage`]
//! (`post`: the IK's branches found in parallel and chosen among in order,
//! [`super::choose_in_order`]; or, for other solvers, the whole solve in
//! order, [`Whole`], whose solver the format may plan with,
//! [`Stage::planner`], or on G-code [`SolveFirst`], which leaves the
//! writing to the last pass; `compensate`: the analytic IK in order, the
//! Newton refinement in parallel, the failure policy and records in
//! order).

use super::{PoseSolver, PostStats, SolvedPose};
use crate::error::{Error, Result};
use crate::machine::Pose;
use std::io::Write;

/// Units per chunk.
pub const CHUNK_UNITS: usize = 512;

/// How many units ahead the in-order passes ask for a unit's memory.
const PREFETCH_AHEAD: usize = 4;

/// Largest number of a chunk's stage jobs (`compensate`: refinements) one
/// task of the pool runs. A round ends when its last task does: with the
/// pool's own split (four tasks of 128 for two threads) a thread that ran
/// out of work waited for the other's last 128 refinements; in tasks of
/// 32 the wait is short (spiral, 200,000 poses: 0.159 → 0.153 s, best of
/// 25; 8 to 64 are equal within the noise).
const JOBS_PER_TASK: usize = 32;

/// Largest number of a chunk's units one task of the pool prepares
/// ([`Format::prepare`]: G-code lines parsed), so that both threads can
/// share the parse at the end of a round (against one task for the whole
/// chunk: outputs identical, times equal within the noise of the hosts
/// measured, `docs/performance.md`).
const UNITS_PER_TASK: usize = 64;

/// Asks the processor to bring the memory of `x` (a value or a slice)
/// into the cache, one 64-byte line at a time.
#[inline]
pub fn prefetch_bytes<T: ?Sized>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (x as *const T).cast::<i8>();
        for off in (0..std::mem::size_of_val(x)).step_by(64) {
            // SAFETY: a prefetch is a hint that never faults, whatever the
            // address; SSE is part of x86_64.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// A program format the driver converts: prepared on any thread,
/// converted in order in two halves around the solve. (Its units are read
/// by the driver's caller, on the driver's thread: the input need not be
/// [`Send`]; the conversion runs on pool threads.)
///
/// Its state is in two halves: the [`Format::Front`] that
/// [`Format::begin`] reads and sets (the program's modal state), and the
/// [`Format::Back`] that [`Format::finish`] writes (the joint values and
/// words written). Where `begin` needs no back ([`Format::splits`]) and
/// the stage solves nothing in the first pass, the first pass of a chunk
/// runs beside the last pass of the chunk two before it.
pub trait Format: Send {
    /// One unit of the program (a line, a statement), reused from chunk to
    /// chunk.
    type Unit: Send + Default;
    /// A pose between [`Format::begin`] and [`Format::finish`].
    type Pending: Send;
    /// What [`Format::begin`] reads and sets.
    type Front: Send;
    /// What [`Format::finish`] reads and sets.
    type Back: Send;
    /// The two halves.
    fn halves(&mut self) -> (&mut Self::Front, &mut Self::Back);
    /// Whether [`Format::begin`] needs no back when it has no planner (it
    /// is then given none).
    fn splits(&self) -> bool;
    /// Prepares a read unit (any thread; G-code: parsing).
    fn prepare(unit: &mut Self::Unit);
    /// Asks the processor for the memory of a prepared unit (the pool
    /// prepared it, so it sits in another core's cache).
    fn prefetch(unit: &Self::Unit) {
        prefetch_bytes(unit);
    }
    /// The 1-based line of the unit.
    fn line(unit: &Self::Unit) -> usize;
    /// In order: the modal state of the unit. A unit that is not a pose
    /// appends its output to `out` and gives `None`; a pose is returned to
    /// be solved. `planner`: the stage's solver while it solves the poses
    /// in this pass ([`Stage::planner`]), so that everything before the
    /// unit is written already (a format may plan with it: APT CL arcs and
    /// holes). `back`: the back half, unless the format [`Format::splits`]
    /// and the stage had no planner when the pass began.
    fn begin(
        front: &mut Self::Front,
        back: Option<&mut Self::Back>,
        unit: &mut Self::Unit,
        out: &mut Vec<u8>,
        planner: Option<&mut dyn PoseSolver>,
    ) -> Result<Option<Self::Pending>>;
    /// Whether the unit last begun is done; else [`Format::begin`] is
    /// called again for it (a unit that gives several poses: an APT CL arc
    /// or hole as its moves).
    fn unit_done(front: &Self::Front) -> bool {
        let _ = front;
        true
    }
    /// The pose to solve.
    fn pose(pending: &Self::Pending) -> &Pose;
    /// The joint values to solve the pose from instead of what the program
    /// continues from ([`Format::previous`], [`Format::continues_from`]):
    /// a G-code pose oriented by rotary positions is solved from them.
    fn solve_from(pending: &Self::Pending) -> Option<&[f64]> {
        let _ = pending;
        None
    }
    /// The joint values the program continues from: the last pose's as
    /// [`Format::begun`] gave them, or the machine position followed since
    /// (what a solver continues from).
    fn previous(front: &Self::Front) -> Option<&[f64]>;
    /// In order, in the first pass: the pose last begun was solved to `q`
    /// there (`post`: its solution; `compensate`: its theoretical one, to
    /// which the refinement adds micrometres). What is begun after it
    /// continues from there, whether or not the pose is written yet (a
    /// block in machine coordinates moves on from the machine's position).
    fn begun(front: &mut Self::Front, q: &[f64]);
    /// Whether the format follows a stage that solves its poses in the
    /// last pass ([`Stage::DEFERS`]): [`Format::deferred`],
    /// [`Format::needs_committed`], [`Format::continues_from`] and
    /// [`Format::sync`] are its.
    const DEFERRABLE: bool = false;
    /// In order, in the first pass: the pose last begun is solved in the
    /// last pass; what is begun after it continues from joint values not
    /// known yet.
    fn deferred(front: &mut Self::Front) {
        let _ = front;
    }
    /// Whether `unit` needs what is written before it: the joint values of
    /// a pose not solved yet (a G-code block in machine coordinates after a
    /// deferred pose), or the stage's planner and the back (an APT CL arc
    /// or hole). Unless the stage has a planner already, the driver then
    /// writes everything before the unit, [`Format::sync`]s and begins the
    /// unit after [`Stage::waited`].
    fn needs_committed(front: &Self::Front, unit: &Self::Unit) -> bool {
        let _ = (front, unit);
        false
    }
    /// In the last pass: the joint values `pending` continues from (the
    /// pose before's, as written, or the machine position followed since).
    fn continues_from<'r>(back: &'r Self::Back, pending: &'r Self::Pending) -> Option<&'r [f64]> {
        let _ = (back, pending);
        None
    }
    /// Between the passes, everything begun being written: the front
    /// continues from the joint values the back wrote last.
    fn sync(front: &mut Self::Front, back: &Self::Back) {
        let _ = (front, back);
    }
    /// The error of a failed solve of `pending` in the first pass.
    fn front_error(
        front: &Self::Front,
        unit: &Self::Unit,
        pending: &Self::Pending,
        message: String,
    ) -> Error;
    /// The error of a failed commit of `pending` in the last pass.
    fn back_error(
        back: &Self::Back,
        unit: &Self::Unit,
        pending: &Self::Pending,
        message: String,
    ) -> Error;
    /// In order: appends the pose's output with the joint values `solved`.
    fn finish(
        back: &mut Self::Back,
        unit: &Self::Unit,
        pending: &Self::Pending,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()>;
    /// Appends what ends the program (after the last unit).
    fn end(&mut self, out: &mut Vec<u8>);
    /// What was done.
    fn stats(self) -> PostStats;
}

/// What the in-order pass made of a pose.
pub enum Step<J> {
    /// Solved: written at once.
    Done(SolvedPose),
    /// To be worked on in parallel (the driver's `work`, [`drive`]) and committed in the
    /// writing pass ([`Stage::commit`]).
    Later(J),
}

/// What the driver does with each pose (in order on pool threads, so
/// [`Send`]), in two halves like a [`Format`]'s: the [`Stage::Front`] of
/// the first pass and the [`Stage::Back`] of the last.
pub trait Stage: Send {
    /// A pose's work between the passes.
    type Job: Send;
    /// What [`Stage::first`] reads and sets.
    type Front: Send;
    /// What [`Stage::commit`] reads and sets.
    type Back: Send;
    /// The two halves.
    fn halves(&mut self) -> (&mut Self::Front, &mut Self::Back);
    /// In order: solves `pose` (line `line`), continuing from `previous`
    /// (the converter's last joint values), or starts its job. A stage
    /// without a planner ([`Stage::planner`]) gives only [`Step::Later`].
    fn first(
        front: &mut Self::Front,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<Step<Self::Job>, String>;
    /// In order, in the writing pass: the joint values of a job that was
    /// worked on; `previous`: the joint values the pose continues from
    /// ([`Format::continues_from`], for a stage that [`Stage::DEFERS`]).
    fn commit(
        back: &mut Self::Back,
        pose: &Pose,
        job: &Self::Job,
        line: usize,
        previous: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String>;
    /// The joint values the first pass gave a job's pose
    /// ([`Format::begun`]); `None` for a stage that [`Stage::DEFERS`].
    fn joints(job: &Self::Job) -> Option<&[f64]>;
    /// The solver, while the stage solves the poses in the first pass
    /// ([`Step::Done`]): the format may plan with it in
    /// [`Format::begin`], where everything before is written. While the
    /// stage has one, the driver runs each first pass after the last pass
    /// before it, in one task, and gives it the format's back. (A stage
    /// that [`Stage::DEFERS`] has one only after [`Stage::waited`], when
    /// nothing begun is left unwritten.)
    fn planner(front: &mut Self::Front) -> Option<&mut dyn PoseSolver> {
        let _ = front;
        None
    }
    /// Whether the stage's jobs have work between the passes (the
    /// driver's `work`); without, no task is started for it.
    const WORKS: bool = true;
    /// The first pass had to wait before a unit ([`Format::needs_committed`]),
    /// or met one while the stage had a planner: a stage that
    /// [`Stage::DEFERS`] may solve the poses after it in the first pass
    /// for a while (and lend its [`Stage::planner`]), where such units come
    /// often.
    fn waited(front: &mut Self::Front) {
        let _ = front;
    }
    /// Whether the stage solves its poses in the last pass, in order
    /// ([`Stage::commit`]), its first pass giving no joint values: the
    /// format must be [`Format::DEFERRABLE`]. A commit that fails then
    /// leaves the text before the pose written, as a first pass's error
    /// does.
    const DEFERS: bool = false;
}

/// The stage of `post`: a [`PoseSolver`] solves each pose in order, so
/// branch choice and rotary unwinding see the poses in order, and every
/// solver works (a compensating solver block by block, one IK per tool).
pub struct Whole<'s> {
    solver: &'s mut (dyn PoseSolver + Send),
    /// The back half: nothing (every pose is written in the first pass).
    back: (),
}

impl<'s> Whole<'s> {
    /// The stage of `solver`.
    pub fn new(solver: &'s mut (dyn PoseSolver + Send)) -> Self {
        Whole { solver, back: () }
    }
}

impl<'s> Stage for Whole<'s> {
    type Job = std::convert::Infallible;
    type Front = &'s mut (dyn PoseSolver + Send);
    type Back = ();
    fn halves(&mut self) -> (&mut Self::Front, &mut ()) {
        (&mut self.solver, &mut self.back)
    }
    fn first(
        solver: &mut Self::Front,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<Step<Self::Job>, String> {
        solver.solve(pose, previous, line).map(Step::Done)
    }
    fn commit(
        _: &mut (),
        _: &Pose,
        job: &Self::Job,
        _: usize,
        _: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String> {
        match *job {}
    }
    fn joints(job: &Self::Job) -> Option<&[f64]> {
        match *job {}
    }
    fn planner(solver: &mut Self::Front) -> Option<&mut dyn PoseSolver> {
        Some(&mut **solver)
    }
}

/// The stage of `post` on G-code: a [`PoseSolver`] solves each pose in
/// order in the first pass, as [`Whole`] does, and the pose is written in
/// the last pass, so the writing of one chunk and the solving of the next
/// run at the same time. No format planning (`Whole` is for APT CL, whose
/// arcs are planned with the solver).
pub struct SolveFirst<'s> {
    solver: &'s mut (dyn PoseSolver + Send),
    /// The back half: nothing (the solved pose travels as the job).
    back: (),
}

impl<'s> SolveFirst<'s> {
    /// The stage of `solver`.
    pub fn new(solver: &'s mut (dyn PoseSolver + Send)) -> Self {
        SolveFirst { solver, back: () }
    }
}

impl<'s> Stage for SolveFirst<'s> {
    type Job = SolvedPose;
    type Front = &'s mut (dyn PoseSolver + Send);
    type Back = ();
    const WORKS: bool = false;
    fn halves(&mut self) -> (&mut Self::Front, &mut ()) {
        (&mut self.solver, &mut self.back)
    }
    fn first(
        solver: &mut Self::Front,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<Step<Self::Job>, String> {
        solver.solve(pose, previous, line).map(Step::Later)
    }
    fn commit(
        _: &mut (),
        _: &Pose,
        job: &Self::Job,
        _: usize,
        _: Option<&[f64]>,
    ) -> std::result::Result<SolvedPose, String> {
        Ok(job.clone())
    }
    fn joints(job: &Self::Job) -> Option<&[f64]> {
        Some(&job.q)
    }
}

/// One unit of a chunk after the first pass.
enum Entry {
    /// Bytes written (a range of the chunk's text buffer).
    Text(usize, usize),
    /// A pose to commit (the chunk's jobs are in the same order).
    Pose,
}

/// A pose of a chunk between the passes.
pub struct Job<P, J> {
    /// Index of its unit in the chunk.
    unit: usize,
    /// The converter's half-done pose.
    pub pending: P,
    /// The stage's work.
    pub job: J,
}

/// A chunk between the stages.
struct Chunk<F: Format, J> {
    units: Vec<F::Unit>,
    /// How many of `units` are the chunk's (the rest are kept buffers).
    count: usize,
    text: Vec<u8>,
    entries: Vec<Entry>,
    jobs: Vec<Job<F::Pending, J>>,
    /// The first pass stopped at an error (raised once the units before it
    /// are written).
    stop: Option<Error>,
    /// The first pass stopped before this unit, which needs the joint
    /// values of poses solved in the last pass ([`Format::needs_committed`]).
    suspended: Option<usize>,
    /// The chunk is the rest of a suspended one: its first unit is not
    /// suspended again.
    resumed: bool,
}

impl<F: Format, J> Default for Chunk<F, J> {
    fn default() -> Self {
        Chunk {
            units: Vec::new(),
            count: 0,
            text: Vec::new(),
            entries: Vec::new(),
            jobs: Vec::new(),
            stop: None,
            suspended: None,
            resumed: false,
        }
    }
}

/// Converts a program with `format`, its units read by `read` (in order,
/// on this thread; the unit's size in bytes, `None` at the end), doing
/// `stage` for each pose and `work` on each of the stage's jobs in
/// parallel, writing to `out`; the result is the same for any number of
/// threads. `after_chunk` runs on this thread after each chunk is written
/// (`compensate` hands its records on there); `progress` gets the bytes read.
///
/// The program goes through in chunks of [`CHUNK_UNITS`] units, each in
/// four stages:
///
/// 1. its units are read (this thread: the input and, for APT CL, the
///    reader and lowering keep state from unit to unit) and prepared (a pool
///    task; G-code lines are parsed);
/// 2. one pass in order (a pool task) applies the modal state and runs
///    [`Stage::first`] on each pose (branch choice and rotary unwinding
///    need the order); a pose solved there is converted at once;
/// 3. `work` runs on the stage's jobs, independent per pose, in parallel;
/// 4. a last pass in order commits the jobs ([`Stage::commit`]) and
///    converts them; this thread writes the chunk's text in the next round.
///
/// The stages are pipelined: while the pool works on chunk *k* (stage 3)
/// and prepares chunk *k + 2* (stage 1), the pool converts chunk *k − 1*
/// (stage 4) and runs the first pass of chunk *k + 1* (stage 2), and this
/// thread writes the text of chunk *k − 2* and reads chunk *k + 3*, then
/// joins the pool (so the output's system calls overlap the conversion);
/// at most five chunks are alive. Stages 2 and 4 touch different halves of
/// the format and the stage ([`Format::Front`], [`Format::Back`]), and run
/// as two tasks at the same time, unless the stage solves in the first
/// pass (it has a [`Stage::planner`]: [`Whole`], or a stage that defers
/// after a wait) or the format's first pass needs its back
/// ([`Format::splits`]); then they run as one task, stage 4 first.
///
/// A unit that [`Format::needs_committed`] stops the first pass of a
/// stage that [`Stage::DEFERS`] (unless the stage has a planner): the
/// chunk's units before it go on through stages 3 and 4, the first pass
/// waits until they are written, [`Format::sync`]s, and goes on from the
/// unit after [`Stage::waited`].
#[allow(clippy::too_many_arguments)]
pub fn drive<F: Format, S: Stage, W: Write + ?Sized>(
    mut format: F,
    mut read: impl FnMut(&mut F::Unit) -> Result<Option<usize>>,
    stage: &mut S,
    work: &(dyn Fn(&Pose, &mut S::Job) + Sync),
    mut after_chunk: impl FnMut(&mut S) -> Result<()>,
    out: &mut W,
    mut progress: impl FnMut(u64),
) -> Result<PostStats> {
    use rayon::prelude::*;
    let mut bytes_read = 0u64;
    // The text of the chunk being converted, and that of the chunk before,
    // which this thread writes out while the pool converts the next.
    let mut buf = Vec::new();
    let mut ready: Vec<u8> = Vec::new();
    let mut eof = false;
    // Reads the next chunk's units into `c` (this thread).
    let mut read_chunk = |c: &mut Chunk<F, S::Job>| -> Result<()> {
        c.count = 0;
        c.resumed = false;
        while c.count < CHUNK_UNITS && !eof {
            if c.units.len() == c.count {
                c.units.push(Default::default());
            }
            match read(&mut c.units[c.count])? {
                Some(n) => {
                    c.count += 1;
                    bytes_read += n as u64;
                }
                None => eof = true,
            }
        }
        progress(bytes_read);
        Ok(())
    };

    let mut spare: Vec<Chunk<F, S::Job>> = Vec::new();
    let mut reading: Chunk<F, S::Job> = Chunk::default();
    read_chunk(&mut reading)?;
    let mut prepared: Option<Chunk<F, S::Job>> = (reading.count > 0).then(|| {
        reading.units[..reading.count]
            .iter_mut()
            .for_each(F::prepare);
        std::mem::take(&mut reading)
    });
    read_chunk(&mut reading)?;
    let mut current: Option<Chunk<F, S::Job>> = None;
    let mut previous: Option<Chunk<F, S::Job>> = None;
    let mut stopped = false;
    if S::DEFERS && !F::DEFERRABLE {
        return Err(Error::Usage(
            "internal error: a stage that solves in the last pass with a format that cannot wait for it; please report it".into(),
        ));
    }
    // The rest of a chunk whose first pass was suspended
    // ([`Format::needs_committed`]), first in line for the next first pass;
    // `waiting`: its first part is not written yet, so the next first pass
    // waits (and reading and preparing with it).
    let mut held: Option<Chunk<F, S::Job>> = None;
    let mut waiting = false;
    while prepared.is_some() || held.is_some() || current.is_some() || previous.is_some() {
        // Whether this round's first pass takes the prepared chunk (so
        // that another is read and prepared behind it).
        let advance = !waiting && held.is_none();
        // A stage that solves in the first pass (now) lends the format its
        // planner there, and the format its back: the last pass then runs
        // first, in the same task.
        let split = format.splits() && S::planner(stage.halves().0).is_none();
        let mut to_prepare =
            (advance && reading.count > 0 && !stopped).then(|| std::mem::take(&mut reading));
        let reads = to_prepare.is_some();
        let mut next_reading = if reads {
            spare.pop().unwrap_or_default()
        } else {
            Chunk::default()
        };
        let mut written: Result<()> = Ok(());
        let mut next: Option<Chunk<F, S::Job>> = None;
        let mut read_result: Result<()> = Ok(());
        let mut out_result: Result<()> = Ok(());
        buf.clear();
        rayon::in_place_scope(|scope| {
            // The in-order tasks first: they cannot be divided, and the
            // pool's other threads take the oldest task first.
            let (front, back) = format.halves();
            let (stage_front, stage_back) = stage.halves();
            let prepared = match (waiting, held.is_some()) {
                (true, _) => None,
                (false, true) => Some(&mut held),
                (false, false) => Some(&mut prepared),
            };
            let previous = &mut previous;
            let (written, next, buf) = (&mut written, &mut next, &mut buf);
            let stopped = stopped;
            if split {
                scope.spawn(move |_| {
                    if !stopped && let Some(mut c) = prepared.and_then(Option::take) {
                        first_pass::<F, S>(front, None, stage_front, &mut c);
                        *next = Some(c);
                    }
                });
                scope.spawn(move |_| {
                    if let Some(p) = previous.as_mut() {
                        *written = write::<F, S>(back, stage_back, p, buf);
                    }
                });
            } else {
                scope.spawn(move |_| {
                    if let Some(p) = previous.as_mut() {
                        *written = write::<F, S>(back, stage_back, p, buf);
                    }
                    if written.is_ok()
                        && !stopped
                        && let Some(mut c) = prepared.and_then(Option::take)
                    {
                        first_pass::<F, S>(front, Some(back), stage_front, &mut c);
                        *next = Some(c);
                    }
                });
            }
            if let Some(c) = current.as_mut()
                && S::WORKS
                && !c.jobs.is_empty()
            {
                let jobs = &mut c.jobs;
                scope.spawn(move |_| {
                    jobs.par_iter_mut()
                        .with_max_len(JOBS_PER_TASK)
                        .for_each(|j| work(F::pose(&j.pending), &mut j.job))
                });
            }
            if let Some(c) = to_prepare.as_mut() {
                let units = &mut c.units[..c.count];
                scope.spawn(move |_| {
                    units
                        .par_iter_mut()
                        .with_max_len(UNITS_PER_TASK)
                        .for_each(F::prepare)
                });
            }
            // Write the chunk before and read the chunk after while the
            // pool works.
            out_result = write_out(out, &ready);
            if !stopped && reads {
                read_result = read_chunk(&mut next_reading);
            }
        });
        out_result?;
        ready.clear();
        if let Some(mut p) = previous.take() {
            if p.suspended.take().is_some() {
                // The poses before the unit that waits are written: it
                // continues from the joint values written last.
                let (front, back) = format.halves();
                F::sync(front, back);
                waiting = false;
            }
            spare.push(p);
            // Written out in the next round (or after the last).
            std::mem::swap(&mut buf, &mut ready);
            after_chunk(stage)?;
            if written.is_err() {
                write_out(out, &ready)?;
                written?;
            }
        }
        // No chunk after one whose first pass stopped.
        stopped |= next.as_ref().is_some_and(|c| c.stop.is_some());
        if !stopped {
            read_result?;
        }
        if let Some(c) = next.as_mut()
            && let Some(at) = c.suspended
        {
            held = Some(rest_of(c, at, spare.pop().unwrap_or_default()));
            waiting = true;
            S::waited(stage.halves().0);
        }
        previous = current.take();
        current = next;
        if stopped {
            prepared = None;
            held = None;
        } else if advance {
            prepared = to_prepare;
            reading = next_reading;
        }
    }
    write_out(out, &ready)?;
    buf.clear();
    format.end(&mut buf);
    write_out(out, &buf)?;
    Ok(format.stats())
}

/// The units of `c` from `at` on, moved into `rest` (a spare chunk), for a
/// first pass of their own; `c` keeps those before.
fn rest_of<F: Format, J>(c: &mut Chunk<F, J>, at: usize, mut rest: Chunk<F, J>) -> Chunk<F, J> {
    rest.count = c.count - at;
    rest.resumed = true;
    for (i, unit) in c.units[at..c.count].iter_mut().enumerate() {
        if rest.units.len() == i {
            rest.units.push(Default::default());
        }
        std::mem::swap(&mut rest.units[i], unit);
    }
    c.count = at;
    rest
}

/// Writes converted text to the driver's output.
fn write_out<W: Write + ?Sized>(out: &mut W, text: &[u8]) -> Result<()> {
    out.write_all(text).map_err(|e| Error::io("<output>", e))
}

/// Stage 2 of a prepared chunk: the modal state and [`Stage::first`] of
/// each unit, in order; a pose solved there converted at once (`back`:
/// the format's back half, when the first pass may use it).
fn first_pass<F: Format, S: Stage>(
    front: &mut F::Front,
    mut back: Option<&mut F::Back>,
    stage: &mut S::Front,
    c: &mut Chunk<F, S::Job>,
) {
    for i in 0..c.count {
        if let Some(ahead) = c.units[..c.count].get(i + PREFETCH_AHEAD) {
            F::prefetch(ahead);
        }
        if S::DEFERS && !(c.resumed && i == 0) && F::needs_committed(front, &c.units[i]) {
            if S::planner(stage).is_none() {
                c.suspended = Some(i);
                return;
            }
            // Everything before is written: solving in order goes on.
            S::waited(stage);
        }
        loop {
            if let Err(e) = first_of::<F, S>(front, back.as_deref_mut(), stage, c, i) {
                c.stop = Some(e);
                return;
            }
            if F::unit_done(front) {
                break;
            }
        }
    }
}

/// One [`Format::begin`] of unit `i` of `c` and, for a pose,
/// [`Stage::first`] (and [`Format::finish`] when solved there).
fn first_of<F: Format, S: Stage>(
    front: &mut F::Front,
    mut back: Option<&mut F::Back>,
    stage: &mut S::Front,
    c: &mut Chunk<F, S::Job>,
    i: usize,
) -> Result<()> {
    let start = c.text.len();
    let begun = F::begin(
        front,
        back.as_deref_mut(),
        &mut c.units[i],
        &mut c.text,
        S::planner(stage),
    )?;
    let Some(pending) = begun else {
        c.entries.push(Entry::Text(start, c.text.len()));
        return Ok(());
    };
    let unit = &c.units[i];
    let from = F::solve_from(&pending).or(F::previous(front));
    match S::first(stage, F::pose(&pending), from, F::line(unit)) {
        Err(m) => Err(F::front_error(front, unit, &pending, m)),
        Ok(Step::Done(solved)) => {
            F::begun(front, &solved.q);
            // A stage that solves here has a planner, and the driver then
            // gives the back ([`drive`]).
            let Some(back) = back else {
                let m = "internal error: a pose solved in the first pass without the format's back half; please report it".to_string();
                return Err(F::front_error(front, unit, &pending, m));
            };
            F::finish(back, unit, &pending, &solved, &mut c.text)?;
            c.entries.push(Entry::Text(start, c.text.len()));
            Ok(())
        }
        Ok(Step::Later(job)) => {
            match S::joints(&job) {
                Some(q) => F::begun(front, q),
                None => F::deferred(front),
            }
            c.entries.push(Entry::Pose);
            c.jobs.push(Job {
                unit: i,
                pending,
                job,
            });
            Ok(())
        }
    }
}

/// Stage 4 of a worked chunk, into `buf`: the text of its units, the jobs
/// committed and converted in order; its first-pass error, if any, after
/// its units are converted. The chunk's buffers are kept for the next.
fn write<F: Format, S: Stage>(
    back: &mut F::Back,
    stage: &mut S::Back,
    c: &mut Chunk<F, S::Job>,
    buf: &mut Vec<u8>,
) -> Result<()> {
    let mut jobs = c.jobs.iter().enumerate();
    for entry in &c.entries {
        match *entry {
            Entry::Text(a, b) => buf.extend_from_slice(&c.text[a..b]),
            Entry::Pose => {
                let (j, job) = jobs.next().expect("one job per pose entry");
                // The work was done on other cores.
                if let Some(ahead) = c.jobs.get(j + PREFETCH_AHEAD) {
                    prefetch_bytes(ahead);
                }
                let unit = &c.units[job.unit];
                let before = buf.len();
                let previous =
                    F::solve_from(&job.pending).or(F::continues_from(back, &job.pending));
                let converted = S::commit(
                    stage,
                    F::pose(&job.pending),
                    &job.job,
                    F::line(unit),
                    previous,
                )
                .map_err(|m| F::back_error(back, unit, &job.pending, m))
                .and_then(|solved| F::finish(back, unit, &job.pending, &solved, buf));
                if let Err(e) = converted {
                    // A stage that solves here writes the text before the
                    // pose, as a first pass's error does; otherwise
                    // nothing of a chunk that fails here is written.
                    buf.truncate(if S::DEFERS { before } else { 0 });
                    return Err(e);
                }
            }
        }
    }
    c.text.clear();
    c.entries.clear();
    c.jobs.clear();
    match c.stop.take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}
