//! Linearised effect fits: design columns of every catalogue effect, the
//! onset (change-point) profile by suffix sums, one-dimensional searches of
//! time constants and periods, time-blocked cross-validation, and forward
//! stepwise selection.
//!
//! Every effect is a parametrised Δq on a joint (or a fixed element) and
//! reaches the tool tip through the model chain: residual ≈ J_tip(q)·Δq(θ).
//! Amplitudes enter linearly; a time constant or a period is searched on a
//! grid and refined by golden-section search; the onset is profiled over
//! every block start at once.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};

use super::motion_components::{
    MOTION_BASIS, MOTION_HARMONICS, TRANSLATIONS, covered_arc, mask_components, motion_span,
    motion_weights, visible_components,
};
use super::prepare::Prepared;
use crate::geometric::effects::{Effect, EffectKind, EffectSpec};
use crate::geometric::error_motion::MotionSpan;
use crate::machine::chain::JointKind;

mod effect;
mod search;
mod spectrum;

pub use effect::{Fitted, nl_derivative, onset_derivative, parameter_sd, term_effect};
pub use search::{
    Candidate, MIN_VIBRATION_HZ, SearchCtx, TAU_GRID, TAU_RANGE, VIBRATION_GRID, search_family,
};

/// A family of candidate terms: one effect on one axis (or pair).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Backlash of a joint.
    Backlash(usize),
    /// Servo lag of a joint.
    ServoLag(usize),
    /// Thermal drift of a linear joint.
    ThermalDrift(usize),
    /// Scale error of a joint.
    Scale(usize),
    /// Squareness: `(first, second)`, Δq_second = S·q_first.
    Squareness(usize, usize),
    /// Cyclic error of a joint.
    Cyclic(usize),
    /// Zero offset of a joint.
    ZeroOffset(usize),
    /// Rotary centre offset of a revolute joint.
    RotaryCenterOffset(usize),
    /// Pivot (tool) length.
    PivotLength,
    /// Vibration of a linear joint (non-linear parameter: frequency, Hz).
    Vibration(usize),
    /// Error motion of a revolute joint once and twice per turn, in the
    /// components of the mask (bit c: component c of the joint's frame,
    /// translations x, y, z then rotations about x, y, z; see
    /// [`visible_components`]).
    ErrorMotion(usize, u8),
    /// Error motion of a prismatic joint as cubic B-splines over the
    /// recorded travel, in the components of the mask.
    LinearMotion(usize, u8),
    /// Not machine physics: a constant offset of the measured tip in the
    /// workpiece frame (the measuring system's registration).
    Registration,
    /// Not machine physics: a constant offset of the measured tip in the
    /// workpiece frame from an onset on (a tracker that re-acquires its
    /// target a few µm off after a beam break, a probe re-zeroed part-way):
    /// a second registration that starts part-way.
    RegistrationStep,
    /// Not machine physics: a slow wander of the measured tip with time
    /// ([`WANDER_BASIS`] cubic B-splines over the recording, per
    /// workpiece coordinate).
    Wander,
}

/// Most [`Family::RegistrationStep`]s one model holds: each a beam break
/// of a tracker (or a probe re-zeroed); more steps than this in one
/// recording are a measurement to repeat, not to model.
pub const MAX_REGISTRATION_STEPS: usize = 3;

/// Basis functions in time of a [`Family::Wander`], per coordinate: cubic
/// B-splines with uniform knots, 13 intervals over the recording (with 5,
/// the faster part of a wander of periods down to a minute was left, and
/// error motions took it up).
pub const WANDER_BASIS: usize = 16;

/// The B-spline basis in time of a wander over the recording of `prep`.
pub fn wander_span(prep: &Prepared) -> Option<MotionSpan> {
    let (lo, hi) = (prep.t.first()?, prep.t.last()?);
    MotionSpan::new(*lo, *hi, WANDER_BASIS)
}

