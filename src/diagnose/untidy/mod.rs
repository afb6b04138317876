//! What real recordings carry besides machine physics (`formats.md` §2c):
//! the resolution of the export, gross outliers and a clock offset between
//! the recording and the program. Each is found here, named for what it is
//! and removed before any machine effect is fitted (`docs/diagnose.md`,
//! "Untidy recordings").
//!
//! * [`resolution`]: the step the values are rounded to ([`quantum`],
//!   [`Resolution`]);
//! * [`outliers`]: gross outliers ([`gross_outliers`], [`departure`]);
//! * [`offset`]: the clock offset ([`clock_offset`]);
//! * [`coarse`]: a clock offset of seconds, searched coarsely first;
//! * [`rate`](mod@rate): a clock that runs fast or slow ([`with_rate`]);
//! * [`align`](mod@align): the commands moved to the machine's clock;
//! * [`registration`](mod@registration): a constant offset of the
//!   measured tip, weighed among the machine effects;
//! * [`wander`](mod@wander): a slow wander of the measured tip with time,
//!   weighed alike;
//! * [`stamps`]: time stamps rounded or jittered off a regular clock;
//! * [`held`]: commands forward-filled from a slower stream.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

pub mod align;
pub mod coarse;
pub mod held;
pub mod offset;
pub mod outliers;
pub mod rate;
pub mod registration;
pub mod resolution;
pub mod stamps;
pub mod wander;

use std::collections::BTreeMap;

pub use align::{Aligned, Clock, align, align_clock, monotone_hermite, without};
pub use held::{HeldCommands, held_commands};
pub use offset::{LOOSE, OffsetEstimate, STRICT, Tolerance, clock_offset};
pub use outliers::{
    OUTLIER_SIGMAS, are_faults, beyond_chance_at_reversals, departure, flag_in_passes,
    gross_outliers,
};
pub use rate::{Rate, with_rate};
pub use registration::{registration_finding, registration_step_finding};
pub use resolution::{Resolution, quantum};
pub use stamps::{RegularClock, regular_clock};
pub use wander::wander_finding;

use super::prepare::{ModelMachine, Prepared, noise_floor, prepare};
use super::recording::Recording;
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

/// The noise floor of a prepared residual per coordinate, and its
/// quadratic mean: the robust estimate (on the residual without each
/// axis's apparent lag, [`offset::lag_free`]), never below the rounding of the
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
    let (per, _) = noise_floor(&offset::lag_free(prep));
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
    /// A clock that also runs fast or slow, when the recording shows one
    /// (then `estimate.offset_s` is the shift at its `t_ref`).
    pub rate: Option<Rate>,
}

