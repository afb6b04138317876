//! The error motion of an axis as the recording sees it: the basis its
//! components are fitted in (harmonics of a turn, B-splines over a
//! travel), which components the recorded motion can tell apart, and the
//! arc of a turn a rotary axis passed through.

use super::prepare::Prepared;
use crate::geometric::effects::{MotionSpan, TurnArc};
use crate::machine::chain::JointKind;

/// Cubic B-spline functions of a linear axis's fitted error motion over
/// its recorded travel.
pub const MOTION_BASIS: usize = 6;

/// Harmonics per turn of a fitted error motion (once and twice per turn).
pub const MOTION_HARMONICS: u32 = 2;

/// The B-spline basis over the travel joint `j` covers in the recording.
pub fn motion_span(prep: &Prepared, j: usize) -> Option<MotionSpan> {
    let (lo, hi) = (0..prep.n).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
        (a.min(prep.qj(i, j)), b.max(prep.qj(i, j)))
    });
    MotionSpan::new(lo, hi, MOTION_BASIS)
}

/// The weights of one component's coefficients at sample `i` of joint
/// `j`: `cos q, sin q, cos 2q, sin 2q` for a revolute joint, the B-spline
/// functions of `span` for a prismatic one. A component's design column
/// for coefficient `k` is its tip change times weight `k`.
pub fn motion_weights(prep: &Prepared, j: usize, i: usize, span: Option<&MotionSpan>) -> Vec<f64> {
    match (prep.kinds[j], span) {
        (JointKind::Revolute, _) => {
            let q = prep.qj(i, j).to_radians();
            (1..=MOTION_HARMONICS)
                .flat_map(|k| {
                    let (s, c) = (k as f64 * q).sin_cos();
                    [c, s]
                })
                .collect()
        }
        (JointKind::Prismatic, Some(sp)) => sp.values(prep.qj(i, j)),
        (JointKind::Prismatic, None) => Vec::new(),
    }
}

/// Coefficients per component of joint `j`'s error motion.
pub fn weights_per_component(prep: &Prepared, j: usize) -> usize {
    match prep.kinds[j] {
        JointKind::Revolute => 2 * MOTION_HARMONICS as usize,
        JointKind::Prismatic => MOTION_BASIS,
    }
}

/// The components of a mask, in ascending order.
pub fn mask_components(mask: u8) -> impl Iterator<Item = usize> {
    (0..6).filter(move |c| mask & (1 << c) != 0)
}

/// Mask of the three translations of an error motion.
pub const TRANSLATIONS: u8 = 0b000_111;

/// Which error-motion components of joint `j` the recording can tell
/// apart, as a mask: taken in the order
/// translations x, y, z, rotation about the joint's own axis, the two
/// tilts, a component is kept when each of its design columns (harmonics
/// or spline functions) keeps at least [`VISIBLE_FRACTION`] of its norm
/// after projection on the columns of the components kept before it.
/// A component the tip does not feel (a rotation about an axis through
/// the tip) or one the motion confounds with another (a tilt at a constant
/// lever looks like a translation) is left out, so the fit stays
/// determined.
pub fn visible_components(prep: &Prepared, j: usize) -> u8 {
    let (Some(&axis), Some(Some(tip))) = (prep.axis_coord.get(j), prep.motion.get(j)) else {
        return 0;
    };
    let span = match prep.kinds[j] {
        JointKind::Prismatic => match motion_span(prep, j) {
            Some(sp) => Some(sp),
            None => return 0,
        },
        JointKind::Revolute => None,
    };
    let weights: Vec<Vec<f64>> = (0..prep.n)
        .map(|i| motion_weights(prep, j, i, span.as_ref()))
        .collect();
    let per = weights_per_component(prep, j);
    // The rotation about the joint's own axis is the most visible one.
    let own = 3 + axis;
    let order = [0, 1, 2, own, 3 + (axis + 1) % 3, 3 + (axis + 2) % 3];
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut kept = 0u8;
    for &c in &order {
        let mut accepted = Vec::new();
        let mut ok = true;
        for p in 0..per {
            let mut v: Vec<f64> = (0..prep.n)
                .flat_map(|i| tip[i][c].map(|x| x * weights[i][p]))
                .collect();
            let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm0.is_nan() || norm0 <= 1e-12 {
                ok = false;
                break;
            }
            for b in basis.iter().chain(accepted.iter()) {
                let d: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < VISIBLE_FRACTION * norm0 {
                ok = false;
                break;
            }
            v.iter_mut().for_each(|x| *x /= norm);
            accepted.push(v);
        }
        if ok {
            basis.extend(accepted);
            kept |= 1 << c;
        }
    }
    kept
}

/// Fraction of a design column's norm that must be its own (not in the
/// span of the columns kept before it) for an error-motion component to be
/// fitted: below it, the recording cannot tell the component from the
/// others.
pub const VISIBLE_FRACTION: f64 = 0.1;

/// The arc of a turn that revolute joint `j` passes through in the
/// recording (rad): the circle less its largest gap between recorded
/// angles. `None` when no gap is wider than [`FULL_TURN_GAP_DEG`]: the
/// recording has seen the whole turn.
pub fn covered_arc(prep: &Prepared, j: usize) -> TurnArc {
    let mut a: Vec<f64> = (0..prep.n)
        .map(|i| prep.qj(i, j).rem_euclid(360.0))
        .collect();
    if a.is_empty() {
        return None;
    }
    a.sort_by(f64::total_cmp);
    // The gap after each angle, the last one round to the first.
    let (mut gap, mut after) = (a[0] + 360.0 - a[a.len() - 1], a[0]);
    for w in a.windows(2) {
        if w[1] - w[0] > gap {
            gap = w[1] - w[0];
            after = w[1];
        }
    }
    if gap <= FULL_TURN_GAP_DEG {
        return None;
    }
    // Start where the gap ends; as near zero as the turn allows.
    let lo = if after > 180.0 { after - 360.0 } else { after };
    Some([lo.to_radians(), (lo + 360.0 - gap).to_radians()])
}

/// Widest gap between recorded angles (deg) with which a rotary axis still
/// counts as having turned through a whole turn.
pub const FULL_TURN_GAP_DEG: f64 = 10.0;
