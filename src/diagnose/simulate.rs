//! Simulated recordings: a machine model with known errors, effects injected
//! on top, driven through a list of waypoints with a plain velocity profile,
//! measured with Gaussian noise. Deterministic for a seed.
//!
//! The commanded trajectory (its timeline and velocity profile) is
//! [`super::timeline`]'s; it streams, so a recording of any length is
//! made in the memory of a few blocks ([`TipSimulator`]).

use nalgebra::Vector3;

use super::recording::{Recording, Sample};
use super::rng::Rng;
use crate::error::{Error, Location, Result};
use crate::geometric::ErrorModel;
use crate::geometric::effects::{
    BoundEffect, DIRECTION_DEAD_BAND, DirectionTracker, EffectSpec, MotionSpan, MotionState,
    MotionTerm, chain_with_effects,
};
use crate::machine::chain::{Chain, JointErrors, JointKind, NoErrors};

use super::timeline::{SegmentBuilder, Window};
pub use super::timeline::{TrajPoint, Waypoint, WaypointPath, path_corners, path_length};

/// Options of [`simulate`].
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Standard deviation of the measurement noise of each measured
    /// coordinate, mm.
    pub noise_mm: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Time between samples, s.
    pub sample_interval_s: f64,
    /// Acceleration limit along the path, mm/s² (deg/s² for rotary moves);
    /// `None` for constant feed within each block.
    pub accel_mm_s2: Option<f64>,
    /// Clock offset of the recording, s (`formats.md` §2c): the sample
    /// stamped t shows the machine at t − offset, while its command
    /// columns hold the command at t. 0 for none.
    pub time_offset_s: f64,
    /// Fraction of samples (0 … 1) whose measured tip carries a gross
    /// fault (a broken laser beam): an error of 0.1 … 1 mm in a random
    /// direction. 0 for none.
    pub outlier_fraction: f64,
    /// Resolution of the recorder's export: every written value (axes in
    /// mm or deg, measured tip in mm) rounded to a multiple of it. 0 for
    /// none.
    pub quantum: f64,
    /// Registration of the measuring system: every measured tip is this
    /// far off in the workpiece frame (a tracker or probe zeroed off),
    /// mm. Zero for none.
    pub registration_mm: [f64; 3],
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            noise_mm: 0.001,
            seed: 1,
            sample_interval_s: 0.1,
            accel_mm_s2: Some(200.0),
            time_offset_s: 0.0,
            outlier_fraction: 0.0,
            quantum: 0.0,
            registration_mm: [0.0; 3],
        }
    }
}

/// The machine as the model knows it plus what it does not: the chain with
/// the model's fixed elements, its error motions, and effects.
pub(crate) struct TrueMachine<'a> {
    chain: Chain,
    errors: Option<crate::geometric::BoundErrors<'a>>,
    /// The model's own dynamic effects first, then the injected ones.
    pub(crate) effects: Vec<BoundEffect>,
    variants: std::collections::HashMap<u64, Chain>,
}

impl<'a> TrueMachine<'a> {
    pub(crate) fn new(
        chain: &Chain,
        model: Option<&'a ErrorModel>,
        effects: &[EffectSpec],
    ) -> Result<Self> {
        let (chain, errors) = match model {
            Some(m) => {
                let c = m.apply_fixed(chain)?;
                let e = m.bind(&c)?;
                (c, Some(e))
            }
            None => (chain.clone(), None),
        };
        let model_dynamic = model
            .map(|m| {
                m.effects
                    .iter()
                    .filter(|e| e.effect.kind().is_dynamic())
                    .cloned()
                    .collect::<Vec<_>>()
            })
            .unwrap_or_default();
        let effects = model_dynamic
            .iter()
            .chain(effects)
            .map(|e| BoundEffect::new(e, &chain))
            .collect::<Result<Vec<_>>>()?;
        if effects.len() > 63 {
            return Err(Error::input(
                Location::new("<effects>", 0, 0),
                "at most 63 effects can be injected at once",
            ));
        }
        Ok(TrueMachine {
            chain,
            errors,
            effects,
            variants: Default::default(),
        })
    }

    fn errors(&self) -> &dyn JointErrors {
        match &self.errors {
            Some(e) => e,
            None => &NoErrors,
        }
    }

