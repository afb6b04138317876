//! Simulated joint-feedback traces with joint-level effects and faults.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::rng::Rng;
use std::collections::VecDeque;

use super::super::simulate::{
    Sampler, SimOptions, TrajPoint, TrajectoryWalker, Waypoint, sample_time, velocity_between,
};
use super::super::timeline::Window;
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

impl From<&SimOptions> for FeedbackSimOptions {
    /// The options of a tool-tip recording for a joint-feedback trace of
    /// the same run: its noise as each axis's (mm or deg).
    fn from(o: &SimOptions) -> Self {
        FeedbackSimOptions {
            noise: o.noise_mm,
            seed: o.seed,
            sample_interval_s: o.sample_interval_s,
            accel_mm_s2: o.accel_mm_s2,
            time_offset_s: o.time_offset_s,
            outlier_fraction: o.outlier_fraction,
            quantum: o.quantum,
        }
    }
}

/// Simulates a joint-feedback trace of every joint of `chain` along
/// `waypoints`: the command sampled, each joint's feedback the command
/// plus the joint-level `effects` (backlash, servo lag, thermal drift,
/// scale, cyclic, zero offset, vibration of that joint), noise, faults and
/// rounding. Deterministic for a seed. (All at once; [`FeedbackSimulator`]
/// streams.)
pub fn simulate_feedback(
    chain: &Chain,
    waypoints: &[Waypoint],
    effects: &[EffectSpec],
    opts: &FeedbackSimOptions,
) -> Result<FeedbackRecording> {
    let n = chain.dof();
    let mut rec = FeedbackRecording {
        axes: chain.names(),
        rotary: chain
            .joints()
            .iter()
            .map(|j| j.kind == JointKind::Revolute)
            .collect(),
        cmd: vec![Vec::new(); n],
        fb: vec![Vec::new(); n],
        ..Default::default()
    };
    let mut keep = |row: FeedbackRow| {
        for j in 0..n {
            rec.cmd[j].push(row.cmd[j]);
            rec.fb[j].push(row.fb[j]);
        }
        rec.t.push(row.t);
        rec.block.push(row.block);
        Ok(())
    };
    let mut sim = FeedbackSimulator::new(chain, effects, opts)?;
    for w in waypoints {
        sim.push(w, &mut keep)?;
    }
    sim.finish(&mut keep)?;
    Ok(rec)
}

/// One sample of a joint-feedback trace.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedbackRow {
    /// Time, s.
    pub t: f64,
    /// The block commanded then.
    pub block: Option<u64>,
    /// Command per axis (mm or deg), chain order.
    pub cmd: Vec<f64>,
    /// Feedback per axis (mm or deg), chain order.
    pub fb: Vec<f64>,
}

/// Spacing of the fine sampling a clock offset is interpolated on, s.
const FINE_S: f64 = 1e-4;

/// [`simulate_feedback`] as the waypoints stream in: each sample is handed
/// on as soon as the blocks it depends on are known.
pub struct FeedbackSimulator<'c> {
    sampler: Sampler<'c>,
    state: FeedbackState,
}

/// What [`FeedbackSimulator`] carries from sample to sample.
struct FeedbackState {
    bound: Vec<BoundEffect>,
    walker: TrajectoryWalker,
    rng: Rng,
    faults: Rng,
    opts: FeedbackSimOptions,
    n: usize,
    /// With a clock offset: the commanded points and the axes' own
    /// positions of the samples whose central velocity waits for the
    /// next sample (at most two).
    waiting: VecDeque<(TrajPoint, TrajPoint)>,
}

impl<'c> FeedbackSimulator<'c> {
    /// A simulation of `chain` with the joint-level `effects`.
    pub fn new(
        chain: &'c Chain,
        effects: &[EffectSpec],
        opts: &FeedbackSimOptions,
    ) -> Result<Self> {
        // The axes run `offset` behind the trace's clock, read on a fine
        // sampling one step either side.
        let offset = opts.time_offset_s;
        let (behind, ahead) = if offset != 0.0 {
            (offset + 3.0 * FINE_S, -offset + 3.0 * FINE_S)
        } else {
            (0.0, 0.0)
        };
        let sampler = Sampler::new(
            chain,
            opts.sample_interval_s,
            opts.accel_mm_s2,
            behind,
            ahead,
        )?;
        let bound: Vec<BoundEffect> = effects
            .iter()
            .map(|e| BoundEffect::new(e, chain))
            .collect::<Result<_>>()?;
        let n = chain.dof();
        Ok(FeedbackSimulator {
            sampler,
            state: FeedbackState {
                walker: TrajectoryWalker::new(n, bound.len()),
                bound,
                rng: Rng::new(opts.seed),
                faults: Rng::new(opts.seed ^ 0x0fee_dbac),
                opts: opts.clone(),
                n,
                waiting: VecDeque::new(),
            },
        })
    }

