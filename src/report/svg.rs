//! SVG plots (plotters): the stacked line panels of `analyze` (one panel
//! per quantity, sharing the x axis) and the two residual panels of a
//! diagnosis (against time, and against the position that matters for the
//! top finding). One way to draw and one way to fail: a plot that cannot
//! be drawn is an error naming its SVG (exit 3, as an output that cannot
//! be written), and the file is written atomically.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::diagnose::Report;
use crate::error::{Error, Result};

/// What a drawing closure returns: any plotters failure.
type Drawn = std::result::Result<(), Box<dyn std::error::Error>>;

/// Draws an SVG document of `size` (pixels) with `f` and returns its text;
/// a failure of the drawing is the one plot error, naming `name`.
fn draw(
    name: &str,
    size: (u32, u32),
    f: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Drawn,
) -> Result<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        f(&root)
            .and_then(|()| root.present().map_err(Into::into))
            .map_err(|e| {
                Error::io(
                    name.to_string(),
                    std::io::Error::other(format!("plotting failed: {e}")),
                )
            })?;
    }
    Ok(out)
}

/// Writes `svg` to `path` atomically.
fn write_file(path: &Path, svg: &str) -> Result<()> {
    crate::output::write_atomically(Some(path), |w| {
        w.write_all(svg.as_bytes())
            .map_err(|e| Error::io(path.display().to_string(), e))
    })
}

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
    let height = 60 + 260 * panels.len() as u32;
    let name = path.display().to_string();
    let svg = draw(&name, (900, height), |root| {
        root.fill(&WHITE)?;
        let root = root.titled(title, ("sans-serif", 20))?;
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
                .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(panel.y_label)
                .draw()?;
            for (k, (name, s)) in panel.series.iter().enumerate() {
                let colour = COLOURS[k % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(s.iter().copied(), colour.stroke_width(2)))?
                    .label(*name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
        Ok(())
    })?;
    write_file(path, &svg)
}

/// Symmetric y range (µm) that holds `p`-quantile of |values|, with margin.
fn y_range(values: &[f64]) -> f64 {
    let mut a: Vec<f64> = values
        .iter()
        .map(|v| v.abs())
        .filter(|v| v.is_finite())
        .collect();
    if a.is_empty() {
        return 1.0;
    }
    let k = ((a.len() as f64) * 0.999) as usize;
    let k = k.min(a.len() - 1);
    a.select_nth_unstable_by(k, |x, y| x.total_cmp(y));
    (a[k] * 1.15).max(1e-3)
}

fn minmax(v: &[f64]) -> (f64, f64) {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, hi + 0.5)
    }
}

/// Largest number of points drawn per series (the rest are thinned out
/// evenly, so that the file stays small).
pub const MAX_POINTS: usize = 800;

/// Renders the report's plots as one SVG document (two panels); `name`
/// names it in an error.
pub fn render(report: &Report, name: &str) -> Result<String> {
    let full = &report.series;
    let stride = full.t.len().div_ceil(MAX_POINTS).max(1);
    let pick = |v: &[f64]| v.iter().step_by(stride).copied().collect::<Vec<f64>>();
    let thinned = crate::diagnose::report::Series {
        t: pick(&full.t),
        before: full.before.iter().step_by(stride).copied().collect(),
        after: full.after.iter().step_by(stride).copied().collect(),
        x_label: full.x_label.clone(),
        x: pick(&full.x),
        y_label: full.y_label.clone(),
        proj_before: pick(&full.proj_before),
        proj_after: pick(&full.proj_after),
    };
    let s = &thinned;
    draw(name, (1000, 760), |root| {
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(380);
        let title = match report.findings.first() {
            Some(f) => format!(
                "kinpost diagnose: {}{} — residual RMS {:.3} → {:.3} µm (noise floor {:.3} µm)",
                f.effect,
                f.axis.as_deref().map_or(String::new(), |a| format!(" {a}")),
                report.rms_before_mm * 1e3,
                report.rms_after_mm * 1e3,
                report.noise_floor_mm * 1e3
            ),
            None => format!(
                "kinpost diagnose: no finding — residual RMS {:.3} µm (noise floor {:.3} µm)",
                report.rms_before_mm * 1e3,
                report.noise_floor_mm * 1e3
            ),
        };
        // Panel 1: the residual component of largest spread vs time.
        let comp = (0..3)
            .max_by(|&a, &b| {
                let v = |c: usize| s.before.iter().map(|r| r[c] * r[c]).sum::<f64>();
                v(a).total_cmp(&v(b))
            })
            .unwrap_or(0);
        let before: Vec<f64> = s.before.iter().map(|r| r[comp] * 1e3).collect();
        let after: Vec<f64> = s.after.iter().map(|r| r[comp] * 1e3).collect();
        let ymax = y_range(&before).max(y_range(&after));
        let (t0, t1) = minmax(&s.t);
        let mut chart = ChartBuilder::on(&top)
            .caption(title, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(t0..t1, -ymax..ymax)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(format!("residual {} (µm)", ["x", "y", "z"][comp]))
            .draw()?;
        let red = RGBColor(214, 39, 40).mix(0.45);
        let blue = RGBColor(31, 119, 180).mix(0.45);
        chart
            .draw_series(
                s.t.iter()
                    .zip(&before)
                    .map(|(&t, &y)| Circle::new((t, y), 1, red.filled())),
            )?
            .label("before (model)")
            .legend(move |(x, y)| Circle::new((x, y), 3, red.filled()));
        chart
            .draw_series(
                s.t.iter()
                    .zip(&after)
                    .map(|(&t, &y)| Circle::new((t, y), 1, blue.filled())),
            )?
            .label("after (model + findings)")
            .legend(move |(x, y)| Circle::new((x, y), 3, blue.filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;

        // Panel 2: projected residual vs the position that matters.
        let pb: Vec<f64> = s.proj_before.iter().map(|v| v * 1e3).collect();
        let pa: Vec<f64> = s.proj_after.iter().map(|v| v * 1e3).collect();
        let ymax = y_range(&pb).max(y_range(&pa));
        let ymin = if pb.iter().chain(&pa).all(|v| *v >= 0.0) {
            0.0
        } else {
            -ymax
        };
        let (x0, x1) = minmax(&s.x);
        let mut chart = ChartBuilder::on(&bottom)
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(x0..x1, ymin..ymax)?;
        chart
            .configure_mesh()
            .x_desc(s.x_label.clone())
            .y_desc(s.y_label.clone())
            .draw()?;
        chart.draw_series(
            s.x.iter()
                .zip(&pb)
                .map(|(&x, &y)| Circle::new((x, y), 1, red.filled())),
        )?;
        chart.draw_series(
            s.x.iter()
                .zip(&pa)
                .map(|(&x, &y)| Circle::new((x, y), 1, blue.filled())),
        )?;
        Ok(())
    })
}

impl Report {
    /// Writes the plots as an SVG file.
    pub fn write_svg(&self, path: &Path) -> Result<()> {
        let svg = render(self, &path.display().to_string())?;
        write_file(path, &svg)
    }

    /// The plots as SVG text.
    pub fn to_svg(&self) -> Result<String> {
        render(self, "<svg>")
    }
}
