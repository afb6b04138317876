//! `kinpost fit`, `kinpost analyze`, `kinpost compensate`: the geometric
//! error model of seed 000.

use super::{InputKind, MachineChoice, PoseStartArg};
use crate::compensate::{
    BlockRecord, CompensatingSolver, Method, OnFail, Options, ReportWriter, RunSummary,
};
use crate::error::{Error, Result};
use crate::geometric::bspline::{Extrapolation, KnotChoice};
use crate::geometric::model::{ErrorModel, FitOptions};
use crate::geometric::table::read_tables;
use crate::input;
use crate::machine::{IkSolver, Machine};
use crate::output::write_atomically;
use crate::post::PostOptions;
use crate::program::PoseStart;
use crate::progress::RunProgress;
use clap::{Args, ValueEnum};
use std::io::Write;
use std::path::PathBuf;

/// Extrapolation outside the measured travel.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ExtrapolateArg {
    /// Hold the end value (derivative 0).
    Hold,
    /// Continue linearly with the end slope.
    Linear,
}

/// `kinpost fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Error table (CSV, formats.md §1): one block per axis, ISO 230-1 names.
    #[arg(value_name = "TABLE.csv")]
    pub table: PathBuf,
    /// Interior knots per spline (a count, no unit; default: chosen by
    /// cross-validation).
    #[arg(long, value_name = "N")]
    pub knots: Option<usize>,
    /// Behaviour outside the measured travel.
    #[arg(long, value_enum, default_value = "hold")]
    pub extrapolate: ExtrapolateArg,
    /// Write the fitted model (JSON, accepted by every --errors) here.
    #[arg(long, short = 'o', value_name = "MODEL.json")]
    pub output: Option<PathBuf>,
    /// Print the fit report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Loads an error model (model JSON, or an error table fitted on the fly).
pub fn load_errors(path: &std::path::Path) -> Result<ErrorModel> {
    ErrorModel::load(path)
}

/// Runs `kinpost fit`.
pub fn fit(a: FitArgs) -> Result<()> {
    super::check_outputs(&[("-o", a.output.as_deref())], &[Some(&a.table)])?;
    let tables = read_tables(&a.table)?;
    let mut opts = match a.knots {
        Some(n) => FitOptions::fixed_knots(n),
        None => FitOptions::default(),
    };
    opts.extrapolation = match a.extrapolate {
        ExtrapolateArg::Hold => Extrapolation::Hold,
        ExtrapolateArg::Linear => Extrapolation::Linear,
    };
    if a.knots.is_none() {
        opts.knots = KnotChoice::default();
    }
    let (model, report) = ErrorModel::fit(&tables, &opts)?;
    if let Some(out) = &a.output {
        let text = serde_json::to_string_pretty(&model.to_json()).unwrap_or_default();
        write_atomically(Some(out), |w| {
            w.write_all(text.as_bytes())
                .and_then(|_| w.write_all(b"\n"))
                .map_err(|e| Error::io(out.display().to_string(), e))
        })?;
    }
    let text = if a.json {
        serde_json::to_string_pretty(&report).unwrap_or_default()
    } else {
        report.to_text()
    };
    let mut o = std::io::stdout().lock();
    writeln!(o, "{text}").map_err(|e| Error::io("<stdout>", e))?;
    if let (Some(out), false) = (&a.output, a.json) {
        writeln!(o, "model written to {}", out.display()).map_err(|e| Error::io("<stdout>", e))?;
    }
    Ok(())
}

/// Newton step method.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Exact Jacobian of the error-aware chain, tip first (default: fewest iterations).
    Exact,
    /// Theoretical Jacobian, tip first.
    Theoretical,
    /// Seed 000 as printed: stacked theoretical Jacobian, unweighted pseudo-inverse.
    Paper,
}

/// Failure policy.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum OnFailArg {
    /// Stop with an error naming the line.
    Error,
    /// Keep the theoretical axes for that block, with a warning.
    Theoretical,
    /// Keep the best compensation within bounds (tip error reported), with a warning.
    Best,
}

