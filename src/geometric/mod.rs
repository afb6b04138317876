//! Geometric errors: error tables, B-spline fits, the error model.
//!
//! * [`table`]: the error-table CSV of `formats.md` §1 ([`parse_tables`]).
//! * [`bspline`]: least-squares cubic B-splines with cross-validated knots.
//! * [`cache`]: the fitted-model cache of the tables given to `--errors`.
//! * [`effects`]: the catalogue of effects (`formats.md` §4) that a model may
//!   carry besides its tables; [`effect_spec`] their command-line syntax;
//!   [`error_motion`] a rotary axis's error motion as a Fourier series.
//! * [`iso230_2`]: ISO 230-2 positioning figures from bidirectional runs.
//! * [`model`]: the fitted [`ErrorModel`], its JSON form, and
//!   [`BoundErrors`], the chain evaluator's error source.
//! * [`axis_errors`]: one axis's fitted error columns ([`axis_errors::AxisErrors`]).
//! * [`merged`]: an axis's error splines as one piecewise cubic, for speed.
//! * [`synth`]: deterministic synthetic tables for the fixture machines.
//!
//! See `docs/error-tables.md`.

pub mod axis_errors;
pub mod bound;
pub mod bspline;
pub mod cache;
pub mod direction;
mod effect_parameters;
pub mod effect_spec;
pub mod effects;
pub mod error_motion;
pub mod iso230_2;
pub mod merged;
pub mod model;
pub mod synth;
pub mod table;
pub mod wander;

pub use bspline::{BSpline, Extrapolation, KnotChoice};
pub use iso230_2::Iso230_2;
pub use model::{
    AxisErrors, BoundErrors, ColumnReport, ColumnSpline, ErrorModel, FitOptions, FitReport,
    FixedError, ModelMeta,
};
pub use table::{Component, ErrorColumn, ErrorTable, parse_tables, read_tables};
