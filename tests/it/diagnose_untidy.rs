//! Untidy recordings (`formats.md` §2c, issue 12): a clock offset, gross
//! outliers and rounded values are named for what they are, never
//! explained with machine effects, and machine effects are still found
//! under them.
//!
//! Sweeps over seeds on both seed machines (σ = 1 µm, fixture geometric
//! errors in the model):
//! - quiet: clean recordings with 0.5 % outliers, rounded to 0.1 µm … 10 µm,
//!   or with only a clock offset give no machine finding in ≥ 95 % of seeds;
//! - the clock offset is found within 10 %, alone, under a servo lag of
//!   one axis (found too), with outliers, and rounded;
//! - a catalogue effect is found within 25 % under outliers and a clock
//!   offset.

use crate::diagnose_support::*;
use kinpost::diagnose::{Effect, Recording, Report, SimOptions, diagnose, simulate};

const SEEDS: u64 = 20;

fn machine_findings(r: &Report) -> Vec<String> {
    r.findings
        .iter()
        .map(|f| format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()))
        .collect()
}

fn measurement(r: &Report, name: &str) -> Option<f64> {
    r.measurement
        .iter()
        .find(|m| m.effect == name)
        .and_then(|m| {
            m.parameters
                .get(if name == "time_offset" {
                    "offset_s"
                } else {
                    "count"
                })
                .copied()
        })
}

/// Simulates `sc`'s program with `effects` and the faults of `faults`, then
/// diagnoses it.
fn run(sc: &Scenario, effects: &[&str], faults: impl Fn(&mut SimOptions)) -> (Recording, Report) {
    let mut opts = sc.opts.clone();
    faults(&mut opts);
    let rec = simulate(
        &sc.chain,
        Some(&sc.errors),
        &sc.program,
        &crate::diagnose_support::effects(effects),
        &opts,
    )
    .unwrap();
    let r = diagnose(
        &sc.chain,
        Some(&sc.errors),
        &rec,
        &kinpost::diagnose::DiagOptions::default(),
    )
    .unwrap();
    (rec, r)
}

fn blocks(m: Machine) -> usize {
    match m {
        Machine::Zhao => 60,
        Machine::Wang => 50,
    }
}

/// Quiet cases: no machine finding in at least 95 % of seeds.
fn quiet(name: &str, faults: &(dyn Fn(&mut SimOptions) + Sync)) {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (3000..3000 + SEEDS).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(blocks(m), seed);
            let (_, r) = run(&sc, &[], faults);
            (seed, machine_findings(&r), r.verdict.clone())
        });
        let alarms: Vec<String> = res
            .iter()
            .filter(|(_, f, _)| !f.is_empty())
            .map(|(s, f, v)| format!("seed {s}: {f:?} ({v})"))
            .collect();
        println!(
            "{name} on {m:?}: {} machine finding(s) in {SEEDS} seeds {alarms:?}",
            alarms.len()
        );
        assert!(
            alarms.len() as f64 <= 0.05 * SEEDS as f64,
            "{name} on {m:?}: {alarms:?}"
        );
        for (_, f, v) in &res {
            if f.is_empty() {
                assert!(v.starts_with("consistent with measurement noise"), "{v}");
            }
        }
    }
}

#[test]
fn clean_recordings_with_outliers_stay_quiet_and_name_the_outliers() {
    quiet("0.5 % outliers", &|o| o.outlier_fraction = 0.005);
    // The outliers are named and counted.
    let sc = Machine::Zhao.scenario(60, 3001);
    let (rec, r) = run(&sc, &[], |o| o.outlier_fraction = 0.005);
    let count = measurement(&r, "outliers").expect("outliers named");
    let truth = 0.005 * rec.len() as f64;
    assert!(
        count >= 1.0 && (count - truth).abs() <= 3.0 * truth.sqrt() + 2.0,
        "{count} vs {truth}"
    );
    let json = r.to_json();
    let f = &json["findings"][0];
    assert_eq!(f["effect"], "outliers");
    assert_eq!(f["machine_physics"], false);
    assert!(f["axis"].is_null());
}

