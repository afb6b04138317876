//! Joint-feedback recordings (`formats.md` §2b): each traced axis's command
//! and the position its own encoder or linear scale reported. Joint-level
//! effects are diagnosed on the joint residual `fb − command` directly,
//! without the chain: a clock offset common to the axes, gross outliers,
//! then per axis backlash, servo lag, zero offset and scale, with the same
//! rules as the tool-tip diagnosis (BIC against a noise floor that respects
//! the values' rounding, held-out folds, physical signs). See
//! `docs/diagnose.md`, "Joint-feedback traces".
//!
//! * [`recording`]: the CSV ([`FeedbackRecording`]);
//! * [`simulate`](mod@simulate): simulated traces ([`simulate_feedback`]);
//! * [`report`]: the report ([`FeedbackReport`]).

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

mod clock;
pub mod recording;
pub mod report;
pub mod simulate;

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

pub use recording::{FeedbackRecording, header_line, is_feedback_header};
pub use report::{AxisSummary, FeedbackReport, JointFinding};
pub use simulate::{FeedbackRow, FeedbackSimOptions, FeedbackSimulator, simulate_feedback};

use super::DiagOptions;
use super::fit::pinv_sym;
use super::report::{FlaggedSample, MeasurementFinding, Where};
use super::untidy::{OUTLIER_SIGMAS, departure, monotone_hermite, quantum};
use crate::error::{Error, Location, Result};
use crate::geometric::effects::{DIRECTION_DEAD_BAND, DirectionTracker, Effect, EffectSpec};

/// One axis's data for the fits.
#[derive(Clone)]
struct AxisData {
    t: Vec<f64>,
    q: Vec<f64>,
    v: Vec<f64>,
    dir: Vec<f64>,
    e: Vec<f64>,
    keep: Vec<bool>,
    /// Time since the axis last reversed, s (infinite before its first).
    since: Vec<f64>,
    /// Decay time of the reversal-spike column being tried, s.
    spike_tau: std::cell::Cell<f64>,
}

fn axis_data(t: &[f64], cmd: &[f64], fb: &[f64]) -> AxisData {
    let n = t.len();
    let mut v = vec![0.0; n];
    if n >= 2 {
        // One-sided at the edges of gaps, as for tool-tip recordings.
        let gap = super::prepare::gap_steps(t);
        for i in 0..n {
            let (a, b) = super::prepare::difference_pair(i, t, &gap);
            v[i] = (cmd[b] - cmd[a]) / (t[b] - t[a]);
        }
    }
    let mut tr = DirectionTracker::new(DIRECTION_DEAD_BAND);
    let dir: Vec<f64> = cmd.iter().map(|q| tr.update(*q)).collect();
    let mut since = vec![f64::INFINITY; n];
    let mut last: Option<f64> = None;
    for i in 0..n {
        if i > 0 && dir[i] * dir[i - 1] < 0.0 {
            last = Some(t[i]);
        }
        if let Some(l) = last {
            since[i] = t[i] - l;
        }
    }
    AxisData {
        t: t.to_vec(),
        q: cmd.to_vec(),
        v,
        dir,
        e: fb.iter().zip(cmd).map(|(f, c)| f - c).collect(),
        keep: vec![true; n],
        since,
        spike_tau: std::cell::Cell::new(0.02),
    }
}

/// Robust noise floor of a 1-D residual: MAD of first differences.
fn floor_1d(e: &[f64]) -> f64 {
    let mut d: Vec<f64> = e.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid] / (0.674_489_75 * std::f64::consts::SQRT_2)
}

/// Gross outliers of a 1-D residual `e` of axis `d` (as
/// [`super::untidy::gross_outliers`]). A spike at a reversal of the axis
/// is its following error, machine physics. So is one that the axis's own
/// lag explains where the command changes speed (a short fast move seen by
/// a sample or two at a low sample rate, where the speed between samples
/// is not known): the lag is fitted with the first flags set aside, and a
/// flagged sample whose spike is within twice that lag times the change
/// of the commanded speed around it is not a fault of the trace.
fn outliers_1d(d: &AxisData, e: &[f64], sigma: f64) -> Vec<usize> {
    let first = spikes(d, e, sigma, 0.0);
    if first.is_empty() {
        return first;
    }
    let mut skip = vec![false; e.len()];
    for &p in &first {
        skip[p] = true;
    }
    let fams = [Fam::ServoLag, Fam::Backlash, Fam::ZeroOffset];
    let on_e = AxisData {
        e: e.to_vec(),
        ..d.clone()
    };
    let (beta, _, _) = lsq(&on_e, &fams, &|i| !skip[i]);
    let tau = beta[0].clamp(0.0, MAX_FOLLOWING_TAU_S);
    let allowed = spikes(d, e, sigma, 4.0 * tau);
    // A fault where the command changes speed hides in the lag's own
    // departure there: looked for again on what the fit leaves, beyond
    // what the fit itself may miss there (the speed between samples is
    // not known: up to about the lag times the change of speed).
    let left: Vec<f64> = (0..e.len())
        .map(|i| {
            e[i] - fams
                .iter()
                .zip(&beta)
                .map(|(f, b)| b * column(&on_e, *f, i))
                .sum::<f64>()
        })
        .collect();
    let mut both: Vec<usize> = spikes(d, &left, sigma, 1.5 * tau)
        .into_iter()
        .filter(|&i| skip[i])
        .chain(allowed)
        .collect();
    both.sort_unstable();
    both.dedup();
    both
}

