//! A joint-feedback trace whose feedback was logged on a clock that runs
//! fast or slow against the controller's (an external encoder or scale
//! read by a data logger of its own): the delay between each axis's
//! command and its feedback grows with time. Eighth hunt,
//! `docs/robustness.md`.

use crate::diagnose_support::*;
use kinpost::diagnose::DiagOptions;
use kinpost::diagnose::feedback::{
    FeedbackRecording, FeedbackReport, FeedbackSimOptions, diagnose_feedback, simulate_feedback,
};
use kinpost::diagnose::rng::Rng;

/// A trace of `m`'s 60-block program with `specs`, sampled every 10 ms,
/// whose feedback is that of the axes at t − (offset + rate·t): simulated
/// noise-free every 2 ms, the feedback interpolated, then 0.5 µm (0.5
/// mdeg) of noise added.
fn drifting(m: Machine, specs: &[&str], offset_s: f64, rate: f64, seed: u64) -> FeedbackRecording {
    let fine = simulate_feedback(
        &m.chain(),
        &m.program(60, seed),
        &effects(specs),
        &FeedbackSimOptions {
            noise: 0.0,
            seed,
            sample_interval_s: 0.002,
            ..FeedbackSimOptions::default()
        },
    )
    .unwrap();
    let mut rng = Rng::new(seed);
    let n_ax = fine.axes.len();
    let mut out = FeedbackRecording {
        axes: fine.axes.clone(),
        rotary: fine.rotary.clone(),
        t: Vec::new(),
        block: Vec::new(),
        cmd: vec![Vec::new(); n_ax],
        fb: vec![Vec::new(); n_ax],
        time_from_rate: false,
    };
    for i in (0..fine.t.len()).step_by(5) {
        let t = fine.t[i];
        let tt = t - (offset_s + rate * t);
        let k = fine.t.partition_point(|x| *x <= tt);
        if k == 0 || k >= fine.t.len() {
            continue;
        }
        let u = (tt - fine.t[k - 1]) / (fine.t[k] - fine.t[k - 1]);
        out.t.push(t);
        out.block.push(fine.block[i]);
        for a in 0..n_ax {
            out.cmd[a].push(fine.cmd[a][i]);
            let f = &fine.fb[a];
            out.fb[a].push(f[k - 1] + u * (f[k] - f[k - 1]) + 0.0005 * rng.normal());
        }
    }
    out
}

fn names(r: &FeedbackReport) -> Vec<String> {
    r.findings
        .iter()
        .map(|f| format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()))
        .collect()
}

fn time_offset(r: &FeedbackReport) -> Option<(f64, Option<f64>)> {
    let m = r.measurement.iter().find(|m| m.effect == "time_offset")?;
    Some((
        m.parameters["offset_s"],
        m.parameters.get("drift_ppm").copied(),
    ))
}

#[test]
fn a_drifting_feedback_clock_is_a_measurement_fault_not_servo_lags() {
    for m in [Machine::Zhao, Machine::Wang] {
        let cases: Vec<(u64, f64, f64)> = vec![
            (7400, 0.0, 5e-5),
            (7401, 0.0, -5e-5),
            (7402, 0.01, 2e-5),
            (7403, -0.005, 1e-4),
        ];
        let res = par_map(&cases, |&(seed, offset, rate)| {
            let rec = drifting(m, &[], offset, rate, seed);
            let span = rec.t.last().unwrap() - rec.t[0];
            let r = diagnose_feedback(&rec, &DiagOptions::default()).unwrap();
            (span, time_offset(&r), names(&r))
        });
        for ((_, offset, rate), (span, found, machine)) in cases.iter().zip(&res) {
            println!(
                "{m:?} offset {offset} s, {} ppm over {span:.0} s: {found:?} {machine:?}",
                rate * 1e6
            );
        }
        for ((_, offset, rate), (_, found, machine)) in cases.iter().zip(&res) {
            assert!(machine.is_empty(), "{m:?} {rate}: {machine:?}");
            let (o, d) = found.expect("a time_offset finding");
            assert!((o - offset).abs() < 5e-4, "{m:?}: offset {o} for {offset}");
            let d = d.expect("drift_ppm");
            assert!(
                (d - rate * 1e6).abs() <= 0.05 * (rate * 1e6).abs(),
                "{m:?}: {d} ppm for {rate}"
            );
        }
    }
}

fn servo_lag(r: &FeedbackReport) -> Option<f64> {
    r.findings
        .iter()
        .find(|f| f.effect == "servo_lag")
        .and_then(|f| f.parameters.get("tau_s").copied())
}

#[test]
fn a_servo_lag_under_a_drift_is_still_found_and_a_steady_clock_reports_no_drift() {
    for m in [Machine::Zhao, Machine::Wang] {
        let lin = match m {
            Machine::Zhao => "X",
            Machine::Wang => "Y",
        };
        let lag = format!("servo_lag:{lin}=0.004");
        // (seed, effects, offset, rate)
        let cases: Vec<(u64, bool, f64, f64)> = vec![
            (7410, true, 0.0, 2e-5),
            (7411, true, 0.005, -5e-5),
            (7412, false, 0.015, 0.0),
            (7413, false, 0.0, 0.0),
            (7414, true, 0.0, 0.0),
        ];
        let res = par_map(&cases, |&(seed, with_lag, offset, rate)| {
            let specs: Vec<&str> = if with_lag { vec![&lag] } else { vec![] };
            let r = diagnose_feedback(
                &drifting(m, &specs, offset, rate, seed),
                &DiagOptions::default(),
            )
            .unwrap();
            (time_offset(&r), servo_lag(&r), names(&r))
        });
        for (c, r) in cases.iter().zip(&res) {
            println!("{m:?} {c:?}: {r:?}");
        }
        for ((_, with_lag, offset, rate), (found, tau, machine)) in cases.iter().zip(&res) {
            if *with_lag {
                assert_eq!(machine, &vec![format!("servo_lag {lin}")], "{m:?} {rate}");
                let tau = tau.unwrap();
                assert!((tau - 0.004).abs() <= 0.25 * 0.004, "{m:?}: τ {tau}");
            } else {
                assert!(machine.is_empty(), "{m:?}: {machine:?}");
            }
            match found {
                None => assert!(
                    *offset == 0.0 && *rate == 0.0,
                    "{m:?}: no clock for {offset} {rate}"
                ),
                Some((o, d)) => {
                    assert!((o - offset).abs() < 5e-4, "{m:?}: offset {o} for {offset}");
                    assert_eq!(d.is_some(), *rate != 0.0, "{m:?}: drift {d:?} for {rate}");
                }
            }
        }
    }
}
