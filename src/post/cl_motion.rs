//! `kinpost post` on APT CL: arcs as `G2`/`G3` and holes as canned cycles
//! (`G81`…`G89`, `G73`), decided through the machine's kinematics.
//!
//! An arc ([`ArcMove`]) is written as `G2`/`G3` when every point of its
//! linearisation, taken through the inverse kinematics, leaves the rotary
//! (and any other) axes where they are and lies on one circle (or helix)
//! of the machine's X, Y, Z axes in the XY, ZX or YZ plane, within the arc
//! tolerance; the centre is the centre point taken through the same
//! kinematics. A hole ([`HoleMove`]) is a canned cycle when its retract
//! level, `R` level and bottom differ in the machine's Z axis alone, the
//! bottom lowest. Otherwise the caller writes the moves.
//!
//! Under cutter compensation (`CUTCOM/LEFT|RIGHT`, written `G41`/`G42`)
//! every move must keep the tool along the machine's Z axis, tested as for
//! holes, and the rotary axes where they were when it went on
//! ([`cutcom_refusal`]); the caller refuses the program otherwise.

use super::{AxisWriter, PoseSolver, PostOptions};
use crate::cl::{ArcMove, ClStatement, HoleMove};
use crate::machine::chain::JointValues;
use crate::machine::{JointKind, Machine, Pose};
use crate::program::Units;
use crate::program::format::push_fixed;
use nalgebra::Vector3;
use std::f64::consts::TAU;

/// Largest change of a joint that is to stay where it is (rad or mm).
const STILL: f64 = 1e-9;

/// Joint indices of the linear axes named X, Y and Z, when the machine has
/// all three.
fn xyz_joints(machine: &Machine) -> Option<[usize; 3]> {
    let find = |n: &str| {
        machine
            .axis(n)
            .filter(|a| a.kind == JointKind::Prismatic)
            .map(|a| a.joint)
    };
    Some([find("X")?, find("Y")?, find("Z")?])
}

/// Whether `a` and `b` agree on every joint not in `free`.
fn others_still(a: &[f64], b: &[f64], free: &[usize]) -> bool {
    others_within(a, b, free, STILL)
}

/// Whether `a` and `b` agree within `still` (mm or rad) on every joint not
/// in `free`.
fn others_within(a: &[f64], b: &[f64], free: &[usize], still: f64) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .enumerate()
            .all(|(k, (x, y))| free.contains(&k) || (x - y).abs() <= still)
}

/// The change of the machine's Z axis (joint `z`) from `upper` to `lower`,
/// the joint values of two tool tips on one tool axis (`lower` the one
/// further down the tool), when no other joint changes by more than
/// `still` (mm or rad): moving along the tool then moves Z alone, so the
/// tool is along the machine's Z axis. The one test of that, for canned
/// cycles ([`plan_hole`]) and for cutter compensation ([`tool_along_z`]).
fn z_change_alone(upper: &[f64], lower: &[f64], z: usize, still: f64) -> Option<f64> {
    others_within(upper, lower, &[z], still).then(|| lower[z] - upper[z])
}

/// Joint values for the tool tip `tip` (CL units, times `scale` for mm)
/// with tool axis `axis`, continuing from `previous`; `None` if the pose is
/// not reached within the axis tolerance.
fn solve(
    solver: &mut dyn PoseSolver,
    opts: &PostOptions,
    tip: [f64; 3],
    axis: [f64; 3],
    scale: f64,
    previous: Option<&[f64]>,
    line: usize,
) -> Option<JointValues> {
    let a = Vector3::from(axis);
    let n = a.norm();
    if n.is_nan() || n <= 1e-12 {
        return None;
    }
    let pose = Pose::new(Vector3::from(tip) * scale, a / n);
    let s = solver.solve(&pose, previous, line).ok()?;
    (s.axis_miss_rad <= opts.axis_tolerance_rad).then_some(s.q)
}

/// How an arc is written.
#[derive(Debug, Clone)]
pub(super) struct ArcPlan {
    /// 17, 18 or 19 (`G17` XY, `G18` ZX, `G19` YZ).
    plane: u8,
    /// 2 (clockwise) or 3 (counter-clockwise) about the plane's normal.
    pub(super) motion: u8,
    /// Joint values at the end.
    pub(super) q_end: JointValues,
    /// The centre minus the start, on the plane's two axes: (word, mm).
    offsets: [(char, f64); 2],
}

