//! Thermal drift over many seeds: the parameters of a drift found by
//! `diagnose`, their spread against the Cramér–Rao bound of the scenario,
//! and (with `BRUTE`) the global maximum of the likelihood by brute force.
//! Measurements behind `docs/diagnose.md` (figures and limits), run by hand:
//!
//! ```text
//! SWEEP="zhao:120:thermal_drift:Z=0.002,tau=90@block=30:1.2:100:40" \
//!     cargo test --release --test it diagnose_thermal::sweep -- --ignored --nocapture
//! ```
//!
//! `SWEEP` is machine:blocks:effect:effect RMS in σ:first seed:seeds.
//! `BRUTE=1` also maximises the profile likelihood over every block start
//! and 301 values of τ (`BRUTE=all`: every sample as onset), with the
//! onset-marginal and posterior-median alternatives; `TEXT=1` prints each
//! report. `clean_long_recordings` counts false alarms on clean recordings
//! of the length of the part-way drift test.

use crate::diagnose_support::*;
use kinpost::diagnose::prepare::{ModelMachine, prepare};
use kinpost::diagnose::{Effect, EffectSpec, Report};

const SIGMA: f64 = 0.001;

/// One run: truth, report and the Cramér–Rao standard deviations of
/// (amplitude, τ, t₀) relative to (a, τ, 1 s).
struct Run {
    truth: EffectSpec,
    t0_true: f64,
    report: Report,
    crb: [f64; 3],
}

fn run(m: Machine, blocks: usize, spec: &str, rms_sigma: f64, seed: u64) -> Run {
    let sc = m.scenario(blocks, seed);
    let truth = sc.calibrated(spec, rms_sigma * SIGMA).spec;
    let (rec, report) = sc.run(std::slice::from_ref(&truth));
    if std::env::var("TEXT").is_ok() {
        println!("{}", report.to_text());
    }
    // Cramér–Rao bound of (a, τ, t₀) for a drift along the axis's tip
    // direction, σ per coordinate.
    let machine = ModelMachine::new(&sc.chain, Some(&sc.errors)).unwrap();
    let prep = prepare(&machine, &rec).unwrap();
    let Effect::ThermalDrift {
        axis,
        amplitude_mm: a,
        tau_s: tau,
    } = &truth.effect
    else {
        panic!("not a drift")
    };
    let j = prep.names.iter().position(|n| n == axis).unwrap();
    let i0 = (0..prep.n)
        .find(|&i| truth.from_block.is_none_or(|b| prep.block[i].unwrap() >= b))
        .unwrap();
    let t0 = prep.t[i0];
    let mut f = nalgebra::Matrix3::<f64>::zeros();
    for i in i0..prep.n {
        let dt = prep.t[i] - t0;
        let e = (-dt / tau).exp();
        let g = [1.0 - e, -a * e * dt / (tau * tau), -a * e / tau];
        let jj = prep.jj(i, j);
        let w = jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2];
        for u in 0..3 {
            for v in 0..3 {
                f[(u, v)] += w * g[u] * g[v] / (SIGMA * SIGMA);
            }
        }
    }
    // From the start the onset is known (it is the start of the recording).
    let cov = if i0 == 0 {
        let f2 = f.fixed_view::<2, 2>(0, 0).into_owned();
        let c = f2.try_inverse().unwrap();
        let mut m = nalgebra::Matrix3::zeros();
        m.fixed_view_mut::<2, 2>(0, 0).copy_from(&c);
        m
    } else {
        f.try_inverse().unwrap()
    };
    if std::env::var("BRUTE").is_ok() {
        brute(&prep, j, *tau, i0, seed);
    }
    Run {
        t0_true: t0,
        crb: [
            cov[(0, 0)].sqrt() / a,
            cov[(1, 1)].sqrt() / tau,
            cov[(2, 2)].sqrt(),
        ],
        truth,
        report,
    }
}

/// Summary of a sweep.
#[derive(Debug)]
struct Sweep {
    tau_err: Vec<f64>,
    amp_err: Vec<f64>,
    onset_err_blocks: Vec<i64>,
    /// Reported τ standard deviation over |τ error| (z-scores).
    tau_z: Vec<f64>,
    wrong: usize,
    crb_tau: f64,
}

