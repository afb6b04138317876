//! A clock offset of seconds: beyond the reach of the linearised common lag
//! ([`super::offset`]), the measured tip is millimetres from the model's
//! and the recording looks like one of another machine. A coarse search
//! over the offset finds where the two meet; the usual refinement takes it
//! from there.

use super::align::align;
use super::{MISFIT_MM, median_miss};
use crate::diagnose::prepare::{ModelMachine, prepare};
use crate::diagnose::recording::Recording;
use crate::error::Result;

/// Samples the search evaluates the residual on (every k-th).
const SUBSAMPLE: usize = 400;
/// Offsets tried on each side of zero.
const STEPS: i32 = 200;
/// The longest offset searched, s (at most a third of the recording).
const REACH_S: f64 = 10.0;

/// The clock offset (s; the sample stamped t shows the machine at
/// t − offset) that brings the measured tip nearest the model's, by the
/// median distance over a subsample, tried every 1/200 of the reach over
/// ±min(10 s, a third of the recording); `None` when none brings it within
/// [`MISFIT_MM`].
pub fn coarse_offset(machine: &ModelMachine, rec: &Recording) -> Result<Option<f64>> {
    let n = rec.samples.len();
    if n < 40 {
        return Ok(None);
    }
    let sub = Recording {
        axes: rec.axes.clone(),
        temp_names: rec.temp_names.clone(),
        samples: rec
            .samples
            .iter()
            .step_by((n / SUBSAMPLE).max(1))
            .cloned()
            .collect(),
    };
    let span = rec.samples[n - 1].t - rec.samples[0].t;
    let reach = REACH_S.min(span / 3.0);
    let mut best: Option<(f64, f64)> = None;
    for k in -STEPS..=STEPS {
        let d = reach * f64::from(k) / f64::from(STEPS);
        let al = align(&sub, d);
        if al.rec.samples.len() < 20 {
            continue;
        }
        let miss = median_miss(&prepare(machine, &al.rec)?.r);
        if best.is_none_or(|(_, b)| miss < b) {
            best = Some((d, miss));
        }
    }
    Ok(best.filter(|&(_, miss)| miss <= MISFIT_MM).map(|(d, _)| d))
}
