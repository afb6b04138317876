//! A clock offset between the recording and the program: the delay every
//! moving axis shares, told apart from an axis's own servo lag.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};

use super::super::fit::pinv_sym;
use super::super::prepare::Prepared;

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

/// The normal equations of the timing columns over the samples `keep`
/// allows: each axis's lag, `−Jⱼ · q̇ⱼ`, and with `rate_about` = t̄ also
/// each axis's rate, `−Jⱼ · q̇ⱼ · (t − t̄)` (lags first, then rates).
fn timing_normal(
    prep: &Prepared,
    keep: &[bool],
    rate_about: Option<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let dof = prep.dof;
    let k = if rate_about.is_some() { 2 * dof } else { dof };
    let mut g = DMatrix::zeros(k, k);
    let mut h = DVector::zeros(k);
    let mut col = vec![[0.0; 3]; k];
    for i in 0..prep.n {
        if !keep[i] {
            continue;
        }
        for j in 0..dof {
            let jj = prep.jj(i, j);
            let v = prep.vj(i, j);
            col[j] = [-jj[0] * v, -jj[1] * v, -jj[2] * v];
            if let Some(t_ref) = rate_about {
                let dt = prep.t[i] - t_ref;
                col[dof + j] = [col[j][0] * dt, col[j][1] * dt, col[j][2] * dt];
            }
        }
        for a in 0..k {
            h[a] += (0..3).map(|c| col[a][c] * prep.r[i][c]).sum::<f64>();
            for b in 0..k {
                g[(a, b)] += (0..3).map(|c| col[a][c] * col[b][c]).sum::<f64>();
            }
        }
    }
    (g, h)
}

/// The normal equations of `g`, `h` with the columns of each group summed
/// into one (a common lag or rate for the axes of a group).
fn grouped(
    g: &DMatrix<f64>,
    h: &DVector<f64>,
    groups: &[Vec<usize>],
) -> (DMatrix<f64>, DVector<f64>) {
    let m = groups.len();
    let gr = DMatrix::from_fn(m, m, |a, b| {
        groups[a]
            .iter()
            .flat_map(|&x| groups[b].iter().map(move |&y| (x, y)))
            .map(|(x, y)| g[(x, y)])
            .sum()
    });
    let hr = DVector::from_fn(m, |a, _| groups[a].iter().map(|&x| h[x]).sum());
    (gr, hr)
}

fn axis_lags(prep: &Prepared, keep: &[bool]) -> AxisLags {
    let dof = prep.dof;
    let (g, h) = timing_normal(prep, keep, None);
    let inv = pinv_sym(&g);
    let lag = (&inv * &h).iter().copied().collect();
    let sd_unit = (0..dof).map(|j| inv[(j, j)].max(0.0).sqrt()).collect();
    AxisLags { lag, sd_unit, g, h }
}

/// The residual of `prep` with each axis's apparent lag taken out (the
/// least-squares fit of `r ≈ −Σⱼ Lⱼ · Jⱼ · q̇ⱼ` over every sample): what the
/// noise floor is read from. A servo lag or a clock offset is smooth in
/// time but not at the sampling's scale where the feed changes (a 20 ms
/// lag at 10 Hz moves the tip by 0.4 mm between two samples there), and
/// left in it raised the floor of a 1 µm recording to 2 µm.
pub fn lag_free(prep: &Prepared) -> Vec<[f64; 3]> {
    let keep = vec![true; prep.n];
    let al = axis_lags(prep, &keep);
    (0..prep.n)
        .map(|i| {
            let mut r = prep.r[i];
            for j in 0..prep.dof {
                let jj = prep.jj(i, j);
                let d = -al.lag[j] * prep.vj(i, j);
                for c in 0..3 {
                    r[c] -= d * jj[c];
                }
            }
            r
        })
        .collect()
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

/// The axes that share a common lag: the median of the apparent lags
/// `(lag, sd)` of the `informative` axes is the common value, and an axis
/// shares it when its lag is within 4 standard deviations plus
/// `tolerance`. `None` unless at least two axes, and more than half of the
/// informative ones, share it.
pub fn shared_axes(
    lags: &[(f64, f64)],
    informative: &[usize],
    tolerance: Tolerance,
) -> Option<Vec<usize>> {
    let mut ls: Vec<f64> = informative.iter().map(|&j| lags[j].0).collect();
    if ls.len() < 2 {
        return None;
    }
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
                <= 4.0 * lags[j].1 + tolerance.relative * median.abs() + tolerance.absolute_s
        })
        .collect();
    (set.len() >= 2 && 2 * set.len() > informative.len()).then_some(set)
}

/// [`shared_axes`] where fewer than two axes determine their own lag:
/// the other moving axes taken together. Axes that move together (X and
/// Z following a tilting B along a lens profile) leave each one's lag
/// undetermined, while their common lag is known as well as any single
/// axis's would be; such a group is one witness of a common delay, beside
/// each axis that determines its own. The group shares the delay as a
/// whole or not at all.
fn shared_with_rest(
    al: &AxisLags,
    sigma: f64,
    informative: &[usize],
    tolerance: Tolerance,
) -> Option<Vec<usize>> {
    let dof = al.lag.len();
    let rest: Vec<usize> = (0..dof)
        .filter(|&j| al.g[(j, j)] > 0.0 && !informative.contains(&j))
        .collect();
    if rest.len() < 2 {
        return None;
    }
    let mut groups: Vec<Vec<usize>> = informative.iter().map(|&j| vec![j]).collect();
    groups.push(rest.clone());
    let (g, h) = grouped(&al.g, &al.h, &groups);
    let inv = pinv_sym(&g);
    let beta = &inv * &h;
    let units: Vec<(f64, f64)> = (0..groups.len())
        .map(|u| (beta[u], inv[(u, u)].max(0.0).sqrt() * sigma))
        .collect();
    let determined: Vec<usize> = (0..groups.len())
        .filter(|&u| units[u].1 < INFORMATIVE_SD_S)
        .collect();
    let set = shared_axes(&units, &determined, tolerance)?;
    Some(
        set.iter()
            .flat_map(|&u| groups[u].iter().copied())
            .collect(),
    )
}

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

