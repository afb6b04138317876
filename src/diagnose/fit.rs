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
use crate::machine::chain::JointKind;

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
            Family::PivotLength => None,
        }
    }

    /// Axis label (`X`, `XZ`, none).
    pub fn axis_label(self, names: &[String]) -> Option<String> {
        match self {
            Family::Squareness(a, b) => Some(format!("{}{}", names[a], names[b])),
            Family::PivotLength => None,
            f => f.joint().map(|j| names[j].clone()),
        }
    }

    /// Number of linear coefficients.
    pub fn linear_params(self) -> usize {
        match self {
            Family::Cyclic(_) | Family::RotaryCenterOffset(_) | Family::Vibration(_) => 2,
            Family::ErrorMotion(_, m) => m.count_ones() as usize * 2 * MOTION_HARMONICS as usize,
            Family::LinearMotion(_, m) => m.count_ones() as usize * MOTION_BASIS,
            _ => 1,
        }
    }

    /// Whether `self` and `other` model the same thing, so that one model
    /// holds at most one of them: the same family, or two error motions of
    /// one joint (with different components).
    pub fn same_slot(self, other: Family) -> bool {
        match (self, other) {
            (Family::ErrorMotion(a, _), Family::ErrorMotion(b, _))
            | (Family::LinearMotion(a, _), Family::LinearMotion(b, _)) => a == b,
            _ => self == other,
        }
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
    let cut = max * 1e-10;
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

/// The best candidate of one family.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The term (with its best non-linear parameter and onset).
    pub term: Term,
    /// Reduction of the residual sum of squares, mm².
    pub delta_rss: f64,
    /// BIC decrease: Δχ² minus the penalty (higher is better).
    pub score: f64,
    /// Penalty in χ² units (parameters and searches).
    pub penalty: f64,
}

/// Settings of the search.
#[derive(Debug, Clone, Copy)]
pub struct SearchCtx {
    /// Noise floor σ, mm.
    pub sigma: f64,
    /// ln(number of residual rows): the BIC price of one parameter.
    pub ln_n: f64,
    /// Smallest number of samples after an onset.
    pub min_after: usize,
}

impl SearchCtx {
    fn onset_penalty(&self, n_onsets: usize) -> f64 {
        self.ln_n + 2.0 * (n_onsets.max(1) as f64).ln()
    }
}

/// Picks the onset: the start of the recording unless a later onset
/// improves the fit by more than the onset penalty. Returns
/// `(onset index, ΔRSS, extra penalty)`.
fn choose_onset(profile: &[f64], ctx: &SearchCtx, n_onsets: usize) -> (usize, f64, f64) {
    let s2 = ctx.sigma * ctx.sigma;
    let d0 = profile.first().copied().unwrap_or(0.0);
    let (mut best, mut bd) = (0usize, d0);
    for (k, &d) in profile.iter().enumerate() {
        if d > bd {
            best = k;
            bd = d;
        }
    }
    let pen = ctx.onset_penalty(n_onsets);
    if best != 0 && (bd - d0) / s2 > pen {
        (best, bd, pen)
    } else {
        (0, d0, 0.0)
    }
}

/// Range of the thermal time constant searched, as multiples of the
/// recording's span.
pub const TAU_RANGE: (f64, f64) = (1.0 / 30.0, 30.0);

/// Coarse grid of the time-constant search: this many values log-spaced
/// over [`TAU_RANGE`] (spacing a factor 1.69). It also sets the look-
/// elsewhere penalty `2 ln TAU_GRID` of a searched τ.
pub const TAU_GRID: usize = 14;

/// Fine grid: the bracket of ±1 coarse step around the best coarse value is
/// scanned at `2·TAU_FINE + 1` values (spacing a factor 1.09) before the
/// golden-section refinement, so that a narrow maximum of the profile
/// (the onset switching between blocks makes it piecewise smooth) is not
/// missed.
const TAU_FINE: usize = 6;

