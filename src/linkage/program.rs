//! `kinpost linkage`: rewrite a program so that no block moves more than
//! `max_axes` axes, with the exact nonlinear error of every segment bounded.
//!
//! Input in machine axes passes through line by line; input in tool poses is
//! converted first (the same converter as `post`). A `G1` block that moves
//! more axes than allowed, or whose nonlinear error exceeds the tolerance, is
//! preceded by inserted blocks (marked `(kinpost linkage i/n)`) and keeps its
//! own line, N number and comments; its axis words are rewritten to the axes
//! that still move. Its other words that act where it starts (modal codes,
//! `S`, `T`, M codes other than stops) move to the first inserted block, a
//! block delete goes on every inserted block (`linkage::carry`).
//!
//! Feeds: in `G94` the feed carries over (the inserted blocks repeat an `F`
//! the block sets); in `G93` every inserted block gets `F = n·F₀` so each of
//! the `n` segments takes `1/n` of the original block's time and the original
//! segment keeps its time (tool tips are evenly spaced along the line). A
//! `G94` block that turns rotaries alone (F in degrees a minute) whose
//! segments move linear axes gets per-segment feeds that keep its time,
//! and the programmed feed is set again after it.

use super::carry::share_out;
use super::nonlinear::nonlinear_error;
use super::plan::{Pattern, RotaryPair, insert_points, worst_segment};
use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, Line, LineReader, parse_line};
use crate::machine::rotary::{unwind_near, unwind_near_degrees, wrap_degrees};
use crate::machine::{IkSolver, JointKind, Machine, NoErrors, RotaryMode};
use crate::post::{GcodeConverter, PostOptions, Start, rewrite};
use crate::program::format::push_fixed;
use crate::program::source::MachineAxisTracker;
use crate::program::{FeedMode, Motion, PoseStart, Units};
use std::io::{BufRead, Write};

mod report;
pub use report::LinkageReport;

/// How blocks are divided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// Seed 003: a fixed number of inserted points (even; 2 is the paper's).
    Insert(usize),
    /// The fewest points such that every segment's exact nonlinear error is
    /// within this many mm.
    Tolerance(f64),
}

/// Options of `kinpost linkage`.
#[derive(Debug, Clone)]
pub struct LinkageOptions {
    /// Division mode.
    pub mode: Mode,
    /// Largest number of axes a block may move (4: four-axis linkage; 5: plain linearisation).
    pub max_axes: usize,
    /// Decimals overriding the machine file.
    pub decimals: Option<u32>,
    /// Which rotary is split and which held (default: split the one nearer the workpiece).
    pub pair: Option<RotaryPair>,
    /// Input file name for messages.
    pub file_name: String,
    /// Pose input: when pose mode starts.
    pub pose_start: PoseStart,
    /// Pose input: accepted tool-axis miss, rad.
    pub axis_tolerance_rad: f64,
    /// Largest number of points inserted into one block before giving up.
    pub max_points: usize,
}

impl Default for LinkageOptions {
    fn default() -> Self {
        LinkageOptions {
            mode: Mode::Tolerance(0.001),
            max_axes: 4,
            decimals: None,
            pair: None,
            file_name: "<stdin>".into(),
            pose_start: PoseStart::On,
            axis_tolerance_rad: 1e-4,
            max_points: 2000,
        }
    }
}

/// Formatting and counting of machine axis values.
struct Axes<'m> {
    machine: &'m Machine,
    /// Decimals of each axis in a millimetre program (0) and in an inch
    /// program (1).
    decimals: [Vec<usize>; 2],
}

/// Lever arm assumed when turning a rotary's rounding into a tool-tip
/// error, mm (a generous machine size).
const ROUNDING_LEVER_MM: f64 = 1000.0;

/// Share of the tolerance that rounding one axis word may take.
const ROUNDING_SHARE: f64 = 0.05;

/// Share of the tolerance the planner aims for, leaving room for rounding
/// the output (five axes at `ROUNDING_SHARE` each, root-sum-square).
pub const PLANNING_SHARE: f64 = 0.85;

/// Decimals needed so that rounding an axis word moves the tool tip by at
/// most 5 % of `tol_mm` (rotaries: at a 1000 mm lever).
pub fn decimals_for_tolerance(kind: JointKind, tol_mm: f64) -> u32 {
    let step = match kind {
        JointKind::Prismatic => 2.0 * tol_mm * ROUNDING_SHARE,
        JointKind::Revolute => (2.0 * tol_mm * ROUNDING_SHARE / ROUNDING_LEVER_MM).to_degrees(),
    };
    (-step.log10()).ceil().clamp(0.0, 12.0) as u32
}

