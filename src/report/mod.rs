//! Plots of reports and analyses (SVG, via `plotters`).

pub mod envelope;
pub mod svg;

pub use envelope::Envelope;
