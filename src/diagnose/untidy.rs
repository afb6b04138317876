//! What real recordings carry besides machine physics (`formats.md` §2c):
//! the resolution of the export, gross outliers and a clock offset between
//! the recording and the program. Each is found here, named for what it is
//! and removed before any machine effect is fitted (`docs/diagnose.md`,
//! "Untidy recordings").

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

use super::fit::pinv_sym;
use super::prepare::{ModelMachine, Prepared, noise_floor, prepare};
use super::recording::{Recording, Sample};
use super::report::{FlaggedSample, MeasurementFinding, Where};
use crate::error::{Error, Location, Result};
use crate::machine::chain::JointKind;

/// A recording whose median tip residual exceeds this (mm) does not fit
/// the machine at all: another machine, another axis order, other units.
pub const MISFIT_MM: f64 = 5.0;

/// A recording that the model, with the effects that fit best, still
/// misses by more than this RMS per coordinate (mm) does not fit the
/// machine either.
pub const MISFIT_AFTER_MM: f64 = 1.0;

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

/// A sample departs from its neighbours by more than this many noise
/// floors to be a gross outlier.
pub const OUTLIER_SIGMAS: f64 = 10.0;

/// Half-width of the running median the outliers are measured against.
const MEDIAN_HALF: usize = 3;

/// More flagged samples than this fraction are not gross faults but a
/// signal the running median cannot follow: none is called an outlier.
const MAX_OUTLIER_FRACTION: f64 = 0.05;

/// Gross outliers of a residual: samples whose residual departs from its
/// neighbours ([`departure`]) by more than [`OUTLIER_SIGMAS`] noise floors
/// in some coordinate (samples `skip` marks are not looked at). A smooth
/// effect, a kink, a step at a reversal or an onset is never flagged. When
/// most flagged samples sit within two samples of a reversal (more than
/// chance would put there), those are a following error at reversals,
/// machine physics, and stay in. More than 5 % flagged is not a fault
/// but a signal the running median cannot follow: then none is flagged.
/// Returns the flagged sample indices and each one's departure (mm).
pub fn gross_outliers(
    prep: &Prepared,
    sigma_xyz: [f64; 3],
    skip: &[bool],
) -> Vec<(usize, [f64; 3])> {
    let n = prep.n;
    if n < 2 * MEDIAN_HALF + 1 {
        return Vec::new();
    }
    let mut out = Vec::new();
    let mut column = vec![0.0; n];
    let mut dev = vec![[0.0; 3]; n];
    let mut far = vec![false; n];
    for c in 0..3 {
        for i in 0..n {
            column[i] = prep.r[i][c];
        }
        for i in 0..n {
            if skip.get(i).copied().unwrap_or(false) {
                continue;
            }
            let d = departure(&column, i);
            dev[i][c] = d;
            if d.abs() > OUTLIER_SIGMAS * sigma_xyz[c].max(1e-9) {
                far[i] = true;
            }
        }
    }
    for i in 0..n {
        if far[i] {
            out.push((i, dev[i]));
        }
    }
    // Spikes that come with reversals are a following error, machine
    // physics: when most flagged samples sit at reversals, more than
    // chance would put there, those are kept in the fits.
    let near = out.iter().filter(|(i, _)| near_reversal(prep, *i)).count();
    let base = (0..n).filter(|&i| near_reversal(prep, i)).count() as f64 / n as f64;
    if out.len() >= 5 && near as f64 >= 0.6 * out.len() as f64 && base < 0.3 {
        out.retain(|(i, _)| !near_reversal(prep, *i));
    }
    if out.len() as f64 > MAX_OUTLIER_FRACTION * n as f64 {
        return Vec::new();
    }
    out
}

