//! Five-axis linkage to four-axis linkage (seed 003), and the exact nonlinear
//! error of linearly interpolated blocks.

pub mod carry;
pub mod nonlinear;
pub mod plan;
pub mod program;

pub use nonlinear::{NonlinearError, nonlinear_error, point_segment_distance};
