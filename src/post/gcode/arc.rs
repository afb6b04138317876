//! Circular moves (`G2`/`G3`) in pose mode, as `post` and `compensate`
//! convert them: the tool tip on the arc in the program's coordinates, the
//! tool axis held (that of the pose before), as a controller's tool centre
//! point control moves it. With the rotary axes still, the machine's
//! linear axes carry the part's frame rigidly, so a straight move between
//! two points of the arc is a chord of it on the part too: the arc is
//! written as straight moves through its points, none farther than the
//! arc tolerance from the arc ([`crate::program::arc::ArcModes::points`]).
//! The arc's block carries the first move (its `G2`/`G3` written `G1`, its
//! centre or radius words dropped, every other word kept); each later
//! point is a `G1` block of its own after it.

use super::{BlockReader, BlockWriter, PendingPose};
use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, Line};
use crate::machine::JointKind;
use crate::post::pending::ArcPart;
use crate::program::arc::MAX_PIECES;
use crate::program::modal::{FeedMode, Motion};
use nalgebra::Vector3;

/// The addresses of an arc's own words besides its end point: the centre
/// (`I J K`), the radius (`R`, Sinumerik `CR=`) and the turns (LinuxCNC
/// `P`, Sinumerik `TURN=`).
const ARC_WORDS: [&str; 7] = ["I", "J", "K", "R", "CR", "P", "TURN"];

/// Largest turn of a rotary axis between two points of one arc, rad: the
/// arc holds the tool axis, so its points share their rotary positions.
const ROTARY_STILL_RAD: f64 = 1e-9;

/// The points of an arc not given out yet, and the pose they are given
/// out as.
pub(super) struct ArcRest {
    /// The points, tip in mm, in order (the last at the arc's end).
    points: std::vec::IntoIter<[f64; 3]>,
    /// The pose block of the arc's first point, of which each later point
    /// is a copy with its own tip.
    template: PendingPose,
}

