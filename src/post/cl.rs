//! APT CL in, G-code for the machine out: the statements read and lowered
//! in order ([`crate::cl::lower`]) on the driver's thread, converted
//! through the driver ([`super::pipeline::drive`]) like G-code.

use super::choose_in_order::ChooseInOrder;
use super::cl_motion::{self, CutcomOn};
use super::pipeline::{Format, Stage, Whole};
use super::{AxisWriter, PoseSolver, PostOptions, PostStats, SolvedPose, unreachable_axis};
use crate::cl::{ClReader, ClRecord, ClStatement, FeedUnit, SpindleDir};
use crate::error::{Error, Location, Result};
use crate::machine::chain::JointValues;
use crate::machine::{Machine, Pose};
use crate::program::Units;
use nalgebra::Vector3;
use std::collections::VecDeque;
use std::io::{BufRead, Write};

mod plan;

/// Converts APT CL data to a G-code program for `machine`, with `solver`
/// solving each pose in order. A solver in two parts
/// ([`PoseSolver::split`]) finds the branches of the poses on every core
/// and chooses among them in order ([`super::choose_in_order`]), as on
/// G-code; an arc or a hole then waits for the poses before it to be
/// written, and is planned with the solver.
///
/// Statements are translated: `GOTO` → `G0`/`G1` with the machine's axes,
/// `FEDRAT` → `F`, `RAPID` → `G0` for the next `GOTO`, `LOADTL` → `T.. M6`,
/// `SPINDL` → `S.. M3/M4/M5`, `COOLNT` → `M7/M8/M9`, `FINI` → `M30`,
/// `END` → `M2`, `$$` and `PARTNO` → comments. `CIRCLE`, `CYCLE`, `CSYS`,
/// `CUTCOM`, `LOAD/TOOL` and the other forms CAM systems write are lowered
/// first ([`crate::cl::lower`]); a statement that moves the tool and is not
/// converted is an error, any other statement is kept as a comment. An arc
/// is a `G2`/`G3` and a hole a canned cycle where the machine's kinematics
/// allow (`post/cl_motion.rs`, docs/programs.md), else their moves.
pub fn post_cl<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    solver: &mut (dyn PoseSolver + Send),
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    // Under inverse time a statement that is not a pose may go back to
    // G94, which depends on what is written before it.
    match solver.split() {
        Some(split) if !opts.inverse_time => convert_cl(
            machine,
            &mut ChooseInOrder::new(split),
            &|pose, job| ChooseInOrder::work(split, pose, job),
            |_| Ok(()),
            input,
            out,
            opts,
            progress,
        ),
        _ => convert_cl(
            machine,
            &mut Whole::new(solver),
            &|_, j| match *j {},
            |_| Ok(()),
            input,
            out,
            opts,
            progress,
        ),
    }
}

