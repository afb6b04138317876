//! Acceptance tests of `kinpost diagnose` (issue 5): on simulated
//! recordings of both seed machines, each catalogue effect hidden under
//! measurement noise (σ = 1 µm per coordinate; the effect's 3-D RMS
//! 1.2 σ, 1.4 σ for the part-way thermal drift, which is tested over 24
//! seeds in longer recordings; a drift from the start also runs in a
//! longer recording, [`LONG_CASES`]) and under the fixture geometric errors
//! (larger than the effect), some starting part-way. For each: the right
//! effect and axis ranked first, the parameters within 20 %, the held-out
//! RMS reduced, and the start found within 10 blocks.

use crate::diagnose_support::*;
use kinpost::diagnose::{Effect, EffectSpec, Report};

const SIGMA: f64 = 0.001;
const TARGET_RMS: f64 = 1.2 * SIGMA;

/// One case's outcome, printed as a table row.
struct Outcome {
    line: String,
    failures: Vec<String>,
    /// Largest relative parameter error of the first finding, when it is
    /// the injected effect.
    param_error: Option<f64>,
    /// For a thermal drift found as such.
    tau: Option<Drift>,
}

/// τ of a thermal drift found, its truth and reported standard deviation,
/// and the amplitude's relative error.
#[derive(Debug, Clone, Copy)]
struct Drift {
    tau: f64,
    tau_true: f64,
    tau_sd: f64,
    amplitude_error: f64,
}