impl Family {
    /// Its catalogue kind.
    pub fn kind(self) -> EffectKind {
        match self {
            Family::Backlash(_) => EffectKind::Backlash,
            Family::ServoLag(_) => EffectKind::ServoLag,
            Family::ThermalDrift(_) => EffectKind::ThermalDrift,
            Family::Scale(_) => EffectKind::Scale,
            Family::Squareness(..) => EffectKind::Squareness,
            Family::Cyclic(_) => EffectKind::Cyclic,
            Family::ZeroOffset(_) => EffectKind::ZeroOffset,
            Family::RotaryCenterOffset(_) => EffectKind::RotaryCenterOffset,
            Family::PivotLength => EffectKind::PivotLength,
            Family::Vibration(_) => EffectKind::Vibration,
            Family::ErrorMotion(..) | Family::LinearMotion(..) => EffectKind::ErrorMotion,
            Family::Registration | Family::RegistrationStep => EffectKind::Registration,
            Family::Wander => EffectKind::Wander,
        }
    }

    /// The joint the effect moves (for squareness the second axis).
    pub fn joint(self) -> Option<usize> {
        match self {
            Family::Backlash(j)
            | Family::ServoLag(j)
            | Family::ThermalDrift(j)
            | Family::Scale(j)
            | Family::Cyclic(j)
            | Family::ZeroOffset(j)
            | Family::RotaryCenterOffset(j)
            | Family::Vibration(j)
            | Family::ErrorMotion(j, _)
            | Family::LinearMotion(j, _) => Some(j),
            Family::Squareness(_, b) => Some(b),
            Family::PivotLength
            | Family::Registration
            | Family::RegistrationStep
            | Family::Wander => None,
        }
    }

    /// Axis label (`X`, `XZ`, none).
    pub fn axis_label(self, names: &[String]) -> Option<String> {
        match self {
            Family::Squareness(a, b) => Some(format!("{}{}", names[a], names[b])),
            Family::PivotLength
            | Family::Registration
            | Family::RegistrationStep
            | Family::Wander => None,
            f => f.joint().map(|j| names[j].clone()),
        }
    }

    /// Number of linear coefficients.
    pub fn linear_params(self) -> usize {
        match self {
            Family::Cyclic(_) | Family::RotaryCenterOffset(_) | Family::Vibration(_) => 2,
            Family::ErrorMotion(_, m) => m.count_ones() as usize * 2 * MOTION_HARMONICS as usize,
            Family::LinearMotion(_, m) => m.count_ones() as usize * MOTION_BASIS,
            Family::Registration | Family::RegistrationStep => 3,
            Family::Wander => 3 * WANDER_BASIS,
            _ => 1,
        }
    }

    /// Whether `self` and `other` model the same thing, so that one model
    /// holds at most one of them: the same family, two error motions of
    /// one joint (with different components), or a registration and a
    /// wander (whose curve holds every constant).
    pub fn same_slot(self, other: Family) -> bool {
        match (self, other) {
            // Each registration step has its own moment: a tracker can
            // lose its beam more than once ([`MAX_REGISTRATION_STEPS`]).
            (Family::RegistrationStep, Family::RegistrationStep) => false,
            (Family::ErrorMotion(a, _), Family::ErrorMotion(b, _))
            | (Family::LinearMotion(a, _), Family::LinearMotion(b, _)) => a == b,
            (Family::Registration | Family::Wander, Family::Registration | Family::Wander) => true,
            _ => self == other,
        }
    }

    /// Whether it is a simple family: a few parameters for one physical
    /// cause. Not simple: an error motion's series or spline, and the
    /// registration and the wander of the measurement, which can each sum
    /// up several simple effects at once (see [`super::stepwise`]).
    pub fn is_simple(self) -> bool {
        !matches!(
            self,
            Family::ErrorMotion(..)
                | Family::LinearMotion(..)
                | Family::Registration
                | Family::RegistrationStep
                | Family::Wander
        )
    }

