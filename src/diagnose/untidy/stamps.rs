//! Time stamps off a regular clock: samples taken at a fixed rate whose
//! stamps were rounded by the export (to whole milliseconds) or jittered
//! by the computer that logged them. Where a recording's clock is offset
//! from the program's, the commands are moved along the stamps
//! ([`super::align()`]), and a stamp 0.5 ms off moves a command at
//! 2,000 mm/min by 17 µm: such a recording was read as servo lags of
//! every axis and a wander of the measured tip. The commands tell which
//! clock is right: a command is smooth in the time it was sampled at, so
//! its third differences nearly vanish at a steady feed on the true
//! clock, and are the feed times the stamps' error on a wrong one.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use std::collections::BTreeMap;

use super::super::recording::Recording;
use super::super::report::{MeasurementFinding, Where};
use super::align::{rounding_allowance, third_difference};

/// The regular clock is taken when the commands' third differences on it
/// are at most this fraction of those on the stamps.
const SMOOTHER: f64 = 0.25;

/// A stamp may stray from the regular clock by at most this fraction of
/// its period (beyond it the samples were not taken at a fixed rate).
const MAX_STRAY: f64 = 0.25;

/// A recording whose stamps were replaced by a regular clock's times.
#[derive(Debug, Clone)]
pub struct RegularClock {
    /// The recording on the regular clock.
    pub rec: Recording,
    /// The clock's period, s.
    pub period_s: f64,
    /// The largest distance of a stamp from the clock, s.
    pub largest_s: f64,
    /// The RMS distance of the stamps from the clock, s.
    pub rms_s: f64,
}

/// The regular clock of `rec`'s samples, where its stamps stray from one
/// and the commands move more smoothly on it than on the stamps; `None`
/// where the stamps are regular already, the samples were not taken at a
/// fixed rate (a stamp strays by more than a quarter period from every
/// regular clock), or the stamps are the smoother time (samples taken at
/// uneven times and stamped as taken). Missing samples (gaps) are kept as
/// gaps of the clock.
pub fn regular_clock(rec: &Recording) -> Option<RegularClock> {
    let s = &rec.samples;
    let n = s.len();
    if n < 20 {
        return None;
    }
    let t: Vec<f64> = s.iter().map(|x| x.t).collect();
    let median = super::median_interval(rec);
    if !(median > 0.0 && median.is_finite()) {
        return None;
    }
    // The mean step without the gaps: stamps rounded to 1 ms at a 7.5 ms
    // rate step by 7 and 8 ms, and their median is either.
    let usual: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| (0.5 * median..=1.5 * median).contains(d))
        .collect();
    let period0 = usual.iter().sum::<f64>() / usual.len() as f64;
    let (ticks, a, b) = fit_clock(&t, period0)?;
    let grid: Vec<f64> = ticks.iter().map(|k| a + b * k).collect();
    let stray: Vec<f64> = (0..n).map(|i| t[i] - grid[i]).collect();
    let largest = stray.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let scale = t[n - 1].abs().max(t[0].abs()).max(1.0);
    if largest > MAX_STRAY * b || largest <= 1e-9 * scale {
        return None;
    }
    let axes = moving_axes(rec);
    if axes.is_empty() {
        return None;
    }
    let on_grid = roughness(rec, &axes, &grid);
    let on_stamps = roughness(rec, &axes, &t);
    if on_grid > SMOOTHER * on_stamps {
        return None;
    }
    let mut out = rec.clone();
    for (smp, &g) in out.samples.iter_mut().zip(&grid) {
        smp.t = g;
    }
    let rms = (stray.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    Some(RegularClock {
        rec: out,
        period_s: b,
        largest_s: largest,
        rms_s: rms,
    })
}

/// The regular clock `t ≈ a + b·tick` of the times `t`, from a first
/// guess `period0` of its period: each time's tick and the line fitted to
/// them by least squares, twice (the ticks read again on the first fit).
/// Returns `(ticks, a, b)`; `None` where the fit fails, its period is not
/// positive, or two times share a tick.
pub(crate) fn fit_clock(t: &[f64], period0: f64) -> Option<(Vec<f64>, f64, f64)> {
    let (mut a, mut b) = (*t.first()?, period0);
    let mut ticks = vec![0.0; t.len()];
    for _ in 0..2 {
        for (k, x) in ticks.iter_mut().zip(t) {
            *k = ((x - a) / b).round();
        }
        (a, b) = line_fit(&ticks, t)?;
    }
    (b > 0.0 && ticks.windows(2).all(|w| w[1] > w[0])).then_some((ticks, a, b))
}

