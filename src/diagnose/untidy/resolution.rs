//! The resolution of a recording's values: the step they are rounded to,
//! and the noise that rounding adds to the residual.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::prepare::Prepared;
use super::super::recording::{Recording, Sample};

/// Below this a resolution does not matter (mm or deg).
const MIN_QUANTUM: f64 = 1e-9;

/// Fewest distinct values from which a resolution is read.
const MIN_DISTINCT: usize = 8;

/// The resolution of a column of values: the largest step `q` such that
/// every value is a whole multiple of `q`, among the steps a controller or
/// logger rounds to (1, 2 or 5 · 10ᵏ in the file's unit, the same in inch
/// converted to mm, 2⁻ᵏ) and the smallest gap between two values. `None`
/// when the values are not rounded (or too few of them differ to tell).
///
/// A gap that is one of those steps but for the floating-point noise of a
/// conversion (0.0001 inch read as 0.0025399999999962 mm) is given as the
/// step itself (0.00254).
pub fn quantum(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() < MIN_DISTINCT {
        return None;
    }
    let gap = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    // Values rounded to `q` differ by `q` at least: a larger step would
    // only seem to divide values far below it (noise about 0, each "0 · q"
    // within the test's tolerance).
    let is_step = |q: f64| {
        q >= MIN_QUANTUM
            && q <= gap * (1.0 + 1e-6)
            && v.iter().all(|x| {
                let k = x / q;
                k.abs() < 1e12 && (k - k.round()).abs() <= 1e-6
            })
    };
    let mut steps: Vec<f64> = Vec::new();
    for e in -10..=2 {
        for m in [1.0, 2.0, 5.0] {
            steps.push(decimal(m, e));
            // The same step in inch, in mm (25.4 = 254 · 10⁻¹).
            steps.push(decimal(m * 254.0, e - 1));
        }
    }
    for k in 0..=30 {
        steps.push(0.5f64.powi(k));
    }
    let step = steps
        .iter()
        .copied()
        .filter(|&q| is_step(q))
        .fold(None, |best: Option<f64>, q| {
            Some(best.map_or(q, |b| b.max(q)))
        });
    if !(gap.is_finite() && is_step(gap)) || step.is_some_and(|s| s >= gap) {
        return step;
    }
    // The gap is the step: one of the usual ones where it is that step
    // within rounding.
    let near = steps
        .into_iter()
        .find(|&q| (q - gap).abs() <= 1e-9 * gap && is_step(q));
    Some(near.unwrap_or(gap))
}

/// `mantissa · 10^exponent`, the double nearest to it (a whole mantissa
/// divided or multiplied by an exact power of ten: one rounding).
fn decimal(mantissa: f64, exponent: i32) -> f64 {
    if exponent < 0 {
        mantissa / 10f64.powi(-exponent)
    } else {
        mantissa * 10f64.powi(exponent)
    }
}

/// The resolutions of a recording: of each axis column (file units) and of
/// the measured tip (the coarsest of its three columns).
#[derive(Debug, Clone, PartialEq)]
pub struct Resolution {
    /// Per axis, chain order (mm or deg).
    pub axes: Vec<Option<f64>>,
    /// Of the measured tip, mm.
    pub meas_mm: Option<f64>,
}

impl Resolution {
    /// Reads the resolutions of `rec`'s columns.
    pub fn of(rec: &Recording) -> Resolution {
        let dof = rec.axes.len();
        let column =
            |f: &dyn Fn(&Sample) -> f64| quantum(&rec.samples.iter().map(f).collect::<Vec<f64>>());
        let axes = (0..dof)
            .map(|j| column(&|s: &Sample| s.q.get(j).copied().unwrap_or(0.0)))
            .collect();
        let meas_mm =
            (0..3)
                .map(|c| column(&|s: &Sample| s.meas[c]))
                .fold(None, |a: Option<f64>, q| match (a, q) {
                    (Some(a), Some(q)) => Some(a.max(q)),
                    (a, q) => a.or(q),
                });
        Resolution { axes, meas_mm }
    }

    /// Whether any column is rounded.
    pub fn any(&self) -> bool {
        self.meas_mm.is_some() || self.axes.iter().any(Option::is_some)
    }

    /// The standard deviations, per coordinate of the residual (mm), that
    /// the rounding adds: of the measured tip (q²/12 per coordinate), and
    /// of the commands (each axis's q²/12 carried to the tip by its
    /// Jacobian column, mean over the samples). Returned apart because
    /// they combine differently with the noise estimate: the rounding of
    /// the measured tip is white, and the estimate from first differences
    /// already holds it when the noise is larger; the rounding of a
    /// command follows the slowly moving axis, so first differences miss
    /// it, and it adds.
    pub fn floor_xyz(&self, prep: &Prepared) -> ([f64; 3], [f64; 3]) {
        let meas = self.meas_mm.map_or(0.0, |q| q / 12f64.sqrt());
        let mut var = [0.0; 3];
        for (j, q) in self.axes.iter().enumerate() {
            let Some(q) = q else { continue };
            if j >= prep.dof || prep.n == 0 {
                continue;
            }
            for c in 0..3 {
                let mean_j2: f64 =
                    (0..prep.n).map(|i| prep.jj(i, j)[c].powi(2)).sum::<f64>() / prep.n as f64;
                var[c] += q * q / 12.0 * mean_j2;
            }
        }
        ([meas; 3], var.map(f64::sqrt))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_is_read_from_the_values() {
        let tenth: Vec<f64> = (0..50)
            .map(|i| (i as f64 * 0.37 * 10.0).round() / 10.0)
            .collect();
        assert_eq!(quantum(&tenth), Some(0.1));
        let mm: Vec<f64> = (0..50).map(|i| (i as f64 * 3.7).round()).collect();
        assert_eq!(quantum(&mm), Some(1.0));
        let counts: Vec<f64> = (0..50).map(|i| (i * i * 7 + 3) as f64 / 4096.0).collect();
        assert_eq!(quantum(&counts), Some(1.0 / 4096.0));
        let free: Vec<f64> = (0..50).map(|i| (i as f64 * 0.731).sin() * 12.3).collect();
        assert_eq!(quantum(&free), None);
        // Too few distinct values to tell.
        assert_eq!(quantum(&[0.0, 1.0, 0.0, 1.0]), None);
        // Noise about 0 (an axis that stands at 0, its tip coordinate
        // measured): no step, where every value seemed "0 · 12700 mm".
        let about_zero: Vec<f64> = (0..50).map(|i| (i as f64 * 0.731).sin() * 1e-3).collect();
        assert_eq!(quantum(&about_zero), None);
        // The same rounded to 0.1 µm: that step.
        let rounded: Vec<f64> = about_zero.iter().map(|x| (x * 1e4).round() / 1e4).collect();
        assert_eq!(quantum(&rounded), Some(1e-4));
        // Inch values to 4 decimals, read in mm: the step is 0.0001 inch,
        // given as 0.00254 mm, not with the conversion's noise.
        let inch: Vec<f64> = (0..50)
            .map(|i| ((i as f64 * 0.731).sin() * 12.3 * 1e4).round() / 1e4 * 25.4)
            .collect();
        assert_eq!(quantum(&inch), Some(0.00254));
        assert_eq!(format!("{}", quantum(&inch).unwrap()), "0.00254");
        // An odd step (an encoder's 1/3 µm) stays the gap.
        let odd: Vec<f64> = (0..50).map(|i| (i * i % 97) as f64 / 3000.0).collect();
        let q = quantum(&odd).unwrap();
        assert!((q - 1.0 / 3000.0).abs() < 1e-15, "{q}");
    }
}