impl<'m> Axes<'m> {
    /// The decimals of each axis: `decimals` (`--decimals`) where given,
    /// else the machine's ([`crate::post::written_decimals`]: one more for
    /// a linear axis in inch), raised where `tolerance` needs more (in the
    /// program's unit).
    fn new(machine: &'m Machine, decimals: Option<u32>, tolerance: Option<f64>) -> Self {
        let per_units = [Units::Mm, Units::Inch].map(|units| {
            (machine.axes.iter())
                .map(|a| {
                    let d = crate::post::written_decimals(a, decimals, units);
                    let per_unit = match a.kind {
                        JointKind::Prismatic => units.mm_per_unit(),
                        JointKind::Revolute => 1.0,
                    };
                    match (decimals, tolerance) {
                        (None, Some(t)) => {
                            d.max(decimals_for_tolerance(a.kind, t / per_unit)) as usize
                        }
                        _ => d as usize,
                    }
                })
                .collect()
        });
        Axes {
            machine,
            decimals: per_units,
        }
    }

    /// The decimals of each axis in a program in `units`.
    fn decimals(&self, units: Units) -> &[usize] {
        &self.decimals[usize::from(units == Units::Inch)]
    }

    /// The decimals of each axis in a program in `units`, by axis name.
    fn named_decimals(&self, units: Units) -> Vec<(String, u32)> {
        (self.machine.axes.iter())
            .zip(self.decimals(units))
            .map(|(a, d)| (a.name.clone(), *d as u32))
            .collect()
    }

    /// External values rounded to the written precision (output order).
    fn rounded(&self, q: &[f64], units: Units) -> Vec<f64> {
        let ext = self.machine.to_external(q);
        ext.iter()
            .zip(&self.machine.axes)
            .zip(self.decimals(units))
            .map(|((v, a), d)| {
                let v = if a.kind == JointKind::Prismatic {
                    v / units.mm_per_unit()
                } else {
                    *v
                };
                let s = 10f64.powi(*d as i32);
                let r = (v * s).round() / s;
                // A modulo axis is written in [0, 360): the controller turns
                // it the short way.
                if a.rotary == RotaryMode::Modulo {
                    let w = (wrap_degrees(r) * s).round() / s;
                    if w >= 360.0 { 0.0 } else { w }
                } else {
                    r
                }
            })
            .collect()
    }

    /// What a `G94` feed applies to from `a` to `b` as written (program
    /// units): the linear axes' path, or where no linear axis moves the
    /// largest rotary turn (deg, a modulo axis the short way); and whether
    /// a linear axis moves.
    fn written_feed_distance(&self, a: &[f64], b: &[f64], units: Units) -> (f64, bool) {
        let (ra, rb) = (self.rounded(a, units), self.rounded(b, units));
        let steps = self.machine.axes.iter().enumerate().map(|(k, axis)| {
            let d = match (axis.kind, axis.rotary) {
                (JointKind::Revolute, RotaryMode::Modulo) => {
                    unwind_near_degrees(rb[k], ra[k]) - ra[k]
                }
                _ => rb[k] - ra[k],
            };
            (axis.kind, d)
        });
        g94_path(steps, 0.0)
    }

    /// Number of axes the machine has.
    fn count(&self) -> usize {
        self.machine.axes.len()
    }

    fn moved(&self, a: &[f64], b: &[f64]) -> usize {
        let ra = self.rounded(a, Units::Mm);
        let rb = self.rounded(b, Units::Mm);
        ra.iter().zip(&rb).filter(|(x, y)| x != y).count()
    }