impl BlockReader<'_> {
    /// The arc modes in force (plane, centre mode, direction) after the
    /// lines begun, when arcs are read ([`BlockReader::read_arcs`]).
    pub fn arc_modes(&self) -> &crate::program::arc::ArcModes {
        &self.arcs[0]
    }

    /// Follows the plane, centre mode and direction of `line` (its `G17`,
    /// `G90.1`, `G3`, …) when arcs are read as poses, also as they stand
    /// with the block delete switch on (`/` lines skipped).
    pub(super) fn follow_arc_modes(&mut self, line: &Line) {
        if !self.modal.arcs_as_poses {
            return;
        }
        let same = self.arcs[0] == self.arcs[1];
        self.arcs[0].apply(line);
        if line.bytes.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'/') {
            if same {
                self.arcs[1] = self.arcs[0];
            } else {
                self.arcs[1].apply(line);
            }
        }
    }

    /// Turns `pending`, the pose at the end of the arc of `line`, into the
    /// pose of the arc's first point and keeps the others for
    /// [`BlockReader::next_arc_point`].
    pub(super) fn begin_arc(&mut self, line: &Line, pending: &mut PendingPose) -> Result<()> {
        let opts = self.opts;
        let meaning = &pending.meaning;
        let at = |item: Option<usize>| {
            let col = item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Location::new(&opts.file_name, line.number, col)
        };
        let motion_item = line.items.iter().position(|it| {
            matches!(&it.kind, ItemKind::Word(w) if w.is("G") && [2.0, 3.0].contains(&w.value))
        });
        let blame = motion_item.or(meaning.pose_items.first().copied());
        let refuse = |col: Location, message: String| {
            Err(Error::input_with(
                col,
                message,
                String::from_utf8_lossy(&line.bytes),
            ))
        };
        if opts.inverse_time || meaning.feed_mode == FeedMode::InverseTime {
            return refuse(
                at(blame),
                "a circular move (G2/G3) in pose mode under inverse-time feed (G93, or --feed inverse-time): kinpost writes the arc as several straight moves, and its F gives the time of the whole arc; program the arc's feed per minute (G94), or have the CAM system linearise it".into(),
            );
        }
        if self.arcs[0] != self.arcs[1] {
            return refuse(
                at(blame),
                "a circular move (G2/G3) in pose mode after a block the controller may skip (`/`) changed the arc's plane, centre mode or direction: with the block delete switch on the arc runs otherwise; set them again without `/` before the arc".into(),
            );
        }
        let [a, b, _] = self.arcs[0].plane().axes();
        let centre = ["I", "J", "K"];
        if let Some(i) = line.items.iter().position(|it| {
            matches!(&it.kind, ItemKind::Word(w) if centre.iter().enumerate().any(|(k, c)| w.is(c) && k != a && k != b))
        }) {
            return refuse(
                at(Some(i)),
                format!(
                    "a centre word outside the plane of the arc ({}: {} {}): kinpost does not know what this control makes of it; drop it, or select the arc's plane",
                    self.arcs[0].plane().code(),
                    centre[a.min(b)],
                    centre[a.max(b)]
                ),
            );
        }
        let (Some(start), true) = (pending.start_tip, pending.start_known) else {
            return refuse(
                at(blame),
                "a circular move (G2/G3) in pose mode where the tool tip is not known (the first pose, or after a move home, a tool change or machine coordinates): it starts where the program does not say; give the start with a straight move first".into(),
            );
        };
        let end = pending.pose.tip;
        let points = self.arcs[0]
            .points(
                line,
                start.into(),
                end.into(),
                meaning.units.mm_per_unit(),
                opts.arc_tolerance_mm,
            )
            .map_err(|(col, message)| {
                Error::input_with(
                    Location::new(&opts.file_name, line.number, col),
                    message,
                    String::from_utf8_lossy(&line.bytes),
                )
            })?;
        if points.len() >= MAX_PIECES {
            return refuse(
                at(blame),
                format!(
                    "this circular move needs {MAX_PIECES} or more straight moves to stay within the arc tolerance ({} mm): raise --arc-tolerance, or have the CAM system linearise it",
                    opts.arc_tolerance_mm
                ),
            );
        }
        let mut points = points
            .into_iter()
            .map(|(_, p)| p)
            .collect::<Vec<_>>()
            .into_iter();
        let first = points.next().unwrap_or(end.into());
        pending.pose.tip = Vector3::from(first);
        pending.arc = ArcPart::First;
        self.arc_written = Some(line.number);
        let own = line
            .items
            .iter()
            .enumerate()
            .filter_map(|(i, it)| match &it.kind {
                ItemKind::Word(w) if ARC_WORDS.iter().any(|a| w.is(a)) => Some(i),
                _ => None,
            });
        let items = &mut pending.meaning.pose_items;
        items.extend(own.chain(motion_item));
        items.sort_unstable();
        items.dedup();
        if points.len() > 0 {
            let mut template = pending.clone();
            template.arc = ArcPart::Later;
            template.after_other = false;
            template.moved = false;
            template.start_known = true;
            template.meaning.tcp_codes.clear();
            template.meaning.tcp_offset_items.clear();
            template.meaning.warnings.clear();
            template.meaning.feed_item = None;
            template.start_tip = Some(pending.pose.tip);
            self.arc_rest = Some(ArcRest { points, template });
        }
        Ok(())
    }

    /// Outside pose mode, `Err` for a line that moves in the arc mode
    /// (`G2`/`G3`) of an arc kinpost wrote as `G1` moves: without a motion
    /// code of its own it would run as a straight move on the controller.
    pub(super) fn inherited_arc(&mut self, line: &Line) -> Result<()> {
        let Some(arc_line) = self.arc_written else {
            return Ok(());
        };
        let own_code = line
            .words()
            .any(|w| w.is("G") && [2.0, 3.0].contains(&w.value));
        if self.modal.motion != Motion::Arc || own_code {
            self.arc_written = None;
            return Ok(());
        }
        if self.modal.pose_mode {
            return Ok(());
        }
        let moving = line.items.iter().position(|it| {
            matches!(&it.kind, ItemKind::Word(w) if ARC_WORDS.iter().chain(&["X", "Y", "Z"]).any(|a| w.is(a))
                || self.machine.axes.iter().any(|a| w.is(&a.name)))
        });
        match moving {
            Some(i) => Err(Error::input_with(
                Location::new(&self.opts.file_name, line.number, line.items[i].start + 1),
                format!(
                    "this block moves in the arc mode (G2/G3) of line {arc_line}, which kinpost wrote as straight moves (G1) under TCP: on the controller it would run as a straight move; give it its motion code (G2 or G3)"
                ),
                String::from_utf8_lossy(&line.bytes),
            )),
            None => Ok(()),
        }
    }

    /// The pose of the next point of the arc begun last, if it has one
    /// left (the last is the arc's end).
    pub(super) fn next_arc_point(&mut self) -> Option<PendingPose> {
        let rest = self.arc_rest.as_mut()?;
        let Some(tip) = rest.points.next() else {
            self.arc_rest = None;
            return None;
        };
        let mut pose = rest.template.clone();
        pose.pose.tip = Vector3::from(tip);
        pose.continues = self.previous.clone();
        rest.template.start_tip = Some(pose.pose.tip);
        if rest.points.len() == 0 {
            self.arc_rest = None;
        }
        Some(pose)
    }

    /// Whether every pose of the line begun last is given out (an arc's
    /// points one by one).
    pub fn line_done(&self) -> bool {
        self.arc_rest.is_none()
    }
}

impl BlockWriter<'_> {
    /// For a pose of an arc, `Err` with a message when its rotary axes
    /// (`q`, the theoretical solution) are not those of the arc's first
    /// point: the straight moves between its points would then not be
    /// chords of the arc on the part.
    pub(super) fn check_arc_rotaries(&mut self, arc: ArcPart, q: &[f64]) -> Result<(), String> {
        let rotaries = self
            .machine
            .chain
            .joints()
            .iter()
            .zip(q)
            .filter(|(j, _)| j.kind == JointKind::Revolute)
            .map(|(_, v)| *v);
        match arc {
            ArcPart::None => {}
            ArcPart::First => {
                self.arc_rotaries.clear();
                self.arc_rotaries.extend(rotaries);
            }
            ArcPart::Later => {
                let turned = rotaries
                    .zip(&self.arc_rotaries)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                if turned > ROTARY_STILL_RAD {
                    return Err(format!(
                        "the machine reaches a point of this circular move only with its rotary axes turned by {:.6}° from the arc's first point (on this machine they depend on the tool tip too, or the held tool axis is at a singular or limit position): the straight moves kinpost writes would leave the arc; have the CAM system linearise it",
                        turned.to_degrees()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The line end of `line` (`\r\n` or `\n`), for the blocks added after it.
pub(super) fn line_end(line: &Line) -> &'static [u8] {
    if line.bytes.ends_with(b"\r\n") {
        b"\r\n"
    } else {
        b"\n"
    }
}
