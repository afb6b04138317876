//! What the diagnosis makes of a constant offset of the measured tip (the
//! measuring system's registration: a tracker or probe zeroed off) and of
//! several simple effects at once (seventh hunt, `docs/robustness.md`).
//!
//! - A registration is a measurement fault: no machine finding, the offset
//!   measured within 4 standard deviations, nothing written into a model.
//!   Before, it was an `error_motion` of the rotary table that carries the
//!   workpiece (its once-per-turn harmonic is the same function).
//! - Two zero offsets are two zero offsets: before, the greedy selection
//!   took one error motion of another axis (a spline per component sums
//!   up constants), or a registration plus a zero offset.
//! - A catalogue effect under a registration is still found.

use crate::diagnose_support::*;
use kinpost::diagnose::{DiagOptions, Effect, Recording, Report, diagnose};

fn machine_findings(r: &Report) -> Vec<String> {
    r.findings
        .iter()
        .map(|f| format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()))
        .collect()
}

/// The recording with every measured tip moved by `d` (mm, workpiece
/// frame), as a measuring system registered off gives it.
fn registered_off(mut rec: Recording, d: [f64; 3]) -> Recording {
    for s in &mut rec.samples {
        for (m, dc) in s.meas.iter_mut().zip(d) {
            *m += dc;
        }
    }
    rec
}

fn run(sc: &Scenario, specs: &[&str], d: [f64; 3]) -> Report {
    let rec = registered_off(sc.simulate(&effects(specs)), d);
    diagnose(&sc.chain, Some(&sc.errors), &rec, &DiagOptions::default()).unwrap()
}

/// The registration the report names: (dx, dy, dz) and their standard
/// deviations, mm.
fn registration(r: &Report) -> Option<([f64; 3], [f64; 3])> {
    let m = r.measurement.iter().find(|m| m.effect == "registration")?;
    assert!(!m.machine_physics);
    let get = |map: &std::collections::BTreeMap<String, f64>, k: &str| map[k];
    let keys = ["dx_mm", "dy_mm", "dz_mm"];
    Some((
        keys.map(|k| get(&m.parameters, k)),
        keys.map(|k| get(&m.uncertainty, k)),
    ))
}

#[test]
fn a_registration_of_the_measurement_is_not_machine_physics() {
    // Offsets the machine's own axes cannot make: on zhao2022-xzbc an
    // offset along z is Z's zero offset, on wang2023-xyzab one along x is
    // X's (A turns about x); there the zero offset, one parameter, is
    // named, as docs/diagnose.md says.
    for (m, offsets) in [
        (
            Machine::Zhao,
            [[0.002, 0.0, 0.0], [0.002, -0.002, 0.001], [0.0, 0.003, 0.0]],
        ),
        (
            Machine::Wang,
            [[0.0, 0.002, 0.0], [0.001, -0.002, 0.002], [0.0, 0.0, 0.003]],
        ),
    ] {
        let seeds: Vec<u64> = (7000..7006).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let d = offsets[seed as usize % offsets.len()];
            (d, run(&sc, &[], d))
        });
        for (d, r) in &res {
            assert!(
                r.findings.is_empty(),
                "{m:?} {d:?}: {:?} ({})",
                machine_findings(r),
                r.verdict
            );
            assert!(
                r.verdict
                    .starts_with("consistent with measurement noise once the measurement faults are removed (a registration offset"),
                "{m:?} {d:?}: {}",
                r.verdict
            );
            let (got, sd) = registration(r).unwrap_or_else(|| panic!("{m:?} {d:?}: not named"));
            for c in 0..3 {
                assert!(
                    (got[c] - d[c]).abs() <= 4.0 * sd[c] + 1e-5,
                    "{m:?}: {got:?} ± {sd:?} vs {d:?}"
                );
            }
            // In the JSON with the measurement faults, and never in a
            // model.
            let json = r.to_json();
            let f = &json["findings"][0];
            assert_eq!(f["effect"], "registration");
            assert_eq!(f["machine_physics"], false);
            let model = r.improved_model(None);
            assert!(model.effects.is_empty(), "{:?}", model.effects);
            assert!(model.axes.is_empty());
        }
    }
}

#[test]
fn two_zero_offsets_are_two_zero_offsets() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (7100..7104).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            run(
                &sc,
                &["zero_offset:X=0.005", "zero_offset:Z=-0.004"],
                [0.0; 3],
            )
        });
        for r in &res {
            let mut names = machine_findings(r);
            names.sort();
            assert_eq!(
                names,
                ["zero_offset X", "zero_offset Z"],
                "{m:?}: {}",
                r.verdict
            );
            assert!(registration(r).is_none(), "{m:?}: {}", r.verdict);
            for f in &r.findings {
                let (Effect::ZeroOffset { axis, value }, Some(sd)) =
                    (&f.spec.effect, f.uncertainty.get("value_mm"))
                else {
                    panic!("{f:?}")
                };
                let want = if axis == "X" { 0.005 } else { -0.004 };
                assert!(
                    (value - want).abs() <= 4.0 * sd,
                    "{m:?} {axis}: {value} ± {sd}"
                );
            }
        }
    }
}

