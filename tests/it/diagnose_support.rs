//! Shared helpers of the diagnose tests: the two seed machines built in
//! code, their fixture error models, exercise programs and effect sizes.
#![allow(dead_code)]

use kinpost::diagnose::programs::{Travel, random_moves};
use kinpost::diagnose::{
    DiagOptions, EffectSpec, Recording, Report, SimOptions, Waypoint, diagnose,
    evaluate_trajectory, parse_effect_spec, sample_waypoints, simulate,
};
use kinpost::geometric::ErrorModel;
use kinpost::machine::Chain;
use nalgebra::Vector3;

pub use crate::util::{wang, zhao};

/// Which seed machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Machine {
    /// zhao2022-xzbc.
    Zhao,
    /// wang2023-xyzab.
    Wang,
}

impl Machine {
    /// Its chain.
    pub fn chain(self) -> Chain {
        match self {
            Machine::Zhao => zhao(),
            Machine::Wang => wang(),
        }
    }

    /// Its fixture error model (fitted from the committed tables).
    pub fn errors(self) -> ErrorModel {
        let path = match self {
            Machine::Zhao => "fixtures/errors/zhao2022-xzbc.csv",
            Machine::Wang => "fixtures/errors/wang2023-xyzab.csv",
        };
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
        ErrorModel::load(&p).expect("fixture error model")
    }

    /// An exercise program of `blocks` random moves (chain order).
    pub fn program(self, blocks: usize, seed: u64) -> Vec<Waypoint> {
        let t = |lo, hi| Travel { lo, hi };
        match self {
            // C X Z B
            Machine::Zhao => random_moves(
                &[
                    t(-120.0, 120.0),
                    t(-80.0, 80.0),
                    t(-80.0, 80.0),
                    t(-60.0, 60.0),
                ],
                blocks,
                (600.0, 6000.0),
                0.7,
                seed,
            ),
            // A X Y Z B
            Machine::Wang => random_moves(
                &[
                    t(-90.0, 90.0),
                    t(100.0, 400.0),
                    t(-150.0, 150.0),
                    t(-300.0, -50.0),
                    t(-45.0, 45.0),
                ],
                blocks,
                (600.0, 6000.0),
                0.6,
                seed,
            ),
        }
    }
}

/// One seed's setup on a seed machine: its chain, fixture error model,
/// exercise program and simulation options.
pub struct Scenario {
    /// The machine's chain.
    pub chain: Chain,
    /// Its fixture error model.
    pub errors: ErrorModel,
    /// The exercise program.
    pub program: Vec<Waypoint>,
    /// The simulation options of the seed ([`sim_options`]).
    pub opts: SimOptions,
}

impl Machine {
    /// The machine with a program of `blocks` random moves and the
    /// simulation options of `seed` (which also seeds the program).
    pub fn scenario(self, blocks: usize, seed: u64) -> Scenario {
        Scenario {
            chain: self.chain(),
            errors: self.errors(),
            program: self.program(blocks, seed),
            opts: sim_options(seed),
        }
    }
}

impl Scenario {
    /// `spec` calibrated to the 3-D tip RMS `target` (mm) on this program,
    /// as [`calibrated_case`].
    pub fn calibrated(&self, spec: &str, target: f64) -> Calibrated {
        calibrated_case(
            &self.chain,
            &self.errors,
            &self.program,
            spec,
            target,
            &self.opts,
        )
    }

    /// A simulated recording of the program with `effects` injected.
    pub fn simulate(&self, effects: &[EffectSpec]) -> Recording {
        simulate(
            &self.chain,
            Some(&self.errors),
            &self.program,
            effects,
            &self.opts,
        )
        .unwrap()
    }

    /// The diagnosis of `rec` against the chain and the fixture error model,
    /// with the default options.
    pub fn diagnose(&self, rec: &Recording) -> Report {
        diagnose(
            &self.chain,
            Some(&self.errors),
            rec,
            &DiagOptions::default(),
        )
        .unwrap()
    }

    /// [`Scenario::simulate`], then [`Scenario::diagnose`].
    pub fn run(&self, effects: &[EffectSpec]) -> (Recording, Report) {
        let rec = self.simulate(effects);
        let report = self.diagnose(&rec);
        (rec, report)
    }
}

/// The effects of the `--inject` specs `specs`.
pub fn effects(specs: &[&str]) -> Vec<EffectSpec> {
    specs
        .iter()
        .map(|s| parse_effect_spec(s).unwrap())
        .collect()
}

/// The top-level fields of the report's JSON that `formats.md` §3 names.
pub const FORMATS_FIELDS: [&str; 8] = [
    "samples",
    "noise_floor_mm",
    "rms_before_mm",
    "rms_after_mm",
    "holdout_rms_before_mm",
    "holdout_rms_after_mm",
    "findings",
    "verdict",
];

/// RMS (3-D norm) of the differences between two series of tips.
pub fn rms_between(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum();
    (s / a.len() as f64).sqrt()
}

/// Default simulation options for the tests: σ = 1 µm, 0.1 s samples.
pub fn sim_options(seed: u64) -> SimOptions {
    SimOptions {
        noise_mm: 0.001,
        seed,
        sample_interval_s: 0.1,
        accel_mm_s2: Some(300.0),
        ..SimOptions::default()
    }
}