    /// Tool tip for commanded `q` (file units) in motion state `state`, with
    /// the effects flagged in `active`; a wander of the measurement among
    /// them moves the tip as measured.
    pub(crate) fn tip(&mut self, state: &MotionState, active: u64) -> Vector3<f64> {
        let mut tip = self.machine_tip(state, active);
        for (k, e) in self.effects.iter().enumerate() {
            if active & (1 << k) != 0
                && let crate::geometric::effects::Effect::Wander { span, coef_mm } = &e.spec.effect
            {
                let w = crate::geometric::effects::wander_at(span, coef_mm, state.t);
                tip += Vector3::from(w);
            }
        }
        tip
    }

    /// The tool tip of the machine (every effect but a wander).
    fn machine_tip(&mut self, state: &MotionState, active: u64) -> Vector3<f64> {
        let n = self.chain.dof();
        let mut q = state.q.to_vec();
        let mut chain_mask = 0u64;
        let mut motions: Vec<Motion<'_>> = Vec::new();
        for (k, e) in self.effects.iter().enumerate() {
            if active & (1 << k) == 0 {
                continue;
            }
            if let (
                crate::geometric::effects::Effect::ErrorMotion {
                    terms, span, arc, ..
                },
                Some(j),
            ) = (&e.spec.effect, e.joint)
            {
                motions.push((j, terms, span.as_ref(), *arc));
            } else if e.modifies_chain() {
                chain_mask |= 1 << k;
            } else if let Some(j) = e.joint {
                q[j] += e.delta_q(state);
            }
        }
        for (j, v) in q.iter_mut().enumerate().take(n) {
            if self.chain.joints()[j].kind == JointKind::Revolute {
                *v = v.to_radians();
            }
        }
        // An injected error motion acts through the chain's error source.
        if chain_mask == 0 {
            if motions.is_empty() {
                return self.chain.pose(&q, self.errors()).tip;
            }
            let with = WithMotions {
                base: self.errors(),
                motions,
            };
            return self.chain.pose(&q, &with).tip;
        }
        if !self.variants.contains_key(&chain_mask) {
            let sel: Vec<&BoundEffect> = self
                .effects
                .iter()
                .enumerate()
                .filter(|(k, _)| chain_mask & (1 << k) != 0)
                .map(|(_, e)| e)
                .collect();
            let c = chain_with_effects(&self.chain, &sel);
            self.variants.insert(chain_mask, c);
        }
        let c = &self.variants[&chain_mask];
        let errors: &dyn JointErrors = match &self.errors {
            Some(e) => e,
            None => &NoErrors,
        };
        if motions.is_empty() {
            c.pose(&q, errors).tip
        } else {
            c.pose(
                &q,
                &WithMotions {
                    base: errors,
                    motions,
                },
            )
            .tip
        }
    }
}

/// An error source plus injected error motions of some joints.
struct WithMotions<'b> {
    base: &'b dyn JointErrors,
    motions: Vec<Motion<'b>>,
}

/// An injected error motion: joint, terms, spline basis, arc.
type Motion<'b> = (
    usize,
    &'b [MotionTerm],
    Option<&'b MotionSpan>,
    crate::geometric::effects::TurnArc,
);

impl JointErrors for WithMotions<'_> {
    fn error(&self, joint: usize, q: f64) -> Option<crate::machine::chain::ErrorMotion> {
        let mut e = self.base.error(joint, q);
        for (j, terms, span, arc) in &self.motions {
            if *j == joint {
                let add = crate::geometric::effects::error_motion_at(terms, *span, *arc, q);
                e = Some(e.unwrap_or_else(crate::machine::chain::ErrorMotion::zeros) + add);
            }
        }
        e
    }
}

/// Most samples one simulated recording may hold.
pub const MAX_SAMPLES: usize = 50_000_000;

/// Samples the commanded trajectory through `waypoints` every
/// `sample_interval_s` seconds, with the velocity profile described in
/// [`super::timeline`]. (All at once; [`TipSimulator`] streams.)
pub fn sample_waypoints(
    chain: &Chain,
    waypoints: &[Waypoint],
    sample_interval_s: f64,
    accel_mm_s2: Option<f64>,
) -> Result<Vec<TrajPoint>> {
    let mut sampler = Sampler::new(chain, sample_interval_s, accel_mm_s2, 0.0, 0.0)?;
    let n = chain.dof();
    let mut out = Vec::new();
    let mut take = |w: &Window, t: f64| {
        out.push(w.point_at(t, n));
        Ok(())
    };
    for w in waypoints {
        sampler.push(w, &mut take)?;
    }
    sampler.finish(&mut take)?;
    Ok(out)
}