/// Samples of `e` that depart from their neighbours by more than
/// [`OUTLIER_SIGMAS`] noise floors, beyond `allow_s` times the change of
/// the commanded speed around them; never the first or the last sample.
/// Searched for in passes, each without the samples flagged before
/// ([`super::untidy::flag_in_passes`]). When more flagged samples sit within two samples of a
/// reversal of the axis than chance would put there
/// ([`super::untidy::beyond_chance_at_reversals`]), those are its following error, machine physics,
/// and stay in; otherwise faults scattered at random are flagged there
/// too. None when they are not scattered as faults are
/// ([`super::untidy::are_faults`]): that is a signal.
fn spikes(d: &AxisData, e: &[f64], sigma: f64, allow_s: f64) -> Vec<usize> {
    let n = e.len();
    if n < 7 {
        return Vec::new();
    }
    // The first and last samples are judged from one side only, and a
    // change of speed just outside the trace does not show: not flagged.
    let mut out = super::untidy::flag_in_passes(n, |series| {
        let column: Vec<f64> = series.iter().map(|&i| e[i]).collect();
        series
            .iter()
            .enumerate()
            .filter(|&(k, &i)| {
                if i == 0 || i == n - 1 {
                    return false;
                }
                let dep = departure(&column, k).abs();
                dep > OUTLIER_SIGMAS * sigma.max(1e-12)
                    && (allow_s == 0.0 || dep > allow_s * speed_change(d, i))
            })
            .map(|(_, &i)| i)
            .collect()
    });
    let dir = &d.dir;
    let reversal =
        |i: usize| (i.saturating_sub(2)..(i + 2).min(n - 1)).any(|k| dir[k] * dir[k + 1] < 0.0);
    if super::untidy::beyond_chance_at_reversals(&out, n, reversal) {
        out.retain(|&i| !reversal(i));
    }
    if super::untidy::are_faults(&out, n) {
        out
    } else {
        Vec::new()
    }
}

/// The slowest servo whose following error a trace may show (time
/// constant, s).
const MAX_FOLLOWING_TAU_S: f64 = 0.05;

/// The largest change of the commanded speed between consecutive sample
/// intervals around sample `i` (mm/s or deg/s).
fn speed_change(d: &AxisData, i: usize) -> f64 {
    let n = d.t.len();
    let speed = |k: usize| (d.q[k + 1] - d.q[k]) / (d.t[k + 1] - d.t[k]).max(1e-12);
    (i.saturating_sub(2)..(i + 2).min(n.saturating_sub(2)))
        .map(|k| (speed(k + 1) - speed(k)).abs())
        .fold(0.0, f64::max)
}

/// A joint-level effect family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fam {
    Backlash,
    ServoLag,
    /// A following error after each reversal, decaying: Δq = −p·d·e^(−s/τ),
    /// d the new direction, s the time since the reversal.
    ReversalSpike,
    ZeroOffset,
    Scale,
}

const FAMS: [Fam; 5] = [
    Fam::Backlash,
    Fam::ServoLag,
    Fam::ReversalSpike,
    Fam::ZeroOffset,
    Fam::Scale,
];

/// Decay times tried for a reversal spike, s.
const SPIKE_TAUS: [f64; 7] = [0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2];

fn column(d: &AxisData, f: Fam, i: usize) -> f64 {
    match f {
        Fam::Backlash => -0.5 * d.dir[i],
        Fam::ServoLag => -d.v[i],
        Fam::ReversalSpike => -d.dir[i] * (-d.since[i] / d.spike_tau.get()).exp(),
        Fam::ZeroOffset => 1.0,
        Fam::Scale => 1e-6 * d.q[i],
    }
}

