//! `kinpost simulate` and `kinpost diagnose`: recordings, and the missing
//! physics found in them.

use super::{MachineChoice, PoseStartArg};
use crate::diagnose::feedback::recording::{write_feedback_header, write_feedback_row};
use crate::diagnose::feedback::{FeedbackRow, FeedbackSimulator};
use crate::diagnose::recording::RecordingCsv;
use crate::diagnose::simulate::TipSimulator;
use crate::diagnose::simulate::path_corners;
use crate::diagnose::{
    DiagOptions, Recording, Sample, SimOptions, Waypoint, WaypointPath, diagnose as run_diagnose,
    parse_effect_spec,
};
use crate::error::{Error, Location, Result};
use crate::input;
use crate::machine::{JointKind, Machine};
use crate::output::write_atomically;
use crate::program::PoseStart;
use crate::trajectory::{TrajectoryOptions, joint_trajectory};
use clap::Args;
use std::io::Write;
use std::path::PathBuf;

/// `kinpost simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub machine: MachineChoice,
    #[command(flatten)]
    pub job: super::JobArgs,
    /// Known geometric errors of the machine (model JSON or error table CSV).
    ///
    /// A table is fitted once: its fitted model is kept in a cache
    /// (KINPOST_CACHE_DIR, else $XDG_CACHE_HOME/kinpost or ~/.cache/kinpost)
    /// and read back by later runs with the same table bytes, with the same
    /// result; KINPOST_CACHE_DIR=off disables it.
    #[arg(long, short = 'e', value_name = "MODEL|TABLE.csv")]
    pub errors: Option<PathBuf>,
    /// Program to run: tool poses (G-code or APT CL) or machine axes.
    #[arg(long, short = 'p', value_name = "PROGRAM")]
    pub program: PathBuf,
    /// APT CL: units of a program without `UNITS` (default: mm, with a
    /// warning).
    #[arg(long, value_enum)]
    pub units: Option<super::UnitsArg>,
    /// Effect to inject, e.g. `backlash:X=0.003`, `servo_lag:X=0.02`,
    /// `thermal_drift:Z=0.01,tau=600`, `scale:X=50`, `squareness:XZ=20`,
    /// `cyclic:X=0.002,period=20,phase=0`, `zero_offset:Z=0.005`,
    /// `rotary_center_offset:C=0.002,0.001,0`, `pivot_length:0.01`; append
    /// `@block=N` to start it at line N. Repeat for several effects.
    #[arg(long, value_name = "SPEC")]
    pub inject: Vec<String>,
    /// Measurement noise, standard deviation per measured coordinate, in mm.
    #[arg(long, value_name = "MM", default_value_t = 0.001)]
    pub noise: f64,
    /// Seed of the noise (an integer, no unit; the same seed gives the same
    /// recording).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Time between samples, in s.
    #[arg(long, value_name = "S", default_value_t = 0.1)]
    pub sample_interval: f64,
    /// Acceleration limit along the path, in mm/s² (0: constant feed per block).
    #[arg(long, value_name = "MM/S2", default_value_t = 200.0)]
    pub accel: f64,
    /// Clock offset of the recording, in s: the sample stamped t shows the
    /// machine at t − offset (formats.md §2c; `diagnose` names it
    /// `time_offset`).
    #[arg(
        long,
        value_name = "S",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub time_offset: f64,
    /// Fraction of samples (a count per sample, no unit; 0 … 0.5) with a
    /// gross measurement fault of 0.1 … 1 mm (a broken laser beam;
    /// `diagnose` names them `outliers`).
    #[arg(long, value_name = "FRACTION", default_value_t = 0.0)]
    pub outliers: f64,
    /// Registration of the measuring system, in mm: every measured tip is
    /// this far off in the workpiece frame (a tracker or probe zeroed
    /// off; `diagnose` names it `registration`). Three numbers `DX,DY,DZ`.
    #[arg(
        long,
        value_name = "DX,DY,DZ",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub registration: Vec<f64>,
    /// Round every written value to a multiple of this step, in mm (axes
    /// in mm or deg, as an export with few decimals does). 0: no rounding.
    #[arg(long, value_name = "STEP", default_value_t = 0.0)]
    pub round: f64,
    /// Write a joint-feedback trace (formats.md §2b: `t,block,<axes>,fb_<axes>`)
    /// instead of a tool-tip recording: each axis's feedback is its command
    /// plus the injected joint-level effects and `--noise` (mm or deg).
    #[arg(long)]
    pub feedback: bool,
    /// Feed of rapid moves and of moves without a programmed feed, in mm/min.
    #[arg(long, value_name = "MM/MIN", default_value_t = 3000.0)]
    pub rapid_feed: f64,
    #[command(flatten)]
    pub axis_tolerance: super::AxisTolerance,
    /// When pose mode starts (pose programs).
    #[arg(long, value_enum, default_value = "tcp")]
    pub pose_start: PoseStartArg,
    /// Write the recording here (atomically). Default: standard output.
    #[arg(long, short = 'o', value_name = "REC.csv")]
    pub output: Option<PathBuf>,
}