/// How far sample `i` of a series departs from its neighbours: the
/// smaller of its departures from the running median of the 7 samples
/// around it (which follows a step) and from the median of three straight-
/// line predictions from its neighbours (from the left pair, the right
/// pair, and the two beside it; which follow a kink). A gross fault departs
/// from both; a step, a kink or a slope from at most one.
pub fn departure(e: &[f64], i: usize) -> f64 {
    let n = e.len();
    let a = i.saturating_sub(MEDIAN_HALF);
    let b = (i + MEDIAN_HALF + 1).min(n);
    let mut w: arrayvec::ArrayVec<f64, 7> = e[a..b].iter().copied().collect();
    let mid = w.len() / 2;
    w.select_nth_unstable_by(mid, f64::total_cmp);
    let from_median = e[i] - w[mid];
    let mut p: arrayvec::ArrayVec<f64, 3> = arrayvec::ArrayVec::new();
    if i >= 2 {
        p.push(2.0 * e[i - 1] - e[i - 2]);
    }
    if i + 2 < n {
        p.push(2.0 * e[i + 1] - e[i + 2]);
    }
    if i >= 1 && i + 1 < n {
        p.push(0.5 * (e[i - 1] + e[i + 1]));
    }
    if p.is_empty() {
        return from_median;
    }
    p.sort_by(f64::total_cmp);
    let from_line = e[i] - p[p.len() / 2];
    if from_median.abs() < from_line.abs() {
        from_median
    } else {
        from_line
    }
}

/// Whether some axis reverses within two samples of sample `i`.
fn near_reversal(prep: &Prepared, i: usize) -> bool {
    let a = i.saturating_sub(2);
    let b = (i + 2).min(prep.n - 1);
    (0..prep.dof).any(|j| (a..b).any(|k| prep.dirj(k, j) * prep.dirj(k + 1, j) < 0.0))
}

/// The lag of each axis as the residual shows it: the least-squares fit of
/// `r ≈ −Σⱼ Lⱼ · Jⱼ · q̇ⱼ` over the samples `keep` allows. Returns each
/// axis's lag (s) and its standard deviation for a noise floor of 1 mm
/// (scale by σ), and the normal matrix with the right-hand side.
struct AxisLags {
    lag: Vec<f64>,
    sd_unit: Vec<f64>,
    g: DMatrix<f64>,
    h: DVector<f64>,
}

fn axis_lags(prep: &Prepared, keep: &[bool]) -> AxisLags {
    let dof = prep.dof;
    let mut g = DMatrix::zeros(dof, dof);
    let mut h = DVector::zeros(dof);
    let mut col = vec![[0.0; 3]; dof];
    for i in 0..prep.n {
        if !keep[i] {
            continue;
        }
        for j in 0..dof {
            let jj = prep.jj(i, j);
            let v = prep.vj(i, j);
            col[j] = [-jj[0] * v, -jj[1] * v, -jj[2] * v];
        }
        for a in 0..dof {
            h[a] += (0..3).map(|c| col[a][c] * prep.r[i][c]).sum::<f64>();
            for b in 0..dof {
                g[(a, b)] += (0..3).map(|c| col[a][c] * col[b][c]).sum::<f64>();
            }
        }
    }
    let inv = pinv_sym(&g);
    let lag = (&inv * &h).iter().copied().collect();
    let sd_unit = (0..dof).map(|j| inv[(j, j)].max(0.0).sqrt()).collect();
    AxisLags { lag, sd_unit, g, h }
}

/// An axis informs the clock offset when its lag is known to this (s).
const INFORMATIVE_SD_S: f64 = 1e-3;

/// How far an axis's lag may be from the common one and still share it,
/// beyond 4 of its standard deviations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// A fraction of the common lag.
    pub relative: f64,
    /// An absolute margin, s.
    pub absolute_s: f64,
}

/// Loose: the first look, on unaligned data, where the second-order
/// terms of a large offset differ between axes.
pub const LOOSE: Tolerance = Tolerance {
    relative: 0.05,
    absolute_s: 1e-4,
};

/// Strict: after a first alignment, where what an axis lags beyond the
/// others is its own servo lag.
pub const STRICT: Tolerance = Tolerance {
    relative: 0.0,
    absolute_s: 1e-6,
};

/// A clock offset seen in a residual.
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetEstimate {
    /// The offset (s): the sample stamped t shows the machine at t − offset.
    pub offset_s: f64,
    /// Its standard deviation, s.
    pub sd_s: f64,
    /// The axes that share it (chain indices).
    pub shared: Vec<usize>,
    /// Each axis's apparent lag and its standard deviation, s.
    pub lags: Vec<(f64, f64)>,
    /// Decrease of χ² when the common lag enters (the other axes' own lags
    /// already in).
    pub delta_chi2: f64,
}