impl Offset {
    /// The recording's clock against the program's.
    pub fn clock(&self) -> Clock {
        self.rate
            .as_ref()
            .map_or(Clock::offset(self.estimate.offset_s), |r| r.clock)
    }
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
    let floor = |p: &Prepared| floor_of(p, rounding_xyz, fixed_floor);
    let (per0, sigma0) = floor(&prep0);
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
    let refine = |first| refine_offset(machine, rec, &prep0, &keep0, &floor, first);
    let offset = match first {
        None => None,
        Some(first) => refine(first)?,
    };
    // A recording that does not fit as it stands may be seconds off the
    // program's clock: searched coarsely, then refined as any offset.
    let offset = match offset {
        None if median_miss(&prep0.r) > MISFIT_MM => match coarse::coarse_offset(machine, rec)? {
            Some(d) => refine(OffsetEstimate {
                offset_s: d,
                sd_s: 0.0,
                shared: (0..prep0.dof).collect(),
                lags: Vec::new(),
                delta_chi2: 0.0,
            })?,
            None => None,
        },
        found => found,
    };
    // A clock that runs fast or slow: a delay that grows with time.
    let offset = with_rate(machine, rec, &prep0, &keep0, &floor, offset, min_delta_chi2)?;
    let (rec1, kept1, blur) = match &offset {
        Some(o) => {
            let al = align_clock(rec, o.clock());
            (al.rec.clone(), al.kept.clone(), Some(al))
        }
        None => (rec.clone(), (0..rec.samples.len()).collect(), None),
    };
    let prep1 = prepare(machine, &rec1)?;
    misfit(&prep1)?;
    let (per1, sigma1) = floor(&prep1);
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
pub(super) fn median_interval(rec: &Recording) -> f64 {
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
pub(super) fn excess_chi2(prep: &Prepared, keep: &[bool], sigma: f64) -> f64 {
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
/// The median distance of the measured tip from the model's, mm
/// (infinite for no samples).
pub(super) fn median_miss(r: &[[f64; 3]]) -> f64 {
    let mut d: Vec<f64> = r
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .collect();
    if d.is_empty() {
        return f64::INFINITY;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid]
}

fn misfit(prep: &Prepared) -> Result<()> {
    let median = median_miss(&prep.r);
    if median > MISFIT_MM {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "the recording does not fit this machine: the measured tool tip is a median {median:.3} mm from where the machine model puts it (more than {MISFIT_MM} mm). Is it a recording of this machine, with its axes in mm and degrees and the tip in the workpiece frame? No clock offset between the trace and the measurement up to 10 s (or a third of the recording) brings them within 5 mm either"
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
    floor: &dyn Fn(&Prepared) -> ([f64; 3], f64),
    first: OffsetEstimate,
) -> Result<Option<Offset>> {
    let usable = |al: &Aligned, pa: &Prepared| usable(al, pa, keep0, floor);
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
        let Some(step) = offset::refine_step(&pa, &keep, sigma, round, &mut shared) else {
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
    let Some(rms_explained_mm) = alignment_gain(prep0, &pa, &al.kept, &keep) else {
        return Ok(None);
    };
    Ok(Some(Offset {
        estimate: last,
        rms_explained_mm,
        dropped: rec.samples.len() - al.kept.len(),
        doubtful: 0,
        rate: None,
    }))
}

/// The samples to fit on after an alignment `al` (`pa` prepared from its
/// recording): placed by the alignment within half the noise floor
/// (`floor`, as [`floor_of`]), not an outlier of the aligned residual, not
/// set aside before (`keep0`, indexed by the original samples). Returns
/// them and the pooled floor.
pub(super) fn usable(
    al: &Aligned,
    pa: &Prepared,
    keep0: &[bool],
    floor: &dyn Fn(&Prepared) -> ([f64; 3], f64),
) -> (Vec<bool>, f64) {
    let (per, sigma) = floor(pa);
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
}

/// What an alignment gains, on the samples `keep` allows (`kept`: their
/// indices in the original recording of `prep0`, `pa` prepared from the
/// aligned one): the RMS per coordinate of the tip change it makes (mm),
/// or `None` when the aligned residual is not smaller.
pub(super) fn alignment_gain(
    prep0: &Prepared,
    pa: &Prepared,
    kept: &[usize],
    keep: &[bool],
) -> Option<f64> {
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
    (before - after > 0.0).then(|| (moved / (3 * kept.len()).max(1) as f64).sqrt())
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
            let t_first = first.map_or(0.0, |s| s.t);
            let t_last = last.map_or(0.0, |s| s.t);
            let clock = o.clock();
            let start = clock.shift(t_first);
            let mut parameters: BTreeMap<String, f64> = [("offset_s".to_string(), start)].into();
            let mut uncertainty: BTreeMap<String, f64> = [("offset_s".to_string(), e.sd_s)].into();
            let mut everywhere = format!(
                "everywhere: the recording {} the program by {:.3} ms, as every moving axis shows the same delay",
                if start >= 0.0 { "lags" } else { "leads" },
                start.abs() * 1e3
            );
            if let Some(r) = &o.rate {
                parameters.insert("drift_ppm".to_string(), r.clock.rate * 1e6);
                uncertainty.insert("drift_ppm".to_string(), r.rate_sd * 1e6);
                everywhere = format!(
                    "everywhere: the recording's clock runs {:.2} ppm against the program's, so the delay every moving axis shows grows from {:.3} ms at the start to {:.3} ms at the end (`offset_s` is the delay at the start)",
                    r.clock.rate * 1e6,
                    start * 1e3,
                    clock.shift(t_last) * 1e3
                );
            }
            out.push(MeasurementFinding {
                effect: "time_offset".into(),
                axis: None,
                parameters,
                uncertainty,
                where_: Where {
                    blocks: [first.and_then(|s| s.block), last.and_then(|s| s.block)],
                    t_s: [first.map_or(0.0, |s| s.t), last.map_or(0.0, |s| s.t)],
                    condition: format!(
                        "{everywhere}; removed before any machine effect was fitted{dropped}"
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

/// The gaps of a recording's sampling ([`super::prepare::gap_steps`]) as a
/// note of the report (`formats.md` §2c: reported, never fitted silently;
/// not a finding, since the samples it has are fitted as they are): how
/// many, the longest, about how many samples are missing.
pub fn gaps_finding(rec: &Recording) -> Option<MeasurementFinding> {
    let t: Vec<f64> = rec.samples.iter().map(|s| s.t).collect();
    gaps_note(&t, |i| rec.samples[i].block)
}

/// [`gaps_finding`] of the time stamps `t`, `block` giving each sample's
/// block (joint-feedback recordings as tool-tip ones).
pub fn gaps_note(t: &[f64], block: impl Fn(usize) -> Option<u64>) -> Option<MeasurementFinding> {
    let gap = super::prepare::gap_steps(t);
    let at: Vec<usize> = (0..gap.len()).filter(|&i| gap[i]).collect();
    let (&first, &last) = (at.first()?, at.last()?);
    let step = |i: usize| t[i + 1] - t[i];
    // The usual step beside a gap, to count the samples it lacks.
    let beside = |i: usize| {
        let before = i.checked_sub(1).map(step);
        let after = (i + 2 < t.len()).then(|| step(i + 1));
        before
            .into_iter()
            .chain(after)
            .fold(f64::INFINITY, f64::min)
    };
    let longest = at.iter().map(|&i| step(i)).fold(0.0, f64::max);
    let missing: f64 = at
        .iter()
        .map(|&i| (step(i) / beside(i)).round() - 1.0)
        .sum();
    let k = at.len();
    Some(MeasurementFinding {
        effect: "gaps".into(),
        axis: None,
        parameters: [
            ("count".to_string(), k as f64),
            ("longest_s".to_string(), longest),
            ("missing_samples".to_string(), missing),
        ]
        .into(),
        uncertainty: BTreeMap::new(),
        where_: Where {
            blocks: [block(first), block(last + 1)],
            t_s: [t[first], t[last + 1]],
            condition: format!(
                "the recording stops {k} time(s) and goes on (about {missing:.0} samples missing in all, the longest gap {longest:.3} s: a trace buffer overflow or a paused export); the samples it has are fitted as they stand, the velocities at the gaps' edges taken from one side"
            ),
        },
        rms_explained_mm: 0.0,
        machine_physics: false,
        samples: Vec::new(),
    })
}
