//! Why the inverse kinematics found no acceptable solution.

/// A value for a message: 6 decimals, or scientific notation when huge.
fn shown(v: f64) -> String {
    if v.abs() < 1e9 {
        format!("{v:.6}")
    } else {
        format!("{v:.6e}")
    }
}

/// Why a pose has no acceptable solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// No joint values produce the pose (or the pose is malformed).
    #[error("pose unreachable: {reason}")]
    Unreachable {
        /// What makes it unreachable.
        reason: String,
    },
    /// Every branch needs an axis beyond its travel; the nearest branch's
    /// first violation is reported (file units).
    #[error(
        "axis {axis} would have to move to {} {unit}, outside its limits {min} … {max} {unit} (no solution branch stays within the limits)",
        shown(*.value)
    )]
    Limit {
        /// Axis name.
        axis: String,
        /// The value needed, mm or degrees.
        value: f64,
        /// Lower limit, mm or degrees (−∞ if none).
        min: f64,
        /// Upper limit, mm or degrees (+∞ if none).
        max: f64,
        /// `"mm"` or `"deg"`.
        unit: &'static str,
    },
    /// The damped-Newton fallback did not meet the tool tip.
    #[error(
        "inverse kinematics did not converge after {iterations} iterations: tool tip off by {tip_residual_mm:.3e} mm, tool axis by {:.3} µrad",
        axis_residual_rad * 1e6
    )]
    NotConverged {
        /// Iterations used.
        iterations: usize,
        /// Remaining tip distance, mm.
        tip_residual_mm: f64,
        /// Remaining axis angle, rad.
        axis_residual_rad: f64,
    },
}