/// The clock offset of a residual, if it shows one.
///
/// A clock offset delays every axis by the same time; a servo lag delays
/// one axis by its own. So each axis's apparent lag is fitted, their
/// median taken as the common value, and the axes whose lag agrees with
/// it (within 4 standard deviations plus `tolerance`) share the offset. It is a
/// clock offset when at least two axes, and more than half of those whose
/// lag the recording determines, share it, and the common lag lowers χ²
/// by more than `min_delta_chi2`. What an axis lags beyond the common
/// value is left for its servo lag. When `shared` is given, those axes are
/// taken as sharing it (for the refinement after a first alignment).
pub fn clock_offset(
    prep: &Prepared,
    keep: &[bool],
    sigma: f64,
    min_delta_chi2: f64,
    shared: Option<&[usize]>,
    tolerance: Tolerance,
) -> Option<OffsetEstimate> {
    let dof = prep.dof;
    let al = axis_lags(prep, keep);
    let lags: Vec<(f64, f64)> = (0..dof)
        .map(|j| (al.lag[j], al.sd_unit[j] * sigma))
        .collect();
    let set: Vec<usize> = match shared {
        Some(s) => s.to_vec(),
        None => {
            let informative: Vec<usize> = (0..dof)
                .filter(|&j| al.g[(j, j)] > 0.0 && lags[j].1 < INFORMATIVE_SD_S)
                .collect();
            if informative.len() < 2 {
                return None;
            }
            let mut ls: Vec<f64> = informative.iter().map(|&j| lags[j].0).collect();
            ls.sort_by(f64::total_cmp);
            let m = ls.len();
            let median = if m % 2 == 1 {
                ls[m / 2]
            } else {
                0.5 * (ls[m / 2 - 1] + ls[m / 2])
            };
            let set: Vec<usize> = informative
                .iter()
                .copied()
                .filter(|&j| {
                    (lags[j].0 - median).abs()
                        <= 4.0 * lags[j].1
                            + tolerance.relative * median.abs()
                            + tolerance.absolute_s
                })
                .collect();
            if set.len() < 2 || 2 * set.len() <= informative.len() {
                return None;
            }
            set
        }
    };
    // Reduced fit: one common lag for the set, an own lag for every other
    // axis.
    let others: Vec<usize> = (0..dof).filter(|j| !set.contains(j)).collect();
    let k = 1 + others.len();
    let idx = |p: usize| -> Vec<usize> {
        if p == 0 {
            set.clone()
        } else {
            vec![others[p - 1]]
        }
    };
    let mut g = DMatrix::zeros(k, k);
    let mut h = DVector::zeros(k);
    for a in 0..k {
        let ia = idx(a);
        h[a] = ia.iter().map(|&j| al.h[j]).sum();
        for b in 0..k {
            let ib = idx(b);
            g[(a, b)] = ia
                .iter()
                .flat_map(|&x| ib.iter().map(move |&y| (x, y)))
                .map(|(x, y)| al.g[(x, y)])
                .sum();
        }
    }
    let inv = pinv_sym(&g);
    let beta = &inv * &h;
    let d = beta[0];
    let sd = inv[(0, 0)].max(0.0).sqrt() * sigma;
    // χ² decrease of the common lag given the others: d² / var(d).
    let delta_chi2 = if sd > 0.0 { (d / sd).powi(2) } else { 0.0 };
    if shared.is_none() && delta_chi2 < min_delta_chi2 {
        return None;
    }
    Some(OffsetEstimate {
        offset_s: d,
        sd_s: sd,
        shared: set,
        lags,
        delta_chi2,
    })
}