/// The commanded trajectory sampled as its waypoints stream in: sample
/// `i` at `t = i × interval` (rounded to 1 ns), handed on as soon as every
/// segment it may need is known, through the end of the last block.
pub(crate) struct Sampler<'c> {
    builder: SegmentBuilder<'c>,
    window: Window,
    interval: f64,
    /// The next sample.
    next: usize,
    /// How far before and after a sample's time its consumer asks for
    /// the commanded trajectory, s.
    behind: f64,
    ahead: f64,
}

impl<'c> Sampler<'c> {
    /// Samples every `interval` s with the acceleration limit `accel`
    /// (mm/s²; `None`: constant feed per block), for a consumer that asks
    /// for the commanded trajectory from `behind` s before to `ahead` s
    /// after each sample's time.
    pub(crate) fn new(
        chain: &'c Chain,
        interval: f64,
        accel: Option<f64>,
        behind: f64,
        ahead: f64,
    ) -> Result<Self> {
        let loc = || Location::new("<simulate>", 0, 0);
        if !(interval.is_finite() && interval > 0.0) {
            return Err(Error::input(loc(), "the sample interval must be positive"));
        }
        if let Some(a) = accel
            && !(a.is_finite() && a > 0.0)
        {
            return Err(Error::input(
                loc(),
                "the acceleration limit must be positive",
            ));
        }
        Ok(Sampler {
            builder: SegmentBuilder::new(chain, accel),
            window: Window::new(),
            interval,
            next: 0,
            behind: behind.max(0.0),
            ahead: ahead.max(0.0),
        })
    }

    /// The next waypoint; `take` is given the window and the time of each
    /// sample that is known now.
    pub(crate) fn push(
        &mut self,
        w: &Waypoint,
        take: &mut dyn FnMut(&Window, f64) -> Result<()>,
    ) -> Result<()> {
        self.window.start(w);
        if let Some(seg) = self.builder.push(w)? {
            self.window.push(seg);
            self.emit(take)?;
        }
        Ok(())
    }

    /// After the last waypoint: the remaining samples, through the end of
    /// the last block; returns how many samples there were.
    pub(crate) fn finish(
        mut self,
        take: &mut dyn FnMut(&Window, f64) -> Result<()>,
    ) -> Result<usize> {
        if self.builder.count() == 0 {
            return Err(Error::input(
                Location::new("<simulate>", 0, 0),
                "no waypoints to simulate",
            ));
        }
        self.window.end();
        self.emit(take)?;
        Ok(self.next)
    }

    /// Hands on the samples that are known: all of them once the window
    /// has ended.
    fn emit(&mut self, take: &mut dyn FnMut(&Window, f64) -> Result<()>) -> Result<()> {
        // Counted in floating point first: a tiny interval must not wrap
        // the count. Before the end, a sample is known when it lies within
        // the blocks pushed (as counted at the end) and no block still to
        // come can start before the last time its consumer asks for.
        let last = (self.window.end_time() / self.interval).floor();
        loop {
            let t = sample_time(self.next, self.interval);
            let known = if self.window.ended() {
                self.next as f64 <= last
            } else {
                self.next as f64 <= last && self.window.settled(t + self.ahead)
            };
            if !known {
                return Ok(());
            }
            if self.next >= MAX_SAMPLES {
                return Err(Error::input(
                    Location::new("<simulate>", 0, 0),
                    format!(
                        "more than {MAX_SAMPLES} samples (every {:e} s, and the program runs on after {t:.3} s) are too many",
                        self.interval
                    ),
                ));
            }
            take(&self.window, t)?;
            self.next += 1;
            self.window.trim(t - self.behind);
        }
    }
}

/// The two samples that the central difference at sample `i` of `n`
/// (`n ≥ 2`) uses: its neighbours, or at the ends the end and its
/// neighbour.
pub(crate) fn central_pair(i: usize, n: usize) -> (usize, usize) {
    if i == 0 {
        (0, 1)
    } else if i == n - 1 {
        (n - 2, n - 1)
    } else {
        (i - 1, i + 1)
    }
}

