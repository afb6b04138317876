//! The searches of one family's non-linear parameter: the onset profiled
//! over every block start, a time constant on a logarithmic grid refined by
//! golden-section search, and the period of a cyclic error or a vibration
//! on a frequency grid; each candidate scored by its penalised fit.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::*;
use rayon::prelude::*;

/// The best candidate of one family.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The term (with its best non-linear parameter and onset).
    pub term: Term,
    /// Reduction of the residual sum of squares, mm².
    pub delta_rss: f64,
    /// BIC decrease: Δχ² minus the penalty (higher is better).
    pub score: f64,
    /// Penalty in χ² units (parameters and searches).
    pub penalty: f64,
}

/// Settings of the search.
#[derive(Debug, Clone, Copy)]
pub struct SearchCtx {
    /// Noise floor σ, mm.
    pub sigma: f64,
    /// ln(number of residual rows): the BIC price of one parameter.
    pub ln_n: f64,
    /// Smallest number of samples after an onset.
    pub min_after: usize,
}

impl SearchCtx {
    fn onset_penalty(&self, n_onsets: usize) -> f64 {
        self.ln_n + 2.0 * (n_onsets.max(1) as f64).ln()
    }
}

/// Picks the onset: the start of the recording unless a later onset
/// improves the fit by more than the onset penalty. Returns
/// `(onset index, ΔRSS, extra penalty)`.
pub(super) fn choose_onset(profile: &[f64], ctx: &SearchCtx, n_onsets: usize) -> (usize, f64, f64) {
    let s2 = ctx.sigma * ctx.sigma;
    let d0 = profile.first().copied().unwrap_or(0.0);
    let (mut best, mut bd) = (0usize, d0);
    for (k, &d) in profile.iter().enumerate() {
        if d > bd {
            best = k;
            bd = d;
        }
    }
    let pen = ctx.onset_penalty(n_onsets);
    if best != 0 && (bd - d0) / s2 > pen {
        (best, bd, pen)
    } else {
        (0, d0, 0.0)
    }
}

/// Range of the thermal time constant searched, as multiples of the
/// recording's span.
pub const TAU_RANGE: (f64, f64) = (1.0 / 30.0, 30.0);

/// Coarse grid of the time-constant search: this many values log-spaced
/// over [`TAU_RANGE`] (spacing a factor 1.69). It also sets the look-
/// elsewhere penalty `2 ln TAU_GRID` of a searched τ.
pub const TAU_GRID: usize = 14;

/// Fine grid: the bracket of ±1 coarse step around the best coarse value is
/// scanned at `2·TAU_FINE + 1` values (spacing a factor 1.09) before the
/// golden-section refinement, so that a narrow maximum of the profile
/// (the onset switching between blocks makes it piecewise smooth) is not
/// missed.
const TAU_FINE: usize = 6;

/// Maximises `f(ln τ).0` over `[lo, hi]`: coarse grid, fine grid around the
/// best, golden-section search within ±1 fine step. Returns the argument
/// and the value at the maximum found.
pub(super) fn maximise_ln<T: Copy>(
    f: &dyn Fn(f64) -> (f64, T),
    lo: f64,
    hi: f64,
) -> (f64, (f64, T)) {
    let coarse = (hi - lo) / (TAU_GRID - 1) as f64;
    let mut best = (lo, f(lo));
    let consider = |x: f64, best: &mut (f64, (f64, T))| {
        let v = f(x);
        if v.0 > best.1.0 {
            *best = (x, v);
        }
    };
    for g in 1..TAU_GRID {
        consider(lo + coarse * g as f64, &mut best);
    }
    let centre = best.0;
    let fine = coarse / TAU_FINE as f64;
    for g in 1..=TAU_FINE {
        for x in [centre - fine * g as f64, centre + fine * g as f64] {
            if x > lo && x < hi {
                consider(x, &mut best);
            }
        }
    }
    let (a, b) = ((best.0 - fine).max(lo), (best.0 + fine).min(hi));
    let (x, _) = crate::numeric::golden_section_max(&mut |x| f(x).0, a, b, 10);
    consider(x, &mut best);
    best
}

