//! Acceptance sweep of the `vibration` effect (issue 12): a time-periodic
//! motion of one linear axis at a fixed frequency, on both seed machines,
//! under the fixture geometric errors (larger than it), with σ = 1 µm and
//! the vibration's tip RMS 1.2 σ (as the catalogue's acceptance cases):
//! - alone;
//! - concealed under a catalogue effect (a backlash of another axis, also
//!   1.2 σ), which must be found too;
//! - at 7 Hz in a recording sampled at 50 Hz.
//!
//! Each must be found on its axis with the frequency within 2 %, the
//! amplitude within 25 %, and nothing else claimed.

use crate::diagnose_support::*;
use kinpost::diagnose::{Effect, Report};

const SIGMA: f64 = 0.001;

/// The vibration found on `axis`: (frequency, amplitude).
fn vibration(r: &Report, axis: &str) -> Option<(f64, f64)> {
    r.findings.iter().find_map(|f| match &f.spec.effect {
        Effect::Vibration {
            axis: a,
            frequency_hz,
            amplitude,
            ..
        } if a == axis => Some((*frequency_hz, *amplitude)),
        _ => None,
    })
}

/// Runs one case: a vibration of `axis` at `f` Hz (calibrated to 1.2 σ),
/// with `extra` (calibrated to 1.2 σ too); returns a failure text or None.
fn case(
    m: Machine,
    blocks: usize,
    seed: u64,
    axis: &str,
    f: f64,
    extra: Option<&str>,
    dt: f64,
) -> Option<String> {
    let mut sc = m.scenario(blocks, seed);
    sc.opts.sample_interval_s = dt;
    let truth = sc
        .calibrated(
            &format!("vibration:{axis}=0.001,f={f},phase=40"),
            1.2 * SIGMA,
        )
        .spec;
    let Effect::Vibration {
        amplitude: a_true, ..
    } = truth.effect
    else {
        unreachable!()
    };
    let mut effects = vec![truth];
    let mut extra_axis = None;
    if let Some(e) = extra {
        let c = sc.calibrated(e, 1.2 * SIGMA).spec;
        extra_axis = c.effect.axis_label();
        effects.push(c);
    }
    let rec = sc.simulate(&effects);
    let r = sc.diagnose(&rec);
    let names: Vec<String> = r
        .findings
        .iter()
        .map(|x| format!("{} {}", x.effect, x.axis.clone().unwrap_or_default()))
        .collect();
    let Some((f_found, a_found)) = vibration(&r, axis) else {
        return Some(format!("seed {seed}: no vibration of {axis}: {names:?}"));
    };
    if ((f_found - f) / f).abs() > 0.02 {
        return Some(format!("seed {seed}: frequency {f_found} vs {f}"));
    }
    if ((a_found - a_true) / a_true).abs() > 0.25 {
        return Some(format!("seed {seed}: amplitude {a_found} vs {a_true}"));
    }
    let expected = 1 + usize::from(extra.is_some());
    if names.len() != expected {
        return Some(format!("seed {seed}: {names:?}"));
    }
    if let (Some(e), Some(ax)) = (extra, extra_axis) {
        let kind = e.split(':').next().unwrap();
        if !names.iter().any(|n| n == &format!("{kind} {ax}")) {
            return Some(format!("seed {seed}: {e} not found: {names:?}"));
        }
    }
    None
}

fn axes(m: Machine) -> (&'static str, &'static str, usize) {
    match m {
        Machine::Zhao => ("X", "Z", 60),
        Machine::Wang => ("Y", "X", 50),
    }
}

#[test]
fn a_vibration_alone_is_found_with_its_frequency() {
    for m in [Machine::Zhao, Machine::Wang] {
        let (axis, _, blocks) = axes(m);
        sweep("vibration alone", m, 4000..4010, |seed| {
            let f = 0.3 + 0.27 * (seed % 10) as f64;
            case(m, blocks, seed, axis, f, None, 0.1)
        });
    }
}

#[test]
fn a_vibration_concealed_under_a_backlash_is_found_with_it() {
    for m in [Machine::Zhao, Machine::Wang] {
        let (axis, other, blocks) = axes(m);
        let extra = format!("backlash:{other}=0.002");
        sweep("vibration under a backlash", m, 4100..4108, |seed| {
            let f = 0.45 + 0.31 * (seed % 8) as f64;
            case(m, blocks, seed, axis, f, Some(&extra), 0.1)
        });
    }
}

#[test]
fn a_seven_hertz_vibration_in_a_fifty_hertz_recording() {
    for m in [Machine::Zhao, Machine::Wang] {
        let (axis, _, _) = axes(m);
        sweep("7 Hz at 50 Hz sampling", m, 4200..4204, |seed| {
            case(m, 12, seed, axis, 7.0, None, 0.02)
        });
    }
}