/// Fills in the velocities of a trajectory by central differences of its
/// positions (one-sided at the ends).
pub fn central_velocities(traj: &mut [TrajPoint]) {
    let n = traj.len();
    if n < 2 {
        return;
    }
    for i in 0..n {
        let (a, b) = central_pair(i, n);
        traj[i].v = velocity_between(&traj[a], &traj[b]);
    }
}

/// The time of sample `i` of a sampling every `interval` s, rounded to
/// 1 ns.
pub(crate) fn sample_time(i: usize, interval: f64) -> f64 {
    (i as f64 * interval * 1e9).round() / 1e9
}

/// The velocity between two points of a trajectory (per component; 0
/// where they share a time).
pub(crate) fn velocity_between(a: &TrajPoint, b: &TrajPoint) -> Vec<f64> {
    let dt = b.t - a.t;
    b.q.iter()
        .zip(&a.q)
        .map(|(qb, qa)| if dt > 0.0 { (qb - qa) / dt } else { 0.0 })
        .collect()
}

/// The tool tip (mm, noise-free) of the machine `chain` + `errors` (its
/// fixed elements, error motions and effects) + `effects`, driven along
/// `traj`. Directions of motion are tracked along the trajectory; an effect
/// with `from_block` acts from the first point whose block is at least that.
pub fn evaluate_trajectory(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    effects: &[EffectSpec],
    traj: &[TrajPoint],
) -> Result<Vec<Vector3<f64>>> {
    let mut machine = TrueMachine::new(chain, errors, effects)?;
    let mut walker = TrajectoryWalker::new(chain.dof(), machine.effects.len());
    traj.iter()
        .map(|p| machine.tip_along(&mut walker, p))
        .collect()
}

impl TrueMachine<'_> {
    /// The tool tip at the next point `p` of a trajectory that `walker`
    /// follows (made for this machine's effects).
    fn tip_along(&mut self, walker: &mut TrajectoryWalker, p: &TrajPoint) -> Result<Vector3<f64>> {
        let (state, active) = walker.step(p, &mut self.effects)?;
        let mask = active
            .iter()
            .enumerate()
            .filter(|(_, a)| **a)
            .fold(0u64, |m, (k, _)| m | 1 << k);
        Ok(self.tip(&state, mask))
    }
}

/// Walks a commanded trajectory for the effects: checks that every point
/// has one position and one velocity per joint, tracks each joint's
/// direction of motion, and switches each effect on at the first point
/// whose block is at least its `from_block`, starting its clock (`t0`)
/// there.
pub(crate) struct TrajectoryWalker {
    trackers: Vec<DirectionTracker>,
    dir: Vec<f64>,
    active: Vec<bool>,
}

impl TrajectoryWalker {
    /// A walker for a chain of `joints` joints and `effects` effects, none
    /// acting yet.
    pub(crate) fn new(joints: usize, effects: usize) -> Self {
        TrajectoryWalker {
            trackers: vec![DirectionTracker::new(DIRECTION_DEAD_BAND); joints],
            dir: vec![0.0; joints],
            active: vec![false; effects],
        }
    }

    /// Advances to `p`, switching on those of `effects` (the ones the
    /// walker was made for, in the same order) that start there; returns
    /// the motion state at `p` and which effects act there.
    pub(crate) fn step<'a>(
        &'a mut self,
        p: &'a TrajPoint,
        effects: &mut [BoundEffect],
    ) -> Result<(MotionState<'a>, &'a [bool])> {
        let n = self.dir.len();
        if p.q.len() != n || p.v.len() != n {
            return Err(Error::input(
                Location::new("<trajectory>", 0, 0),
                format!(
                    "a trajectory point has {} values; the machine has {n} joints",
                    p.q.len()
                ),
            ));
        }
        for (d, (tracker, q)) in self.dir.iter_mut().zip(self.trackers.iter_mut().zip(&p.q)) {
            *d = tracker.update(*q);
        }
        for (active, e) in self.active.iter_mut().zip(effects) {
            if !*active && e.spec.from_block.is_none_or(|b| p.block >= b) {
                *active = true;
                e.t0 = p.t;
            }
        }
        let state = MotionState {
            t: p.t,
            q: &p.q,
            v: &p.v,
            dir: &self.dir,
        };
        Ok((state, &self.active))
    }
}

