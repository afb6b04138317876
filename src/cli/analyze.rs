//! `kinpost analyze`: the influence of a machine's errors on a program
//! (seed 000's E and ε per block, and what each error term causes), and
//! the exact nonlinear error of every block. The per-block results stream:
//! the JSON report is written as the blocks come (`json_stream`), so
//! memory does not grow with the program; the SVG plot keeps them.

use std::io::{BufRead, Seek, Write};
use std::path::PathBuf;

use clap::Args;

use super::errors::load_errors;
use super::{MachineChoice, PoseStartArg};
use crate::analyze::{Analysis, Analyzer};
use crate::error::{Error, Result};
use crate::geometric::BoundErrors;
use crate::geometric::model::ErrorModel;
use crate::input;
use crate::json_stream::PrettyWriter;
use crate::linkage::nonlinear_error;
use crate::machine::{Machine, NoErrors};
use crate::output::write_atomically;
use crate::program::PoseStart;
use crate::program::source::looks_like_poses;
use crate::report::Envelope;
use crate::report::svg::{Panel, write_panels};
use crate::trajectory::{TrajectoryOptions, joint_trajectory};

/// Blocks whose nonlinear error `analyze --nonlinear` measures on every
/// core at a time (memory: two joint vectors each).
const NONLINEAR_BATCH: usize = 4096;

/// `kinpost analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
    /// Program: tool poses (G-code or APT CL) or, with --nonlinear, machine axes.
    #[arg(value_name = "PROGRAM")]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub machine: MachineChoice,
    #[command(flatten)]
    pub job: super::JobArgs,
    /// Error model: model JSON from `kinpost fit`, or an error table CSV
    /// (fitted on the fly). Required unless --nonlinear.
    ///
    /// A table is fitted once: its fitted model is kept in a cache
    /// (KINPOST_CACHE_DIR, else $XDG_CACHE_HOME/kinpost or ~/.cache/kinpost)
    /// and read back by later runs with the same table bytes, with the same
    /// result; KINPOST_CACHE_DIR=off disables it.
    #[arg(long, short = 'e', value_name = "MODEL|TABLE.csv")]
    pub errors: Option<PathBuf>,
    /// Report the exact nonlinear error of every block (largest distance of
    /// the tool tip from the straight line while the axes interpolate linearly).
    #[arg(long)]
    pub nonlinear: bool,
    /// APT CL: units of a program without `UNITS` (default: mm, with a
    /// warning).
    #[arg(long, value_enum)]
    pub units: Option<super::UnitsArg>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Plot the errors along the program (SVG).
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// When pose mode starts (pose programs).
    #[arg(long, value_enum, default_value = "tcp")]
    pub pose_start: PoseStartArg,
    #[command(flatten)]
    pub axis_tolerance: super::AxisTolerance,
}

/// Nonlinear error of one block.
#[derive(Debug, Clone, serde::Serialize)]
pub struct NonlinearBlock {
    /// 1-based line of the block.
    pub line: usize,
    /// Exact largest deviation from the straight line, mm.
    pub max_mm: f64,
    /// Where along the block (0…1).
    pub t_at_max: f64,
    /// The r·Δθ²/8 estimate, mm.
    pub estimate_mm: f64,
}

