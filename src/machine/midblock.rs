//! What the controller does between two blocks: it moves every joint along
//! a straight line in joint space (a modulo axis the short way). Where a
//! rotary axis turns far within one block the tool may leave the programmed
//! line mid-block; this says by how much.

use super::chain::NoErrors;
use super::{JointKind, Machine, Pose, RotaryMode};

/// A rotary axis turning more than this within one block (deg) is looked
/// at mid-block. Ordinary five-axis blocks turn a rotary by a degree or
/// two; a pass near the singular pose (tilt near 0, where a small change
/// of the tool axis turns the other rotary far), a change of branch or an
/// unwinding turns it by tens of degrees.
pub const BIG_TURN_DEG: f64 = 5.0;

/// A rotary turn above which the block is said to change branch, deg.
const BRANCH_TURN_DEG: f64 = 90.0;

/// Mid-block departure from the programmed line above which a big turn is
/// warned of, mm.
pub const BIG_TURN_DEPARTURE_MM: f64 = 1.0;

/// The warning for a block in which a rotary axis turns by more than
/// [`BIG_TURN_DEG`] (a pass near the singular pose, a change of branch at
/// a tilt limit, or an unwinding) and the tool, moved by the controller
/// along the straight line in joint space, leaves the programmed line by
/// more than [`BIG_TURN_DEPARTURE_MM`] mid-block; `None` otherwise.
pub fn branch_change_warning(
    machine: &Machine,
    prev: &[f64],
    q: &[f64],
    pose: &Pose,
) -> Option<String> {
    let joints = machine.chain.joints();
    if prev.len() != q.len() || q.len() != joints.len() {
        return None;
    }
    // Most blocks: no rotary turns that far even the long way.
    let big = BIG_TURN_DEG.to_radians();
    if !joints
        .iter()
        .zip(prev.iter().zip(q))
        .any(|(jt, (a, b))| jt.kind == JointKind::Revolute && (b - a).abs() > big)
    {
        return None;
    }
    // The move the controller makes: a modulo axis takes the short way.
    let step: Vec<f64> = (0..q.len())
        .map(|j| {
            let d = q[j] - prev[j];
            let modulo = machine
                .axes
                .iter()
                .any(|a| a.joint == j && a.rotary == RotaryMode::Modulo);
            if modulo {
                let tau = std::f64::consts::TAU;
                d - tau * (d / tau).round()
            } else {
                d
            }
        })
        .collect();
    let (j, turn) = joints
        .iter()
        .enumerate()
        .filter(|(_, jt)| jt.kind == JointKind::Revolute)
        .map(|(j, _)| (j, step[j].abs().to_degrees()))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    if turn <= BIG_TURN_DEG {
        return None;
    }
    let none = NoErrors;
    let start = machine.chain.pose(prev, &none).tip;
    let mid_q: Vec<f64> = prev.iter().zip(&step).map(|(a, d)| a + 0.5 * d).collect();
    let mid = machine.chain.pose(&mid_q, &none).tip;
    let departure = (mid - 0.5 * (start + pose.tip)).norm();
    let why = if turn > BRANCH_TURN_DEG {
        "the pose is reached on another branch of the kinematics"
    } else {
        "a large change of the tool axis in one block, or a small one near the singular pose, where it turns a rotary far"
    };
    (departure > BIG_TURN_DEPARTURE_MM).then(|| {
        format!(
            "{} turns {turn:.1}° within this block ({why}); moved along a straight line in joint space the tool is {departure:.3} mm off the programmed line mid-block: check the clearance, or let `kinpost linkage` insert points",
            joints[j].name
        )
    })
}
