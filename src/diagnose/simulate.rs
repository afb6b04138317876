//! Simulated recordings: a machine model with known errors, effects injected
//! on top, driven through a list of waypoints with a plain velocity profile,
//! measured with Gaussian noise. Deterministic for a seed.
//!
//! Time comes from the feeds: each segment between two waypoints is one
//! block, run at its feed F (mm/min) along its path length (a circular
//! move along the straight pieces that stand for it, [`WaypointPath`])
//!
//! ```text
//! L = sqrt( Σ Δ(linear axis, mm)² + Σ Δ(rotary axis, deg)² )
//! ```
//!
//! i.e. one degree counts as one millimetre (the usual controller rule for
//! mixed linear/rotary moves; a pure rotary move runs at F deg/min). The
//! speed along the path follows a trapezoid with the acceleration limit
//! [`SimOptions::accel_mm_s2`] (a triangle when the block is too short to
//! reach F), starting and stopping in every block (exact stop). With no
//! acceleration limit the speed is F throughout the block.

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

/// A commanded machine position: the end point of a block.
#[derive(Debug, Clone, PartialEq)]
pub struct Waypoint {
    /// Axis positions in the machine's joint order (mm, deg).
    pub q: Vec<f64>,
    /// Feed of the block that ends here, mm/min (deg/min for pure rotary
    /// moves). Ignored for the first waypoint, the start position.
    pub feed: f64,
    /// NC block number of the move that ends here.
    pub block: u64,
    /// How the block gets here from the waypoint before.
    pub path: WaypointPath,
}

/// How a block reaches its waypoint from the one before.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum WaypointPath {
    /// A straight move of the axes.
    #[default]
    Straight,
    /// Through these axis positions (mm, deg; joint order), in order, and
    /// straight between them: a circular move as the points it passes.
    Through(Vec<Vec<f64>>),
    /// A move whose path the program does not give (to the reference
    /// point, a canned cycle): the recording leaves it out, and the next
    /// block starts at this waypoint at the time the block before ended.
    Unknown,
}

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
        }
    }
}

/// One block of the timeline.
#[derive(Debug, Clone)]
struct Segment {
    t_start: f64,
    duration: f64,
    length: f64,
    v_max: f64,
    accel: Option<f64>,
    /// The path's corners, from the block's start to its end (two for a
    /// straight move).
    corners: Vec<Vec<f64>>,
    /// The path length at each corner (0 at the first).
    at: Vec<f64>,
    block: u64,
}

impl Segment {
    /// The position and the velocity along the path (per unit of path
    /// speed) `p` along it.
    fn position(&self, p: f64, q: &mut [f64], dir: &mut [f64]) {
        let last = self.corners.len() - 1;
        let i = self
            .at
            .partition_point(|&a| a <= p)
            .saturating_sub(1)
            .min(last - 1);
        let (a, b) = (&self.corners[i], &self.corners[i + 1]);
        let piece = self.at[i + 1] - self.at[i];
        let f = if piece > 0.0 {
            ((p - self.at[i]) / piece).clamp(0.0, 1.0)
        } else {
            1.0
        };
        for j in 0..q.len() {
            q[j] = a[j] + f * (b[j] - a[j]);
            dir[j] = if piece > 0.0 {
                (b[j] - a[j]) / piece
            } else {
                0.0
            };
        }
    }

    /// Path position and speed `duration` seconds… at local time `tau`.
    fn s_and_v(&self, tau: f64) -> (f64, f64) {
        let tau = tau.clamp(0.0, self.duration);
        match self.accel {
            None => (self.v_max * tau, self.v_max),
            Some(a) => {
                let ta = self.v_max / a; // time to reach v_max (may be cut short)
                let t_half = 0.5 * self.duration;
                let t_acc = ta.min(t_half);
                let v_top = a * t_acc;
                if tau <= t_acc {
                    (0.5 * a * tau * tau, a * tau)
                } else if tau <= self.duration - t_acc {
                    (0.5 * a * t_acc * t_acc + v_top * (tau - t_acc), v_top)
                } else {
                    let r = self.duration - tau;
                    (self.length - 0.5 * a * r * r, a * r)
                }
            }
        }
    }
}

/// The corners of a block's path, from `from` through the points of
/// `path` ([`WaypointPath::Through`]; none for the others) to `to`, and the
/// path length at each ([`path_length`] summed; 0 at the first).
pub fn path_corners(
    chain: &Chain,
    from: &[f64],
    path: &WaypointPath,
    to: &[f64],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut corners = vec![from.to_vec()];
    if let WaypointPath::Through(points) = path {
        corners.extend(points.iter().cloned());
    }
    corners.push(to.to_vec());
    let mut at = vec![0.0];
    for pair in corners.windows(2) {
        at.push(at[at.len() - 1] + path_length(chain, &pair[0], &pair[1]));
    }
    (corners, at)
}