/// RMS (3-D norm, over all samples) of the tip displacement that `effects`
/// cause on the machine with `errors`, along `program`.
pub fn effect_rms(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    program: &[Waypoint],
    effects: &[EffectSpec],
    opts: &SimOptions,
) -> f64 {
    let traj = sample_waypoints(chain, program, opts.sample_interval_s, opts.accel_mm_s2).unwrap();
    let a = evaluate_trajectory(chain, errors, &[], &traj).unwrap();
    let b = evaluate_trajectory(chain, errors, effects, &traj).unwrap();
    rms_between(&a, &b)
}

/// RMS (3-D norm) of the tip displacement of the geometric errors (model
/// versus nominal chain) along `program`.
pub fn geometric_rms(
    chain: &Chain,
    errors: &ErrorModel,
    program: &[Waypoint],
    opts: &SimOptions,
) -> f64 {
    let traj = sample_waypoints(chain, program, opts.sample_interval_s, opts.accel_mm_s2).unwrap();
    let a = evaluate_trajectory(chain, None, &[], &traj).unwrap();
    let b = evaluate_trajectory(chain, Some(errors), &[], &traj).unwrap();
    rms_between(&a, &b)
}

/// Multiplies the amplitude-like parameter of an effect by `k` (the
/// time constant, period and phase stay).
pub fn scale_effect(e: &mut kinpost::diagnose::Effect, k: f64) {
    use kinpost::diagnose::Effect::*;
    match e {
        Backlash { value, .. } | ZeroOffset { value, .. } => *value *= k,
        ServoLag { tau_s, .. } => *tau_s *= k,
        ThermalDrift { amplitude_mm, .. } => *amplitude_mm *= k,
        Scale { ppm, .. } => *ppm *= k,
        Squareness { angle_urad, .. } => *angle_urad *= k,
        Cyclic { amplitude, .. } | Vibration { amplitude, .. } => *amplitude *= k,
        RotaryCenterOffset { offset_mm, .. } | Registration { offset_mm } => {
            offset_mm.iter_mut().for_each(|v| *v *= k)
        }
        PivotLength { delta_mm } => *delta_mm *= k,
        Wander { coef_mm, .. } => coef_mm.iter_mut().flatten().for_each(|v| *v *= k),
        ErrorMotion { terms, .. } => terms.iter_mut().for_each(|t| {
            t.2 *= k;
            t.3 *= k;
        }),
    }
}

/// An effect calibrated to a tip RMS, with the figures the acceptance
/// checks need.
pub struct Calibrated {
    /// The effect, its amplitude scaled.
    pub spec: EffectSpec,
    /// 3-D tip RMS of the scaled effect (as [`effect_rms`]), mm.
    pub effect_rms: f64,
    /// 3-D tip RMS of the geometric errors (as [`geometric_rms`]), mm.
    pub geometric_rms: f64,
}

/// `spec` with its amplitude scaled so that the effect's tip displacement
/// has the 3-D RMS `target` (mm) along `program`, with [`effect_rms`] of
/// the result and [`geometric_rms`], the trajectory sampled and the model
/// evaluated once (four chain evaluations along the program).
pub fn calibrated_case(
    chain: &Chain,
    errors: &ErrorModel,
    program: &[Waypoint],
    spec: &str,
    target: f64,
    opts: &SimOptions,
) -> Calibrated {
    let traj = sample_waypoints(chain, program, opts.sample_interval_s, opts.accel_mm_s2).unwrap();
    let model = evaluate_trajectory(chain, Some(errors), &[], &traj).unwrap();
    let rms_against = |effects: &[EffectSpec]| {
        rms_between(
            &model,
            &evaluate_trajectory(chain, Some(errors), effects, &traj).unwrap(),
        )
    };
    let mut s = parse_effect_spec(spec).unwrap();
    let r = rms_against(std::slice::from_ref(&s));
    assert!(r > 0.0, "{spec} has no effect on this program");
    scale_effect(&mut s.effect, target / r);
    let effect_rms = rms_against(std::slice::from_ref(&s));
    let nominal = evaluate_trajectory(chain, None, &[], &traj).unwrap();
    Calibrated {
        spec: s,
        effect_rms,
        geometric_rms: rms_between(&nominal, &model),
    }
}

/// `f` applied to every item on two threads (items alternate between them),
/// the results in the order of `items`.
pub fn par_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let f = &f;
    let mut halves: Vec<Vec<R>> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..2usize)
            .map(|half| s.spawn(move || items.iter().skip(half).step_by(2).map(f).collect()))
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let odd = halves.pop().unwrap_or_default();
    let even = halves.pop().unwrap_or_default();
    let mut out = Vec::with_capacity(items.len());
    let mut odd = odd.into_iter();
    for r in even {
        out.push(r);
        out.extend(odd.next());
    }
    out
}

/// Runs `run` for each seed in parallel and asserts that at most 10 % of
/// them fail; prints the failures (a failure is `run`'s text).
pub fn sweep(
    label: &str,
    m: Machine,
    seeds: std::ops::Range<u64>,
    run: impl Fn(u64) -> Option<String> + Sync,
) {
    let seeds: Vec<u64> = seeds.collect();
    let fails: Vec<String> = par_map(&seeds, |s| run(*s)).into_iter().flatten().collect();
    println!(
        "{label} on {m:?}: {} of {} failed {fails:?}",
        fails.len(),
        seeds.len()
    );
    assert!(
        fails.len() as f64 <= 0.1 * seeds.len() as f64,
        "{label} on {m:?}: {fails:?}"
    );
}
