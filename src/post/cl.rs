//! `kinpost post` on APT CL data: the statements, lowered
//! ([`crate::cl::lower`]), become blocks of G-code in the machine's axes.

use super::cl_motion;
use super::{AxisWriter, PoseSolver, PostOptions, PostStats, unreachable_axis};
use crate::cl::{ClReader, ClStatement, FeedUnit, SpindleDir};
use crate::error::{Error, Location, Result};
use crate::machine::{Machine, Pose};
use crate::program::Units;
use nalgebra::Vector3;
use std::io::{BufRead, Write};

/// Converts APT CL data to a G-code program for `machine`.
///
/// Statements are translated: `GOTO` → `G0`/`G1` with the machine's axes,
/// `FEDRAT` → `F`, `RAPID` → `G0` for the next `GOTO`, `LOADTL` → `T.. M6`,
/// `SPINDL` → `S.. M3/M4/M5`, `COOLNT` → `M7/M8/M9`, `FINI` → `M30`,
/// `END` → `M2`, `$$` and `PARTNO` → comments. `CIRCLE`, `CYCLE`, `CSYS`,
/// `CUTCOM`, `LOAD/TOOL` and the other forms CAM systems write are lowered
/// first ([`crate::cl::lower`]); a statement that moves the tool and is not
/// converted is an error, any other statement is kept as a comment. An arc
/// is a `G2`/`G3` and a hole a canned cycle where the machine's kinematics
/// allow (`post/cl_motion.rs`, docs/programs.md), else their moves.
pub fn post_cl<R: BufRead, W: Write + ?Sized>(
    machine: &Machine,
    solver: &mut dyn PoseSolver,
    input: R,
    out: &mut W,
    opts: &PostOptions,
    mut progress: impl FnMut(u64),
) -> Result<PostStats> {
    let io = |e: std::io::Error| Error::io("<output>", e);
    let mut stats = PostStats::default();
    let mut writer = AxisWriter::new(machine, opts.decimals);
    let mut previous: Option<crate::machine::chain::JointValues> = None;
    let mut axis = Vector3::z();
    let mut rapid_next = false;
    let mut units = Units::Mm;
    let mut feed: Option<f64> = None;
    let mut feed_written: Option<f64> = None;
    let mut motion_written: Option<u8> = None;
    let mut plane_written: Option<u8> = None;
    let mut bytes_read = 0u64;
    // `--feed inverse-time`: the feed is per revolution (no conversion),
    // the output is in G93, the last programmed tool tip (mm).
    let mut per_rev = false;
    let mut g93 = false;
    let mut last_tip: Option<Vector3<f64>> = None;
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
    // Statements an arc or a hole turned into (its moves, or the steps of
    // its canned form), before the next record.
    let mut pending: std::collections::VecDeque<crate::cl::ClRecord> = Default::default();
    while let Some(record) = pending.pop_front().map(Ok).or_else(|| records.next()) {
        let record = record?;
        // Back to G94 before anything but a straight move in pose order
        // (an arc, a hole, the end): it keeps the programmed feed.
        if g93
            && matches!(
                record.statement,
                ClStatement::Arc(_) | ClStatement::Hole(_) | ClStatement::End
            )
        {
            writeln!(out, "G94").map_err(io)?;
            g93 = false;
            feed_written = None;
        }
        stats.lines += 1;
        bytes_read += record.text.len() as u64;
        progress(bytes_read);
        let loc = Location::new(&opts.file_name, record.line, record.col);
        let text = String::from_utf8_lossy(&record.text).trim().to_string();
        match &record.statement {
            ClStatement::Goto { tip, axis: a } => {
                let scale = units.mm_per_unit();
                let tip = Vector3::new(tip[0], tip[1], tip[2]) * scale;
                if let Some(a) = a {
                    axis = Vector3::new(a[0], a[1], a[2]);
                }
                let norm = axis.norm();
                if norm.is_nan()
                    || norm <= 1e-12
                    || (norm - 1.0).abs() > crate::program::modal::TOOL_VECTOR_TOLERANCE
                {
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
                    stats.warnings.push(format!(
                        "{loc}: tool axis of length {norm:.9} normalised to unit length"
                    ));
                }
                let pose = Pose::new(tip, axis / norm);
                let solved = solver
                    .solve(&pose, previous.as_deref(), record.line)
                    .map_err(|m| Error::input_with(loc.clone(), m, text.clone()))?;
                if solved.axis_miss_rad > opts.axis_tolerance_rad {
                    return Err(Error::input_with(
                        loc,
                        unreachable_axis(
                            &machine.name,
                            solved.axis_miss_rad,
                            opts.axis_tolerance_rad,
                        ),
                        text,
                    ));
                }
                stats.max_axis_miss_rad = stats.max_axis_miss_rad.max(solved.axis_miss_rad);
                stats.poses += 1;
                if let Some(prev) = &previous
                    && let Some(w) = crate::machine::midblock::branch_change_warning(
                        machine, prev, &solved.q, &pose,
                    )
                {
                    stats.warnings.push(format!("{loc}: {w}"));
                }
                let words = writer
                    .words(&solved.q, Units::Mm, true, opts.modal_axes, " ")
                    .map_err(|m| Error::input(loc.clone(), m))?;
                let motion = if rapid_next { 0 } else { 1 };
                rapid_next = false;
                // Inverse time: a feed move per minute that turns a rotary
                // axis and moves the tip lasts tip path / feed.
                let inverse_f = match (opts.inverse_time, motion, per_rev, feed, &previous) {
                    (true, 1, false, Some(f), Some(p)) => {
                        let turns = machine
                            .chain
                            .joints()
                            .iter()
                            .zip(p.iter().zip(&solved.q))
                            .any(|(j, (a, b))| {
                                j.kind == crate::machine::JointKind::Revolute
                                    && (a - b).abs() > 1e-12
                            });
                        let path = last_tip.map_or(0.0, |t| (tip - t).norm());
                        (turns && path > crate::program::inverse_time::MIN_TIP_PATH_MM)
                            .then(|| f / path)
                    }
                    _ => None,
                };
                let mut block = String::new();
                match (inverse_f, g93) {
                    (Some(_), false) => block.push_str("G93 "),
                    (None, true) => {
                        block.push_str("G94 ");
                        feed_written = None;
                    }
                    _ => {}
                }
                g93 = inverse_f.is_some();
                if motion_written != Some(motion) {
                    block.push_str(if motion == 0 { "G0 " } else { "G1 " });
                    motion_written = Some(motion);
                }
                // Axis names and digits: ASCII.
                block.push_str(std::str::from_utf8(words).unwrap_or_default());
                if let Some(f93) = inverse_f {
                    block.push_str(" F");
                    block.push_str(&crate::program::inverse_time::feed_text(f93));
                    feed_written = None;
                } else if motion == 1 && feed.is_some() && feed != feed_written {
                    block.push_str(" F");
                    cl_motion::push_number(&mut block, feed.unwrap_or(0.0));
                    feed_written = feed;
                }
                writeln!(out, "{}", block.trim_end()).map_err(io)?;
                previous = Some(solved.q);
                last_tip = Some(tip);
            }
            ClStatement::Fedrat { value, unit } => {
                feed = Some(match unit {
                    FeedUnit::Ipm => value * 25.4,
                    FeedUnit::Unspecified => value * units.mm_per_unit(),
                    _ => *value,
                });
                per_rev = matches!(unit, FeedUnit::Mmpr | FeedUnit::Ipr);
                if per_rev {
                    writeln!(out, "({})", sanitize_comment(&text)).map_err(io)?;
                }
            }
            ClStatement::Rapid => rapid_next = true,
            ClStatement::TlAxis(a) => axis = Vector3::new(a[0], a[1], a[2]),
            ClStatement::LoadTl(n) => writeln!(out, "T{n} M6").map_err(io)?,
            ClStatement::Spindle { rpm, dir, off } => {
                if *off {
                    writeln!(out, "M5").map_err(io)?;
                } else {
                    let m = match dir {
                        Some(SpindleDir::CounterClockwise) => "M4",
                        _ => "M3",
                    };
                    match rpm {
                        Some(s) => writeln!(out, "S{} {m}", crate::program::format::fixed(*s, 0))
                            .map_err(io)?,
                        None => writeln!(out, "{m}").map_err(io)?,
                    }
                }
            }
            ClStatement::Coolant(on) => {
                writeln!(out, "{}", if *on { "M8" } else { "M9" }).map_err(io)?
            }
            ClStatement::Units(u) => {
                units = match u {
                    crate::cl::ClUnits::Inches => Units::Inch,
                    crate::cl::ClUnits::Mm => Units::Mm,
                };
                writeln!(out, "({})", sanitize_comment(&text)).map_err(io)?;
            }
            ClStatement::Comment(c) => {
                writeln!(out, "({})", sanitize_comment(c.trim())).map_err(io)?
            }
            ClStatement::End => {
                let t = text.to_ascii_uppercase();
                writeln!(out, "{}", if t.starts_with("FINI") { "M30" } else { "M2" }).map_err(io)?
            }
            ClStatement::Multax(_) | ClStatement::Other { .. } => {
                writeln!(out, "({})", sanitize_comment(&text)).map_err(io)?
            }
            ClStatement::Block(b) => {
                if b == "G80" {
                    motion_written = None;
                }
                writeln!(out, "{b}").map_err(io)?
            }
            ClStatement::Warning(w) => stats.warnings.push(w.clone()),
            ClStatement::Arc(arc) => {
                let scale = units.mm_per_unit();
                let plan = match (&previous, rapid_next) {
                    (Some(p), false) => {
                        cl_motion::plan_arc(machine, solver, opts, arc, p, scale, record.line)
                    }
                    _ => None,
                };
                let Some(plan) = plan else {
                    let steps = arc.moves.iter().cloned();
                    cl_motion::put_back(&mut pending, &record, steps);
                    continue;
                };
                let mut block = cl_motion::arc_block(&mut writer, &plan, &mut plane_written)
                    .map_err(|m| Error::input(loc.clone(), m))?;
                if feed.is_some() && feed != feed_written {
                    block.push_str(" F");
                    cl_motion::push_number(&mut block, feed.unwrap_or(0.0));
                    feed_written = feed;
                }
                writeln!(out, "{block}").map_err(io)?;
                motion_written = Some(plan.motion);
                axis = Vector3::from(arc.tool_axis);
                stats.poses += 1;
                previous = Some(plan.q_end);
                last_tip = Some(Vector3::from(arc.end) * scale);
            }
            ClStatement::Hole(hole) => {
                let scale = units.mm_per_unit();
                let (line, prev) = (record.line, previous.as_deref());
                let plan = cl_motion::plan_hole(machine, solver, opts, hole, prev, scale, line);
                match (plan, hole.positioned) {
                    (Some(plan), true) => {
                        let block = cl_motion::hole_block(
                            &mut writer,
                            hole,
                            &plan,
                            scale,
                            feed,
                            &mut plane_written,
                        )
                        .map_err(|m| Error::input(loc.clone(), m))?;
                        writeln!(out, "{block}").map_err(io)?;
                        feed_written = None;
                        rapid_next = false;
                        motion_written = hole.code;
                        axis = Vector3::from(hole.axis);
                        stats.poses += 1;
                        previous = Some(plan.q_after(hole));
                        let after = if hole.retract_to_r {
                            hole.r_plane
                        } else {
                            hole.clear
                        };
                        last_tip = Some(Vector3::from(after) * scale);
                        let after = hole.feed_after.iter().cloned();
                        cl_motion::put_back(&mut pending, &record, after);
                    }
                    (Some(plan), false) => {
                        let steps = cl_motion::canned_steps(hole, plan.preposition).into_iter();
                        cl_motion::put_back(&mut pending, &record, steps);
                    }
                    (None, _) => match &hole.moves {
                        Some(moves) => {
                            let steps = moves.iter().cloned();
                            cl_motion::put_back(&mut pending, &record, steps);
                        }
                        None => {
                            return Err(Error::input_with(
                                loc,
                                cl_motion::not_canned(&machine.name),
                                text,
                            ));
                        }
                    },
                }
            }
        }
    }
    if g93 {
        writeln!(out, "G94").map_err(io)?;
    }
    Ok(stats)
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