/// Least squares of `d.e` on the families' columns over the samples
/// `train` allows: (coefficients, normal matrix pseudo-inverse, RSS).
fn lsq(d: &AxisData, fams: &[Fam], train: &dyn Fn(usize) -> bool) -> (Vec<f64>, DMatrix<f64>, f64) {
    let k = fams.len();
    let mut g = DMatrix::zeros(k, k);
    let mut h = DVector::zeros(k);
    let mut ee = 0.0;
    for i in 0..d.t.len() {
        if !d.keep[i] || !train(i) {
            continue;
        }
        ee += d.e[i] * d.e[i];
        for a in 0..k {
            let ca = column(d, fams[a], i);
            h[a] += ca * d.e[i];
            for b in 0..k {
                g[(a, b)] += ca * column(d, fams[b], i);
            }
        }
    }
    let inv = pinv_sym(&g);
    let beta = &inv * &h;
    let rss = ee - beta.dot(&h);
    (beta.iter().copied().collect(), inv, rss.max(0.0))
}

/// Held-out RSS over 5 contiguous time folds.
fn holdout(d: &AxisData, fams: &[Fam]) -> f64 {
    let n = d.t.len();
    let fold = |i: usize| (i * 5 / n.max(1)).min(4);
    let mut rss = 0.0;
    for f in 0..5 {
        let (beta, _, _) = lsq(d, fams, &|i| fold(i) != f);
        for i in 0..n {
            if fold(i) == f && d.keep[i] {
                let pred: f64 = fams
                    .iter()
                    .zip(&beta)
                    .map(|(fa, b)| column(d, *fa, i) * b)
                    .sum();
                rss += (d.e[i] - pred).powi(2);
            }
        }
    }
    rss
}

/// A fitted family as the report names it: effect name, parameters with
/// units, and the catalogue effect where there is one.
fn describe(
    f: Fam,
    d: &AxisData,
    axis: &str,
    b: f64,
    rotary: bool,
) -> (String, Vec<(String, f64)>, Option<Effect>) {
    if f == Fam::ReversalSpike {
        let u = if rotary { "deg" } else { "mm" };
        return (
            "reversal_spike".into(),
            vec![
                (format!("peak_{u}"), b),
                ("tau_s".into(), d.spike_tau.get()),
            ],
            None,
        );
    }
    let e = effect_of(f, axis, b);
    (e.kind().name().to_string(), e.parameters(rotary), Some(e))
}

fn effect_of(f: Fam, axis: &str, b: f64) -> Effect {
    let axis = axis.to_string();
    match f {
        Fam::ReversalSpike => Effect::ZeroOffset { axis, value: b },
        Fam::Backlash => Effect::Backlash { axis, value: b },
        Fam::ServoLag => Effect::ServoLag { axis, tau_s: b },
        Fam::ZeroOffset => Effect::ZeroOffset { axis, value: b },
        Fam::Scale => Effect::Scale { axis, ppm: b },
    }
}

/// Why a fitted joint-level coefficient is not physics.
fn implausible(f: Fam, b: f64, d: &AxisData) -> Option<String> {
    match f {
        Fam::Backlash if b <= 0.0 => {
            Some("a negative backlash: the axis would lead its command after a reversal".into())
        }
        Fam::Backlash if !d.dir.windows(2).any(|w| w[0] * w[1] < 0.0) => {
            Some("the axis never reverses, so a backlash cannot show".into())
        }
        Fam::ReversalSpike if b <= 0.0 => {
            Some("a spike that leads the motion after a reversal: not a following error".into())
        }
        Fam::ServoLag if b <= 0.0 => {
            Some("a negative lag: the axis would move before its command".into())
        }
        Fam::ServoLag if b > super::plausible::MAX_LAG_S => {
            Some("a lag beyond any servo loop".into())
        }
        Fam::Scale if b.abs() > super::plausible::MAX_SCALE_PPM => {
            Some("a scale error above 1 %".into())
        }
        Fam::ZeroOffset if b.abs() > super::plausible::MAX_OFFSET => {
            Some("a zero offset beyond a reference error".into())
        }
        _ => None,
    }
}