/// Runs `kinpost analyze`.
pub fn analyze(a: AnalyzeArgs) -> Result<()> {
    super::check_outputs(
        &[("--svg", a.svg.as_deref())],
        &[
            a.input.as_deref(),
            a.errors.as_deref(),
            a.machine.file(),
            a.job.inputs(),
        ],
    )?;
    let base = a.machine.load()?;
    if a.errors.is_none() && !a.nonlinear {
        return Err(Error::Usage(
            "analyze needs --errors MODEL (or --nonlinear)".into(),
        ));
    }
    let model = match &a.errors {
        Some(p) => Some(load_errors(p)?),
        None => None,
    };
    if let Some(m) = &model {
        a.job.check_model(m)?;
    }
    let mut inp = input::open(a.input.as_deref())?;
    super::require_program(&mut inp)?;
    let machine = a.job.machine(&base, Some(&mut inp))?;
    let bound = match &model {
        Some(m) => Some(m.bind(&machine.chain)?),
        None => None,
    };
    // A CAM header can run past 4 KiB before the TCP code (as `simulate`).
    let head = input::peek_far(&mut *inp.reader)?;
    let poses = looks_like_poses(&head);
    let name = inp.name.clone();
    let start = match a.pose_start {
        PoseStartArg::On => PoseStart::On,
        PoseStartArg::Tcp => PoseStart::Off,
    };

    let job = Job {
        a: &a,
        machine: &machine,
        model: model.as_ref(),
        bound: bound.as_ref(),
        poses,
        name,
        start,
    };
    if a.json {
        // The report streams into a spool that reaches standard output
        // only when the run succeeds.
        return write_atomically(None, |w| run(&job, &mut inp, &head, Some(w)).map(|_| ()));
    }
    let done = run(&job, &mut inp, &head, None)?;
    let (analysis, nl_max, nl_count) = (done.analysis, done.nl_max, done.nl_count);
    let mut o = std::io::stdout().lock();
    let io = |e| Error::io("<stdout>", e);
    if let Some(an) = &analysis {
        write!(o, "{}", an.to_text()).map_err(io)?;
    }
    if a.nonlinear {
        writeln!(
            o,
            "nonlinear error (exact, from the chain; r·Δθ²/8 estimate beside it):"
        )
        .map_err(io)?;
        match &nl_max {
            Some(b) => writeln!(
                o,
                "  max {:.4} µm at line {} (t = {:.3}); estimate there {:.4} µm; {} blocks",
                b.max_mm * 1e3,
                b.line,
                b.t_at_max,
                b.estimate_mm * 1e3,
                nl_count
            )
            .map_err(io)?,
            None => writeln!(o, "  no blocks").map_err(io)?,
        }
    }
    Ok(())
}

/// What `analyze` reads, set up.
struct Job<'a> {
    a: &'a AnalyzeArgs,
    machine: &'a Machine,
    model: Option<&'a ErrorModel>,
    bound: Option<&'a BoundErrors<'a>>,
    /// Whether the program gives tool poses.
    poses: bool,
    name: String,
    start: PoseStart,
}

/// What the text report needs of a run.
/// The per-pose series of `--svg`, thinned as they grow (x: the pose's
/// index from 0).
#[derive(Default)]
struct PosePlot {
    /// Poses analysed.
    poses: usize,
    tip: Envelope,
    orientation: Envelope,
}

/// The per-block series of `--svg --nonlinear` (x: the measured block's
/// index from 1).
#[derive(Default)]
struct NonlinearPlot {
    exact: Envelope,
    estimate: Envelope,
}

struct Done {
    analysis: Option<Analysis>,
    nl_max: Option<NonlinearBlock>,
    nl_count: usize,
}

