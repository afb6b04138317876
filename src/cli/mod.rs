//! The command line: clap definitions and dispatch into the library.

pub mod analyze;
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
    /// Convert a program of tool poses (G-code X Y Z + I J K / A3= B3= C3=,
    /// or + A B C under G43.4 / G234 / TRAORI; APT CL GOTO/) into machine
    /// axis words. Works as a stdin→stdout filter and as a LinuxCNC
    /// `[FILTER]` program.
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
    Analyze(analyze::AnalyzeArgs),
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

/// The job set-up: the tool and the work offset, applied to the machine's
/// chain (`crate::machine::job`), the same for every command that takes it.
#[derive(Debug, Args, Clone)]
pub struct JobArgs {
    /// Tool length in mm, from the gauge line to the tool tip along the tool
    /// axis. It replaces the machine file's tool (its `tool_length`, default
    /// 0: the chain ends at the gauge line): `translate [0, 0, tool_length -
    /// MM]` is appended to the chain.
    #[arg(
        long,
        value_name = "MM",
        conflicts_with = "tool_table",
        allow_hyphen_values = true
    )]
    pub tool_length: Option<f64>,
    /// LinuxCNC tool table (`T1 P1 Z+50.0 D6 ;comment`, Z the length in mm,
    /// or in inch with --tool-table-units inch): the program's `G43`/`G43.4`/
    /// `G43.5` H word, or the T word of its tool change (M6), selects the tool
    /// whose length is used as with --tool-length (`post` switches at each
    /// change; the other commands refuse a change to another length).
    #[arg(long, value_name = "FILE")]
    pub tool_table: Option<PathBuf>,
    /// Length unit of the tool table's Z values.
    #[arg(long, value_enum, default_value = "mm", requires = "tool_table")]
    pub tool_table_units: UnitsArg,
    /// Work offset X,Y,Z in mm: the position of the program's origin in the
    /// machine file's workpiece frame (program point p is the point p + offset
    /// of that frame; the frame's axes are kept).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_xyz_mm)]
    pub work_offset: Option<Vector3Arg>,
}

/// The units `--units` gives an APT CL program without `UNITS`.
fn cl_units(units: Option<UnitsArg>) -> Option<crate::cl::ClUnits> {
    units.map(|u| match u {
        UnitsArg::Mm => crate::cl::ClUnits::Mm,
        UnitsArg::Inch => crate::cl::ClUnits::Inches,
    })
}

/// The whole program `inp`, for a tool table to select the tool from
/// (G-code only).
fn read_program(inp: &mut input::Input) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut inp.reader, &mut bytes).map_err(|e| Error::io(&inp.name, e))?;
    if crate::cl::looks_like_cl(&bytes[..bytes.len().min(4096)]) {
        return Err(Error::Usage(
            "--tool-table selects the tool by G-code H and T words; for APT CL give --tool-length"
                .into(),
        ));
    }
    Ok(bytes)
}

/// One inverse-kinematics solver per tool of a job whose tool changes
/// (`post --tool-table`), each from the line its tool applies from.
struct ToolSolvers {
    solvers: Vec<(usize, IkSolver)>,
}

impl crate::post::PoseSolver for ToolSolvers {
    fn solve(
        &mut self,
        pose: &crate::machine::Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        let k = self.index(line);
        crate::post::PoseSolver::solve(&mut self.solvers[k].1, pose, previous, line)
    }

    fn split(&self) -> Option<&dyn crate::post::SplitSolver> {
        Some(self)
    }
}

impl ToolSolvers {
    /// The index of the tool at `line`.
    fn index(&self, line: usize) -> usize {
        self.solvers
            .iter()
            .rposition(|(from, _)| *from <= line)
            .unwrap_or(0)
    }

    /// The solver of the tool at `line`.
    fn at(&self, line: usize) -> &IkSolver {
        &self.solvers[self.index(line)].1
    }
}

impl crate::post::SplitSolver for ToolSolvers {
    fn prepare(&self, pose: &crate::machine::Pose, line: usize) -> crate::machine::PreparedPose {
        self.at(line).prepare(pose)
    }
    fn choose(
        &self,
        pose: &crate::machine::Pose,
        prepared: &crate::machine::PreparedPose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        crate::post::SplitSolver::choose(self.at(line), pose, prepared, previous, line)
    }
}

/// Three lengths in mm from `X,Y,Z`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vector3Arg(pub [f64; 3]);

/// Largest tool length, mm (10 m: far beyond any tool assembly).
const MAX_TOOL_MM: f64 = 1e4;

/// Largest work offset per coordinate, mm (1 km: no machine travels so far).
const MAX_OFFSET_MM: f64 = 1e6;

