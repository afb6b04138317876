//! The command line: clap definitions and dispatch into the library.

pub mod diagnose;
pub mod errors;
pub mod linkage;
pub mod machine;

use crate::error::{Error, Result};
use crate::input;
use crate::machine::{IkSolver, Machine};
use crate::output::write_atomically;
use crate::post::{PostOptions, post_cl, post_gcode};
use crate::program::PoseStart;
use crate::progress::RunProgress;
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::io::Write;
use std::path::PathBuf;

/// kinpost — tool poses to machine axes, with the machine's geometric errors compensated.
///
/// Lengths are in mm and angles in degrees on the command line, in programs
/// and in every report (orientation errors also in µrad and arcsec).
#[derive(Debug, Parser)]
#[command(name = "kinpost", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Convert a program of tool poses (G-code X Y Z + I J K / A3= B3= C3=, or
    /// APT CL GOTO/) into machine axis words. Works as a stdin→stdout filter
    /// and as a LinuxCNC `[FILTER]` program.
    Post(PostArgs),
    /// Parse a program and summarise its blocks, words and opaque lines, or
    /// re-emit it from the parse tree (--echo; byte-identical).
    Parse(ParseArgs),
    /// Show a machine: its chain, joints, limits, IK family and output format.
    Machine(MachineArgs),
    /// Fit least-squares cubic B-splines to measured error tables (ISO 230-1
    /// names) and report residuals and ISO 230-2 figures; write a model file.
    Fit(errors::FitArgs),
    /// How far the tool would miss each pose on the actual machine (tool-tip
    /// error in µm, orientation error in µrad and arcsec), and which error
    /// term is to blame; with --nonlinear, the exact nonlinear error per block.
    Analyze(errors::AnalyzeArgs),
    /// Like post, but the axes put the actual machine's tool on the pose:
    /// Newton refinement on the error-aware chain (seed 000).
    Compensate(errors::CompensateArgs),
    /// Rewrite a five-axis linkage program so that no block moves more than
    /// four axes, with the exact nonlinear error of every segment bounded (seed 003).
    Linkage(linkage::LinkageArgs),
    /// Make a recording: run a program on the model machine with chosen
    /// effects injected (backlash, servo lag, thermal drift, …) and noise.
    Simulate(diagnose::SimulateArgs),
    /// Find where a recording and the model disagree, name the physics the
    /// model left out, fit it, and show the fit improve on held-out data.
    Diagnose(diagnose::DiagnoseArgs),
    /// Print a shell completion script on standard output, e.g.
    /// `kinpost completions bash > /etc/bash_completion.d/kinpost`.
    Completions(CompletionsArgs),
}

/// `kinpost completions`.
#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell to write the completion script for.
    #[arg(value_enum, value_name = "SHELL")]
    pub shell: clap_complete::Shell,
}

/// Choosing a machine.
#[derive(Debug, Args, Clone)]
pub struct MachineChoice {
    /// Machine file (JSON) or the name of an embedded machine
    /// (zhao2022-xzbc, wang2023-xyzab, …). Default: the embedded zhao2022-xzbc.
    #[arg(long, short = 'm', value_name = "FILE|NAME")]
    pub machine: Option<String>,
}

impl MachineChoice {
    /// The machine file, when `--machine` names an existing file.
    pub fn file(&self) -> Option<&std::path::Path> {
        self.machine
            .as_deref()
            .map(std::path::Path::new)
            .filter(|p| p.is_file())
    }

    /// Loads the chosen machine.
    pub fn load(&self) -> Result<Machine> {
        match &self.machine {
            None => Ok(Machine::embedded_default()),
            Some(m) => {
                let p = PathBuf::from(m);
                if p.exists() {
                    Machine::load(&p)
                } else if let Some(machine) = Machine::embedded(m) {
                    Ok(machine)
                } else if m.contains(std::path::MAIN_SEPARATOR)
                    || m.contains('/')
                    || m.ends_with(".json")
                {
                    Err(Error::io(
                        m.clone(),
                        std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            format!(
                                "no such machine file (embedded machines: {})",
                                Machine::embedded_names().join(", ")
                            ),
                        ),
                    ))
                } else {
                    Err(Error::Usage(format!(
                        "--machine {m}: no such file, and no embedded machine of that name (embedded: {})",
                        Machine::embedded_names().join(", ")
                    )))
                }
            }
        }
    }
}

/// The tool-axis tolerance of a four-axis machine, for the commands that
/// turn poses into axes besides `post` (which has the same option).
#[derive(Debug, Args, Clone, Copy)]
pub struct AxisTolerance {
    /// Largest tool-axis miss accepted on a machine that cannot reach every
    /// tool axis (four-axis machines), in µrad (1 µrad ≈ 0.2 arcsec). Poses
    /// beyond it are an error.
    #[arg(long, value_name = "URAD", default_value_t = 100.0)]
    pub axis_tolerance_urad: f64,
}

