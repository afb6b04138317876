//! The trace's clock against the drives' in a joint-feedback trace: a
//! delay every traced axis shows alike (a clock offset), and one that
//! grows with time alike on every axis (the feedback logged on a clock
//! that runs fast or slow: an external encoder or scale read by a data
//! logger of its own). What one axis lags beyond the others is its servo
//! lag, fitted later.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};

use super::super::fit::pinv_sym;
use super::super::untidy::LOOSE;
use super::super::untidy::align::Clock;
use super::super::untidy::offset::shared_axes;

/// An axis informs the clock offset when its lag is known to this (s).
const INFORMATIVE_LAG_S: f64 = 1e-3;

/// An axis informs the clock rate when its own rate is known to this
/// (s per s, 100 ppm).
const INFORMATIVE_RATE: f64 = 1e-4;

/// One traced axis as the clock sees it.
pub struct AxisTiming<'a> {
    /// `fb − command`, per sample.
    pub e: &'a [f64],
    /// The command's velocity, per sample.
    pub v: &'a [f64],
    /// The axis's noise floor (its unit).
    pub sigma: f64,
}

/// The clock found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceClock {
    /// The sample stamped t shows the axes at t − `clock.shift(t)`.
    pub clock: Clock,
    /// Standard deviation of `clock.offset_s` (at `clock.t_ref`), s.
    pub offset_sd: f64,
    /// Standard deviation of `clock.rate`, when a rate was found.
    pub rate_sd: Option<f64>,
}

impl TraceClock {
    /// The delay at `t` and its standard deviation, s.
    pub fn shift_at(&self, t: f64) -> (f64, f64) {
        let dt = t - self.clock.t_ref;
        let sd = self.rate_sd.map_or(0.0, |s| s * dt);
        (self.clock.shift(t), self.offset_sd.hypot(sd))
    }
}