/// `rec` with its command columns moved to the machine's clock: each
/// sample stamped t gets the command of t − `offset_s`, interpolated by a
/// cubic Hermite spline through the recorded commands (tangents from
/// central differences; exact for a constant feed and for a constant
/// acceleration within a block). Samples whose t − offset falls outside
/// the recording are dropped.
///
/// Where a command changes its acceleration between two samples no
/// interpolant knows where, and the aligned command may be off by up to
/// about a quarter of the largest third difference nearby times the shift
/// in samples: that bound is returned per sample and axis (`blur`, mm or
/// deg), so that samples the alignment cannot place within the noise are
/// left out of the fits.
pub fn align(rec: &Recording, offset_s: f64) -> Aligned {
    let s = &rec.samples;
    let n = s.len();
    let mut out = Recording {
        axes: rec.axes.clone(),
        temp_names: rec.temp_names.clone(),
        samples: Vec::with_capacity(n),
    };
    let mut kept = Vec::with_capacity(n);
    let dof = rec.axes.len();
    let mut blur = Vec::with_capacity(n * dof);
    if n < 2 {
        return Aligned {
            rec: out,
            kept,
            blur,
        };
    }
    // Third difference of the commands over samples k − 1 … k + 2.
    // Rounded commands carry a third difference of their own (its
    // standard deviation is √(20/12)·q for a step q); three of those are
    // not a change of acceleration.
    let rounding: Vec<f64> = (0..dof)
        .map(|j| {
            let col: Vec<f64> = s.iter().map(|x| x.q[j]).collect();
            quantum(&col).map_or(0.0, |q| 3.0 * (20.0f64 / 12.0).sqrt() * q)
        })
        .collect();
    // Near the ends the tangents are one-sided and nothing bounds the
    // error: such samples count as doubtful (a bound of 1 m).
    let d3 = |k: usize, j: usize| {
        if k == 0 || k + 2 >= n {
            return 4e3;
        }
        let d = (s[k + 2].q[j] - 3.0 * s[k + 1].q[j] + 3.0 * s[k].q[j] - s[k - 1].q[j]).abs();
        (d - rounding[j]).max(0.0)
    };
    let times: Vec<f64> = s.iter().map(|x| x.t).collect();
    let columns: Vec<Vec<f64>> = (0..dof)
        .map(|j| s.iter().map(|x| x.q[j]).collect())
        .collect();
    let mut k = 0usize;
    for (i, smp) in s.iter().enumerate() {
        let tt = smp.t - offset_s;
        if tt < s[0].t || tt > s[n - 1].t {
            continue;
        }
        while k + 2 < n && s[k + 1].t <= tt {
            k += 1;
        }
        while k > 0 && s[k].t > tt {
            k -= 1;
        }
        let (t0, t1) = (s[k].t, s[k + 1].t);
        let dt = t1 - t0;
        let u = ((tt - t0) / dt).clamp(0.0, 1.0);
        let q: Vec<f64> = columns
            .iter()
            .map(|y| monotone_hermite(&times, y, k, tt))
            .collect();
        let block = if u < 0.5 { s[k].block } else { s[k + 1].block };
        let shift = (offset_s.abs() / dt).min(1.0);
        for j in 0..dof {
            let worst = (k.saturating_sub(1)..=k + 1)
                .map(|m| d3(m, j))
                .fold(0.0, f64::max);
            blur.push(0.25 * worst * shift);
        }
        out.samples.push(Sample {
            q,
            block,
            ..smp.clone()
        });
        kept.push(i);
    }
    Aligned {
        rec: out,
        kept,
        blur,
    }
}

/// The value at `tt` (within interval `k` of the increasing times `t`) of
/// the cubic Hermite spline through `y` with central-difference tangents,
/// limited so that it never overshoots (Fritsch–Carlson): a tangent is 0
/// where the data turns or stands still, and at most three times the
/// smaller neighbouring slope. Exact for a constant feed and a constant
/// acceleration away from stops; a command that stands still stays still
/// (an overshoot there would fake a reversal).
pub fn monotone_hermite(t: &[f64], y: &[f64], k: usize, tt: f64) -> f64 {
    let n = t.len();
    let slope = |i: usize| (y[i + 1] - y[i]) / (t[i + 1] - t[i]);
    let tangent = |i: usize| -> f64 {
        if i == 0 {
            return slope(0);
        }
        if i == n - 1 {
            return slope(n - 2);
        }
        let (a, b) = (slope(i - 1), slope(i));
        if a * b <= 0.0 {
            return 0.0;
        }
        let m = (y[i + 1] - y[i - 1]) / (t[i + 1] - t[i - 1]);
        let cap = 3.0 * a.abs().min(b.abs());
        m.clamp(-cap, cap)
    };
    let h = t[k + 1] - t[k];
    let (m0, m1) = if y[k + 1] == y[k] {
        (0.0, 0.0)
    } else {
        (tangent(k), tangent(k + 1))
    };
    let u = ((tt - t[k]) / h).clamp(0.0, 1.0);
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0) * y[k]
        + (u3 - 2.0 * u2 + u) * h * m0
        + (-2.0 * u3 + 3.0 * u2) * y[k + 1]
        + (u3 - u2) * h * m1
}