    /// Axis words for the axes that differ between `from` and `to`; `Err`
    /// where a wrapped rotary would turn a full turn or more.
    fn words(
        &self,
        from: &[f64],
        to: &[f64],
        units: Units,
        absolute: bool,
    ) -> std::result::Result<String, String> {
        let rf = self.rounded(from, units);
        let rt = self.rounded(to, units);
        let mut s = String::new();
        for (k, a) in self.machine.axes.iter().enumerate() {
            if rf[k] == rt[k] {
                continue;
            }
            if !s.is_empty() {
                s.push(' ');
            }
            s.push_str(&a.name);
            let v = match (absolute, a.rotary) {
                // LinuxCNC's wrapped rotary: the position in [0, 360) with
                // the sign of the turn (`machine::wrapped`).
                (true, RotaryMode::Wrapped) => {
                    let scale = 10f64.powi(self.decimals(units)[k] as i32);
                    let int = |v: f64| (v * scale).round() as i64;
                    let (negative, m) = crate::machine::wrapped::wrapped_word(
                        Some(int(rf[k])),
                        int(rt[k]),
                        int(360.0),
                    )
                    .map_err(|m| format!("axis {}: {m}", a.name))?;
                    if negative {
                        s.push('-');
                    }
                    m as f64 / scale
                }
                (true, _) => rt[k],
                // The short way, as the controller turns a modulo axis.
                (false, RotaryMode::Modulo) => unwind_near_degrees(rt[k], rf[k]) - rf[k],
                (false, _) => rt[k] - rf[k],
            };
            push_fixed(&mut s, v, self.decimals(units)[k]);
        }
        Ok(s)
    }
}

/// Time of one move at the programmed feed, min: `G94` F applies to the
/// linear axes' path (to the rotary's degrees when only rotaries move);
/// `G93` gives the time directly.
fn move_minutes(machine: &Machine, qa: &[f64], qb: &[f64], feed: &FeedState) -> f64 {
    match feed.mode {
        FeedMode::InverseTime => feed.value.map(|f| 1.0 / f).unwrap_or(0.0),
        FeedMode::PerRevolution => 0.0,
        FeedMode::PerMinute => match feed.value {
            Some(f) if f > 0.0 => match feed_distance(machine, qa, qb) {
                (mm, true) => mm / (f * feed.mm_per_unit),
                (deg, false) => deg / f,
            },
            _ => 0.0,
        },
    }
}

/// What a `G94` feed applies to from `qa` to `qb`: the linear axes' path
/// (mm), or where no linear axis moves the largest rotary turn (deg); and
/// whether a linear axis moves.
fn feed_distance(machine: &Machine, qa: &[f64], qb: &[f64]) -> (f64, bool) {
    let ea = machine.to_external(qa);
    let eb = machine.to_external(qb);
    let steps = (machine.axes.iter().enumerate()).map(|(k, a)| (a.kind, eb[k] - ea[k]));
    g94_path(steps, 1e-18)
}

/// The path a `G94` feed applies to over the axes' `steps` (kind, change):
/// the linear axes' path where its square is above `floor`, else the
/// largest rotary turn; and whether it is the linear path.
fn g94_path(steps: impl Iterator<Item = (JointKind, f64)>, floor: f64) -> (f64, bool) {
    let (mut lin, mut rot) = (0.0f64, 0.0f64);
    for (kind, d) in steps {
        match kind {
            JointKind::Prismatic => lin += d * d,
            JointKind::Revolute => rot = rot.max(d.abs()),
        }
    }
    if lin > floor {
        (lin.sqrt(), true)
    } else {
        (rot, false)
    }
}

#[derive(Debug, Clone, Copy)]
struct FeedState {
    mode: FeedMode,
    /// F as programmed: feed units a minute (deg a minute where only
    /// rotaries move), or 1/min in G93.
    value: Option<f64>,
    /// Millimetres per unit of the feed's length (25.4 in G20).
    mm_per_unit: f64,
}

/// Lines converted, unwound and measured a batch at a time.
const LINES_PER_BATCH: usize = 512;

/// A line after the in-order conversion.
enum Unit {
    /// Converted text written as it is (a block outside pose mode).
    Raw(Vec<u8>),
    /// A line written as it is (no block).
    Line(Line),
    /// A block, measured and perhaps divided before it is written.
    Block(Box<Pending>),
}

/// A block between the conversion and the writing.
struct Pending {
    mline: Line,
    block: Block,
    /// Where the block starts (none for the first block).
    qa: Option<Vec<f64>>,
    /// Whether the block before it may be skipped (block delete).
    start_skippable: bool,
}

/// A block's exact nonlinear error, its division (the inserted points, or
/// why it cannot be divided) and the largest error of its segments once
/// divided.
type Measured = (
    super::nonlinear::NonlinearError,
    std::result::Result<Option<Vec<Vec<f64>>>, String>,
    Option<f64>,
);