    /// Whether a non-linear parameter (τ or period) is searched.
    pub fn has_nonlinear(self) -> bool {
        matches!(
            self,
            Family::ThermalDrift(_) | Family::Cyclic(_) | Family::Vibration(_)
        )
    }

    /// Every family that applies to the machine of `prep`.
    pub fn all(prep: &Prepared) -> Vec<Family> {
        let mut v = Vec::new();
        let lin: Vec<usize> = (0..prep.dof)
            .filter(|&j| prep.kinds[j] == JointKind::Prismatic)
            .collect();
        for j in 0..prep.dof {
            v.push(Family::Backlash(j));
            v.push(Family::ServoLag(j));
            if prep.kinds[j] == JointKind::Prismatic {
                v.push(Family::ThermalDrift(j));
                v.push(Family::Vibration(j));
                motion_families(prep, j, Family::LinearMotion, &mut v);
            }
            v.push(Family::Scale(j));
            v.push(Family::Cyclic(j));
            v.push(Family::ZeroOffset(j));
            if prep.kinds[j] == JointKind::Revolute {
                v.push(Family::RotaryCenterOffset(j));
                motion_families(prep, j, Family::ErrorMotion, &mut v);
            }
        }
        for &a in &lin {
            for &b in &lin {
                if a != b && !prep.revolute_between(a, b) {
                    v.push(Family::Squareness(a, b));
                }
            }
        }
        v.push(Family::PivotLength);
        v.push(Family::Registration);
        v.push(Family::RegistrationStep);
        v.push(Family::Wander);
        v
    }
}

/// The error-motion families of joint `j`: each visible component alone,
/// its visible translations together, and every visible component (the
/// selection pays for each coefficient, so it prefers the smallest family
/// that explains the residual; one model holds at most one of them, see
/// [`Family::same_slot`]).
fn motion_families(prep: &Prepared, j: usize, fam: fn(usize, u8) -> Family, v: &mut Vec<Family>) {
    let all = visible_components(prep, j);
    let translations = all & TRANSLATIONS;
    let mut masks: Vec<u8> = mask_components(all).map(|c| 1u8 << c).collect();
    masks.extend([translations, all]);
    masks.retain(|&m| m != 0);
    masks.sort_unstable();
    masks.dedup();
    v.extend(masks.into_iter().map(|m| fam(j, m)));
}

impl Prepared {
    /// Whether a revolute joint lies between joints `a` and `b` (in joint
    /// order, which is chain order).
    pub fn revolute_between(&self, a: usize, b: usize) -> bool {
        let (lo, hi) = (a.min(b), a.max(b));
        (lo + 1..hi).any(|k| self.kinds[k] == JointKind::Revolute)
    }
}

/// Design columns: row `3·i + c` (sample i, coordinate c), `k` columns,
/// row-major.
#[derive(Debug, Clone, Default)]
pub struct Cols {
    /// Number of columns.
    pub k: usize,
    /// `rows × k` values.
    pub data: Vec<f64>,
}

impl Cols {
    fn zeros(rows: usize, k: usize) -> Cols {
        Cols {
            k,
            data: vec![0.0; rows * k],
        }
    }
    #[inline]
    fn row(&self, r: usize) -> &[f64] {
        &self.data[r * self.k..(r + 1) * self.k]
    }
    /// Appends the columns of `other` (same rows).
    pub fn hcat(&self, other: &Cols) -> Cols {
        if self.k == 0 {
            return other.clone();
        }
        if other.k == 0 {
            return self.clone();
        }
        let rows = self.data.len() / self.k;
        let k = self.k + other.k;
        let mut data = Vec::with_capacity(rows * k);
        for r in 0..rows {
            data.extend_from_slice(self.row(r));
            data.extend_from_slice(other.row(r));
        }
        Cols { k, data }
    }
}

/// A candidate term: a family with its non-linear parameter (τ in s, or
/// period in mm/deg; 0 when none) and its onset sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// Family.
    pub family: Family,
    /// τ (s) or period (mm, deg); 0 when not applicable.
    pub nl: f64,
    /// First sample in which the effect acts.
    pub onset: usize,
}

