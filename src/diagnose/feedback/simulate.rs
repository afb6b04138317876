//! Simulated joint-feedback traces with joint-level effects and faults.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::central_velocities;
use super::super::rng::Rng;
use super::super::simulate::{TrajPoint, TrajectoryWalker, Waypoint, sample_waypoints};
use super::FeedbackRecording;
use crate::error::Result;
use crate::geometric::effects::{BoundEffect, EffectSpec};
use crate::machine::chain::{Chain, JointKind};

/// Options of [`simulate_feedback`].
#[derive(Debug, Clone, PartialEq)]
pub struct FeedbackSimOptions {
    /// Encoder / scale noise of each axis, mm (deg on rotary axes).
    pub noise: f64,
    /// Seed.
    pub seed: u64,
    /// Time between samples, s.
    pub sample_interval_s: f64,
    /// Acceleration limit along the path, mm/s².
    pub accel_mm_s2: Option<f64>,
    /// Clock offset, s: the sample stamped t shows the axes at t − offset.
    pub time_offset_s: f64,
    /// Fraction of samples with a gross fault (0.01 … 0.1 mm or deg) on
    /// one axis.
    pub outlier_fraction: f64,
    /// Rounding step of every written value (0: none).
    pub quantum: f64,
}

impl Default for FeedbackSimOptions {
    fn default() -> Self {
        FeedbackSimOptions {
            noise: 0.0005,
            seed: 1,
            sample_interval_s: 0.01,
            accel_mm_s2: Some(300.0),
            time_offset_s: 0.0,
            outlier_fraction: 0.0,
            quantum: 0.0,
        }
    }
}

/// Simulates a joint-feedback trace of every joint of `chain` along
/// `waypoints`: the command sampled, each joint's feedback the command
/// plus the joint-level `effects` (backlash, servo lag, thermal drift,
/// scale, cyclic, zero offset, vibration of that joint), noise, faults and
/// rounding. Deterministic for a seed.
pub fn simulate_feedback(
    chain: &Chain,
    waypoints: &[Waypoint],
    effects: &[EffectSpec],
    opts: &FeedbackSimOptions,
) -> Result<FeedbackRecording> {
    let n = chain.dof();
    let traj = sample_waypoints(chain, waypoints, opts.sample_interval_s, opts.accel_mm_s2)?;
    let machine: Vec<TrajPoint> = if opts.time_offset_s != 0.0 {
        let times: Vec<f64> = traj.iter().map(|p| p.t - opts.time_offset_s).collect();
        let mut m = sample_at(chain, waypoints, opts, &times)?;
        central_velocities(&mut m);
        m
    } else {
        traj.clone()
    };
    let mut bound: Vec<BoundEffect> = effects
        .iter()
        .map(|e| BoundEffect::new(e, chain))
        .collect::<Result<_>>()?;
    let mut walker = TrajectoryWalker::new(n, bound.len());
    let mut rng = Rng::new(opts.seed);
    let mut faults = Rng::new(opts.seed ^ 0x0fee_dbac);
    let round = |v: f64| {
        if opts.quantum > 0.0 {
            (v / opts.quantum).round() * opts.quantum
        } else {
            v
        }
    };
    let mut rec = FeedbackRecording {
        axes: chain.joints().iter().map(|j| j.name.clone()).collect(),
        rotary: chain
            .joints()
            .iter()
            .map(|j| j.kind == JointKind::Revolute)
            .collect(),
        cmd: vec![Vec::with_capacity(traj.len()); n],
        fb: vec![Vec::with_capacity(traj.len()); n],
        ..Default::default()
    };
    for (p, mp) in traj.iter().zip(&machine) {
        let (state, active) = walker.step(mp, &mut bound)?;
        let mut fb: Vec<f64> = mp.q.clone();
        for (e, _) in bound.iter().zip(active).filter(|(_, a)| **a) {
            if let Some(j) = e.joint
                && !e.modifies_chain()
            {
                fb[j] += e.delta_q(&state);
            }
        }
        let fault = opts.outlier_fraction > 0.0 && faults.uniform() < opts.outlier_fraction;
        let fault_axis = (faults.uniform() * n as f64) as usize;
        for j in 0..n {
            let mut v = fb[j] + opts.noise * rng.normal();
            if fault && j == fault_axis.min(n - 1) {
                v += (0.01 + 0.09 * faults.uniform())
                    * if faults.uniform() < 0.5 { -1.0 } else { 1.0 };
            }
            rec.fb[j].push(round(v));
            rec.cmd[j].push(round(p.q[j]));
        }
        rec.t.push(p.t);
        rec.block.push(Some(p.block));
    }
    Ok(rec)
}

/// The commanded trajectory at arbitrary times (for a clock offset).
fn sample_at(
    chain: &Chain,
    waypoints: &[Waypoint],
    opts: &FeedbackSimOptions,
    times: &[f64],
) -> Result<Vec<TrajPoint>> {
    // A fine sampling, interpolated linearly: 1 ms against the offsets and
    // sample intervals used (≥ 1 ms), exact at constant speed.
    let fine = sample_waypoints(chain, waypoints, 1e-4, opts.accel_mm_s2)?;
    let n = chain.dof();
    Ok(times
        .iter()
        .map(|&t| {
            let x = (t / 1e-4).clamp(0.0, (fine.len() - 1) as f64);
            let k = (x.floor() as usize).min(fine.len().saturating_sub(2));
            let u = x - k as f64;
            let (a, b) = (&fine[k], &fine[(k + 1).min(fine.len() - 1)]);
            TrajPoint {
                t,
                block: a.block,
                q: (0..n).map(|j| a.q[j] + u * (b.q[j] - a.q[j])).collect(),
                v: vec![0.0; n],
            }
        })
        .collect())
}
