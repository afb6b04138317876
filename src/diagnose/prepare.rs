//! The residual of a recording against the model, with everything the
//! effect fits need per sample: commanded positions, velocities, directions
//! of motion, the tool-tip Jacobian of the model chain, the tool axis and
//! the exact tip change of a unit rotary-centre offset.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use nalgebra::{Matrix4, Unit, Vector3};

use super::recording::Recording;
use super::simulate::central_pair;
use crate::error::{Error, Location, Result};
use crate::geometric::effects::{
    BoundEffect, DIRECTION_DEAD_BAND, DirectionTracker, EffectSpec, MotionState,
};
use crate::geometric::{BoundErrors, ErrorModel};
use crate::machine::chain::{Chain, Element, JointErrors, JointKind, NoErrors, error_matrix};

/// The model machine: chain with the model's fixed elements, error motions
/// and the model's own dynamic effects.
pub struct ModelMachine<'a> {
    /// Chain with the model's fixed elements (and pivot length) inserted.
    pub chain: Chain,
    errors: Option<BoundErrors<'a>>,
    /// The model's dynamic effects (backlash, servo lag, thermal drift).
    pub dynamic: Vec<BoundEffect>,
}

impl<'a> ModelMachine<'a> {
    /// Builds the model machine for `chain` and an optional error model.
    pub fn new(chain: &Chain, model: Option<&'a ErrorModel>) -> Result<Self> {
        match model {
            None => Ok(ModelMachine {
                chain: chain.clone(),
                errors: None,
                dynamic: Vec::new(),
            }),
            Some(m) => {
                let c = m.apply_fixed(chain)?;
                let errors = m.bind(&c)?;
                let dynamic = m
                    .effects
                    .iter()
                    .filter(|e| e.effect.kind().is_dynamic())
                    .map(|e| BoundEffect::new(e, &c))
                    .collect::<Result<Vec<_>>>()?;
                Ok(ModelMachine {
                    chain: c,
                    errors: Some(errors),
                    dynamic,
                })
            }
        }
    }

    /// The chain's error source.
    pub fn errors(&self) -> &dyn JointErrors {
        match &self.errors {
            Some(e) => e,
            None => &NoErrors,
        }
    }
}

/// Per-sample data for the fits. Positions in file units (mm, deg); the
/// Jacobian columns are per file unit (mm per mm, mm per deg).
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Number of samples.
    pub n: usize,
    /// Number of joints.
    pub dof: usize,
    /// Joint names.
    pub names: Vec<String>,
    /// Joint kinds.
    pub kinds: Vec<JointKind>,
    /// For each joint, the coordinate (0 x, 1 y, 2 z) of the frame before
    /// it that its axis (direction of motion or of rotation) lies closest
    /// to.
    pub axis_coord: Vec<usize>,
    /// Time, s.
    pub t: Vec<f64>,
    /// Block of each sample (`None` when the recording has none).
    pub block: Vec<Option<u64>>,
    /// Commanded positions, `n × dof`.
    pub q: Vec<f64>,
    /// Commanded velocities (the median of three quadratics' slopes,
    /// central differences near the ends and gaps), `n × dof`.
    pub v: Vec<f64>,
    /// Direction of the last motion, `n × dof`.
    pub dir: Vec<f64>,
    /// Tip Jacobian columns, `n × dof` 3-vectors.
    pub jac: Vec<[f64; 3]>,
    /// Tool axis per sample.
    pub tool_axis: Vec<[f64; 3]>,
    /// For each revolute joint: two unit offset directions perpendicular to
    /// its axis (frame before the joint) and the exact tip change for a
    /// 1 mm offset along each, per sample.
    pub rco: Vec<Option<RcoBasis>>,
    /// Residual measured − model, mm.
    pub r: Vec<[f64; 3]>,
    /// Model tip, mm.
    pub model_tip: Vec<[f64; 3]>,
    /// Sample indices where a new block (or pseudo-block) starts: the
    /// candidate onsets.
    pub onsets: Vec<usize>,
    /// For each joint: the tip change per unit of each of its six
    /// error-motion components (translations x, y, z of its own frame per
    /// mm, rotations about x, y, z per rad), per sample (the columns of its
    /// `error_motion`).
    pub motion: Vec<Option<Vec<[[f64; 3]; 6]>>>,
}

