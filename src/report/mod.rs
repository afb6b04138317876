//! Plots of reports and analyses (SVG, via `plotters`).

pub mod svg;
