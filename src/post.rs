//! `kinpost post`: tool poses in, machine axis words out.
//!
//! The program streams through block by block: parse (lossless), modal state,
//! pose → machine axes (analytic IK, optionally refined by compensation),
//! and the emitter, which rewrites only the axis words of converted blocks.
//! Everything else leaves byte for byte as it came.

pub mod pipeline;

use crate::error::{Error, Result};
use crate::gcode::Line;
use crate::machine::{IkSolver, Machine, Pose};
use crate::program::format::{push_fixed, push_scaled, scaled_integer};
pub use crate::program::rewrite::rewrite;
use crate::program::{PoseStart, Units};
use pipeline::{Format, SolveFirst, Stage, Whole};
use std::io::{BufRead, Write};

pub mod choose_in_order;
mod cl;
mod cl_motion;
mod gcode;
mod pending;
mod position;
mod rotary_pose;
pub use cl::{convert_cl, post_cl};
pub use gcode::{BlockReader, BlockWriter, Converted, GcodeConverter, PendingPose, Start};

/// Turns a tool pose into joint values (chain order, internal units).
///
/// The theoretical machine uses the analytic IK ([`IkSolver`]); compensation
/// wraps it with Newton refinement on the error-aware chain.
pub trait PoseSolver {
    /// Joint values for `pose` (programmed at `line`), continuing from `previous`.
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<SolvedPose, String>;

    /// Whether poses that are not written (an arc's centre and points, a
    /// hole's levels) may be solved to plan a `G2`/`G3` or canned cycle on
    /// APT CL; `false` for a solver that reports every pose it solves, which
    /// then gets the moves.
    fn plans_freely(&self) -> bool {
        true
    }

    /// The solver in two parts, where it has them: `post` then finds each
    /// pose's branches in parallel and chooses among them in order
    /// ([`choose_in_order`]).
    fn split(&self) -> Option<&dyn SplitSolver> {
        None
    }
}

/// A [`PoseSolver`] in two parts: the branches of a pose, which do not
/// depend on the pose before (any thread), and the choice among them,
/// which does (in order). Together they give what
/// [`PoseSolver::solve`] gives.
pub trait SplitSolver: Sync {
    /// The order-free part of `pose` (programmed at `line`).
    fn prepare(&self, pose: &Pose, line: usize) -> crate::machine::PreparedPose;
    /// The joint values of `pose` from its `prepared` part, continuing
    /// from `previous`.
    fn choose(
        &self,
        pose: &Pose,
        prepared: &crate::machine::PreparedPose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<SolvedPose, String>;
}

impl SplitSolver for IkSolver {
    fn prepare(&self, pose: &Pose, _line: usize) -> crate::machine::PreparedPose {
        IkSolver::prepare(self, pose)
    }
    fn choose(
        &self,
        pose: &Pose,
        prepared: &crate::machine::PreparedPose,
        previous: Option<&[f64]>,
        _line: usize,
    ) -> std::result::Result<SolvedPose, String> {
        IkSolver::choose(self, pose, prepared, previous)
            .map(|s| SolvedPose {
                q: s.q,
                axis_miss_rad: s.axis_miss_rad,
                theoretical: None,
            })
            .map_err(|e| e.to_string())
    }
}

/// The message for a pose whose closest reachable tool axis misses the
/// programmed one by `miss_rad`, more than `tolerance_rad`: the same words
/// from every command that turns poses into axes.
pub fn unreachable_axis(machine: &str, miss_rad: f64, tolerance_rad: f64) -> String {
    format!(
        "machine {machine} cannot reach this tool axis: the closest reachable axis misses it by {:.3} µrad ({:.6}°), more than the tolerance {:.3} µrad (--axis-tolerance-urad)",
        miss_rad * 1e6,
        miss_rad.to_degrees(),
        tolerance_rad * 1e6
    )
}

/// The joint values found for one pose.
#[derive(Debug, Clone, PartialEq)]
pub struct SolvedPose {
    /// Joint values, chain order, mm / rad.
    pub q: crate::machine::chain::JointValues,
    /// Angle by which the reachable tool axis misses the programmed one, rad
    /// (non-zero on four-axis machines for poses off the machine's cone).
    pub axis_miss_rad: f64,
    /// The theoretical joint values of the pose (the inverse kinematics of
    /// the nominal machine) when `q` is compensated (`kinpost compensate`),
    /// `None` when `q` is theoretical: the checks of what the program asks
    /// of the machine (cutter compensation) compare these.
    pub theoretical: Option<crate::machine::chain::JointValues>,
}

impl SolvedPose {
    /// The theoretical joint values ([`SolvedPose::theoretical`], else `q`).
    pub fn theoretical_q(&self) -> &[f64] {
        self.theoretical.as_deref().unwrap_or(&self.q)
    }
}

impl PoseSolver for IkSolver {
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        _line: usize,
    ) -> std::result::Result<SolvedPose, String> {
        IkSolver::solve(self, pose, previous)
            .map(|s| SolvedPose {
                q: s.q,
                axis_miss_rad: s.axis_miss_rad,
                theoretical: None,
            })
            .map_err(|e| e.to_string())
    }