#[test]
fn a_backlash_is_found_under_a_registration() {
    for (m, axis) in [(Machine::Zhao, "X"), (Machine::Wang, "Y")] {
        let seeds: Vec<u64> = (7200..7203).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            run(
                &sc,
                &[&format!("backlash:{axis}=0.006")],
                [0.003, -0.002, 0.0],
            )
        });
        for r in &res {
            assert_eq!(
                machine_findings(r),
                [format!("backlash {axis}")],
                "{m:?}: {}",
                r.verdict
            );
            let (got, sd) = registration(r).unwrap_or_else(|| panic!("{m:?}: {}", r.verdict));
            assert!((got[0] - 0.003).abs() <= 4.0 * sd[0] + 1e-5, "{got:?}");
            assert!(r.verdict.starts_with("missing physics found once the measurement faults are removed (a registration offset"), "{}", r.verdict);
        }
    }
}

/// With a registration removed and a mismatch left that no effect
/// explains (here the measurement's noise grows fourfold half-way), the
/// verdict quotes the residual after the registration, as the "consistent
/// with noise" verdict does: before, it quoted the RMS with the
/// registration still in (3.7 instead of 3.0 µm).
#[test]
fn an_unexplained_mismatch_beside_a_registration_quotes_the_residual_without_it() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (7260..7262).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let mut rec = registered_off(sc.simulate(&[]), [0.003, -0.002, 0.0]);
            let mut rng = kinpost::diagnose::rng::Rng::new(seed);
            let n = rec.samples.len();
            for s in &mut rec.samples[n / 2..] {
                for c in 0..3 {
                    s.meas[c] += 0.004 * rng.normal();
                }
            }
            diagnose(&sc.chain, Some(&sc.errors), &rec, &DiagOptions::default()).unwrap()
        });
        for r in &res {
            assert!(machine_findings(r).is_empty(), "{m:?}: {}", r.verdict);
            assert!(registration(r).is_some(), "{m:?}: {}", r.verdict);
            assert!(
                r.verdict
                    .starts_with("unexplained mismatch once the measurement faults are removed"),
                "{}",
                r.verdict
            );
            let quoted = format!("the residual RMS {:.3} µm", r.rms_after_mm * 1e3);
            assert!(r.rms_before_mm > r.rms_after_mm * 1.1);
            assert!(r.verdict.contains(&quoted), "{quoted}: {}", r.verdict);
        }
    }
}

/// The recording with every measured tip from sample `from` on moved by
/// `d` (mm, workpiece frame): a tracker that re-acquired its target off
/// after a beam break. Returns it with the time of the step.
fn stepped_off(mut rec: Recording, from: usize, d: [f64; 3]) -> (Recording, f64) {
    let t = rec.samples[from].t;
    for s in rec.samples.iter_mut().skip(from) {
        for (m, dc) in s.meas.iter_mut().zip(d) {
            *m += dc;
        }
    }
    (rec, t)
}

/// `step` is a measurement fault whose offset is within 4 standard
/// deviations of `d` (mm) and whose moment is within 3 samples (`dt`, s)
/// of `t` (s).
fn assert_step(
    m: Machine,
    step: &kinpost::diagnose::report::MeasurementFinding,
    d: [f64; 3],
    t: f64,
    dt: f64,
) {
    assert!(!step.machine_physics);
    for (c, key) in ["dx_mm", "dy_mm", "dz_mm"].iter().enumerate() {
        let (got, sd) = (step.parameters[*key], step.uncertainty[*key]);
        assert!(
            (got - d[c]).abs() <= 4.0 * sd + 1e-5,
            "{m:?} {d:?} {key}: {got} ± {sd}"
        );
    }
    assert!(
        (step.where_.t_s[0] - t).abs() <= 3.0 * dt,
        "{m:?} {d:?}: the step at {} s, made at {t} s",
        step.where_.t_s[0]
    );
}