/// Waypoints of a program: its commanded axes per block (joint order, mm/deg).
pub fn program_waypoints(
    machine: &Machine,
    path: &std::path::Path,
    start: PoseStart,
    cl_units: Option<crate::cl::ClUnits>,
    rapid_feed: f64,
    axis_tolerance_rad: f64,
    mut each: impl FnMut(&Waypoint) -> Result<()>,
) -> Result<usize> {
    let mut inp = input::open(Some(path))?;
    // A pose program whose TCP code comes after a long header is still
    // one (the recording reads its blocks in machine axes before it too).
    let head = input::peek_far(&mut *inp.reader)?;
    let name = inp.name.clone();
    let ext = |q: &[f64]| -> Vec<f64> {
        q.iter()
            .zip(machine.chain.joints())
            .map(|(v, j)| {
                if j.kind == JointKind::Revolute {
                    v.to_degrees()
                } else {
                    *v
                }
            })
            .collect()
    };
    // Whether a straight move from `a` to `b` (mm, deg) turns rotaries
    // alone.
    let rotaries_alone = |a: &[f64], b: &[f64], path: &WaypointPath| {
        matches!(path, WaypointPath::Straight)
            && machine
                .chain
                .joints()
                .iter()
                .zip(a.iter().zip(b))
                .all(|(j, (x, y))| j.kind == JointKind::Revolute || x == y)
    };
    // The last waypoint (a G93 block's feed needs the path from it), and
    // how many there were.
    let mut last: Option<Waypoint> = None;
    let mut count = 0usize;
    let mut unknown = LineList::default();
    let mut no_feed = LineList::default();
    let opts = TrajectoryOptions {
        start,
        axis_tolerance_rad,
        arc_points: true,
        as_poses: false,
        cl_units,
    };
    joint_trajectory(machine, &mut inp.reader, &head, &name, opts, |b| {
        // After a move whose path is not known the recording goes on
        // from the next block's end (said on standard error).
        let path = if b.restart && last.is_some() {
            unknown.push(b.line);
            WaypointPath::Unknown
        } else if b.via.is_empty() {
            WaypointPath::Straight
        } else {
            WaypointPath::Through(b.via.iter().map(|q| ext(q)).collect())
        };
        let q = ext(&b.q);
        let feed = match (b.rapid, b.inverse_time, last.as_ref()) {
            (true, _, _) => rapid_feed,
            // G93: the block takes 1/F minutes, so it runs at the feed
            // that covers its path (1° counted as 1 mm) in that time.
            (false, Some(f), Some(before)) => {
                if !(f.is_finite() && f > 0.0) {
                    return Err(Error::input(
                        Location::new(&name, b.line, 1),
                        format!(
                            "inverse-time feed F{f} (G93): expected a positive number of moves per minute"
                        ),
                    ));
                }
                let (_, at) = path_corners(&machine.chain, &before.q, &path, &q);
                let length = at[at.len() - 1];
                if length > 0.0 { length * f } else { rapid_feed }
            }
            // A move of rotaries alone runs at F degrees a minute, also
            // where F is inches a minute for the linear axes.
            (false, _, Some(before))
                if b.feed_mm_min.is_some() && rotaries_alone(&before.q, &q, &path) =>
            {
                b.feed_mm_min.unwrap_or(rapid_feed) / b.feed_unit_mm
            }
            (false, _, before) => b.feed_mm_min.unwrap_or_else(|| {
                // No feed per minute (none given, or per revolution
                // without a spindle speed): said on standard error.
                if before.is_some() {
                    no_feed.push(b.line);
                }
                rapid_feed
            }),
        };
        let w = Waypoint {
            q,
            feed,
            block: b.line as u64,
            path,
        };
        each(&w)?;
        count += 1;
        last = Some(w);
        Ok(())
    })?;
    if count < 2 {
        // Named at the one position, or at the start of a program with none.
        let (line, what) = match &last {
            Some(w) => (
                w.block as usize,
                "this is the program's only position: a recording needs two or more to move between",
            ),
            None => (
                1,
                "the program has no position to move between: no block in it moves the machine",
            ),
        };
        return Err(Error::input(Location::new(&name, line, 1), what));
    }
    if !no_feed.is_empty() {
        eprintln!(
            "warning: {name}: {} block(s) move without a feed per minute (no F, or F per revolution without a known spindle speed: line {}): they run at --rapid-feed {rapid_feed} mm/min",
            no_feed.count, no_feed
        );
    }
    if !unknown.is_empty() {
        eprintln!(
            "warning: {name}: {} block(s) start where the program does not say (after G28, G30, G53, G92 or a canned cycle; line {}): the recording leaves out the move before each and goes on from the block's end",
            unknown.count, unknown
        );
    }
    Ok(count)
}

