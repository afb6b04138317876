//! Newton refinement on the error-aware chain (seed 000, Section 5, improved).
//!
//! Start from the analytic IK of the theoretical machine, then step with a
//! generalised inverse until the *actual* machine (the chain with its error
//! motions) puts the tool on the pose.
//!
//! The tool tip comes first and is met exactly; the tool axis comes as close
//! as the remaining freedom allows (task-priority least squares):
//!
//! ```text
//! Δq = J_p⁺ r_p + N (W J_o N)⁺ W (r_o − J_o J_p⁺ r_p),   N = I − J_p⁺ J_p
//! ```
//!
//! with `r_p`, `r_o` the tip and axis residuals, `J_p`, `J_o` the rows of the
//! Jacobian for tip and axis and `W` the axis weights. On a five-axis machine
//! both are met; on a four-axis machine the tip is met to floating-point level
//! and the axis lands on the closest direction the actual machine can reach.
//!
//! The paper's variant ([`Method::Paper`]) steps with the pseudo-inverse of the
//! stacked 6×n theoretical Jacobian on the stacked residual: it minimises
//! `|r_p|² + |r_o|²` with mm and rad mixed, so where the axis cannot be met it
//! trades tip accuracy for axis accuracy and stalls at a tip residual of tens
//! of nanometres (see `docs/error-model.md`).

mod pipeline;
mod refine;
mod report;
mod solver;
mod step;
mod written;

pub use pipeline::{Input, compensate, compensate_gcode};
pub use refine::{MAX_COMPENSATION_MM, MAX_COMPENSATION_RAD, Refined, refine};
pub use report::{ReportWriter, RunSummary};
pub use solver::{BlockRecord, CompensatingSolver, OnFail};
pub use step::{Method, Options};