/// A recording moved to the machine's clock ([`align`]).
#[derive(Debug, Clone)]
pub struct Aligned {
    /// The aligned recording.
    pub rec: Recording,
    /// Per sample, its index in the original recording.
    pub kept: Vec<usize>,
    /// Per sample and axis (`kept.len() × dof`), a bound of the
    /// interpolation error of the aligned command (mm or deg).
    pub blur: Vec<f64>,
}

impl Aligned {
    /// Samples whose interpolation error, carried to the tip by the
    /// Jacobian of `prep` (prepared from this recording), may exceed
    /// `limit_mm`.
    pub fn doubtful(&self, prep: &Prepared, limit_mm: f64) -> Vec<bool> {
        let dof = prep.dof;
        (0..prep.n)
            .map(|i| {
                let e: f64 = (0..dof)
                    .map(|j| {
                        let jj = prep.jj(i, j);
                        (jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]).sqrt()
                            * self.blur[i * dof + j]
                    })
                    .sum();
                e > limit_mm
            })
            .collect()
    }
}

/// `rec` without the samples at `drop` (sorted indices); with the indices
/// of the samples kept.
pub fn without(rec: &Recording, drop: &[usize]) -> (Recording, Vec<usize>) {
    let mut out = Recording {
        axes: rec.axes.clone(),
        temp_names: rec.temp_names.clone(),
        samples: Vec::with_capacity(rec.samples.len()),
    };
    let mut kept = Vec::with_capacity(rec.samples.len());
    let mut d = drop.iter().peekable();
    for (i, s) in rec.samples.iter().enumerate() {
        if d.peek() == Some(&&i) {
            d.next();
            continue;
        }
        out.samples.push(s.clone());
        kept.push(i);
    }
    (out, kept)
}

/// The noise floor of a prepared residual per coordinate, and its
/// quadratic mean: the robust estimate, never below the rounding of the
/// measured tip, plus the rounding of the commands (`rounding` as
/// [`Resolution::floor_xyz`], mm); `fixed` overrides both.
pub fn floor_of(
    prep: &Prepared,
    rounding: ([f64; 3], [f64; 3]),
    fixed: Option<f64>,
) -> ([f64; 3], f64) {
    if let Some(f) = fixed {
        return ([f; 3], f);
    }
    let (per, _) = noise_floor(&prep.r);
    let (meas, cmd) = rounding;
    let per: [f64; 3] = std::array::from_fn(|c| per[c].max(meas[c]).hypot(cmd[c]));
    let pooled = ((per[0] * per[0] + per[1] * per[1] + per[2] * per[2]) / 3.0).sqrt();
    (per, pooled.max(1e-6))
}

/// A clock offset found and removed.
#[derive(Debug, Clone, PartialEq)]
pub struct Offset {
    /// The estimate after the refinement.
    pub estimate: OffsetEstimate,
    /// RMS per coordinate of the tip change the alignment makes, mm.
    pub rms_explained_mm: f64,
    /// Samples dropped at the ends (no command within the recording).
    pub dropped: usize,
    /// Samples left out because the alignment cannot place their command
    /// within half the noise floor (a change of acceleration between
    /// samples).
    pub doubtful: usize,
}

/// A recording made tidy: aligned to the program's clock, without its
/// gross outliers, and with the resolution of its values read.
#[derive(Debug, Clone)]
pub struct Tidy {
    /// The recording to fit machine effects on.
    pub rec: Recording,
    /// For each of its samples, the index in the original recording.
    pub kept: Vec<usize>,
    /// The clock offset, when there is one.
    pub offset: Option<Offset>,
    /// Gross outliers: index in the original recording, time (s), block,
    /// departure from the running median (mm).
    pub outliers: Vec<(usize, f64, Option<u64>, [f64; 3])>,
    /// Resolution of the values.
    pub resolution: Resolution,
    /// The noise the rounding adds, per coordinate, mm: of the measured
    /// tip, of the commands ([`Resolution::floor_xyz`]).
    pub rounding_xyz: ([f64; 3], [f64; 3]),
}