fn sweep(
    m: Machine,
    blocks: usize,
    spec: &str,
    rms_sigma: f64,
    seeds: std::ops::Range<u64>,
) -> Sweep {
    let seeds: Vec<u64> = seeds.collect();
    let runs = par_map(&seeds, |&seed| {
        (seed, run(m, blocks, spec, rms_sigma, seed))
    });
    let mut out = Sweep {
        tau_err: Vec::new(),
        amp_err: Vec::new(),
        onset_err_blocks: Vec::new(),
        tau_z: Vec::new(),
        wrong: 0,
        crb_tau: 0.0,
    };
    for (seed, r) in &runs {
        let Effect::ThermalDrift {
            amplitude_mm: a,
            tau_s: tau,
            ..
        } = &r.truth.effect
        else {
            unreachable!()
        };
        let f = r.report.findings.first();
        let found = f.and_then(|f| match &f.spec.effect {
            Effect::ThermalDrift {
                axis,
                amplitude_mm,
                tau_s,
            } if Some(axis.clone()) == r.truth.effect.axis_label() => {
                Some((*amplitude_mm, *tau_s, f))
            }
            _ => None,
        });
        out.crb_tau += r.crb[1] / runs.len() as f64;
        let Some((fa, ft, f)) = found else {
            out.wrong += 1;
            println!(
                "seed {seed}: first finding {:?}",
                f.map(|f| (&f.effect, &f.axis))
            );
            continue;
        };
        let te = (ft - tau) / tau;
        let ae = (fa - a) / a;
        let first_block = r.report.blocks[0].unwrap();
        let expected = r.truth.from_block.unwrap_or(first_block).max(first_block);
        let ob = f.where_.blocks[0].unwrap() as i64 - expected as i64;
        let sd_tau = f.uncertainty.get("tau_s").copied().unwrap_or(f64::NAN);
        out.tau_err.push(te);
        out.amp_err.push(ae);
        out.onset_err_blocks.push(ob);
        out.tau_z.push((ft - tau) / sd_tau);
        println!(
            "seed {seed}: {} samples, span {:.0} s, τ {ft:7.2} s (true {tau:.1}, err {:+6.1} %, ±{:.1} %, CRB {:.1} %), a err {:+6.1} % (CRB {:.1} %), onset t {:.1} s (true {:.1}, CRB ±{:.1} s) block err {ob:+}",
            r.report.samples,
            r.report.t_s[1] - r.report.t_s[0],
            te * 100.0,
            sd_tau / tau * 100.0,
            r.crb[1] * 100.0,
            ae * 100.0,
            r.crb[0] * 100.0,
            f.where_.t_s[0],
            r.t0_true,
            r.crb[2],
        );
    }
    out
}