    fn split(&self) -> Option<&dyn SplitSolver> {
        Some(self)
    }
}

/// Why a move of APT CL data under cutter compensation `on` cannot run as
/// the `G41`/`G42` `post` writes, as `post` refuses it (the tool not along
/// the machine's Z axis, or a rotary axis turned since `reference`, the
/// joint values when it went on), or `None` when it can: for the commands
/// that read CL without rewriting it (`analyze`, `simulate`). `q`: the
/// joint values of `pose` (chain order, mm / rad), programmed at `line`.
#[allow(clippy::too_many_arguments)]
pub fn cl_cutter_comp_refusal(
    machine: &Machine,
    ik: &mut IkSolver,
    axis_tolerance_rad: f64,
    q: &[f64],
    pose: &Pose,
    reference: &[f64],
    on: crate::program::source::CutterComp,
    line: usize,
) -> Option<String> {
    let opts = PostOptions {
        axis_tolerance_rad,
        ..PostOptions::default()
    };
    let on = cl_motion::CutcomOn {
        seq: 0,
        line: on.line,
        left: on.left,
    };
    cl_motion::cutcom_refusal(machine, ik, &opts, q, pose, reference, on, line)
}

/// Options of the post-processor.
#[derive(Debug, Clone)]
pub struct PostOptions {
    /// Decimals for every axis, overriding the machine file.
    pub decimals: Option<u32>,
    /// Whether pose mode is on before the program switches it.
    pub pose_start: PoseStart,
    /// Largest tool-axis miss accepted on a machine that cannot reach every axis, rad.
    pub axis_tolerance_rad: f64,
    /// Write only the axes whose value changed (modal output) instead of all axes.
    pub modal_axes: bool,
    /// Name of the input file for messages.
    pub file_name: String,
    /// APT CL: largest chord error of linearised arcs, mm.
    pub arc_tolerance_mm: f64,
    /// APT CL: units of a program without `UNITS` (None: mm, with a warning).
    pub cl_units: Option<crate::cl::ClUnits>,
    /// G-code `post`: inverse-time feeds on pose blocks that turn a rotary
    /// axis ([`crate::program::inverse_time`]).
    pub inverse_time: bool,
    /// G-code `post` of a job whose tool changes: the machine of each tool
    /// with the 1-based line it applies from (empty: the converter's one
    /// machine throughout). The solver must switch at the same lines.
    pub tool_machines: Vec<(usize, Machine)>,
}

impl Default for PostOptions {
    fn default() -> Self {
        PostOptions {
            decimals: None,
            pose_start: PoseStart::On,
            axis_tolerance_rad: 1e-4,
            modal_axes: false,
            file_name: "<stdin>".into(),
            arc_tolerance_mm: crate::cl::DEFAULT_ARC_TOLERANCE_MM,
            cl_units: None,
            inverse_time: false,
            tool_machines: Vec::new(),
        }
    }
}

/// What the post-processor did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct PostStats {
    /// Lines read.
    pub lines: usize,
    /// Blocks converted from poses to machine axes.
    pub poses: usize,
    /// Largest tool-axis miss, rad.
    pub max_axis_miss_rad: f64,
    /// Largest deviation of a programmed tool vector's length from 1
    /// (normalised; per-block warnings only beyond 1e-5).
    pub max_vector_deviation: f64,
    /// Warnings with their locations.
    pub warnings: Vec<String>,
}