/// Diagnoses a joint-feedback recording.
pub fn diagnose_feedback(rec: &FeedbackRecording, opts: &DiagOptions) -> Result<FeedbackReport> {
    let n = rec.len();
    if n < 20 {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!("the recording has {n} samples; a diagnosis needs at least 20"),
        ));
    }
    let n_ax = rec.axes.len();
    let ln_n = (n as f64).ln();
    let mut data: Vec<AxisData> = (0..n_ax)
        .map(|k| axis_data(&rec.t, &rec.cmd[k], &rec.fb[k]))
        .collect();
    // Noise floors: the robust estimate, never below the feedback's
    // rounding, plus the command's rounding.
    let res_fb: Vec<Option<f64>> = rec.fb.iter().map(|v| quantum(v)).collect();
    let res_cmd: Vec<Option<f64>> = rec.cmd.iter().map(|v| quantum(v)).collect();
    let sigma: Vec<f64> = (0..n_ax)
        .map(|k| {
            if let Some(f) = opts.noise_floor_mm.filter(|f| *f > 0.0) {
                return f;
            }
            let est = floor_1d(&data[k].e);
            let qf = res_fb[k].map_or(0.0, |q| q / 12f64.sqrt());
            let qc = res_cmd[k].map_or(0.0, |q| q / 12f64.sqrt());
            est.max(qf).hypot(qc).max(1e-9)
        })
        .collect();
    // Outliers of the raw residual, set aside for the clock offset only
    // (a large offset makes the raw residual bend at every change of
    // acceleration, which a running median does not follow).
    let mut bad = vec![false; n];
    for k in 0..n_ax {
        for i in outliers_1d(&data[k], &data[k].e, sigma[k]) {
            bad[i] = true;
        }
    }
    // The trace's clock: a delay common to the axes, maybe growing.
    let use_sample: Vec<bool> = bad.iter().map(|b| !b).collect();
    let timing: Vec<clock::AxisTiming<'_>> = (0..n_ax)
        .map(|k| clock::AxisTiming {
            e: &data[k].e,
            v: &data[k].v,
            sigma: sigma[k],
        })
        .collect();
    let mut offset = clock::trace_clock(&timing, &rec.t, &use_sample, opts.bic_margin, false);
    let mut dropped_ends = 0usize;
    let mut doubtful = 0usize;
    // Index in the recording of each sample of `data`.
    let mut index: Vec<usize> = (0..n).collect();
    if let Some(tc) = offset.as_mut() {
        let mut aligned = align_to_clock(rec, tc, &sigma);
        // The delay is estimated from its linear term (−v·d), which the
        // command's acceleration biases where the delay is long (about 1 %
        // of 20 ms at 10 ms sampling): what the axes still share after the
        // alignment is the rest of the trace's delay, not servo lags. It is
        // added until it stops changing.
        for _ in 0..3 {
            let t_al: Vec<f64> = aligned.index.iter().map(|&i| rec.t[i]).collect();
            let mut keep = aligned.data[0].keep.clone();
            for (k, d) in aligned.data.iter().enumerate() {
                for i in outliers_1d(d, &d.e, sigma[k]) {
                    keep[i] = false;
                }
            }
            let timing: Vec<clock::AxisTiming<'_>> = (0..n_ax)
                .map(|k| clock::AxisTiming {
                    e: &aligned.data[k].e,
                    v: &aligned.data[k].v,
                    sigma: sigma[k],
                })
                .collect();
            let Some(rest) = clock::trace_clock(&timing, &t_al, &keep, opts.bic_margin, true)
            else {
                break;
            };
            let more = rest.clock.shift(tc.clock.t_ref);
            tc.clock.offset_s += more;
            tc.clock.rate += rest.clock.rate;
            tc.offset_sd = rest.offset_sd;
            aligned = align_to_clock(rec, tc, &sigma);
            if more.abs() <= rest.offset_sd {
                break;
            }
        }
        data = aligned.data;
        index = aligned.index;
        dropped_ends = aligned.dropped_ends;
        doubtful = aligned.doubtful;
    }
    // Outliers of the (aligned) residual: excluded from every fit.
    let mut flagged: Vec<(usize, usize, f64)> = Vec::new();
    for k in 0..n_ax {
        for p in outliers_1d(&data[k], &data[k].e, sigma[k]) {
            if data[k].keep[p] {
                flagged.push((index[p], k, data[k].e[p]));
            }
        }
    }
    flagged.sort_by_key(|f| f.0);
    let out_set: std::collections::BTreeSet<usize> = flagged.iter().map(|f| f.0).collect();
    for k in 0..n_ax {
        for p in 0..index.len() {
            if out_set.contains(&index[p]) {
                data[k].keep[p] = false;
            }
        }
    }
    let used = data
        .first()
        .map_or(0, |d| d.keep.iter().filter(|k| **k).count());
    // What the rounding of the commands (and of the feedback, where it
    // is coarser than half the noise) and the alignment leave as structure.
    let unresolved: Vec<f64> = (0..n_ax)
        .map(|k| {
            let qc = res_cmd[k].map_or(0.0, |q| q / 12f64.sqrt());
            let qf = res_fb[k].map_or(0.0, |q| q / 12f64.sqrt());
            let qf = if qf > 0.5 * floor_1d(&data[k].e) {
                qf
            } else {
                0.0
            };
            // Samples kept after an alignment may be off by up to half the
            // noise floor; what that leaves is up to about a fifth of it.
            let al = if offset.is_some() {
                0.2 * sigma[k]
            } else {
                0.0
            };
            qc.hypot(qf).max(al)
        })
        .collect();
    // Per axis: forward selection.
    let mut findings = Vec::new();
    let mut rejected = Vec::new();
    let mut axes = Vec::new();
    // Per axis: the standard deviation of χ² per sample when the residual
    // is noise (for the verdict).
    let mut chi_sds = Vec::new();
    let (mut lin_before, mut lin_after, mut lin_hb, mut lin_ha, mut lin_floor, mut lin_n) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0usize);
    for k in 0..n_ax {
        let d = &data[k];
        let s2 = sigma[k] * sigma[k];
        let m = d.keep.iter().filter(|x| **x).count().max(1) as f64;
        let mut terms: Vec<Fam> = Vec::new();
        let (_, _, rss0) = lsq(d, &[], &|_| true);
        let mut rss_prev = rss0;
        let hold0 = holdout(d, &[]);
        let mut hold_prev = hold0;
        while terms.len() < opts.max_effects {
            let mut best: Option<(Fam, f64)> = None;
            for f in FAMS {
                if terms.contains(&f) {
                    continue;
                }
                let mut trial = terms.clone();
                trial.push(f);
                let mut search = 0.0;
                if f == Fam::ReversalSpike {
                    // Its decay time: the best of a few, paid in the score.
                    let best_tau = SPIKE_TAUS
                        .iter()
                        .map(|&tau| {
                            d.spike_tau.set(tau);
                            (tau, lsq(d, &trial, &|_| true).2)
                        })
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .map_or(0.02, |x| x.0);
                    d.spike_tau.set(best_tau);
                    search = 2.0 * (SPIKE_TAUS.len() as f64).ln();
                }
                let (beta, _, rss) = lsq(d, &trial, &|_| true);
                let score = (rss_prev - rss) / s2 - ln_n - search;
                if score <= opts.bic_margin {
                    continue;
                }
                if let Some(reason) = implausible(f, beta[trial.len() - 1], d) {
                    let (name, params, _) =
                        describe(f, d, &rec.axes[k], beta[trial.len() - 1], rec.rotary[k]);
                    rejected.push(super::report::Rejected {
                        effect: name,
                        axis: Some(rec.axes[k].clone()),
                        parameters: params.into_iter().collect(),
                        reason,
                    });
                    continue;
                }
                // An effect smaller than what the rounding of the command
                // (or, after a clock offset, the alignment) leaves is not
                // resolved.
                let b = beta[trial.len() - 1];
                let size = ((0..d.t.len())
                    .filter(|&i| d.keep[i])
                    .map(|i| (column(d, f, i) * b).powi(2))
                    .sum::<f64>()
                    / m)
                    .sqrt();
                if size < unresolved[k] {
                    let (name, params, _) = describe(f, d, &rec.axes[k], b, rec.rotary[k]);
                    rejected.push(super::report::Rejected {
                        effect: name,
                        axis: Some(rec.axes[k].clone()),
                        parameters: params.into_iter().collect(),
                        reason: format!(
                            "it moves the axis by {size:.3e} RMS, less than the {:.3e} the rounding of the values or the clock alignment leaves",
                            unresolved[k]
                        ),
                    });
                    continue;
                }
                if best.is_none_or(|(_, s)| score > s) {
                    best = Some((f, score));
                }
            }
            let Some((f, _)) = best else { break };
            let mut trial = terms.clone();
            trial.push(f);
            let hold = holdout(d, &trial);
            if hold_prev - hold < ln_n * s2 {
                break;
            }
            terms.push(f);
            rss_prev = lsq(d, &terms, &|_| true).2;
            hold_prev = hold;
        }
        let (beta, inv, rss) = lsq(d, &terms, &|_| true);
        let (t0, t1) = (d.t[0], d.t[d.t.len() - 1]);
        let blocks = [
            rec.block.first().copied().flatten(),
            rec.block.last().copied().flatten(),
        ];
        for (p, f) in terms.iter().enumerate() {
            let (name, params, effect) = describe(*f, d, &rec.axes[k], beta[p], rec.rotary[k]);
            let sd = inv[(p, p)].max(0.0).sqrt() * sigma[k];
            let contrib: f64 = (0..d.t.len())
                .filter(|&i| d.keep[i])
                .map(|i| (column(d, *f, i) * beta[p]).powi(2))
                .sum::<f64>()
                / m;
            let unit = if rec.rotary[k] { "deg" } else { "mm" };
            let condition = match &effect {
                Some(e) => super::report::condition_text(e, rec.rotary[k]),
                None => format!(
                    "after each reversal of {}: a following error that decays with τ = {:.0} ms",
                    rec.axes[k],
                    d.spike_tau.get() * 1e3
                ),
            };
            findings.push(JointFinding {
                effect: name,
                axis: Some(rec.axes[k].clone()),
                // One fitted coefficient; a spike's decay time is chosen from a grid.
                uncertainty: params
                    .iter()
                    .take(1)
                    .map(|(n, _)| (n.clone(), sd))
                    .collect(),
                parameters: params.into_iter().collect(),
                where_: Where {
                    blocks,
                    t_s: [t0, t1],
                    condition: condition + " (seen by the axis's own feedback)",
                },
                rms_explained: [(format!("rms_explained_{unit}"), contrib.sqrt())].into(),
                machine_physics: true,
                spec: effect.map(EffectSpec::from),
            });
        }
        let hb = (hold0 / m).sqrt();
        let ha = (hold_prev / m).sqrt();
        let rb = (rss0 / m).sqrt();
        let ra = (rss / m).sqrt();
        if !rec.rotary[k] {
            lin_before += rb * rb;
            lin_after += ra * ra;
            lin_hb += hb * hb;
            lin_ha += ha * ha;
            lin_floor += s2;
            lin_n += 1;
        }
        let kept: Vec<usize> = (0..d.t.len()).filter(|&i| d.keep[i]).collect();
        let step = (kept.len() / super::feedback::report::PLOT_POINTS).max(1);
        let series = kept
            .iter()
            .step_by(step)
            .map(|&i| {
                let model: f64 = terms
                    .iter()
                    .zip(&beta)
                    .map(|(f, b)| column(d, *f, i) * b)
                    .sum();
                (d.t[i], d.e[i], d.e[i] - model)
            })
            .collect();
        let qf = res_fb[k].unwrap_or(0.0);
        let qc = res_cmd[k].unwrap_or(0.0);
        chi_sds.push(chi_sd(d, qf.max(qc), (qf * qf + qc * qc) / 12.0, sigma[k]));
        axes.push(AxisSummary {
            axis: rec.axes[k].clone(),
            unit: if rec.rotary[k] { "deg" } else { "mm" }.into(),
            noise_floor: sigma[k],
            rms_before: rb,
            rms_after: ra,
            holdout_rms: [hb, ha],
            resolution: res_fb[k],
            series,
        });
    }
    findings.sort_by(|a, b| {
        let x = |f: &JointFinding| f.rms_explained.values().next().copied().unwrap_or(0.0);
        x(b).total_cmp(&x(a))
    });
    let pooled = |x: f64| {
        if lin_n > 0 {
            (x / lin_n as f64).sqrt()
        } else {
            0.0
        }
    };
    // Measurement findings.
    let mut measurement = Vec::new();
    let span = [rec.t[0], rec.t[n - 1]];
    let blocks = [rec.block[0], rec.block[n - 1]];
    if let Some(tc) = offset {
        let (start, start_sd) = tc.shift_at(rec.t[0]);
        let mut parameters: BTreeMap<String, f64> = [("offset_s".to_string(), start)].into();
        let mut uncertainty: BTreeMap<String, f64> = [("offset_s".to_string(), start_sd)].into();
        let mut everywhere = format!(
            "everywhere: every traced axis lags its command by the same {:.3} ms, which is the trace's clock, not the drives",
            start * 1e3
        );
        if let Some(rate_sd) = tc.rate_sd {
            parameters.insert("drift_ppm".to_string(), tc.clock.rate * 1e6);
            uncertainty.insert("drift_ppm".to_string(), rate_sd * 1e6);
            everywhere = format!(
                "everywhere: the feedback's clock runs {:.2} ppm against the commands', so the delay every traced axis shows grows from {:.3} ms at the start to {:.3} ms at the end (`offset_s` is the delay at the start); the trace's clocks, not the drives",
                tc.clock.rate * 1e6,
                start * 1e3,
                tc.clock.shift(rec.t[n - 1]) * 1e3
            );
        }
        measurement.push(MeasurementFinding {
            effect: "time_offset".into(),
            axis: None,
            parameters,
            uncertainty,
            where_: Where {
                blocks,
                t_s: span,
                condition: format!(
                    "{everywhere}; removed before the axes were fitted ({dropped_ends} sample(s) at the ends left out; {doubtful} where the command changes its acceleration between samples cannot be aligned within half the noise floor and are left out of the fits)"
                ),
            },
            rms_explained_mm: 0.0,
            machine_physics: false,
            samples: Vec::new(),
        });
    }
    if !flagged.is_empty() {
        let c = flagged.len();
        measurement.push(MeasurementFinding {
            effect: "outliers".into(),
            axis: None,
            parameters: [
                ("count".to_string(), c as f64),
                ("fraction".to_string(), c as f64 / n as f64),
            ]
            .into(),
            uncertainty: BTreeMap::new(),
            where_: Where {
                blocks: [rec.block[flagged[0].0], rec.block[flagged[c - 1].0]],
                t_s: [rec.t[flagged[0].0], rec.t[flagged[c - 1].0]],
                condition: format!(
                    "{c} isolated sample(s) depart from their neighbours by more than {OUTLIER_SIGMAS} noise floors: gross faults of the trace, excluded from every fit"
                ),
            },
            rms_explained_mm: 0.0,
            machine_physics: false,
            samples: flagged
                .iter()
                .take(50)
                .map(|&(i, _, e)| FlaggedSample {
                    index: i,
                    t_s: rec.t[i],
                    block: rec.block[i],
                    departure_mm: [e, 0.0, 0.0],
                })
                .collect(),
        });
    }
    let above: Vec<String> = axes
        .iter()
        .zip(&chi_sds)
        .filter(|(a, sd)| {
            let chi = (a.rms_after / a.noise_floor).powi(2);
            chi > 1.1 && chi - 1.0 > 4.0 * **sd
        })
        .map(|(a, _)| a)
        .map(|a| a.axis.clone())
        .collect();
    let verdict = if findings.is_empty() {
        if above.is_empty() {
            "consistent with measurement noise: every axis follows its command to within its noise floor; no missing physics found".to_string()
        } else {
            format!(
                "unexplained mismatch on {}: above the noise floor, and no joint-level effect (backlash, servo lag, zero offset, scale) explains it on held-out data",
                above.join(", ")
            )
        }
    } else {
        let names: Vec<String> = findings
            .iter()
            .map(|f| format!("{} of {}", f.effect, f.axis.as_deref().unwrap_or("")))
            .collect();
        let rest = if above.is_empty() {
            "; what remains is consistent with measurement noise".to_string()
        } else {
            format!(
                "; a mismatch above the noise remains on {}",
                above.join(", ")
            )
        };
        format!("missing physics found: {}{rest}", names.join(", "))
    };
    Ok(FeedbackReport {
        gaps: super::untidy::gaps_note(&rec.t, |i| rec.block.get(i).copied().flatten()),
        recording: "joint_feedback".into(),
        samples: n,
        samples_used: used,
        noise_floor_mm: pooled(lin_floor),
        rms_before_mm: pooled(lin_before),
        rms_after_mm: pooled(lin_after),
        holdout_rms_before_mm: pooled(lin_hb),
        holdout_rms_after_mm: pooled(lin_ha),
        measurement,
        findings,
        axes,
        rejected,
        verdict,
    })
}