/// Path length of a move (mm, with 1° counted as 1 mm).
pub fn path_length(chain: &Chain, from: &[f64], to: &[f64]) -> f64 {
    chain
        .joints()
        .iter()
        .zip(from.iter().zip(to))
        .map(|(_, (a, b))| (b - a) * (b - a))
        .sum::<f64>()
        .sqrt()
}

fn timeline(chain: &Chain, wps: &[Waypoint], accel: Option<f64>) -> Result<Vec<Segment>> {
    let loc = || Location::new("<waypoints>", 0, 0);
    let mut segs = Vec::new();
    let mut t = 0.0;
    for (k, w) in wps.iter().enumerate() {
        if w.q.len() != chain.dof() {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}) has {} axis values; the machine has {} joints",
                    w.block,
                    w.q.len(),
                    chain.dof()
                ),
            ));
        }
        if w.q.iter().any(|v| !v.is_finite()) {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}) has a non-finite axis value",
                    w.block
                ),
            ));
        }
        if k == 0 {
            continue;
        }
        let from = &wps[k - 1].q;
        match &w.path {
            WaypointPath::Straight => {}
            WaypointPath::Through(points) => {
                if let Some(p) = points
                    .iter()
                    .find(|p| p.len() != chain.dof() || p.iter().any(|v| !v.is_finite()))
                {
                    return Err(Error::input(
                        loc(),
                        format!(
                            "waypoint {k} (block {}) passes a point of {} values, not {} finite axis values",
                            w.block,
                            p.len(),
                            chain.dof()
                        ),
                    ));
                }
            }
            WaypointPath::Unknown => continue,
        }
        let (corners, at) = path_corners(chain, from, &w.path, &w.q);
        let length = at[at.len() - 1];
        if length == 0.0 {
            continue;
        }
        if !(w.feed.is_finite() && w.feed > 0.0) {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}): feed {} mm/min must be positive",
                    w.block, w.feed
                ),
            ));
        }
        let v = w.feed / 60.0;
        let duration = match accel {
            None => length / v,
            Some(a) => {
                if length >= v * v / a {
                    length / v + v / a
                } else {
                    2.0 * (length / a).sqrt()
                }
            }
        };
        segs.push(Segment {
            t_start: t,
            duration,
            length,
            v_max: v,
            accel,
            corners,
            at,
            block: w.block,
        });
        t += duration;
    }
    Ok(segs)
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
    /// the effects flagged in `active`.
    pub(crate) fn tip(&mut self, state: &MotionState, active: u64) -> Vector3<f64> {
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

/// One sample of a commanded trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajPoint {
    /// Time, s.
    pub t: f64,
    /// NC block.
    pub block: u64,
    /// Commanded positions (mm, deg), chain order.
    pub q: Vec<f64>,
    /// Commanded velocities (mm/s, deg/s).
    pub v: Vec<f64>,
}

/// Most samples one simulated recording may hold.
pub const MAX_SAMPLES: usize = 50_000_000;

/// Samples the commanded trajectory through `waypoints` every
/// `sample_interval_s` seconds, with the velocity profile described in the
/// module documentation.
pub fn sample_waypoints(
    chain: &Chain,
    waypoints: &[Waypoint],
    sample_interval_s: f64,
    accel_mm_s2: Option<f64>,
) -> Result<Vec<TrajPoint>> {
    let loc = || Location::new("<simulate>", 0, 0);
    if !(sample_interval_s.is_finite() && sample_interval_s > 0.0) {
        return Err(Error::input(loc(), "the sample interval must be positive"));
    }
    if let Some(a) = accel_mm_s2
        && !(a.is_finite() && a > 0.0)
    {
        return Err(Error::input(
            loc(),
            "the acceleration limit must be positive",
        ));
    }
    if waypoints.is_empty() {
        return Err(Error::input(loc(), "no waypoints to simulate"));
    }
    let segs = timeline(chain, waypoints, accel_mm_s2)?;
    let n = chain.dof();
    let total = segs.last().map_or(0.0, |s| s.t_start + s.duration);
    // Counted in floating point first: a tiny interval must not wrap the count.
    let count = (total / sample_interval_s).floor() + 1.0;
    if count.is_nan() || count > MAX_SAMPLES as f64 {
        return Err(Error::input(
            loc(),
            format!(
                "{count:.3e} samples ({total:.3} s every {sample_interval_s:e} s) are too many: at most {MAX_SAMPLES}"
            ),
        ));
    }
    let count = count as usize;
    let times = (0..count).map(|i| (i as f64 * sample_interval_s * 1e9).round() / 1e9);
    Ok(points_at(&segs, waypoints, n, times))
}