/// The statistics of a format whose two halves count apart: the front's
/// lines read and largest tool-vector deviation, the back's poses written
/// and largest tool-axis miss, and the warnings of both, each with its
/// place in the program, in program order (stable: at one place the
/// front's come first, each half's in its own order).
fn stats_of_halves<K: Ord>(
    (lines, max_vector_deviation, front): (usize, f64, Vec<(K, String)>),
    (poses, max_axis_miss_rad, back): (usize, f64, Vec<(K, String)>),
) -> PostStats {
    let mut warnings = front;
    warnings.extend(back);
    warnings.sort_by(|a, b| a.0.cmp(&b.0));
    PostStats {
        lines,
        poses,
        max_axis_miss_rad,
        max_vector_deviation,
        warnings: warnings.into_iter().map(|w| w.1).collect(),
    }
}

/// The decimals an axis word of `axis` is written with in a program in
/// `units`: `given` (`--decimals`) where given, else the machine file's;
/// for a linear axis in an inch program one more, as a control's least
/// input increment of 0.001 mm is 0.0001 in (Fanuc's IS-B), so that an
/// inch word is not 25.4 times as coarse as a millimetre word (3 decimals
/// of an inch are steps of 25.4 µm).
pub fn written_decimals(axis: &crate::machine::AxisSpec, given: Option<u32>, units: Units) -> u32 {
    let inch_length = units == Units::Inch && axis.kind == crate::machine::JointKind::Prismatic;
    given.unwrap_or(axis.decimals + u32::from(inch_length))
}

/// Emits the machine's axis words for one converted block.
struct AxisWriter<'m> {
    machine: &'m Machine,
    /// Decimals of each axis in a millimetre program (0) and in an inch
    /// program (1) ([`written_decimals`]).
    decimals: [Vec<usize>; 2],
    /// `10^decimals` of each axis, the same way.
    scales: [Vec<f64>; 2],
    /// The last block's words (output order, file units), for modal output
    /// and G91; empty before the first.
    last: Vec<AxisValue>,
    /// The next block writes every axis word ([`AxisWriter::write_all_next`]).
    write_all: bool,
    /// mm per program unit of `last` (the units it was written in).
    last_per_unit: f64,
    /// Scratch for the next block's (its allocation reused).
    next: Vec<AxisValue>,
    /// The words of the last block (ASCII), their buffer reused.
    text: Vec<u8>,
    /// Scratch for a word formatted through floating point.
    scratch: String,
}

/// One axis word's value as written: rounded to the axis's decimals.
#[derive(Clone, Copy)]
struct AxisValue {
    /// The value in file units, before rounding.
    raw: f64,
    /// `raw · 10^decimals` rounded, when it fits (see [`scaled_integer`]).
    scaled: Option<i64>,
}

impl AxisValue {
    /// The word of `axis` at joint value `q` (internal units) in a program
    /// unit of `per_unit` mm, to `1 / scale`.
    #[inline]
    fn of(axis: &crate::machine::AxisSpec, scale: f64, q: f64, per_unit: f64) -> Self {
        let v = crate::machine::output_value(axis, q);
        // (v / 1 is v: millimetre programs skip the division.)
        let raw = if axis.kind == crate::machine::JointKind::Prismatic && per_unit != 1.0 {
            v / per_unit
        } else {
            v
        };
        let scaled = scaled_integer(raw * scale);
        // A modulo axis just below 360° rounds to 360: it is written 0.
        let full_turn = axis.rotary == crate::machine::RotaryMode::Modulo
            && scaled.is_some_and(|i| i as f64 == 360.0 * scale);
        if full_turn {
            AxisValue {
                raw: 0.0,
                scaled: Some(0),
            }
        } else {
            AxisValue { raw, scaled }
        }
    }

    /// The value rounded to `1 / scale`: the double nearest the decimal
    /// written (so that incremental output does not drift).
    fn rounded(self, scale: f64) -> f64 {
        match self.scaled {
            Some(i) => i as f64 / scale,
            None => (self.raw * scale).round() / scale,
        }
    }

    /// Whether both round to the same written decimal: the integers, when
    /// both have one (distinct integers below 2^50 give distinct doubles).
    fn same_as(self, other: AxisValue, scale: f64) -> bool {
        match (self.scaled, other.scaled) {
            (Some(a), Some(b)) => a == b,
            _ => self.rounded(scale) == other.rounded(scale),
        }
    }
}

impl<'m> AxisWriter<'m> {
    fn new(machine: &'m Machine, decimals: Option<u32>) -> Self {
        let decimals = [Units::Mm, Units::Inch].map(|u| {
            (machine.axes.iter())
                .map(|a| written_decimals(a, decimals, u) as usize)
                .collect::<Vec<_>>()
        });
        let scales = decimals
            .each_ref()
            .map(|d| d.iter().map(|&d| 10f64.powi(d as i32)).collect());
        AxisWriter {
            machine,
            decimals,
            scales,
            last: Vec::with_capacity(machine.axes.len()),
            write_all: false,
            last_per_unit: 1.0,
            next: Vec::with_capacity(machine.axes.len()),
            text: Vec::with_capacity(128),
            scratch: String::new(),
        }
    }