/// Lines a warning names: how many, and the first five (a program's
/// length of them is not kept).
#[derive(Default)]
struct LineList {
    count: usize,
    first: Vec<usize>,
}

impl LineList {
    fn push(&mut self, line: usize) {
        self.count += 1;
        if self.first.len() < 5 {
            self.first.push(line);
        }
    }

    fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// The first five lines, and an ellipsis for more: "3, 8, …".
impl std::fmt::Display for LineList {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let shown: Vec<String> = self.first.iter().map(|l| l.to_string()).collect();
        let more = if self.count > 5 { ", …" } else { "" };
        write!(f, "{}{more}", shown.join(", "))
    }
}

/// A number as a person would type it: plain where that is short,
/// in exponent form for the very large and the very small.
fn shown(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// A numeric option's range check: `ok`, or a usage error naming the
/// option, its value as typed and what was expected.
fn check(ok: bool, option: &str, value: f64, expected: &str) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::Usage(format!(
            "{option} {}: {expected}",
            shown(value)
        )))
    }
}

/// Refuses an injected effect that would never act, or a clock offset
/// that leaves nothing of the program in the recording: an effect's
/// `@block=N` beyond `last_block`, the program's last block that moves,
/// and a `time_offset` (s) of `span` (s, the recording's length) or more,
/// where every sample would show the machine before its start or after
/// its end.
fn check_reach(
    effects: &[crate::geometric::effects::EffectSpec],
    last_block: u64,
    time_offset: f64,
    span: f64,
) -> Result<()> {
    if let Some(n) = effects
        .iter()
        .filter_map(|e| e.from_block)
        .find(|&n| n > last_block)
    {
        return Err(Error::Usage(format!(
            "--inject …@block={n}: the program's last move is at block {last_block}, so the effect would never act; expected a block of the program"
        )));
    }
    if time_offset != 0.0 && time_offset.abs() >= span {
        return Err(Error::Usage(format!(
            "--time-offset {}: the recording lasts {} s, and every sample would show the machine before the program starts or after it ends; expected an offset shorter than the recording",
            shown(time_offset),
            crate::numeric::readable(span)
        )));
    }
    Ok(())
}