/// Least-squares line `y = a + b·x`.
fn line_fit(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (xi, yi) in x.iter().zip(y) {
        sxx += (xi - mx) * (xi - mx);
        sxy += (xi - mx) * (yi - my);
    }
    (sxx > 0.0).then(|| {
        let b = sxy / sxx;
        (my - b * mx, b)
    })
}

/// An axis whose command moves in at least a quarter of the steps: its
/// index, its median step (mm or deg) and its values' rounding allowance
/// ([`rounding_allowance`]).
struct Moving {
    j: usize,
    step: f64,
    rounding: f64,
}

/// The axes of `rec` that move ([`Moving`]).
fn moving_axes(rec: &Recording) -> Vec<Moving> {
    let n = rec.samples.len();
    (0..rec.axes.len())
        .filter_map(|j| {
            let q: Vec<f64> = rec.samples.iter().map(|x| x.q[j]).collect();
            let mut steps: Vec<f64> = q
                .windows(2)
                .map(|w| (w[1] - w[0]).abs())
                .filter(|d| *d > 0.0)
                .collect();
            (steps.len() >= n / 4 && !steps.is_empty()).then(|| Moving {
                j,
                step: median(&mut steps),
                rounding: rounding_allowance(&q),
            })
        })
        .collect()
}

/// How rough the commands of the moving `axes` of `rec` are on the times
/// `t`: the sum over them of the median third difference (at the local
/// spacing, less what the rounding of the values alone gives) relative to
/// the axis's median step.
fn roughness(rec: &Recording, axes: &[Moving], t: &[f64]) -> f64 {
    let s = &rec.samples;
    let n = s.len();
    let mut total = 0.0;
    for m in axes {
        let q = |k: usize| s[k].q[m.j];
        let mut d3: Vec<f64> = (1..n - 2)
            .filter(|&k| q(k - 1) != q(k) || q(k) != q(k + 1) || q(k + 1) != q(k + 2))
            .map(|k| {
                let d = third_difference(
                    [t[k - 1], t[k], t[k + 1], t[k + 2]],
                    [q(k - 1), q(k), q(k + 1), q(k + 2)],
                );
                (d - m.rounding).max(0.0) / m.step
            })
            .collect();
        if !d3.is_empty() {
            total += median(&mut d3);
        }
    }
    total
}

/// The upper median of `v` (not empty); reorders it.
fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// A stray of a stamp, in ms, or in µs below 0.1 ms (a stamp rounded to
/// the microsecond strays by 0.5 µs, which reads as 0.000 ms).
fn short_time(s: f64) -> String {
    if s.abs() < 1e-4 {
        format!("{:.2} µs", s * 1e6)
    } else {
        format!("{:.3} ms", s * 1e3)
    }
}

impl RegularClock {
    /// The note of the report (`formats.md` §2c: repaired and reported;
    /// not a finding, since no effect is fitted to it).
    pub fn note(&self) -> MeasurementFinding {
        let s = &self.rec.samples;
        let (first, last) = (s.first(), s.last());
        MeasurementFinding {
            effect: "time_stamps".into(),
            axis: None,
            parameters: BTreeMap::from([
                ("period_s".to_string(), self.period_s),
                ("largest_stray_s".to_string(), self.largest_s),
                ("rms_stray_s".to_string(), self.rms_s),
            ]),
            uncertainty: BTreeMap::new(),
            where_: Where {
                blocks: [first.and_then(|x| x.block), last.and_then(|x| x.block)],
                t_s: [first.map_or(0.0, |x| x.t), last.map_or(0.0, |x| x.t)],
                condition: format!(
                    "the time stamps stray from a regular clock of {:.3} ms by up to {} (RMS {}: rounded by the export or jittered by the logging computer), while the commands move smoothly on that clock and not on the stamps; the samples are taken at the clock's times",
                    self.period_s * 1e3,
                    short_time(self.largest_s),
                    short_time(self.rms_s)
                ),
            },
            rms_explained_mm: 0.0,
            machine_physics: false,
            samples: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stamps rounded to the microsecond at 300 Hz read "by up to 0.000 ms
    /// (RMS 0.000 ms)" before.
    #[test]
    fn strays_below_a_tenth_of_a_millisecond_are_given_in_microseconds() {
        assert_eq!(short_time(5e-7), "0.50 µs");
        assert_eq!(short_time(2.9e-7), "0.29 µs");
        assert_eq!(short_time(5e-4), "0.500 ms");
    }
}