    /// Makes the next block write every axis word, also with modal output
    /// (the machine may have moved since, in a way kinpost did not write);
    /// the last block's values stay the base of incremental words.
    pub(crate) fn write_all_next(&mut self) {
        self.write_all = true;
    }

    /// The machine was moved since the last block by blocks kinpost passed
    /// through, to joint values `q` (internal units; `None` where the
    /// program does not say where): they, not the last block's words, are
    /// where the controller adds the next block's increments (G91).
    pub(crate) fn moved_to(&mut self, q: Option<&[f64]>) {
        self.last.clear();
        self.last_per_unit = 1.0;
        let Some(q) = q else {
            return;
        };
        for (axis, s) in self.machine.axes.iter().zip(&self.scales[0]) {
            let q = q.get(axis.joint).copied().unwrap_or(0.0);
            self.last.push(AxisValue::of(axis, *s, q, 1.0));
        }
    }

    /// Axis words for joint values `q` (chain order, internal units), written
    /// in program `units`, absolute or incremental, separated by `sep`.
    fn words(
        &mut self,
        q: &[f64],
        units: Units,
        absolute: bool,
        modal: bool,
        sep: &str,
    ) -> std::result::Result<&[u8], String> {
        let mut next = std::mem::take(&mut self.next);
        next.clear();
        let per_unit = units.mm_per_unit();
        let u = usize::from(units == Units::Inch);
        if per_unit != self.last_per_unit {
            // G20/G21 since the last block: the controller holds the
            // position and reads the next increments in the new unit.
            let ratio = self.last_per_unit / per_unit;
            let before = usize::from(self.last_per_unit != 1.0);
            for (p, (axis, s)) in self
                .last
                .iter_mut()
                .zip(self.machine.axes.iter().zip(&self.scales[before]))
            {
                if axis.kind == crate::machine::JointKind::Prismatic {
                    let raw = p.rounded(*s) * ratio;
                    *p = AxisValue { raw, scaled: None };
                }
            }
            self.last_per_unit = per_unit;
        }
        for (axis, s) in self.machine.axes.iter().zip(&self.scales[u]) {
            next.push(AxisValue::of(axis, *s, q[axis.joint], per_unit));
        }
        let out = &mut self.text;
        out.clear();
        for (k, axis) in self.machine.axes.iter().enumerate() {
            let (value, scale) = (next[k], self.scales[u][k]);
            let previous = self.last.get(k).copied();
            if modal && !self.write_all && previous.is_some_and(|p| p.same_as(value, scale)) {
                continue;
            }
            // Separators and axis names are a byte or two: pushed, not copied.
            if !out.is_empty() {
                for &b in sep.as_bytes() {
                    out.push(b);
                }
            }
            for &b in axis.name.as_bytes() {
                out.push(b);
            }
            let d = self.decimals[u][k];
            match (absolute, value.scaled, previous) {
                // LinuxCNC's wrapped rotary: the position in [0, 360) with
                // the sign of the block's turn (`machine::wrapped`).
                (true, Some(i), _) if axis.rotary == crate::machine::RotaryMode::Wrapped => {
                    let turn = (360.0 * scale) as i64;
                    let from = previous.and_then(|p| p.scaled);
                    let (negative, m) = crate::machine::wrapped::wrapped_word(from, i, turn)
                        .map_err(|m| format!("axis {}: {m}", axis.name))?;
                    if negative {
                        out.push(b'-');
                    }
                    push_scaled(out, m, d);
                }
                (true, None, _) if axis.rotary == crate::machine::RotaryMode::Wrapped => {
                    return Err(format!(
                        "axis {} at {:.3e}°: beyond the turns a wrapped rotary axis is followed over",
                        axis.name, value.raw
                    ));
                }
                (true, Some(i), _) => push_scaled(out, i, d),
                (true, None, _) => {
                    push_fixed_bytes(out, &mut self.scratch, value.rounded(scale), d)
                }
                (false, _, Some(p)) => push_fixed_bytes(
                    out,
                    &mut self.scratch,
                    value.rounded(scale) - p.rounded(scale),
                    d,
                ),
                (false, _, None) => {
                    return Err(format!(
                        "incremental output (G91) needs an earlier absolute position of axis {}",
                        axis.name
                    ));
                }
            }
        }
        // The previous values become the next block's scratch.
        self.next = std::mem::replace(&mut self.last, next);
        self.write_all = false;
        Ok(&self.text)
    }
}

