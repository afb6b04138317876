//! APT CL in, G-code for the machine out: the statements read and lowered
//! in order ([`crate::cl`]), the moves converted through the driver
//! ([`super::pipeline::drive`]) like G-code.

use super::pipeline::{Format, Stage, Whole};
use super::{AxisWriter, PoseSolver, PostOptions, PostStats, SolvedPose, unreachable_axis};
use crate::cl::{ClReader, ClRecord, ClStatement, FeedUnit, SpindleDir};
use crate::error::{Error, Location, Result};
use crate::machine::{Machine, Pose};
use crate::program::Units;
use crate::program::format::push_fixed;
use nalgebra::Vector3;
use std::io::{BufRead, Write};

/// Converts APT CL data to a G-code program for `machine`, with `solver`
/// solving each pose in order.
///
/// Statements are translated: `GOTO` → `G0`/`G1` with the machine's axes,
/// `FEDRAT` → `F`, `RAPID` → `G0` for the next `GOTO`, `LOADTL` → `T.. M6`,
/// `SPINDL` → `S.. M3/M4/M5`, `COOLNT` → `M7/M8/M9`, `FINI` → `M30`,
/// `END` → `M2`, `$$` and `PARTNO` → comments. `CIRCLE`, `CYCLE`, `CSYS`,
/// `CUTCOM`, `LOAD/TOOL` and the other forms CAM systems write are lowered
/// first ([`crate::cl::lower`]); a statement that moves the tool and is not
/// converted is an error, any other statement is kept as a comment.
pub fn post_cl<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    solver: &mut (dyn PoseSolver + Send),
    input: R,
    out: &mut W,
    opts: &PostOptions,
    progress: impl FnMut(u64),
) -> Result<PostStats> {
    convert_cl(
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

/// Converts APT CL data as [`post_cl`] does, with `stage` doing each pose,
/// `work` on the stage's jobs in parallel and `after_chunk` after each
/// chunk is written ([`super::pipeline::drive`]). The statements are read
/// and lowered on this thread, the moves converted on the pool.
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
        machine,
        opts,
        stats: PostStats::default(),
        writer: AxisWriter::new(machine, opts.decimals),
        previous: None,
        axis: Vector3::z(),
        rapid_next: false,
        units: Units::Mm,
        feed: None,
        feed_written: None,
        motion_written: None,
    };
    let read = |unit: &mut Option<Result<ClRecord>>| -> Result<Option<usize>> {
        *unit = records.next();
        Ok(unit
            .as_ref()
            .map(|r| r.as_ref().map_or(0, |r| r.text.len())))
    };
    super::pipeline::drive(format, read, stage, work, after_chunk, out, progress)
}

/// A `GOTO` between [`Format::begin`] and [`Format::finish`], with the
/// modal state it was programmed in.
pub struct ClPending {
    pose: Pose,
    /// `RAPID` came before it.
    rapid: bool,
    /// The feed in force, mm/min.
    feed: Option<f64>,
}

/// APT CL as a [`Format`]: the lowered statements (read in order on the
/// driver's thread: the reader and the lowering keep state from statement
/// to statement), converted in order.
struct ClFormat<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    stats: PostStats,
    writer: AxisWriter<'a>,
    /// Joint values of the last `GOTO` written.
    previous: Option<crate::machine::chain::JointValues>,
    /// The tool axis in force.
    axis: Vector3<f64>,
    rapid_next: bool,
    units: Units,
    feed: Option<f64>,
    feed_written: Option<f64>,
    motion_written: Option<u8>,
}

/// Where a statement is and its text, for messages.
fn located(opts: &PostOptions, record: &ClRecord) -> (Location, String) {
    (
        Location::new(&opts.file_name, record.line, record.col),
        String::from_utf8_lossy(&record.text).trim().to_string(),
    )
}

/// The record of a unit that `begin` accepted.
fn record(unit: &Option<Result<ClRecord>>) -> &ClRecord {
    match unit {
        Some(Ok(r)) => r,
        _ => unreachable!("a pose comes from a statement read without error"),
    }
}

