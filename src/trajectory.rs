//! A program as a joint trajectory: the commanded joint values of every
//! motion block, whether the program is written in tool poses (solved by the
//! machine's theoretical inverse kinematics, continuing from the previous
//! block, and refused where the machine misses the tool axis by more than
//! the tolerance, as `post` refuses it) or in machine axes. `analyze`,
//! `simulate` and `diagnose` read programs through it.

use std::io::BufRead;

use crate::error::{Error, Location, Result};
use crate::machine::chain::JointValues;
use crate::machine::{IkSolver, Machine, Pose};
use crate::program::PoseStart;
use crate::program::source::{arc_joint_path, cl_poses, looks_like_poses, machine_axis_blocks};

/// One motion block of a program as joint values.
#[derive(Debug, Clone)]
pub struct TrajectoryBlock {
    /// 1-based line number of the block.
    pub line: usize,
    /// Joint values after the block, chain order, mm / rad.
    pub q: Vec<f64>,
    /// The programmed tool pose (tip in mm, unit axis; workpiece frame),
    /// for a program of tool poses.
    pub pose: Option<Pose>,
    /// Feed in force, mm/min (None in G93/G95 or when none was given).
    pub feed_mm_min: Option<f64>,
    /// Millimetres per unit of the feed's length (25.4 when F is in
    /// inches a minute): a move of rotaries alone runs at F as programmed,
    /// deg/min, which is `feed_mm_min / feed_unit_mm`.
    pub feed_unit_mm: f64,
    /// Inverse-time feed in force (G93), 1/min: the block takes 1/F
    /// minutes, whatever its length.
    pub inverse_time: Option<f64>,
    /// Rapid move (G0 / RAPID).
    pub rapid: bool,
    /// The block does not start where the previous one ended (it follows a
    /// move in machine coordinates or to the reference point, `G53`,
    /// `G28`, `G30`, whose end the program does not give): the segment
    /// between them is not known.
    pub restart: bool,
    /// A circular move in machine axes (`G2`, `G3`): not a straight move
    /// of the joints.
    pub arc: bool,
    /// The joint values (chain order, mm / rad) a circular move in
    /// machine axes passes through between the previous block and `q`
    /// (both excluded), in order ([`arc_joint_path`]), where asked for;
    /// empty otherwise.
    pub via: Vec<Vec<f64>>,
}

/// The theoretical joint values of `pose` (continuing from `previous`), or
/// the reason it cannot be reached: an IK failure, or a tool axis the
/// machine misses by more than `tolerance_rad` (the same refusal as `post`).
pub fn reachable(
    ik: &IkSolver,
    machine: &Machine,
    pose: &Pose,
    previous: Option<&[f64]>,
    tolerance_rad: f64,
) -> std::result::Result<JointValues, String> {
    let s = ik.solve(pose, previous).map_err(|e| e.to_string())?;
    if s.axis_miss_rad > tolerance_rad {
        return Err(crate::post::unreachable_axis(
            &machine.name,
            s.axis_miss_rad,
            tolerance_rad,
        ));
    }
    Ok(s.q)
}

/// How [`joint_trajectory`] reads a program.
#[derive(Debug, Clone, Copy)]
pub struct TrajectoryOptions {
    /// When pose mode starts (G-code pose programs).
    pub start: PoseStart,
    /// A tool axis missed by more than this (rad) is an error naming the
    /// line.
    pub axis_tolerance_rad: f64,
    /// Give each circular move in machine axes the points it passes
    /// through ([`TrajectoryBlock::via`]); an arc that cannot be followed
    /// is then refused at its line.
    pub arc_points: bool,
    /// Read G-code as a program of tool poses whatever its first bytes
    /// look like (`analyze --errors`, which reads poses alone: a program
    /// whose TCP code comes after its first 4 KB). Its blocks before pose
    /// mode are then followed as `post` follows them.
    pub as_poses: bool,
    /// APT CL: the units of a program without `UNITS` (`--units`; `None`:
    /// mm, with a warning).
    pub cl_units: Option<crate::cl::ClUnits>,
}