/// Searches one family: non-linear parameter (grid + golden section) and
/// onset (profile over all block starts). `None` if the family has no
/// support in the data (joint never moves, …).
pub fn search_family(
    prep: &Prepared,
    sel: &Selected,
    fam: Family,
    ctx: &SearchCtx,
) -> Option<Candidate> {
    let s2 = ctx.sigma * ctx.sigma;
    let onsets = &prep.onsets;
    let k_lin = fam.linear_params() as f64;
    let n_on = onsets.len();
    match fam {
        Family::ThermalDrift(_) => {
            let t0 = prep.t[0];
            let span = (prep.t[prep.n - 1] - t0).max(1e-9);
            let (lo, hi) = (span * TAU_RANGE.0, span * TAU_RANGE.1);
            // The joint profile over (onset, τ): for each τ every onset is
            // profiled by one suffix-sum pass; the best onset is kept.
            let eval = |ln_tau: f64| -> (f64, (usize, f64, f64)) {
                let tau = ln_tau.exp();
                let base = base_columns(prep, fam, tau);
                let gf = |s: usize| thermal_gamma(prep, tau, prep.t[s]).to_vec();
                let prof = scan(prep, sel, &base, onsets, Some(&gf), ctx.min_after);
                let (k, d, pen) = choose_onset(&prof, ctx, n_on);
                (d / s2 - pen, (k, d, pen))
            };
            let (x, (_, (k, d, pen))) = maximise_ln(&eval, lo.ln(), hi.ln());
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (TAU_GRID as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: x.exp(),
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        Family::Cyclic(j) => {
            let (mut qmin, mut qmax) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut steps: Vec<f64> = Vec::with_capacity(prep.n);
            for i in 0..prep.n {
                let q = prep.qj(i, j);
                qmin = qmin.min(q);
                qmax = qmax.max(q);
                if i > 0 {
                    let d = (q - prep.qj(i - 1, j)).abs();
                    if d > 1e-9 {
                        steps.push(d);
                    }
                }
            }
            let range = qmax - qmin;
            if range.partial_cmp(&1e-6) != Some(std::cmp::Ordering::Greater) || steps.is_empty() {
                return None;
            }
            let mid = steps.len() / 2;
            steps.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            let p_min = (range / 50.0).max(4.0 * steps[mid]);
            let p_max = range / 1.5;
            if p_min >= p_max {
                return None;
            }
            let (f_lo, f_hi) = (1.0 / p_max, 1.0 / p_min);
            let df = 1.0 / (2.5 * range);
            let x: Vec<f64> = (0..prep.n).map(|i| prep.qj(i, j)).collect();
            let (f, d, k, pen, grid) =
                periodic_search(prep, sel, ctx, fam, j, &x, None, (f_lo, f_hi), df, 250)?;
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (grid as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: 1.0 / f,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        Family::Vibration(j) => {
            let span = prep.t[prep.n - 1] - prep.t[0];
            let mut dts: Vec<f64> = prep.t.windows(2).map(|w| w[1] - w[0]).collect();
            if span <= 0.0 || dts.is_empty() {
                return None;
            }
            let mid = dts.len() / 2;
            dts.select_nth_unstable_by(mid, f64::total_cmp);
            // From ten cycles per recording and 0.2 Hz (slower is a drift
            // or a mismatch confined to part of the recording, not a
            // structure's oscillation) to just below the Nyquist frequency
            // of the median interval.
            let (f_lo, f_hi) = ((10.0 / span).max(MIN_VIBRATION_HZ), 0.49 / dts[mid]);
            if f_lo >= f_hi {
                return None;
            }
            let df = 1.0 / (2.5 * span);
            let clock = super::spectrum::regular_clock(&prep.t, dts[mid]);
            let (f, d, k, pen, grid) = periodic_search(
                prep,
                sel,
                ctx,
                fam,
                j,
                &prep.t,
                clock.as_ref(),
                (f_lo, f_hi),
                df,
                VIBRATION_GRID,
            )?;
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (grid as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: f,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        _ => {
            if let Family::RotaryCenterOffset(j) = fam
                && prep.rco[j].is_none()
            {
                return None;
            }
            let base = base_columns(prep, fam, 0.0);
            let norm: f64 = base.data.iter().map(|x| x * x).sum();
            if norm.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            if fam == Family::RegistrationStep {
                // A step of the registration part-way, at any sample (a
                // beam break does not wait for a block to end) with at
                // least `min_after` samples before and after it, paying
                // for the onsets searched.
                let steps: Vec<usize> =
                    (ctx.min_after..prep.n.saturating_sub(ctx.min_after)).collect();
                let prof = scan(prep, sel, &base, &steps, None, ctx.min_after);
                let (k, d) = prof
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.total_cmp(b.1))
                    .map(|(k, d)| (k, *d))?;
                let penalty = k_lin * ctx.ln_n + ctx.onset_penalty(steps.len());
                return Some(Candidate {
                    term: Term {
                        family: fam,
                        nl: 0.0,
                        onset: steps[k],
                    },
                    delta_rss: d,
                    score: d / s2 - penalty,
                    penalty,
                });
            }
            let prof = scan(prep, sel, &base, onsets, None, ctx.min_after);
            let (k, d, pen) = if fam.kind().is_measurement() {
                // The measuring system's registration holds for the whole
                // recording: from part-way it would take up the mean of
                // an effect that starts moving there (a backlash).
                (0, prof.first().copied().unwrap_or(0.0), 0.0)
            } else {
                choose_onset(&prof, ctx, n_on)
            };
            let penalty = k_lin * ctx.ln_n + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: 0.0,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
    }
}

/// Lowest frequency searched for a vibration, Hz.
pub const MIN_VIBRATION_HZ: f64 = 0.2;

/// Grid size cap of the vibration frequency search where the samples are
/// not on a regular clock (on one, the scan by FFT takes every frequency).
pub const VIBRATION_GRID: usize = 20_000;

/// The frequency search of a periodic family (cyclic in a position,
/// vibration in time): sinusoid columns `J_j·[sin 2πf·x, cos 2πf·x]` scored
/// on a uniform frequency grid over `band` with spacing `df` (at most
/// `max_grid` values; where `x` lies on the regular `clock`, every
/// frequency of the grid, scored by FFT), refined by golden section, then
/// the onset profiled. Returns (frequency, ΔRSS, onset index, onset
/// penalty, grid size).
#[allow(clippy::too_many_arguments)]
pub(super) fn periodic_search(
    prep: &Prepared,
    sel: &Selected,
    ctx: &SearchCtx,
    fam: Family,
    j: usize,
    x: &[f64],
    clock: Option<&super::spectrum::Clock>,
    band: (f64, f64),
    df: f64,
    max_grid: usize,
) -> Option<(f64, f64, usize, f64, usize)> {
    let (f_lo, f_hi) = band;
    let onsets = &prep.onsets;
    // Per-sample projections, so that a frequency costs one pass:
    // columns J_j·[sin θ, cos θ], θ = 2π f x (x a position or time).
    let ks = sel.cols.k;
    let mut w = Vec::with_capacity(prep.n);
    let mut pr = Vec::with_capacity(prep.n);
    let mut ps = vec![0.0; prep.n * ks];
    for i in 0..prep.n {
        let jj = prep.jj(i, j);
        w.push(jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]);
        pr.push(jj[0] * prep.r[i][0] + jj[1] * prep.r[i][1] + jj[2] * prep.r[i][2]);
        for a in 0..3 {
            if ks > 0 {
                let row = sel.cols.row(3 * i + a);
                for z in 0..ks {
                    ps[i * ks + z] += jj[a] * row[z];
                }
            }
        }
    }
    // Score of one frequency from the per-sample (sin θ, cos θ); `cs`: a
    // buffer of 2·ks values.
    let score = |trig: &[(f64, f64)], cs: &mut [f64]| -> f64 {
        let (mut ss, mut sc, mut cc, mut rs, mut rc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        cs.iter_mut().for_each(|x| *x = 0.0);
        for (i, &(sn, co)) in trig.iter().enumerate() {
            ss += w[i] * sn * sn;
            sc += w[i] * sn * co;
            cc += w[i] * co * co;
            rs += pr[i] * sn;
            rc += pr[i] * co;
            for z in 0..ks {
                let v = ps[i * ks + z];
                cs[z] += sn * v;
                cs[ks + z] += co * v;
            }
        }
        let mut a = [ss, sc, sc, cc];
        let mut c = [rs, rc];
        if ks > 0 {
            for u in 0..2 {
                let mut mrow = vec![0.0; ks];
                for (zz, m) in mrow.iter_mut().enumerate() {
                    for z in 0..ks {
                        *m += cs[u * ks + z] * sel.ginv[(z, zz)];
                    }
                }
                for z in 0..ks {
                    c[u] -= mrow[z] * sel.h[z];
                    for v in 0..2 {
                        a[u * 2 + v] -= mrow[z] * cs[v * ks + z];
                    }
                }
            }
        }
        quad_form_2(&a, &c, [ss, cc])
    };
    let trig_at = |f: f64| -> Vec<(f64, f64)> {
        let omega = std::f64::consts::TAU * f;
        (0..prep.n).map(|i| (omega * x[i]).sin_cos()).collect()
    };
    let scanned = clock.map(|clock| {
        let proj = super::spectrum::Projections {
            w: &w,
            pr: &pr,
            ps: &ps,
            ks,
        };
        super::spectrum::scan(clock, &proj, &sel.ginv, &sel.h, band, df)
    });
    let (mut vals, step) = match scanned {
        Some(v) if v.len() >= 2 => {
            let step = v[1].1 - v[0].1;
            (v, step)
        }
        _ => direct_scan(band, df, max_grid, &score, &trig_at, ks),
    };
    let grid = vals.len();
    vals.sort_by(|a, b| b.0.total_cmp(&a.0));
    let f_best = vals[0].1;
    let mut cs = vec![0.0; 2 * ks];
    let (f, _) = crate::numeric::golden_section_max(
        &mut |f| score(&trig_at(f), &mut cs),
        (f_best - step).max(f_lo),
        (f_best + step).min(f_hi),
        16,
    );
    let nl = match fam {
        Family::Cyclic(_) => 1.0 / f,
        _ => f,
    };
    let base = base_columns(prep, fam, nl);
    let prof = scan(prep, sel, &base, onsets, None, ctx.min_after);
    let (k, d, pen) = choose_onset(&prof, ctx, onsets.len());
    Some((f, d, k, pen, grid))
}

/// The score of one frequency from each sample's `(sin θ, cos θ)`, with a
/// buffer of twice the selected columns.
type ScoreFn<'a> = dyn Fn(&[(f64, f64)], &mut [f64]) -> f64 + Sync + 'a;

/// The direct scan: `(score, frequency)` on a uniform grid over `band`
/// with spacing `df` (at most `max_grid` values), and the spacing used.
fn direct_scan(
    band: (f64, f64),
    df: f64,
    max_grid: usize,
    score: &ScoreFn<'_>,
    trig_at: &(dyn Fn(f64) -> Vec<(f64, f64)> + Sync),
    ks: usize,
) -> (Vec<(f64, f64)>, f64) {
    let (f_lo, f_hi) = band;
    let grid = (((f_hi - f_lo) / df).ceil() as usize).clamp(2, max_grid);
    let step = (f_hi - f_lo) / (grid - 1) as f64;
    // The grid is uniform in frequency: each sample's (sin, cos)
    // advances by a fixed rotation from one grid value to the next,
    // re-seeded exactly every `RESEED` steps against rounding drift; the
    // runs between seeds are independent, and are scored on every core
    // (the same numbers as one after the other).
    const RESEED: usize = 32;
    let rot = trig_at(step);
    let vals: Vec<(f64, f64)> = (0..grid.div_ceil(RESEED))
        .into_par_iter()
        .flat_map_iter(|run| {
            let mut cs = vec![0.0; 2 * ks];
            let mut trig = Vec::new();
            let (first, end) = (run * RESEED, ((run + 1) * RESEED).min(grid));
            (first..end)
                .map(|g| {
                    let f = f_lo + step * g as f64;
                    if g == first {
                        trig = trig_at(f);
                    } else {
                        for (t, r) in trig.iter_mut().zip(&rot) {
                            *t = (t.0 * r.1 + t.1 * r.0, t.1 * r.1 - t.0 * r.0);
                        }
                    }
                    (score(&trig, &mut cs), f)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    (vals, step)
}