/// Rotary-centre-offset basis of one revolute joint.
#[derive(Debug, Clone)]
pub struct RcoBasis {
    /// Two unit directions perpendicular to the joint axis.
    pub dirs: [Vector3<f64>; 2],
    /// Tip change per mm along each direction, per sample.
    pub cols: Vec<[[f64; 3]; 2]>,
}

impl Prepared {
    /// `q` of joint `j` at sample `i`.
    #[inline]
    pub fn qj(&self, i: usize, j: usize) -> f64 {
        self.q[i * self.dof + j]
    }
    /// Velocity of joint `j` at sample `i`.
    #[inline]
    pub fn vj(&self, i: usize, j: usize) -> f64 {
        self.v[i * self.dof + j]
    }
    /// Direction of joint `j` at sample `i`.
    #[inline]
    pub fn dirj(&self, i: usize, j: usize) -> f64 {
        self.dir[i * self.dof + j]
    }
    /// Jacobian column of joint `j` at sample `i`.
    #[inline]
    pub fn jj(&self, i: usize, j: usize) -> [f64; 3] {
        self.jac[i * self.dof + j]
    }

    /// Number of residual rows (3 per sample).
    pub fn rows(&self) -> usize {
        3 * self.n
    }

    /// The motion state of sample `i`, for evaluating effects.
    pub fn state(&self, i: usize) -> MotionState<'_> {
        let a = i * self.dof;
        MotionState {
            t: self.t[i],
            q: &self.q[a..a + self.dof],
            v: &self.v[a..a + self.dof],
            dir: &self.dir[a..a + self.dof],
        }
    }
}

/// Exact tool-tip change, at joint values `q` (internal units), of a 1 mm
/// offset along each of `dirs[j]` of every revolute joint `j` that has them:
/// the chain with `Trans(d)` inserted before the joint and `Trans(−d)` after
/// it. With the joint's transform `G = [R t; 0 1]` (motion and error
/// motion), `Trans(d)·G·Trans(−d) − G = [0, d − R d; 0 0]`, so the tip moves
/// by `A·(d − R d)`, `A` the linear part of the product of the elements
/// before the joint: one pass along the chain gives every column.
fn rco_columns(
    chain: &Chain,
    q: &[f64],
    errors: &dyn JointErrors,
    dirs: &[Option<[Vector3<f64>; 2]>],
    out: &mut [[[f64; 3]; 2]],
) {
    let mut prefix = Matrix4::<f64>::identity();
    for el in chain.elements() {
        match el {
            Element::Fixed(m) => prefix *= m,
            Element::Joint(j) => {
                let j = *j;
                let mut g = chain.joint_motion(j, q[j]);
                if let Some(e) = errors.error(j, q[j]) {
                    g *= error_matrix(&e);
                }
                if let Some(d) = &dirs[j] {
                    let a = prefix.fixed_view::<3, 3>(0, 0);
                    let r = g.fixed_view::<3, 3>(0, 0);
                    for k in 0..2 {
                        let v = a * (d[k] - r * d[k]);
                        out[j][k] = [v.x, v.y, v.z];
                    }
                }
                prefix *= g;
            }
        }
    }
}

/// Two unit vectors perpendicular to `u`.
fn perpendicular_pair(u: &Unit<Vector3<f64>>) -> [Vector3<f64>; 2] {
    let u = u.into_inner();
    let pick = if u.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (pick - u * u.dot(&pick)).normalize();
    let e2 = u.cross(&e1).normalize();
    [e1, e2]
}