/// The standard deviation of χ² per sample (the mean of `e²/σ²`) of axis
/// `d`'s kept residual when it is noise of floor `sigma`, of which the
/// variance `frozen` is the rounding of the values (feedback and command,
/// `step` the coarser step). White noise gives `2/n`. A rounding error is
/// no fresh draw at every sample: while the axis stands, or creeps by less
/// than a step, it stays what it was, so a run of samples within one step
/// of its first holds one draw of a uniform error (its square has a
/// relative variance of 0.8), counted with the run's length. A trace in
/// whole encoder counts whose axes rest for seconds at a time has a few
/// hundred such draws, not tens of thousands of samples, and its χ² spreads
/// accordingly (a B axis at 0.001 deg, noise-free, resting at 168
/// effective positions: χ² 1.12, within its 4 standard deviations of
/// 0.28; it was an "unexplained mismatch").
fn chi_sd(d: &AxisData, step: f64, frozen: f64, sigma: f64) -> f64 {
    let kept: Vec<usize> = (0..d.t.len()).filter(|&i| d.keep[i]).collect();
    let n = kept.len().max(1) as f64;
    let rho = (frozen / (sigma * sigma).max(1e-300)).clamp(0.0, 1.0);
    // Σ L² / (Σ L)² over the runs of samples sharing one rounding error.
    let mut sum_sq = 0.0;
    let mut run = 0.0;
    let mut start: Option<f64> = None;
    for &i in &kept {
        match start {
            Some(q0) if step > 0.0 && (d.q[i] - q0).abs() < step => run += 1.0,
            _ => {
                sum_sq += run * run;
                run = 1.0;
                start = Some(d.q[i]);
            }
        }
    }
    sum_sq += run * run;
    let share = sum_sq / (n * n);
    let var = (2.0 * (1.0 - rho).powi(2) + 4.0 * rho * (1.0 - rho)) / n + 0.8 * rho * rho * share;
    // Never below white noise's (the floor is itself an estimate).
    var.max(2.0 / n).sqrt()
}