/// [`push_fixed`] onto bytes, through the reused `scratch`.
fn push_fixed_bytes(out: &mut Vec<u8>, scratch: &mut String, value: f64, decimals: usize) {
    scratch.clear();
    push_fixed(scratch, value, decimals);
    out.extend_from_slice(scratch.as_bytes());
}

/// Converts a G-code pose program, writing the machine program to `out`,
/// with `solver` solving each pose in order (a pool task), the lines
/// parsed on the pool and each chunk's poses written while the next
/// chunk's are solved ([`pipeline::SolveFirst`]; with inverse-time feeds,
/// which tie a line to what was written before it, as they are solved:
/// [`pipeline::Whole`]) ([`pipeline::drive`]).
pub fn post_gcode<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    solver: &mut (dyn PoseSolver + Send),
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    // Under inverse time a line that is not a pose may go back to G94,
    // which depends on what is written before it: each pose is then
    // written as it is solved ([`Whole`]).
    if opts.inverse_time {
        convert_gcode(
            machine,
            &mut Whole::new(solver),
            &|_, j| match *j {},
            |_| Ok(()),
            input,
            out,
            opts,
            progress,
        )
    } else if let Some(split) = solver.split() {
        convert_gcode(
            machine,
            &mut choose_in_order::ChooseInOrder::new(split),
            &|pose, job| choose_in_order::ChooseInOrder::work(split, pose, job),
            |_| Ok(()),
            input,
            out,
            opts,
            progress,
        )
    } else {
        convert_gcode(
            machine,
            &mut SolveFirst::new(solver),
            &|_, _| {},
            |_| Ok(()),
            input,
            out,
            opts,
            progress,
        )
    }
}

/// Converts a G-code pose program with `stage` doing each pose, `work` on
/// the stage's jobs in parallel and `after_chunk` after each chunk is
/// written ([`pipeline::drive`]).
#[allow(clippy::too_many_arguments)]
pub fn convert_gcode<S: Stage, R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    stage: &mut S,
    work: &(dyn Fn(&Pose, &mut S::Job) + Sync),
    after_chunk: impl FnMut(&mut S) -> Result<()>,
    mut input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    let mut format = GcodeFormat {
        conv: GcodeConverter::new(machine, opts),
    };
    format.conv.reader.read_arcs();
    let mut number = 0;
    let read = |unit: &mut GcodeUnit| -> Result<Option<usize>> {
        unit.raw.clear();
        match input.read_until(b'\n', &mut unit.raw) {
            Ok(0) => Ok(None),
            Ok(n) => {
                number += 1;
                unit.line.number = number;
                Ok(Some(n))
            }
            Err(e) => Err(Error::io(&opts.file_name, e)),
        }
    };
    pipeline::drive(format, read, stage, work, after_chunk, out, progress)
}

/// A G-code line for [`pipeline::drive`]: its bytes as read, then parsed.
#[derive(Default)]
pub struct GcodeUnit {
    /// The bytes read (after parsing: a spare buffer).
    raw: Vec<u8>,
    /// The parsed line.
    line: Line,
}

/// G-code as a [`Format`]: lines parsed on the pool, converted by a
/// [`GcodeConverter`]'s two halves.
struct GcodeFormat<'a> {
    conv: GcodeConverter<'a>,
}

