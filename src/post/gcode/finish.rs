//! The second half of the G-code converter: a solved pose block written
//! ([`BlockWriter::finish`]).

use super::arc::line_end;
use super::{ArcPart, BlockWriter, PendingPose, machine_at, separator, solve_error};
use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, Line};
use crate::post::{SolvedPose, unreachable_axis};
use crate::program::modal::Motion;
use crate::program::rewrite::rewrite;

impl BlockWriter<'_> {
    /// The error of a failed solve of `pending` (programmed at `line`).
    pub fn solve_error(&self, line: &Line, pending: &PendingPose, message: String) -> Error {
        solve_error(&self.opts.file_name, line, pending, message)
    }

    /// Writes the pose block `pending` of `line` with the machine axes of
    /// `solved`.
    pub fn finish(
        &mut self,
        line: &Line,
        pending: &PendingPose,
        solved: &SolvedPose,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let opts = self.opts;
        let meaning = &pending.meaning;
        let loc = |item: Option<usize>| {
            let col = item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Location::new(&opts.file_name, line.number, col)
        };
        let last = self.last.take();
        let from = pending.from(last.as_deref());
        if let Err(m) = pending.check_pinned(self.machine, solved.theoretical_q()) {
            return Err(Error::input_with(
                loc(meaning.pose_items.first().copied()),
                m,
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        if let Err(m) = self.check_arc_rotaries(pending.arc, solved.theoretical_q()) {
            return Err(Error::input_with(
                loc(meaning.pose_items.first().copied()),
                m,
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        if solved.axis_miss_rad > opts.axis_tolerance_rad {
            return Err(Error::input_with(
                loc(meaning.pose_items.first().copied()),
                unreachable_axis(
                    &self.machine.name,
                    solved.axis_miss_rad,
                    opts.axis_tolerance_rad,
                ),
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        self.max_axis_miss_rad = self.max_axis_miss_rad.max(solved.axis_miss_rad);
        self.poses += 1;
        let sep = match pending.arc {
            ArcPart::Later => " ",
            _ => separator(line, &meaning.pose_items),
        };
        if pending.after_other {
            self.axes.write_all_next();
        }
        if pending.moved && !meaning.absolute {
            self.axes.moved_to(from);
        }
        let words_text = self
            .axes
            .words(
                &solved.q,
                meaning.units,
                meaning.absolute,
                opts.modal_axes,
                sep,
            )
            .map_err(|m| Error::input(loc(meaning.pose_items.first().copied()), m))?;
        if pending.arc != ArcPart::None {
            // An arc's point: a straight move (inverse time is refused).
            let mut words = Vec::with_capacity(words_text.len() + 3);
            words.extend_from_slice(b"G1");
            if !words_text.is_empty() {
                words.extend_from_slice(sep.as_bytes());
                words.extend_from_slice(words_text);
            }
            if pending.arc == ArcPart::Later {
                out.extend_from_slice(&words);
                out.extend_from_slice(line_end(line));
            } else {
                rewrite(
                    line,
                    &meaning.pose_items,
                    &words,
                    &meaning.tcp_codes,
                    &meaning.tcp_offset_items,
                    out,
                );
            }
            self.last = Some(solved.q.clone());
            return Ok(());
        }
        let feed = opts.inverse_time.then(|| {
            let moved = from.is_some_and(|p| {
                self.machine
                    .chain
                    .joints()
                    .iter()
                    .zip(p.iter().zip(&solved.q))
                    .any(|(j, (a, b))| {
                        j.kind == crate::machine::JointKind::Revolute && (a - b).abs() > 1e-12
                    })
            });
            let tip = pending.pose.tip;
            self.feed.pose_block(meaning, pending.start_tip, tip, moved)
        });
        if let Some(crate::program::inverse_time::PoseFeed::Append(extra)) = feed {
            let mut drop = meaning.tcp_offset_items.clone();
            drop.extend(
                line.items
                    .iter()
                    .enumerate()
                    .filter_map(|(i, it)| match &it.kind {
                        ItemKind::Word(w) if w.address == "F" => Some(i),
                        ItemKind::Word(w)
                            if w.address == "G" && [93.0, 94.0].contains(&w.value) =>
                        {
                            Some(i)
                        }
                        _ => None,
                    }),
            );
            let mut words = words_text.to_vec();
            words.extend_from_slice(extra.as_bytes());
            rewrite(
                line,
                &meaning.pose_items,
                &words,
                &meaning.tcp_codes,
                &drop,
                out,
            );
        } else {
            rewrite(
                line,
                &meaning.pose_items,
                words_text,
                &meaning.tcp_codes,
                &meaning.tcp_offset_items,
                out,
            );
        }
        if matches!(meaning.motion, Motion::Linear | Motion::Rapid)
            && let Some(prev) = from
            && let Some(w) = crate::machine::midblock::branch_change_warning(
                machine_at(self.machine, self.opts, line.number),
                prev,
                &solved.q,
                &pending.pose,
            )
        {
            let at = loc(meaning.pose_items.first().copied());
            self.warnings.push(((line.number, 1), format!("{at}: {w}")));
        }
        self.last = Some(solved.q.clone());
        Ok(())
    }

    /// The joint values of the last pose written.
    pub fn last_joints(&self) -> Option<&[f64]> {
        self.last.as_deref()
    }
}
