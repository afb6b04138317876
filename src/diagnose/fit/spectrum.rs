//! The vibration search's frequency scan on a regular clock, by FFT.
//!
//! The scan scores the sinusoid pair `J_j·[sin 2πft, cos 2πft]` against
//! the residual, with the effects already selected, at every frequency of
//! a uniform grid ([`super::search`]). Directly that costs the number of
//! frequencies times the number of samples times the selected columns: on
//! a 300 Hz recording of eight minutes (150,000 samples, 20,000
//! frequencies, a hundred selected columns) about 10¹² operations a
//! family, hours of a run. On a regular clock (samples at whole ticks of
//! one period, gaps allowed) every sum over the samples is a discrete
//! Fourier transform at once for all frequencies `m/(N·period)`:
//!
//! - `Σ w sin²θ`, `Σ w sin θ cos θ`, `Σ w cos²θ` from the transform of
//!   the weights `w = |J_j|²` at `2m` (sin²θ = (1 − cos 2θ)/2, …);
//! - `Σ p sin θ`, `Σ p cos θ` from the transform of the projected residual
//!   `p = J_j·r` at `m`;
//! - the selected columns' part `M G⁺ Mᵀ` and `M G⁺ h` as sums over the
//!   whitened columns `S·L` (`G⁺ = L Lᵀ`), one transform each.
//!
//! The score of a frequency depends only on the span of its sine and
//! cosine, so the phase of the first sample is immaterial and the ticks
//! count from it. The transforms cost `N log N` per column: seconds, not
//! hours. The best frequency is then refined on the exact sample times by
//! the direct score, so the scan only has to rank the frequencies.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::quad_form_2;

/// A sample time may stray from its tick of the regular clock by at most
/// this fraction of the period: at the highest frequency scanned (0.49 of
/// the sampling rate) its phase is then off by at most 0.003 rad.
const MAX_STRAY: f64 = 1e-3;

/// The transform is at most this many times longer than the recording has
/// samples (beyond it the gaps dominate and the direct scan is cheaper).
const MAX_LENGTH_PER_SAMPLE: usize = 16;

/// Fixed number of groups the whitened columns are split into, each
/// summed on one task: the sums (and so the scan) do not depend on the
/// number of cores.
const GROUPS: usize = 4;

/// Sample times on a regular clock.
#[derive(Debug, Clone)]
pub(super) struct Clock {
    /// Tick of each sample, counted from the first (strictly increasing).
    pub ticks: Vec<usize>,
    /// The clock's period, s.
    pub period: f64,
}

/// The regular clock the times `t` lie on (within [`MAX_STRAY`] of a
/// period), `median` the median interval; `None` where they do not.
pub(super) fn regular_clock(t: &[f64], median: f64) -> Option<Clock> {
    let n = t.len();
    if n < 4 || !(median > 0.0 && median.is_finite()) {
        return None;
    }
    let (ticks, a, period) = crate::diagnose::untidy::stamps::fit_clock(t, median)?;
    let first = ticks[0];
    if ticks[n - 1] - first >= (MAX_LENGTH_PER_SAMPLE * n) as f64
        || (0..n).any(|i| (t[i] - a - ticks[i] * period).abs() > MAX_STRAY * period)
    {
        return None;
    }
    Some(Clock {
        ticks: ticks.iter().map(|k| (k - first) as usize).collect(),
        period,
    })
}

/// Per-sample projections onto joint `j`'s tip direction: weights
/// `|J_j|²`, the projected residual `J_j·r` and the selected columns
/// `J_j·S` (row-major, `ks` a sample).
pub(super) struct Projections<'a> {
    /// `|J_j|²` per sample.
    pub w: &'a [f64],
    /// `J_j·r` per sample, mm.
    pub pr: &'a [f64],
    /// `J_j·S` per sample, `ks` values each.
    pub ps: &'a [f64],
    /// Number of selected columns.
    pub ks: usize,
}