/// Runs `kinpost simulate`.
pub fn simulate(a: SimulateArgs) -> Result<()> {
    super::check_outputs(
        &[("-o", a.output.as_deref())],
        &[
            a.errors.as_deref(),
            Some(&a.program),
            a.machine.file(),
            a.job.inputs(),
        ],
    )?;
    let base = a.machine.load()?;
    // Ranges a real machine and a real recorder can have: a value outside
    // them is a typo, and would give no samples or infinite values.
    check(
        (1e-6..=3600.0).contains(&a.sample_interval),
        "--sample-interval",
        a.sample_interval,
        "expected 1e-6 … 3600 s (a recorder samples at most at 1 MHz)",
    )?;
    check(
        a.rapid_feed > 0.0 && a.rapid_feed <= 1e6,
        "--rapid-feed",
        a.rapid_feed,
        "expected more than 0 and at most 1e6 mm/min",
    )?;
    check(
        (0.0..=10.0).contains(&a.noise),
        "--noise",
        a.noise,
        "expected a standard deviation of 0 … 10 mm",
    )?;
    check(
        a.accel == 0.0 || (1.0..=1e6).contains(&a.accel),
        "--accel",
        a.accel,
        "expected 0 (constant feed per block) or an acceleration of 1 … 1e6 mm/s²",
    )?;
    check(
        a.time_offset.is_finite() && a.time_offset.abs() <= 3600.0,
        "--time-offset",
        a.time_offset,
        "expected −3600 … 3600 s",
    )?;
    check(
        (0.0..=0.5).contains(&a.outliers),
        "--outliers",
        a.outliers,
        "expected a fraction of 0 … 0.5",
    )?;
    let bad_registration = a
        .registration
        .iter()
        .copied()
        .find(|v| !(v.is_finite() && v.abs() <= 10.0));
    if !(a.registration.is_empty() || a.registration.len() == 3) {
        return Err(Error::Usage(format!(
            "--registration: expected three offsets DX,DY,DZ in mm, found {}",
            a.registration.len()
        )));
    }
    check(
        bad_registration.is_none(),
        "--registration",
        bad_registration.unwrap_or(0.0),
        "expected three offsets of −10 … 10 mm",
    )?;
    check(
        a.round == 0.0 || (1e-9..=10.0).contains(&a.round),
        "--round",
        a.round,
        "expected 0 (no rounding) or a step of 1e-9 … 10 mm",
    )?;
    let model = match &a.errors {
        Some(p) => Some(super::errors::load_errors(p)?),
        None => None,
    };
    if let Some(m) = &model {
        a.job.check_model(m)?;
    }
    // A tool table reads the program for the tool it selects.
    let mut program = match &a.job.tool_table {
        Some(_) => Some(input::open(Some(&a.program))?),
        None => None,
    };
    let machine = a.job.machine(&base, program.as_mut())?;
    let effects = a
        .inject
        .iter()
        .map(|s| parse_effect_spec(s))
        .collect::<Result<Vec<_>>>()
        // A bad --inject is a bad command line (exit 2), not bad input.
        .map_err(|e| Error::Usage(e.to_string()))?;
    let start = match a.pose_start {
        PoseStartArg::On => PoseStart::On,
        PoseStartArg::Tcp => PoseStart::Off,
    };
    // The program is read while the recording is written: what an effect's
    // `@block=` and the clock offset need of it (its last block, its
    // length) is checked once it is read, and the recording is then
    // dropped unwritten (`check_reach`).
    // The program's blocks and the last block that moves.
    let read_program = |each: &mut dyn FnMut(&Waypoint) -> Result<()>| {
        let mut last_block = 0u64;
        let blocks = program_waypoints(
            &machine,
            &a.program,
            start,
            super::cl_units(a.units),
            a.rapid_feed,
            a.axis_tolerance.rad()?,
            &mut |wp: &Waypoint| {
                last_block = last_block.max(wp.block);
                each(wp)
            },
        )?;
        Ok::<_, Error>((blocks, last_block))
    };
    let axes = machine.chain.names();
    let io = |e| Error::io("<output>", e);
    // The recording is written as the program is read: memory holds a
    // few blocks, not the program.
    let opts = SimOptions {
        noise_mm: a.noise,
        seed: a.seed,
        sample_interval_s: a.sample_interval,
        accel_mm_s2: (a.accel > 0.0).then_some(a.accel),
        time_offset_s: a.time_offset,
        outlier_fraction: a.outliers,
        quantum: a.round,
        registration_mm: match a.registration[..] {
            [x, y, z] => [x, y, z],
            _ => [0.0; 3],
        },
    };
    if a.feedback {
        let fopts = crate::diagnose::feedback::FeedbackSimOptions::from(&opts);
        let mut sim = FeedbackSimulator::new(&machine.chain, &effects, &fopts)?;
        let (n, blocks) = write_atomically(a.output.as_deref(), |w| {
            write_feedback_header(w, &axes).map_err(io)?;
            let mut sink = |r: FeedbackRow| {
                write_feedback_row(&mut *w, r.t, r.block, &r.cmd, &r.fb).map_err(io)
            };
            let mut span = 0.0f64;
            let mut sink = |r: FeedbackRow| {
                span = span.max(r.t.abs());
                sink(r)
            };
            let (blocks, last_block) = read_program(&mut |wp| sim.push(wp, &mut sink))?;
            let n = sim.finish(&mut sink)?;
            check_reach(&effects, last_block, a.time_offset, span)?;
            Ok((n, blocks))
        })?;
        if crate::output::standard_output_closed() {
            return Ok(());
        }
        eprintln!(
            "kinpost simulate: joint-feedback trace of {n} samples from {blocks} blocks of {}, noise σ = {} (mm or deg), {} effect(s) injected",
            a.program.display(),
            crate::numeric::readable(a.noise),
            effects.len()
        );
        return Ok(());
    }
    let mut sim = TipSimulator::new(&machine.chain, model.as_ref(), &effects, &opts)?;
    let (n, last_t, blocks) = write_atomically(a.output.as_deref(), |w| {
        let csv = RecordingCsv::tool_tip(&axes);
        csv.write_header(&mut *w).map_err(io)?;
        let mut last_t = 0.0;
        let mut sink = |s: Sample| {
            last_t = s.t;
            csv.write_sample(&mut *w, &s).map_err(io)
        };
        let (blocks, last_block) = read_program(&mut |wp| sim.push(wp, &mut sink))?;
        let n = sim.finish(&mut sink)?;
        check_reach(&effects, last_block, a.time_offset, last_t)?;
        Ok((n, last_t, blocks))
    })?;
    if crate::output::standard_output_closed() {
        return Ok(());
    }
    eprintln!(
        "kinpost simulate: {n} samples over {last_t:.1} s from {blocks} blocks of {}, noise σ = {} µm, {} effect(s) injected",
        a.program.display(),
        crate::numeric::readable(a.noise * 1e3),
        effects.len()
    );
    Ok(())
}