/// Finds and removes what is not machine physics, in this order: a
/// recording that does not fit the machine at all is an error; the
/// resolution of the values sets the least noise floor; gross outliers of
/// the raw residual are set aside; a clock offset is estimated without them
/// and removed by moving the commands to the machine's clock; the outliers
/// are found again on the aligned residual and excluded.
/// `min_delta_chi2` is what a clock offset must lower χ² by.
pub fn tidy(
    machine: &ModelMachine,
    rec: &Recording,
    fixed_floor: Option<f64>,
    min_delta_chi2: f64,
) -> Result<Tidy> {
    let prep0 = prepare(machine, rec)?;
    let resolution = Resolution::of(rec);
    let rounding_xyz = resolution.floor_xyz(&prep0);
    let (per0, sigma0) = floor_of(&prep0, rounding_xyz, fixed_floor);
    let out0: Vec<usize> = gross_outliers(&prep0, per0, &[])
        .into_iter()
        .map(|(i, _)| i)
        .collect();
    let mut keep0 = vec![true; prep0.n];
    for &i in &out0 {
        keep0[i] = false;
    }
    let first = clock_offset(&prep0, &keep0, sigma0, min_delta_chi2, None, LOOSE)
        .filter(|e| e.offset_s.abs() >= MIN_OFFSET_SAMPLES * median_interval(rec))
        .filter(|e| e.delta_chi2 >= MIN_OFFSET_SHARE * excess_chi2(&prep0, &keep0, sigma0));
    let offset = match first {
        None => None,
        Some(first) => refine_offset(
            machine,
            rec,
            &prep0,
            &keep0,
            rounding_xyz,
            fixed_floor,
            first,
        )?,
    };
    let (rec1, kept1, blur) = match &offset {
        Some(o) => {
            let al = align(rec, o.estimate.offset_s);
            (al.rec.clone(), al.kept.clone(), Some(al))
        }
        None => (rec.clone(), (0..rec.samples.len()).collect(), None),
    };
    let prep1 = prepare(machine, &rec1)?;
    misfit(&prep1)?;
    let (per1, sigma1) = floor_of(&prep1, rounding_xyz, fixed_floor);
    // Samples the alignment cannot place are left out first, so that they
    // are never taken for outliers.
    let doubtful = match &blur {
        Some(al) => al.doubtful(&prep1, 0.5 * sigma1),
        None => vec![false; prep1.n],
    };
    let mut offset = offset;
    if let Some(o) = offset.as_mut() {
        o.doubtful = doubtful.iter().filter(|d| **d).count();
    }
    let out1: Vec<(usize, [f64; 3])> = gross_outliers(&prep1, per1, &doubtful);
    let mut drop: Vec<usize> = out1.iter().map(|(i, _)| *i).collect();
    drop.extend((0..prep1.n).filter(|&i| doubtful[i]));
    drop.sort_unstable();
    drop.dedup();
    let (rec2, kept2) = without(&rec1, &drop);
    let outliers = out1
        .iter()
        .map(|&(i, d)| (kept1[i], rec1.samples[i].t, rec1.samples[i].block, d))
        .collect();
    Ok(Tidy {
        rec: rec2,
        kept: kept2.iter().map(|&i| kept1[i]).collect(),
        offset,
        outliers,
        resolution,
        rounding_xyz,
    })
}

/// A clock offset shorter than this fraction of the sampling interval is
/// not resolved by the recording (and would be the side effect of some
/// other mismatch).
pub const MIN_OFFSET_SAMPLES: f64 = 0.01;

/// A clock offset must account for at least this share of the
/// residual's excess χ²: a common delay that explains only a little of a
/// mismatch is the side effect of another effect, not the clock.
pub const MIN_OFFSET_SHARE: f64 = 0.25;

/// The median time between samples, s.
fn median_interval(rec: &Recording) -> f64 {
    let mut d: Vec<f64> = rec.samples.windows(2).map(|w| w[1].t - w[0].t).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid]
}

/// χ² of the residual above its degrees of freedom, over the samples
/// `keep` allows.
fn excess_chi2(prep: &Prepared, keep: &[bool], sigma: f64) -> f64 {
    let (mut chi, mut dof) = (0.0, 0.0);
    for i in 0..prep.n {
        if keep[i] {
            let r = prep.r[i];
            chi += (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) / (sigma * sigma);
            dof += 3.0;
        }
    }
    (chi - dof).max(0.0)
}

/// A recording whose median tip residual (after any alignment) exceeds
/// [`MISFIT_MM`] does not fit the machine: a clear error.
fn misfit(prep: &Prepared) -> Result<()> {
    let mut norms: Vec<f64> = prep
        .r
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .collect();
    let mid = norms.len() / 2;
    norms.select_nth_unstable_by(mid, f64::total_cmp);
    let median = norms[mid];
    if median > MISFIT_MM {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "the recording does not fit this machine: the measured tool tip is a median {median:.3} mm from where the machine model puts it (more than {MISFIT_MM} mm). Is it a recording of this machine, with its axes in mm and degrees and the tip in the workpiece frame?"
            ),
        ));
    }
    Ok(())
}

