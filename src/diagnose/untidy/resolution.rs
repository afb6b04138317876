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

/// The resolution of a column of values: the largest step `q` of the form
/// 1, 2 or 5 · 10ᵏ, 2⁻ᵏ, or the smallest gap between two values, such that
/// every value is a whole multiple of `q`. `None` when the values are not
/// rounded (or too few of them differ to tell).
pub fn quantum(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() < MIN_DISTINCT {
        return None;
    }
    let is_step = |q: f64| {
        q >= MIN_QUANTUM
            && v.iter().all(|x| {
                let k = x / q;
                k.abs() < 1e12 && (k - k.round()).abs() <= 1e-6
            })
    };
    let gap = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    let mut candidates: Vec<f64> = Vec::new();
    for e in -9..=2 {
        for m in [1.0, 2.0, 5.0] {
            candidates.push(m * 10f64.powi(e));
        }
    }
    for k in 0..=30 {
        candidates.push(0.5f64.powi(k));
    }
    candidates.push(gap);
    candidates
        .into_iter()
        .filter(|q| q.is_finite() && is_step(*q))
        .fold(None, |best: Option<f64>, q| {
            Some(best.map_or(q, |b| b.max(q)))
        })
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
    }
}