/// Simulates a recording: the commanded axes sampled along the waypoints,
/// and the tool tip of the *true* machine (chain + `errors` + `effects`)
/// plus N(0, σ²) noise on each coordinate. Effects with a `from_block`
/// act from the first sample whose block is at least that number.
/// Deterministic for a seed. (All at once; [`TipSimulator`] streams.)
pub fn simulate(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    waypoints: &[Waypoint],
    effects: &[EffectSpec],
    opts: &SimOptions,
) -> Result<Recording> {
    let mut sim = TipSimulator::new(chain, errors, effects, opts)?;
    let mut samples = Vec::new();
    let mut keep = |s: Sample| {
        samples.push(s);
        Ok(())
    };
    for w in waypoints {
        sim.push(w, &mut keep)?;
    }
    sim.finish(&mut keep)?;
    Ok(Recording {
        axes: chain.names(),
        temp_names: Vec::new(),
        samples,
    })
}

/// [`simulate`] as the waypoints stream in: each sample is handed on as
/// soon as the blocks it depends on are known, so memory does not grow
/// with the program.
pub struct TipSimulator<'a> {
    sampler: Sampler<'a>,
    state: TipState<'a>,
}

/// What [`TipSimulator`] carries from sample to sample.
struct TipState<'a> {
    machine: TrueMachine<'a>,
    walker: TrajectoryWalker,
    rng: Rng,
    faults: Rng,
    opts: SimOptions,
    n: usize,
}

impl<'a> TipSimulator<'a> {
    /// A simulation of `chain` with `errors` and `effects` (see
    /// [`simulate`]); checks the options.
    pub fn new(
        chain: &'a Chain,
        errors: Option<&'a ErrorModel>,
        effects: &[EffectSpec],
        opts: &SimOptions,
    ) -> Result<Self> {
        if !(opts.noise_mm.is_finite() && opts.noise_mm >= 0.0) {
            return Err(Error::input(
                Location::new("<simulate>", 0, 0),
                "the noise must be a non-negative number of mm",
            ));
        }
        let faults_ok = opts.time_offset_s.is_finite()
            && (0.0..=1.0).contains(&opts.outlier_fraction)
            && opts.quantum.is_finite()
            && opts.quantum >= 0.0
            && opts.registration_mm.iter().all(|v| v.is_finite());
        if !faults_ok {
            return Err(Error::input(
                Location::new("<simulate>", 0, 0),
                "the clock offset and the registration must be finite, the outlier fraction 0 … 1 and the quantum ≥ 0",
            ));
        }
        // The machine runs `offset` behind the recording's clock.
        let offset = opts.time_offset_s;
        let sampler = Sampler::new(
            chain,
            opts.sample_interval_s,
            opts.accel_mm_s2,
            offset,
            -offset,
        )?;
        let machine = TrueMachine::new(chain, errors, effects)?;
        let walker = TrajectoryWalker::new(chain.dof(), machine.effects.len());
        Ok(TipSimulator {
            sampler,
            state: TipState {
                machine,
                walker,
                rng: Rng::new(opts.seed),
                // Faults draw from their own stream, so that a recording
                // with faults has the same noise as the one without.
                faults: Rng::new(opts.seed ^ 0x5eed_fa17),
                opts: opts.clone(),
                n: chain.dof(),
            },
        })
    }

    /// The next waypoint; the samples known now go to `sink`.
    pub fn push(&mut self, w: &Waypoint, sink: &mut dyn FnMut(Sample) -> Result<()>) -> Result<()> {
        let state = &mut self.state;
        self.sampler
            .push(w, &mut |win: &Window, t| sink(state.sample(win, t)?))
    }

    /// After the last waypoint: the remaining samples go to `sink`;
    /// returns how many samples the recording has.
    pub fn finish(self, sink: &mut dyn FnMut(Sample) -> Result<()>) -> Result<usize> {
        let mut state = self.state;
        self.sampler
            .finish(&mut |win: &Window, t| sink(state.sample(win, t)?))
    }
}