/// One offset step of a refinement round `round` (0-based) of an
/// alignment: the common lag of the axes `shared` ([`STRICT`]), which in
/// round 1, once roughly aligned, are chosen again, strictly (an axis
/// that lags beyond the others keeps that as its own servo lag). Used by
/// the offset's refinement and by the rate's, which refine alike.
pub fn refine_step(
    prep: &Prepared,
    keep: &[bool],
    sigma: f64,
    round: usize,
    shared: &mut Vec<usize>,
) -> Option<OffsetEstimate> {
    if round == 1
        && let Some(strict) = clock_offset(prep, keep, sigma, 0.0, None, STRICT)
    {
        *shared = strict.shared;
    }
    clock_offset(prep, keep, sigma, 0.0, Some(shared), STRICT)
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
            if informative.len() >= 2 {
                shared_axes(&lags, &informative, tolerance)?
            } else {
                shared_with_rest(&al, sigma, &informative, tolerance)?
            }
        }
    };
    // Reduced fit: one common lag for the set, an own lag for every other
    // axis.
    let mut groups = vec![set.clone()];
    groups.extend((0..dof).filter(|j| !set.contains(j)).map(|j| vec![j]));
    let (g, h) = grouped(&al.g, &al.h, &groups);
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

/// A clock that runs fast or slow, seen in a residual.
#[derive(Debug, Clone, PartialEq)]
pub struct RateEstimate {
    /// How much faster the recording's clock runs, s per s: the delay
    /// grows by this much per second of recording.
    pub rate: f64,
    /// Its standard deviation.
    pub sd: f64,
    /// The time the rate is taken about (the mean time of the samples
    /// used), s.
    pub t_ref: f64,
    /// The axes that share it (chain indices).
    pub shared: Vec<usize>,
    /// Decrease of χ² when the common rate enters (each axis's own lag
    /// already in).
    pub delta_chi2: f64,
    /// Decrease of χ² by the whole timing model: the common rate, every
    /// axis's own lag, the own rates of the others.
    pub timing_chi2: f64,
}

/// An axis informs the clock rate when its own rate is known to this
/// (s per s, 100 ppm).
const INFORMATIVE_RATE: f64 = 1e-4;

/// The clock rate of a residual: a delay that grows with time alike on
/// every moving axis, `r ≈ −Σⱼ (Lⱼ + ρ·(t − t̄)) · Jⱼ · q̇ⱼ`. Each axis's own
/// lag and rate are fitted, the median rate of the axes that determine
/// theirs to 100 ppm is the common one, and the axes within 4 standard
/// deviations plus `tolerance` share it (at least two, and more than half
/// of the informative ones). The common rate is then fitted with every
/// axis's own lag, and an own rate for the axes that do not share it (a
/// servo lag that starts part-way grows on one axis only). `shared`
/// fixes the set (for the refinement). `None` unless the common rate
/// lowers χ² by more than `min_delta_chi2`.
pub fn clock_rate(
    prep: &Prepared,
    keep: &[bool],
    sigma: f64,
    min_delta_chi2: f64,
    shared: Option<&[usize]>,
    tolerance: Tolerance,
) -> Option<RateEstimate> {
    let dof = prep.dof;
    let (mut tw, mut w) = (0.0, 0.0);
    for i in 0..prep.n {
        if keep[i] {
            tw += prep.t[i];
            w += 1.0;
        }
    }
    if w < 20.0 {
        return None;
    }
    let t_ref = tw / w;
    let (g, h) = timing_normal(prep, keep, Some(t_ref));
    let set: Vec<usize> = match shared {
        Some(s) => s.to_vec(),
        None => {
            let inv = pinv_sym(&g);
            let beta = &inv * &h;
            let rates: Vec<(f64, f64)> = (0..dof)
                .map(|j| {
                    let m = dof + j;
                    (beta[m], inv[(m, m)].max(0.0).sqrt() * sigma)
                })
                .collect();
            let informative: Vec<usize> = (0..dof)
                .filter(|&j| g[(dof + j, dof + j)] > 0.0 && rates[j].1 < INFORMATIVE_RATE)
                .collect();
            shared_axes(&rates, &informative, tolerance)?
        }
    };
    // Reduced fit: every axis's own lag, the common rate, an own rate for
    // the others.
    let mut groups: Vec<Vec<usize>> = (0..dof).map(|j| vec![j]).collect();
    groups.push(set.iter().map(|&j| dof + j).collect());
    groups.extend((0..dof).filter(|j| !set.contains(j)).map(|j| vec![dof + j]));
    let (gr, hr) = grouped(&g, &h, &groups);
    let inv = pinv_sym(&gr);
    let beta = &inv * &hr;
    let rate = beta[dof];
    let sd = inv[(dof, dof)].max(0.0).sqrt() * sigma;
    let delta_chi2 = if sd > 0.0 { (rate / sd).powi(2) } else { 0.0 };
    if shared.is_none() && delta_chi2 < min_delta_chi2 {
        return None;
    }
    Some(RateEstimate {
        rate,
        sd,
        t_ref,
        shared: set,
        delta_chi2,
        timing_chi2: hr.dot(&beta) / (sigma * sigma),
    })
}