/// The command `y(t)` at `tt` (within `t`): [`monotone_hermite`].
/// A joint-feedback trace's axes with their commands moved to the trace's
/// clock `tc` (the samples whose command then falls outside the trace
/// left out), and which samples that keeps.
struct Aligned {
    data: Vec<AxisData>,
    /// Index in the recording of each sample of `data`.
    index: Vec<usize>,
    /// Samples left out at the ends.
    dropped_ends: usize,
    /// Samples left out of the fits where the command changes its
    /// acceleration between samples.
    doubtful: usize,
}

/// [`Aligned`] for `rec` on the clock `tc`, with the axes' noise floors
/// `sigma`.
fn align_to_clock(rec: &FeedbackRecording, tc: &clock::TraceClock, sigma: &[f64]) -> Aligned {
    let (n, n_ax) = (rec.len(), rec.axes.len());
    let mut data: Vec<AxisData> = Vec::with_capacity(n_ax);
    let shift = |t: f64| tc.clock.shift(t);
    // Move every command to the axes' clock and start again.
    let mut cmd_al: Vec<Vec<f64>> = vec![Vec::with_capacity(n); n_ax];
    let mut keep_idx = Vec::with_capacity(n);
    for i in 0..n {
        let tt = rec.t[i] - shift(rec.t[i]);
        if tt < rec.t[0] || tt > rec.t[n - 1] {
            continue;
        }
        keep_idx.push(i);
        for k in 0..n_ax {
            cmd_al[k].push(hermite(&rec.t, &rec.cmd[k], tt));
        }
    }
    let dropped_ends = n - keep_idx.len();
    let t_al: Vec<f64> = keep_idx.iter().map(|&i| rec.t[i]).collect();
    // Where the command changes its acceleration between samples the
    // aligned command is uncertain (as in `untidy::align`): such
    // samples are left out when that may exceed half the noise floor.
    let m = keep_idx.len();
    let mut unsure = vec![false; m];
    for k in 0..n_ax {
        let c = &rec.cmd[k];
        let d3 = |i: usize| {
            if i == 0 || i + 2 >= n {
                f64::INFINITY
            } else {
                (c[i + 2] - 3.0 * c[i + 1] + 3.0 * c[i] - c[i - 1]).abs()
            }
        };
        for (p, &i) in keep_idx.iter().enumerate() {
            let d = shift(rec.t[i]);
            let tt = rec.t[i] - d;
            let j = rec.t.partition_point(|x| *x <= tt).clamp(1, n - 1) - 1;
            let dt = rec.t[j + 1] - rec.t[j];
            let worst = (j.saturating_sub(1)..=j + 1).map(d3).fold(0.0, f64::max);
            if 0.25 * worst * (d.abs() / dt).min(1.0) > 0.5 * sigma[k] {
                unsure[p] = true;
            }
        }
        let fb: Vec<f64> = keep_idx.iter().map(|&i| rec.fb[k][i]).collect();
        data.push(axis_data(&t_al, &cmd_al[k], &fb));
    }
    let doubtful = unsure.iter().filter(|u| **u).count();
    for k in 0..n_ax {
        data[k].keep = unsure.iter().map(|u| !u).collect();
    }
    Aligned {
        data,
        index: keep_idx,
        dropped_ends,
        doubtful,
    }
}

fn hermite(t: &[f64], y: &[f64], tt: f64) -> f64 {
    let n = t.len();
    let k = t.partition_point(|x| *x <= tt).clamp(1, n - 1) - 1;
    monotone_hermite(t, y, k, tt)
}
