//! kinpost: a post-processor for multi-axis machine tools.
//!
//! Tool poses (tool tip + tool axis) from CAM programs become the axis words a
//! particular machine needs, through one kinematic chain evaluator, with the
//! machine's measured geometric errors taken into account.

pub mod analyze;
pub mod cl;
pub mod compensate;
pub mod demo;
pub mod diagnose;
pub mod error;
pub mod gcode;
pub mod geometric;
pub mod input;
pub mod json_stream;
pub mod linalg;
pub mod linkage;
pub mod machine;
pub mod numeric;
pub mod output;
pub mod post;
pub mod program;
pub mod progress;
pub mod report;
#[cfg(test)]
pub(crate) mod test_support;
pub mod text;
pub mod trajectory;

pub use error::{Error, Location, Result};