/// Maximises `f(ln τ).0` over `[lo, hi]`: coarse grid, fine grid around the
/// best, golden-section search within ±1 fine step. Returns the argument
/// and the value at the maximum found.
fn maximise_ln<T: Copy>(f: &dyn Fn(f64) -> (f64, T), lo: f64, hi: f64) -> (f64, (f64, T)) {
    let coarse = (hi - lo) / (TAU_GRID - 1) as f64;
    let mut best = (lo, f(lo));
    let consider = |x: f64, best: &mut (f64, (f64, T))| {
        let v = f(x);
        if v.0 > best.1.0 {
            *best = (x, v);
        }
    };
    for g in 1..TAU_GRID {
        consider(lo + coarse * g as f64, &mut best);
    }
    let centre = best.0;
    let fine = coarse / TAU_FINE as f64;
    for g in 1..=TAU_FINE {
        for x in [centre - fine * g as f64, centre + fine * g as f64] {
            if x > lo && x < hi {
                consider(x, &mut best);
            }
        }
    }
    let (a, b) = ((best.0 - fine).max(lo), (best.0 + fine).min(hi));
    let (x, _) = crate::numeric::golden_section_max(&mut |x| f(x).0, a, b, 10);
    consider(x, &mut best);
    best
}

/// Searches one family: non-linear parameter (grid + golden section) and
/// onset (profile over all block starts). `None` if the family has no
/// support in the data (joint never moves, …).
pub fn search_family(
    prep: &Prepared,
    sel: &Selected,
    fam: Family,
    ctx: &SearchCtx,
) -> Option<Candidate> {
    let s2 = ctx.sigma * ctx.sigma;
    let onsets = &prep.onsets;
    let k_lin = fam.linear_params() as f64;
    let n_on = onsets.len();
    match fam {
        Family::ThermalDrift(_) => {
            let t0 = prep.t[0];
            let span = (prep.t[prep.n - 1] - t0).max(1e-9);
            let (lo, hi) = (span * TAU_RANGE.0, span * TAU_RANGE.1);
            // The joint profile over (onset, τ): for each τ every onset is
            // profiled by one suffix-sum pass; the best onset is kept.
            let eval = |ln_tau: f64| -> (f64, (usize, f64, f64)) {
                let tau = ln_tau.exp();
                let base = base_columns(prep, fam, tau);
                let gf = |s: usize| thermal_gamma(prep, tau, prep.t[s]).to_vec();
                let prof = scan(prep, sel, &base, onsets, Some(&gf), ctx.min_after);
                let (k, d, pen) = choose_onset(&prof, ctx, n_on);
                (d / s2 - pen, (k, d, pen))
            };
            let (x, (_, (k, d, pen))) = maximise_ln(&eval, lo.ln(), hi.ln());
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (TAU_GRID as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: x.exp(),
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        Family::Cyclic(j) => {
            let (mut qmin, mut qmax) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut steps: Vec<f64> = Vec::with_capacity(prep.n);
            for i in 0..prep.n {
                let q = prep.qj(i, j);
                qmin = qmin.min(q);
                qmax = qmax.max(q);
                if i > 0 {
                    let d = (q - prep.qj(i - 1, j)).abs();
                    if d > 1e-9 {
                        steps.push(d);
                    }
                }
            }
            let range = qmax - qmin;
            if range.partial_cmp(&1e-6) != Some(std::cmp::Ordering::Greater) || steps.is_empty() {
                return None;
            }
            let mid = steps.len() / 2;
            steps.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            let p_min = (range / 50.0).max(4.0 * steps[mid]);
            let p_max = range / 1.5;
            if p_min >= p_max {
                return None;
            }
            let (f_lo, f_hi) = (1.0 / p_max, 1.0 / p_min);
            let df = 1.0 / (2.5 * range);
            let x: Vec<f64> = (0..prep.n).map(|i| prep.qj(i, j)).collect();
            let (f, d, k, pen, grid) =
                periodic_search(prep, sel, ctx, fam, j, &x, (f_lo, f_hi), df, 250)?;
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (grid as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: 1.0 / f,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        Family::Vibration(j) => {
            let span = prep.t[prep.n - 1] - prep.t[0];
            let mut dts: Vec<f64> = prep.t.windows(2).map(|w| w[1] - w[0]).collect();
            if span <= 0.0 || dts.is_empty() {
                return None;
            }
            let mid = dts.len() / 2;
            dts.select_nth_unstable_by(mid, f64::total_cmp);
            // From ten cycles per recording and 0.2 Hz (slower is a drift
            // or a mismatch confined to part of the recording, not a
            // structure's oscillation) to just below the Nyquist frequency
            // of the median interval.
            let (f_lo, f_hi) = ((10.0 / span).max(MIN_VIBRATION_HZ), 0.49 / dts[mid]);
            if f_lo >= f_hi {
                return None;
            }
            let df = 1.0 / (2.5 * span);
            let (f, d, k, pen, grid) = periodic_search(
                prep,
                sel,
                ctx,
                fam,
                j,
                &prep.t,
                (f_lo, f_hi),
                df,
                VIBRATION_GRID,
            )?;
            let penalty = (k_lin + 1.0) * ctx.ln_n + 2.0 * (grid as f64).ln() + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: f,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
        _ => {
            if let Family::RotaryCenterOffset(j) = fam
                && prep.rco[j].is_none()
            {
                return None;
            }
            let base = base_columns(prep, fam, 0.0);
            let norm: f64 = base.data.iter().map(|x| x * x).sum();
            if norm.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            let prof = scan(prep, sel, &base, onsets, None, ctx.min_after);
            let (k, d, pen) = choose_onset(&prof, ctx, n_on);
            let penalty = k_lin * ctx.ln_n + pen;
            Some(Candidate {
                term: Term {
                    family: fam,
                    nl: 0.0,
                    onset: onsets[k],
                },
                delta_rss: d,
                score: d / s2 - penalty,
                penalty,
            })
        }
    }
}

/// Lowest frequency searched for a vibration, Hz.
pub const MIN_VIBRATION_HZ: f64 = 0.2;

/// Grid size cap of the vibration frequency search.
pub const VIBRATION_GRID: usize = 20_000;

/// The frequency search of a periodic family (cyclic in a position,
/// vibration in time): sinusoid columns `J_j·[sin 2πf·x, cos 2πf·x]` scored
/// on a uniform frequency grid over `band` with spacing `df` (at most
/// `max_grid` values), refined by golden section, then the onset profiled.
/// Returns (frequency, ΔRSS, onset index, onset penalty, grid size).
#[allow(clippy::too_many_arguments)]
fn periodic_search(
    prep: &Prepared,
    sel: &Selected,
    ctx: &SearchCtx,
    fam: Family,
    j: usize,
    x: &[f64],
    band: (f64, f64),
    df: f64,
    max_grid: usize,
) -> Option<(f64, f64, usize, f64, usize)> {
    let (f_lo, f_hi) = band;
    let onsets = &prep.onsets;
    let grid = (((f_hi - f_lo) / df).ceil() as usize).clamp(2, max_grid);
    let step = (f_hi - f_lo) / (grid - 1) as f64;
    // Per-sample projections, so that a frequency costs one pass:
    // columns J_j·[sin θ, cos θ], θ = 2π f x (x a position or time).
    let ks = sel.cols.k;
    let mut w = Vec::with_capacity(prep.n);
    let mut pr = Vec::with_capacity(prep.n);
    let mut ps = vec![0.0; prep.n * ks];
    for i in 0..prep.n {
        let jj = prep.jj(i, j);
        w.push(jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]);
        pr.push(jj[0] * prep.r[i][0] + jj[1] * prep.r[i][1] + jj[2] * prep.r[i][2]);
        for a in 0..3 {
            if ks > 0 {
                let row = sel.cols.row(3 * i + a);
                for z in 0..ks {
                    ps[i * ks + z] += jj[a] * row[z];
                }
            }
        }
    }
    // Score of one frequency from the per-sample (sin θ, cos θ).
    let mut cs = vec![0.0; 2 * ks];
    let mut score = |trig: &[(f64, f64)]| -> f64 {
        let (mut ss, mut sc, mut cc, mut rs, mut rc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        cs.iter_mut().for_each(|x| *x = 0.0);
        for (i, &(sn, co)) in trig.iter().enumerate() {
            ss += w[i] * sn * sn;
            sc += w[i] * sn * co;
            cc += w[i] * co * co;
            rs += pr[i] * sn;
            rc += pr[i] * co;
            for z in 0..ks {
                let v = ps[i * ks + z];
                cs[z] += sn * v;
                cs[ks + z] += co * v;
            }
        }
        let mut a = [ss, sc, sc, cc];
        let mut c = [rs, rc];
        if ks > 0 {
            for u in 0..2 {
                let mut mrow = vec![0.0; ks];
                for (zz, m) in mrow.iter_mut().enumerate() {
                    for z in 0..ks {
                        *m += cs[u * ks + z] * sel.ginv[(z, zz)];
                    }
                }
                for z in 0..ks {
                    c[u] -= mrow[z] * sel.h[z];
                    for v in 0..2 {
                        a[u * 2 + v] -= mrow[z] * cs[v * ks + z];
                    }
                }
            }
        }
        quad_form_2(&a, &c, [ss, cc])
    };
    let trig_at = |f: f64| -> Vec<(f64, f64)> {
        let omega = std::f64::consts::TAU * f;
        (0..prep.n).map(|i| (omega * x[i]).sin_cos()).collect()
    };
    // The grid is uniform in frequency: each sample's (sin, cos)
    // advances by a fixed rotation from one grid value to the next
    // (re-seeded exactly every 32 steps against rounding drift).
    let rot = trig_at(step);
    let mut trig = Vec::new();
    let mut vals: Vec<(f64, f64)> = Vec::with_capacity(grid);
    for g in 0..grid {
        let f = f_lo + step * g as f64;
        if g % 32 == 0 {
            trig = trig_at(f);
        } else {
            for (t, r) in trig.iter_mut().zip(&rot) {
                *t = (t.0 * r.1 + t.1 * r.0, t.1 * r.1 - t.0 * r.0);
            }
        }
        vals.push((score(&trig), f));
    }
    vals.sort_by(|a, b| b.0.total_cmp(&a.0));
    let f_best = vals[0].1;
    let (f, _) = crate::numeric::golden_section_max(
        &mut |f| score(&trig_at(f)),
        (f_best - step).max(f_lo),
        (f_best + step).min(f_hi),
        16,
    );
    let nl = match fam {
        Family::Cyclic(_) => 1.0 / f,
        _ => f,
    };
    let base = base_columns(prep, fam, nl);
    let prof = scan(prep, sel, &base, onsets, None, ctx.min_after);
    let (k, d, pen) = choose_onset(&prof, ctx, onsets.len());
    Some((f, d, k, pen, grid))
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
    let fold_of = |i: usize| (i * FOLDS / n.max(1)).min(FOLDS - 1);
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

/// Converts fitted coefficients of a term into an effect (and the Jacobian
/// of its reported parameters with respect to the coefficients, for the
/// uncertainties).
pub fn term_effect(prep: &Prepared, term: &Term, beta: &[f64]) -> Effect {
    let name = |j: usize| prep.names[j].clone();
    match term.family {
        Family::Backlash(j) => Effect::Backlash {
            axis: name(j),
            value: beta[0],
        },
        Family::ServoLag(j) => Effect::ServoLag {
            axis: name(j),
            tau_s: beta[0],
        },
        Family::ThermalDrift(j) => Effect::ThermalDrift {
            axis: name(j),
            amplitude_mm: beta[0],
            tau_s: term.nl,
        },
        Family::Scale(j) => Effect::Scale {
            axis: name(j),
            ppm: beta[0],
        },
        Family::Squareness(a, b) => Effect::Squareness {
            axes: [name(a), name(b)],
            angle_urad: beta[0],
        },
        Family::Cyclic(j) => {
            let (c, s) = (beta[0], beta[1]);
            Effect::Cyclic {
                axis: name(j),
                amplitude: c.hypot(s),
                period: term.nl,
                phase_deg: s.atan2(c).to_degrees(),
            }
        }
        Family::ZeroOffset(j) => Effect::ZeroOffset {
            axis: name(j),
            value: beta[0],
        },
        Family::RotaryCenterOffset(j) => {
            let d = prep.rco[j]
                .as_ref()
                .map(|b| b.dirs[0] * beta[0] + b.dirs[1] * beta[1])
                .unwrap_or_default();
            Effect::RotaryCenterOffset {
                axis: name(j),
                offset_mm: [d.x, d.y, d.z],
            }
        }
        Family::PivotLength => Effect::PivotLength { delta_mm: beta[0] },
        Family::ErrorMotion(j, mask) => {
            let mut terms = Vec::new();
            for (p, c) in mask_components(mask).enumerate() {
                for k in 1..=MOTION_HARMONICS {
                    let base = (p * MOTION_HARMONICS as usize + (k as usize - 1)) * 2;
                    terms.push((c, k, beta[base], beta[base + 1]));
                }
            }
            Effect::ErrorMotion {
                axis: name(j),
                terms,
                span: None,
                arc: covered_arc(prep, j),
            }
        }
        Family::LinearMotion(j, mask) => {
            let mut terms = Vec::new();
            for (p, c) in mask_components(mask).enumerate() {
                for k in 0..MOTION_BASIS {
                    terms.push((c, k as u32, beta[p * MOTION_BASIS + k], 0.0));
                }
            }
            Effect::ErrorMotion {
                axis: name(j),
                terms,
                span: motion_span(prep, j),
                arc: None,
            }
        }
        Family::Vibration(j) => {
            let (c, s) = (beta[0], beta[1]);
            Effect::Vibration {
                axis: name(j),
                amplitude: c.hypot(s),
                frequency_hz: term.nl,
                phase_deg: s.atan2(c).to_degrees(),
            }
        }
    }
}

/// Standard deviations of the reported parameters (in the order of
/// [`Effect::parameters`]) from the covariance of `[β…, nl]`.
pub fn parameter_sd(prep: &Prepared, term: &Term, beta: &[f64], cov: &DMatrix<f64>) -> Vec<f64> {
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    match term.family {
        Family::ThermalDrift(_) => vec![sd(0), sd(1)],
        Family::Cyclic(_) | Family::Vibration(_) => {
            let (c, s) = (beta[0], beta[1]);
            let a = c.hypot(s).max(1e-300);
            let ga = [c / a, s / a];
            let gp = [-s / (a * a), c / (a * a)];
            let q = |g: [f64; 2]| {
                (g[0] * g[0] * cov[(0, 0)]
                    + 2.0 * g[0] * g[1] * cov[(0, 1)]
                    + g[1] * g[1] * cov[(1, 1)])
                    .max(0.0)
                    .sqrt()
            };
            vec![q(ga), sd(2), q(gp).to_degrees()]
        }
        Family::RotaryCenterOffset(j) => {
            let Some(b) = prep.rco[j].as_ref() else {
                return vec![0.0; 3];
            };
            (0..3)
                .map(|x| {
                    let g = [b.dirs[0][x], b.dirs[1][x]];
                    (g[0] * g[0] * cov[(0, 0)]
                        + 2.0 * g[0] * g[1] * cov[(0, 1)]
                        + g[1] * g[1] * cov[(1, 1)])
                        .max(0.0)
                        .sqrt()
                })
                .collect()
        }
        Family::ErrorMotion(_, mask) | Family::LinearMotion(_, mask) => {
            // The peaks' uncertainty: the largest coefficient's of their
            // kind (rotations in µrad, as reported); a spline's span (from,
            // to, basis count) is chosen, not fitted.
            let n = beta.len();
            let per = n / (mask.count_ones() as usize).max(1);
            let comp = |p: usize| mask_components(mask).nth(p / per.max(1)).unwrap_or(0);
            let scaled = |p: usize| if comp(p) < 3 { sd(p) } else { sd(p) * 1e6 };
            let peak = |rot: bool| {
                (0..n)
                    .filter(|&p| (comp(p) >= 3) == rot)
                    .map(scaled)
                    .fold(0.0, f64::max)
            };
            let mut v = vec![peak(false)];
            if mask & !TRANSLATIONS != 0 {
                v.push(peak(true));
            }
            if matches!(term.family, Family::LinearMotion(..)) {
                v.extend([0.0; 3]);
            }
            v.extend((0..n).map(scaled));
            v
        }
        _ => vec![sd(0)],
    }
}

/// Derivative of a term's (onset-masked) columns times its coefficients
/// with respect to its non-linear parameter (numerical, relative step
/// 1e-4): the Gauss–Newton column of that parameter.
pub fn nl_derivative(prep: &Prepared, term: &Term, beta: &[f64]) -> Cols {
    let h = term.nl * 1e-4;
    let mut tp = *term;
    let mut tm = *term;
    tp.nl += h;
    tm.nl -= h;
    let cp = term_columns(prep, &tp);
    let cm = term_columns(prep, &tm);
    let k = cp.k;
    let rows = prep.rows();
    let mut out = Cols::zeros(rows, 1);
    for r in 0..rows {
        let mut s = 0.0;
        for p in 0..k {
            s += (cp.data[r * k + p] - cm.data[r * k + p]) * beta[p];
        }
        out.data[r] = s / (2.0 * h);
    }
    out
}

/// For a thermal drift that starts part-way, the Gauss–Newton column of its
/// onset time t₀: `∂/∂t₀ [a·J·(1 − e^−(t−t₀)/τ)] = −(a/τ)·e^−(t−t₀)/τ·J`
/// from the onset on (the drift is continuous at its onset, so the
/// likelihood is smooth in a continuous t₀ and this column gives t₀ a
/// standard deviation, and lets the onset's trade-off with τ and the
/// amplitude enter theirs). `None` for other terms and for a drift from
/// the start of the recording (whose onset is not a free parameter).
pub fn onset_derivative(prep: &Prepared, term: &Term, beta: &[f64]) -> Option<Cols> {
    let Family::ThermalDrift(j) = term.family else {
        return None;
    };
    if term.onset == 0 || term.onset >= prep.n {
        return None;
    }
    let t0 = prep.t[term.onset];
    let mut out = Cols::zeros(prep.rows(), 1);
    for i in term.onset..prep.n {
        let g = -beta[0] / term.nl * (-(prep.t[i] - t0) / term.nl).exp();
        let jj = prep.jj(i, j);
        for a in 0..3 {
            out.data[3 * i + a] = g * jj[a];
        }
    }
    Some(out)
}

/// An effect found, with everything the report needs.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The term.
    pub term: Term,
    /// The effect with fitted parameters (from its onset block).
    pub spec: EffectSpec,
    /// Standard deviations of the parameters (order of `Effect::parameters`).
    pub sd: Vec<f64>,
    /// Standard deviation of a drift's onset time, s (when it starts
    /// part-way).
    pub onset_sd_s: Option<f64>,
    /// The candidate score when it entered.
    pub score: f64,
    /// Held-out RSS before / after it entered, mm².
    pub holdout: (f64, f64),
    /// The runner-up of its round: term, score, fitted effect.
    pub runner_up: Option<(Term, f64, Effect)>,
}