/// `kinpost diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    #[command(flatten)]
    pub machine: MachineChoice,
    #[command(flatten)]
    pub job: super::JobArgs,
    /// Known geometric errors of the machine (model JSON or error table CSV).
    ///
    /// A table is fitted once: its fitted model is kept in a cache
    /// (KINPOST_CACHE_DIR, else $XDG_CACHE_HOME/kinpost or ~/.cache/kinpost)
    /// and read back by later runs with the same table bytes, with the same
    /// result; KINPOST_CACHE_DIR=off disables it.
    #[arg(long, short = 'e', value_name = "MODEL|TABLE.csv")]
    pub errors: Option<PathBuf>,
    /// The recording (formats.md §2): commanded axes and measured tool tip.
    #[arg(long, short = 'r', value_name = "REC.csv")]
    pub recording: PathBuf,
    /// Print the report as JSON (formats.md §3).
    #[arg(long)]
    pub json: bool,
    /// Plot the residual before and after (SVG).
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Write the improved model (error model + effects found) here.
    #[arg(long, value_name = "MODEL.json")]
    pub write_model: Option<PathBuf>,
    /// Largest number of effects to report (a count, no unit).
    #[arg(long, value_name = "N", default_value_t = 4)]
    pub max_effects: usize,
    /// Noise floor per measured coordinate, in mm (default: estimated robustly).
    #[arg(long, value_name = "MM")]
    pub noise_floor: Option<f64>,
    /// Sample rate of a joint-feedback trace without a `t` column, in Hz
    /// (formats.md §2b; e.g. 1000 for a LinuxCNC halsampler trace of a
    /// 1 ms servo thread).
    #[arg(long, value_name = "HZ")]
    pub sample_rate: Option<f64>,
}