/// Refines a first clock-offset estimate by aligning and re-fitting the
/// common lag of the same axes until it stops changing; `None` when the
/// aligned recording does not fit better.
fn refine_offset(
    machine: &ModelMachine,
    rec: &Recording,
    prep0: &Prepared,
    keep0: &[bool],
    rounding: ([f64; 3], [f64; 3]),
    fixed_floor: Option<f64>,
    first: OffsetEstimate,
) -> Result<Option<Offset>> {
    // The samples to fit on after an alignment: not doubtful, not an
    // outlier of the aligned residual, not set aside before.
    let usable = |al: &Aligned, pa: &Prepared| {
        let (per, sigma) = floor_of(pa, rounding, fixed_floor);
        let doubtful = al.doubtful(pa, 0.5 * sigma);
        let mut keep: Vec<bool> = al
            .kept
            .iter()
            .zip(&doubtful)
            .map(|(&i, &dbt)| keep0[i] && !dbt)
            .collect();
        for (i, _) in gross_outliers(pa, per, &doubtful) {
            keep[i] = false;
        }
        (keep, sigma)
    };
    let mut shared = first.shared.clone();
    let mut d = first.offset_s;
    let mut last = first;
    for round in 0..8 {
        let al = align(rec, d);
        if al.rec.samples.len() < 20 {
            return Ok(None);
        }
        let pa = prepare(machine, &al.rec)?;
        let (keep, sigma) = usable(&al, &pa);
        // Once roughly aligned, the axes that share the offset are chosen
        // again, strictly: an axis that lags beyond the others keeps that
        // as its own servo lag.
        if round == 1
            && let Some(strict) = clock_offset(&pa, &keep, sigma, 0.0, None, STRICT)
        {
            shared = strict.shared;
        }
        let Some(step) = clock_offset(&pa, &keep, sigma, 0.0, Some(&shared), STRICT) else {
            break;
        };
        d += step.offset_s;
        last = OffsetEstimate {
            offset_s: d,
            ..step
        };
        if round >= 1 && step.offset_s.abs() <= 1e-4 * d.abs() + 1e-7 {
            break;
        }
    }
    let al = align(rec, d);
    if al.rec.samples.len() < 20 {
        return Ok(None);
    }
    let pa = prepare(machine, &al.rec)?;
    let (keep, _) = usable(&al, &pa);
    let kept = &al.kept;
    // The aligned residual must be smaller, on the same samples.
    let rss = |r: &[f64; 3]| r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    let (mut before, mut after, mut moved) = (0.0, 0.0, 0.0);
    for (k, &i) in kept.iter().enumerate() {
        if !keep[k] {
            continue;
        }
        before += rss(&prep0.r[i]);
        after += rss(&pa.r[k]);
        let m = [
            prep0.model_tip[i][0] - pa.model_tip[k][0],
            prep0.model_tip[i][1] - pa.model_tip[k][1],
            prep0.model_tip[i][2] - pa.model_tip[k][2],
        ];
        moved += rss(&m);
    }
    if before - after <= 0.0 {
        return Ok(None);
    }
    Ok(Some(Offset {
        estimate: last,
        rms_explained_mm: (moved / (3 * kept.len()).max(1) as f64).sqrt(),
        dropped: rec.samples.len() - kept.len(),
        doubtful: 0,
    }))
}