impl AxisTolerance {
    /// The tolerance in rad, or a usage error for a negative or NaN value.
    pub fn rad(&self) -> Result<f64> {
        if self.axis_tolerance_urad.is_nan() || self.axis_tolerance_urad < 0.0 {
            return Err(Error::Usage(format!(
                "--axis-tolerance-urad {}: expected a tolerance ≥ 0 µrad",
                self.axis_tolerance_urad
            )));
        }
        Ok(self.axis_tolerance_urad * 1e-6)
    }
}

/// When pose mode starts.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PoseStartArg {
    /// Every straight move with X Y Z / I J K is a tool pose from the first
    /// block on (for CAM output that writes poses without a TCP code);
    /// G49 / TRAFOOF switch pose mode off, G43.4 / G43.5 / TRAORI on.
    On,
    /// The default: pose mode only where the program asks for it — after
    /// G43.4 / G43.5 / TRAORI, or a straight move that carries a tool axis
    /// (I J K, A3= B3= C3=). A program that never asks passes through
    /// unchanged.
    Tcp,
}

/// Input kind.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum InputKind {
    /// Decide from the content (APT CL if it starts with CL statements).
    Auto,
    /// RS-274 / ISO 6983 G-code.
    Gcode,
    /// APT CL data (GOTO/x,y,z,i,j,k).
    Cl,
}

/// `kinpost post`.
#[derive(Debug, Args)]
pub struct PostArgs {
    /// Program to convert (`-` or nothing: standard input).
    #[arg(value_name = "PROGRAM")]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub machine: MachineChoice,
    /// Write the output here (atomically: a failed run leaves FILE untouched).
    /// Default: standard output.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Decimals of every axis word (a count, 0–12; the words are in mm or
    /// inch and degrees), overriding the machine file.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=12))]
    pub decimals: Option<u32>,
    /// When pose mode starts.
    #[arg(long, value_enum, default_value = "tcp")]
    pub pose_start: PoseStartArg,
    /// Largest tool-axis miss accepted on a machine that cannot reach every
    /// tool axis (four-axis machines), in µrad (1 µrad ≈ 0.2 arcsec). Poses
    /// beyond it are an error.
    #[arg(long, value_name = "URAD", default_value_t = 100.0)]
    pub axis_tolerance_urad: f64,
    /// Write only the axes whose value changed (modal), not all axes.
    #[arg(long)]
    pub modal_axes: bool,
    /// Input format.
    #[arg(long, value_enum, default_value = "auto")]
    pub input_kind: InputKind,
    /// Print no summary on standard error.
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// APT CL: largest chord error of a `CIRCLE` arc turned into straight
    /// moves, in mm (0.001 = 1 µm).
    #[arg(long = "arc-tolerance", value_name = "MM", default_value_t = 0.001)]
    pub arc_tolerance_mm: f64,
    /// APT CL: units of a program without `UNITS` (default: mm, with a
    /// warning).
    #[arg(long, value_enum)]
    pub units: Option<UnitsArg>,
}

/// Units of `--units`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum UnitsArg {
    /// Millimetres.
    Mm,
    /// Inches.
    Inch,
}

/// `kinpost parse`.
#[derive(Debug, Args)]
pub struct ParseArgs {
    /// Program to parse (`-` or nothing: standard input).
    #[arg(value_name = "PROGRAM")]
    pub input: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Re-emit the program from the parse tree instead of summarising it.
    #[arg(long, conflicts_with = "json")]
    pub echo: bool,
}

/// `kinpost machine`.
#[derive(Debug, Args)]
pub struct MachineArgs {
    #[command(flatten)]
    pub machine: MachineChoice,
    /// Print as JSON: a machine file that loads back (the IK family in the
    /// comment key `_ik_family`).
    #[arg(long)]
    pub json: bool,
    /// List the embedded machines: name, IK family, axes.
    #[arg(long, conflicts_with_all = ["json", "template"])]
    pub list: bool,
    /// Print a commented starting machine file for FAMILY: 2R3T, 1R3T,
    /// RTTR or 3T.
    #[arg(long, value_name = "FAMILY", conflicts_with = "json")]
    pub template: Option<String>,
    /// Write a machine file for a LinuxCNC configuration: its `[KINS]`
    /// KINEMATICS (xyzac-trt-kins, xyzbc-trt-kins, 5axiskins) and the HAL
    /// setp values of its HAL files.
    #[arg(long, value_name = "INI", conflicts_with_all = ["json", "list", "template"])]
    pub from_linuxcnc: Option<PathBuf>,
    /// With --from-linuxcnc: the tool length in mm (the last element of the
    /// chain; default: the kinematics' tool-offset setp, else 0).
    #[arg(long, value_name = "MM", requires = "from_linuxcnc")]
    pub tool_length: Option<f64>,
    /// With --from-linuxcnc: write the machine file here (atomically).
    /// Default: standard output.
    #[arg(long, short = 'o', value_name = "FILE", requires = "from_linuxcnc")]
    pub output: Option<PathBuf>,
}

