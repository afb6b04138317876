//! What an unexplained mismatch correlates with (`formats.md` §4): where it
//! shows (blocks, time) and how much of it follows an axis position, an
//! axis velocity, time, or one frequency.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::prepare::Prepared;
use super::report::{Correlation, Unexplained, Window};
use crate::machine::chain::JointKind;

/// Number of bins of a position, velocity or time.
const BINS: usize = 12;

/// Correlations explaining less than this share of the residual's
/// variance (beyond what noise alone would give) are left out.
const MIN_SHARE: f64 = 0.05;

/// Most samples the frequency scan runs over (it costs samples²).
const MAX_SPECTRUM_SAMPLES: usize = 20_000;

/// Share of the variance of `e` (beyond noise σ²) that the means of `e`
/// in bins of `x` account for.
fn binned_share(x: &[f64], e: &[[f64; 3]], sigma: f64, total: f64) -> f64 {
    let n = x.len();
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    if hi <= lo || !hi.is_finite() || total <= 0.0 {
        return 0.0;
    }
    let mut sum = [[0.0; 3]; BINS];
    let mut cnt = [0usize; BINS];
    for i in 0..n {
        let b = (((x[i] - lo) / (hi - lo)) * BINS as f64).floor() as usize;
        let b = b.min(BINS - 1);
        cnt[b] += 1;
        for c in 0..3 {
            sum[b][c] += e[i][c];
        }
    }
    let mut between = 0.0;
    let mut used = 0;
    for b in 0..BINS {
        if cnt[b] > 0 {
            used += 1;
            between += (0..3).map(|c| sum[b][c] * sum[b][c]).sum::<f64>() / cnt[b] as f64;
        }
    }
    // Noise alone puts 3σ² per bin into the bin means' sum of squares.
    ((between - 3.0 * used as f64 * sigma * sigma) / total).clamp(0.0, 1.0)
}

/// The strongest frequency of `e` over time `t` (uniform-ish sampling):
/// a least-squares sinusoid per coordinate at each trial frequency from
/// one cycle per recording to the Nyquist frequency. Returns (Hz, share).
fn strongest_frequency(t: &[f64], e: &[[f64; 3]], sigma: f64, total: f64) -> Option<(f64, f64)> {
    let n = t.len();
    if !(16..=MAX_SPECTRUM_SAMPLES).contains(&n) || total <= 0.0 {
        return None;
    }
    let span = t[n - 1] - t[0];
    if span <= 0.0 {
        return None;
    }
    let dt = span / (n - 1) as f64;
    let nyquist = 0.5 / dt;
    let df = 1.0 / (2.0 * span);
    let mut best: Option<(f64, f64)> = None;
    let mut f = 1.0 / span;
    while f < nyquist {
        let w = 2.0 * std::f64::consts::PI * f;
        let (mut ss, mut cc, mut sc) = (0.0, 0.0, 0.0);
        let mut es = [0.0; 3];
        let mut ec = [0.0; 3];
        for i in 0..n {
            let (s, c) = (w * (t[i] - t[0])).sin_cos();
            ss += s * s;
            cc += c * c;
            sc += s * c;
            for k in 0..3 {
                es[k] += e[i][k] * s;
                ec[k] += e[i][k] * c;
            }
        }
        let det = ss * cc - sc * sc;
        if det > 1e-9 * ss * cc {
            let mut explained = 0.0;
            for k in 0..3 {
                let a = (cc * es[k] - sc * ec[k]) / det;
                let b = (ss * ec[k] - sc * es[k]) / det;
                explained += a * es[k] + b * ec[k];
            }
            let share = ((explained - 6.0 * sigma * sigma) / total).clamp(0.0, 1.0);
            if best.is_none_or(|(_, s)| share > s) {
                best = Some((f, share));
            }
        }
        f += df;
    }
    best
}