/// Largest number of pseudo-blocks used as candidate onsets when the
/// recording has no block column (or very many blocks).
pub const MAX_ONSETS: usize = 400;

/// A step of the sampling more than this many times the steps beside it
/// is a gap (a trace buffer overflow, a paused export): a change of the
/// sampling rate changes the steps for good, jitter by a fraction.
pub const GAP_RATIO: f64 = 3.0;

/// For each step of the time stamps `t` (between samples `i` and `i + 1`),
/// whether it is a gap: more than [`GAP_RATIO`] times each step beside it.
pub fn gap_steps(t: &[f64]) -> Vec<bool> {
    let dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    (0..dt.len())
        .map(|i| {
            let before = i.checked_sub(1).map(|k| dt[k]);
            let after = dt.get(i + 1).copied();
            let beside = match (before, after) {
                (Some(a), Some(b)) => a.max(b),
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => return false,
            };
            dt[i] > GAP_RATIO * beside
        })
        .collect()
}

/// The two samples the velocity at sample `i` of `t` (`t.len() ≥ 2`) is
/// differenced over: its neighbours, or one of them and itself at an end
/// or at the edge of a gap (`gap`: [`gap_steps`] of `t`), and between two
/// gaps the shorter side.
pub fn difference_pair(i: usize, t: &[f64], gap: &[bool]) -> (usize, usize) {
    let n = t.len();
    let (mut a, mut b) = central_pair(i, n);
    if b > i && gap[i] {
        b = i;
    }
    if a < i && gap[i - 1] {
        a = i;
    }
    if a == b {
        (a, b) = if i + 1 < n && (i == 0 || t[i + 1] - t[i] <= t[i] - t[i - 1]) {
            (i, i + 1)
        } else {
            (i - 1, i)
        };
    }
    (a, b)
}

/// Velocities of the commands. Where two samples on each side are
/// without a gap, the median of the slopes at the sample of the
/// quadratics through the three samples to its left, around it and to its
/// right: a command that changes its acceleration once between two
/// samples (a corner of the feed profile) spoils the quadratics across the
/// corner, and the median is one that does not cross it. A central
/// difference there missed the speed by up to a·h/2: with a 20 ms servo
/// lag sampled at 10 Hz, spikes of 0.18 mm. Elsewhere central
/// differences, one-sided at the ends and at the edges of gaps
/// ([`gap_steps`]): a difference across a gap would be the mean over
/// seconds of motion the recording does not show.
fn velocities(t: &[f64], q: &[f64], dof: usize) -> Vec<f64> {
    let n = t.len();
    let mut v = vec![0.0; n * dof];
    if n < 2 {
        return v;
    }
    let gap = gap_steps(t);
    for i in 0..n {
        // Two samples on each side without a gap: the median of the
        // slopes at t_i of the quadratics through the left, central and
        // right three samples.
        if i >= 2 && i + 2 < n && !gap[i - 2..=i + 1].iter().any(|g| *g) {
            for j in 0..dof {
                let y = |k: usize| q[k * dof + j];
                let slope = |k: usize| {
                    quadratic_slope([t[k], t[k + 1], t[k + 2]], [y(k), y(k + 1), y(k + 2)], t[i])
                };
                let mut three = [slope(i - 2), slope(i - 1), slope(i)];
                three.sort_by(f64::total_cmp);
                v[i * dof + j] = three[1];
            }
            continue;
        }
        let (a, b) = difference_pair(i, t, &gap);
        let dt = t[b] - t[a];
        for j in 0..dof {
            v[i * dof + j] = (q[b * dof + j] - q[a * dof + j]) / dt;
        }
    }
    v
}

