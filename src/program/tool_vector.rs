//! A programmed tool vector made a unit vector: refused when it is out of
//! range, zero, or far from unit length; normalised within a tolerance.

use nalgebra::Vector3;

/// Largest deviation of a tool vector's length from 1 that is normalised
/// without a warning per block (CAM output printed to 6–9 decimals is off
/// by up to about 1e-6); the run's summary reports the largest.
pub const QUIET_NORMALISATION: f64 = 1e-5;

/// Tolerance on the length of a programmed tool vector: within it the vector
/// is normalised with a warning; beyond it the block is an error.
pub const TOOL_VECTOR_TOLERANCE: f64 = 1e-3;

/// `axis` (as programmed) as a unit vector, with its length; `Err` with
/// the message when it cannot be one.
pub fn normalised(axis: Vector3<f64>) -> Result<(Vector3<f64>, f64), String> {
    let norm = axis.norm();
    if norm.is_infinite() {
        return Err(format!(
            "the tool vector ({}, {}, {}) is out of range: expected a unit vector",
            axis.x, axis.y, axis.z
        ));
    }
    if !norm.is_finite() || norm < 1e-12 {
        return Err("the tool vector (I, J, K) is zero: expected a unit vector pointing from the tool tip towards the spindle".into());
    }
    if (norm - 1.0).abs() > TOOL_VECTOR_TOLERANCE {
        return Err(format!(
            "the tool vector ({}, {}, {}) has length {norm:.6}, not 1 (tolerance {TOOL_VECTOR_TOLERANCE}): expected a unit vector",
            axis.x, axis.y, axis.z
        ));
    }
    Ok((axis / norm, norm))
}