/// The `G2`/`G3` form of `arc`, which starts at the joint values
/// `previous`, if it has one within `opts.arc_tolerance_mm` (module
/// documentation). Under cutter compensation (`cutcom`) only a `G17` arc
/// with the tool along the machine's Z axis ([`tool_along_z`]): the
/// controller compensates in the plane in force, and changing it under
/// `G41`/`G42` is an error on Fanuc and LinuxCNC.
#[allow(clippy::too_many_arguments)]
pub(super) fn plan_arc(
    machine: &Machine,
    solver: &mut dyn PoseSolver,
    opts: &PostOptions,
    arc: &ArcMove,
    previous: &[f64],
    scale: f64,
    line: usize,
    cutcom: bool,
) -> Option<ArcPlan> {
    if !arc.constant_axis || !solver.plans_freely() {
        return None;
    }
    let xyz = xyz_joints(machine)?;
    let tol = opts.arc_tolerance_mm;
    let at = |q: &[f64]| [q[xyz[0]], q[xyz[1]], q[xyz[2]]];
    let qc = solve(
        solver,
        opts,
        arc.centre,
        arc.tool_axis,
        scale,
        Some(previous),
        line,
    )?;
    if !others_still(previous, &qc, &xyz) {
        return None;
    }
    let mut qs: Vec<JointValues> = Vec::with_capacity(arc.moves.len());
    for m in &arc.moves {
        let ClStatement::Goto { tip, .. } = m else {
            return None;
        };
        let seed: &[f64] = qs.last().map_or(previous, |q| q.as_slice());
        let q = solve(solver, opts, *tip, arc.tool_axis, scale, Some(seed), line)?;
        if !others_still(previous, &q, &xyz) {
            return None;
        }
        qs.push(q);
    }
    let (c, s) = (at(&qc), at(previous));
    let pts: Vec<[f64; 3]> = qs.iter().map(|q| at(q)).collect();
    let (first, end) = (*pts.first()?, *pts.last()?);
    let d = |p: [f64; 3]| [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    let (ds, d1) = (d(s), d(first));
    let m = [
        ds[1] * d1[2] - ds[2] * d1[1],
        ds[2] * d1[0] - ds[0] * d1[2],
        ds[0] * d1[1] - ds[1] * d1[0],
    ];
    // The plane: the machine axis nearest the rotation's normal.
    let k = (0..3).max_by(|&i, &j| m[i].abs().total_cmp(&m[j].abs()))?;
    let (a, b) = match k {
        2 => (0, 1),
        1 => (2, 0),
        _ => (1, 2),
    };
    let sense = if m[k] > 0.0 { 1.0 } else { -1.0 };
    let r_start = ds[a].hypot(ds[b]);
    if r_start.is_nan() || r_start <= tol {
        return None;
    }
    let angle = |p: [f64; 3]| {
        let v = d(p);
        (sense * (v[b].atan2(v[a]) - ds[b].atan2(ds[a]))).rem_euclid(TAU)
    };
    let full = arc.sweep_rad >= TAU - 1e-12;
    let total = if full { TAU } else { angle(end) };
    if (total - arc.sweep_rad).abs() * r_start > tol {
        return None;
    }
    // A short arc whose written end equals its start would be read as a
    // full circle.
    let chord = (end[a] - s[a]).hypot(end[b] - s[b]);
    if !full && chord < 0.01 {
        return None;
    }
    let mut last = 0.0;
    for (i, p) in pts.iter().enumerate() {
        let th = if i + 1 == pts.len() { total } else { angle(*p) };
        if th < last - 1e-12 || th > total + 1e-12 {
            return None;
        }
        last = th;
        let v = d(*p);
        let axial = s[k] + (end[k] - s[k]) * th / total;
        if (v[a].hypot(v[b]) - r_start).abs() > tol || (p[k] - axial).abs() > tol {
            return None;
        }
    }
    let word = |j: usize| ['I', 'J', 'K'][j];
    let mut offsets = [(word(a), -ds[a]), (word(b), -ds[b])];
    offsets.sort_by_key(|o| o.0);
    let q_end = qs.pop()?;
    if cutcom {
        let end = Pose::new(Vector3::from(arc.end) * scale, Vector3::from(arc.tool_axis));
        let along = tool_along_z(machine, solver, opts, &q_end, &end, line);
        if k != 2 || along != Some(true) {
            return None;
        }
    }
    Some(ArcPlan {
        plane: [19, 18, 17][k],
        motion: if sense > 0.0 { 3 } else { 2 },
        q_end,
        offsets,
    })
}

/// Decimals written for the machine axis named `name` (the CL is written
/// in millimetres).
fn decimals_of(writer: &AxisWriter, name: &str) -> usize {
    writer
        .machine
        .axes
        .iter()
        .position(|a| a.name.eq_ignore_ascii_case(name))
        .map_or(4, |k| writer.decimals[0][k])
}

/// The plane code to put before a block, when it is not the one in force.
fn plane_word(plane: u8, plane_written: &mut Option<u8>) -> String {
    if *plane_written == Some(plane) {
        String::new()
    } else {
        *plane_written = Some(plane);
        format!("G{plane} ")
    }
}

/// The `G2`/`G3` block of `plan` (without the feed), all axes written.
pub(super) fn arc_block(
    writer: &mut AxisWriter,
    plan: &ArcPlan,
    plane_written: &mut Option<u8>,
) -> Result<String, String> {
    let mut block = plane_word(plan.plane, plane_written);
    block.push_str(if plan.motion == 2 { "G2 " } else { "G3 " });
    let words = writer.words(&plan.q_end, Units::Mm, true, false, " ")?;
    block.push_str(std::str::from_utf8(words).unwrap_or_default());
    for (w, v) in plan.offsets {
        let axis = match w {
            'I' => "X",
            'J' => "Y",
            _ => "Z",
        };
        block.push(' ');
        block.push(w);
        push_fixed(&mut block, v, decimals_of(writer, axis));
    }
    Ok(block)
}

/// Where a canned hole goes, in joint values.
#[derive(Debug, Clone)]
pub(super) struct HolePlan {
    q_clear: JointValues,
    q_r: JointValues,
    q_bottom: JointValues,
    z: usize,
    /// The tool must first go to the retract level above the hole (it is
    /// not at that level with the rotaries in place).
    pub(super) preposition: bool,
}

/// The canned form of `hole`, when the tool is along the machine's Z axis
/// (module documentation); `previous`: the joint values before it.
pub(super) fn plan_hole(
    machine: &Machine,
    solver: &mut dyn PoseSolver,
    opts: &PostOptions,
    hole: &HoleMove,
    previous: Option<&[f64]>,
    scale: f64,
    line: usize,
) -> Option<HolePlan> {
    hole.code?;
    if !solver.plans_freely() {
        return None;
    }
    let [_, _, z] = xyz_joints(machine)?;
    let q_clear = solve(solver, opts, hole.clear, hole.axis, scale, previous, line)?;
    let q_r = solve(
        solver,
        opts,
        hole.r_plane,
        hole.axis,
        scale,
        Some(&q_clear),
        line,
    )?;
    let q_bottom = solve(
        solver,
        opts,
        hole.bottom,
        hole.axis,
        scale,
        Some(&q_r),
        line,
    )?;
    // The tool along Z: R and the bottom differ from the retract level in
    // Z alone, the bottom lowest and R not above the retract level.
    let dr = z_change_alone(&q_clear, &q_r, z, STILL)?;
    let db = z_change_alone(&q_clear, &q_bottom, z, STILL)?;
    if !(db < dr - STILL && dr <= STILL) {
        return None;
    }
    let preposition = previous.is_none_or(|p| {
        !(others_still(p, &q_clear, &xyz_joints(machine).unwrap_or([z; 3]))
            && (p[z] - q_clear[z]).abs() <= STILL)
    });
    Some(HolePlan {
        q_clear,
        q_r,
        q_bottom,
        z,
        preposition,
    })
}

/// The canned-cycle block of `hole` once the tool is at the retract level
/// above it; the writer then holds the position after the cycle. `feed`:
/// the feed in force (mm/min, or mm/rev under `G95`).
pub(super) fn hole_block(
    writer: &mut AxisWriter,
    hole: &HoleMove,
    plan: &HolePlan,
    scale: f64,
    feed: Option<f64>,
    plane_written: &mut Option<u8>,
) -> Result<String, String> {
    let code = hole.code.unwrap_or(81);
    let mut block = plane_word(17, plane_written);
    block.push_str(if hole.retract_to_r { "G99" } else { "G98" });
    block.push_str(&format!(" G{code}"));
    let after = if hole.retract_to_r {
        &plan.q_r
    } else {
        &plan.q_clear
    };
    let words = writer.words(after, Units::Mm, true, false, " ")?;
    let words = std::str::from_utf8(words).unwrap_or_default().to_string();
    for w in words.split(' ') {
        let name = w.trim_end_matches(|c: char| c.is_ascii_digit() || c == '.' || c == '-');
        if name.eq_ignore_ascii_case("X") || name.eq_ignore_ascii_case("Y") {
            block.push(' ');
            block.push_str(w);
        }
    }
    let dz = decimals_of(writer, "Z");
    block.push_str(" Z");
    push_fixed(&mut block, plan.q_bottom[plan.z], dz);
    block.push_str(" R");
    push_fixed(&mut block, plan.q_r[plan.z], dz);
    if matches!(code, 83 | 73) {
        block.push_str(" Q");
        push_fixed(&mut block, hole.peck * scale, dz);
    }
    if matches!(code, 82 | 84 | 86 | 89) && hole.dwell_s > 0.0 {
        block.push_str(" P");
        push_number(&mut block, hole.dwell_s);
    }
    if let Some(f) = feed {
        block.push_str(" F");
        push_number(&mut block, f);
    }
    Ok(block)
}

/// A number with one decimal, or up to four when one is not enough (a
/// feed of 0.05 mm/rev stays 0.05).
pub(super) fn push_number(out: &mut String, v: f64) {
    if ((v * 10.0).round() - v * 10.0).abs() < 1e-9 {
        push_fixed(out, v, 1);
    } else {
        let mut s = String::new();
        push_fixed(&mut s, v, 4);
        out.push_str(s.trim_end_matches('0'));
    }
}

impl HolePlan {
    /// Joint values after the cycle: at `R` (`G99`) or the retract level.
    pub(super) fn q_after(&self, hole: &HoleMove) -> JointValues {
        if hole.retract_to_r {
            self.q_r.clone()
        } else {
            self.q_clear.clone()
        }
    }
}

/// The steps of a canned hole: its feed, a rapid move to the retract level
/// above it when needed, the hole again (marked positioned: the canned
/// block), then the feed back.
pub(super) fn canned_steps(hole: &HoleMove, preposition: bool) -> Vec<ClStatement> {
    let mut steps = hole.feed_before.clone();
    if preposition {
        steps.push(ClStatement::Rapid);
        steps.push(ClStatement::Goto {
            tip: hole.clear,
            axis: Some(hole.axis),
        });
    }
    let mut again = hole.clone();
    again.positioned = true;
    again.feed_before.clear();
    let after = std::mem::take(&mut again.feed_after);
    steps.push(ClStatement::Hole(Box::new(again)));
    steps.extend(after);
    steps
}

/// Puts `steps` before the other statements in `queue` (all of them of
/// the same record).
pub(super) fn put_back(
    queue: &mut std::collections::VecDeque<ClStatement>,
    steps: impl DoubleEndedIterator<Item = ClStatement>,
) {
    for statement in steps.rev() {
        queue.push_front(statement);
    }
}

/// Why a tapping or drag-boring hole is refused: it has no form as moves.
pub(super) fn not_canned(machine: &str) -> String {
    format!(
        "this cycle (tapping, or boring with a spindle stop) has no form as moves and needs a canned cycle, which kinpost writes only when the tool is along the machine's Z axis (on machine {machine}), the retract level is not below R and cutter compensation is off, and not under `compensate` (which converts every pose): the program is refused"
    )
}

/// Under cutter compensation, the largest angle between the tool and the
/// machine's Z axis, and the largest turn of a rotary axis since the
/// compensation went on, rad. The controller's offset of radius r then
/// points at most r × 1e-5 away from where the CL asks (0.25 µm at r =
/// 25 mm), and tool axes printed to six decimals, or set-ups (`CSYS`)
/// orthonormal to 1e-6, stay well within it.
pub const CUTCOM_TOLERANCE_RAD: f64 = 1e-5;

/// How far along the tool [`tool_along_z`] moves the tip, mm.
const PROBE_MM: f64 = 1.0;

/// Whether the tool is along the machine's Z axis (pointing up it) at the
/// joint values `q` of `pose` (mm), within [`CUTCOM_TOLERANCE_RAD`]: the tip
/// [`PROBE_MM`] further down the tool (up, where down is beyond a limit),
/// solved from `q`, is reached by moving Z alone ([`z_change_alone`]), Z
/// lower at the lower tip. `None` when the machine has no linear X, Y and
/// Z axes or neither tip is reached.
pub(super) fn tool_along_z(
    machine: &Machine,
    solver: &mut dyn PoseSolver,
    opts: &PostOptions,
    q: &[f64],
    pose: &Pose,
    line: usize,
) -> Option<bool> {
    let [_, _, z] = xyz_joints(machine)?;
    let still = PROBE_MM * CUTCOM_TOLERANCE_RAD;
    for d in [-PROBE_MM, PROBE_MM] {
        let tip = pose.tip + pose.axis * d;
        let axis = pose.axis.into();
        let Some(qp) = solve(solver, opts, tip.into(), axis, 1.0, Some(q), line) else {
            continue;
        };
        let (upper, lower) = if d < 0.0 { (q, &qp[..]) } else { (&qp[..], q) };
        return Some(z_change_alone(upper, lower, z, still).is_some_and(|dz| dz < -0.5 * PROBE_MM));
    }
    None
}

/// Cutter compensation that is on (`CUTCOM/LEFT|RIGHT`): where it was
/// switched on, for the messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct CutcomOn {
    /// The statement's place among the statements: one per section.
    pub(super) seq: u64,
    /// Its line.
    pub(super) line: usize,
    /// `CUTCOM/LEFT` (`G41`) or `CUTCOM/RIGHT` (`G42`).
    pub(super) left: bool,
}