    /// The next waypoint; the samples known now go to `sink`.
    pub fn push(
        &mut self,
        w: &Waypoint,
        sink: &mut dyn FnMut(FeedbackRow) -> Result<()>,
    ) -> Result<()> {
        let state = &mut self.state;
        self.sampler
            .push(w, &mut |win: &Window, t| state.take(win, t, sink))
    }

    /// After the last waypoint: the remaining samples go to `sink`;
    /// returns how many samples the trace has.
    pub fn finish(self, sink: &mut dyn FnMut(FeedbackRow) -> Result<()>) -> Result<usize> {
        let mut state = self.state;
        let n = self
            .sampler
            .finish(&mut |win: &Window, t| state.take(win, t, sink))?;
        // The last sample's velocity: one-sided, from the one before.
        if let Some((p, mut m)) = state.waiting.pop_back() {
            if let Some((_, before)) = state.waiting.pop_back() {
                m.v = velocity_between(&before, &m);
            }
            let row = state.row(&p, &m)?;
            sink(row)?;
        }
        Ok(n)
    }
}

impl FeedbackState {
    /// Sample `t`: handed on at once without a clock offset; with one, when
    /// the next sample gives its central velocity.
    fn take(
        &mut self,
        win: &Window,
        t: f64,
        sink: &mut dyn FnMut(FeedbackRow) -> Result<()>,
    ) -> Result<()> {
        let p = win.point_at(t, self.n);
        if self.opts.time_offset_s == 0.0 {
            let row = self.row(&p, &p)?;
            return sink(row);
        }
        let m = self.axes_at(win, t - self.opts.time_offset_s);
        self.waiting.push_back((p, m));
        match self.waiting.len() {
            // The first sample (later ones leave two waiting, and the next
            // makes three): one-sided, towards the second.
            2 => {
                let v = velocity_between(&self.waiting[0].1, &self.waiting[1].1);
                self.waiting[0].1.v = v;
                let (p0, m0) = self.waiting[0].clone();
                let row = self.row(&p0, &m0)?;
                sink(row)
            }
            3 => {
                let v = velocity_between(&self.waiting[0].1, &self.waiting[2].1);
                self.waiting[1].1.v = v;
                self.waiting.pop_front();
                let (p1, m1) = self.waiting[0].clone();
                let row = self.row(&p1, &m1)?;
                sink(row)
            }
            _ => Ok(()),
        }
    }

    /// The axes' own positions at `t` (the command `offset` earlier):
    /// linear between the two points of a fine sampling of the command
    /// (every [`FINE_S`], at most 0.1 ms off against the offsets and sample
    /// intervals used) about it; velocity 0 (set from the neighbours).
    fn axes_at(&self, win: &Window, t: f64) -> TrajPoint {
        let at = |k: usize| sample_time(k, FINE_S);
        // The fine sampling's last point: known once the window ended, and
        // not reached before (the sampler asks that far ahead).
        let last = (win.end_time() / FINE_S).floor() as usize;
        let x = if win.ended() {
            (t / FINE_S).clamp(0.0, last as f64)
        } else {
            (t / FINE_S).max(0.0)
        };
        let k = (x.floor() as usize).min(last.saturating_sub(1));
        let u = x - k as f64;
        let a = win.point_at(at(k), self.n);
        let b = win.point_at(at((k + 1).min(last)), self.n);
        TrajPoint {
            t,
            block: a.block,
            q: (0..self.n)
                .map(|j| a.q[j] + u * (b.q[j] - a.q[j]))
                .collect(),
            v: vec![0.0; self.n],
        }
    }

    /// The trace's line for the commanded point `p`, the axes being at `m`.
    fn row(&mut self, p: &TrajPoint, m: &TrajPoint) -> Result<FeedbackRow> {
        let (n, opts) = (self.n, &self.opts);
        let (state, active) = self.walker.step(m, &mut self.bound)?;
        let mut fb: Vec<f64> = m.q.clone();
        for (e, _) in self.bound.iter().zip(active).filter(|(_, a)| **a) {
            if let Some(j) = e.joint
                && !e.modifies_chain()
            {
                fb[j] += e.delta_q(&state);
            }
        }
        let round = |v: f64| {
            if opts.quantum > 0.0 {
                (v / opts.quantum).round() * opts.quantum
            } else {
                v
            }
        };
        let (rng, faults) = (&mut self.rng, &mut self.faults);
        let fault = opts.outlier_fraction > 0.0 && faults.uniform() < opts.outlier_fraction;
        let fault_axis = (faults.uniform() * n as f64) as usize;
        let mut row = FeedbackRow {
            t: p.t,
            block: Some(p.block),
            cmd: Vec::with_capacity(n),
            fb: Vec::with_capacity(n),
        };
        for j in 0..n {
            let mut v = fb[j] + opts.noise * rng.normal();
            if fault && j == fault_axis.min(n - 1) {
                v += (0.01 + 0.09 * faults.uniform())
                    * if faults.uniform() < 0.5 { -1.0 } else { 1.0 };
            }
            row.fb.push(round(v));
            row.cmd.push(round(p.q[j]));
        }
        Ok(row)
    }
}