/// Least squares over the axes: each axis's residual as
/// `−v·(L_group + ρ_group·(t − t_ref))`, the lags and rates grouped as
/// given (`lag_of[k]`, `rate_of[k]`: the unknown each axis's lag and rate
/// belong to; `None` leaves it out). Returns the unknowns and their
/// covariance (for unit noise: the columns are divided by each axis's σ).
fn solve(
    axes: &[AxisTiming<'_>],
    t: &[f64],
    use_sample: &[bool],
    t_ref: f64,
    lag_of: &[Option<usize>],
    rate_of: &[Option<usize>],
    unknowns: usize,
) -> (DVector<f64>, DMatrix<f64>) {
    let mut g = DMatrix::zeros(unknowns, unknowns);
    let mut h = DVector::zeros(unknowns);
    for (k, a) in axes.iter().enumerate() {
        for i in 0..t.len() {
            if !use_sample[i] || a.v[i] == 0.0 {
                continue;
            }
            let c_lag = -a.v[i] / a.sigma;
            let c_rate = c_lag * (t[i] - t_ref);
            let y = a.e[i] / a.sigma;
            let cols = [(lag_of[k], c_lag), (rate_of[k], c_rate)];
            for &(p, cp) in &cols {
                let Some(p) = p else { continue };
                h[p] += cp * y;
                for &(q, cq) in &cols {
                    if let Some(q) = q {
                        g[(p, q)] += cp * cq;
                    }
                }
            }
        }
    }
    let inv = pinv_sym(&g);
    (&inv * &h, inv)
}

/// The clock of a trace: `None` when the axes show no common delay.
///
/// 1. Each axis's own lag and rate about the mean time; the axes whose
///    rate is known to 100 ppm and lies within 4 standard deviations
///    (plus the tolerance of the tool-tip diagnosis) of their median share
///    a common rate, at least two of them and more than half. It is a
///    drift when it lowers χ² by more than ln n + `bic_margin` and moves
///    the delay by at least 1 % of the sampling interval over the trace.
/// 2. With that rate (or none), each axis's lag; the axes whose lag is
///    known to 1 ms and shares the median share the offset, which is
///    their weighted mean. Without a drift it is an offset when it lowers
///    χ² by more than ln n + `bic_margin` and is at least 1 % of the
///    sampling interval; with one, the offset goes with it.
///
/// `found`: a clock was found and removed already, and this is what the
/// axes still share: the offset is then taken without the tests of step 2
/// (it refines one that passed them).
pub fn trace_clock(
    axes: &[AxisTiming<'_>],
    t: &[f64],
    use_sample: &[bool],
    bic_margin: f64,
    found: bool,
) -> Option<TraceClock> {
    let n = t.len();
    let n_ax = axes.len();
    let used: Vec<f64> = (0..n).filter(|&i| use_sample[i]).map(|i| t[i]).collect();
    if used.len() < 20 || n < 2 {
        return None;
    }
    let t_ref = used.iter().sum::<f64>() / used.len() as f64;
    let min_chi2 = (n as f64).ln() + bic_margin;
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let span = t[n - 1] - t[0];
    let moving: Vec<bool> = axes
        .iter()
        .map(|a| (0..n).any(|i| use_sample[i] && a.v[i] != 0.0))
        .collect();
    let own = |k: usize| moving[k].then_some(k);
    // 1. Each axis's lag and rate, then the common rate.
    let lag_of: Vec<Option<usize>> = (0..n_ax).map(own).collect();
    let rate_own: Vec<Option<usize>> = (0..n_ax).map(|k| own(k).map(|k| n_ax + k)).collect();
    let (beta, cov) = solve(axes, t, use_sample, t_ref, &lag_of, &rate_own, 2 * n_ax);
    let rates: Vec<(f64, f64)> = (0..n_ax)
        .map(|k| (beta[n_ax + k], cov[(n_ax + k, n_ax + k)].max(0.0).sqrt()))
        .collect();
    let informative: Vec<usize> = (0..n_ax)
        .filter(|&k| moving[k] && rates[k].1 > 0.0 && rates[k].1 < INFORMATIVE_RATE)
        .collect();
    let mut rate: Option<(f64, f64)> = None;
    let mut rate_of: Vec<Option<usize>> = vec![None; n_ax];
    if let Some(set) = shared_axes(&rates, &informative, LOOSE) {
        // The common rate (unknown n_ax), an own rate for the others.
        let mut groups: Vec<Option<usize>> = vec![None; n_ax];
        let mut next = n_ax + 1;
        for k in 0..n_ax {
            if set.contains(&k) {
                groups[k] = Some(n_ax);
            } else if moving[k] {
                groups[k] = Some(next);
                next += 1;
            }
        }
        let (beta, cov) = solve(axes, t, use_sample, t_ref, &lag_of, &groups, next);
        let (r, sd) = (beta[n_ax], cov[(n_ax, n_ax)].max(0.0).sqrt());
        if sd > 0.0 && (r / sd).powi(2) > min_chi2 && r.abs() * span >= 0.01 * dt {
            rate = Some((r, sd));
            rate_of = (0..n_ax)
                .map(|k| set.contains(&k).then_some(n_ax))
                .collect();
        }
    }
    // 2. Each axis's lag with the common rate, then the common offset.
    let (beta, cov) = solve(axes, t, use_sample, t_ref, &lag_of, &rate_of, n_ax + 1);
    let lags: Vec<(f64, f64)> = (0..n_ax)
        .map(|k| (beta[k], cov[(k, k)].max(0.0).sqrt()))
        .collect();
    let informative: Vec<usize> = (0..n_ax)
        .filter(|&k| moving[k] && lags[k].1 > 0.0 && lags[k].1 < INFORMATIVE_LAG_S)
        .collect();
    let shared = shared_axes(&lags, &informative, LOOSE);
    let weighted = |set: &[usize]| {
        let (mut num, mut den) = (0.0, 0.0);
        for &k in set {
            let (l, sd) = lags[k];
            num += l / (sd * sd);
            den += 1.0 / (sd * sd);
        }
        (den > 0.0).then(|| (num / den, den.sqrt().recip()))
    };
    let offset = match (&shared, rate) {
        (Some(set), None) => weighted(set)
            .filter(|(d, sd)| found || ((d / sd).powi(2) > min_chi2 && d.abs() >= 0.01 * dt)),
        (Some(set), Some(_)) => weighted(set),
        // A drift whose axes do not share one delay at its mean time: the
        // delay of the axes that share the rate.
        (None, Some(_)) => {
            let set: Vec<usize> = (0..n_ax).filter(|&k| rate_of[k].is_some()).collect();
            weighted(&set)
        }
        (None, None) => None,
    };
    let (offset_s, offset_sd) = match (offset, rate) {
        (Some(o), _) => o,
        (None, Some(_)) => (0.0, 0.0),
        (None, None) => return None,
    };
    Some(TraceClock {
        clock: Clock {
            offset_s,
            rate: rate.map_or(0.0, |r| r.0),
            t_ref,
        },
        offset_sd,
        rate_sd: rate.map(|r| r.1),
    })
}