/// Runs `kinpost diagnose`.
pub fn diagnose(a: DiagnoseArgs) -> Result<()> {
    super::check_outputs(
        &[
            ("--svg", a.svg.as_deref()),
            ("--write-model", a.write_model.as_deref()),
        ],
        &[
            a.errors.as_deref(),
            Some(&a.recording),
            a.machine.file(),
            a.job.inputs(),
        ],
    )?;
    // The recording's tool tip is that of the job: the same set-up as the
    // program it recorded (a tool table needs that program: refused here).
    let machine = a.job.machine(&a.machine.load()?, None)?;
    let model = match &a.errors {
        Some(p) => Some(super::errors::load_errors(p)?),
        None => None,
    };
    if let Some(m) = &model {
        a.job.check_model(m)?;
    }
    if a.noise_floor
        .is_some_and(|nf| !(nf.is_finite() && nf > 0.0 && nf <= 10.0))
    {
        return Err(Error::Usage(
            "--noise-floor must be above 0 and at most 10 mm".into(),
        ));
    }
    let axes = machine.chain.names();
    // A drive trace is sampled at a few Hz or faster (a servo thread at
    // 1 kHz, a slow logger at a few Hz); a rate far below that stretches the
    // trace's time, and a lag read on it becomes a backlash or an offset.
    if a.sample_rate
        .is_some_and(|r| !(r.is_finite() && (0.1..=1e7).contains(&r)))
    {
        return Err(Error::Usage(
            "--sample-rate must be 0.1 … 1e7 Hz (a joint-feedback trace's samples per second)"
                .into(),
        ));
    }
    let rec_name = a.recording.display().to_string();
    if is_feedback_file(&a.recording)? {
        return diagnose_feedback_file(&a, &machine, model.as_ref(), &axes);
    }
    let rec = Recording::load(&a.recording, &axes)?;
    // Problems found after reading name the recording, not a placeholder.
    let named = |e: Error| match e {
        Error::Input {
            mut loc,
            message,
            snippet,
        } if loc.file == "<recording>" => {
            loc.file = rec_name.clone();
            Error::Input {
                loc,
                message,
                snippet,
            }
        }
        e => e,
    };
    let opts = DiagOptions {
        max_effects: a.max_effects,
        noise_floor_mm: a.noise_floor,
        ..DiagOptions::default()
    };
    let spinner = crate::progress::Spinner::start(&format!(
        "diagnose: {} samples of {rec_name}",
        rec.samples.len()
    ));
    let report = run_diagnose(&machine.chain, model.as_ref(), &rec, &opts).map_err(named)?;
    drop(spinner);
    if let Some(svg) = &a.svg {
        let text = report.to_svg()?;
        write_atomically(Some(svg), |w| {
            w.write_all(text.as_bytes())
                .map_err(|e| Error::io(svg.display().to_string(), e))
        })?;
    }
    if let Some(out) = &a.write_model {
        let improved = report.improved_model(model.as_ref());
        let text = serde_json::to_string_pretty(&improved.to_json()).unwrap_or_default();
        write_atomically(Some(out), |w| {
            w.write_all(text.as_bytes())
                .and_then(|_| w.write_all(b"\n"))
                .map_err(|e| Error::io(out.display().to_string(), e))
        })?;
    }
    let mut o = std::io::stdout().lock();
    let text = if a.json {
        report.to_json_string()
    } else {
        report.to_text()
    };
    writeln!(o, "{}", text.trim_end()).map_err(|e| Error::io("<stdout>", e))
}