/// One motion block as the linkage stage sees it.
struct Block {
    q: Vec<f64>,
    motion: Motion,
    units: Units,
    /// Units of its feed (Sinumerik `G70`/`G71`: not those of the lengths).
    feed_units: Units,
    absolute: bool,
    feed: FeedState,
    feed_item: Option<usize>,
    /// Items of the machine-axis words in the (converted) line.
    axis_items: Vec<usize>,
    /// Whether the block can be measured and divided: the program's
    /// coordinates give where it starts (not after G28, G30, G53 until the
    /// axes they moved are programmed again), or no rotary axis turns
    /// (`MachineBlock::measurable`).
    measurable: bool,
}

/// Items of machine-axis words in a line.
fn axis_items(machine: &Machine, line: &Line) -> Vec<usize> {
    line.items
        .iter()
        .enumerate()
        .filter_map(|(i, it)| match &it.kind {
            ItemKind::Word(w) if machine.axes.iter().any(|a| a.name == w.address) => Some(i),
            _ => None,
        })
        .collect()
}

/// Rewrites a program for `machine` (in machine axes, or in tool poses when
/// `poses`), writing it to `out`.
pub fn linkage<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    input: R,
    out: &mut W,
    opts: &LinkageOptions,
    poses: bool,
) -> Result<LinkageReport> {
    let io = |e: std::io::Error| Error::io("<output>", e);
    let tolerance = match opts.mode {
        Mode::Tolerance(t) => Some(t),
        Mode::Insert(_) => None,
    };
    // The machine as written: decimals raised where the tolerance needs them.
    let axes = Axes::new(machine, opts.decimals, tolerance);
    let mut written = machine.clone();
    for (a, d) in written.axes.iter_mut().zip(axes.decimals(Units::Mm)) {
        a.decimals = *d as u32;
    }
    let machine = &written;
    let pair = opts
        .pair
        .or_else(|| RotaryPair::default_for(&machine.chain));
    let mut report = LinkageReport {
        machine: machine.name.clone(),
        ..Default::default()
    };
    report.decimals = axes.named_decimals(Units::Mm);
    let post_opts = PostOptions {
        decimals: opts.decimals,
        pose_start: opts.pose_start,
        axis_tolerance_rad: opts.axis_tolerance_rad,
        modal_axes: true,
        file_name: opts.file_name.clone(),
        ..PostOptions::default()
    };
    let mut ik = IkSolver::new(machine);
    let mut conv = poses.then(|| GcodeConverter::new(machine, &post_opts));
    let mut tracker = MachineAxisTracker::new(machine);
    let mut prev: Option<Vec<f64>> = None;
    // Whether the block that gave `prev` may be skipped (block delete).
    let mut prev_skippable = false;
    // A pose program: a move home or a new origin since the last pose, so
    // where the next one starts is not known.
    let mut start_unknown = false;
    let mut lines_in = 0usize;
    let mut buf = Vec::with_capacity(256);
    let mut text = Vec::with_capacity(256);
    // In order: each line converted and its block unwound against the one
    // before (stage 1); the blocks to measure measured on every core
    // (stage 2, the bulk of the work); then in order again, the report
    // and the output (stage 3), a batch of lines at a time.
    let mut read = |line: Line| -> Result<Unit> {
        // The line in machine axes and its block, if it moves.
        buf.clear();
        let (mline, block) = match conv.as_mut() {
            Some(c) => match c.convert(&line, &mut ik, &mut buf)? {
                Some(cv) => {
                    let ml = parse_line(&buf, line.number);
                    let items = axis_items(machine, &ml);
                    let feed_item = ml
                        .items
                        .iter()
                        .position(|it| matches!(&it.kind, ItemKind::Word(w) if w.address == "F"));
                    let b = Block {
                        q: cv.q.to_vec(),
                        motion: cv.meaning.motion,
                        units: cv.meaning.units,
                        feed_units: cv.meaning.feed_units,
                        absolute: cv.meaning.absolute,
                        feed: FeedState {
                            mode: cv.meaning.feed_mode,
                            value: cv.meaning.feed,
                            mm_per_unit: cv.meaning.feed_units.mm_per_unit(),
                        },
                        feed_item,
                        axis_items: items,
                        measurable: !std::mem::take(&mut start_unknown),
                    };
                    (ml, Some(b))
                }
                None => {
                    crate::program::unfollowed::check_line(
                        &line,
                        &opts.file_name,
                        c.reader.take_unfollowed(),
                    )?;
                    // A block in machine coordinates (pose mode off) moves
                    // where the next pose's segment starts.
                    match c.reader.start() {
                        Start::Followed => {
                            prev = c.reader.previous().map(<[f64]>::to_vec);
                            start_unknown = false;
                        }
                        Start::Unknown => start_unknown = true,
                        Start::AtPose => {}
                    }
                    return Ok(Unit::Raw(buf.clone()));
                }
            },
            None => {
                let b = tracker
                    .line(machine, &line, &opts.file_name)?
                    .map(|mb| Block {
                        q: mb.q,
                        motion: mb.meaning.motion,
                        units: mb.meaning.units,
                        feed_units: mb.meaning.feed_units,
                        absolute: mb.meaning.absolute,
                        feed: FeedState {
                            mode: mb.meaning.feed_mode,
                            value: mb.meaning.feed,
                            mm_per_unit: mb.meaning.feed_units.mm_per_unit(),
                        },
                        feed_item: mb.meaning.feed_item,
                        axis_items: mb.axis_items,
                        measurable: mb.measurable,
                    });
                (line, b)
            }
        };
        let Some(block) = block else {
            return Ok(Unit::Line(mline));
        };
        // A modulo axis turns the short way (the controller's rule, and the
        // way its words are written): the segment is measured and divided
        // on that path, not across the 0/360° seam.
        let mut block = block;
        if let Some(qa) = &prev {
            for a in &machine.axes {
                if a.rotary == RotaryMode::Modulo {
                    let k = a.joint;
                    block.q[k] = unwind_near(block.q[k], qa[k]);
                }
            }
        }
        let skippable = mline
            .items
            .iter()
            .any(|it| matches!(it.kind, ItemKind::BlockDelete));
        let start_skippable = std::mem::replace(&mut prev_skippable, skippable);
        let qa = prev.replace(block.q.clone());
        Ok(Unit::Block(Box::new(Pending {
            mline,
            block,
            qa,
            start_skippable,
        })))
    };
    let measure = |u: &Unit| -> Option<Measured> {
        let Unit::Block(b) = u else { return None };
        let (qa, qb) = (b.qa.as_ref()?, &b.block.q);
        if b.block.motion != Motion::Linear || !b.block.measurable {
            return None;
        }
        let before = nonlinear_error(&machine.chain, &NoErrors, qa, qb);
        let moved = axes.moved(qa, qb);
        let plan = plan_block(machine, &axes, qa, qb, moved, before.max_mm, opts, pair);
        let worst = match &plan {
            Ok(Some(points)) => {
                Some(worst_segment(&machine.chain, &NoErrors, qa, points, qb).max_mm)
            }
            _ => None,
        };
        Some((before, plan, worst))
    };
    let mut any_inch = false;
    let mut write = |u: Unit, measured: Option<Measured>| -> Result<()> {
        let Pending {
            mline,
            block,
            qa,
            start_skippable,
        } = match u {
            Unit::Raw(bytes) => return out.write_all(&bytes).map_err(io),
            Unit::Line(line) => return line.write_to(&mut &mut *out).map_err(io),
            Unit::Block(b) => *b,
        };
        report.blocks_in += 1;
        any_inch |= block.units == Units::Inch;
        report.blocks_out += 1;
        let Some(qa) = qa else {
            return mline.write_to(&mut &mut *out).map_err(io);
        };
        let qb = &block.q;
        let moved = axes.moved(&qa, qb);
        report.max_axes_moved_before = report.max_axes_moved_before.max(moved);
        let time_before = match block.motion {
            Motion::Rapid => 0.0,
            _ => move_minutes(machine, &qa, qb, &block.feed),
        };
        report.cycle_time_before_s += 60.0 * time_before;
        if block.motion != Motion::Linear {
            report.max_axes_moved_after = report.max_axes_moved_after.max(moved);
            report.over_axes_before += usize::from(moved > opts.max_axes);
            report.over_axes_after += usize::from(moved > opts.max_axes);
            report.cycle_time_after_s += 60.0 * time_before;
            mline.write_to(&mut &mut *out).map_err(io)?;
            return Ok(());
        }
        if !block.measurable {
            return Err(Error::input_with(
                Location::new(&opts.file_name, mline.number, 1),
                "where this G1 block starts is not known in the program's coordinates (G28, G30 or G53 moved an axis to the reference point or in machine coordinates before it, an axis moved under a frame such as G68 or G254, or a canned cycle ended at a level of its own, and a rotary axis may turn in it): linkage cannot measure or divide it; program every axis moved there (a G0 to a known position) before it",
                mline.text_lossy(),
            ));
        }
        report.over_axes_before += usize::from(moved > opts.max_axes);
        let (before, plan, worst) = measured.expect("a measured block has its measurement");
        if before.max_mm > report.nonlinear_max_before_mm {
            report.nonlinear_max_before_mm = before.max_mm;
            report.nonlinear_max_before_line = line_number(&mline);
        }
        let plan = plan.map_err(|m| {
            Error::input_with(
                Location::new(&opts.file_name, mline.number, 1),
                m,
                mline.text_lossy(),
            )
        })?;
        let points = match plan {
            None => {
                report.max_axes_moved_after = report.max_axes_moved_after.max(moved);
                report.over_axes_after += usize::from(moved > opts.max_axes);
                note_after(&mut report, before.max_mm, &mline);
                report.cycle_time_after_s += 60.0 * time_before;
                mline.write_to(&mut &mut *out).map_err(io)?;
                return Ok(());
            }
            Some(p) => p,
        };
        // Divided: inserted blocks, then the original block's line. The
        // words that act where the block starts go to the first inserted
        // block, a block delete to all of them (`linkage::carry`).
        let at = |item: Option<usize>| {
            Location::new(
                &opts.file_name,
                mline.number,
                item.map(|i| mline.items[i].start + 1).unwrap_or(0),
            )
        };
        if start_skippable {
            return Err(Error::input_with(
                at(None),
                "this block must be divided, but the block before it may be skipped (block delete /): where this block starts depends on the switch, so its inserted points cannot be placed; take the / off, or program a position after it",
                mline.text_lossy(),
            ));
        }
        let carried = share_out(&mline, &block.axis_items, block.feed_item)
            .map_err(|(i, m)| Error::input_with(at(Some(i)), m, mline.text_lossy()))?;
        let segments = points.len() + 1;
        // A G94 block that turns rotaries alone runs at F degrees a minute;
        // where its segments move linear axes, F would be mm/min there and
        // the turn would run at another speed. Each segment then gets the
        // feed that keeps its share (1/n) of the block's time, and the
        // programmed feed is set again after the block.
        let ends: Vec<&[f64]> = std::iter::once(qa.as_slice())
            .chain(points.iter().map(|p| p.as_slice()))
            .chain(std::iter::once(qb.as_slice()))
            .collect();
        let block_minutes = move_minutes(machine, &qa, qb, &block.feed);
        // Each segment's path as written (program units: inch in G20), a
        // linear path in the feed's units (Sinumerik G70/G71: mm).
        let to_feed_units = block.units.mm_per_unit() / block.feed_units.mm_per_unit();
        let written: Vec<(f64, bool)> = ends
            .windows(2)
            .map(|w| axes.written_feed_distance(w[0], w[1], block.units))
            .map(|(d, linear)| (if linear { d * to_feed_units } else { d }, linear))
            .collect();
        let retimed: Option<Vec<f64>> = (block.feed.mode == FeedMode::PerMinute
            && block_minutes > 0.0
            && !feed_distance(machine, &qa, qb).1
            && written.iter().any(|w| w.1))
        .then(|| {
            written
                .iter()
                .map(|(d, _)| d * segments as f64 / block_minutes)
                .collect()
        });
        let retimed_text = |k: usize| {
            let mut t = String::from(" F");
            push_fixed(&mut t, retimed.as_ref().map_or(0.0, |f| f[k]), 4);
            t
        };
        // The feed of each segment: in G93 every one gets n·F₀.
        let segment_feed = match block.feed.mode {
            FeedMode::InverseTime => FeedState {
                value: block.feed.value.map(|f| f * segments as f64),
                ..block.feed
            },
            _ => block.feed,
        };
        report.blocks_split += 1;
        report.points_inserted += points.len();
        report.blocks_out += points.len();
        let worst = worst.expect("a divided block has its worst segment");
        note_after(&mut report, worst, &mline);
        let feed_text = |text: &mut String| {
            if let (FeedMode::InverseTime, Some(f)) = (block.feed.mode, block.feed.value) {
                text.push_str(" F");
                push_fixed(text, f * segments as f64, 4);
            }
        };
        let mut from = qa.clone();
        for (i, p) in points.iter().enumerate() {
            let mut s = String::new();
            if let Some(bd) = &carried.block_delete {
                s.push_str(&String::from_utf8_lossy(bd));
            }
            s.push_str("G1 ");
            if i == 0 {
                for &item in &carried.to_first {
                    s.push_str(&String::from_utf8_lossy(
                        mline.item_bytes(&mline.items[item]),
                    ));
                    s.push(' ');
                }
            }
            s.push_str(
                &axes
                    .words(&from, p, block.units, block.absolute)
                    .map_err(|m| Error::input_with(at(None), m, mline.text_lossy()))?,
            );
            if block.feed.mode == FeedMode::InverseTime {
                feed_text(&mut s);
            } else if retimed.is_some() {
                s.push_str(&retimed_text(i));
            } else if let (0, Some(item)) = (i, block.feed_item) {
                // The block sets a new feed: it applies from the first inserted block on.
                s.push(' ');
                s.push_str(&String::from_utf8_lossy(
                    mline.item_bytes(&mline.items[item]),
                ));
            }
            s.push_str(&format!(" (kinpost linkage {}/{})", i + 1, points.len()));
            s.push_str(eol(&mline));
            text.clear();
            text.extend_from_slice(s.as_bytes());
            out.write_all(&text).map_err(io)?;
            let m = axes.moved(&from, p);
            report.max_axes_moved_after = report.max_axes_moved_after.max(m);
            report.over_axes_after += usize::from(m > opts.max_axes);
            report.cycle_time_after_s += 60.0
                * match retimed {
                    Some(_) => block_minutes / segments as f64,
                    None => move_minutes(machine, &from, p, &segment_feed),
                };
            from = p.clone();
        }
        let m = axes.moved(&from, qb);
        report.max_axes_moved_after = report.max_axes_moved_after.max(m);
        report.over_axes_after += usize::from(m > opts.max_axes);
        report.cycle_time_after_s += 60.0
            * match retimed {
                Some(_) => block_minutes / segments as f64,
                None => move_minutes(machine, &from, qb, &segment_feed),
            };
        let mut words = axes
            .words(&from, qb, block.units, block.absolute)
            .map_err(|m| Error::input_with(at(None), m, mline.text_lossy()))?;
        let mut replace = block.axis_items.clone();
        if let (FeedMode::InverseTime, Some(item)) = (block.feed.mode, block.feed_item) {
            replace.push(item);
            replace.sort_unstable();
            let mut f = String::new();
            feed_text(&mut f);
            words.push_str(&f);
        } else if retimed.is_some() {
            if let Some(item) = block.feed_item {
                replace.push(item);
                replace.sort_unstable();
            }
            words.push_str(&retimed_text(segments - 1));
        }
        text.clear();
        rewrite(
            &mline,
            &replace,
            words.trim_start().as_bytes(),
            &[],
            &carried.to_first,
            &mut text,
        );
        out.write_all(&text).map_err(io)?;
        if let (Some(_), Some(f)) = (&retimed, block.feed.value) {
            let mut s = String::from("F");
            push_fixed(&mut s, f, 4);
            s.push_str(" (kinpost linkage: the programmed feed again)");
            s.push_str(eol(&mline));
            out.write_all(s.as_bytes()).map_err(io)?;
            report.blocks_out += 1;
        }
        Ok(())
    };
    let mut lines = LineReader::new(input);
    let mut batch: Vec<Unit> = Vec::with_capacity(LINES_PER_BATCH);
    loop {
        let mut stop = None;
        let mut ended = false;
        while batch.len() < LINES_PER_BATCH {
            let Some(line) = lines.next() else {
                ended = true;
                break;
            };
            lines_in += 1;
            match line
                .map_err(|e| Error::io(&opts.file_name, e))
                .and_then(&mut read)
            {
                Ok(u) => batch.push(u),
                Err(e) => {
                    stop = Some(e);
                    break;
                }
            }
        }
        let measured: Vec<Option<Measured>> = {
            use rayon::prelude::*;
            batch.par_iter().map(measure).collect()
        };
        for (u, m) in batch.drain(..).zip(measured) {
            write(u, m)?;
        }
        if let Some(e) = stop {
            return Err(e);
        }
        if ended {
            break;
        }
    }
    report.lines_in = lines_in;
    if any_inch {
        report.decimals_inch = axes.named_decimals(Units::Inch);
    }
    Ok(report)
}

