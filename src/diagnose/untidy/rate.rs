//! A clock that runs fast or slow against the program's: the delay
//! between the recording and the program grows with time (two free-running
//! clocks, a tracker's PC and the controller, differ by some ppm: 20 ppm is
//! 5.5 ms over a 275 s recording). Left in, every moving axis shows a servo
//! lag from some block on. Found after the clock offset, refined with it,
//! and removed by moving the commands to the machine's clock.

use super::align::{Aligned, Clock, align_clock};
use super::offset::{STRICT, Tolerance, clock_rate};
use super::{
    MIN_OFFSET_SAMPLES, MIN_OFFSET_SHARE, Offset, alignment_gain, excess_chi2, median_interval,
    usable,
};
use crate::diagnose::prepare::{ModelMachine, Prepared, prepare};
use crate::diagnose::recording::Recording;
use crate::error::Result;

/// The first look at a rate: as [`super::LOOSE`] for the lags, with an
/// absolute margin of 1 ppm.
const LOOSE_RATE: Tolerance = Tolerance {
    relative: 0.05,
    absolute_s: 1e-6,
};

/// A clock rate found and refined.
#[derive(Debug, Clone, PartialEq)]
pub struct Rate {
    /// The clock: offset at `t_ref` and rate.
    pub clock: Clock,
    /// Standard deviation of the rate, s per s.
    pub rate_sd: f64,
}

/// Looks for a clock rate in `rec` once the clock offset `offset` (if
/// any) is removed, and refines offset and rate together. Returns the
/// offset with its rate, or the offset as it was when the recording shows
/// no rate. `floor` gives the noise floor of a prepared residual, per
/// coordinate and pooled, as [`super::floor_of`]; `min_delta_chi2` is
/// what the rate must lower χ² by. The rate must also account for a
/// quarter of the excess χ² and move the commands by at least 1 % of a
/// sampling interval over the recording.
pub fn with_rate(
    machine: &ModelMachine,
    rec: &Recording,
    prep0: &Prepared,
    keep0: &[bool],
    floor: &dyn Fn(&Prepared) -> ([f64; 3], f64),
    offset: Option<Offset>,
    min_delta_chi2: f64,
) -> Result<Option<Offset>> {
    let n = rec.samples.len();
    if n < 40 {
        return Ok(offset);
    }
    let span = rec.samples[n - 1].t - rec.samples[0].t;
    let d0 = offset.as_ref().map_or(0.0, |o| o.estimate.offset_s);
    let usable = |al: &Aligned, pa: &Prepared| usable(al, pa, keep0, floor);
    let al = align_clock(rec, Clock::offset(d0));
    let pa = prepare(machine, &al.rec)?;
    let (keep, sigma) = usable(&al, &pa);
    let Some(first) = clock_rate(&pa, &keep, sigma, min_delta_chi2, None, LOOSE_RATE) else {
        return Ok(offset);
    };
    let resolved = first.rate.abs() * span >= MIN_OFFSET_SAMPLES * median_interval(rec);
    // The timing as a whole (the rate with the lags, which take up the
    // offset) must account for a quarter of the excess: with a drift the
    // axes' apparent lags differ (each shows the delay of when it moves),
    // so the offset's own first look may have found nothing.
    if !resolved || first.timing_chi2 < MIN_OFFSET_SHARE * excess_chi2(&pa, &keep, sigma) {
        return Ok(offset);
    }
    let rate_axes = first.shared.clone();
    let mut lag_axes = offset
        .as_ref()
        .map_or(rate_axes.clone(), |o| o.estimate.shared.clone());
    let mut clock = Clock {
        offset_s: d0,
        rate: 0.0,
        t_ref: first.t_ref,
    };
    let mut rate_sd = first.sd;
    let mut step = first;
    let mut estimate = offset.as_ref().map(|o| o.estimate.clone());
    for round in 0..8 {
        clock.offset_s += step.rate * (clock.t_ref - step.t_ref);
        clock.rate += step.rate;
        let al = align_clock(rec, clock);
        if al.rec.samples.len() < 20 {
            return Ok(offset);
        }
        let pa = prepare(machine, &al.rec)?;
        let (keep, sigma) = usable(&al, &pa);
        let mut moved = 0.0;
        if let Some(lag) = super::offset::refine_step(&pa, &keep, sigma, round, &mut lag_axes) {
            clock.offset_s += lag.offset_s;
            moved = lag.offset_s.abs();
            estimate = Some(lag);
        }
        let Some(next) = clock_rate(&pa, &keep, sigma, 0.0, Some(&rate_axes), STRICT) else {
            break;
        };
        rate_sd = next.sd;
        let small = next.rate.abs() <= 1e-3 * clock.rate.abs() + 1e-9;
        if round >= 1 && small && moved <= 1e-4 * clock.offset_s.abs() + 1e-7 {
            break;
        }
        step = next;
    }
    // The aligned residual must be smaller, on the same samples.
    let al = align_clock(rec, clock);
    if al.rec.samples.len() < 20 {
        return Ok(offset);
    }
    let pa = prepare(machine, &al.rec)?;
    let (keep, _) = usable(&al, &pa);
    let (Some(mut estimate), Some(rms_explained_mm)) =
        (estimate, alignment_gain(prep0, &pa, &al.kept, &keep))
    else {
        return Ok(offset);
    };
    estimate.offset_s = clock.offset_s;
    Ok(Some(Offset {
        estimate,
        rms_explained_mm,
        dropped: n - al.kept.len(),
        doubtful: 0,
        rate: Some(Rate { clock, rate_sd }),
    }))
}