/// Calls `f` with every motion block of the program read from `input`
/// (`head`: its first bytes, which tell tool poses from machine axes; `file`
/// names it in messages), in order, read as `opts` says.
pub fn joint_trajectory<R: BufRead>(
    machine: &Machine,
    input: R,
    head: &[u8],
    file: &str,
    opts: TrajectoryOptions,
    mut f: impl FnMut(TrajectoryBlock) -> Result<()>,
) -> Result<()> {
    let TrajectoryOptions {
        axis_tolerance_rad,
        arc_points,
        as_poses,
        cl_units,
        ..
    } = opts;
    if crate::cl::looks_like_cl(head) {
        let mut ik = IkSolver::new(machine);
        let mut previous: Option<JointValues> = None;
        // Under cutter compensation: the line of its `CUTCOM` and the joint
        // values when it went on (those of the pose before its first move).
        let mut comp_reference: Option<(usize, Vec<f64>)> = None;
        cl_poses(input, file, cl_units, |ev| {
            let q = reachable(
                &ik,
                machine,
                &ev.pose,
                previous.as_deref(),
                axis_tolerance_rad,
            )
            .map_err(|m| Error::input(Location::new(file, ev.line, 1), m))?;
            // A move `post` refuses under cutter compensation is refused
            // here too: the controller's offset would not be the one the
            // CL asks for, and the path analysed would not be run.
            if let Some(on) = ev.cutter_comp {
                if comp_reference.as_ref().is_none_or(|(l, _)| *l != on.line) {
                    let r = previous.as_deref().unwrap_or(&q).to_vec();
                    comp_reference = Some((on.line, r));
                }
                let reference = comp_reference.as_ref().map_or(&[][..], |(_, r)| r);
                if let Some(m) = crate::post::cl_cutter_comp_refusal(
                    machine,
                    &mut ik,
                    axis_tolerance_rad,
                    &q,
                    &ev.pose,
                    reference,
                    on,
                    ev.line,
                ) {
                    return Err(Error::input(Location::new(file, ev.line, 1), m));
                }
            }
            let block = TrajectoryBlock {
                line: ev.line,
                q: q.to_vec(),
                pose: Some(ev.pose),
                feed_mm_min: ev.feed_mm_min,
                // `post` writes a CL program's feeds in mm a minute.
                feed_unit_mm: 1.0,
                inverse_time: None,
                rapid: ev.rapid,
                restart: false,
                arc: false,
                via: Vec::new(),
            };
            previous = Some(q);
            f(block)
        })
    } else if as_poses || looks_like_poses(head) {
        gcode_trajectory(machine, input, file, opts, f)
    } else {
        machine_axis_blocks(machine, input, file, arc_points, |ev| {
            f(TrajectoryBlock {
                line: ev.line,
                q: ev.q,
                pose: None,
                feed_mm_min: ev.feed_mm_min,
                feed_unit_mm: ev.feed_unit_mm,
                inverse_time: ev.inverse_time,
                rapid: ev.rapid,
                restart: ev.restart,
                arc: ev.arc,
                via: ev.via,
            })
        })
    }
}