/// Runs the analysis over the program (whose start `head` was peeked);
/// writes the SVG and, with `json`, the JSON report as the blocks come.
fn run(
    job: &Job<'_>,
    inp: &mut input::Input,
    head: &[u8],
    json: Option<&mut dyn Write>,
) -> Result<Done> {
    let (a, machine, name) = (job.a, job.machine, &job.name);
    let io = |e| Error::io("<stdout>", e);
    // Joint values per block (theoretical IK for poses).
    let mut analyzer = match (job.model, job.bound) {
        // The per-block results are not kept: the JSON streams them and
        // the plot thins them as they come, so memory stays flat.
        (Some(m), Some(b)) => Some(Analyzer::new(machine, m, b)?.keep_blocks(false)),
        _ => None,
    };
    // The plotted series, thinned as they grow (`--svg`).
    let mut pose_plot = a.svg.as_ref().map(|_| PosePlot::default());
    let mut nl_plot = a.svg.as_ref().map(|_| NonlinearPlot::default());
    let mut prev_q: Option<Vec<f64>> = None;
    let axis_tolerance = a.axis_tolerance.rad()?;
    // The text report needs only the largest and the count; the JSON
    // streams the blocks (those of the nonlinear error through a spool, as
    // they come after the analysis's own in the report).
    let mut spool = match (a.json, a.nonlinear) {
        (true, true) => Some(std::io::BufWriter::new(
            tempfile::tempfile().map_err(|e| Error::io("<spool>", e))?,
        )),
        _ => None,
    };
    let mut nl_count = 0usize;
    let mut nl_max: Option<NonlinearBlock> = None;
    // The blocks to measure are gathered (line, start, end) and measured
    // on every core a batch at a time; the results are taken in order.
    let mut batch: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new();
    let mut measure = |batch: &mut Vec<(usize, Vec<f64>, Vec<f64>)>| {
        use rayon::prelude::*;
        let measured: Vec<NonlinearBlock> = batch
            .par_iter()
            .map(|(line, from, to)| {
                let e = nonlinear_error(&machine.chain, &NoErrors, from, to);
                NonlinearBlock {
                    line: *line,
                    max_mm: e.max_mm,
                    t_at_max: e.t_at_max,
                    estimate_mm: e.estimate_mm,
                }
            })
            .collect();
        batch.clear();
        for b in measured {
            if let Some(sp) = spool.as_mut() {
                serde_json::to_writer(&mut *sp, &b)
                    .map_err(std::io::Error::other)
                    .and_then(|()| sp.write_all(b"\n"))
                    .map_err(|e| Error::io("<spool>", e))?;
            }
            nl_count += 1;
            // The last of equal largest, as `max_by` over the list gives.
            if nl_max
                .as_ref()
                .is_none_or(|m| b.max_mm.total_cmp(&m.max_mm).is_ge())
            {
                nl_max = Some(b.clone());
            }
            if let Some(p) = nl_plot.as_mut() {
                let x = nl_count as f64;
                p.exact.push(x, b.max_mm * 1e3);
                p.estimate.push(x, b.estimate_mm * 1e3);
            }
        }
        Ok::<(), Error>(())
    };
    // `restart`: where this block starts is not known (after a move in
    // machine coordinates): no segment to measure.
    let mut step = |line: usize, q: Vec<f64>, restart: bool| {
        if restart {
            prev_q = None;
        }
        if let (true, Some(p)) = (a.nonlinear, prev_q.take()) {
            batch.push((line, p, q.clone()));
            if batch.len() == NONLINEAR_BATCH {
                measure(&mut batch)?;
            }
        }
        prev_q = Some(q);
        Ok::<(), Error>(())
    };
    let opts = TrajectoryOptions {
        start: job.start,
        axis_tolerance_rad: axis_tolerance,
        // Circular moves are not measured: their points are not needed.
        arc_points: false,
        // The errors are analysed at poses: a G-code program whose first
        // 4 KB hold none (its TCP code comes later) is read as `post`
        // reads it, its blocks before pose mode followed.
        as_poses: analyzer.is_some(),
        cl_units: super::cl_units(a.units),
    };
    let mut poses_seen = false;
    let mut report = json.map(PrettyWriter::new);
    if let Some(r) = report.as_mut() {
        r.begin_object().map_err(io)?;
        if analyzer.is_some() {
            r.key("blocks").map_err(io)?;
            r.begin_array().map_err(io)?;
        }
    }
    let read = joint_trajectory(machine, &mut inp.reader, head, name, opts, |b| {
        poses_seen |= b.pose.is_some();
        if let (Some(an), Some(pose)) = (analyzer.as_mut(), &b.pose) {
            let block = an
                .add(b.line, pose)
                .map_err(|m| Error::input(crate::error::Location::new(name, b.line, 1), m))?;
            if let Some(r) = report.as_mut() {
                r.value(&block).map_err(io)?;
            }
            if let Some(p) = pose_plot.as_mut() {
                let x = p.poses as f64;
                p.tip.push(x, block.tip_error_mm * 1e3);
                p.orientation.push(x, block.orientation_error_urad);
                p.poses += 1;
            }
        }
        // A circular move is not a straight move of the joints: not
        // measured; the next block starts at its end.
        step(b.line, b.q, b.restart || b.arc)
    });
    // A program in machine axes (no pose before it ended, or before what
    // stopped it): the errors have nothing to be analysed at. Not where
    // pose mode is on from the start (`--pose-start on`): what stopped it
    // then is the answer.
    if analyzer.is_some() && !job.poses && !poses_seen && job.start != PoseStart::On {
        return Err(Error::Usage(
            "analyze --errors needs a program of tool poses; this one is in machine axes (use --nonlinear alone)".into(),
        ));
    }
    read?;
    measure(&mut batch)?;
    let analysis = analyzer.map(|an| an.finish());

    if let (Some(svg), Some(p), Some(nl)) = (&a.svg, &pose_plot, &nl_plot) {
        let mut panels = Vec::new();
        if analysis.is_some() {
            panels.push(Panel {
                y_label: "tool-tip error E [µm]",
                series: vec![("E", p.tip.points())],
            });
            panels.push(Panel {
                y_label: "orientation error ε [µrad]",
                series: vec![("ε", p.orientation.points())],
            });
        }
        if a.nonlinear {
            panels.push(Panel {
                y_label: "nonlinear error [µm]",
                series: vec![
                    ("exact", nl.exact.points()),
                    ("r·Δθ²/8", nl.estimate.points()),
                ],
            });
        }
        write_panels(
            svg,
            &format!("kinpost analyze — {} — {}", machine.name, name),
            "block (pose index)",
            &panels,
        )?;
    }

    if let Some(mut r) = report {
        // Keys in alphabetical order, as `serde_json::to_string_pretty` of
        // the whole report would list them.
        if let Some(an) = &analysis {
            r.end().map_err(io)?;
            r.key("contributions").map_err(io)?;
            r.value(&an.contributions).map_err(io)?;
        }
        r.key("machine").map_err(io)?;
        r.value(&machine.name).map_err(io)?;
        if let Some(sp) = spool {
            r.key("nonlinear").map_err(io)?;
            r.begin_object().map_err(io)?;
            r.key("blocks").map_err(io)?;
            r.begin_array().map_err(io)?;
            let spool_err = |e| Error::io("<spool>", e);
            let mut file = sp.into_inner().map_err(|e| spool_err(e.into_error()))?;
            file.rewind().map_err(spool_err)?;
            for line in std::io::BufReader::new(file).lines() {
                let line = line.map_err(spool_err)?;
                let v: serde_json::Value =
                    serde_json::from_str(&line).map_err(|e| spool_err(std::io::Error::other(e)))?;
                r.value(&v).map_err(io)?;
            }
            r.end().map_err(io)?;
            r.key("estimate_at_max_mm").map_err(io)?;
            r.value(&nl_max.as_ref().map(|b| b.estimate_mm).unwrap_or(0.0))
                .map_err(io)?;
            r.key("max_line").map_err(io)?;
            r.value(&nl_max.as_ref().map(|b| b.line)).map_err(io)?;
            r.key("max_mm").map_err(io)?;
            r.value(&nl_max.as_ref().map(|b| b.max_mm).unwrap_or(0.0))
                .map_err(io)?;
            r.end().map_err(io)?;
        }
        if let Some(an) = &analysis {
            r.key("summary").map_err(io)?;
            r.value(&an.summary).map_err(io)?;
        }
        let out = r.finish().map_err(io)?;
        writeln!(out).map_err(io)?;
    }
    Ok(Done {
        analysis,
        nl_max,
        nl_count,
    })
}