/// Whether the recording at `path` is a joint-feedback trace (formats.md
/// §2b): its header has an `fb_` column and no `meas_x`.
fn is_feedback_file(path: &std::path::Path) -> Result<bool> {
    let name = path.display().to_string();
    crate::text::check_not_dir(path)?;
    let f = std::fs::File::open(path).map_err(|e| Error::io(name.clone(), e))?;
    Ok(
        crate::diagnose::feedback::header_line(std::io::BufReader::new(f), &name)
            .is_some_and(|h| crate::diagnose::feedback::is_feedback_header(&h)),
    )
}

/// `kinpost diagnose` on a joint-feedback trace.
fn diagnose_feedback_file(
    a: &DiagnoseArgs,
    machine: &crate::machine::Machine,
    model: Option<&crate::geometric::ErrorModel>,
    axes: &[String],
) -> Result<()> {
    use crate::diagnose::feedback::{FeedbackRecording, diagnose_feedback};
    let name = a.recording.display().to_string();
    let rotary: Vec<bool> = machine
        .chain
        .joints()
        .iter()
        .map(|j| j.kind == crate::machine::chain::JointKind::Revolute)
        .collect();
    let f = std::fs::File::open(&a.recording).map_err(|e| Error::io(name.clone(), e))?;
    let rec = FeedbackRecording::read(
        std::io::BufReader::new(f),
        &name,
        axes,
        &rotary,
        a.sample_rate,
    )?;
    let opts = DiagOptions {
        max_effects: a.max_effects,
        noise_floor_mm: a.noise_floor,
        ..DiagOptions::default()
    };
    let report = diagnose_feedback(&rec, &opts).map_err(|e| match e {
        Error::Input {
            mut loc,
            message,
            snippet,
        } if loc.file == "<recording>" => {
            loc.file = name.clone();
            Error::Input {
                loc,
                message,
                snippet,
            }
        }
        e => e,
    })?;
    if let Some(svg) = &a.svg {
        write_feedback_plot(svg, &report)?;
    }
    if let Some(out) = &a.write_model {
        let improved = report.improved_model(model);
        let text = serde_json::to_string_pretty(&improved.to_json()).unwrap_or_default();
        write_atomically(Some(out), |w| {
            w.write_all(text.as_bytes())
                .and_then(|_| w.write_all(b"\n"))
                .map_err(|e| Error::io(out.display().to_string(), e))
        })?;
    }
    let mut o = std::io::stdout().lock();
    let text = if a.json {
        report.to_json_string()
    } else {
        report.to_text()
    };
    writeln!(o, "{}", text.trim_end()).map_err(|e| Error::io("<stdout>", e))
}

/// The plot of a joint-feedback diagnosis: one panel per axis, `fb −
/// command` against time before the fit and what the fit leaves (µm on a
/// linear axis, arcsec on a rotary one).
fn write_feedback_plot(
    path: &std::path::Path,
    report: &crate::diagnose::feedback::FeedbackReport,
) -> Result<()> {
    use crate::report::svg::{Panel, write_panels};
    let labels: Vec<String> = report
        .axes
        .iter()
        .map(|ax| {
            let unit = if ax.unit == "deg" { "arcsec" } else { "µm" };
            format!("{} fb − command [{unit}]", ax.axis)
        })
        .collect();
    let panels: Vec<Panel<'_>> = report
        .axes
        .iter()
        .zip(&labels)
        .map(|(ax, label)| {
            let k = if ax.unit == "deg" { 3600.0 } else { 1e3 };
            let pick = |f: fn(&(f64, f64, f64)) -> f64| {
                ax.series
                    .iter()
                    .map(|p| (p.0, f(p) * k))
                    .collect::<Vec<_>>()
            };
            Panel {
                y_label: label,
                series: vec![
                    ("before the fit", pick(|p| p.1)),
                    ("after the fit", pick(|p| p.2)),
                ],
            }
        })
        .collect();
    write_panels(
        path,
        "kinpost diagnose: joint feedback against command",
        "time t [s]",
        &panels,
    )
}