#[test]
fn rounded_recordings_stay_quiet_with_an_honest_noise_floor() {
    for q in [1e-4, 1e-3, 1e-2] {
        quiet(&format!("rounded to {q} mm"), &move |o| o.quantum = q);
    }
    // Rounded far above the noise: the floor is the rounding's.
    let sc = Machine::Zhao.scenario(60, 3002);
    let (_, r) = run(&sc, &[], |o| o.quantum = 0.1);
    assert!(r.findings.is_empty(), "{:?}", machine_findings(&r));
    assert!(
        r.noise_floor_mm >= 0.1 / 12f64.sqrt() * 0.99,
        "{}",
        r.noise_floor_mm
    );
    assert_eq!(r.resolution.get("meas_mm"), Some(&0.1));
    assert!(r.chi2_per_dof_before < 2.0, "{}", r.chi2_per_dof_before);
}

#[test]
fn a_clock_offset_alone_is_named_and_measured_within_ten_percent() {
    quiet("clock offset 15 ms", &|o| o.time_offset_s = 0.015);
    for m in [Machine::Zhao, Machine::Wang] {
        for offset in [0.015, -0.04, 0.2] {
            let seeds: Vec<u64> = (3100..3100 + 6).collect();
            let res = par_map(&seeds, |&seed| {
                let sc = m.scenario(blocks(m), seed);
                let (_, r) = run(&sc, &[], |o| o.time_offset_s = offset);
                (measurement(&r, "time_offset"), machine_findings(&r))
            });
            let worst = res
                .iter()
                .filter_map(|(f, _)| f.map(|d| ((d - offset) / offset).abs()))
                .fold(0.0, f64::max);
            println!(
                "{m:?}: clock offset {offset} s found in {} of {} seeds, worst error {:.2} %",
                res.iter().filter(|(f, _)| f.is_some()).count(),
                res.len(),
                worst * 100.0
            );
            for (found, others) in &res {
                let d = found.unwrap_or_else(|| panic!("{m:?} {offset}: not found"));
                assert!(
                    ((d - offset) / offset).abs() < 0.1,
                    "{m:?}: {d} vs {offset}"
                );
                assert!(others.is_empty(), "{m:?} {offset}: {others:?}");
            }
        }
    }
}

#[test]
fn a_servo_lag_is_found_beside_a_clock_offset_and_outliers() {
    // The servo lag at the size of the catalogue's acceptance cases (tip
    // RMS 1.2 σ), under a 15 ms clock offset and 0.5 % outliers.
    for m in [Machine::Zhao, Machine::Wang] {
        let axis = match m {
            Machine::Zhao => "X",
            Machine::Wang => "Y",
        };
        let seeds: Vec<u64> = (3200..3200 + 8).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(blocks(m), seed);
            let truth = sc
                .calibrated(&format!("servo_lag:{axis}=0.001"), 1.2 * 0.001)
                .spec;
            let Effect::ServoLag { tau_s: want, .. } = truth.effect else {
                unreachable!()
            };
            let spec = format!("servo_lag:{axis}={want}");
            let (_, r) = run(&sc, &[spec.as_str()], |o| {
                o.time_offset_s = 0.015;
                o.outlier_fraction = 0.005;
            });
            let lag = r.findings.iter().find_map(|f| match &f.spec.effect {
                Effect::ServoLag { axis: a, tau_s } if a == axis => Some(*tau_s),
                _ => None,
            });
            (
                measurement(&r, "time_offset"),
                lag.map(|l| (l, want)),
                machine_findings(&r),
                r.verdict.clone(),
            )
        });
        let mut misses = Vec::new();
        for (offset, lag, names, verdict) in &res {
            let d = offset.unwrap_or_else(|| panic!("{m:?}: no clock offset: {verdict}"));
            assert!(((d - 0.015) / 0.015).abs() < 0.1, "{m:?}: offset {d}");
            match lag {
                Some((tau, want)) if ((tau - want) / want).abs() < 0.25 && names.len() == 1 => {}
                _ => misses.push(format!("{lag:?} {names:?}")),
            }
        }
        println!(
            "{m:?}: servo lag of {axis} under a clock offset: {} of {} missed {misses:?}",
            misses.len(),
            res.len()
        );
        assert!(misses.len() <= 1, "{m:?}: {misses:?}");
    }
}