/// `kinpost compensate`.
#[derive(Debug, Args)]
pub struct CompensateArgs {
    /// Program of tool poses (G-code or APT CL; `-` or nothing: stdin).
    #[arg(value_name = "PROGRAM")]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub machine: MachineChoice,
    #[command(flatten)]
    pub job: super::JobArgs,
    /// Error model: model JSON from `kinpost fit`, or an error table CSV.
    ///
    /// A table is fitted once: its fitted model is kept in a cache
    /// (KINPOST_CACHE_DIR, else $XDG_CACHE_HOME/kinpost or ~/.cache/kinpost)
    /// and read back by later runs with the same table bytes, with the same
    /// result; KINPOST_CACHE_DIR=off disables it.
    #[arg(long, short = 'e', value_name = "MODEL|TABLE.csv")]
    pub errors: PathBuf,
    /// Write the output here (atomically). Default: standard output.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Decimals of every axis word (a count, 0–12; the words are in mm or
    /// inch and degrees), overriding the machine file.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=12))]
    pub decimals: Option<u32>,
    /// How the Newton step is computed (the Jacobian it uses).
    #[arg(long, value_enum, default_value = "exact")]
    pub method: MethodArg,
    /// Weights of the tool-axis residual (x,y,z of the workpiece frame),
    /// dimensionless, each ≥ 0.
    #[arg(long, value_name = "WX,WY,WZ", default_value = "1,1,1", allow_hyphen_values = true, value_parser = parse_weights)]
    pub axis_weights: [f64; 3],
    /// Largest number of Newton iterations per pose (a count, no unit).
    #[arg(long, value_name = "N", default_value_t = 30)]
    pub max_iterations: usize,
    #[command(flatten)]
    pub axis_tolerance: super::AxisTolerance,
    /// Largest accepted tool-tip residual, in mm (1e-9 mm = 1 pm); beyond it a
    /// block has not converged.
    #[arg(long, value_name = "MM", default_value_t = 1e-9)]
    pub tip_tolerance_mm: f64,
    /// What to do with a block that does not converge or breaks a limit.
    #[arg(long, value_enum, default_value = "error")]
    pub on_fail: OnFailArg,
    /// Largest chord error of an arc turned into straight moves (APT CL
    /// `CIRCLE`; G-code `G2`/`G3` under TCP), in mm (0.001 = 1 µm).
    #[arg(long = "arc-tolerance", value_name = "MM", default_value_t = 0.001)]
    pub arc_tolerance_mm: f64,
    /// APT CL: units of a program without `UNITS` (default: mm, with a
    /// warning).
    #[arg(long, value_enum)]
    pub units: Option<super::UnitsArg>,
    /// Write a JSON report (per block: iterations, residuals, compensation).
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// When pose mode starts.
    #[arg(long, value_enum, default_value = "tcp")]
    pub pose_start: PoseStartArg,
    /// Input format.
    #[arg(long, value_enum, default_value = "auto")]
    pub input_kind: InputKind,
    /// Print no summary on standard error.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// `WX,WY,WZ`: three finite weights ≥ 0.
fn parse_weights(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("{e}; expected three numbers WX,WY,WZ such as 1,1,0.5"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|w| w.is_finite() && *w >= 0.0) => Ok([x, y, z]),
        [_, _, _] => Err("weights must be finite and ≥ 0".into()),
        _ => Err(format!(
            "{} values; expected three numbers WX,WY,WZ such as 1,1,0.5",
            v.len()
        )),
    }
}