/// The slope at `x` of the quadratic through the points `(t, y)`.
fn quadratic_slope(t: [f64; 3], y: [f64; 3], x: f64) -> f64 {
    let [t0, t1, t2] = t;
    y[0] * ((x - t1) + (x - t2)) / ((t0 - t1) * (t0 - t2))
        + y[1] * ((x - t0) + (x - t2)) / ((t1 - t0) * (t1 - t2))
        + y[2] * ((x - t0) + (x - t1)) / ((t2 - t0) * (t2 - t1))
}

/// Prepares `rec` against the model machine.
pub fn prepare(machine: &ModelMachine, rec: &Recording) -> Result<Prepared> {
    let chain = &machine.chain;
    let dof = chain.dof();
    let n = rec.samples.len();
    if rec.axes.len() != dof {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "the recording has {} axes, the machine {} joints",
                rec.axes.len(),
                dof
            ),
        ));
    }
    let t: Vec<f64> = rec.samples.iter().map(|s| s.t).collect();
    for (i, s) in rec.samples.iter().enumerate() {
        let bad = |what: &str| {
            Error::input(
                Location::new("<recording>", 0, 0),
                format!("sample {i} (t = {} s): {what}", s.t),
            )
        };
        if !s.t.is_finite() || (i > 0 && s.t <= rec.samples[i - 1].t) {
            return Err(bad("time must be finite and strictly increasing"));
        }
        if s.q.iter().chain(&s.meas).any(|v| !v.is_finite()) {
            return Err(bad("axis and measured values must be finite numbers"));
        }
    }
    let block: Vec<Option<u64>> = rec.samples.iter().map(|s| s.block).collect();
    let mut q = Vec::with_capacity(n * dof);
    for s in &rec.samples {
        if s.q.len() != dof {
            return Err(Error::input(
                Location::new("<recording>", 0, 0),
                "a sample has the wrong number of axis values",
            ));
        }
        q.extend_from_slice(&s.q);
    }
    let v = velocities(&t, &q, dof);
    let mut dir = vec![0.0; n * dof];
    let mut trackers = vec![DirectionTracker::new(DIRECTION_DEAD_BAND); dof];
    for i in 0..n {
        for j in 0..dof {
            dir[i * dof + j] = trackers[j].update(q[i * dof + j]);
        }
    }
    let kinds: Vec<JointKind> = chain.joints().iter().map(|j| j.kind).collect();
    let axis_coord: Vec<usize> = chain.joints().iter().map(|j| j.axis.iamax()).collect();
    let deg = std::f64::consts::PI / 180.0;
    // Onsets of the model's dynamic effects.
    let mut dynamic = machine.dynamic.clone();
    let mut active = vec![false; dynamic.len()];
    // Rotary-centre-offset bases: two unit offsets perpendicular to each
    // revolute joint's axis.
    let rco_dirs: Vec<Option<[Vector3<f64>; 2]>> = (0..dof)
        .map(|j| {
            (kinds[j] == JointKind::Revolute).then(|| perpendicular_pair(&chain.joints()[j].axis))
        })
        .collect();
    let mut rco: Vec<Option<RcoBasis>> = rco_dirs
        .iter()
        .map(|d| {
            d.map(|dirs| RcoBasis {
                dirs,
                cols: Vec::with_capacity(n),
            })
        })
        .collect();
    let mut rco_cols = vec![[[0.0; 3]; 2]; dof];
    let mut motion: Vec<Option<Vec<[[f64; 3]; 6]>>> =
        kinds.iter().map(|_| Some(Vec::with_capacity(n))).collect();
    let mut jac = Vec::with_capacity(n * dof);
    let mut tool_axis = Vec::with_capacity(n);
    let mut r = Vec::with_capacity(n);
    let mut model_tip = Vec::with_capacity(n);
    let errors = machine.errors();
    let mut qi = vec![0.0; dof];
    for i in 0..n {
        let st = MotionState {
            t: t[i],
            q: &q[i * dof..(i + 1) * dof],
            v: &v[i * dof..(i + 1) * dof],
            dir: &dir[i * dof..(i + 1) * dof],
        };
        for (k, e) in dynamic.iter_mut().enumerate() {
            if !active[k]
                && e.spec
                    .from_block
                    .is_none_or(|b| block[i].is_none_or(|bi| bi >= b))
            {
                active[k] = true;
                e.t0 = t[i];
            }
        }
        qi[..dof].copy_from_slice(&st.q[..dof]);
        for (k, e) in dynamic.iter().enumerate() {
            if active[k]
                && let Some(j) = e.joint
            {
                qi[j] += e.delta_q(&st);
            }
        }
        for j in 0..dof {
            if kinds[j] == JointKind::Revolute {
                qi[j] *= deg;
            }
        }
        let (pose, jm) = chain.pose_and_jacobian(&qi, errors);
        for j in 0..dof {
            let f = if kinds[j] == JointKind::Revolute {
                deg
            } else {
                1.0
            };
            jac.push([jm[(0, j)] * f, jm[(1, j)] * f, jm[(2, j)] * f]);
        }
        tool_axis.push([pose.axis.x, pose.axis.y, pose.axis.z]);
        let m = rec.samples[i].meas;
        r.push([m[0] - pose.tip.x, m[1] - pose.tip.y, m[2] - pose.tip.z]);
        model_tip.push([pose.tip.x, pose.tip.y, pose.tip.z]);
        for (j, cols) in motion.iter_mut().enumerate() {
            let Some(cols) = cols else { continue };
            let mut c6 = [[0.0; 3]; 6];
            for (c, col) in c6.iter_mut().enumerate() {
                let eps = if c < 3 {
                    MOTION_STEP_MM
                } else {
                    MOTION_STEP_RAD
                };
                let poked = Poke {
                    base: errors,
                    joint: j,
                    comp: c,
                    eps,
                };
                let t = chain.pose(&qi, &poked).tip;
                *col = [
                    (t.x - pose.tip.x) / eps,
                    (t.y - pose.tip.y) / eps,
                    (t.z - pose.tip.z) / eps,
                ];
            }
            cols.push(c6);
        }
        if rco_dirs.iter().any(Option::is_some) {
            rco_columns(chain, &qi, errors, &rco_dirs, &mut rco_cols);
            for j in 0..dof {
                if let Some(b) = rco[j].as_mut() {
                    b.cols.push(rco_cols[j]);
                }
            }
        }
    }
    // Candidate onsets: first sample of every block; thinned to MAX_ONSETS.
    let mut onsets: Vec<usize> = Vec::new();
    if block.iter().all(Option::is_some) {
        for i in 0..n {
            if i == 0 || block[i] != block[i - 1] {
                onsets.push(i);
            }
        }
    }
    if onsets.len() > MAX_ONSETS || onsets.is_empty() {
        let step = (n as f64 / MAX_ONSETS as f64).max(1.0);
        let mut thinned: Vec<usize> = Vec::new();
        let base: Vec<usize> = if onsets.is_empty() {
            (0..n).collect()
        } else {
            onsets.clone()
        };
        let mut next = 0.0;
        for &i in &base {
            if i as f64 >= next {
                thinned.push(i);
                next = i as f64 + step;
            }
        }
        onsets = thinned;
    }
    Ok(Prepared {
        n,
        dof,
        names: chain.names(),
        kinds,
        axis_coord,
        t,
        block,
        q,
        v,
        dir,
        jac,
        tool_axis,
        rco,
        r,
        model_tip,
        onsets,
        motion,
    })
}