#[test]
fn a_negative_lag_is_never_a_finding() {
    // A recording that leads its program by 15 ms on one axis only would
    // fit a negative servo lag of that axis: rejected with its reason.
    let sc = Machine::Zhao.scenario(60, 3300);
    let (_, r) = run(&sc, &["servo_lag:X=-0.006"], |_| {});
    for f in &r.findings {
        if let Effect::ServoLag { tau_s, .. } = f.spec.effect {
            assert!(tau_s > 0.0, "{}", r.verdict);
        }
    }
    assert!(
        r.rejected
            .iter()
            .any(|x| x.effect == "servo_lag" && x.reason.contains("negative")),
        "{:?}",
        r.rejected
    );
}

/// Gaps in the sampling (a trace buffer overflow: rows missing, the clock
/// going on) are reported, not fitted silently (`formats.md` §2c), and the
/// velocities at their edges come from one side. Before, nothing said
/// there were gaps, and a servo lag beside them brought a spurious
/// `vibration` or `cyclic` finding: the central differences across a gap
/// averaged seconds of motion the recording does not show.
#[test]
fn gaps_are_reported_and_do_not_bring_findings_of_their_own() {
    let cut = |rec: &mut Recording| {
        let n = rec.samples.len();
        let mut k = 0;
        rec.samples.retain(|_| {
            k += 1;
            ![n / 5, n / 2, 4 * n / 5]
                .iter()
                .any(|&at| (at..at + 80).contains(&(k - 1)))
        });
    };
    for m in [Machine::Zhao, Machine::Wang] {
        let axis = match m {
            Machine::Zhao => "Z",
            Machine::Wang => "X",
        };
        let seeds: Vec<u64> = (3400..3400 + 4).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(blocks(m), seed);
            let mut out = Vec::new();
            // A lag of the catalogue's acceptance size (tip RMS 1.2 σ).
            let truth = sc
                .calibrated(&format!("servo_lag:{axis}=0.001"), 1.2 * 0.001)
                .spec;
            let Effect::ServoLag { tau_s, .. } = truth.effect else {
                unreachable!()
            };
            for effects in [vec![], vec![format!("servo_lag:{axis}={tau_s}")]] {
                let effects: Vec<&str> = effects.iter().map(String::as_str).collect();
                let mut rec = simulate(
                    &sc.chain,
                    Some(&sc.errors),
                    &sc.program,
                    &crate::diagnose_support::effects(&effects),
                    &sc.opts,
                )
                .unwrap();
                cut(&mut rec);
                let r = diagnose(
                    &sc.chain,
                    Some(&sc.errors),
                    &rec,
                    &kinpost::diagnose::DiagOptions::default(),
                )
                .unwrap();
                let gaps = r
                    .gaps
                    .as_ref()
                    .map(|g| (g.parameters["count"], g.parameters["missing_samples"]));
                out.push((effects.len(), gaps, machine_findings(&r), r.verdict.clone()));
            }
            out
        });
        for (lagged, gaps, names, verdict) in res.iter().flatten() {
            assert_eq!(*gaps, Some((3.0, 240.0)), "{m:?}: {verdict}");
            let want: Vec<String> = if *lagged == 1 {
                vec![format!("servo_lag {axis}")]
            } else {
                vec![]
            };
            assert_eq!(*names, want, "{m:?}: {verdict}");
        }
    }
}