/// Base columns of a family for a non-linear parameter, without onset
/// mask. Thermal drift gets two columns `[J, J·exp(−t/τ)]` that the onset
/// combines as `J·(1 − exp(−(t − t₀)/τ)) = col₀ − exp(t₀/τ)·col₁`.
pub fn base_columns(prep: &Prepared, fam: Family, nl: f64) -> Cols {
    let rows = prep.rows();
    let k = match fam {
        Family::ThermalDrift(_) => 2,
        f => f.linear_params(),
    };
    let mut c = Cols::zeros(rows, k);
    let t_ref = prep.t.first().copied().unwrap_or(0.0);
    let span = match fam {
        Family::LinearMotion(j, _) => motion_span(prep, j),
        Family::Wander => wander_span(prep),
        _ => None,
    };
    for i in 0..prep.n {
        let mut put = |col: usize, v: [f64; 3]| {
            for (a, x) in v.iter().enumerate() {
                c.data[(3 * i + a) * k + col] = *x;
            }
        };
        let scaled = |j: usize, s: f64| {
            let jj = prep.jj(i, j);
            [jj[0] * s, jj[1] * s, jj[2] * s]
        };
        match fam {
            Family::Backlash(j) => put(0, scaled(j, -0.5 * prep.dirj(i, j))),
            Family::ServoLag(j) => put(0, scaled(j, -prep.vj(i, j))),
            Family::ThermalDrift(j) => {
                put(0, scaled(j, 1.0));
                put(1, scaled(j, (-(prep.t[i] - t_ref) / nl).exp()));
            }
            Family::Scale(j) => put(0, scaled(j, 1e-6 * prep.qj(i, j))),
            Family::Squareness(a, b) => put(0, scaled(b, 1e-6 * prep.qj(i, a))),
            Family::Cyclic(j) => {
                let x = std::f64::consts::TAU * prep.qj(i, j) / nl;
                let (s, co) = x.sin_cos();
                put(0, scaled(j, s));
                put(1, scaled(j, co));
            }
            Family::ZeroOffset(j) => put(0, scaled(j, 1.0)),
            Family::RotaryCenterOffset(j) => {
                if let Some(b) = &prep.rco[j] {
                    put(0, b.cols[i][0]);
                    put(1, b.cols[i][1]);
                }
            }
            Family::PivotLength => put(0, prep.tool_axis[i]),
            Family::Registration | Family::RegistrationStep => {
                put(0, [1.0, 0.0, 0.0]);
                put(1, [0.0, 1.0, 0.0]);
                put(2, [0.0, 0.0, 1.0]);
            }
            Family::Wander => {
                if let Some(sp) = &span {
                    for (b, w) in sp.values(prep.t[i]).into_iter().enumerate() {
                        put(b, [w, 0.0, 0.0]);
                        put(WANDER_BASIS + b, [0.0, w, 0.0]);
                        put(2 * WANDER_BASIS + b, [0.0, 0.0, w]);
                    }
                }
            }
            Family::ErrorMotion(j, mask) | Family::LinearMotion(j, mask) => {
                let Some(Some(m)) = prep.motion.get(j) else {
                    continue;
                };
                let w = motion_weights(prep, j, i, span.as_ref());
                for (p, c) in mask_components(mask).enumerate() {
                    let col = m[i][c];
                    for (k, wk) in w.iter().enumerate() {
                        put(p * w.len() + k, col.map(|x| x * wk));
                    }
                }
            }
            Family::Vibration(j) => {
                let x = std::f64::consts::TAU * nl * prep.t[i];
                let (s, co) = x.sin_cos();
                put(0, scaled(j, s));
                put(1, scaled(j, co));
            }
        }
    }
    c
}