fn parse_xyz_mm(s: &str) -> std::result::Result<Vector3Arg, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z in mm (three numbers), got `{s}`"));
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{p}` is not a finite length in mm"))?;
        if v[k].abs() > MAX_OFFSET_MM {
            return Err(format!(
                "`{p}` mm is beyond any machine's travel (|offset| ≤ {MAX_OFFSET_MM:.0e} mm)"
            ));
        }
    }
    Ok(Vector3Arg(v))
}

impl JobArgs {
    /// The job set-up these options describe (reads the tool table).
    pub fn setup(&self) -> Result<crate::machine::job::JobSetup> {
        use crate::machine::job::{JobSetup, ToolChoice, ToolTable};
        let tool = match (&self.tool_length, &self.tool_table) {
            (Some(l), _) if !(l.is_finite() && l.abs() <= MAX_TOOL_MM) => {
                return Err(Error::Usage(format!(
                    "--tool-length {l}: expected a length of −{MAX_TOOL_MM:.0} … {MAX_TOOL_MM:.0} mm"
                )));
            }
            (Some(l), _) => ToolChoice::Length(*l),
            (None, Some(path)) => {
                let text = crate::text::read_text_file(path)?;
                let scale = match self.tool_table_units {
                    UnitsArg::Mm => 1.0,
                    UnitsArg::Inch => 25.4,
                };
                ToolChoice::Table(ToolTable::parse(&text, &path.display().to_string(), scale)?)
            }
            (None, None) => ToolChoice::MachineFile,
        };
        Ok(JobSetup {
            tool,
            work_offset_mm: self
                .work_offset
                .map(|v| nalgebra::Vector3::from(v.0))
                .unwrap_or_else(nalgebra::Vector3::zeros),
        })
    }

    /// Refuses a work offset with an error model that has a fixed error at
    /// the start of the chain (`after_joint` null): that error belongs to
    /// the machine file's workpiece frame, but the model would insert it in
    /// front of the work offset, turning it about the program's origin.
    pub fn check_model(&self, model: &crate::geometric::ErrorModel) -> Result<()> {
        let offset = self.work_offset.is_some_and(|v| v.0 != [0.0; 3]);
        match model.fixed.iter().find(|f| f.after_joint.is_none()) {
            Some(f) if offset => Err(Error::Usage(format!(
                "--work-offset with the error model's fixed error `{}` at the start of the chain (after_joint null) is not supported: the error would turn about the program's origin instead of the workpiece frame's; give the program in the workpiece frame (its origin set in the CAM system) without --work-offset",
                f.name
            ))),
            _ => Ok(()),
        }
    }

    /// The input files these options name (for the output checks).
    pub fn inputs(&self) -> Option<&std::path::Path> {
        self.tool_table.as_deref()
    }

    /// The machines of a job whose tool may change (`post`): one per tool
    /// length the program changes to, each with the 1-based line from which
    /// it applies (the first from line 1, also for poses before the first
    /// selection). Without a tool table, the one machine of
    /// [`Self::machine`].
    pub fn machines_by_line(
        &self,
        base: &Machine,
        inp: &mut input::Input,
    ) -> Result<Vec<(usize, Machine)>> {
        let setup = self.setup()?;
        if !matches!(setup.tool, crate::machine::job::ToolChoice::Table(_)) {
            return Ok(vec![(1, self.machine(base, Some(inp))?)]);
        }
        let bytes = read_program(inp)?;
        let changes = setup.tool_changes(&mut &bytes[..], &inp.name)?;
        inp.reader = Box::new(std::io::Cursor::new(bytes));
        Ok(changes
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let from = if k == 0 { 1 } else { c.at.line };
                (from, setup.machine(base, Some(c.length_mm)))
            })
            .collect())
    }

    /// The machine of the job: `base` with the set-up applied. With a tool
    /// table the program `inp` selects the tool: it is read whole into
    /// memory for that (G-code only) and handed back to be read again.
    pub fn machine(&self, base: &Machine, inp: Option<&mut input::Input>) -> Result<Machine> {
        let setup = self.setup()?;
        if setup.is_identity() {
            return Ok(base.clone());
        }
        match (&setup.tool, inp) {
            (crate::machine::job::ToolChoice::Table(_), Some(inp)) => {
                let bytes = read_program(inp)?;
                let name = inp.name.clone();
                let m = setup.machine_for_program(base, Some((&mut &bytes[..], &name)))?;
                inp.reader = Box::new(std::io::Cursor::new(bytes));
                Ok(m)
            }
            _ => setup.machine_for_program(base, None),
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
    /// The tolerance in rad, or a usage error (see [`axis_tolerance_rad`]).
    pub fn rad(&self) -> Result<f64> {
        axis_tolerance_rad(self.axis_tolerance_urad)
    }
}

/// Largest `--axis-tolerance-urad`, µrad: no two tool axes are further
/// apart than π rad (3.14e6 µrad), so a tolerance of that size already
/// accepts every pose.
const MAX_AXIS_TOLERANCE_URAD: f64 = 3.2e6;

/// `--axis-tolerance-urad` in rad, or a usage error for a value outside
/// 0 … [`MAX_AXIS_TOLERANCE_URAD`] (negative, NaN, infinite).
pub fn axis_tolerance_rad(urad: f64) -> Result<f64> {
    if !(0.0..=MAX_AXIS_TOLERANCE_URAD).contains(&urad) {
        return Err(Error::Usage(format!(
            "--axis-tolerance-urad {}: expected a tolerance of 0 … {MAX_AXIS_TOLERANCE_URAD:.1e} µrad (π rad, 3.14e6 µrad, already accepts every tool axis)",
            crate::numeric::readable(urad)
        )));
    }
    Ok(urad * 1e-6)
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
    /// Largest chord error of an arc turned into straight moves (APT CL
    /// `CIRCLE`; G-code `G2`/`G3` under TCP), in mm (0.001 = 1 µm).
    #[arg(long = "arc-tolerance", value_name = "MM", default_value_t = 0.001)]
    pub arc_tolerance_mm: f64,
    /// APT CL: units of a program without `UNITS` (default: mm, with a
    /// warning).
    #[arg(long, value_enum)]
    pub units: Option<UnitsArg>,
    #[command(flatten)]
    pub job: JobArgs,
    /// Feeds of converted blocks: `keep` (default) writes the programmed F
    /// as it is; `inverse-time` writes G93 with F = 1/(block time in min) on
    /// every pose block that moves a rotary axis, the time being the tool
    /// tip's path length over the programmed feed (mm/min), and G94 with the
    /// programmed F again after them.
    #[arg(long, value_enum, default_value = "keep")]
    pub feed: FeedArg,
}

/// How `post` writes feeds of converted blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum FeedArg {
    /// The programmed F word stays as it is.
    #[default]
    Keep,
    /// Inverse time (G93) on the blocks that move a rotary axis, so that the
    /// tool tip keeps the programmed feed.
    InverseTime,
}

/// Units of `--units`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
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
    /// KINEMATICS (xyzac-trt-kins, xyzbc-trt-kins, 5axiskins with the HAL
    /// setp values of its HAL files; trivkins with X Y Z and at most one
    /// rotary table) and its axis limits, inch converted to mm.
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
        Command::Analyze(a) => analyze::analyze(a),
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

/// `Err` unless `mm` is a usable `--arc-tolerance`.
fn check_arc_tolerance(mm: f64) -> Result<()> {
    if mm.is_finite() && mm >= 1e-6 {
        Ok(())
    } else {
        Err(Error::Usage(
            "--arc-tolerance must be a number in mm, at least 0.000001".into(),
        ))
    }
}

fn post(a: PostArgs) -> Result<()> {
    check_arc_tolerance(a.arc_tolerance_mm)?;
    let axis_tolerance_rad = axis_tolerance_rad(a.axis_tolerance_urad)?;
    check_outputs(
        &[("-o", a.output.as_deref())],
        &[a.input.as_deref(), a.machine.file(), a.job.inputs()],
    )?;
    let base = a.machine.load()?;
    let mut inp = input::open(a.input.as_deref())?;
    require_program(&mut inp)?;
    let mut machines = a.job.machines_by_line(&base, &mut inp)?;
    let machine = machines[0].1.clone();
    let mut solver = ToolSolvers {
        solvers: machines
            .iter()
            .map(|(from, m)| (*from, IkSolver::new(m)))
            .collect(),
    };
    if machines.len() == 1 {
        machines.clear();
    }
    let kind = resolve_kind(a.input_kind, &mut *inp.reader)?;
    let opts = PostOptions {
        decimals: a.decimals,
        pose_start: match a.pose_start {
            PoseStartArg::On => PoseStart::On,
            PoseStartArg::Tcp => PoseStart::Off,
        },
        axis_tolerance_rad,
        modal_axes: a.modal_axes,
        file_name: inp.name.clone(),
        arc_tolerance_mm: a.arc_tolerance_mm,
        cl_units: cl_units(a.units),
        inverse_time: a.feed == FeedArg::InverseTime,
        tool_machines: machines,
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
    if !a.quiet && !crate::output::standard_output_closed() {
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