/// [`joint_trajectory`] of a G-code pose program, read as `post` reads it
/// (its [`crate::post::BlockReader`]): each pose solved in order, and the
/// blocks in machine coordinates between poses (pose mode off) followed as
/// `post` follows them, each straight move (`G0`, `G1`) and each circular
/// move (`G2`, `G3`, with the points it passes through) a block of its own
/// (no pose). After a cycle there, or a block that leaves the machine
/// where the program does not say (`G28`, `G53`, `G92`), the next block
/// restarts.
fn gcode_trajectory<R: BufRead>(
    machine: &Machine,
    input: R,
    file: &str,
    opts: TrajectoryOptions,
    mut f: impl FnMut(TrajectoryBlock) -> Result<()>,
) -> Result<()> {
    let TrajectoryOptions {
        start,
        axis_tolerance_rad,
        arc_points,
        ..
    } = opts;
    use crate::post::{GcodeConverter, PostOptions, Start};
    use crate::program::{FeedMode, modal::Motion};
    let opts = PostOptions {
        pose_start: start,
        axis_tolerance_rad,
        file_name: file.to_string(),
        ..PostOptions::default()
    };
    let mut conv = GcodeConverter::new(machine, &opts);
    let reader = &mut conv.reader;
    reader.read_arcs();
    let ik = IkSolver::new(machine);
    // The joint values of the last block given to `f`.
    let mut last: Option<Vec<f64>> = None;
    let mut restart = false;
    let mut scratch = Vec::new();
    // The spindle's speed, for feeds per revolution.
    let mut spindle = crate::program::spindle::Spindle::default();
    let inverse_of = |m: &crate::program::ModalState| match m.feed_mode {
        FeedMode::InverseTime => m.feed,
        _ => None,
    };
    // Where the G-code frame in force was set (G68, G254, …).
    let mut frame_from: Option<usize> = None;
    for line in crate::gcode::LineReader::new(input) {
        let line = line.map_err(|e| Error::io(file, e))?;
        scratch.clear();
        spindle.line(&line);
        let mut begun = reader.begin(None, &line, &mut scratch)?;
        crate::program::unfollowed::check_line(&line, file, reader.take_unfollowed())?;
        frame_from =
            crate::program::frames::frame_since(reader.modal().frame_seen, frame_from, line.number);
        if begun.is_none() {
            // A move in machine axes under a frame goes where its words do
            // not say: refused, as in a program in machine axes alone.
            if let Some(at) = frame_from
                && let Some(item) = line.items.iter().find(|i| {
                    matches!(&i.kind, crate::gcode::ItemKind::Word(w)
                        if machine.axes.iter().any(|a| w.is(&a.name)))
                })
            {
                return Err(Error::input_with(
                    crate::error::Location::new(file, line.number, item.start + 1),
                    crate::program::frames::move_under(crate::program::frames::GCODE_FRAMES, at),
                    line.text_lossy(),
                ));
            }
            match reader.start() {
                Start::Followed => {
                    // Only a line that moved the machine is a block (a
                    // full circle ends where it starts: an arc is a line
                    // with axis or centre words).
                    let modal = reader.modal();
                    let arc = modal.motion == Motion::Arc
                        && line.words().any(|w| {
                            ["I", "J", "K", "R", "CR"].iter().any(|a| w.is(a))
                                || machine.axes.iter().any(|a| w.is(&a.name))
                        });
                    let Some(q) = reader
                        .previous()
                        .filter(|q| arc || last.as_deref() != Some(*q))
                        .map(<[f64]>::to_vec)
                    else {
                        continue;
                    };
                    let from = last.replace(q.clone());
                    let via = match (modal.motion, from) {
                        (Motion::Rapid | Motion::Linear, _) => Vec::new(),
                        (Motion::Arc, Some(_)) if !arc_points && !restart => Vec::new(),
                        (Motion::Arc, Some(from)) if !restart => {
                            let units = modal.units.mm_per_unit();
                            arc_joint_path(
                                machine,
                                reader.arc_modes(),
                                &line,
                                file,
                                &from,
                                &q,
                                units,
                            )?
                        }
                        _ => {
                            // A cycle, or an arc from where the program
                            // does not say: the next block starts afresh
                            // from its end.
                            restart = true;
                            continue;
                        }
                    };
                    f(TrajectoryBlock {
                        line: line.number,
                        q,
                        pose: None,
                        feed_mm_min: spindle.feed_mm_min(
                            modal.feed_mode,
                            modal.feed,
                            modal.feed_units,
                        ),
                        feed_unit_mm: modal.feed_units.mm_per_unit(),
                        inverse_time: inverse_of(modal),
                        rapid: modal.motion == Motion::Rapid,
                        restart: std::mem::take(&mut restart),
                        arc: modal.motion == Motion::Arc,
                        via,
                    })?;
                }
                Start::Unknown => restart = true,
                Start::AtPose => {}
            }
            continue;
        }
        // A pose, or the points of an arc in pose mode one by one.
        while let Some(pending) = begun.take() {
            // Where the block starts is not known (after G28, G53 between
            // poses): the path goes on afresh from its end.
            if pending.from(None).is_none() && last.is_some() {
                restart = true;
            }
            let q = reachable(
                &ik,
                machine,
                &pending.pose,
                pending.solve_from(reader.previous()),
                axis_tolerance_rad,
            )
            .and_then(|q| pending.check_pinned(machine, &q).map(|()| q))
            .map_err(|m| reader.solve_error(&line, &pending, m))?;
            reader.begun(&q);
            // A modulo axis turns the short way, as the controller turns it
            // (the solution is in [0, 2π): 359° to 0° is a turn of 1°).
            let mut q = q.to_vec();
            if let Some(before) = &last {
                for axis in &machine.axes {
                    if axis.rotary == crate::machine::RotaryMode::Modulo {
                        let j = axis.joint;
                        q[j] = crate::machine::rotary::unwind_near(q[j], before[j]);
                    }
                }
            }
            last = Some(q.clone());
            let modal = reader.modal();
            f(TrajectoryBlock {
                line: line.number,
                q,
                pose: Some(pending.pose),
                feed_mm_min: spindle.feed_mm_min(modal.feed_mode, modal.feed, modal.feed_units),
                feed_unit_mm: modal.feed_units.mm_per_unit(),
                inverse_time: inverse_of(modal),
                rapid: pending.meaning.motion == Motion::Rapid,
                restart: std::mem::take(&mut restart),
                arc: false,
                via: Vec::new(),
            })?;
            if !reader.line_done() {
                begun = reader.begin(None, &line, &mut scratch)?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::NoErrors;

    fn run(machine: &Machine, text: &str) -> Result<Vec<TrajectoryBlock>> {
        let mut out = Vec::new();
        joint_trajectory(
            machine,
            text.as_bytes(),
            text.as_bytes(),
            "p.nc",
            TrajectoryOptions {
                start: PoseStart::Off,
                axis_tolerance_rad: 1e-4,
                arc_points: true,
                as_poses: false,
                cl_units: None,
            },
            |b| {
                out.push(b);
                Ok(())
            },
        )?;
        Ok(out)
    }

    /// Pose blocks come back as joint values that put the theoretical
    /// machine on the programmed pose (forward kinematics, evaluated here),
    /// with the line, feed and rapid flag of the block; the same moves in
    /// machine axes give the same joint values.
    #[test]
    fn poses_and_machine_axes_give_one_trajectory() {
        let m = Machine::embedded("xyzac-trt").unwrap();
        let poses = "G21 G90 G94\nG43.4 H1\nG0 X10 Y0 Z50 I0 J0 K1\nG1 X12 Y3 Z40 I0 J0.5 K0.8660254037844386 F600\nG1 X0 Y20 Z30 I0.3 J0 K0.9539392014169456\n";
        let got = run(&m, poses).unwrap();
        assert_eq!(got.len(), 3);
        assert_eq!(
            got.iter().map(|b| b.line).collect::<Vec<_>>(),
            vec![3, 4, 5]
        );
        assert!(got[0].rapid && !got[1].rapid);
        assert_eq!(got[1].feed_mm_min, Some(600.0));
        for b in &got {
            let want = b.pose.unwrap();
            let p = m.chain.pose(&b.q, &NoErrors);
            assert!((p.tip - want.tip).norm() < 1e-9, "line {}", b.line);
            assert!(p.axis_angle(&want) < 1e-12, "line {}", b.line);
        }
        // The same moves in machine axes (words in mm and degrees).
        let mut axes = String::from("G21 G90 G94\n");
        for b in &got {
            let words: Vec<String> = m
                .axes
                .iter()
                .map(|a| {
                    let v = b.q[a.joint];
                    let v = match a.kind {
                        crate::machine::JointKind::Revolute => v.to_degrees(),
                        crate::machine::JointKind::Prismatic => v,
                    };
                    format!("{}{v:.12}", a.name)
                })
                .collect();
            axes.push_str(&format!("G1 {} F600\n", words.join(" ")));
        }
        let again = run(&m, &axes).unwrap();
        assert_eq!(again.len(), 3);
        for (a, b) in again.iter().zip(&got) {
            assert!(a.pose.is_none());
            for (x, y) in a.q.iter().zip(&b.q) {
                assert!((x - y).abs() < 1e-9, "{:?} vs {:?}", a.q, b.q);
            }
        }
    }

    /// A tool axis a four-axis machine cannot reach is refused, naming
    /// the file and line.
    #[test]
    fn an_unreachable_tool_axis_names_its_line() {
        let m = Machine::embedded("xyza-4axis").unwrap();
        let text = "G21 G90 G94\nG43.4 H1\nG1 X0 Y0 Z50 I0 J0 K1 F600\nG1 X0 Y0 Z50 I0.5 J0 K0.8660254037844386\n";
        let e = run(&m, text).unwrap_err().to_string();
        assert!(e.starts_with("p.nc:4"), "{e}");
    }
}