impl Drift {
    /// τ error in reported standard deviations.
    fn z(&self) -> f64 {
        (self.tau - self.tau_true) / self.tau_sd
    }
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

/// Largest relative parameter error (phase in degrees / 360·100 %, a
/// rotary-centre offset as the vector error over its length).
fn parameter_error(found: &Effect, truth: &Effect) -> Option<f64> {
    use Effect::*;
    Some(match (found, truth) {
        (Backlash { value: a, .. }, Backlash { value: b, .. })
        | (ZeroOffset { value: a, .. }, ZeroOffset { value: b, .. }) => rel(*a, *b),
        (ServoLag { tau_s: a, .. }, ServoLag { tau_s: b, .. }) => rel(*a, *b),
        (
            ThermalDrift {
                amplitude_mm: a,
                tau_s: ta,
                ..
            },
            ThermalDrift {
                amplitude_mm: b,
                tau_s: tb,
                ..
            },
        ) => rel(*a, *b).max(rel(*ta, *tb)),
        (Scale { ppm: a, .. }, Scale { ppm: b, .. }) => rel(*a, *b),
        (Squareness { angle_urad: a, .. }, Squareness { angle_urad: b, .. }) => rel(*a, *b),
        (
            Cyclic {
                amplitude: a,
                period: pa,
                phase_deg: fa,
                ..
            },
            Cyclic {
                amplitude: b,
                period: pb,
                phase_deg: fb,
                ..
            },
        ) => {
            let dphi = ((fa - fb + 540.0).rem_euclid(360.0) - 180.0).abs();
            rel(*a, *b).max(rel(*pa, *pb)).max(dphi / 360.0)
        }
        (
            RotaryCenterOffset {
                offset_mm: a, axis, ..
            },
            RotaryCenterOffset { offset_mm: b, .. },
        ) => {
            // Only the components perpendicular to the axis act.
            let keep = |v: &[f64; 3]| -> [f64; 3] {
                let mut w = *v;
                match axis.as_str() {
                    "A" => w[0] = 0.0,
                    "B" => w[1] = 0.0,
                    _ => w[2] = 0.0,
                }
                w
            };
            let (a, b) = (keep(a), keep(b));
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            d / (b[0].powi(2) + b[1].powi(2) + b[2].powi(2)).sqrt()
        }
        (PivotLength { delta_mm: a }, PivotLength { delta_mm: b }) => rel(*a, *b),
        _ => return None,
    })
}

/// Cases that need a longer recording than the machine's default, with
/// their program length (blocks).
///
/// A thermal drift from the start needs, for τ within 20 % in practically
/// every recording, ρ√N ≥ 95 (N ≥ 6300 samples at 1.2 σ) and at least 4 τ
/// of recording (`docs/diagnose.md`, limits). The default wang program
/// (100 blocks, 3300–4700 samples, 330–470 s) covers only 2 τ of a 200 s
/// drift: τ missed 20 % on 5 of 40 seeds. With 280 blocks, the length of
/// the part-way test (10 000–12 600 samples, 1000–1260 s, 5–6 τ; CRB of τ
/// 4.6 %), every case of seeds 100–139 and 200–399 meets the acceptance
/// criteria (largest τ error 11.9 % and 15.6 %).
///
/// On zhao the 120-block program (2900–4000 samples, ρ√N ≈ 71) held a
/// 60 s drift with τ within 20 % on 40 of 40 seeds (100–139) but not on 6
/// of 200 (200–399, up to 26 %). A 150 s drift in 250 blocks
/// (6700–8300 samples, 670–830 s, 4.5–5.5 τ; ρ√N ≈ 103, CRB of τ 5.6 %)
/// meets every criterion on seeds 100–139 and 200–399 (largest τ error
/// 13.3 % and 14.5 %).
const LONG_CASES: &[(Machine, &str, usize)] = &[
    (Machine::Zhao, "thermal_drift:Z=0.002,tau=150", 250),
    (Machine::Wang, "thermal_drift:X=0.002,tau=200", 280),
];

/// Program length (blocks) of a case: as in [`LONG_CASES`], else 120 on
/// zhao and 100 on wang (3000–4500 samples).
fn case_blocks(m: Machine, spec: &str) -> usize {
    match LONG_CASES.iter().find(|c| c.0 == m && c.1 == spec) {
        Some(c) => c.2,
        None => match m {
            Machine::Zhao => 120,
            Machine::Wang => 100,
        },
    }
}

fn run_case(m: Machine, spec: &str, seed: u64) -> Outcome {
    run_sized(m, case_blocks(m, spec), spec, TARGET_RMS, seed)
}

/// A case with a program of `blocks` blocks and the effect scaled to the
/// 3-D tip RMS `target` (mm).
fn run_sized(m: Machine, blocks: usize, spec: &str, target: f64, seed: u64) -> Outcome {
    let sc = m.scenario(blocks, seed);
    let Calibrated {
        spec: truth,
        effect_rms: eff_rms,
        geometric_rms: geo_rms,
    } = sc.calibrated(spec, target);
    let (_, report) = sc.run(std::slice::from_ref(&truth));
    check(m, spec, &truth, eff_rms, geo_rms, &report)
}

fn check(
    m: Machine,
    spec: &str,
    truth: &EffectSpec,
    eff_rms: f64,
    geo_rms: f64,
    r: &Report,
) -> Outcome {
    let mut failures = Vec::new();
    if eff_rms > 1.5 * SIGMA {
        failures.push(format!("effect RMS {eff_rms} above 1.5 σ"));
    }
    if geo_rms <= eff_rms {
        failures.push(format!(
            "geometric errors {geo_rms} not larger than the effect {eff_rms}"
        ));
    }
    let Some(f) = r.findings.first() else {
        return Outcome {
            line: format!("{m:?} {spec}: no finding"),
            failures: vec!["no finding".into()],
            param_error: None,
            tau: None,
        };
    };
    let tau = match (&f.spec.effect, &truth.effect) {
        (
            Effect::ThermalDrift {
                tau_s,
                amplitude_mm,
                ..
            },
            Effect::ThermalDrift {
                tau_s: tau_true,
                amplitude_mm: a_true,
                ..
            },
        ) => Some(Drift {
            tau: *tau_s,
            tau_true: *tau_true,
            tau_sd: f.uncertainty.get("tau_s").copied().unwrap_or(f64::NAN),
            amplitude_error: rel(*amplitude_mm, *a_true),
        }),
        _ => None,
    };
    if f.effect != truth.effect.kind().name() || f.axis != truth.effect.axis_label() {
        failures.push(format!(
            "first finding {} {:?}, expected {} {:?}",
            f.effect,
            f.axis,
            truth.effect.kind().name(),
            truth.effect.axis_label()
        ));
    }
    let perr = parameter_error(&f.spec.effect, &truth.effect);
    match perr {
        Some(e) if e <= 0.2 => {}
        _ => failures.push(format!(
            "parameters {:?} vs truth {:?}",
            f.spec.effect, truth.effect
        )),
    }
    if r.holdout_rms_after_mm >= r.holdout_rms_before_mm {
        failures.push("held-out RMS not reduced".into());
    }
    let first_block = r.blocks[0].unwrap();
    let expected_start = truth.from_block.unwrap_or(first_block).max(first_block);
    let found_start = f.where_.blocks[0].unwrap();
    let onset_err = found_start as i64 - expected_start as i64;
    if onset_err.abs() > 10 {
        failures.push(format!(
            "start block {found_start}, expected {expected_start}"
        ));
    }
    Outcome {
        line: format!(
            "{:<5} {:<45} rank1 {:<22} param err {:>5.1} %  holdout {:.3}→{:.3} µm  start {:>3} (err {:+})  effect {:.2} µm, geometric {:.2} µm, runner-up {}",
            format!("{m:?}"),
            spec,
            format!("{} {}", f.effect, f.axis.clone().unwrap_or_default()),
            perr.unwrap_or(f64::NAN) * 100.0,
            r.holdout_rms_before_mm * 1e3,
            r.holdout_rms_after_mm * 1e3,
            found_start,
            onset_err,
            eff_rms * 1e3,
            geo_rms * 1e3,
            f.runner_up
                .as_ref()
                .map(|u| format!("{} {}", u.effect, u.axis.clone().unwrap_or_default()))
                .unwrap_or_default()
        ),
        failures,
        param_error: perr,
        tau,
    }
}

/// Runs `cases` on two threads and asserts that every one meets the
/// criteria. Case `i` of `n` has the seed 11 + (i mod ⌈n/2⌉): seeds 11–15
/// for ten cases, each used on both halves of the list.
fn run_all(cases: &[(Machine, &str)]) {
    let half = cases.len().div_ceil(2);
    let seeded: Vec<(Machine, &str, u64)> = cases
        .iter()
        .enumerate()
        .map(|(i, &(m, spec))| (m, spec, 11 + (i % half) as u64))
        .collect();
    let outcomes = par_map(&seeded, |&(m, spec, seed)| run_case(m, spec, seed));
    let mut bad = Vec::new();
    for o in &outcomes {
        println!("{}", o.line);
        if !o.failures.is_empty() {
            bad.push(format!("{}: {}", o.line, o.failures.join("; ")));
        }
    }
    assert!(bad.is_empty(), "failed cases:\n{}", bad.join("\n"));
}

/// The catalogue on zhao2022-xzbc, 120-block programs (seeds 11–15),
/// except the thermal drift from the start, which runs 250 blocks (see
/// [`LONG_CASES`]): a 60 s drift in 120 blocks missed 20 % in τ on 6 of 200
/// seeds; the 150 s drift in 250 blocks meets every criterion in
/// `robustness_sweep` on 40 of 40 seeds (100–139, largest τ error 13.3 %)
/// and 200 of 200 (200–399, largest 14.5 %).
#[test]
fn every_effect_is_found_on_zhao2022_xzbc() {
    run_all(&[
        (Machine::Zhao, "backlash:X=0.003"),
        (Machine::Zhao, "backlash:B=0.003@block=40"),
        (Machine::Zhao, "servo_lag:Z=0.0001"),
        (Machine::Zhao, "thermal_drift:Z=0.002,tau=150"),
        (Machine::Zhao, "scale:X=20"),
        (Machine::Zhao, "squareness:XZ=10"),
        (Machine::Zhao, "cyclic:X=0.002,period=25,phase=30"),
        (Machine::Zhao, "zero_offset:Z=0.0015@block=60"),
        (Machine::Zhao, "rotary_center_offset:C=0.0012,0.0016,0"),
        (Machine::Zhao, "pivot_length:0.0015"),
    ]);
}

/// The catalogue on wang2023-xyzab, 100-block programs (seeds 11–15),
/// except the thermal drift from the start, which runs 280 blocks (see
/// [`LONG_CASES`]): τ in the 100-block recording (2 τ) missed 20 % on 5 of
/// 40 seeds; in 280 blocks `robustness_sweep` finds every criterion met on
/// 40 of 40 seeds (100–139, largest τ error 11.9 %) and 200 of 200
/// (200–399, largest 15.6 %).
#[test]
fn every_effect_is_found_on_wang2023_xyzab() {
    run_all(&[
        (Machine::Wang, "backlash:Y=0.003@block=50"),
        (Machine::Wang, "servo_lag:X=0.00004"),
        (Machine::Wang, "thermal_drift:X=0.002,tau=200"),
        (Machine::Wang, "scale:Z=8"),
        (Machine::Wang, "squareness:XY=8"),
        (
            Machine::Wang,
            "cyclic:Y=0.0015,period=40,phase=-45@block=20",
        ),
        (Machine::Wang, "zero_offset:X=0.0015"),
        (Machine::Wang, "rotary_center_offset:A=0,0.0012,0.0016"),
        (
            Machine::Wang,
            "rotary_center_offset:B=0.0015,0,0.001@block=40",
        ),
        (Machine::Wang, "pivot_length:0.0015@block=50"),
    ]);
}

/// Thermal drift that starts part-way: onset, τ and amplitude are traded
/// off along a ridge of the likelihood, so τ needs more data than the other
/// effects. With 11 000–12 500 samples (a 20-minute recording, about 6τ
/// after the onset) and the effect at 1.4 σ, the Cramér–Rao bound of τ is
/// about 5.5 % and the diagnosis reaches it; every case of 12 seeds on each
/// machine must meet the acceptance criteria (τ and amplitude within
/// 20 %), and τ's reported uncertainty (which includes the onset's) must
/// cover its error (see `docs/diagnose.md`, limits).
#[test]
fn thermal_drift_starting_part_way() {
    let cases: Vec<(Machine, usize, &str, u64)> = (0..12u64)
        .flat_map(|k| {
            [
                (
                    Machine::Zhao,
                    400,
                    "thermal_drift:Z=0.002,tau=200@block=40",
                    300 + k,
                ),
                (
                    Machine::Wang,
                    280,
                    "thermal_drift:X=0.002,tau=200@block=30",
                    300 + k,
                ),
            ]
        })
        .collect();
    let outcomes = par_map(&cases, |&(m, b, spec, seed)| {
        run_sized(m, b, spec, 1.4 * SIGMA, seed)
    });
    let mut bad = Vec::new();
    let mut z2 = 0.0;
    let mut worst: f64 = 0.0;
    for o in &outcomes {
        let z = o.tau.map_or(f64::NAN, |d| d.z());
        println!("{}  τ error {z:+.1} σ", o.line);
        if let Some(d) = o.tau {
            worst = worst.max(rel(d.tau, d.tau_true));
        }
        z2 += z * z;
        if !o.failures.is_empty() {
            bad.push(format!("{}: {}", o.line, o.failures.join("; ")));
        }
        if z.is_nan() || z.abs() > 3.5 {
            bad.push(format!("{}: τ error {z:.1} reported σ", o.line));
        }
    }
    let z_rms = (z2 / outcomes.len() as f64).sqrt();
    println!(
        "{} cases: largest τ error {:.1} %, RMS of τ error / reported σ {z_rms:.2}",
        outcomes.len(),
        worst * 100.0
    );
    assert!(bad.is_empty(), "failed cases:\n{}", bad.join("\n"));
    assert!(
        (0.5..1.6).contains(&z_rms),
        "τ uncertainty miscalibrated: {z_rms}"
    );
}

/// The same drift in a recording too short for τ (325 s, 2.7 τ after the
/// onset, 1.2 σ): the Cramér–Rao bound of τ is 12–13 % and about one seed
/// in five misses 20 %. The effect, axis, onset and amplitude are still
/// found, and τ's reported uncertainty is honest about it.
#[test]
fn thermal_drift_starting_part_way_in_a_short_recording() {
    let o = run_case(Machine::Zhao, "thermal_drift:Z=0.002,tau=90@block=30", 14);
    let d = o.tau.expect("a thermal drift");
    println!("{}  τ error {:+.1} σ", o.line, d.z());
    let rest: Vec<&String> = o
        .failures
        .iter()
        .filter(|f| !f.starts_with("parameters"))
        .collect();
    assert!(rest.is_empty(), "{}: {:?}", o.line, rest);
    assert!(d.amplitude_error <= 0.2, "{}", o.line);
    assert!(d.z().abs() <= 3.0, "{}", o.line);
}

/// Robustness sweep over seeds, run by hand:
///
/// ```text
/// ROBUST="wang:scale:Z=8" SEEDS=100:40 \
///     cargo test --release --test it diagnose_effects::robustness_sweep -- --ignored --nocapture
/// ```
///
/// `ROBUST` is machine:effect as in the tables above, `SEEDS` first
/// seed:count (default 100:12), `BLOCKS` the program length (default that
/// of the case, [`case_blocks`]). Prints each seed's row and failures, the
/// largest parameter error and, for a thermal drift, the largest τ error.
#[test]
#[ignore]
fn robustness_sweep() {
    let spec =
        std::env::var("ROBUST").unwrap_or("zhao:thermal_drift:Z=0.002,tau=90@block=30".into());
    let (m, s) = spec.split_once(':').unwrap();
    let m = if m == "wang" {
        Machine::Wang
    } else {
        Machine::Zhao
    };
    let seeds = std::env::var("SEEDS").unwrap_or("100:12".into());
    let (first, count) = seeds.split_once(':').expect("SEEDS=first:count");
    let first: u64 = first.parse().unwrap();
    let count: u64 = count.parse().unwrap();
    let seeds: Vec<u64> = (first..first + count).collect();
    let blocks = std::env::var("BLOCKS").map_or(case_blocks(m, s), |b| b.parse().unwrap());
    let outcomes = par_map(&seeds, |&seed| {
        (seed, run_sized(m, blocks, s, TARGET_RMS, seed))
    });
    let mut fails = 0;
    let mut worst_param: f64 = 0.0;
    let mut worst_tau: Option<(f64, u64)> = None;
    for (seed, o) in &outcomes {
        println!("seed {seed}: {} {}", o.line, o.failures.join("; "));
        fails += usize::from(!o.failures.is_empty());
        worst_param = worst_param.max(o.param_error.unwrap_or(f64::INFINITY));
        if let Some(d) = o.tau {
            let e = rel(d.tau, d.tau_true);
            if worst_tau.is_none_or(|(w, _)| e > w) {
                worst_tau = Some((e, *seed));
            }
        }
    }
    println!(
        "{spec}, {blocks} blocks, seeds {first}..{}: failures {fails}/{count}; largest parameter error {:.1} %{}",
        first + count - 1,
        worst_param * 100.0,
        worst_tau
            .map(|(e, seed)| format!("; largest τ error {:.1} % (seed {seed})", e * 100.0))
            .unwrap_or_default()
    );
}