/// Converts APT CL data as [`post_cl`] does, with `stage` doing each pose,
/// `work` on the stage's jobs in parallel and `after_chunk` after each
/// chunk is written ([`super::pipeline::drive`]). The statements are read
/// and lowered on this thread, converted on the pool. Arcs and holes are
/// planned (`G2`/`G3`, canned cycles) only where the stage lends its
/// solver ([`Stage::planner`]: `post`'s stages, the one that defers after
/// a wait before each arc or hole); under `compensate` they are their
/// moves.
#[allow(clippy::too_many_arguments)]
pub fn convert_cl<S: Stage, R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    stage: &mut S,
    work: &(dyn Fn(&Pose, &mut S::Job) + Sync),
    after_chunk: impl FnMut(&mut S) -> Result<()>,
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    let io = |e: std::io::Error| Error::io("<output>", e);
    writeln!(
        out,
        "(kinpost: APT CL {} for machine {})",
        sanitize_comment(&opts.file_name),
        sanitize_comment(&machine.name)
    )
    .map_err(io)?;
    writeln!(out, "G21 G90 G94").map_err(io)?;
    let mut records = crate::cl::lower(
        ClReader::new(input, &opts.file_name),
        &opts.file_name,
        opts.arc_tolerance_mm,
        opts.cl_units,
    );
    let format = ClFormat {
        front: ClFront {
            machine,
            opts,
            lines: 0,
            max_vector_deviation: 0.0,
            warnings: Vec::new(),
            seq: 0,
            queue: VecDeque::new(),
            axis: Vector3::z(),
            rapid_next: false,
            other_since_pose: false,
            units: Units::Mm,
            feed: None,
            per_rev: false,
            g80: 0,
            cutcom: None,
            previous: None,
            deferred: false,
        },
        back: ClBack {
            machine,
            opts,
            poses: 0,
            max_axis_miss_rad: 0.0,
            warnings: Vec::new(),
            writer: AxisWriter::new(machine, opts.decimals),
            previous: None,
            previous_th: None,
            cutcom_reference: None,
            probe: None,
            last_tip: None,
            g93: false,
            feed_written: None,
            warned_no_feed: false,
            motion_written: None,
            plane_written: None,
            g80_applied: 0,
            scratch: String::new(),
        },
    };
    // Nothing is read after a statement that failed (it is raised in order).
    let mut failed = false;
    let read = |unit: &mut ClUnit| -> Result<Option<usize>> {
        if failed {
            return Ok(None);
        }
        // The text of the record the unit held is read into again.
        if let Some(Ok(old)) = unit.take() {
            records.recycle(old.text);
        }
        *unit = records.next();
        Ok(match unit {
            None => None,
            Some(Ok(r)) => Some(r.text.len()),
            Some(Err(_)) => {
                failed = true;
                Some(0)
            }
        })
    };
    super::pipeline::drive(format, read, stage, work, after_chunk, out, progress)
}

/// One lowered statement as read (or the error reading it).
type ClUnit = Option<Result<ClRecord>>;

/// A `GOTO` between [`Format::begin`] and [`Format::finish`], with the
/// modal state it was programmed in.
pub struct ClPending {
    pose: Pose,
    /// The tool tip, mm.
    tip: Vector3<f64>,
    /// `RAPID` came before it.
    rapid: bool,
    /// The feed in force (mm/min, or mm/rev when `per_rev`).
    feed: Option<f64>,
    per_rev: bool,
    /// The `G80` blocks begun before it ([`ClFormat::g80`]).
    g80: u64,
    /// Its place among the statements (for the order of warnings).
    seq: u64,
    /// Cutter compensation in force.
    cutcom: Option<CutcomOn>,
    /// A block that may move the machine or change the controlled point
    /// (a tool change, `G43`, a hole's cycle) was written since the pose
    /// before: with `--modal-axes` every axis word is written.
    after_other: bool,
}

/// Warnings with the place of their statement and half (0: begin,
/// 1: finish): sorted at the end into statement order.
type Warnings = Vec<((u64, u8), String)>;

/// APT CL as a [`Format`]: the lowered statements (read in order on the
/// driver's thread: the reader and the lowering keep state from statement
/// to statement), converted in order.
///
/// Its state is in two halves. [`Format::begin`] reads and sets the modal
/// state of the program (units, tool axis, `RAPID`, feed: [`ClFront`]),
/// captured in each pose's [`ClPending`]; [`Format::finish`] the state of
/// what is written (joint values, axis words, modal words written:
/// [`ClBack`]). Under `compensate` the first pass of a chunk runs beside
/// the last pass of the chunk two before it, so `begin` does not touch
/// the written state; with a planner (`post`) every pose before is written
/// when `begin` runs, and arcs and holes are planned and written there.
struct ClFormat<'a> {
    front: ClFront<'a>,
    back: ClBack<'a>,
}