/// Per-frequency sums of the selected columns' part.
#[derive(Debug, Clone)]
struct Correction {
    ss: Vec<f64>,
    sc: Vec<f64>,
    cc: Vec<f64>,
    s: Vec<f64>,
    c: Vec<f64>,
}

impl Correction {
    fn zeros(nb: usize) -> Self {
        Correction {
            ss: vec![0.0; nb],
            sc: vec![0.0; nb],
            cc: vec![0.0; nb],
            s: vec![0.0; nb],
            c: vec![0.0; nb],
        }
    }

    fn add(&mut self, o: &Correction) {
        for (a, b) in [
            (&mut self.ss, &o.ss),
            (&mut self.sc, &o.sc),
            (&mut self.cc, &o.cc),
            (&mut self.s, &o.s),
            (&mut self.c, &o.c),
        ] {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
    }
}

/// `L` with `G⁺ = L Lᵀ` (the symmetric positive semi-definite `ginv`'s
/// eigenvectors scaled by the roots of their eigenvalues).
fn whitening(ginv: &DMatrix<f64>) -> DMatrix<f64> {
    let k = ginv.nrows();
    if k == 0 {
        return DMatrix::zeros(0, 0);
    }
    let e = ginv.clone().symmetric_eigen();
    let max = e.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let keep: Vec<usize> = (0..k).filter(|&c| e.eigenvalues[c] > 1e-14 * max).collect();
    DMatrix::from_fn(k, keep.len(), |z, c| {
        e.eigenvectors[(z, keep[c])] * e.eigenvalues[keep[c]].sqrt()
    })
}

/// The smallest length ≥ `n` whose only prime factors are 2, 3 and 5.
fn smooth_length(n: usize) -> usize {
    (n.max(1)..)
        .find(|&m| {
            let mut r = m;
            for p in [2, 3, 5] {
                while r % p == 0 {
                    r /= p;
                }
            }
            r == 1
        })
        .unwrap_or(n)
}

/// Scores `(ΔRSS mm², frequency Hz)` of the sinusoid pair at every
/// frequency `m/(N·period)` within `band`, spaced at most `df`: the same
/// value as the direct scan's at that frequency, up to rounding and the
/// clock's strays. `sel_h` is `Sᵀr`.
pub(super) fn scan(
    clock: &Clock,
    proj: &Projections,
    ginv: &DMatrix<f64>,
    sel_h: &DVector<f64>,
    band: (f64, f64),
    df: f64,
) -> Vec<(f64, f64)> {
    let n = clock.ticks.len();
    let last = clock.ticks[n - 1];
    let len = smooth_length(((1.0 / (df * clock.period)).ceil() as usize).max(last + 1));
    let bin = 1.0 / (len as f64 * clock.period);
    let m_lo = (band.0 / bin).ceil() as usize;
    let m_hi = ((band.1 / bin).floor() as usize).min(len / 2);
    if m_hi < m_lo + 1 {
        return Vec::new();
    }
    let nb = m_hi - m_lo + 1;
    let fft = FftPlanner::<f64>::new().plan_fft_forward(len);
    // Transform of two real signals at once: `x` the real part, `y` the
    // imaginary; their transforms separated at each bin.
    let transform = |x: &dyn Fn(usize) -> f64, y: &dyn Fn(usize) -> f64| -> Vec<Complex<f64>> {
        let mut buf = vec![Complex::new(0.0, 0.0); len];
        for i in 0..n {
            buf[clock.ticks[i] % len] += Complex::new(x(i), y(i));
        }
        fft.process(&mut buf);
        buf
    };
    let split = |z: &[Complex<f64>], m: usize| -> (Complex<f64>, Complex<f64>) {
        let a = z[m % len];
        let b = z[(len - m % len) % len].conj();
        ((a + b) * 0.5, (a - b) * Complex::new(0.0, -0.5))
    };
    // Weights (at 2m) and the projected residual (at m).
    let wp = transform(&|i| proj.w[i], &|i| proj.pr[i]);
    let w_sum: f64 = proj.w.iter().sum();
    // Selected columns, whitened, in pairs.
    let l = whitening(ginv);
    let r = l.ncols();
    let lh: Vec<f64> = (0..r)
        .map(|c| (0..proj.ks).map(|z| l[(z, c)] * sel_h[z]).sum())
        .collect();
    let whitened = |i: usize, c: usize| -> f64 {
        let row = &proj.ps[i * proj.ks..(i + 1) * proj.ks];
        row.iter().zip(l.column(c).iter()).map(|(a, b)| a * b).sum()
    };
    let pairs: Vec<usize> = (0..r.div_ceil(2)).collect();
    let per_group = pairs.len().div_ceil(GROUPS).max(1);
    let parts: Vec<Correction> = pairs
        .par_chunks(per_group)
        .map(|group| {
            let mut acc = Correction::zeros(nb);
            for &p in group {
                let (c0, c1) = (2 * p, 2 * p + 1);
                let z = if c1 < r {
                    transform(&|i| whitened(i, c0), &|i| whitened(i, c1))
                } else {
                    transform(&|i| whitened(i, c0), &|_| 0.0)
                };
                for b in 0..nb {
                    let (x0, x1) = split(&z, m_lo + b);
                    for (c, x) in [(c0, x0), (c1, x1)] {
                        if c >= r {
                            continue;
                        }
                        // Σ p cos θ = Re X, Σ p sin θ = −Im X.
                        let (ms, mc) = (-x.im, x.re);
                        acc.ss[b] += ms * ms;
                        acc.sc[b] += ms * mc;
                        acc.cc[b] += mc * mc;
                        acc.s[b] += ms * lh[c];
                        acc.c[b] += mc * lh[c];
                    }
                }
            }
            acc
        })
        .collect();
    let mut corr = Correction::zeros(nb);
    parts.iter().for_each(|p| corr.add(p));
    (0..nb)
        .map(|b| {
            let m = m_lo + b;
            let w2 = split(&wp, 2 * m).0;
            let pr = split(&wp, m).1;
            let ss = 0.5 * (w_sum - w2.re);
            let cc = 0.5 * (w_sum + w2.re);
            let sc = -0.5 * w2.im;
            let (rs, rc) = (-pr.im, pr.re);
            let a_sc = sc - corr.sc[b];
            let a = [ss - corr.ss[b], a_sc, a_sc, cc - corr.cc[b]];
            let c = [rs - corr.s[b], rc - corr.c[b]];
            (quad_form_2(&a, &c, [ss, cc]), m as f64 * bin)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::rng::Rng;

    /// ΔRSS of adding the columns `J_i sin θ_i`, `J_i cos θ_i` to the
    /// columns `s` in the least-squares fit of `r` (3 rows a sample),
    /// by two independent solves (SVD).
    fn delta_rss_by_solves(jac: &[[f64; 3]], r: &[[f64; 3]], s: &[Vec<f64>], theta: &[f64]) -> f64 {
        let n = jac.len();
        let ks = s[0].len() / 3;
        let rss = |extra: bool| -> f64 {
            let k = ks + if extra { 2 } else { 0 };
            let a = DMatrix::from_fn(3 * n, k, |row, col| {
                let (i, a) = (row / 3, row % 3);
                if col < ks {
                    s[i][a * ks + col]
                } else if col == ks {
                    jac[i][a] * theta[i].sin()
                } else {
                    jac[i][a] * theta[i].cos()
                }
            });
            let b = DVector::from_fn(3 * n, |row, _| r[row / 3][row % 3]);
            let x = a.clone().svd(true, true).solve(&b, 1e-13).expect("solve");
            (b - a * x).norm_squared()
        };
        rss(false) - rss(true)
    }

    #[test]
    fn the_fft_scan_scores_as_least_squares_does_at_every_frequency() {
        let mut rng = Rng::new(7);
        let (period, ks) = (0.01, 3);
        let ticks: Vec<usize> = (0..400).filter(|k| k % 23 != 4 && k % 31 != 9).collect();
        let n = ticks.len();
        let t: Vec<f64> = ticks.iter().map(|&k| 12.5 + period * k as f64).collect();
        let jac: Vec<[f64; 3]> = (0..n)
            .map(|_| [rng.normal(), rng.normal(), 0.3 * rng.normal()])
            .collect();
        // A residual with a sinusoid at 7.3 Hz along J and a part of the
        // selected columns, and selected columns (3 rows × ks a sample).
        let s: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..3 * ks).map(|_| rng.normal()).collect())
            .collect();
        let r: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let wave = 0.8 * (std::f64::consts::TAU * 7.3 * t[i] + 0.4).sin();
                std::array::from_fn(|a| jac[i][a] * wave + 0.5 * s[i][a * ks] + 0.2 * rng.normal())
            })
            .collect();
        let clock = regular_clock(&t, period).expect("regular");
        assert_eq!(clock.ticks[0], 0);
        let mut g = DMatrix::zeros(ks, ks);
        let mut h = DVector::zeros(ks);
        let (mut w, mut pr, mut ps) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..n {
            let jj = jac[i];
            w.push(jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]);
            pr.push(jj[0] * r[i][0] + jj[1] * r[i][1] + jj[2] * r[i][2]);
            for z in 0..ks {
                ps.push((0..3).map(|a| jj[a] * s[i][a * ks + z]).sum::<f64>());
                for a in 0..3 {
                    h[z] += s[i][a * ks + z] * r[i][a];
                    for q in 0..ks {
                        g[(z, q)] += s[i][a * ks + z] * s[i][a * ks + q];
                    }
                }
            }
        }
        let proj = Projections {
            w: &w,
            pr: &pr,
            ps: &ps,
            ks,
        };
        let span = t[n - 1] - t[0];
        let scores = scan(
            &clock,
            &proj,
            &super::super::pinv_sym(&g),
            &h,
            (0.5, 49.0),
            1.0 / (2.5 * span),
        );
        assert!(scores.len() > 400, "{} frequencies", scores.len());
        assert!(
            scores
                .windows(2)
                .all(|p| p[1].1 - p[0].1 <= 1.0 / (2.5 * span))
        );
        for &(score, f) in scores.iter().step_by(7) {
            let theta: Vec<f64> = t.iter().map(|x| std::f64::consts::TAU * f * x).collect();
            let want = delta_rss_by_solves(&jac, &r, &s, &theta);
            assert!(
                (score - want).abs() <= 1e-9 * want.abs().max(1.0),
                "{f} Hz: {score} against {want}"
            );
        }
        let best = scores
            .iter()
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .expect("some");
        assert!((best.1 - 7.3).abs() < 1.0 / span, "best at {} Hz", best.1);
    }

    #[test]
    fn smooth_lengths_have_only_small_prime_factors() {
        assert_eq!(smooth_length(1), 1);
        assert_eq!(smooth_length(7), 8);
        assert_eq!(smooth_length(31), 32);
        assert_eq!(smooth_length(241), 243);
        assert_eq!(smooth_length(1001), 1024);
    }

    #[test]
    fn a_clock_with_gaps_is_regular_and_jitter_is_not() {
        let t: Vec<f64> = (0..200)
            .filter(|k| k % 17 != 5)
            .map(|k| 3.0 + 0.004 * k as f64)
            .collect();
        let c = regular_clock(&t, 0.004).expect("regular with gaps");
        assert!((c.period - 0.004).abs() < 1e-15);
        assert_eq!(c.ticks[5], 6);
        let jittered: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, x)| x + if i % 3 == 0 { 1e-4 } else { 0.0 })
            .collect();
        assert!(regular_clock(&jittered, 0.004).is_none());
    }
}