fn line_number(line: &Line) -> usize {
    line.number
}

fn note_after(report: &mut LinkageReport, e: f64, line: &Line) {
    if e > report.nonlinear_max_after_mm {
        report.nonlinear_max_after_mm = e;
        report.nonlinear_max_after_line = line.number;
    }
}

fn eol(line: &Line) -> &'static str {
    if line.bytes.ends_with(b"\r\n") {
        "\r\n"
    } else {
        "\n"
    }
}

/// The inserted points for one block, or `None` when it stays as it is.
#[allow(clippy::too_many_arguments)]
fn plan_block(
    machine: &Machine,
    axes: &Axes<'_>,
    qa: &[f64],
    qb: &[f64],
    moved: usize,
    nonlinear: f64,
    opts: &LinkageOptions,
    pair: Option<RotaryPair>,
) -> std::result::Result<Option<Vec<Vec<f64>>>, String> {
    let chain = &machine.chain;
    let too_many = moved > opts.max_axes;
    let both_rotaries =
        pair.is_some_and(|p| qa[p.split] != qb[p.split] && qa[p.held] != qb[p.held]);
    if too_many && !both_rotaries {
        return Err(format!(
            "this block moves {moved} axes; only blocks that move both rotary axes can be divided into blocks of at most {} axes",
            opts.max_axes
        ));
    }
    let check = |pts: &[Vec<f64>]| -> std::result::Result<(), String> {
        let mut from = qa;
        for p in pts.iter().map(|v| v.as_slice()).chain(std::iter::once(qb)) {
            let m = axes.moved(from, p);
            if m > opts.max_axes {
                return Err(format!("an inserted segment still moves {m} axes"));
            }
            from = p;
        }
        Ok(())
    };
    match opts.mode {
        Mode::Insert(n) => {
            if !too_many {
                return Ok(None);
            }
            let pts = insert_points(
                chain,
                &NoErrors,
                qa,
                qb,
                Pattern::Staggered { m: (n / 2).max(1) },
                pair,
            )?;
            check(&pts)?;
            Ok(Some(pts))
        }
        Mode::Tolerance(tolerance) => {
            if !too_many && nonlinear <= tolerance {
                return Ok(None);
            }
            let tol = tolerance * PLANNING_SHARE;
            // Even division moves every axis in every segment once both
            // rotaries turn (the linear axes follow the swing), so a block
            // that turns both is staggered whenever that would be too many.
            let staggered = too_many || (both_rotaries && axes.count() > opts.max_axes);
            let pattern = |n: usize| {
                if staggered {
                    Pattern::Staggered { m: n }
                } else {
                    Pattern::Even { k: n + 1 }
                }
            };
            let eval = |n: usize| -> std::result::Result<(Vec<Vec<f64>>, f64), String> {
                let pts = insert_points(chain, &NoErrors, qa, qb, pattern(n), pair)?;
                let w = worst_segment(chain, &NoErrors, qa, &pts, qb).max_mm;
                Ok((pts, w))
            };
            let max_n = if staggered {
                opts.max_points / 2
            } else {
                opts.max_points
            };
            let (mut failing, mut n) = (0usize, 1usize);
            while n <= max_n {
                let (pts, w) = eval(n)?;
                if w <= tol {
                    // Fewest points: bisect between the last failing and this count.
                    let (mut lo, mut hi, mut best) = (failing, n, pts);
                    while hi - lo > 1 {
                        let mid = (lo + hi) / 2;
                        let (p, w) = eval(mid)?;
                        if w <= tol {
                            hi = mid;
                            best = p;
                        } else {
                            lo = mid;
                        }
                    }
                    check(&best)?;
                    return Ok(Some(best));
                }
                failing = n;
                n = next_count(n, w, tol).min(max_n.max(n + 1));
            }
            Err(format!(
                "more than {} inserted points would be needed to bring the nonlinear error within the tolerance {tolerance:e} mm (planned to {:.0} % of it)",
                opts.max_points,
                PLANNING_SHARE * 100.0
            ))
        }
    }
}

/// The next count to try after a failing one: the error falls roughly with
/// the square of the step, so jump to the predicted count (the bisection
/// afterwards finds the fewest).
fn next_count(n: usize, err: f64, tol: f64) -> usize {
    let predicted = (n as f64 * (err / tol).sqrt() * 1.05).ceil() as usize;
    predicted.max(n + 1)
}
