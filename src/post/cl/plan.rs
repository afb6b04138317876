//! APT CL arcs and holes in the CL format's first pass: planned as
//! `G2`/`G3` and canned cycles through the planner (`post`) and written
//! there, or given out as their moves.

use super::{ClBack, ClFront, error_at, line, location};
use crate::cl::ClRecord;
use crate::error::{Error, Result};
use crate::post::PoseSolver;
use crate::post::cl_motion;
use nalgebra::Vector3;

impl ClFront<'_> {
    /// An arc: its `G2`/`G3` block when the planner finds one (written
    /// with `back`), else its moves queued.
    pub(super) fn arc(
        &mut self,
        back: Option<&mut ClBack<'_>>,
        record: &ClRecord,
        arc: &crate::cl::ArcMove,
        planner: Option<&mut dyn PoseSolver>,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let scale = self.units.mm_per_unit();
        let plan = match (planner, back, &self.previous, self.rapid_next) {
            (Some(solver), Some(back), Some(p), false) => {
                let cutcom = self.cutcom.is_some();
                cl_motion::plan_arc(
                    self.machine,
                    solver,
                    self.opts,
                    arc,
                    p,
                    scale,
                    record.line,
                    cutcom,
                )
                .map(|plan| (plan, back))
            }
            _ => None,
        };
        let Some((plan, back)) = plan else {
            cl_motion::put_back(&mut self.queue, arc.moves.iter().cloned());
            return Ok(());
        };
        back.apply_g80(self.g80);
        let mut block = cl_motion::arc_block(&mut back.writer, &plan, &mut back.plane_written)
            .map_err(|m| Error::input(location(self.opts, record), m))?;
        if self.feed.is_some() && self.feed != back.feed_written {
            block.push_str(" F");
            cl_motion::push_number(&mut block, self.feed.unwrap_or(0.0));
            back.feed_written = self.feed;
        }
        line(out, format_args!("{block}"));
        back.motion_written = Some(plan.motion);
        self.axis = Vector3::from(arc.tool_axis);
        back.poses += 1;
        back.previous_th = Some(plan.q_end.clone());
        self.previous = Some(plan.q_end.clone());
        back.previous = Some(plan.q_end);
        back.last_tip = Some(Vector3::from(arc.end) * scale);
        Ok(())
    }

    /// A hole: its canned cycle when the planner finds one (written with
    /// `back`; the steps before and after it queued), else its moves
    /// queued; a hole without moves is refused.
    pub(super) fn hole(
        &mut self,
        back: Option<&mut ClBack<'_>>,
        record: &ClRecord,
        hole: &crate::cl::HoleMove,
        planner: Option<&mut dyn PoseSolver>,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        let scale = self.units.mm_per_unit();
        let plan = match (planner, back) {
            (Some(solver), Some(back)) => {
                let prev = self.previous.as_deref();
                cl_motion::plan_hole(
                    self.machine,
                    solver,
                    self.opts,
                    hole,
                    prev,
                    scale,
                    record.line,
                )
                .map(|plan| (plan, back))
            }
            _ => None,
        };
        match (plan, hole.positioned) {
            (Some((plan, back)), true) => {
                back.apply_g80(self.g80);
                let block = cl_motion::hole_block(
                    &mut back.writer,
                    hole,
                    &plan,
                    scale,
                    self.feed,
                    &mut back.plane_written,
                )
                .map_err(|m| Error::input(location(self.opts, record), m))?;
                line(out, format_args!("{block}"));
                back.feed_written = None;
                self.rapid_next = false;
                back.motion_written = hole.code;
                self.axis = Vector3::from(hole.axis);
                back.poses += 1;
                let q = plan.q_after(hole);
                self.previous = Some(q.clone());
                back.previous_th = Some(q.clone());
                back.previous = Some(q);
                let after = if hole.retract_to_r {
                    hole.r_plane
                } else {
                    hole.clear
                };
                back.last_tip = Some(Vector3::from(after) * scale);
                cl_motion::put_back(&mut self.queue, hole.feed_after.iter().cloned());
            }
            (Some((plan, _)), false) => {
                let steps = cl_motion::canned_steps(hole, plan.preposition);
                cl_motion::put_back(&mut self.queue, steps.into_iter());
            }
            (None, _) => match &hole.moves {
                Some(moves) => cl_motion::put_back(&mut self.queue, moves.iter().cloned()),
                None => {
                    return Err(error_at(
                        self.opts,
                        record,
                        cl_motion::not_canned(&self.machine.name),
                    ));
                }
            },
        }
        Ok(())
    }
}
