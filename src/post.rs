//! `kinpost post`: tool poses in, machine axis words out.
//!
//! The program streams through block by block: parse (lossless), modal state,
//! pose → machine axes (analytic IK, optionally refined by compensation),
//! and the emitter, which rewrites only the axis words of converted blocks.
//! Everything else leaves byte for byte as it came.

pub mod pipeline;

use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, Line};
use crate::machine::{IkSolver, Machine, Pose};
use crate::program::format::{push_fixed, push_scaled, scaled_integer};
use crate::program::modal::Motion;
use crate::program::opaque::opaque_in_pose_block;
pub use crate::program::rewrite::rewrite;
use crate::program::{ModalState, PoseStart, Units, WordRef};
use nalgebra::Vector3;
use pipeline::{Format, Stage, Whole};
use std::io::{BufRead, Write};

mod cl;
mod cl_motion;
pub use cl::{convert_cl, post_cl};

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

/// Emits the machine's axis words for one converted block.
struct AxisWriter<'m> {
    machine: &'m Machine,
    decimals: Vec<usize>,
    /// `10^decimals` of each axis.
    scales: Vec<f64>,
    /// The last block's words (output order, file units), for modal output
    /// and G91; empty before the first.
    last: Vec<AxisValue>,
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
        let decimals: Vec<usize> = machine
            .axes
            .iter()
            .map(|a| decimals.unwrap_or(a.decimals) as usize)
            .collect();
        let scales = decimals.iter().map(|&d| 10f64.powi(d as i32)).collect();
        AxisWriter {
            machine,
            decimals,
            scales,
            last: Vec::with_capacity(machine.axes.len()),
            next: Vec::with_capacity(machine.axes.len()),
            text: Vec::with_capacity(128),
            scratch: String::new(),
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
        for (axis, s) in self.machine.axes.iter().zip(&self.scales) {
            let v = crate::machine::output_value(axis, q[axis.joint]);
            // (v / 1 is v: millimetre programs skip the division.)
            let raw = if axis.kind == crate::machine::JointKind::Prismatic && per_unit != 1.0 {
                v / per_unit
            } else {
                v
            };
            next.push(AxisValue {
                raw,
                scaled: scaled_integer(raw * s),
            });
        }
        let out = &mut self.text;
        out.clear();
        for (k, axis) in self.machine.axes.iter().enumerate() {
            let (value, scale) = (next[k], self.scales[k]);
            let previous = self.last.get(k).copied();
            if modal && previous.is_some_and(|p| p.same_as(value, scale)) {
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
            let d = self.decimals[k];
            match (absolute, value.scaled, previous) {
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
        Ok(&self.text)
    }
}

/// [`push_fixed`] onto bytes, through the reused `scratch`.
fn push_fixed_bytes(out: &mut Vec<u8>, scratch: &mut String, value: f64, decimals: usize) {
    scratch.clear();
    push_fixed(scratch, value, decimals);
    out.extend_from_slice(scratch.as_bytes());
}

/// A converted pose block.
#[derive(Debug, Clone)]
pub struct Converted {
    /// Joint values (chain order, mm / rad).
    pub q: crate::machine::chain::JointValues,
    /// What the block meant (modal state, items).
    pub meaning: crate::program::BlockMeaning,
}

/// Converts G-code line by line: the per-line core of `post` and
/// `compensate`, reused by `linkage` on pose programs.
pub struct GcodeConverter<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    modal: ModalState,
    /// The modal state with the block-delete switch on, where it differs.
    switch: crate::program::block_delete_switch::BlockDeleteSwitch,
    /// Plain tool length compensation (`G43 Hn`) the program switched on.
    length_comp: crate::program::length_comp::LengthCompensation,
    /// The chain ends at a tool's tip (the machine's or a job tool's
    /// length): the axis words of a pose include the tool.
    tool_in_chain: bool,
    writer: AxisWriter<'a>,
    /// The joint values the program continues from: those of the last
    /// pose begun (as the first pass solved it: `post`'s solution,
    /// `compensate`'s theoretical one; [`GcodeConverter::begun`]) or of the
    /// machine position followed since.
    previous: Option<crate::machine::chain::JointValues>,
    /// Machine axis positions (output order, mm / deg) followed through
    /// blocks in machine coordinates (pose mode off); unknown axes are 0.
    machine_ext: Vec<f64>,
    /// `machine_ext` is that of `previous` (a pose block came since it was
    /// last followed) and is recomputed before use.
    machine_ext_stale: bool,
    /// The allocation of the vector of a block's words, kept from block to
    /// block (empty between blocks).
    words: Vec<WordRef<'static>>,
    /// The feed mode written (`--feed inverse-time`).
    pub feed: crate::program::inverse_time::InverseTime,
    /// What has been done so far.
    pub stats: PostStats,
}

impl<'a> GcodeConverter<'a> {
    /// A converter for `machine`. It does not solve poses: a driver solves
    /// each pose [`GcodeConverter::begin`] gives and hands the joint values
    /// to [`GcodeConverter::finish`] ([`GcodeConverter::convert`] does both
    /// with a [`PoseSolver`]).
    pub fn new(machine: &'a Machine, opts: &'a PostOptions) -> Self {
        GcodeConverter {
            machine,
            opts,
            modal: ModalState::new(opts.pose_start),
            switch: crate::program::block_delete_switch::BlockDeleteSwitch::new(opts.inverse_time),
            length_comp: Default::default(),
            tool_in_chain: machine.tool_length_mm != 0.0
                || opts
                    .tool_machines
                    .iter()
                    .any(|(_, m)| m.tool_length_mm != 0.0),
            writer: AxisWriter::new(machine, opts.decimals),
            previous: None,
            machine_ext: vec![0.0; machine.axes.len()],
            machine_ext_stale: false,
            words: Vec::with_capacity(16),
            feed: Default::default(),
            stats: PostStats::default(),
        }
    }

    /// Converts one line with `solver`, appending the bytes to write to
    /// `out`; returns the joint values when the line was a pose.
    pub fn convert(
        &mut self,
        line: &Line,
        solver: &mut dyn PoseSolver,
        out: &mut Vec<u8>,
    ) -> Result<Option<Converted>> {
        let Some(pending) = self.begin(line, out)? else {
            return Ok(None);
        };
        let solved = solver
            .solve(&pending.pose, self.previous.as_deref(), line.number)
            .map_err(|m| self.solve_error(line, &pending, m))?;
        self.begun(&solved.q);
        self.finish(line, &pending, &solved, out)?;
        Ok(Some(Converted {
            q: solved.q,
            meaning: pending.meaning,
        }))
    }

    /// First half of [`GcodeConverter::convert`]: the modal state and the
    /// pose. A line that is not a pose is written to `out` and `None`
    /// returned; a pose is returned for solving.
    pub fn begin(&mut self, line: &Line, out: &mut Vec<u8>) -> Result<Option<PendingPose>> {
        let opts = self.opts;
        self.stats.lines += 1;
        let loc = |item: Option<usize>| {
            let col = item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Location::new(&opts.file_name, line.number, col)
        };
        crate::program::integrity::check_line(line, &opts.file_name, self.modal.pose_mode)?;
        let mut words = recycle(std::mem::take(&mut self.words));
        let mut keywords = Vec::new();
        for (i, item) in line.items.iter().enumerate() {
            match &item.kind {
                ItemKind::Word(w) => words.push(WordRef {
                    address: w.address.as_str(),
                    value: w.value,
                    item: i,
                }),
                ItemKind::Keyword(k) => keywords.push((i, k.as_str())),
                // Block delete reaches the modal state as a pseudo-keyword.
                ItemKind::BlockDelete => keywords.push((i, "/")),
                ItemKind::Opaque => {
                    if let Some(k) = crate::program::opaque::known_call(&String::from_utf8_lossy(
                        line.item_bytes(item),
                    )) {
                        keywords.push((i, k));
                    }
                }
                _ => {}
            }
        }
        let opaque_error = |i: usize| {
            Error::input_with(
                loc(Some(i)),
                crate::program::opaque::describe_opaque(line.item_bytes(&line.items[i])),
                String::from_utf8_lossy(&line.bytes),
            )
        };
        // Only G codes of a plain move (no cycle, no non-modal code): the
        // blocks whose unreadable text may still be a tool vector.
        let plain_move = words.iter().all(|w| {
            w.address != "G"
                || [
                    0.0, 1.0, 17.0, 18.0, 19.0, 20.0, 21.0, 40.0, 49.0, 90.0, 91.0, 93.0, 94.0,
                ]
                .contains(&w.value)
        });
        let has_words = !words.is_empty() || !keywords.is_empty();
        let start_tip = self.modal.tip;
        let applied = self.switch.apply(&mut self.modal, &words, &keywords, line);
        self.length_comp.block(&words, line);
        self.words = recycle(words);
        let meaning = applied.map_err(|e| match e {
            crate::program::block_delete_switch::Refused::Slash { at, message } => {
                Error::input_with(
                    Location::new(&opts.file_name, at.line, at.col),
                    message,
                    at.text,
                )
            }
            // Text not understood in the block explains the failure best.
            crate::program::block_delete_switch::Refused::Block(e) => {
                match opaque_in_pose_block(line, true, true, true) {
                    Some(i) => opaque_error(i),
                    None => Error::input_with(
                        loc(e.item),
                        e.message,
                        String::from_utf8_lossy(&line.bytes),
                    ),
                }
            }
        })?;
        for w in &meaning.warnings {
            self.stats
                .warnings
                .push(format!("{}: {w}", loc(meaning.pose_items.first().copied())));
        }
        self.stats.max_vector_deviation = self
            .stats
            .max_vector_deviation
            .max(meaning.vector_deviation);
        let straight = plain_move && matches!(meaning.motion, Motion::Rapid | Motion::Linear);
        if let Some(i) =
            opaque_in_pose_block(line, self.modal.pose_mode, meaning.pose.is_some(), straight)
        {
            return Err(opaque_error(i));
        }
        let Some((tip, axis)) = meaning.pose else {
            let text = String::from_utf8_lossy(&line.bytes);
            let unended = !line.bytes.ends_with(b"\n")
                && !text.trim().is_empty()
                && !crate::program::integrity::ends_program(line);
            if unended {
                self.stats.warnings.push(format!(
                    "{}: the file ends without a line end after `{}`: a truncated file? (passed on unchanged)",
                    Location::new(&opts.file_name, line.number, 1),
                    crate::error::visible(text.trim())
                ));
            }
            if !self.modal.pose_mode {
                self.follow_machine_words(line, &meaning);
            }
            let crlf = line.bytes.ends_with(b"\r\n");
            if let (true, Some(s)) = (
                opts.inverse_time,
                self.feed.before_other(has_words, meaning.feed, crlf),
            ) {
                out.extend_from_slice(s.as_bytes());
            }
            if meaning.tcp_codes.is_empty() {
                out.extend_from_slice(&line.bytes);
            } else {
                rewrite(
                    line,
                    &[],
                    b"",
                    &meaning.tcp_codes,
                    &meaning.tcp_offset_items,
                    out,
                );
            }
            return Ok(None);
        };
        // Only the last line of a file can lack its line end. A pose block
        // there may have been cut mid-number (`X12.3` of `X12.345`).
        if !line.bytes.ends_with(b"\n") {
            return Err(Error::input_with(
                Location::new(&opts.file_name, line.number, line.bytes.len() + 1),
                "the file ends inside this pose block, without a line end: a truncated file? A block cut short would put the tool elsewhere; if the program is complete, end it with a line break (and M30)",
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        // The chain ends at the tool's tip: a G43 of the program's own
        // would add the tool's length to axis words that include it.
        if self.tool_in_chain
            && let Some(at) = self.length_comp.on()
        {
            return Err(Error::input_with(
                Location::new(&opts.file_name, at.line, at.col),
                format!(
                    "tool length compensation (G43/G43.1/G44) is on while the pose at line {} is converted, and the machine's chain ends at the tool's tip (--tool-length, --tool-table or the machine file's tool_length): the axis words include the tool, and the controller would add its length again; switch it off (G49) before the poses, or start them with G43.4 (written as G49)",
                    line.number
                ),
                at.text.clone(),
            ));
        }
        Ok(Some(PendingPose {
            pose: Pose::new(tip, axis),
            from: self.previous.clone(),
            start_tip: match start_tip {
                [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
                _ => None,
            },
            meaning,
        }))
    }

    /// The error of a failed solve of `pending` (programmed at `line`).
    pub fn solve_error(&self, line: &Line, pending: &PendingPose, message: String) -> Error {
        let col = pending
            .meaning
            .pose_items
            .first()
            .map(|&i| line.items[i].start + 1)
            .unwrap_or(0);
        Error::input_with(
            Location::new(&self.opts.file_name, line.number, col),
            message,
            String::from_utf8_lossy(&line.bytes),
        )
    }

    /// Second half of [`GcodeConverter::convert`]: writes the pose block
    /// with the machine axes of `solved`.
    pub fn finish(
        &mut self,
        line: &Line,
        pending: &PendingPose,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let opts = self.opts;
        let meaning = &pending.meaning;
        let loc = |item: Option<usize>| {
            let col = item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Location::new(&opts.file_name, line.number, col)
        };
        if solved.axis_miss_rad > opts.axis_tolerance_rad {
            return Err(Error::input_with(
                loc(meaning.pose_items.first().copied()),
                unreachable_axis(
                    &self.machine.name,
                    solved.axis_miss_rad,
                    opts.axis_tolerance_rad,
                ),
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        self.stats.max_axis_miss_rad = self.stats.max_axis_miss_rad.max(solved.axis_miss_rad);
        self.stats.poses += 1;
        let sep = separator(line, &meaning.pose_items);
        let words_text = self
            .writer
            .words(
                &solved.q,
                meaning.units,
                meaning.absolute,
                opts.modal_axes,
                sep,
            )
            .map_err(|m| Error::input(loc(meaning.pose_items.first().copied()), m))?;
        let feed = opts.inverse_time.then(|| {
            let moved = pending.from.as_ref().is_some_and(|p| {
                self.machine
                    .chain
                    .joints()
                    .iter()
                    .zip(p.iter().zip(&solved.q))
                    .any(|(j, (a, b))| {
                        j.kind == crate::machine::JointKind::Revolute && (a - b).abs() > 1e-12
                    })
            });
            let tip = pending.pose.tip;
            self.feed.pose_block(meaning, pending.start_tip, tip, moved)
        });
        if let Some(crate::program::inverse_time::PoseFeed::Append(extra)) = feed {
            let mut drop = meaning.tcp_offset_items.clone();
            drop.extend(
                line.items
                    .iter()
                    .enumerate()
                    .filter_map(|(i, it)| match &it.kind {
                        ItemKind::Word(w) if w.address == "F" => Some(i),
                        ItemKind::Word(w)
                            if w.address == "G" && [93.0, 94.0].contains(&w.value) =>
                        {
                            Some(i)
                        }
                        _ => None,
                    }),
            );
            let mut words = words_text.to_vec();
            words.extend_from_slice(extra.as_bytes());
            rewrite(
                line,
                &meaning.pose_items,
                &words,
                &meaning.tcp_codes,
                &drop,
                out,
            );
        } else {
            rewrite(
                line,
                &meaning.pose_items,
                words_text,
                &meaning.tcp_codes,
                &meaning.tcp_offset_items,
                out,
            );
        }
        if matches!(meaning.motion, Motion::Linear | Motion::Rapid)
            && let Some(prev) = &pending.from
            && let Some(w) = crate::machine::midblock::branch_change_warning(
                self.machine_at(line.number),
                prev,
                &solved.q,
                &pending.pose,
            )
        {
            self.stats
                .warnings
                .push(format!("{}: {w}", loc(meaning.pose_items.first().copied())));
        }
        Ok(())
    }

    /// The pose last begun was solved to `q` in the first pass (`post`'s
    /// solution, `compensate`'s theoretical one): the blocks after it
    /// continue from there. Called between [`GcodeConverter::begin`] and the
    /// next `begin`; [`GcodeConverter::finish`] may come later (under
    /// `compensate` a chunk's poses are written after the next chunk is
    /// begun), so nothing `begin` reads depends on it.
    pub fn begun(&mut self, q: &[f64]) {
        self.previous = Some(q.iter().copied().collect());
        // `machine_ext` follows from `previous` when next needed.
        self.machine_ext_stale = true;
    }
}

impl GcodeConverter<'_> {
    /// The machine in force at `line` (the tool of that part of the job).
    fn machine_at(&self, line: usize) -> &Machine {
        let tools = &self.opts.tool_machines;
        match tools.iter().rposition(|(from, _)| *from <= line) {
            Some(k) => &tools[k].1,
            None => tools.first().map_or(self.machine, |t| &t.1),
        }
    }

    /// A block in machine coordinates (pose mode off): follow its axis words
    /// and tell the modal state where the tool tip now is, so that a pose
    /// block after `G43.4`/`TRAORI` that gives only some coordinates
    /// continues from the machine's position.
    fn follow_machine_words(&mut self, line: &Line, meaning: &crate::program::BlockMeaning) {
        if meaning.non_modal {
            let g = |v: f64| {
                line.words()
                    .any(|w| w.address == "G" && (w.value - v).abs() < 1e-9)
            };
            if [28.0, 30.0, 53.0, 92.1, 92.2, 92.3].into_iter().any(g) {
                // Home, machine coordinates, offsets reset: where the tool
                // is in program coordinates is no longer known, so the
                // next pose must give X, Y and Z.
                self.modal.tip = [None; 3];
            }
            if !g(92.0) {
                // `G10 L2 P1 X100`, `G52 X5`, `G68 X10 Y10 R30`, `G111 X0
                // Y0`: data, not a position. `G92 X100` says where the tool
                // is now, and is followed.
                return;
            }
        }
        if std::mem::take(&mut self.machine_ext_stale)
            && let Some(q) = &self.previous
        {
            for (e, axis) in self.machine_ext.iter_mut().zip(&self.machine.axes) {
                *e = crate::machine::output_value(axis, q.get(axis.joint).copied().unwrap_or(0.0));
            }
        }
        let mut moved = false;
        let mut given = 0usize;
        for w in line.words() {
            if let Some(k) = self.machine.axes.iter().position(|a| a.name == w.address) {
                given |= 1 << k;
                let scale = if self.machine.axes[k].kind == crate::machine::JointKind::Prismatic {
                    meaning.units.mm_per_unit()
                } else {
                    1.0
                };
                let v = w.value * scale;
                self.machine_ext[k] = if meaning.absolute {
                    v
                } else {
                    self.machine_ext[k] + v
                };
                moved = true;
            }
        }
        if moved {
            let slash = line
                .items
                .iter()
                .position(|i| matches!(i.kind, ItemKind::BlockDelete));
            let whole = meaning.absolute && given.count_ones() as usize == self.machine.axes.len();
            self.switch.followed_move(&self.modal, line, slash, whole);
            let q = self.machine.to_internal(&self.machine_ext);
            let pose = self
                .machine_at(line.number)
                .chain
                .pose(&q, &crate::machine::NoErrors);
            self.modal.seed_from_machine(pose.tip, pose.axis);
            self.previous = Some(q);
        }
    }
}

/// A pose block between [`GcodeConverter::begin`] and
/// [`GcodeConverter::finish`].
#[derive(Debug, Clone)]
pub struct PendingPose {
    /// The tool pose to solve.
    pub pose: Pose,
    /// The joint values the block starts from: the pose before's (as
    /// solved in the first pass) or the machine position followed since.
    pub from: Option<crate::machine::chain::JointValues>,
    /// The tool tip before the block, mm, when known.
    pub start_tip: Option<Vector3<f64>>,
    /// What the block means.
    pub meaning: crate::program::BlockMeaning,
}

/// Converts a G-code pose program, writing the machine program to `out`,
/// with `solver` solving each pose in order (a pool task), the lines
/// parsed on the pool ([`pipeline::drive`]).
pub fn post_gcode<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    solver: &mut (dyn PoseSolver + Send),
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    convert_gcode(
        machine,
        &mut Whole(solver),
        &|_, j| match *j {},
        |_| Ok(()),
        input,
        out,
        opts,
        progress,
    )
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
    let format = GcodeFormat {
        conv: GcodeConverter::new(machine, opts),
    };
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
/// [`GcodeConverter`].
struct GcodeFormat<'a> {
    conv: GcodeConverter<'a>,
}

impl Format for GcodeFormat<'_> {
    type Unit = GcodeUnit;
    type Pending = PendingPose;
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
        &mut self,
        unit: &mut GcodeUnit,
        out: &mut Vec<u8>,
        _: Option<&mut dyn PoseSolver>,
    ) -> Result<Option<PendingPose>> {
        self.conv.begin(&unit.line, out)
    }
    fn pose(pending: &PendingPose) -> &Pose {
        &pending.pose
    }
    fn previous(&self) -> Option<&[f64]> {
        self.conv.previous.as_deref()
    }
    fn begun(&mut self, q: &[f64]) {
        self.conv.begun(q);
    }
    fn solve_error(&self, unit: &GcodeUnit, pending: &PendingPose, message: String) -> Error {
        self.conv.solve_error(&unit.line, pending, message)
    }
    fn finish(
        &mut self,
        unit: &GcodeUnit,
        pending: &PendingPose,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        self.conv.finish(&unit.line, pending, solved, out)
    }
    fn end(&mut self, out: &mut Vec<u8>) {
        if let Some(end) = self.conv.feed.end() {
            out.extend_from_slice(end.as_bytes());
        }
    }
    fn stats(self) -> PostStats {
        self.conv.stats
    }
}

/// `v` emptied, keeping its allocation, as a vector whose elements borrow
/// for another lifetime: the words of each block borrow from that block's
/// line, and one allocation serves them all. (Collecting a vector's
/// `into_iter` into a vector of a type of the same size and alignment reuses
/// its buffer; the map never runs, `v` being empty.)
fn recycle<'x, 'y>(mut v: Vec<WordRef<'x>>) -> Vec<WordRef<'y>> {
    v.clear();
    v.into_iter()
        .map(|w| WordRef {
            address: "",
            value: w.value,
            item: w.item,
        })
        .collect()
}

/// The separator between words in this line's style: nothing when the first
/// replaced word is glued to the item before it (`G1X1Y2`), else a space.
fn separator(line: &Line, replace: &[usize]) -> &'static str {
    match replace.first() {
        Some(&i) if i > 0 && !matches!(line.items[i - 1].kind, ItemKind::Space) => "",
        _ => " ",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::TcpCode;

    #[test]
    fn recycle_keeps_the_allocation() {
        let text = String::from("X");
        let mut v = Vec::with_capacity(16);
        v.push(WordRef {
            address: text.as_str(),
            value: 1.0,
            item: 0,
        });
        let ptr = v.as_ptr() as usize;
        let r: Vec<WordRef<'static>> = recycle(v);
        assert!(r.is_empty());
        assert_eq!(r.capacity(), 16);
        assert_eq!(r.as_ptr() as usize, ptr);
    }

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
