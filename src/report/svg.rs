//! SVG plots of a diagnosis: the residual before and after the fit against
//! time, and against the position that matters for the top finding.

use plotters::prelude::*;

use crate::diagnose::Report;
use crate::error::{Error, Result};

fn plot_err<E: std::fmt::Debug>(e: E) -> Error {
    Error::Usage(format!("plotting failed: {e:?}"))
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

/// Renders the report's plots as one SVG document (two panels).
pub fn render(report: &Report) -> Result<String> {
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
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (1000, 760)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
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
            .build_cartesian_2d(t0..t1, -ymax..ymax)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(format!("residual {} (µm)", ["x", "y", "z"][comp]))
            .draw()
            .map_err(plot_err)?;
        let red = RGBColor(214, 39, 40).mix(0.45);
        let blue = RGBColor(31, 119, 180).mix(0.45);
        chart
            .draw_series(
                s.t.iter()
                    .zip(&before)
                    .map(|(&t, &y)| Circle::new((t, y), 1, red.filled())),
            )
            .map_err(plot_err)?
            .label("before (model)")
            .legend(move |(x, y)| Circle::new((x, y), 3, red.filled()));
        chart
            .draw_series(
                s.t.iter()
                    .zip(&after)
                    .map(|(&t, &y)| Circle::new((t, y), 1, blue.filled())),
            )
            .map_err(plot_err)?
            .label("after (model + findings)")
            .legend(move |(x, y)| Circle::new((x, y), 3, blue.filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;

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
            .build_cartesian_2d(x0..x1, ymin..ymax)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(s.x_label.clone())
            .y_desc(s.y_label.clone())
            .draw()
            .map_err(plot_err)?;
        chart
            .draw_series(
                s.x.iter()
                    .zip(&pb)
                    .map(|(&x, &y)| Circle::new((x, y), 1, red.filled())),
            )
            .map_err(plot_err)?;
        chart
            .draw_series(
                s.x.iter()
                    .zip(&pa)
                    .map(|(&x, &y)| Circle::new((x, y), 1, blue.filled())),
            )
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(out)
}

impl Report {
    /// Writes the plots as an SVG file.
    pub fn write_svg(&self, path: &std::path::Path) -> Result<()> {
        let svg = render(self)?;
        crate::output::write_atomically(Some(path), |w| {
            w.write_all(svg.as_bytes())
                .map_err(|e| Error::io(path.display().to_string(), e))
        })
    }

    /// The plots as SVG text.
    pub fn to_svg(&self) -> Result<String> {
        render(self)
    }
}