/// A registration that steps part-way (a laser tracker that re-acquires
/// its target a few µm off after a beam break) is a measurement fault:
/// `registration_step`, its offset and time measured, no machine finding.
/// Before, 11 of these 12 recordings claimed machine physics (`error_motion`
/// of C or A, `zero_offset`, `thermal_drift`), the 12th a wander.
#[test]
fn a_registration_step_after_a_beam_break_is_not_machine_physics() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (7100..7106).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let rec = sc.simulate(&effects(&[]));
            let k = seed as usize % 3;
            // At a sample picked by its share of the recording, wherever
            // the blocks start (a step between block starts is what the
            // onsets at block starts could not place).
            let from = (rec.samples.len() as f64 * [0.3, 0.5, 0.7][k]) as usize + 1;
            let d = [[0.003, -0.002, 0.0], [0.0, 0.003, 0.002], [0.004, 0.0, 0.0]][k];
            let (rec, t) = stepped_off(rec, from, d);
            let dt = rec.samples[from].t - rec.samples[from - 1].t;
            let r = diagnose(&sc.chain, Some(&sc.errors), &rec, &DiagOptions::default()).unwrap();
            (d, t, dt, r)
        });
        for (d, t, dt, r) in &res {
            assert!(
                r.findings.is_empty(),
                "{m:?} {d:?}: {:?} ({})",
                machine_findings(r),
                r.verdict
            );
            let step = r
                .measurement
                .iter()
                .find(|f| f.effect == "registration_step")
                .unwrap_or_else(|| panic!("{m:?} {d:?}: {}", r.verdict));
            assert_step(m, step, *d, *t, *dt);
            assert!(r.verdict.starts_with("consistent with measurement noise once the measurement faults are removed (a step of the measured tip's registration"), "{}", r.verdict);
        }
    }
}

/// A backlash under a registration step is still found, the step beside
/// it as a measurement fault.
#[test]
fn a_backlash_is_found_under_a_registration_step() {
    for (m, axis) in [(Machine::Zhao, "X"), (Machine::Wang, "Y")] {
        let seeds: Vec<u64> = (7300..7303).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let rec = sc.simulate(&effects(&[&format!("backlash:{axis}=0.006")]));
            let from = rec.samples.len() / 2 + 3;
            let (rec, _) = stepped_off(rec, from, [0.003, -0.002, 0.0]);
            diagnose(&sc.chain, Some(&sc.errors), &rec, &DiagOptions::default()).unwrap()
        });
        for r in &res {
            assert_eq!(
                machine_findings(r),
                [format!("backlash {axis}")],
                "{m:?}: {}",
                r.verdict
            );
            assert!(
                r.measurement
                    .iter()
                    .any(|f| f.effect == "registration_step"),
                "{m:?}: {}",
                r.verdict
            );
        }
    }
}

/// Two beam breaks in one recording are two registration steps, told in
/// the order they happened. Before, one model held one step: 7 of these 12
/// recordings claimed machine physics for the other (`error_motion A`,
/// `zero_offset X` with `rotary_center_offset C`, `thermal_drift X` with
/// `squareness ZX`), and the others took it for a wander.
#[test]
fn two_beam_breaks_are_two_registration_steps() {
    for m in [Machine::Zhao, Machine::Wang] {
        let seeds: Vec<u64> = (7100..7106).collect();
        let res = par_map(&seeds, |&seed| {
            let sc = m.scenario(60, seed);
            let rec = sc.simulate(&effects(&[]));
            let n = rec.samples.len();
            let k = seed as usize % 3;
            let d1 = [[0.003, -0.002, 0.0], [0.0, 0.003, 0.002], [0.004, 0.0, 0.0]][k];
            let d2 = [[0.0, 0.003, 0.002], [0.004, 0.0, 0.0], [0.003, -0.002, 0.0]][k];
            let (from1, from2) = (n * 3 / 10, n * 13 / 20);
            let (rec, t1) = stepped_off(rec, from1, d1);
            let (rec, t2) = stepped_off(rec, from2, d2);
            let dt = rec.samples[from1].t - rec.samples[from1 - 1].t;
            let r = diagnose(&sc.chain, Some(&sc.errors), &rec, &DiagOptions::default()).unwrap();
            ([(d1, t1), (d2, t2)], dt, r)
        });
        for (made, dt, r) in &res {
            assert!(
                r.findings.is_empty(),
                "{m:?} {made:?}: {:?} ({})",
                machine_findings(r),
                r.verdict
            );
            let steps: Vec<_> = r
                .measurement
                .iter()
                .filter(|f| f.effect == "registration_step")
                .collect();
            assert_eq!(steps.len(), 2, "{m:?} {made:?}: {}", r.verdict);
            for (step, (d, t)) in steps.iter().zip(made) {
                assert_step(m, step, *d, *t, *dt);
            }
            assert!(
                r.verdict.starts_with("consistent with measurement noise once the measurement faults are removed (a step of the measured tip's registration"),
                "{}",
                r.verdict
            );
        }
    }
}