/// The program's modal state ([`Format::begin`]).
struct ClFront<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    /// Statements read.
    lines: usize,
    /// Largest deviation of a tool axis's length from 1.
    max_vector_deviation: f64,
    warnings: Warnings,
    /// Statements begun.
    seq: u64,
    /// Statements an arc or a hole of the unit turned into (its moves, or
    /// the steps of its canned form), given out one `begin` at a time.
    queue: VecDeque<ClStatement>,
    /// The tool axis in force.
    axis: Vector3<f64>,
    rapid_next: bool,
    /// See [`ClPending::after_other`].
    other_since_pose: bool,
    units: Units,
    feed: Option<f64>,
    /// `--feed inverse-time`: the feed is per revolution (no conversion).
    per_rev: bool,
    /// `G80` blocks begun: each one resets the motion code written, in
    /// order, when the first pose after it is written.
    g80: u64,
    /// Cutter compensation in force (`CUTCOM/LEFT|RIGHT` until
    /// `CUTCOM/OFF`).
    cutcom: Option<CutcomOn>,
    /// The joint values the program continues from: the last pose's as the
    /// first pass solved it ([`Format::begun`]), or a planned arc's or
    /// hole's end.
    previous: Option<JointValues>,
    /// The last pose begun is solved in the last pass ([`Format::deferred`]):
    /// `previous` is not known yet.
    deferred: bool,
}

/// What is written ([`Format::finish`]; [`Format::begin`] with a planner).
struct ClBack<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    /// Poses written.
    poses: usize,
    /// Largest tool-axis miss, rad.
    max_axis_miss_rad: f64,
    warnings: Warnings,
    writer: AxisWriter<'a>,
    /// Joint values of the last pose written.
    previous: Option<JointValues>,
    /// Its theoretical joint values (`compensate` writes compensated ones).
    previous_th: Option<JointValues>,
    /// The theoretical joint values in force when the cutter compensation
    /// in force went on (its [`CutcomOn::seq`]): the rotary axes must stay
    /// at them.
    cutcom_reference: Option<(u64, JointValues)>,
    /// The inverse kinematics of the nominal machine, for the test that the
    /// tool is along Z under cutter compensation (made at the first
    /// compensated move).
    probe: Option<crate::machine::IkSolver>,
    /// The last programmed tool tip, mm.
    last_tip: Option<Vector3<f64>>,
    /// The output is in `G93`.
    g93: bool,
    feed_written: Option<f64>,
    /// A feed move without a feed was warned of.
    warned_no_feed: bool,
    motion_written: Option<u8>,
    plane_written: Option<u8>,
    /// The `G80` blocks applied to `motion_written`.
    g80_applied: u64,
    /// Scratch for a formatted number.
    scratch: String,
}

/// The record of a unit that was read without error.
fn record(unit: &ClUnit) -> &ClRecord {
    match unit {
        Some(Ok(r)) => r,
        _ => unreachable!("a statement that failed to read is raised at its begin"),
    }
}

/// Where a statement is.
fn location(opts: &PostOptions, record: &ClRecord) -> Location {
    Location::new(&opts.file_name, record.line, record.col)
}

/// The statement's text, trimmed, for messages and comments.
fn text(record: &ClRecord) -> String {
    String::from_utf8_lossy(&record.text).trim().to_string()
}

/// An error at `record`, quoting it.
fn error_at(opts: &PostOptions, record: &ClRecord, message: String) -> Error {
    Error::input_with(location(opts, record), message, text(record))
}

/// Appends a line to `out` (writing to a vector cannot fail).
fn line(out: &mut Vec<u8>, args: std::fmt::Arguments) {
    let _ = out.write_fmt(args);
    out.push(b'\n');
}

impl ClBack<'_> {
    /// Resets the motion code written for the `G80` blocks up to `upto`.
    fn apply_g80(&mut self, upto: u64) {
        if self.g80_applied != upto {
            self.motion_written = None;
            self.g80_applied = upto;
        }
    }
}

