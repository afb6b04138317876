//! Plots of reports (SVG, via `plotters`).

pub mod svg;