/// The commanded trajectory at increasing `times` (rounded to 1 ns by the
/// caller where it wants clean numbers): before the start at the first
/// waypoint, after the end at the last.
fn points_at(
    segs: &[Segment],
    waypoints: &[Waypoint],
    n: usize,
    times: impl Iterator<Item = f64>,
) -> Vec<TrajPoint> {
    let mut out = Vec::new();
    let mut seg = 0usize;
    for t in times {
        while seg + 1 < segs.len() && t >= segs[seg + 1].t_start {
            seg += 1;
        }
        let mut q = vec![0.0; n];
        let mut v = vec![0.0; n];
        let block = match segs.get(seg) {
            Some(s) => {
                let (p, sp) = s.s_and_v(t - s.t_start);
                s.position(p, &mut q, &mut v);
                for x in v.iter_mut() {
                    *x *= sp;
                }
                s.block
            }
            None => {
                q.copy_from_slice(&waypoints[0].q);
                waypoints[0].block
            }
        };
        out.push(TrajPoint { t, block, q, v });
    }
    out
}

/// The machine's own trajectory when the recording's clock is offset by
/// `offset_s`: at each of `traj`'s stamps t, the command at t − offset.
fn delayed(
    chain: &Chain,
    waypoints: &[Waypoint],
    accel_mm_s2: Option<f64>,
    traj: &[TrajPoint],
    offset_s: f64,
) -> Result<Vec<TrajPoint>> {
    let segs = timeline(chain, waypoints, accel_mm_s2)?;
    let mut out = points_at(
        &segs,
        waypoints,
        chain.dof(),
        traj.iter().map(|p| (p.t - offset_s).max(0.0)),
    );
    // The machine's own clock: effects that grow with time see it.
    for (o, p) in out.iter_mut().zip(traj) {
        o.t = p.t - offset_s;
    }
    Ok(out)
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
        let dt = traj[b].t - traj[a].t;
        let v: Vec<f64> = traj[b]
            .q
            .iter()
            .zip(&traj[a].q)
            .map(|(qb, qa)| if dt > 0.0 { (qb - qa) / dt } else { 0.0 })
            .collect();
        traj[i].v = v;
    }
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
    let mut out = Vec::with_capacity(traj.len());
    for p in traj {
        let (state, active) = walker.step(p, &mut machine.effects)?;
        let mask = active
            .iter()
            .enumerate()
            .filter(|(_, a)| **a)
            .fold(0u64, |m, (k, _)| m | 1 << k);
        out.push(machine.tip(&state, mask));
    }
    Ok(out)
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
/// Deterministic for a seed.
pub fn simulate(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    waypoints: &[Waypoint],
    effects: &[EffectSpec],
    opts: &SimOptions,
) -> Result<Recording> {
    if !(opts.noise_mm.is_finite() && opts.noise_mm >= 0.0) {
        return Err(Error::input(
            Location::new("<simulate>", 0, 0),
            "the noise must be a non-negative number of mm",
        ));
    }
    let faults_ok = opts.time_offset_s.is_finite()
        && (0.0..=1.0).contains(&opts.outlier_fraction)
        && opts.quantum.is_finite()
        && opts.quantum >= 0.0;
    if !faults_ok {
        return Err(Error::input(
            Location::new("<simulate>", 0, 0),
            "the clock offset must be finite, the outlier fraction 0 … 1 and the quantum ≥ 0",
        ));
    }
    let traj = sample_waypoints(chain, waypoints, opts.sample_interval_s, opts.accel_mm_s2)?;
    let tips = if opts.time_offset_s != 0.0 {
        let machine = delayed(
            chain,
            waypoints,
            opts.accel_mm_s2,
            &traj,
            opts.time_offset_s,
        )?;
        evaluate_trajectory(chain, errors, effects, &machine)?
    } else {
        evaluate_trajectory(chain, errors, effects, &traj)?
    };
    let mut rng = Rng::new(opts.seed);
    // Faults draw from their own stream, so that a recording with faults
    // has the same noise as the one without.
    let mut faults = Rng::new(opts.seed ^ 0x5eed_fa17);
    let round = |v: f64| {
        if opts.quantum > 0.0 {
            (v / opts.quantum).round() * opts.quantum
        } else {
            v
        }
    };
    let samples = traj
        .into_iter()
        .zip(tips)
        .map(|(p, tip)| {
            let mut meas = [
                tip.x + opts.noise_mm * rng.normal(),
                tip.y + opts.noise_mm * rng.normal(),
                tip.z + opts.noise_mm * rng.normal(),
            ];
            if opts.outlier_fraction > 0.0 && faults.uniform() < opts.outlier_fraction {
                let d = [faults.normal(), faults.normal(), faults.normal()];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
                let size = 0.1 + 0.9 * faults.uniform();
                for c in 0..3 {
                    meas[c] += size * d[c] / len;
                }
            }
            Sample {
                t: p.t,
                block: Some(p.block),
                q: p.q.into_iter().map(round).collect(),
                meas: meas.map(round),
                meas_axis: None,
                temps: Vec::new(),
            }
        })
        .collect();
    Ok(Recording {
        axes: chain.joints().iter().map(|j| j.name.clone()).collect(),
        temp_names: Vec::new(),
        samples,
    })
}