impl ClFront<'_> {
    /// A warning of the statement begun last.
    fn warn(&mut self, w: String) {
        self.warnings.push(((self.seq, 0), w));
    }

    /// The pose of a `GOTO` to tip `tip` (CL units), tool axis `a` or the
    /// one in force.
    fn goto(
        &mut self,
        record: &ClRecord,
        tip: &[f64; 3],
        a: Option<&[f64; 3]>,
    ) -> Result<Option<ClPending>> {
        let scale = self.units.mm_per_unit();
        let tip = Vector3::new(tip[0], tip[1], tip[2]) * scale;
        if let Some(a) = a {
            self.axis = Vector3::new(a[0], a[1], a[2]);
        }
        let norm = self.axis.norm();
        if norm.is_nan()
            || norm <= 1e-12
            || (norm - 1.0).abs() > crate::program::modal::TOOL_VECTOR_TOLERANCE
        {
            return Err(error_at(
                self.opts,
                record,
                format!(
                    "tool axis of length {norm:.6}, not 1 (tolerance {}): expected a unit vector",
                    crate::program::modal::TOOL_VECTOR_TOLERANCE
                ),
            ));
        }
        self.max_vector_deviation = self.max_vector_deviation.max((norm - 1.0).abs());
        if (norm - 1.0).abs() > crate::program::modal::QUIET_NORMALISATION {
            let loc = location(self.opts, record);
            self.warn(format!(
                "{loc}: tool axis of length {norm:.9} normalised to unit length"
            ));
        }
        Ok(Some(ClPending {
            pose: Pose::new(tip, self.axis / norm),
            tip,
            rapid: std::mem::take(&mut self.rapid_next),
            feed: self.feed,
            per_rev: self.per_rev,
            g80: self.g80,
            seq: self.seq,
            cutcom: self.cutcom,
            after_other: std::mem::take(&mut self.other_since_pose),
        }))
    }

    /// In order: one statement of `record` (its own, or one its arc or
    /// hole turned into). `back`: what is written, with a planner.
    fn statement(
        &mut self,
        mut back: Option<&mut ClBack<'_>>,
        record: &ClRecord,
        statement: &ClStatement,
        planner: Option<&mut dyn PoseSolver>,
        out: &mut Vec<u8>,
    ) -> Result<Option<ClPending>> {
        self.seq += 1;
        self.other_since_pose |= matches!(
            statement,
            ClStatement::Block(_)
                | ClStatement::LoadTl { .. }
                | ClStatement::CutterCompensation { .. }
                | ClStatement::Hole(_)
        );
        // Back to G94 before anything but a straight move in pose order
        // (an arc, a hole, the end): it keeps the programmed feed. (Only
        // `post` writes G93, and it writes each pose before the next
        // statement begins.)
        if let Some(b) = back.as_deref_mut()
            && b.g93
            && matches!(
                statement,
                ClStatement::Arc(_) | ClStatement::Hole(_) | ClStatement::End
            )
        {
            out.extend_from_slice(b"G94\n");
            b.g93 = false;
            b.feed_written = None;
        }
        self.lines += 1;
        match statement {
            ClStatement::Goto { tip, axis } => return self.goto(record, tip, axis.as_ref()),
            ClStatement::Fedrat { value, unit } => {
                self.feed = Some(match unit {
                    FeedUnit::Ipm => value * 25.4,
                    FeedUnit::Unspecified => value * self.units.mm_per_unit(),
                    _ => *value,
                });
                self.per_rev = matches!(unit, FeedUnit::Mmpr | FeedUnit::Ipr);
                if self.per_rev {
                    line(out, format_args!("({})", sanitize_comment(&text(record))));
                }
            }
            ClStatement::Rapid => self.rapid_next = true,
            ClStatement::TlAxis(a) => self.axis = Vector3::new(a[0], a[1], a[2]),
            ClStatement::LoadTl { tool, .. } => line(out, format_args!("T{tool} M6")),
            ClStatement::Spindle { rpm, dir, off } => {
                if *off {
                    line(out, format_args!("M5"));
                } else {
                    let m = match dir {
                        Some(SpindleDir::CounterClockwise) => "M4",
                        _ => "M3",
                    };
                    match rpm {
                        Some(s) => line(
                            out,
                            format_args!("S{} {m}", crate::program::format::fixed(*s, 0)),
                        ),
                        None => line(out, format_args!("{m}")),
                    }
                }
            }
            ClStatement::Coolant(on) => {
                line(out, format_args!("{}", if *on { "M8" } else { "M9" }))
            }
            ClStatement::Units(u) => {
                self.units = match u {
                    crate::cl::ClUnits::Inches => Units::Inch,
                    crate::cl::ClUnits::Mm => Units::Mm,
                };
                line(out, format_args!("({})", sanitize_comment(&text(record))));
            }
            ClStatement::Comment(c) => line(out, format_args!("({})", sanitize_comment(c.trim()))),
            ClStatement::End => {
                let t = text(record).to_ascii_uppercase();
                line(
                    out,
                    format_args!("{}", if t.starts_with("FINI") { "M30" } else { "M2" }),
                );
            }
            ClStatement::Multax(_) | ClStatement::Other { .. } => {
                line(out, format_args!("({})", sanitize_comment(&text(record))))
            }
            ClStatement::Block(b) => {
                if b == "G80" {
                    self.g80 += 1;
                    if planner.is_some()
                        && let Some(back) = back
                    {
                        back.apply_g80(self.g80);
                    }
                }
                if b.starts_with("G43 H") && self.machine.tool_length_mm > 0.0 {
                    // The chain ends at the tip of a tool of known length
                    // (`--tool-length`, or the machine file's `tool_length`):
                    // the axis words include it, so the controller's tool
                    // length compensation must be off, as G43.4 becomes G49.
                    // Before, `G43 H1` made the controller add the length a
                    // second time.
                    line(
                        out,
                        format_args!("G49 ({b}: the tool length is in the axis words)"),
                    );
                } else {
                    line(out, format_args!("{b}"));
                }
            }
            ClStatement::CutterCompensation { block, on } => {
                self.cutcom = on.then(|| CutcomOn {
                    seq: self.seq,
                    line: record.line,
                    left: block.starts_with("G41"),
                });
                line(out, format_args!("{block}"));
            }
            ClStatement::Warning(w) => self.warn(w.clone()),
            ClStatement::Arc(arc) => self.arc(back, record, arc, planner, out)?,
            ClStatement::Hole(hole) => self.hole(back, record, hole, planner, out)?,
        }
        Ok(None)
    }
}