/// For thermal drift, the combination vector of the two base columns for an
/// onset at time `t0`.
fn thermal_gamma(prep: &Prepared, tau: f64, t0: f64) -> [f64; 2] {
    let t_ref = prep.t.first().copied().unwrap_or(0.0);
    [1.0, -((t0 - t_ref) / tau).exp()]
}

/// Columns of a term (onset mask applied), `linear_params` wide.
pub fn term_columns(prep: &Prepared, term: &Term) -> Cols {
    let base = base_columns(prep, term.family, term.nl);
    let k = term.family.linear_params();
    let mut out = Cols::zeros(prep.rows(), k);
    match term.family {
        Family::ThermalDrift(_) => {
            let g = thermal_gamma(prep, term.nl, prep.t[term.onset.min(prep.n - 1)]);
            for r in 3 * term.onset..prep.rows() {
                let b = base.row(r);
                out.data[r] = b[0] * g[0] + b[1] * g[1];
            }
        }
        _ => {
            let start = 3 * term.onset * k;
            out.data[start..].copy_from_slice(&base.data[start..]);
        }
    }
    out
}

/// Columns of several terms side by side.
pub fn design(prep: &Prepared, terms: &[Term]) -> Cols {
    let mut d = Cols {
        k: 0,
        data: Vec::new(),
    };
    for t in terms {
        d = d.hcat(&term_columns(prep, t));
    }
    d
}