impl Format for ClFormat<'_> {
    type Unit = Option<Result<ClRecord>>;
    type Pending = ClPending;
    fn prepare(_: &mut Self::Unit) {}
    fn line(unit: &Self::Unit) -> usize {
        match unit {
            Some(Ok(r)) => r.line,
            _ => 0,
        }
    }
    fn begin(&mut self, unit: &mut Self::Unit, out: &mut Vec<u8>) -> Result<Option<ClPending>> {
        if let Some(Err(_)) = unit
            && let Some(Err(e)) = unit.take()
        {
            return Err(e);
        }
        let Some(Ok(record)) = unit.as_ref() else {
            unreachable!("the driver begins only statements it read")
        };
        let opts = self.opts;
        let stats = &mut self.stats;
        stats.lines += 1;
        // Writing to a vector cannot fail.
        let mut line = |s: std::fmt::Arguments| {
            let _ = out.write_fmt(s);
            out.push(b'\n');
        };
        match &record.statement {
            ClStatement::Goto { tip, axis: a } => {
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
                    let (loc, text) = located(opts, record);
                    return Err(Error::input_with(
                        loc,
                        format!(
                            "tool axis of length {norm:.6}, not 1 (tolerance {}): expected a unit vector",
                            crate::program::modal::TOOL_VECTOR_TOLERANCE
                        ),
                        text,
                    ));
                }
                stats.max_vector_deviation = stats.max_vector_deviation.max((norm - 1.0).abs());
                if (norm - 1.0).abs() > crate::program::modal::QUIET_NORMALISATION {
                    let (loc, _) = located(opts, record);
                    stats.warnings.push(format!(
                        "{loc}: tool axis of length {norm:.9} normalised to unit length"
                    ));
                }
                let rapid = std::mem::take(&mut self.rapid_next);
                return Ok(Some(ClPending {
                    pose: Pose::new(tip, self.axis / norm),
                    rapid,
                    feed: self.feed,
                }));
            }
            ClStatement::Fedrat { value, unit } => {
                self.feed = Some(match unit {
                    FeedUnit::Ipm => value * 25.4,
                    FeedUnit::Unspecified => value * self.units.mm_per_unit(),
                    _ => *value,
                });
                if matches!(unit, FeedUnit::Mmpr | FeedUnit::Ipr) {
                    line(format_args!(
                        "({})",
                        sanitize_comment(&located(opts, record).1)
                    ));
                }
            }
            ClStatement::Rapid => self.rapid_next = true,
            ClStatement::TlAxis(a) => self.axis = Vector3::new(a[0], a[1], a[2]),
            ClStatement::LoadTl(n) => line(format_args!("T{n} M6")),
            ClStatement::Spindle { rpm, dir, off } => {
                if *off {
                    line(format_args!("M5"));
                } else {
                    let m = match dir {
                        Some(SpindleDir::CounterClockwise) => "M4",
                        _ => "M3",
                    };
                    match rpm {
                        Some(s) => line(format_args!(
                            "S{} {m}",
                            crate::program::format::fixed(*s, 0)
                        )),
                        None => line(format_args!("{m}")),
                    }
                }
            }
            ClStatement::Coolant(on) => line(format_args!("{}", if *on { "M8" } else { "M9" })),
            ClStatement::Units(u) => {
                self.units = match u {
                    crate::cl::ClUnits::Inches => Units::Inch,
                    crate::cl::ClUnits::Mm => Units::Mm,
                };
                line(format_args!(
                    "({})",
                    sanitize_comment(&located(opts, record).1)
                ));
            }
            ClStatement::Comment(c) => line(format_args!("({})", sanitize_comment(c.trim()))),
            ClStatement::End => {
                let t = located(opts, record).1.to_ascii_uppercase();
                line(format_args!(
                    "{}",
                    if t.starts_with("FINI") { "M30" } else { "M2" }
                ))
            }
            ClStatement::Multax(_) | ClStatement::Other { .. } => line(format_args!(
                "({})",
                sanitize_comment(&located(opts, record).1)
            )),
            ClStatement::Block(b) => line(format_args!("{b}")),
            ClStatement::Warning(w) => stats.warnings.push(w.clone()),
        }
        Ok(None)
    }
    fn pose(pending: &ClPending) -> &Pose {
        &pending.pose
    }
    fn previous(&self) -> Option<&[f64]> {
        self.previous.as_deref()
    }
    fn solve_error(&self, unit: &Self::Unit, _: &ClPending, message: String) -> Error {
        let (loc, text) = located(self.opts, record(unit));
        Error::input_with(loc, message, text)
    }
    fn finish(
        &mut self,
        unit: &Self::Unit,
        pending: &ClPending,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let opts = self.opts;
        let record = record(unit);
        if solved.axis_miss_rad > opts.axis_tolerance_rad {
            let (loc, text) = located(opts, record);
            return Err(Error::input_with(
                loc,
                unreachable_axis(
                    &self.machine.name,
                    solved.axis_miss_rad,
                    opts.axis_tolerance_rad,
                ),
                text,
            ));
        }
        let stats = &mut self.stats;
        stats.max_axis_miss_rad = stats.max_axis_miss_rad.max(solved.axis_miss_rad);
        stats.poses += 1;
        if let Some(prev) = &self.previous
            && let Some(w) = crate::machine::midblock::branch_change_warning(
                self.machine,
                prev,
                &solved.q,
                &pending.pose,
            )
        {
            let (loc, _) = located(opts, record);
            stats.warnings.push(format!("{loc}: {w}"));
        }
        let words = self
            .writer
            .words(&solved.q, Units::Mm, true, opts.modal_axes, " ")
            .map_err(|m| Error::input(located(opts, record).0, m))?;
        let motion = if pending.rapid { 0 } else { 1 };
        let mut block = String::new();
        if self.motion_written != Some(motion) {
            block.push_str(if motion == 0 { "G0 " } else { "G1 " });
            self.motion_written = Some(motion);
        }
        // Axis names and digits: ASCII.
        block.push_str(std::str::from_utf8(words).unwrap_or_default());
        if motion == 1 && pending.feed.is_some() && pending.feed != self.feed_written {
            block.push_str(" F");
            push_fixed(&mut block, pending.feed.unwrap_or(0.0), 1);
            self.feed_written = pending.feed;
        }
        out.extend_from_slice(block.trim_end().as_bytes());
        out.push(b'\n');
        self.previous = Some(solved.q.clone());
        Ok(())
    }
    fn end(&mut self, _: &mut Vec<u8>) {}
    fn stats(self) -> PostStats {
        self.stats
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