impl ClBack<'_> {
    /// Refuses the move `pending` under cutter compensation `on` where the
    /// controller's `G41`/`G42` would not be the compensation the CL asks
    /// for ([`cl_motion::cutcom_refusal`]), comparing theoretical joint
    /// values ([`SolvedPose::theoretical_q`]).
    fn check_cutcom(
        &mut self,
        record: &ClRecord,
        pending: &ClPending,
        solved: &SolvedPose,
        on: CutcomOn,
    ) -> Result<()> {
        let (opts, machine) = (self.opts, self.machine);
        let q = solved.theoretical_q();
        // The joint values in force when it went on: those of the pose
        // before its first move (or of that move, the program's first).
        let reference = match &self.cutcom_reference {
            Some((seq, r)) if *seq == on.seq => r.clone(),
            _ => {
                let r = self
                    .previous_th
                    .clone()
                    .unwrap_or_else(|| q.iter().copied().collect());
                self.cutcom_reference = Some((on.seq, r.clone()));
                r
            }
        };
        let probe = self
            .probe
            .get_or_insert_with(|| crate::machine::IkSolver::new(machine));
        match cl_motion::cutcom_refusal(
            machine,
            probe,
            opts,
            q,
            &pending.pose,
            &reference,
            on,
            record.line,
        ) {
            Some(m) => Err(error_at(opts, record, m)),
            None => Ok(()),
        }
    }
}