impl TipState<'_> {
    /// The sample at time `t`.
    fn sample(&mut self, win: &Window, t: f64) -> Result<Sample> {
        let opts = &self.opts;
        let p = win.point_at(t, self.n);
        let tip = if opts.time_offset_s != 0.0 {
            // The machine's own trajectory: at the stamp t, the command at
            // t − offset; effects that grow with time see its own clock.
            let mut m = win.point_at((t - opts.time_offset_s).max(0.0), self.n);
            m.t = t - opts.time_offset_s;
            self.machine.tip_along(&mut self.walker, &m)?
        } else {
            self.machine.tip_along(&mut self.walker, &p)?
        };
        let round = |v: f64| {
            if opts.quantum > 0.0 {
                (v / opts.quantum).round() * opts.quantum
            } else {
                v
            }
        };
        let (rng, faults) = (&mut self.rng, &mut self.faults);
        let reg = opts.registration_mm;
        let mut meas = [
            tip.x + reg[0] + opts.noise_mm * rng.normal(),
            tip.y + reg[1] + opts.noise_mm * rng.normal(),
            tip.z + reg[2] + opts.noise_mm * rng.normal(),
        ];
        if opts.outlier_fraction > 0.0 && faults.uniform() < opts.outlier_fraction {
            let d = [faults.normal(), faults.normal(), faults.normal()];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
            let size = 0.1 + 0.9 * faults.uniform();
            for c in 0..3 {
                meas[c] += size * d[c] / len;
            }
        }
        Ok(Sample {
            t: p.t,
            block: Some(p.block),
            q: p.q.into_iter().map(round).collect(),
            meas: meas.map(round),
            meas_axis: None,
            temps: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Memory does not grow with the program: the window keeps the blocks
    /// between the earliest time still asked for and the latest pushed.
    #[test]
    fn the_sampler_keeps_a_few_blocks_whatever_the_program_length() {
        let m = crate::machine::Machine::embedded("xyz-3axis").unwrap();
        // 1 s blocks of 10 mm at F600; the consumer asks up to 2.5 s back
        // (a clock offset).
        for (behind, ahead, most) in [(0.0, 0.0, 2), (2.5, 0.0, 5), (0.0, 2.5, 5)] {
            let mut s = Sampler::new(&m.chain, 0.1, Some(200.0), behind, ahead).unwrap();
            let mut taken = 0usize;
            let mut take = |_: &Window, _: f64| {
                taken += 1;
                Ok(())
            };
            for k in 0..5000 {
                let w = Waypoint {
                    q: vec![10.0 * (k % 2) as f64, 0.0, 0.0],
                    feed: 600.0,
                    block: k + 1,
                    path: WaypointPath::Straight,
                };
                s.push(&w, &mut take).unwrap();
                assert!(
                    s.window.kept() <= most,
                    "behind {behind}, ahead {ahead}: {} blocks kept after {k}",
                    s.window.kept()
                );
            }
            let n = s.finish(&mut take).unwrap();
            assert_eq!(n, taken);
        }
    }

    /// A run that would need more than [`MAX_SAMPLES`] samples is refused
    /// when the first one too many is due (the disk, not the memory, is
    /// what the limit now protects).
    #[test]
    fn more_samples_than_the_limit_are_refused() {
        let m = crate::machine::Machine::embedded("xyz-3axis").unwrap();
        // 60 s of moves every 1 µs: 60,000,001 samples.
        let mut s = Sampler::new(&m.chain, 1e-6, None, 0.0, 0.0).unwrap();
        let mut taken = 0usize;
        let mut take = |_: &Window, _: f64| {
            taken += 1;
            Ok(())
        };
        let mut result = Ok(());
        for k in 0..=6u64 {
            let w = Waypoint {
                q: vec![100.0 * k as f64, 0.0, 0.0],
                feed: 600.0,
                block: k + 1,
                path: WaypointPath::Straight,
            };
            result = s.push(&w, &mut take);
            if result.is_err() {
                break;
            }
        }
        let err = match result {
            Err(e) => e.to_string(),
            Ok(()) => s.finish(&mut take).unwrap_err().to_string(),
        };
        assert!(err.contains("more than 50000000 samples"), "{err}");
        assert_eq!(taken, MAX_SAMPLES);
    }
}
