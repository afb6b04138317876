//! A recording whose clock runs fast or slow against the controller's
//! (seventh hunt, `docs/robustness.md`): two free-running clocks differ by
//! some ppm, so the delay between the measured tip and the commands grows
//! with time. Before, 20 ppm over a 275 s recording were servo lags of
//! every axis "from block 82 on"; now the drift is a measurement fault of
//! the `time_offset` finding (`drift_ppm`), removed before the machine
//! effects are fitted, and a servo lag under it is still found.

use crate::diagnose_support::*;
use kinpost::diagnose::rng::Rng;
use kinpost::diagnose::{Effect, Recording, Report, SimOptions, simulate};

/// A recording of `sc`'s program with `specs`, sampled every 0.1 s, whose
/// measured tip is that of the machine at t − (offset + rate·t): simulated
/// noise-free every 2 ms, interpolated, then 1 µm of noise added.
fn drifting(sc: &Scenario, specs: &[&str], offset_s: f64, rate: f64, seed: u64) -> Recording {
    let fine = simulate(
        &sc.chain,
        Some(&sc.errors),
        &sc.program,
        &effects(specs),
        &SimOptions {
            noise_mm: 0.0,
            sample_interval_s: 0.002,
            ..sc.opts.clone()
        },
    )
    .unwrap();
    let s = &fine.samples;
    let mut rng = Rng::new(seed);
    let mut out = Recording {
        axes: fine.axes.clone(),
        temp_names: Vec::new(),
        samples: Vec::new(),
    };
    for smp in s.iter().step_by(50) {
        let tt = smp.t - (offset_s + rate * smp.t);
        let k = s.partition_point(|x| x.t <= tt);
        if k == 0 || k >= s.len() {
            continue;
        }
        let (a, b) = (&s[k - 1], &s[k]);
        let u = (tt - a.t) / (b.t - a.t);
        let mut m = smp.clone();
        for c in 0..3 {
            m.meas[c] = a.meas[c] + u * (b.meas[c] - a.meas[c]) + 0.001 * rng.normal();
        }
        out.samples.push(m);
    }
    out
}

fn time_offset(r: &Report) -> Option<(f64, Option<(f64, f64)>)> {
    let m = r.measurement.iter().find(|m| m.effect == "time_offset")?;
    let drift = m
        .parameters
        .get("drift_ppm")
        .map(|v| (*v, m.uncertainty["drift_ppm"]));
    Some((m.parameters["offset_s"], drift))
}

fn machine_findings(r: &Report) -> Vec<String> {
    r.findings
        .iter()
        .map(|f| format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()))
        .collect()
}

#[test]
fn a_clock_drift_is_a_measurement_fault_not_servo_lags() {
    for m in [Machine::Zhao, Machine::Wang] {
        let cases: Vec<(u64, f64, f64)> = vec![
            (7300, 0.0, 2e-5),
            (7301, 0.0, -2e-5),
            (7302, 0.01, 5e-5),
            (7303, -0.005, 1e-5),
        ];
        let res = par_map(&cases, |&(seed, offset, rate)| {
            let sc = m.scenario(100, seed);
            let rec = drifting(&sc, &[], offset, rate, seed);
            (offset, rate, sc.diagnose(&rec))
        });
        for (offset, rate, r) in &res {
            assert!(
                r.findings.is_empty(),
                "{m:?} {rate}: {:?} ({})",
                machine_findings(r),
                r.verdict
            );
            let (start, drift) = time_offset(r).unwrap_or_else(|| panic!("{m:?}: {}", r.verdict));
            let (ppm, sd) =
                drift.unwrap_or_else(|| panic!("{m:?} {rate}: no drift ({})", r.verdict));
            // Within 5 % or 4 standard deviations.
            assert!(
                (ppm - rate * 1e6).abs() <= (0.05 * rate.abs() * 1e6).max(4.0 * sd),
                "{m:?}: {ppm} ± {sd} ppm vs {}",
                rate * 1e6
            );
            assert!(
                (start - offset).abs() < 2e-4,
                "{m:?}: offset {start} vs {offset}"
            );
            assert!(
                r.verdict.starts_with("consistent with measurement noise"),
                "{}",
                r.verdict
            );
        }
    }
}

#[test]
fn a_servo_lag_is_found_under_a_clock_drift() {
    for (m, axis) in [(Machine::Zhao, "X"), (Machine::Wang, "Y")] {
        let seeds: Vec<u64> = (7400..7403).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(100, seed);
            // At the size of the catalogue's acceptance cases: a tip RMS
            // of 1.2 σ.
            let truth = sc
                .calibrated(&format!("servo_lag:{axis}=0.001"), 1.2 * 0.001)
                .spec;
            let Effect::ServoLag { tau_s: want, .. } = truth.effect else {
                unreachable!()
            };
            let spec = format!("servo_lag:{axis}={want}");
            let rec = drifting(&sc, &[spec.as_str()], 0.0, 2e-5, seed);
            (want, sc.diagnose(&rec))
        });
        for (want, r) in &res {
            assert_eq!(
                machine_findings(r),
                [format!("servo_lag {axis}")],
                "{m:?}: {}",
                r.verdict
            );
            let Effect::ServoLag { tau_s, .. } = r.findings[0].spec.effect else {
                unreachable!()
            };
            assert!(
                ((tau_s - want) / want).abs() < 0.25,
                "{m:?}: {tau_s} vs {want}"
            );
            assert!(time_offset(r).and_then(|t| t.1).is_some(), "{}", r.verdict);
        }
    }
}

#[test]
fn a_constant_clock_offset_reports_no_drift() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (7500..7504).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let rec = drifting(&sc, &[], 0.02, 0.0, seed);
            sc.diagnose(&rec)
        });
        for r in &res {
            let (start, drift) = time_offset(r).unwrap_or_else(|| panic!("{}", r.verdict));
            assert!((start - 0.02).abs() < 2e-4, "{start}");
            assert!(drift.is_none(), "{m:?}: {drift:?}");
            assert!(r.findings.is_empty(), "{:?}", machine_findings(r));
        }
    }
}