impl<'a> Format for ClFormat<'a> {
    type Unit = ClUnit;
    type Pending = ClPending;
    type Front = ClFront<'a>;
    type Back = ClBack<'a>;
    fn halves(&mut self) -> (&mut ClFront<'a>, &mut ClBack<'a>) {
        (&mut self.front, &mut self.back)
    }
    fn splits(&self) -> bool {
        // Only `post` writes G93 (and plans: it has a planner).
        !self.front.opts.inverse_time
    }
    fn prepare(_: &mut ClUnit) {}
    fn line(unit: &ClUnit) -> usize {
        match unit {
            Some(Ok(r)) => r.line,
            _ => 0,
        }
    }
    fn begin(
        front: &mut ClFront<'a>,
        back: Option<&mut ClBack<'a>>,
        unit: &mut ClUnit,
        out: &mut Vec<u8>,
        planner: Option<&mut dyn PoseSolver>,
    ) -> Result<Option<ClPending>> {
        if let Some(Err(_)) = unit
            && let Some(Err(e)) = unit.take()
        {
            return Err(e);
        }
        let record = record(unit);
        match front.queue.pop_front() {
            Some(s) => front.statement(back, record, &s, planner, out),
            None => front.statement(back, record, &record.statement, planner, out),
        }
    }
    fn unit_done(front: &ClFront<'a>) -> bool {
        front.queue.is_empty()
    }
    fn pose(pending: &ClPending) -> &Pose {
        &pending.pose
    }
    fn previous<'r>(front: &'r ClFront<'a>) -> Option<&'r [f64]> {
        if front.deferred {
            None
        } else {
            front.previous.as_deref()
        }
    }
    fn begun(front: &mut ClFront<'a>, q: &[f64]) {
        front.previous = Some(q.iter().copied().collect());
        front.deferred = false;
    }
    const DEFERRABLE: bool = true;
    fn deferred(front: &mut ClFront<'a>) {
        front.deferred = true;
    }
    fn needs_committed(_: &ClFront<'a>, unit: &ClUnit) -> bool {
        // An arc or a hole is planned with the solver, from the joint
        // values before it, and written at once (`plan.rs`).
        matches!(unit, Some(Ok(r)) if matches!(r.statement, ClStatement::Arc(_) | ClStatement::Hole(_)))
    }
    fn continues_from<'r>(back: &'r ClBack<'a>, _: &'r ClPending) -> Option<&'r [f64]> {
        back.previous.as_deref()
    }
    fn sync(front: &mut ClFront<'a>, back: &ClBack<'a>) {
        if front.deferred {
            front.previous = back.previous.clone();
            front.deferred = false;
        }
    }
    fn front_error(front: &ClFront<'a>, unit: &ClUnit, _: &ClPending, message: String) -> Error {
        error_at(front.opts, record(unit), message)
    }
    fn back_error(back: &ClBack<'a>, unit: &ClUnit, _: &ClPending, message: String) -> Error {
        error_at(back.opts, record(unit), message)
    }
    fn finish(
        back: &mut ClBack<'a>,
        unit: &ClUnit,
        pending: &ClPending,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        back.finish(unit, pending, solved, out)
    }
    fn end(&mut self, out: &mut Vec<u8>) {
        if self.back.g93 {
            out.extend_from_slice(b"G94\n");
        }
    }
    fn stats(self) -> PostStats {
        let (f, b) = (self.front, self.back);
        super::stats_of_halves(
            (f.lines, f.max_vector_deviation, f.warnings),
            (b.poses, b.max_axis_miss_rad, b.warnings),
        )
    }
}