impl Tidy {
    /// The measurement findings (`time_offset`, `outliers`) against the
    /// original recording `rec`.
    pub fn findings(&self, rec: &Recording) -> Vec<MeasurementFinding> {
        let n = rec.samples.len().max(1);
        let first = rec.samples.first();
        let last = rec.samples.last();
        let mut out = Vec::new();
        if let Some(o) = &self.offset {
            let e = &o.estimate;
            let mut dropped = String::new();
            if o.dropped > 0 {
                dropped.push_str(&format!(
                    "; {} sample(s) at the ends have no command {:.1} ms earlier and are left out",
                    o.dropped,
                    e.offset_s * 1e3
                ));
            }
            if o.doubtful > 0 {
                dropped.push_str(&format!(
                    "; {} sample(s) where the command changes its acceleration between samples cannot be aligned within half the noise floor and are left out of the machine fits",
                    o.doubtful
                ));
            }
            out.push(MeasurementFinding {
                effect: "time_offset".into(),
                axis: None,
                parameters: [("offset_s".to_string(), e.offset_s)].into(),
                uncertainty: [("offset_s".to_string(), e.sd_s)].into(),
                where_: Where {
                    blocks: [first.and_then(|s| s.block), last.and_then(|s| s.block)],
                    t_s: [first.map_or(0.0, |s| s.t), last.map_or(0.0, |s| s.t)],
                    condition: format!(
                        "everywhere: the recording {} the program by {:.3} ms, as every moving axis shows the same delay; removed before any machine effect was fitted{dropped}",
                        if e.offset_s >= 0.0 { "lags" } else { "leads" },
                        e.offset_s.abs() * 1e3
                    ),
                },
                rms_explained_mm: o.rms_explained_mm,
                machine_physics: false,
                samples: Vec::new(),
            });
        }
        if !self.outliers.is_empty() {
            let k = self.outliers.len();
            let ss: f64 = self
                .outliers
                .iter()
                .map(|(_, _, _, d)| d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                .sum();
            let a = &self.outliers[0];
            let b = &self.outliers[k - 1];
            let largest = self
                .outliers
                .iter()
                .map(|(_, _, _, d)| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
                .fold(0.0, f64::max);
            out.push(MeasurementFinding {
                effect: "outliers".into(),
                axis: None,
                parameters: [
                    ("count".to_string(), k as f64),
                    ("fraction".to_string(), k as f64 / n as f64),
                ]
                .into(),
                uncertainty: BTreeMap::new(),
                where_: Where {
                    blocks: [a.2, b.2],
                    t_s: [a.1, b.1],
                    condition: format!(
                        "{k} isolated sample(s) depart from their neighbours by more than {OUTLIER_SIGMAS} noise floors (up to {largest:.4} mm): gross measurement faults, excluded from every fit"
                    ),
                },
                rms_explained_mm: (ss / (3 * n) as f64).sqrt(),
                machine_physics: false,
                samples: self
                    .outliers
                    .iter()
                    .take(50)
                    .map(|&(index, t_s, block, departure_mm)| FlaggedSample {
                        index,
                        t_s,
                        block,
                        departure_mm,
                    })
                    .collect(),
            });
        }
        out
    }

    /// The resolutions read, keyed with their unit (`meas_mm`, `X_mm`,
    /// `C_deg`).
    pub fn resolution_keys(&self, prep: &Prepared) -> BTreeMap<String, f64> {
        let mut m = BTreeMap::new();
        if let Some(q) = self.resolution.meas_mm {
            m.insert("meas_mm".to_string(), q);
        }
        for (j, q) in self.resolution.axes.iter().enumerate() {
            if let (Some(q), Some(name)) = (q, prep.names.get(j)) {
                let unit = if prep.kinds[j] == JointKind::Revolute {
                    "deg"
                } else {
                    "mm"
                };
                m.insert(format!("{name}_{unit}"), *q);
            }
        }
        m
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

    #[test]
    fn alignment_reproduces_a_quadratic_command() {
        // q(t) = 3 + 2t + 0.5t²: the Hermite spline with central tangents
        // is exact for it away from the ends.
        let q = |t: f64| 3.0 + 2.0 * t + 0.5 * t * t;
        let samples: Vec<Sample> = (0..40)
            .map(|i| {
                let t = i as f64 * 0.1;
                Sample {
                    t,
                    block: Some(1),
                    q: vec![q(t)],
                    meas: [0.0; 3],
                    meas_axis: None,
                    temps: Vec::new(),
                }
            })
            .collect();
        let rec = Recording {
            axes: vec!["X".into()],
            temp_names: Vec::new(),
            samples,
        };
        let al = align(&rec, 0.015);
        let (a, kept) = (&al.rec, &al.kept);
        assert_eq!(
            kept.first(),
            Some(&1),
            "the first sample has no command 15 ms before"
        );
        for (s, &i) in a.samples.iter().zip(kept).skip(1).take(30) {
            let want = q(rec.samples[i].t - 0.015);
            assert!((s.q[0] - want).abs() < 1e-12, "{} vs {want}", s.q[0]);
        }
    }
}