impl<'a> Format for GcodeFormat<'a> {
    type Unit = GcodeUnit;
    type Pending = PendingPose;
    type Front = BlockReader<'a>;
    type Back = BlockWriter<'a>;
    fn halves(&mut self) -> (&mut BlockReader<'a>, &mut BlockWriter<'a>) {
        (&mut self.conv.reader, &mut self.conv.writer)
    }
    fn splits(&self) -> bool {
        // Under inverse time a line that is not a pose may go back to G94,
        // which depends on what is written.
        !self.conv.reader.inverse_time()
    }
    fn prepare(unit: &mut GcodeUnit) {
        let number = unit.line.number;
        crate::gcode::parse_line_swap(&mut unit.raw, number, &mut unit.line);
    }
    fn prefetch(unit: &GcodeUnit) {
        pipeline::prefetch_bytes(unit.line.items.as_slice());
        pipeline::prefetch_bytes(unit.line.bytes.as_slice());
    }
    fn line(unit: &GcodeUnit) -> usize {
        unit.line.number
    }
    fn begin(
        reader: &mut BlockReader<'a>,
        writer: Option<&mut BlockWriter<'a>>,
        unit: &mut GcodeUnit,
        out: &mut Vec<u8>,
        _: Option<&mut dyn PoseSolver>,
    ) -> Result<Option<PendingPose>> {
        reader.begin(writer, &unit.line, out)
    }
    fn unit_done(reader: &BlockReader<'a>) -> bool {
        reader.line_done()
    }
    fn pose(pending: &PendingPose) -> &Pose {
        &pending.pose
    }
    fn solve_from(pending: &PendingPose) -> Option<&[f64]> {
        pending.pinned.as_deref()
    }
    fn previous<'r>(reader: &'r BlockReader<'a>) -> Option<&'r [f64]> {
        reader.previous()
    }
    fn begun(reader: &mut BlockReader<'a>, q: &[f64]) {
        reader.begun(q);
    }
    const DEFERRABLE: bool = true;
    fn deferred(reader: &mut BlockReader<'a>) {
        reader.deferred();
    }
    fn needs_committed(reader: &BlockReader<'a>, unit: &GcodeUnit) -> bool {
        reader.needs_committed(&unit.line)
    }
    fn continues_from<'r>(
        writer: &'r BlockWriter<'a>,
        pending: &'r PendingPose,
    ) -> Option<&'r [f64]> {
        pending.continues.resolve(writer.last_joints())
    }
    fn sync(reader: &mut BlockReader<'a>, writer: &BlockWriter<'a>) {
        reader.sync(writer.last_joints());
    }
    fn front_error(
        reader: &BlockReader<'a>,
        unit: &GcodeUnit,
        pending: &PendingPose,
        message: String,
    ) -> Error {
        reader.solve_error(&unit.line, pending, message)
    }
    fn back_error(
        writer: &BlockWriter<'a>,
        unit: &GcodeUnit,
        pending: &PendingPose,
        message: String,
    ) -> Error {
        writer.solve_error(&unit.line, pending, message)
    }
    fn finish(
        writer: &mut BlockWriter<'a>,
        unit: &GcodeUnit,
        pending: &PendingPose,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        writer.finish(&unit.line, pending, solved, out)
    }
    fn end(&mut self, out: &mut Vec<u8>) {
        if let Some(end) = self.conv.end() {
            out.extend_from_slice(end.as_bytes());
        }
    }
    fn stats(self) -> PostStats {
        self.conv.stats()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::TcpCode;

    /// The rewritten line does not depend on what the output already holds
    /// (a dropped offset word at the start of a line keeps the indentation
    /// before it), and kept bytes are copied as they were.
    #[test]
    fn rewrite_is_line_local() {
        let line = crate::gcode::parse_line(b"  H1 G43.4 X1 Y2 Z3 I0 J0 K1 (tcp)\n", 1);
        let is = |a: &str| {
            line.items
                .iter()
                .position(|it| line.item_bytes(it) == a.as_bytes())
                .unwrap()
        };
        let replace = [is("X1"), is("Y2"), is("Z3"), is("I0"), is("J0"), is("K1")];
        let tcp = [TcpCode::FanucOn(is("G43.4"))];
        let drop = [is("H1")];
        let mut fresh = Vec::new();
        rewrite(&line, &replace, b"X0.1 Z-2.0", &tcp, &drop, &mut fresh);
        assert_eq!(String::from_utf8_lossy(&fresh), "  G49 X0.1 Z-2.0 (tcp)\n");
        let mut after = b"N10 G0 X0\n".to_vec();
        rewrite(&line, &replace, b"X0.1 Z-2.0", &tcp, &drop, &mut after);
        assert_eq!(&after[10..], &fresh[..]);
        let line = crate::gcode::parse_line(b"H1 G43.4 X1\n", 2);
        let mut out = Vec::new();
        rewrite(&line, &[4], b"X2", &[TcpCode::FanucOn(2)], &[0], &mut out);
        assert_eq!(String::from_utf8_lossy(&out), "G49 X2\n");
        // Nothing replaced: the bytes as they came.
        let mut same = Vec::new();
        rewrite(&line, &[], b"", &[], &[], &mut same);
        assert_eq!(same, line.bytes);
    }
}