fn stats(name: &str, v: &[f64]) -> String {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let rms = (v.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    let med = a.get(a.len() / 2).copied().unwrap_or(f64::NAN);
    let max = a.last().copied().unwrap_or(f64::NAN);
    format!(
        "{name}: mean {:+.1} %, RMS {:.1} %, median |e| {:.1} %, max |e| {:.1} %, > 20 %: {}",
        mean * 100.0,
        rms * 100.0,
        med * 100.0,
        max * 100.0,
        a.iter().filter(|x| **x > 0.2).count()
    )
}

#[test]
#[ignore]
fn thermal_sweep() {
    let arg = std::env::var("SWEEP")
        .unwrap_or("zhao:120:thermal_drift:Z=0.002,tau=90@block=30:1.2:100:30".into());
    let parts: Vec<&str> = arg.split(':').collect();
    let m = if parts[0] == "wang" {
        Machine::Wang
    } else {
        Machine::Zhao
    };
    let blocks: usize = parts[1].parse().unwrap();
    let spec = format!("{}:{}", parts[2], parts[3]);
    let rms_sigma: f64 = parts[4].parse().unwrap();
    let first: u64 = parts[5].parse().unwrap();
    let count: u64 = parts[6].parse().unwrap();
    let s = sweep(m, blocks, &spec, rms_sigma, first..first + count);
    println!("{arg}");
    println!("{}", stats("τ", &s.tau_err));
    println!("{}", stats("a", &s.amp_err));
    let z = &s.tau_z;
    let zr = (z.iter().map(|x| x * x).sum::<f64>() / z.len().max(1) as f64).sqrt();
    println!(
        "τ CRB (mean) {:.1} %; RMS of τ error / reported sd {:.2}; onset block errors {:?}; wrong first finding {}",
        s.crb_tau * 100.0,
        zr,
        s.onset_err_blocks,
        s.wrong
    );
}

/// Global maximum of the profile over (onset, τ) by brute force: every
/// block start (or every sample with BRUTE=all) and 300 values of τ.
fn brute(
    prep: &kinpost::diagnose::prepare::Prepared,
    j: usize,
    tau_true: f64,
    i0: usize,
    seed: u64,
) {
    use kinpost::diagnose::fit::{Cols, Family, Selected, base_columns, scan};
    let sel = Selected::new(
        prep,
        Cols {
            k: 0,
            data: Vec::new(),
        },
    );
    let fam = Family::ThermalDrift(j);
    let all = std::env::var("BRUTE").unwrap() == "all";
    let onsets: Vec<usize> = if all {
        (0..prep.n).collect()
    } else {
        prep.onsets.clone()
    };
    let t_ref = prep.t[0];
    let mut best = (0.0, 0.0, 0usize);
    let mut at_truth = 0.0;
    // Log-marginal over the onset (uniform over block starts) per τ.
    let mut marg: Vec<(f64, f64)> = Vec::new();
    let min_after = (prep.n / 50).max(20);
    for g in 0..=300 {
        let tau = tau_true * (3f64).powf(-1.0 + 2.0 * g as f64 / 300.0);
        let base = base_columns(prep, fam, tau);
        let gf = |s: usize| vec![1.0, -((prep.t[s] - t_ref) / tau).exp()];
        let prof = scan(prep, &sel, &base, &onsets, Some(&gf), min_after);
        let mx = prof.iter().cloned().fold(0.0, f64::max) / (2.0 * 1e-6);
        let lm = mx + prof.iter().map(|d| (d / 2e-6 - mx).exp()).sum::<f64>().ln();
        marg.push((tau, lm));
        for (k, &d) in prof.iter().enumerate() {
            if d > best.0 {
                best = (d, tau, onsets[k]);
            }
        }
        if g == 150 {
            let k = onsets.iter().position(|&o| o == i0).unwrap();
            at_truth = prof[k];
        }
    }
    let s2 = 1e-6;
    let mm = marg.iter().cloned().fold(
        (0.0, f64::NEG_INFINITY),
        |a, b| if b.1 > a.1 { b } else { a },
    );
    // Posterior median of ln τ (flat prior in ln τ on the grid).
    let w: Vec<f64> = marg.iter().map(|m| (m.1 - mm.1).exp()).collect();
    let tot: f64 = w.iter().sum();
    let mut acc = 0.0;
    let mut med = 0.0;
    for (k, x) in w.iter().enumerate() {
        acc += x;
        if acc >= tot / 2.0 {
            med = marg[k].0;
            break;
        }
    }
    println!(
        "seed {seed}: marginal τ {:.2} (err {:+.1} %), posterior median τ {:.2} (err {:+.1} %)",
        mm.0,
        (mm.0 - tau_true) / tau_true * 100.0,
        med,
        (med - tau_true) / tau_true * 100.0
    );
    println!(
        "seed {seed}: brute MLE τ {:.2} (err {:+.1} %), onset t {:.1} (true {:.1}); Δχ² MLE − truth {:.1}",
        best.1,
        (best.1 - tau_true) / tau_true * 100.0,
        prep.t[best.2],
        prep.t[i0],
        (best.0 - at_truth) / s2
    );
}

/// False alarms on long clean recordings (the length of the part-way drift
/// test): `CLEAN=20 cargo test --release --test it diagnose_thermal::clean -- --ignored --nocapture`.
#[test]
#[ignore]
fn clean_long_recordings() {
    let n: u64 = std::env::var("CLEAN")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let seeds: Vec<u64> = (2000..2000 + n).collect();
    for (m, blocks) in [(Machine::Zhao, 400), (Machine::Wang, 280)] {
        let res = par_map(&seeds, |&seed| {
            let (_, r) = m.scenario(blocks, seed).run(&[]);
            let best = r.candidates.first().map_or(f64::NAN, |c| c.delta_bic);
            (seed, r.findings.len(), best)
        });
        let alarms = res.iter().filter(|r| r.1 > 0).count();
        let worst = res.iter().map(|r| r.2).fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{m:?} {blocks} blocks: {alarms} false alarms in {n}; largest first-round ΔBIC {worst:.1}"
        );
    }
}