impl CutcomOn {
    /// `CUTCOM/LEFT at line 5, written as G41`.
    fn describe(&self) -> String {
        let (side, g) = if self.left {
            ("LEFT", "G41")
        } else {
            ("RIGHT", "G42")
        };
        format!("CUTCOM/{side} at line {}, written as {g}", self.line)
    }
}

/// Why a move under cutter compensation `on` cannot be written, or `None`
/// when it can: the tool must be along the machine's Z axis
/// ([`tool_along_z`]) and no rotary axis may turn by more than
/// [`CUTCOM_TOLERANCE_RAD`] from `reference`, the joint values in force
/// when the compensation went on. `q`: the theoretical joint values of the
/// move's pose `pose` (mm), also for `compensate`, whose compensated
/// rotaries differ by microradians from pose to pose, which turns the
/// controller's offset by as little.
#[allow(clippy::too_many_arguments)]
pub(super) fn cutcom_refusal(
    machine: &Machine,
    solver: &mut dyn PoseSolver,
    opts: &PostOptions,
    q: &[f64],
    pose: &Pose,
    reference: &[f64],
    on: CutcomOn,
    line: usize,
) -> Option<String> {
    const DO: &str = "have the CAM system output the tool-centre path for this operation (cutter compensation off, the radius applied in CAM)";
    let name = &machine.name;
    let why = format!(
        "cutter compensation is on here ({}): the controller offsets the path by the tool radius in the machine's X Y plane (G17), at right angles to its Z axis",
        on.describe()
    );
    match tool_along_z(machine, solver, opts, q, pose, line) {
        None if xyz_joints(machine).is_none() => {
            return Some(format!(
                "{why}, and machine {name} has no linear X, Y and Z axes to offset in; {DO}"
            ));
        }
        Some(true) => {}
        _ => {
            let axes: Vec<String> = machine
                .axes
                .iter()
                .filter(|a| a.kind == JointKind::Revolute)
                .map(|a| {
                    let v = crate::machine::output_value(a, q.get(a.joint).copied().unwrap_or(0.0));
                    format!("{}{v:.4}", a.name)
                })
                .collect();
            return Some(format!(
                "{why}, but on machine {name} the tool is not along the machine's Z axis at this pose ({}): the offset would lie in another plane than the contour's; {DO}, or use a machine whose tool stays along Z (a table-table machine)",
                if axes.is_empty() {
                    "no rotary axis".to_string()
                } else {
                    axes.join(" ")
                }
            ));
        }
    }
    for a in &machine.axes {
        let j = a.joint;
        let (Some(&now), Some(&then)) = (q.get(j), reference.get(j)) else {
            continue;
        };
        if a.kind == JointKind::Revolute && (now - then).abs() > CUTCOM_TOLERANCE_RAD {
            return Some(format!(
                "{why}, and rotary axis {} turns from {:.4}° to {:.4}° since it went on: the part turns under the offset the controller computed in X and Y, so the offset no longer points where the CL asks; keep the rotary axes still from CUTCOM/LEFT|RIGHT to CUTCOM/OFF, or {DO}",
                a.name,
                crate::machine::output_value(a, then),
                crate::machine::output_value(a, now),
            ));
        }
    }
    None
}
