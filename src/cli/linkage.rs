//! `kinpost linkage`: five-axis linkage to four-axis linkage (seed 003).

use super::{MachineChoice, PoseStartArg};
use crate::error::{Error, Result};
use crate::input;
use crate::linkage::plan::RotaryPair;
use crate::linkage::program::{LinkageOptions, Mode, linkage as run_linkage};
use crate::machine::JointKind;
use crate::output::write_atomically;
use crate::program::PoseStart;
use crate::program::source::looks_like_poses;
use clap::Args;
use std::path::PathBuf;

/// `kinpost linkage`.
#[derive(Debug, Args)]
pub struct LinkageArgs {
    /// Five-axis G-code program: machine axes, or tool poses (converted
    /// first). APT CL: convert it with `kinpost post` first and pass its output.
    #[arg(value_name = "PROGRAM")]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub machine: MachineChoice,
    #[command(flatten)]
    pub job: super::JobArgs,
    /// Seed 003 exactly: insert this many points (a count, even; 2) into every block that
    /// moves both rotaries — tips at 1/3 and 2/3 of the line, the split rotary
    /// (A) half way with the other (B) held, then B, then A.
    #[arg(long, value_name = "N", conflicts_with = "tolerance", value_parser = parse_insert)]
    pub insert: Option<usize>,
    /// Insert the fewest points such that every segment's exact nonlinear
    /// error is within this tolerance, in mm (default 0.001 mm unless --insert).
    #[arg(long, value_name = "MM")]
    pub tolerance: Option<f64>,
    /// Largest number of axes one block may move (a count, no unit): 4
    /// (four-axis linkage) or 5 (plain linearisation within --tolerance).
    #[arg(long, value_name = "N", default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=6))]
    pub max_axes: u32,
    /// The rotary that moves in half steps around the other (default: the one
    /// nearer the workpiece, seed 003's A).
    #[arg(long, value_name = "AXIS")]
    pub split_axis: Option<String>,
    /// Write the output here (atomically). Default: standard output.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Decimals of every axis word (a count, 0–12; the words are in mm or
    /// inch and degrees), overriding the machine file.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=12))]
    pub decimals: Option<u32>,
    /// Write the report (blocks, nonlinear error, cycle time) as JSON here.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// When pose mode starts (pose programs).
    #[arg(long, value_enum, default_value = "tcp")]
    pub pose_start: PoseStartArg,
    /// Print no report on standard error.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

fn parse_insert(s: &str) -> std::result::Result<usize, String> {
    let n: usize = s
        .parse()
        .map_err(|_| format!("{s}: expected an even number of points, e.g. 2"))?;
    if n == 0 || !n.is_multiple_of(2) {
        return Err(format!(
            "{n}: the staggered pattern inserts an even number of points (2 is seed 003)"
        ));
    }
    Ok(n)
}

/// Runs `kinpost linkage`.
pub fn linkage(a: LinkageArgs) -> Result<()> {
    super::check_outputs(
        &[
            ("-o", a.output.as_deref()),
            ("--report", a.report.as_deref()),
        ],
        &[a.input.as_deref(), a.machine.file(), a.job.inputs()],
    )?;
    let base = a.machine.load()?;
    let mode = match (a.insert, a.tolerance) {
        (Some(n), _) => Mode::Insert(n),
        (None, Some(t)) if t.is_finite() && t > 0.0 => Mode::Tolerance(t),
        (None, Some(t)) => {
            return Err(Error::Usage(format!(
                "--tolerance {t}: expected a length > 0 mm"
            )));
        }
        (None, None) => Mode::Tolerance(0.001),
    };
    let pair = match &a.split_axis {
        None => None,
        Some(name) => {
            let split = base
                .chain
                .joint_index(name)
                .filter(|&j| base.chain.joints()[j].kind == JointKind::Revolute)
                .ok_or_else(|| {
                    Error::Usage(format!(
                        "--split-axis {name}: not a rotary axis of {}",
                        base.name
                    ))
                })?;
            let held = (0..base.chain.dof())
                .find(|&j| j != split && base.chain.joints()[j].kind == JointKind::Revolute)
                .ok_or_else(|| Error::Usage(format!("{} has no second rotary axis", base.name)))?;
            Some(RotaryPair { split, held })
        }
    };
    let mut inp = input::open(a.input.as_deref())?;
    super::require_program(&mut inp)?;
    // The job's machine has the same joints as `base`.
    let machine = a.job.machine(&base, Some(&mut inp))?;
    // A CAM header can run past 4 KiB before the TCP code.
    let poses = looks_like_poses(&input::peek_far(&mut *inp.reader)?);
    if poses && crate::cl::looks_like_cl(&input::peek(&mut *inp.reader)?) {
        return Err(Error::Usage(format!(
            "{}: APT CL; linkage reads G-code: convert it with `kinpost post` first and pass its output",
            inp.name
        )));
    }
    let opts = LinkageOptions {
        mode,
        max_axes: a.max_axes as usize,
        decimals: a.decimals,
        pair,
        file_name: inp.name.clone(),
        pose_start: match a.pose_start {
            PoseStartArg::On => PoseStart::On,
            PoseStartArg::Tcp => PoseStart::Off,
        },
        ..LinkageOptions::default()
    };
    let report = write_atomically(a.output.as_deref(), |out| {
        run_linkage(&machine, &mut inp.reader, out, &opts, poses)
    })?;
    if let Some(r) = &a.report {
        let text = serde_json::to_string_pretty(&report).unwrap_or_default();
        write_atomically(Some(r), |w| {
            w.write_all(text.as_bytes())
                .map_err(|e| Error::io(r.display().to_string(), e))
        })?;
    }
    if !a.quiet && !crate::output::standard_output_closed() {
        eprint!("{}", report.to_text());
    }
    Ok(())
}