/// Step of the translation error motion by which its tip change is taken
/// (the change is linear in it), mm.
const MOTION_STEP_MM: f64 = 1e-3;

/// Step of the rotational error motion by which its tip change is taken,
/// rad (a lever of a metre moves the tip by 1 µm: still linear, and far
/// above the rounding of the pose).
const MOTION_STEP_RAD: f64 = 1e-6;

/// An error source with one component of one joint's error motion raised.
struct Poke<'a> {
    base: &'a dyn JointErrors,
    joint: usize,
    comp: usize,
    eps: f64,
}

impl JointErrors for Poke<'_> {
    fn error(&self, joint: usize, q: f64) -> Option<crate::machine::chain::ErrorMotion> {
        let e = self.base.error(joint, q);
        if joint != self.joint {
            return e;
        }
        let mut e = e.unwrap_or_else(crate::machine::chain::ErrorMotion::zeros);
        e[self.comp] += self.eps;
        Some(e)
    }
}

/// Robust noise floor of the residual: for each coordinate, the median
/// absolute first difference divided by 0.6745·√2 (the first difference of
/// white noise has standard deviation σ√2; a smooth effect hardly changes
/// between consecutive samples, and the median ignores the few jumps at
/// reversals or onsets). Returns the per-coordinate figures and their
/// quadratic mean, floored at 1 nm.
pub fn noise_floor(r: &[[f64; 3]]) -> ([f64; 3], f64) {
    let mut per = [0.0; 3];
    if r.len() < 3 {
        return (per, 1e-6);
    }
    for (c, out) in per.iter_mut().enumerate() {
        let mut d: Vec<f64> = r.windows(2).map(|w| (w[1][c] - w[0][c]).abs()).collect();
        let mid = d.len() / 2;
        d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        *out = d[mid] / (0.674_489_75 * std::f64::consts::SQRT_2);
    }
    let pooled = ((per[0] * per[0] + per[1] * per[1] + per[2] * per[2]) / 3.0).sqrt();
    (per, pooled.max(1e-6))
}