impl ClBack<'_> {
    /// Appends the pose `pending` with the joint values `solved`.
    fn finish(
        &mut self,
        unit: &ClUnit,
        pending: &ClPending,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let (opts, machine) = (self.opts, self.machine);
        let record = record(unit);
        if solved.axis_miss_rad > opts.axis_tolerance_rad {
            return Err(error_at(
                opts,
                record,
                unreachable_axis(&machine.name, solved.axis_miss_rad, opts.axis_tolerance_rad),
            ));
        }
        if let Some(on) = pending.cutcom {
            self.check_cutcom(record, pending, solved, on)?;
        }
        self.apply_g80(pending.g80);
        self.max_axis_miss_rad = self.max_axis_miss_rad.max(solved.axis_miss_rad);
        self.poses += 1;
        if let Some(prev) = &self.previous
            && let Some(w) = crate::machine::midblock::branch_change_warning(
                machine,
                prev,
                &solved.q,
                &pending.pose,
            )
        {
            let loc = location(opts, record);
            self.warnings
                .push(((pending.seq, 1), format!("{loc}: {w}")));
        }
        let motion = if pending.rapid { 0 } else { 1 };
        // Inverse time: a feed move per minute that turns a rotary axis
        // and moves the tip lasts tip path / feed.
        let inverse_f = match (
            opts.inverse_time,
            motion,
            pending.per_rev,
            pending.feed,
            &self.previous,
        ) {
            (true, 1, false, Some(f), Some(p)) => {
                let turns = machine
                    .chain
                    .joints()
                    .iter()
                    .zip(p.iter().zip(&solved.q))
                    .any(|(j, (a, b))| {
                        j.kind == crate::machine::JointKind::Revolute && (a - b).abs() > 1e-12
                    });
                let path = self.last_tip.map_or(0.0, |t| (pending.tip - t).norm());
                (turns && path > crate::program::inverse_time::MIN_TIP_PATH_MM).then(|| f / path)
            }
            _ => None,
        };
        if pending.after_other {
            self.writer.write_all_next();
        }
        let words = self
            .writer
            .words(&solved.q, Units::Mm, true, opts.modal_axes, " ")
            .map_err(|m| Error::input(location(opts, record), m))?;
        let start = out.len();
        match (inverse_f, self.g93) {
            (Some(_), false) => out.extend_from_slice(b"G93 "),
            (None, true) => {
                out.extend_from_slice(b"G94 ");
                self.feed_written = None;
            }
            _ => {}
        }
        self.g93 = inverse_f.is_some();
        if self.motion_written != Some(motion) {
            out.extend_from_slice(if motion == 0 { b"G0 " } else { b"G1 " });
            self.motion_written = Some(motion);
        }
        out.extend_from_slice(words);
        let scratch = &mut self.scratch;
        scratch.clear();
        if let Some(f93) = inverse_f {
            scratch.push_str(" F");
            scratch.push_str(&crate::program::inverse_time::feed_text(f93));
            self.feed_written = None;
        } else if motion == 1 && pending.feed.is_some() && pending.feed != self.feed_written {
            scratch.push_str(" F");
            cl_motion::push_number(scratch, pending.feed.unwrap_or(0.0));
            self.feed_written = pending.feed;
        } else if motion == 1 && pending.feed.is_none() && !self.warned_no_feed {
            self.warned_no_feed = true;
            self.warnings.push((
                (pending.seq, 1),
                format!(
                    "{}: a feed move (a GOTO after no RAPID) before any FEDRAT: written as G1 without F; a controller refuses it (LinuxCNC, Fanuc) or moves at a feed left from before the program; give a FEDRAT in the CL data",
                    location(opts, record)
                ),
            ));
        }
        out.extend_from_slice(scratch.as_bytes());
        // The block without trailing spaces (the words may be none).
        while out.len() > start && out.last().is_some_and(u8::is_ascii_whitespace) {
            out.pop();
        }
        out.push(b'\n');
        self.previous = Some(solved.q.clone());
        self.previous_th = Some(solved.theoretical_q().iter().copied().collect());
        self.last_tip = Some(pending.tip);
        Ok(())
    }
}

/// Makes text safe inside a `( )` comment: parentheses become brackets and
/// line breaks become spaces.
fn sanitize_comment(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            '\r' | '\n' => ' ',
            c => c,
        })
        .collect()
}