/// A clock offset of seconds (a tracker and a trace started by hand):
/// beyond the linearised lag's reach the tip is millimetres off, and the
/// recording was refused as "does not fit this machine". A coarse search
/// finds it, the refinement measures it, and nothing else is claimed.
#[test]
fn a_clock_offset_of_seconds_is_found() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (3500..3500 + 2).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(blocks(m), seed);
            let (_, r) = run(&sc, &[], |o| o.time_offset_s = 2.5);
            (
                measurement(&r, "time_offset"),
                machine_findings(&r),
                r.verdict.clone(),
            )
        });
        for (offset, names, verdict) in res {
            let d = offset.unwrap_or_else(|| panic!("{m:?}: no clock offset: {verdict}"));
            assert!((d - 2.5).abs() < 2.5e-3, "{m:?}: offset {d}: {verdict}");
            assert!(names.is_empty(), "{m:?}: {names:?}: {verdict}");
        }
    }
}

/// Short clean traces stay quiet, also in the verdict: the noise floor of
/// 30 samples is itself uncertain by about 20 %, and a residual 19 % above
/// it had been called an "unexplained mismatch" (with a correlation read
/// from 12 bins of 30 samples).
#[test]
fn short_clean_traces_are_consistent_with_noise() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (3600..3600 + 40).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(blocks(m), seed);
            let mut rec = simulate(
                &sc.chain,
                Some(&sc.errors),
                &sc.program,
                &crate::diagnose_support::effects(&[]),
                &sc.opts,
            )
            .unwrap();
            // 30 samples from the middle of the trace.
            let mid = rec.samples.len() / 2;
            rec.samples = rec.samples[mid..mid + 30].to_vec();
            let r = diagnose(
                &sc.chain,
                Some(&sc.errors),
                &rec,
                &kinpost::diagnose::DiagOptions::default(),
            )
            .unwrap();
            (seed, machine_findings(&r), r.verdict.clone())
        });
        let loud: Vec<_> = res
            .iter()
            .filter(|(_, f, v)| {
                !f.is_empty() || !v.starts_with("consistent with measurement noise")
            })
            .collect();
        assert!(loud.is_empty(), "{m:?}: {loud:?}");
    }
}

/// Gross outliers well above 5 % of the samples (a tracker whose beam is
/// broken often; `simulate` allows up to 50 %): scattered at random, they
/// are named and counted, and a backlash under them is still found alone
/// (at 30 % in some runs, not in all: `docs/robustness.md`).
/// Before, more than 5 % flagged was taken for a signal: none was named,
/// and the verdict was "unexplained mismatch" (residual 82–160 µm) with
/// the backlash lost, from 5 % of outliers on.
#[test]
fn a_backlash_is_found_under_a_quarter_of_outliers() {
    for m in [Machine::Zhao, Machine::Wang] {
        let axis = match m {
            Machine::Zhao => "X",
            Machine::Wang => "Y",
        };
        let cases: Vec<(f64, u64)> = [0.1, 0.2, 0.25]
            .iter()
            .flat_map(|&f| (3400..3402).map(move |s| (f, s)))
            .collect();
        let res = par_map(&cases, |&(fraction, seed)| {
            let sc = m.scenario(blocks(m), seed);
            let spec = format!("backlash:{axis}=0.004");
            let (rec, r) = run(&sc, &[spec.as_str()], |o| o.outlier_fraction = fraction);
            let backlash = r.findings.iter().find_map(|f| match &f.spec.effect {
                Effect::Backlash { axis: a, value } if a == axis => Some(*value),
                _ => None,
            });
            (
                fraction,
                measurement(&r, "outliers").map(|c| c / rec.len() as f64),
                backlash,
                machine_findings(&r),
                r.verdict.clone(),
            )
        });
        for (fraction, flagged, backlash, names, verdict) in &res {
            println!("{m:?} {fraction}: flagged {flagged:?}, backlash {backlash:?}, {names:?}");
            let flagged = flagged.unwrap_or_else(|| panic!("{m:?} {fraction}: {verdict}"));
            assert!(
                (flagged - fraction).abs() < 0.25 * fraction,
                "{m:?} {fraction}: {flagged} flagged"
            );
            let b = backlash.unwrap_or_else(|| panic!("{m:?} {fraction}: {verdict}"));
            assert!((b - 0.004).abs() < 0.001, "{m:?} {fraction}: {b}");
            assert_eq!(names.len(), 1, "{m:?} {fraction}: {names:?}");
        }
    }
}