/// Where and with what the residual `after` departs from noise σ, given
/// the time windows of [`super::report::Locate`]; `None` when no window
/// departs.
pub fn unexplained(
    prep: &Prepared,
    after: &[[f64; 3]],
    sigma: f64,
    windows: &[Window],
) -> Option<Unexplained> {
    let departing: Vec<&Window> = windows
        .iter()
        .filter(|w| w.excess_sigma_after > 4.0)
        .collect();
    let (first, last) = (departing.first()?, departing.last()?);
    let n = prep.n;
    let total: f64 = after
        .iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sum();
    let mut corr: Vec<Correlation> = Vec::new();
    for j in 0..prep.dof {
        let name = prep.names[j].clone();
        let unit = if prep.kinds[j] == JointKind::Revolute {
            "deg"
        } else {
            "mm"
        };
        let q: Vec<f64> = (0..n).map(|i| prep.qj(i, j)).collect();
        let share = binned_share(&q, after, sigma, total);
        corr.push(Correlation {
            with: "axis position".into(),
            axis: Some(name.clone()),
            detail: format!(
                "the residual follows the {name} position ({:.0} % of its variance in {BINS} bins of {name}, {unit})",
                share * 100.0
            ),
            share,
        });
        let v: Vec<f64> = (0..n).map(|i| prep.vj(i, j)).collect();
        let share = binned_share(&v, after, sigma, total);
        corr.push(Correlation {
            with: "axis velocity".into(),
            axis: Some(name.clone()),
            detail: format!(
                "the residual follows the {name} velocity ({:.0} % of its variance in {BINS} bins of {name} speed, {unit}/s)",
                share * 100.0
            ),
            share,
        });
    }
    let share = binned_share(&prep.t, after, sigma, total);
    corr.push(Correlation {
        with: "time".into(),
        axis: None,
        detail: format!(
            "the residual drifts with time ({:.0} % of its variance in {BINS} time windows)",
            share * 100.0
        ),
        share,
    });
    if let Some((f, share)) = strongest_frequency(&prep.t, after, sigma, total) {
        corr.push(Correlation {
            with: "frequency".into(),
            axis: None,
            detail: format!(
                "the residual oscillates at {f:.4} Hz ({:.0} % of its variance in one sinusoid)",
                share * 100.0
            ),
            share,
        });
    }
    corr.retain(|c| c.share >= MIN_SHARE);
    corr.sort_by(|a, b| b.share.total_cmp(&a.share));
    corr.truncate(6);
    let lead = corr.first().map_or(
        "it follows none of the axis positions, velocities, time or a single frequency".to_string(),
        |c| c.detail.clone(),
    );
    Some(Unexplained {
        blocks: [first.blocks[0], last.blocks[1]],
        t_s: [first.t_s[0], last.t_s[1]],
        condition: format!(
            "in {} of {} time windows (blocks {}…{}, t = {:.1}…{:.1} s); {lead}",
            departing.len(),
            windows.len(),
            first.blocks[0].map_or("-".into(), |b| b.to_string()),
            last.blocks[1].map_or("-".into(), |b| b.to_string()),
            first.t_s[0],
            last.t_s[1]
        ),
        correlates_with: corr,
    })
}

/// Noise of any distribution is white and steady: whatever its tails, a
/// residual of independent samples has a mean square equal to half that
/// of its first differences, and the level of those differences does not
/// change along the recording. The robust floor (a median of first
/// differences) reads heavy-tailed noise low: Student-t noise with 5
/// degrees of freedom gives 0.84 of its standard deviation, so χ² 1.4 on a
/// clean recording. Returns the variance per coordinate the first
/// differences give, and whether their level is steady: the means of
/// `|Δr|²` in 20 contiguous windows of time spread no more than
/// independent windows do (an F ratio against the variation inside the
/// windows, which counts the tails; corrected for the correlation of
/// neighbouring differences, which share a sample; within 4 standard
/// deviations of 1). Noise that grows part-way is not steady.
pub fn white_level(r: &[[f64; 3]]) -> Option<(f64, bool)> {
    const WINDOWS: usize = 20;
    let e: Vec<f64> = r
        .windows(2)
        .map(|w| (0..3).map(|c| (w[1][c] - w[0][c]).powi(2)).sum::<f64>() / 6.0)
        .collect();
    let n = e.len();
    if n < 4 * WINDOWS {
        return None;
    }
    let mean = e.iter().sum::<f64>() / n as f64;
    let (mut between, mut within) = (0.0, 0.0);
    for w in 0..WINDOWS {
        let part = &e[w * n / WINDOWS..(w + 1) * n / WINDOWS];
        let m = part.iter().sum::<f64>() / part.len() as f64;
        between += part.len() as f64 * (m - mean).powi(2);
        within += part.iter().map(|x| (x - m).powi(2)).sum::<f64>();
    }
    let var = within / (n - WINDOWS) as f64;
    if var <= 0.0 {
        return Some((mean, true));
    }
    // Lag-one correlation of the differences' squares.
    let rho = (e
        .windows(2)
        .map(|w| (w[0] - mean) * (w[1] - mean))
        .sum::<f64>()
        / ((n - 1) as f64 * var))
        .clamp(0.0, 1.0);
    let f = between / (WINDOWS - 1) as f64 / (var * (1.0 + 2.0 * rho));
    let steady = f - 1.0 <= 4.0 * (2.0 / (WINDOWS - 1) as f64).sqrt();
    Some((mean, steady))
}