/// Makes the calling thread (the binary's main thread) one of the global
/// thread pool's `RAYON_NUM_THREADS` (default: one per core) workers, so
/// that the pool does not add a thread to it: `compensate`'s in-order work
/// runs on this thread and, whenever it waits for the parallel stages,
/// this thread works on them (instead of sleeping while the pool's own
/// threads compete with it for the cores). Without effect if the global
/// pool is already running.
pub fn use_this_thread_as_worker() {
    let _ = rayon::ThreadPoolBuilder::new()
        .use_current_thread()
        .build_global();
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Post(a) => post(a),
        Command::Parse(a) => parse(a),
        Command::Machine(a) => machine(a),
        Command::Fit(a) => errors::fit(a),
        Command::Analyze(a) => errors::analyze(a),
        Command::Compensate(a) => errors::compensate(a),
        Command::Linkage(a) => linkage::linkage(a),
        Command::Simulate(a) => diagnose::simulate(a),
        Command::Diagnose(a) => diagnose::diagnose(a),
        Command::Completions(a) => completions(a),
    }
}

fn completions(a: CompletionsArgs) -> Result<()> {
    use clap::CommandFactory;
    let mut cmd = Cli::command();
    let mut script = Vec::new();
    clap_complete::generate(a.shell, &mut cmd, "kinpost", &mut script);
    let mut out = std::io::stdout().lock();
    out.write_all(&script)
        .and_then(|_| out.flush())
        .map_err(|e| Error::io("<stdout>", e))
}

fn post(a: PostArgs) -> Result<()> {
    if !(a.arc_tolerance_mm.is_finite() && a.arc_tolerance_mm >= 1e-6) {
        return Err(Error::Usage(
            "--arc-tolerance must be a number in mm, at least 0.000001".into(),
        ));
    }
    if a.axis_tolerance_urad.is_nan() || a.axis_tolerance_urad < 0.0 {
        return Err(Error::Usage(
            "--axis-tolerance-urad must be a number ≥ 0".into(),
        ));
    }
    check_outputs(
        &[("-o", a.output.as_deref())],
        &[a.input.as_deref(), a.machine.file()],
    )?;
    let machine = a.machine.load()?;
    let mut solver = IkSolver::new(&machine);
    let mut inp = input::open(a.input.as_deref())?;
    require_program(&mut inp)?;
    let kind = resolve_kind(a.input_kind, &mut *inp.reader)?;
    let opts = PostOptions {
        decimals: a.decimals,
        pose_start: match a.pose_start {
            PoseStartArg::On => PoseStart::On,
            PoseStartArg::Tcp => PoseStart::Off,
        },
        axis_tolerance_rad: a.axis_tolerance_urad * 1e-6,
        modal_axes: a.modal_axes,
        file_name: inp.name.clone(),
        arc_tolerance_mm: a.arc_tolerance_mm,
        cl_units: a.units.map(|u| match u {
            UnitsArg::Mm => crate::cl::ClUnits::Mm,
            UnitsArg::Inch => crate::cl::ClUnits::Inches,
        }),
    };
    let mut progress = RunProgress::new(inp.size, a.quiet, "post");
    let stats = write_atomically(a.output.as_deref(), |out| {
        if kind == InputKind::Cl {
            post_cl(&machine, &mut solver, &mut inp.reader, out, &opts, |n| {
                progress.update(n)
            })
        } else {
            post_gcode(&machine, &mut solver, &mut inp.reader, out, &opts, |n| {
                progress.update(n)
            })
        }
    })?;
    progress.finish();
    if !a.quiet {
        let mut e = std::io::stderr().lock();
        for w in &stats.warnings {
            let _ = writeln!(e, "warning: {w}");
        }
        let _ = writeln!(
            e,
            "kinpost: {} poses converted for {} ({} lines); largest tool-axis miss {:.3} µrad",
            stats.poses,
            machine.name,
            stats.lines,
            stats.max_axis_miss_rad * 1e6
        );
        // Below 1e-9 it is the rounding of a vector printed to 9 decimals.
        if stats.max_vector_deviation > 1e-9 {
            let _ = writeln!(
                e,
                "kinpost: tool vectors normalised to unit length; largest deviation of a length from 1: {:.3e}",
                stats.max_vector_deviation
            );
        }
        if a.machine.machine.is_none() && stats.poses > 0 {
            let _ = writeln!(
                e,
                "kinpost: note: no --machine given; the poses were converted for the embedded machine {} (kinpost machine --list)",
                machine.name
            );
        }
    }
    Ok(())
}