/// Pseudo-inverse of a small symmetric positive semi-definite matrix:
/// scaled to unit diagonal first (columns of very different units), then
/// inverted by eigen-decomposition with a relative cut-off.
pub fn pinv_sym(m: &DMatrix<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    if n == 0 {
        return DMatrix::zeros(0, 0);
    }
    let d: Vec<f64> = (0..n)
        .map(|k| {
            let v = m[(k, k)];
            if v > 0.0 && v.is_finite() {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let scaled = DMatrix::from_fn(n, n, |a, b| m[(a, b)] * d[a] * d[b]);
    let e = scaled.symmetric_eigen();
    let max = e.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let cut = crate::linalg::rank::fit_cutoff(max);
    let mut inv = DMatrix::zeros(n, n);
    for k in 0..n {
        let l = e.eigenvalues[k];
        if l > cut && l > 0.0 {
            let v = e.eigenvectors.column(k);
            inv += (v * v.transpose()) / l;
        }
    }
    DMatrix::from_fn(n, n, |a, b| inv[(a, b)] * d[a] * d[b])
}

/// The currently selected design with its normal equations.
#[derive(Debug, Clone)]
pub struct Selected {
    /// Columns.
    pub cols: Cols,
    /// `(SᵀS)⁺`.
    pub ginv: DMatrix<f64>,
    /// `Sᵀr`.
    pub h: DVector<f64>,
}

impl Selected {
    /// Normal equations of `cols` against the residual.
    pub fn new(prep: &Prepared, cols: Cols) -> Selected {
        let k = cols.k;
        let mut g = DMatrix::zeros(k, k);
        let mut h = DVector::zeros(k);
        if k > 0 {
            for i in 0..prep.n {
                for a in 0..3 {
                    let row = cols.row(3 * i + a);
                    let r = prep.r[i][a];
                    for p in 0..k {
                        h[p] += row[p] * r;
                        for q in 0..=p {
                            g[(p, q)] += row[p] * row[q];
                        }
                    }
                }
            }
            for p in 0..k {
                for q in 0..p {
                    g[(q, p)] = g[(p, q)];
                }
            }
        }
        Selected {
            ginv: pinv_sym(&g),
            cols,
            h,
        }
    }
}

/// Reduction of the residual sum of squares (mm²) when a candidate with
/// `base` columns is added to `sel`, for every onset in `onsets` (sample
/// indices, ascending). `gamma(onset)` combines the base columns into the
/// candidate's (identity when `None`). Onsets with fewer than `min_after`
/// samples after them are skipped (reported as 0).
pub fn scan(
    prep: &Prepared,
    sel: &Selected,
    base: &Cols,
    onsets: &[usize],
    gamma: Option<&dyn Fn(usize) -> Vec<f64>>,
    min_after: usize,
) -> Vec<f64> {
    let kc = base.k;
    let ks = sel.cols.k;
    let mut acc_cc = vec![0.0; kc * kc];
    let mut acc_cs = vec![0.0; kc * ks];
    let mut acc_cr = vec![0.0; kc];
    let mut m_buf = vec![0.0; kc * ks];
    let mut a_buf = vec![0.0; kc * kc];
    let mut c_buf = vec![0.0; kc];
    let mut out = vec![0.0; onsets.len()];
    let mut p = onsets.len();
    let mut i = prep.n;
    while p > 0 {
        p -= 1;
        let target = onsets[p];
        while i > target {
            i -= 1;
            for a in 0..3 {
                let r = 3 * i + a;
                let x = base.row(r);
                let s = if ks > 0 { sel.cols.row(r) } else { &[][..] };
                let rv = prep.r[i][a];
                for u in 0..kc {
                    let xu = x[u];
                    if xu == 0.0 {
                        continue;
                    }
                    acc_cr[u] += xu * rv;
                    for w in 0..kc {
                        acc_cc[u * kc + w] += xu * x[w];
                    }
                    for w in 0..ks {
                        acc_cs[u * ks + w] += xu * s[w];
                    }
                }
            }
        }
        if prep.n - target < min_after {
            continue;
        }
        // M = Acc_cs·G⁺ (kc × ks); A = Acc_cc − M·Acc_csᵀ; c = Acc_cr − M·h.
        for u in 0..kc {
            for w in 0..ks {
                let mut v = 0.0;
                for z in 0..ks {
                    v += acc_cs[u * ks + z] * sel.ginv[(z, w)];
                }
                m_buf[u * ks + w] = v;
            }
        }
        for u in 0..kc {
            let mut cv = acc_cr[u];
            for z in 0..ks {
                cv -= m_buf[u * ks + z] * sel.h[z];
            }
            c_buf[u] = cv;
            for w in 0..kc {
                let mut av = acc_cc[u * kc + w];
                for z in 0..ks {
                    av -= m_buf[u * ks + z] * acc_cs[w * ks + z];
                }
                a_buf[u * kc + w] = av;
            }
        }
        let d = match gamma {
            Some(gf) => {
                let g = gf(target);
                let mut a1 = 0.0;
                let mut c1 = 0.0;
                for u in 0..kc {
                    c1 += g[u] * c_buf[u];
                    for w in 0..kc {
                        a1 += g[u] * a_buf[u * kc + w] * g[w];
                    }
                }
                quad_form_1(a1, c1, diag_scale(&acc_cc, kc, Some(&g)))
            }
            None if kc == 1 => quad_form_1(a_buf[0], c_buf[0], acc_cc[0]),
            None if kc == 2 => quad_form_2(&a_buf[..4], &c_buf[..2], [acc_cc[0], acc_cc[3]]),
            None => {
                let a = DMatrix::from_row_slice(kc, kc, &a_buf);
                let c = DVector::from_column_slice(&c_buf);
                (c.transpose() * pinv_sym(&a) * &c)[(0, 0)]
            }
        };
        out[p] = if d.is_finite() { d.max(0.0) } else { 0.0 };
    }
    out
}

/// Scale of the candidate column's own sum of squares (for the
/// degeneracy test): `gᵀ·Acc_cc·g` or the first diagonal element.
fn diag_scale(acc_cc: &[f64], kc: usize, g: Option<&[f64]>) -> f64 {
    match g {
        None => acc_cc[0],
        Some(g) => {
            let mut s = 0.0;
            for u in 0..kc {
                for w in 0..kc {
                    s += g[u] * acc_cc[u * kc + w] * g[w];
                }
            }
            s
        }
    }
}

/// `c²/a`, or 0 when the candidate is (nearly) a combination of the
/// selected columns (`a` tiny against its own sum of squares `scale`).
fn quad_form_1(a: f64, c: f64, scale: f64) -> f64 {
    if a > 1e-10 * scale.abs() && a > 0.0 {
        c * c / a
    } else {
        0.0
    }
}

/// `cᵀA⁻¹c` for a 2×2 `A` (row-major), falling back to the better of the
/// two single columns when `A` is nearly singular.
fn quad_form_2(a: &[f64], c: &[f64], scale: [f64; 2]) -> f64 {
    let det = a[0] * a[3] - a[1] * a[2];
    let ok0 = a[0] > 1e-10 * scale[0].abs();
    let ok1 = a[3] > 1e-10 * scale[1].abs();
    if ok0 && ok1 && det > 1e-10 * a[0] * a[3] {
        (a[3] * c[0] * c[0] - (a[1] + a[2]) * c[0] * c[1] + a[0] * c[1] * c[1]) / det
    } else {
        quad_form_1(a[0], c[0], scale[0]).max(quad_form_1(a[3], c[1], scale[1]))
    }
}

/// Least squares on the rows of the samples for which `train(i)` holds:
/// coefficients and the normal matrix.
pub fn lsq(
    prep: &Prepared,
    cols: &Cols,
    train: &dyn Fn(usize) -> bool,
) -> (DVector<f64>, DMatrix<f64>) {
    let k = cols.k;
    let mut g = DMatrix::zeros(k, k);
    let mut h = DVector::zeros(k);
    for i in 0..prep.n {
        if !train(i) {
            continue;
        }
        for a in 0..3 {
            let row = cols.row(3 * i + a);
            let r = prep.r[i][a];
            for p in 0..k {
                if row[p] == 0.0 {
                    continue;
                }
                h[p] += row[p] * r;
                for q in 0..k {
                    g[(p, q)] += row[p] * row[q];
                }
            }
        }
    }
    (pinv_sym(&g) * &h, g)
}

/// Number of contiguous time folds of the held-out validation.
pub const FOLDS: usize = 5;

/// Held-out residual sum of squares (mm²) of a design: the recording is cut
/// into [`FOLDS`] contiguous blocks of time; each is predicted from a fit
/// on the others.
pub fn holdout_rss(prep: &Prepared, cols: &Cols) -> f64 {
    let n = prep.n;
    holdout_rss_by(prep, cols, &|i| (i * FOLDS / n.max(1)).min(FOLDS - 1))
}

/// Chunks of time of [`holdout_rss_chunked`].
pub const CHUNKS: usize = 50;

/// [`holdout_rss`] with each fold [`CHUNKS`] / [`FOLDS`] short stretches of
/// time spread over the recording (chunk k in fold k mod 5): what a model
/// with a smooth function of time (a wander of the measurement) is judged
/// on. A contiguous fold takes away a fifth of the recording, and with it
/// whatever fixes that function there: its prediction would be a guess,
/// whatever the function.
pub fn holdout_rss_chunked(prep: &Prepared, cols: &Cols) -> f64 {
    let n = prep.n;
    holdout_rss_by(prep, cols, &|i| {
        (i * CHUNKS / n.max(1)).min(CHUNKS - 1) % FOLDS
    })
}

fn holdout_rss_by(prep: &Prepared, cols: &Cols, fold_of: &dyn Fn(usize) -> usize) -> f64 {
    let n = prep.n;
    let mut rss = 0.0;
    for f in 0..FOLDS {
        let beta = if cols.k > 0 {
            lsq(prep, cols, &|i| fold_of(i) != f).0
        } else {
            DVector::zeros(0)
        };
        for i in 0..n {
            if fold_of(i) != f {
                continue;
            }
            for a in 0..3 {
                let mut pred = 0.0;
                if cols.k > 0 {
                    let row = cols.row(3 * i + a);
                    for p in 0..cols.k {
                        pred += row[p] * beta[p];
                    }
                }
                let e = prep.r[i][a] - pred;
                rss += e * e;
            }
        }
    }
    rss
}
