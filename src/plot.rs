//! SVG line charts (plotters) for the reports: one panel per quantity,
//! sharing the x axis.

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// One panel: a title with its unit and one or more named series of (x, y).
pub struct Panel<'a> {
    /// Y-axis label with unit, e.g. `"tool-tip error E [µm]"`.
    pub y_label: &'a str,
    /// Named series.
    pub series: Vec<(&'a str, Vec<(f64, f64)>)>,
}

const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// Writes stacked panels to `path` as SVG (atomically).
pub fn write_panels(path: &Path, title: &str, x_label: &str, panels: &[Panel<'_>]) -> Result<()> {
    let mut svg = String::new();
    {
        let height = 60 + 260 * panels.len() as u32;
        let root = SVGBackend::with_string(&mut svg, (900, height)).into_drawing_area();
        let fail = |e: &dyn std::fmt::Display| {
            Error::io(
                path.display().to_string(),
                std::io::Error::other(e.to_string()),
            )
        };
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let root = root
            .titled(title, ("sans-serif", 20))
            .map_err(|e| fail(&e))?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (panel, area) in panels.iter().zip(areas) {
            let pts = panel.series.iter().flat_map(|(_, s)| s.iter());
            let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for &(x, y) in pts {
                if x.is_finite() && y.is_finite() {
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
            if x0 > x1 {
                (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
            }
            if x1 - x0 < 1e-12 {
                x1 = x0 + 1.0;
            }
            let pad = ((y1 - y0) * 0.05).max(1e-12);
            let mut chart = ChartBuilder::on(&area)
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
                .map_err(|e| fail(&e))?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(panel.y_label)
                .draw()
                .map_err(|e| fail(&e))?;
            for (k, (name, s)) in panel.series.iter().enumerate() {
                let colour = COLOURS[k % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(s.iter().copied(), colour.stroke_width(2)))
                    .map_err(|e| fail(&e))?
                    .label(*name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    crate::output::write_atomically(Some(path), |w| {
        w.write_all(svg.as_bytes())
            .map_err(|e| Error::io(path.display().to_string(), e))
    })
}