/// Checks every output path before any work: its directory exists, it is
/// not a directory, a block device or one of the `inputs` (by device and
/// inode, so links are caught), and no two outputs name the same file. A
/// command with several outputs (`-o` and `--report`, `--svg` and
/// `--write-model`) then does not commit the first and fail on the second.
/// `outputs` pairs each path with the option that named it.
pub fn check_outputs(
    outputs: &[(&str, Option<&std::path::Path>)],
    inputs: &[Option<&std::path::Path>],
) -> Result<()> {
    crate::output::check_outputs(outputs, inputs)
}

/// Fails with an input error if the program `inp` is empty (no byte at all):
/// an empty program in a filter chain is almost surely a failed stage
/// before, and passing it on would lose that.
pub fn require_program(inp: &mut input::Input) -> Result<()> {
    let empty = inp
        .reader
        .fill_buf()
        .map_err(|e| Error::io(&inp.name, e))?
        .is_empty();
    if empty {
        return Err(Error::input(
            crate::error::Location::new(&inp.name, 1, 0),
            "the program is empty: expected G-code blocks or APT CL statements",
        ));
    }
    Ok(())
}

/// Resolves `--input-kind auto` from the start of the input.
pub fn resolve_kind(kind: InputKind, reader: &mut dyn std::io::BufRead) -> Result<InputKind> {
    Ok(match kind {
        InputKind::Auto => {
            if crate::cl::looks_like_cl(&input::peek(reader)?) {
                InputKind::Cl
            } else {
                InputKind::Gcode
            }
        }
        k => k,
    })
}

fn parse(a: ParseArgs) -> Result<()> {
    let mut inp = input::open(a.input.as_deref())?;
    let name = inp.name.clone();
    if a.echo {
        return write_atomically(None, |out| {
            crate::gcode::echo(&mut inp.reader, out).map_err(|e| Error::io(&name, e))
        });
    }
    let summary = crate::gcode::summarize(&mut inp.reader).map_err(|e| Error::io(&name, e))?;
    let mut out = std::io::stdout().lock();
    let text = if a.json {
        serde_json::to_string_pretty(&summary).unwrap_or_default()
    } else {
        format!("{name}\n{summary}")
    };
    writeln!(out, "{text}").map_err(|e| Error::io("<stdout>", e))
}

fn machine(a: MachineArgs) -> Result<()> {
    use crate::machine::template;
    let mut out = std::io::stdout().lock();
    let put = |text: &str, out: &mut std::io::StdoutLock| {
        writeln!(out, "{}", text.trim_end()).map_err(|e| Error::io("<stdout>", e))
    };
    if a.list {
        return put(&template::embedded_list(), &mut out);
    }
    if let Some(f) = &a.template {
        let text = template::template(f).ok_or_else(|| {
            let known: Vec<&str> = template::TEMPLATE_FAMILIES.iter().map(|t| t.0).collect();
            Error::Usage(format!(
                "--template {f}: no such family; expected one of {}",
                known.join(", ")
            ))
        })?;
        return put(text, &mut out);
    }
    if let Some(ini) = &a.from_linuxcnc {
        if let Some(t) = a.tool_length
            && !t.is_finite()
        {
            return Err(Error::Usage(format!(
                "--tool-length {t}: expected a finite length in mm"
            )));
        }
        check_outputs(&[("-o", a.output.as_deref())], &[Some(ini.as_path())])?;
        let file = crate::machine::linuxcnc::machine_from_linuxcnc(ini, a.tool_length)?;
        let text = serde_json::to_string_pretty(&file).unwrap_or_default();
        drop(out);
        return write_atomically(a.output.as_deref(), |w| {
            writeln!(w, "{text}").map_err(|e| Error::io("<output>", e))
        });
    }
    let machine = a.machine.load()?;
    let solver = IkSolver::new(&machine);
    let text = if a.json {
        let mut file = machine.to_file_json();
        if let Some(o) = file.as_object_mut() {
            o.insert(
                "_ik_family".into(),
                solver.family().short_name().to_string().into(),
            );
        }
        serde_json::to_string_pretty(&file).unwrap_or_default()
    } else {
        machine::summary_text(&machine, &solver)
    };
    writeln!(out, "{text}").map_err(|e| Error::io("<stdout>", e))
}