/// Runs `kinpost compensate`.
pub fn compensate(a: CompensateArgs) -> Result<()> {
    if a.tip_tolerance_mm.is_nan() || a.tip_tolerance_mm <= 0.0 {
        return Err(Error::Usage("--tip-tolerance-mm must be > 0".into()));
    }
    super::check_arc_tolerance(a.arc_tolerance_mm)?;
    super::check_outputs(
        &[
            ("-o", a.output.as_deref()),
            ("--report", a.report.as_deref()),
        ],
        &[
            a.input.as_deref(),
            Some(&a.errors),
            a.machine.file(),
            a.job.inputs(),
        ],
    )?;
    let base: Machine = a.machine.load()?;
    let model = load_errors(&a.errors)?;
    a.job.check_model(&model)?;
    let axis_tolerance_rad = a.axis_tolerance.rad()?;
    let mut inp = input::open(a.input.as_deref())?;
    super::require_program(&mut inp)?;
    let machine = a.job.machine(&base, Some(&mut inp))?;
    let bound = model.bind(&machine.chain)?;
    let method = match a.method {
        MethodArg::Exact => Method::Exact,
        MethodArg::Theoretical => Method::Theoretical,
        MethodArg::Paper => Method::Paper,
    };
    let (backlash, dynamic_warnings) = CompensatingSolver::dynamic_effects(&model, &machine.chain);
    let mut solver = CompensatingSolver {
        machine: &machine,
        actual_chain: model.apply_fixed(&machine.chain)?,
        errors: &bound,
        ik: IkSolver::new(&machine),
        options: Options {
            method,
            max_iterations: a.max_iterations,
            tip_tolerance_mm: 1e-12,
            axis_weights: a.axis_weights,
        },
        on_fail: match a.on_fail {
            OnFailArg::Error => OnFail::Error,
            OnFailArg::Theoretical => OnFail::Theoretical,
            OnFailArg::Best => OnFail::Best,
        },
        accept_tip_mm: a.tip_tolerance_mm,
        axis_tolerance_rad,
        records: Vec::new(),
        warnings: dynamic_warnings,
        singular_blocks: 0,
        decimals: machine
            .axes
            .iter()
            .map(|ax| a.decimals.unwrap_or(ax.decimals))
            .collect(),
        backlash,
        directions: Vec::new(),
        written_per_block: a.report.is_some(),
        written_largest: (0.0, 0.0),
    };
    let report_name = a
        .report
        .as_ref()
        .map(|r| r.display().to_string())
        .unwrap_or_default();
    let kind = super::resolve_kind(a.input_kind, &mut *inp.reader)?;
    let opts = PostOptions {
        decimals: a.decimals,
        pose_start: match a.pose_start {
            PoseStartArg::On => PoseStart::On,
            PoseStartArg::Tcp => PoseStart::Off,
        },
        axis_tolerance_rad: f64::INFINITY,
        modal_axes: false,
        file_name: inp.name.clone(),
        arc_tolerance_mm: a.arc_tolerance_mm,
        cl_units: super::cl_units(a.units),
        ..PostOptions::default()
    };
    let mut progress = RunProgress::new(inp.size, a.quiet, "compensate");
    // The per-block records stream into the summary and (with --report) into
    // the report file as they are computed: memory stays flat.
    // The summary, and the warnings of reading the program (in program
    // order; the solver's own come after them).
    let mut run = |report: Option<&mut dyn Write>| -> Result<(RunSummary, Vec<String>)> {
        let mut summary = RunSummary::start(&machine, method);
        let mut writer = match report {
            Some(w) => Some(
                ReportWriter::new(w, &machine).map_err(|e| Error::io(report_name.clone(), e))?,
            ),
            None => None,
        };
        let mut sink = |records: &mut Vec<BlockRecord>| -> Result<()> {
            for r in records.iter() {
                summary.add(r);
            }
            if let Some(w) = &mut writer {
                w.blocks(records)
                    .map_err(|e| Error::io(report_name.clone(), e))?;
            }
            records.clear();
            Ok(())
        };
        let stats = write_atomically(a.output.as_deref(), |out| {
            let input = if kind == InputKind::Cl {
                crate::compensate::Input::Cl
            } else {
                crate::compensate::Input::Gcode
            };
            crate::compensate::compensate(
                input,
                &machine,
                &mut solver,
                &mut inp.reader,
                out,
                &opts,
                |n| progress.update(n),
                &mut sink,
            )
        })?;
        let summary = summary.finish();
        if let Some(w) = writer.take() {
            let warnings: Vec<String> = stats
                .warnings
                .iter()
                .chain(&solver.warnings)
                .cloned()
                .collect();
            w.finish(&summary, &warnings)
                .map_err(|e| Error::io(report_name.clone(), e))?;
        }
        Ok((summary, stats.warnings))
    };
    let (summary, read_warnings) = match &a.report {
        Some(r) => write_atomically(Some(r), |w| run(Some(w)))?,
        None => run(None)?,
    };
    progress.finish();
    if !a.quiet && !crate::output::standard_output_closed() {
        let mut e = std::io::stderr().lock();
        for w in read_warnings.iter().chain(&solver.warnings) {
            let _ = writeln!(e, "warning: {w}");
        }
        let _ = write!(e, "{}", summary.to_text());
    }
    Ok(())
}