/// Helper for callers: effect specs bound to the model chain.
pub fn bind_all(specs: &[EffectSpec], chain: &Chain) -> Result<Vec<BoundEffect>> {
    specs.iter().map(|s| BoundEffect::new(s, chain)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::{ErrorMotion, translation};

    /// Error motions with every component non-zero and varying with q.
    struct Wobbly;

    impl JointErrors for Wobbly {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            let k = joint as f64 + 1.0;
            Some(ErrorMotion::from_fn(|c, _| {
                let s = if c < 3 { 2e-3 } else { 3e-5 };
                s * (k * q + c as f64).sin()
            }))
        }
    }

    #[test]
    fn rotary_centre_columns_equal_the_offset_chains() {
        let mut c = Chain::new();
        c.joint("A", JointKind::Revolute, Vector3::new(-1.0, 0.0, 0.0));
        c.translate(Vector3::new(3.0, -4.0, 12.0));
        c.joint("X", JointKind::Prismatic, Vector3::x());
        c.rotate(Vector3::new(0.2, 1.0, 0.1), 0.3);
        c.joint("B", JointKind::Revolute, Vector3::y());
        c.translate(Vector3::new(0.0, 0.0, -265.0));
        let q = [0.7, 41.0, -0.4];
        let dirs: Vec<Option<[Vector3<f64>; 2]>> = c
            .joints()
            .iter()
            .map(|j| (j.kind == JointKind::Revolute).then(|| perpendicular_pair(&j.axis)))
            .collect();
        let mut cols = vec![[[0.0; 3]; 2]; 3];
        rco_columns(&c, &q, &Wobbly, &dirs, &mut cols);
        let base = c.pose(&q, &Wobbly).tip;
        for (j, d) in dirs.iter().enumerate() {
            let Some(d) = d else { continue };
            let el = c.joints()[j].element;
            for k in 0..2 {
                let off = c
                    .with_fixed_inserted(el + 1, translation(&(-d[k])))
                    .with_fixed_inserted(el, translation(&d[k]));
                let v = off.pose(&q, &Wobbly).tip - base;
                for a in 0..3 {
                    assert!(
                        (v[a] - cols[j][k][a]).abs() < 1e-9,
                        "{j} {k}: {v} vs {:?}",
                        cols[j][k]
                    );
                }
                assert!(v.norm() > 1e-3);
            }
        }
    }
}
