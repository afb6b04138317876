//! Newton refinement on the error-aware chain (seed 000, Section 5, improved).
//!
//! Start from the analytic IK of the theoretical machine, then step with a
//! generalised inverse until the *actual* machine (the chain with its error
//! motions) puts the tool on the pose.
//!
//! The tool tip comes first and is met exactly; the tool axis comes as close
//! as the remaining freedom allows (task-priority least squares):
//!
//! ```text
//! Δq = J_p⁺ r_p + N (W J_o N)⁺ W (r_o − J_o J_p⁺ r_p),   N = I − J_p⁺ J_p
//! ```
//!
//! with `r_p`, `r_o` the tip and axis residuals, `J_p`, `J_o` the rows of the
//! Jacobian for tip and axis and `W` the axis weights. On a five-axis machine
//! both are met; on a four-axis machine the tip is met to floating-point level
//! and the axis lands on the closest direction the actual machine can reach.
//!
//! The paper's variant ([`Method::Paper`]) steps with the pseudo-inverse of the
//! stacked 6×n theoretical Jacobian on the stacked residual: it minimises
//! `|r_p|² + |r_o|²` with mm and rad mixed, so where the axis cannot be met it
//! trades tip accuracy for axis accuracy and stalls at a tip residual of tens
//! of nanometres (see `docs/error-model.md`).

use crate::linalg::{self, Col, Qr};
use crate::machine::chain::{
    Chain, JacobianColumns, JointErrors, JointValues, MAX_JOINTS, NoErrors, Pose,
};
use crate::post::{GcodeConverter, PendingPose, PostOptions, PostStats};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use std::io::{BufRead, Write};

/// Which Jacobian (and which step) to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Task-priority step with the exact Jacobian of the error-aware chain,
    /// including the derivatives of the fitted error splines (default).
    Exact,
    /// Task-priority step with the theoretical Jacobian (error-free chain).
    Theoretical,
    /// Seed 000 as printed: stacked 6×n theoretical Jacobian, unweighted
    /// pseudo-inverse on the stacked residual.
    Paper,
}

/// Options of the refinement.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Step method.
    pub method: Method,
    /// Largest number of Newton iterations.
    pub max_iterations: usize,
    /// Tool-tip residual at which to stop, mm.
    pub tip_tolerance_mm: f64,
    /// Weights of the tool-axis residual components (x, y, z of the workpiece frame).
    pub axis_weights: [f64; 3],
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Exact,
            max_iterations: 30,
            tip_tolerance_mm: 1e-12,
            axis_weights: [1.0, 1.0, 1.0],
        }
    }
}

/// The result of refining one pose.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Refined {
    /// Joint values (chain order, mm / rad).
    pub q: JointValues,
    /// Newton iterations taken.
    pub iterations: usize,
    /// Remaining tool-tip error on the actual machine, mm.
    pub tip_residual_mm: f64,
    /// Remaining tool-axis error on the actual machine, rad.
    pub axis_residual_rad: f64,
    /// Whether the tip tolerance was reached (or the step became negligible).
    pub converged: bool,
    /// Not converged, but no move within the bounds reduces the tool-tip
    /// residual to first order: the pose is at (or next to) a singularity
    /// of the machine, where part of the error lies across every direction
    /// the machine can move the tip, and `q` is the best there is.
    pub best_within_bounds: bool,
    /// Tool-tip error at `q0` (where the refinement started), mm.
    pub start_tip_mm: f64,
    /// Tool-axis error at `q0`, rad.
    pub start_axis_rad: f64,
}

fn residual(target: &Pose, p: &Pose) -> (Vector3<f64>, Vector3<f64>) {
    (target.tip - p.tip, target.axis - p.axis)
}

/// Moore–Penrose pseudo-inverse via SVD with a relative singular-value cut-off.
fn pinv(m: &DMatrix<f64>) -> DMatrix<f64> {
    let svd = m.clone().svd(true, true);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let eps = smax * 1e-12 * (m.nrows().max(m.ncols()) as f64);
    svd.pseudo_inverse(eps.max(f64::MIN_POSITIVE))
        .unwrap_or_else(|_| DMatrix::zeros(m.ncols(), m.nrows()))
}

/// Damped least-squares solution of `J Δ = r` with joint scaling `scale`
/// (Δ = S (J S)ᵀ ((J S)(J S)ᵀ + λ² I)⁻¹ r): λ = 0 is the minimum-norm
/// solution; a larger λ shortens the step along ill-conditioned directions.
fn damped(j: &DMatrix<f64>, r: &DVector<f64>, scale: &[f64], lambda: f64) -> DVector<f64> {
    let n = j.ncols();
    let js = DMatrix::from_fn(j.nrows(), n, |row, c| j[(row, c)] * scale[c]);
    let sol = if lambda == 0.0 {
        pinv(&js) * r
    } else {
        let a = &js * js.transpose() + DMatrix::identity(j.nrows(), j.nrows()) * (lambda * lambda);
        match a.lu().solve(r) {
            Some(y) => js.transpose() * y,
            None => DVector::zeros(n),
        }
    };
    DVector::from_fn(n, |k, _| sol[k] * scale[k])
}

/// Joint-space vectors of the refinement (entries past the dof unused).
type Joints = [f64; MAX_JOINTS];

/// Largest condition estimate of the Gram matrix `(J_p S)(J_p S)ᵀ` for
/// the closed-form tip step ([`Factored::factor_gram`]); above it the QR path.
const GRAM_CONDITION_LIMIT: f64 = 1e8;

/// Problems whose (small) matrices have a condition number above this are
/// handed to the SVD path; below it the Householder QR solution is accurate
/// to far better than the next Newton step needs.
const QR_CONDITION_LIMIT: f64 = 1e8;

/// Smallest damping (in decades from 1e-6) of the tip step `S (J S)ᵀ ((J S)
/// (J S)ᵀ + λ² I)⁻¹ r` that keeps it within `caps`, starting from the
/// undamped step `dq1`; `jp` holds the three tip rows. 3×3 solves on the stack.
fn damp_into_caps(jp: &[Col], rp: &Vector3<f64>, caps: &Joints, n: usize, dq1: &mut Joints) {
    let within = |d: &Joints| (0..n).all(|k| d[k].abs() <= caps[k]);
    if within(dq1) {
        return;
    }
    // J S, 3×n.
    let js = nalgebra::Matrix3xX::from_fn(n, |r, c| jp[r][c] * caps[c]);
    let jjt = &js * js.transpose();
    let mut lambda = 1e-6;
    while lambda < 1e6 {
        let a = jjt + Matrix3::identity() * (lambda * lambda);
        let sol = match a.lu().solve(rp) {
            Some(y) => js.transpose() * y,
            None => nalgebra::DVector::zeros(n),
        };
        for k in 0..n {
            dq1[k] = sol[k] * caps[k];
        }
        if within(dq1) {
            break;
        }
        lambda *= 10.0;
    }
}

/// The exact method keeps its Jacobian while every step shrinks the tool-tip
/// residual at least this many times: see [`refine`].
const CHORD_GAIN: f64 = 1e3;

/// Steps on the joints not held back by their bounds after a refinement
/// that did not converge (see the end of [`refine`]).
const POLISH_STEPS: usize = 8;

/// A step no larger than this (relative to `1 + |q|`, mm or rad) is taken to
/// be the last: see [`refine`].
const FINAL_STEP: f64 = 1e-6;

/// The residual-independent part of one step of the chosen method, on the
/// stack: the factorisations of [`Factored::step`] for one Jacobian, so that
/// several steps can share them (see [`refine`]).
///
/// Tip part: the minimum-norm solution of `J_p S x = r_p` by QR of
/// `(J_p S)ᵀ`, `Δ₁ = S x`. Axis part: with `Z` an orthonormal basis of the
/// null space of `J_p` (one direction: `S z_s` normalised, `z_s` the scaled
/// problem's null vector; more: trailing columns of the QR of `J_pᵀ`),
/// `N (W J_o N)⁺ = Z (W J_o Z)⁺`, so `Δ₂ = Z (W J_o Z)⁺ W (r_o − J_o Δ₁)`,
/// the same step as the SVD form with `N = I − J_p⁺ J_p` and every vector
/// exactly in the null space up to rounding. Paper: least squares on the
/// stacked 6×n Jacobian by QR.
struct Factored {
    /// The last [`Factored::factor`] succeeded.
    usable: bool,
    n: usize,
    /// The paper's stacked 6×n problem (factored in `scaled`).
    paper: bool,
    /// QR of `(J_p S)ᵀ` (of the stacked Jacobian for the paper's step).
    scaled: Qr,
    /// Joint scaling `S` (the trust-region caps).
    caps: Joints,
    /// The tip rows of the Jacobian (for the damped tip step).
    jp_rows: [Col; 3],
    /// The axis rows of the Jacobian.
    jo_rows: [Col; 3],
    /// Axis weights `W`.
    weights: [f64; 3],
    /// Dimension of the null space of `J_p` the axis part may use (0 when
    /// the axis cannot move in it).
    free: usize,
    /// Orthonormal basis of that null space.
    z: [Col; 3],
    /// `B = W J_o Z` (3 × free).
    b: [Col; 3],
    /// QR of `J_pᵀ` (null-space basis), then of `B`, when `free > 1`.
    aux: Qr,
    /// The tip step is solved through the Gram matrix (see
    /// [`Factored::factor_gram`]) instead of `scaled`.
    gram: bool,
    /// Rows of `J_p S` (Gram path).
    a_rows: [Col; 3],
    /// `((J_p S)(J_p S)ᵀ)⁻¹` (Gram path).
    gram_inv: [[f64; 3]; 3],
}

impl Factored {
    /// Nothing factored yet.
    const EMPTY: Factored = Factored {
        usable: false,
        n: 0,
        paper: false,
        scaled: Qr::EMPTY,
        caps: [0.0; MAX_JOINTS],
        jp_rows: [[0.0; linalg::ROWS]; 3],
        jo_rows: [[0.0; linalg::ROWS]; 3],
        weights: [0.0; 3],
        free: 0,
        z: [[0.0; linalg::ROWS]; 3],
        b: [[0.0; linalg::ROWS]; 3],
        aux: Qr::EMPTY,
        gram: false,
        a_rows: [[0.0; linalg::ROWS]; 3],
        gram_inv: [[0.0; 3]; 3],
    };

    /// Factors the step for the Jacobian `jac` (columns, chain order), in
    /// place; `false` (and `usable` false) when a matrix is too
    /// ill-conditioned for the QR path (the caller then uses [`step_svd`]).
    fn factor(&mut self, jac: &JacobianColumns, n: usize, opts: &Options, caps: &Joints) -> bool {
        self.usable = self.factor_qr(jac, n, opts, caps);
        self.usable
    }

    fn factor_qr(
        &mut self,
        jac: &JacobianColumns,
        n: usize,
        opts: &Options,
        caps: &Joints,
    ) -> bool {
        self.n = n;
        self.caps = *caps;
        self.weights = opts.axis_weights;
        self.free = 0;
        self.gram = false;
        self.paper = opts.method == Method::Paper;
        if self.paper {
            if n > linalg::COLS {
                return false;
            }
            let cols: [Col; linalg::COLS] = std::array::from_fn(|c| {
                let mut col = [0.0; linalg::ROWS];
                if c < n {
                    col[..6].copy_from_slice(&jac[c]);
                }
                col
            });
            self.scaled.factor(&cols[..n], 6);
            return self.scaled.condition() <= QR_CONDITION_LIMIT;
        }
        if !(3..=linalg::ROWS).contains(&n) {
            return false;
        }
        // The tip rows, as columns of J_pᵀ (n×3), unscaled and scaled by caps.
        let mut jpst = [[0.0; linalg::ROWS]; 3];
        for (r, (col, cols)) in self.jp_rows.iter_mut().zip(jpst.iter_mut()).enumerate() {
            *col = [0.0; linalg::ROWS];
            for c in 0..n {
                col[c] = jac[c][r];
                cols[c] = jac[c][r] * caps[c];
            }
        }
        for (r, row) in self.jo_rows.iter_mut().enumerate() {
            *row = [0.0; linalg::ROWS];
            for c in 0..n {
                row[c] = jac[c][r + 3];
            }
        }
        if (n == 3 || n == 4) && self.factor_gram(&jpst, n) {
            return true;
        }
        self.scaled.factor(&jpst, n);
        if self.scaled.condition() > QR_CONDITION_LIMIT {
            return false;
        }
        // Null space of J_p and the weighted axis rows on it. With one free
        // direction it is the scaled problem's null vector mapped back through S
        // (J_p (S z) = (J_p S) z = 0), normalised; with more, an orthonormal
        // basis from the QR of J_pᵀ itself.
        let free = n - 3;
        if free == 0 {
            return true;
        }
        if free > 3 {
            return false;
        }
        if free == 1 {
            let zs = self.scaled.q_column(3);
            let mut z = [0.0; linalg::ROWS];
            for k in 0..n {
                z[k] = caps[k] * zs[k];
            }
            let norm = z[..n].iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm.is_nan() || norm <= 0.0 {
                return false;
            }
            for x in z.iter_mut().take(n) {
                *x /= norm;
            }
            self.z[0] = z;
        } else {
            self.aux.factor(&self.jp_rows, n);
            if self.aux.condition() > QR_CONDITION_LIMIT {
                return false;
            }
            for i in 0..free {
                self.z[i] = self.aux.q_column(3 + i);
            }
        }
        // B = W J_o Z (3 × free).
        for i in 0..free {
            let mut col = [0.0; linalg::ROWS];
            for (r, x) in col.iter_mut().take(3).enumerate() {
                *x = self.jo(r, &self.z[i]);
            }
            self.b[i] = col;
        }
        let scale = self.b[..free]
            .iter()
            .flat_map(|c| c[..3].iter())
            .fold(0.0f64, |m, x| m.max(x.abs()));
        if scale == 0.0 {
            // The axis cannot move in the null space (or all weights are 0).
            return true;
        }
        if free > 1 {
            self.aux.factor(&self.b[..free], 3);
            if self.aux.condition() > QR_CONDITION_LIMIT {
                return false;
            }
        }
        self.free = free;
        true
    }

    /// The tip step and (for four joints) the null direction of `J_p` for a
    /// well-conditioned problem of three or four joints, the common case, in
    /// closed form: with `A = J_p S` (rows `a`), the minimum-norm solution of
    /// `A x = r_p` is `Aᵀ (A Aᵀ)⁻¹ r_p`, the 3×3 inverse by cofactors; the null
    /// vector of the 3×4 `A` is its generalised cross product (the signed 3×3
    /// minors), mapped back through `S`. Used only when the Gram matrix's
    /// condition estimate `‖G‖_F ‖G⁻¹‖_F` is at most [`GRAM_CONDITION_LIMIT`]
    /// (`cond(A)` up to 10⁴, where squaring the condition still leaves the
    /// step far more accurate than the next Newton step needs); otherwise
    /// `false`, and the caller takes the Householder QR path.
    fn factor_gram(&mut self, a: &[Col; 3], n: usize) -> bool {
        let dot = |i: usize, j: usize| (0..n).map(|k| a[i][k] * a[j][k]).sum::<f64>();
        let g = [
            [dot(0, 0), dot(0, 1), dot(0, 2)],
            [0.0, dot(1, 1), dot(1, 2)],
            [0.0, 0.0, dot(2, 2)],
        ];
        let (g00, g01, g02, g11, g12, g22) = (g[0][0], g[0][1], g[0][2], g[1][1], g[1][2], g[2][2]);
        // Cofactors of the symmetric G.
        let c00 = g11 * g22 - g12 * g12;
        let c01 = g02 * g12 - g01 * g22;
        let c02 = g01 * g12 - g02 * g11;
        let c11 = g00 * g22 - g02 * g02;
        let c12 = g01 * g02 - g00 * g12;
        let c22 = g00 * g11 - g01 * g01;
        let det = g00 * c00 + g01 * c01 + g02 * c02;
        if det.is_nan() || det <= 0.0 {
            return false;
        }
        let inv = [
            [c00 / det, c01 / det, c02 / det],
            [c01 / det, c11 / det, c12 / det],
            [c02 / det, c12 / det, c22 / det],
        ];
        let frob = |m: &[[f64; 3]; 3]| m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
        let full = [[g00, g01, g02], [g01, g11, g12], [g02, g12, g22]];
        let cond = frob(&full) * frob(&inv);
        if cond.is_nan() || cond > GRAM_CONDITION_LIMIT {
            return false;
        }
        if n == 4 {
            // z_k = (−1)^k det(A without column k), then S z, normalised.
            let minor = |c0: usize, c1: usize, c2: usize| {
                a[0][c0] * (a[1][c1] * a[2][c2] - a[1][c2] * a[2][c1])
                    - a[0][c1] * (a[1][c0] * a[2][c2] - a[1][c2] * a[2][c0])
                    + a[0][c2] * (a[1][c0] * a[2][c1] - a[1][c1] * a[2][c0])
            };
            let zs = [
                minor(1, 2, 3),
                -minor(0, 2, 3),
                minor(0, 1, 3),
                -minor(0, 1, 2),
            ];
            let mut z = [0.0; linalg::ROWS];
            for k in 0..4 {
                z[k] = self.caps[k] * zs[k];
            }
            let norm = z[..4].iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm.is_nan() || norm <= 0.0 {
                return false;
            }
            for x in z.iter_mut().take(4) {
                *x /= norm;
            }
            self.z[0] = z;
            let mut col = [0.0; linalg::ROWS];
            for (r, x) in col.iter_mut().take(3).enumerate() {
                *x = self.jo(r, &z);
            }
            self.b[0] = col;
            let movable = col[..3].iter().any(|x| *x != 0.0);
            self.free = if movable { 1 } else { 0 };
        }
        self.a_rows = *a;
        self.gram_inv = inv;
        self.gram = true;
        true
    }

    /// Row `r` of `W J_o` applied to `v`.
    fn jo(&self, r: usize, v: &Col) -> f64 {
        self.weights[r] * (0..self.n).map(|c| self.jo_rows[r][c] * v[c]).sum::<f64>()
    }

    /// The step for the residuals `rp` (tip) and `ro` (axis), split into its
    /// tip part and its axis part; the tip part damped just enough to stay
    /// inside the trust region (the caps).
    fn step(&self, rp: &Vector3<f64>, ro: &Vector3<f64>) -> (Joints, Joints) {
        let n = self.n;
        let mut d1 = [0.0; MAX_JOINTS];
        let mut d2 = [0.0; MAX_JOINTS];
        if self.paper {
            let mut r = [0.0; linalg::ROWS];
            r[..6].copy_from_slice(&[rp.x, rp.y, rp.z, ro.x, ro.y, ro.z]);
            let x = self.scaled.least_squares(&r);
            d1[..n].copy_from_slice(&x[..n]);
            return (d1, d2);
        }
        let x = if self.gram {
            // Aᵀ (A Aᵀ)⁻¹ r_p.
            let g = &self.gram_inv;
            let y: [f64; 3] =
                std::array::from_fn(|i| g[i][0] * rp.x + g[i][1] * rp.y + g[i][2] * rp.z);
            let a = &self.a_rows;
            let mut x = [0.0; linalg::ROWS];
            for k in 0..n {
                x[k] = a[0][k] * y[0] + a[1][k] * y[1] + a[2][k] * y[2];
            }
            x
        } else {
            self.scaled
                .min_norm_transposed(&[rp.x, rp.y, rp.z, 0.0, 0.0, 0.0])
        };
        for k in 0..n {
            d1[k] = x[k] * self.caps[k];
        }
        damp_into_caps(&self.jp_rows, rp, &self.caps, n, &mut d1);
        let free = self.free;
        if free == 0 {
            return (d1, d2);
        }
        // v = W r_o − W J_o Δ₁.
        let mut v = [0.0; linalg::ROWS];
        for (r, x) in v.iter_mut().take(3).enumerate() {
            *x = self.weights[r] * ro[r] - self.jo(r, &d1);
        }
        let y: [f64; linalg::COLS] = if free == 1 {
            // B⁺ v = Bᵀ v / |B|² for a single column.
            let c = &self.b[0];
            let nn: f64 = c[..3].iter().map(|x| x * x).sum();
            let mut y = [0.0; linalg::COLS];
            y[0] = (c[0] * v[0] + c[1] * v[1] + c[2] * v[2]) / nn;
            y
        } else {
            self.aux.least_squares(&v)
        };
        for (i, zi) in self.z.iter().enumerate().take(free) {
            for k in 0..n {
                d2[k] += zi[k] * y[i];
            }
        }
        (d1, d2)
    }
}

/// One step of the chosen method with heap matrices and SVD pseudo-inverses,
/// split into its tip part and its axis part (the paper's stacked step is
/// all "tip part"). The tip part is damped just enough to stay inside the
/// trust region `caps` (Levenberg–Marquardt). The reference form of
/// the QR path of [`Factored`], used where that one declines
/// (ill-conditioned matrices).
fn step_svd(
    jac: &JacobianColumns,
    n: usize,
    rp: &Vector3<f64>,
    ro: &Vector3<f64>,
    opts: &Options,
    caps: &[f64],
) -> (Joints, Joints) {
    let within = |d: &DVector<f64>| d.iter().zip(caps).all(|(x, c)| x.abs() <= *c);
    let out = |d: &DVector<f64>| -> Joints {
        let mut a = [0.0; MAX_JOINTS];
        a[..n].copy_from_slice(d.as_slice());
        a
    };
    if opts.method == Method::Paper {
        let j = DMatrix::from_fn(6, n, |r, c| jac[c][r]);
        let r = DVector::from_vec(vec![rp.x, rp.y, rp.z, ro.x, ro.y, ro.z]);
        return (out(&(pinv(&j) * r)), [0.0; MAX_JOINTS]);
    }
    let jp = DMatrix::from_fn(3, n, |r, c| jac[c][r]);
    let w = &opts.axis_weights;
    let jo = DMatrix::from_fn(3, n, |r, c| w[r] * jac[c][r + 3]);
    let rp = DVector::from_column_slice(rp.as_slice());
    let ro = DVector::from_vec(vec![w[0] * ro.x, w[1] * ro.y, w[2] * ro.z]);
    let mut dq1 = damped(&jp, &rp, caps, 0.0);
    if !within(&dq1) {
        // Smallest damping (in decades) that keeps the tip step in bounds.
        let mut lambda = 1e-6;
        while lambda < 1e6 {
            dq1 = damped(&jp, &rp, caps, lambda);
            if within(&dq1) {
                break;
            }
            lambda *= 10.0;
        }
    }
    let jp_pinv = pinv(&jp);
    let null = DMatrix::identity(n, n) - &jp_pinv * &jp;
    let jon = &jo * &null;
    let dq2 = &null * (pinv(&jon) * (ro - &jo * &dq1));
    (out(&dq1), out(&dq2))
}

/// Largest change of a linear axis per Newton step, mm.
const STEP_LINEAR_MM: f64 = 0.05;
/// Largest change of a rotary axis per Newton step, rad.
const STEP_ROTARY_RAD: f64 = 5e-4;
/// Largest total compensation of a linear axis, mm: far above any geometric
/// error compensation (micrometres), low enough to stop a wandering iteration.
pub const MAX_COMPENSATION_MM: f64 = 0.5;
/// Largest total compensation of a rotary axis, rad (0.29°).
pub const MAX_COMPENSATION_RAD: f64 = 5e-3;

/// Refines joint values `q0` so that the actual machine (`chain` with
/// `errors`) puts the tool on `target`.
///
/// Safeguards: each step is scaled into a trust region (0.05 mm, 0.5 mrad
/// per axis), the axis part of the step is backtracked until it does not
/// make things worse, and the total compensation is bounded (0.5 mm, 5 mrad):
/// near the singular poses of a four-axis machine (the tool tip on the C
/// axis) a tangential tip error would need an unbounded turn of C, and the
/// refinement then stops with the best compensation within bounds
/// (`converged == false`).
///
/// The steps are computed on the stack (`Factored`: a closed-form Gram
/// solve for three or four joints, Householder QR of the 3×n and 6×n
/// problems otherwise, chains of at most [`MAX_JOINTS`] joints); a problem
/// whose matrices are ill-conditioned is solved with SVD pseudo-inverses
/// instead. With [`Method::Exact`] the Jacobian and its factorisation are
/// kept from step to step while each step shrinks the tool-tip residual at
/// least `CHORD_GAIN` times (simplified Newton; the trial points are then
/// evaluated without a Jacobian), and evaluated again where a step gains
/// less or fails; the other methods evaluate theirs at every step.
pub fn refine(
    chain: &Chain,
    errors: &dyn JointErrors,
    target: &Pose,
    q0: &[f64],
    opts: &Options,
) -> Refined {
    thread_local! {
        /// The factorisations of [`refine`], kept per thread (a few kB that
        /// would otherwise be cleared for every pose).
        static FACTORS: std::cell::RefCell<Factored> =
            const { std::cell::RefCell::new(Factored::EMPTY) };
    }
    FACTORS.with_borrow_mut(|factors| refine_with(chain, errors, target, q0, opts, factors))
}

/// [`refine`] with the caller's factorisation space.
fn refine_with(
    chain: &Chain,
    errors: &dyn JointErrors,
    target: &Pose,
    q0: &[f64],
    opts: &Options,
    factors: &mut Factored,
) -> Refined {
    let n = q0.len();
    assert!(
        n <= MAX_JOINTS && n == chain.dof(),
        "refine: {n} joint values for a chain of {} joints (at most {MAX_JOINTS})",
        chain.dof()
    );
    let mut step_cap = [0.0; MAX_JOINTS];
    let mut total_cap = [0.0; MAX_JOINTS];
    for (k, j) in chain.joints.iter().enumerate() {
        let revolute = j.kind == crate::machine::chain::JointKind::Revolute;
        step_cap[k] = if revolute {
            STEP_ROTARY_RAD
        } else {
            STEP_LINEAR_MM
        };
        total_cap[k] = if revolute {
            MAX_COMPENSATION_RAD
        } else {
            MAX_COMPENSATION_MM
        };
    }
    // The iteration moves the offsets `d` from `q0`, not the joint values
    // themselves: a rotary at thousands of degrees resolves its value to
    // 1e-14 rad or so, its offset to far below that. The exact method
    // takes its rotaries' sines and cosines at `q0 + d` from those at `q0`
    // by the addition theorem with the exact offsets (`NearTrig::shifted`),
    // so large angles cost no precision; the other methods evaluate at the
    // rounded values, as printed.
    let near = (opts.method == Method::Exact).then(|| chain.trig_at(q0));
    let at = |d: &[f64]| -> [f64; MAX_JOINTS] {
        let mut q = [0.0; MAX_JOINTS];
        for k in 0..n {
            q[k] = q0[k] + d[k];
        }
        q
    };
    let eval = |d: &[f64], jac: &mut JacobianColumns| -> Pose {
        let q = at(d);
        match (opts.method, &near) {
            (Method::Exact, Some(near)) => {
                chain.pose_and_jacobian_near(&q[..n], errors, jac, &near.shifted(d))
            }
            (Method::Exact, None) => chain.pose_and_jacobian_into(&q[..n], errors, jac),
            (Method::Theoretical | Method::Paper, _) => {
                chain.pose_and_jacobian_into(&q[..n], &NoErrors, jac);
                chain.pose(&q[..n], errors)
            }
        }
    };
    // The pose alone, where the Jacobian is not needed.
    let eval_pose = |d: &[f64]| -> Pose {
        let q = at(d);
        match &near {
            Some(near) => chain.pose_near(&q[..n], errors, &near.shifted(d)),
            None => chain.pose(&q[..n], errors),
        }
    };
    // Offsets from q0 (mm / rad).
    let mut d = [0.0; MAX_JOINTS];
    let mut iterations = 0;
    let mut converged = false;
    let mut jac = [[0.0; 6]; MAX_JOINTS];
    let mut pose = eval(&d[..n], &mut jac);
    // The residuals of `pose`, carried from step to step.
    let mut tip = pose.tip_distance(target);
    let mut ax = pose.axis_angle(target);
    let (start_tip, start_ax) = (tip, ax);
    factors.factor(&jac, n, opts, &step_cap);
    let mut trial = [0.0; MAX_JOINTS];
    let mut jac2 = [[0.0; 6]; MAX_JOINTS];
    // The exact method keeps its Jacobian while the steps contract fast
    // (simplified Newton): every trial is then evaluated without one.
    let chord = opts.method == Method::Exact;
    // The Jacobian was evaluated at the current joint values.
    let mut fresh = true;
    loop {
        let (rp, ro) = residual(target, &pose);
        if iterations >= opts.max_iterations {
            break;
        }
        let (d1, d2) = if factors.usable {
            factors.step(&rp, &ro)
        } else {
            step_svd(&jac, n, &rp, &ro, opts, &step_cap[..n])
        };
        // Trust region: scale the whole step so no axis moves too far.
        let mut scale = 1.0f64;
        for k in 0..n {
            let s = (d1[k] + d2[k]).abs();
            if s > step_cap[k] {
                scale = scale.min(step_cap[k] / s);
            }
        }
        // Already there: the tip is met and the step is at floating-point level.
        let negligible =
            (0..n).all(|k| (scale * (d1[k] + d2[k])).abs() <= 1e-14 * (1.0 + d[k].abs()));
        if negligible && (tip <= opts.tip_tolerance_mm || opts.method == Method::Paper) {
            converged = true;
            break;
        }
        // Backtrack the axis part until the move is no worse (tip first).
        let mut accepted = None;
        let mut s2 = 1.0;
        for _ in 0..12 {
            for k in 0..n {
                trial[k] = d[k] + scale * (d1[k] + s2 * d2[k]);
            }
            let within = (0..n).all(|k| trial[k].abs() <= total_cap[k]);
            if within {
                // After a step this small the next one is at floating-point
                // level (Newton: the residual goes with the step squared), so
                // the trial is most likely the result: its Jacobian is only
                // computed if another step turns out to be needed.
                let final_guess = (0..n)
                    .all(|k| (trial[k] - d[k]).abs() <= FINAL_STEP * (1.0 + (q0[k] + d[k]).abs()));
                let p2 = if chord || final_guess {
                    eval_pose(&trial[..n])
                } else {
                    eval(&trial[..n], &mut jac2)
                };
                let tip2 = p2.tip_distance(target);
                let ax2 = p2.axis_angle(target);
                // The paper's step is taken as printed (no safeguard but the bounds).
                let tip_ok = opts.method == Method::Paper
                    || tip2 <= tip.max(opts.tip_tolerance_mm) * (1.0 + 1e-9) + 1e-15;
                let ax_ok = opts.method == Method::Paper || ax2 <= ax + 1e-15 || tip2 < 0.5 * tip;
                if tip_ok && ax_ok {
                    accepted = Some((p2, tip2, ax2, !chord && !final_guess));
                    break;
                }
            }
            s2 *= 0.5;
        }
        let Some((p2, tip2, ax2, with_jacobian)) = accepted else {
            if chord && !fresh {
                // The kept Jacobian may be what fails: evaluate it here
                // and try again before giving up.
                pose = eval(&d[..n], &mut jac);
                (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
                factors.factor(&jac, n, opts, &step_cap);
                fresh = true;
                continue;
            }
            // No step improves within the bounds: this is the best there is.
            converged = tip <= opts.tip_tolerance_mm;
            break;
        };
        iterations += 1;
        d[..n].copy_from_slice(&trial[..n]);
        pose = p2;
        if with_jacobian {
            std::mem::swap(&mut jac, &mut jac2);
            factors.factor(&jac, n, opts, &step_cap);
        }
        let (last_tip, last_ax) = (tip, ax);
        (tip, ax) = (tip2, ax2);
        // Converged when the tip is met and neither the tip nor the axis
        // improves any more at floating-point level: the tip is at that
        // level, or it stopped improving.
        // Floating-point floor of the tip: a few ulps of the coordinates.
        let floor = 1e-14 * (1.0 + target.tip.amax());
        let tip_settled = tip2 <= opts.tip_tolerance_mm
            && (tip2 <= floor || last_tip - tip2 <= floor + 1e-9 * last_tip);
        let ax_settled = last_ax - ax2 <= 1e-15 + 1e-9 * last_ax;
        if opts.method == Method::Paper {
            if (last_tip - tip2).abs() <= floor + 1e-9 * last_tip
                && (last_ax - ax2).abs() <= 1e-15 + 1e-9 * last_ax
            {
                converged = true;
                break;
            }
        } else if tip_settled && ax_settled {
            converged = true;
            break;
        }
        if chord {
            // Keep the Jacobian while a step gains at least CHORD_GAIN on
            // the tip (or the tip is at its floor); otherwise evaluate it
            // where the iteration stands.
            fresh = false;
            if tip2 > floor && tip2 * CHORD_GAIN > last_tip {
                pose = eval(&d[..n], &mut jac);
                (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
                factors.factor(&jac, n, opts, &step_cap);
                fresh = true;
            }
        } else if !with_jacobian {
            pose = eval(&d[..n], &mut jac);
            (tip, ax) = (pose.tip_distance(target), pose.axis_angle(target));
            factors.factor(&jac, n, opts, &step_cap);
        }
    }
    // Where it did not converge, the step was held back by the bounds of a
    // joint that would need an unbounded move (a four-axis machine's C with
    // the tip on or next to its axis). One last step on the other joints
    // removes what they can still remove of the tip residual. Where no
    // admissible move can then reduce it by more than the tip tolerance (to
    // first order), or removing it would take moves beyond the
    // compensation bounds (millimetres and radians for micrometres), this
    // is the best the machine can do here (`best_within_bounds`).
    let mut best_within_bounds = false;
    if !converged {
        let mut j = [[0.0; 6]; MAX_JOINTS];
        for pass in 0..POLISH_STEPS + 1 {
            let p = eval(&d[..n], &mut j);
            let r = target.tip - p.tip;
            let rn = r.norm();
            let column = |k: usize| Vector3::new(j[k][0], j[k][1], j[k][2]);
            // Joints that can still help: they move the tip, and removing
            // the residual's component along them fits within their bound.
            let free: Vec<usize> = (0..n)
                .filter(|&k| {
                    let c = column(k);
                    let cn2 = c.norm_squared();
                    cn2 > 0.0 && c.dot(&r).abs() / cn2 <= total_cap[k] - d[k].abs()
                })
                .collect();
            // What the free joints can still remove, to first order: the
            // residual's projection on the directions they move the tip.
            let jf = DMatrix::from_fn(3, free.len(), |row, c| j[free[c]][row]);
            let rv = DVector::from_column_slice(r.as_slice());
            let step = if free.is_empty() {
                None
            } else {
                jf.clone().svd(true, true).solve(&rv, 1e-12).ok()
            };
            let removable = step.as_ref().map_or(0.0, |s| (&jf * s).norm());
            let gain = rn - (rn * rn - removable * removable).max(0.0).sqrt();
            // Stuck when no admissible move gains the tip tolerance.
            let stuck = gain <= opts.tip_tolerance_mm.max(1e-14 * (1.0 + target.tip.amax()));
            let Some(step) = step.filter(|_| !stuck && pass < POLISH_STEPS) else {
                best_within_bounds = stuck;
                break;
            };
            let mut trial = d;
            for (c, &k) in free.iter().enumerate() {
                trial[k] += step[c];
            }
            // A step beyond the bounds (millimetres and radians for a few
            // micrometres: the machine is singular there), or one that
            // gains nothing, leaves this the best there is.
            if (0..n).any(|k| trial[k].abs() > total_cap[k]) {
                best_within_bounds = true;
                break;
            }
            let p2 = eval_pose(&trial[..n]);
            let tip2 = p2.tip_distance(target);
            if tip2 >= tip {
                best_within_bounds = true;
                break;
            }
            d = trial;
            (tip, ax) = (tip2, p2.axis_angle(target));
            converged = tip <= opts.tip_tolerance_mm;
            if converged {
                break;
            }
        }
    }
    let q = at(&d[..n]);
    Refined {
        tip_residual_mm: tip,
        axis_residual_rad: ax,
        start_tip_mm: start_tip,
        start_axis_rad: start_ax,
        q: q[..n].iter().copied().collect(),
        iterations,
        converged,
        best_within_bounds,
    }
}

/// Per-block record of a compensation run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BlockRecord {
    /// 1-based line of the block.
    pub line: usize,
    /// Newton iterations.
    pub iterations: usize,
    /// Tool-tip error before compensation (theoretical axes on the actual machine), mm.
    pub tip_error_before_mm: f64,
    /// Remaining tool-tip error after compensation, mm.
    pub tip_residual_mm: f64,
    /// Orientation error before compensation, µrad.
    pub orientation_error_before_urad: f64,
    /// Remaining orientation error after compensation, µrad.
    pub orientation_residual_urad: f64,
    /// Tool-tip error of the axis words as written (rounded to their
    /// decimals), mm: what the machine really gets.
    pub tip_residual_written_mm: f64,
    /// Orientation error of the axis words as written, µrad.
    pub orientation_residual_written_urad: f64,
    /// Compensation per axis (compensated − theoretical), output order, mm / deg.
    pub compensation: JointValues,
}

/// What to do with a block that does not converge or breaks a limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnFail {
    /// Stop with an error naming the line (default).
    Error,
    /// Keep the theoretical axes for that block and warn.
    Theoretical,
    /// Keep the best compensation found within bounds and warn.
    Best,
}

/// A [`crate::post::PoseSolver`] that starts from the analytic IK and refines
/// on the error-aware chain.
pub struct CompensatingSolver<'a> {
    /// The machine (theoretical chain, axes, limits).
    pub machine: &'a crate::machine::Machine,
    /// The actual chain (fixed error elements inserted).
    pub actual_chain: Chain,
    /// Position-dependent errors (shared with worker threads).
    pub errors: &'a (dyn JointErrors + Sync),
    /// Analytic IK of the theoretical machine.
    pub ik: crate::machine::IkSolver,
    /// Refinement options.
    pub options: Options,
    /// Policy for failing blocks.
    pub on_fail: OnFail,
    /// Tip tolerance that counts as converged for the policy, mm.
    pub accept_tip_mm: f64,
    /// Largest tool-axis miss of the theoretical solution accepted (a
    /// four-axis machine off its cone), rad; as `post`'s.
    pub axis_tolerance_rad: f64,
    /// Records, one per block.
    pub records: Vec<BlockRecord>,
    /// Warnings.
    pub warnings: Vec<String>,
    /// Decimals of the written axis words, output order (the machine's or
    /// `--decimals`): the miss of the values as written is reported beside
    /// that of the solution. Empty: not rounded.
    pub decimals: Vec<u32>,
    /// Blocks at a singularity where the best compensation within bounds
    /// was kept with a tool-tip residual above `accept_tip_mm`.
    pub singular_blocks: usize,
    /// Backlash to pre-compensate: (joint, reversal value in mm / rad).
    pub backlash: Vec<(usize, f64)>,
    /// Direction of the last motion of each joint in `backlash`, by the
    /// rule `diagnose` and `simulate` use (a reversal counts once the axis
    /// is back by more than the dead band); filled on the first block.
    pub directions: Vec<crate::diagnose::effects::DirectionTracker>,
}

impl CompensatingSolver<'_> {
    /// Backlash of the model's diagnosed effects, for pre-compensation, and
    /// a warning for the dynamic effects a block-wise post cannot apply.
    pub fn dynamic_effects(
        model: &crate::geometric::model::ErrorModel,
        chain: &Chain,
    ) -> (Vec<(usize, f64)>, Vec<String>) {
        use crate::diagnose::effects::Effect;
        let mut backlash = Vec::new();
        let mut warnings = Vec::new();
        for e in &model.effects {
            match &e.effect {
                Effect::Backlash { axis, value } => {
                    if let Some(j) = chain.joint_index(axis) {
                        let v = if chain.joints[j].kind == crate::machine::chain::JointKind::Revolute {
                            value.to_radians()
                        } else {
                            *value
                        };
                        backlash.push((j, v));
                    }
                }
                Effect::ServoLag { axis, .. } | Effect::ThermalDrift { axis, .. } => warnings.push(format!(
                    "the model's {} of {axis} depends on speed or time along the run; compensate does not apply it (it is a controller feed-forward or a thermal model's job)",
                    e.effect.kind().name()
                )),
                _ => {}
            }
        }
        (backlash, warnings)
    }
}

impl crate::post::PoseSolver for CompensatingSolver<'_> {
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        let th = self.theoretical(pose, previous)?;
        let r = self.refine_block(pose, &th);
        self.commit(pose, &th, &r, line)
    }
}

impl CompensatingSolver<'_> {
    /// Stage 1 of [`crate::post::PoseSolver::solve`] (in block order): the
    /// analytic IK of the theoretical machine, continuing from `previous`.
    pub fn theoretical(
        &self,
        pose: &Pose,
        previous: Option<&[f64]>,
    ) -> std::result::Result<JointValues, String> {
        let s = self.ik.solve(pose, previous).map_err(|e| e.to_string())?;
        if s.axis_miss_rad > self.axis_tolerance_rad {
            return Err(crate::post::unreachable_axis(
                &self.machine.name,
                s.axis_miss_rad,
                self.axis_tolerance_rad,
            ));
        }
        Ok(s.q)
    }

    /// Stage 2 (independent per block, any thread): the Newton refinement
    /// from the theoretical joint values `th`.
    pub fn refine_block(&self, pose: &Pose, th: &[f64]) -> Refined {
        refine(&self.actual_chain, self.errors, pose, th, &self.options)
    }

    /// Stage 3 (in block order): the failure policy, backlash
    /// pre-compensation and the block's record.
    pub fn commit(
        &mut self,
        pose: &Pose,
        th: &JointValues,
        r: &Refined,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        // A tip within the accepted residual is met, whether or not the
        // tool axis had settled. Where the machine is singular, the best
        // compensation within bounds is kept, and said.
        let singular = r.best_within_bounds && r.tip_residual_mm <= r.start_tip_mm;
        // The paper's step stops where its least squares balances tip and
        // axis (picometres of tip on a four-axis machine): that point is
        // its answer, whatever the tip tolerance.
        let paper_fixed_point = r.converged && self.options.method == Method::Paper;
        let failure = if r.tip_residual_mm > self.accept_tip_mm && !singular && !paper_fixed_point {
            Some(format!(
                "compensation did not converge: tool-tip residual {:.3e} mm after {} iterations, more than the accepted {:.1e} mm",
                r.tip_residual_mm, r.iterations, self.accept_tip_mm
            ))
        } else if self.ik.within_all_limits(&r.q) {
            if r.tip_residual_mm > self.accept_tip_mm && !paper_fixed_point {
                self.singular_blocks += 1;
                self.warnings.push(format!(
                    "line {line}: the machine is singular here (for a four-axis lens machine: the tool tip on or next to the C axis); {:.4} µm of the {:.4} µm tool-tip error lie where no move within the compensation bounds reaches; the best compensation is kept",
                    r.tip_residual_mm * 1e3,
                    r.start_tip_mm * 1e3
                ));
            }
            None
        } else {
            self.ik
                .check_limits(&r.q)
                .err()
                .map(|e| format!("compensated axes break a limit: {e}"))
        };
        let q = match failure {
            None => r.q.clone(),
            Some(msg) => match self.on_fail {
                OnFail::Error => return Err(msg),
                OnFail::Theoretical => {
                    self.warnings
                        .push(format!("line {line}: {msg}; theoretical axes kept"));
                    th.clone()
                }
                OnFail::Best if self.ik.within_all_limits(&r.q) => {
                    self.warnings.push(format!(
                        "line {line}: {msg}; best compensation within bounds kept"
                    ));
                    r.q.clone()
                }
                OnFail::Best => {
                    self.warnings.push(format!(
                        "line {line}: {msg}; theoretical axes kept (limits)"
                    ));
                    th.clone()
                }
            },
        };
        // Backlash: the axis lags its command by value/2 against the direction
        // of its last motion, so command value/2 further in that direction.
        // Where the machine really goes (after its backlash): what the record reports.
        let (after_tip, after_axis) = if q == r.q {
            (r.tip_residual_mm, r.axis_residual_rad)
        } else {
            let after = self.actual_chain.pose(&q, self.errors);
            (after.tip_distance(pose), after.axis_angle(pose))
        };
        // The direction is that of the commanded targets, in the units of the
        // program (mm, degrees), with the dead band of the effect catalogue.
        let mut q = q;
        if self.directions.len() != self.backlash.len() {
            use crate::diagnose::effects::{DIRECTION_DEAD_BAND, DirectionTracker};
            self.directions = vec![DirectionTracker::new(DIRECTION_DEAD_BAND); self.backlash.len()];
        }
        let mut lag = [0.0; crate::machine::chain::MAX_JOINTS];
        for (k, &(j, value)) in self.backlash.iter().enumerate() {
            let revolute =
                self.machine.chain.joints[j].kind == crate::machine::chain::JointKind::Revolute;
            let file_units = if revolute { q[j].to_degrees() } else { q[j] };
            lag[j] = 0.5 * value * self.directions[k].update(file_units);
            q[j] += lag[j];
        }
        // Where the machine goes with the words as written: rounded to their
        // decimals, less the backlash it lags by.
        let (written_tip, written_axis) = if self.decimals.is_empty() {
            (after_tip, after_axis)
        } else {
            let mut ext = self.machine.to_external(&q);
            for (v, &d) in ext.iter_mut().zip(&self.decimals) {
                let scale = 10f64.powi(d as i32);
                if let Some(i) = crate::numeric::round_half_away(*v * scale) {
                    *v = i as f64 / scale;
                }
            }
            let mut written = self.machine.to_internal(&ext);
            for (w, l) in written.iter_mut().zip(lag) {
                *w -= l;
            }
            let p = self.actual_chain.pose(&written, self.errors);
            (p.tip_distance(pose), p.axis_angle(pose))
        };
        let ext_c = self.machine.to_external(&q);
        let ext_t = self.machine.to_external(th);
        self.records.push(BlockRecord {
            line,
            iterations: r.iterations,
            tip_error_before_mm: r.start_tip_mm,
            tip_residual_mm: after_tip,
            orientation_error_before_urad: r.start_axis_rad * 1e6,
            orientation_residual_urad: after_axis * 1e6,
            tip_residual_written_mm: written_tip,
            orientation_residual_written_urad: written_axis * 1e6,
            compensation: ext_c
                .iter()
                .zip(&ext_t)
                .zip(&self.machine.axes)
                .map(|((c, t), a)| {
                    let d = c - t;
                    if a.rotary == crate::machine::RotaryMode::Modulo {
                        (d + 180.0).rem_euclid(360.0) - 180.0
                    } else {
                        d
                    }
                })
                .collect(),
        });
        Ok(crate::post::SolvedPose {
            axis_miss_rad: 0.0,
            q,
        })
    }
}

/// How many lines ahead the in-order pass asks for a line's memory.
const PREFETCH_LINES: usize = 4;

/// Asks the processor to bring the memory of `x` (a value or a slice)
/// into the cache, one 64-byte line at a time.
#[inline]
fn prefetch_bytes<T: ?Sized>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (x as *const T).cast::<i8>();
        for off in (0..std::mem::size_of_val(x)).step_by(64) {
            // SAFETY: a prefetch is a hint that never faults, whatever the
            // address; SSE is part of x86_64.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// Asks the processor to bring `line`'s items and bytes into the cache: a
/// chunk's lines are parsed by a pool thread, so to the in-order pass they
/// usually sit in another core's cache, and each line's items are a
/// separate allocation the hardware prefetcher cannot guess.
#[inline]
fn prefetch_line(line: &crate::gcode::Line) {
    prefetch_bytes(line.items.as_slice());
    prefetch_bytes(line.bytes.as_slice());
}

/// Lines per chunk of [`compensate_gcode`].
const CHUNK_LINES: usize = 512;

/// A solver for [`GcodeConverter`] that is never called (the chunked driver
/// solves outside the converter).
struct Unused;

impl crate::post::PoseSolver for Unused {
    fn solve(
        &mut self,
        _: &Pose,
        _: Option<&[f64]>,
        _: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        Err("internal: the chunked driver solves poses itself".into())
    }
}

/// One line of a chunk after the sequential first pass.
enum Entry {
    /// Bytes to write unchanged (a range of the chunk's text buffer).
    Text(usize, usize),
    /// A pose block (the chunk's jobs are in the same order).
    Pose,
}

/// A pose block of a chunk.
struct Job {
    line: usize,
    pending: PendingPose,
    th: JointValues,
    refined: Option<Refined>,
}

/// The buffers of a [`Chunk`] besides its lines, kept for the next chunk.
#[derive(Default)]
struct ChunkParts {
    text: Vec<u8>,
    entries: Vec<Entry>,
    jobs: Vec<Job>,
}

/// A chunk of the program between the driver's stages.
struct Chunk {
    /// The parsed lines.
    lines: Vec<crate::gcode::Line>,
    /// Text of the non-pose lines (ranges in `entries`).
    text: Vec<u8>,
    /// Every line of the chunk up to `stop`, in order.
    entries: Vec<Entry>,
    /// The pose blocks, in order.
    jobs: Vec<Job>,
    /// The first pass stopped at an error (raised once the lines before it
    /// are written).
    stop: Option<crate::error::Error>,
}

/// Compensates a G-code pose program, writing the machine program to `out`,
/// on every core: the result is the same for any number of threads.
///
/// The program goes through in chunks of lines, each in four stages:
///
/// 1. its lines are read (this thread) and parsed (a pool task);
/// 2. one sequential pass applies the modal state and solves the analytic IK
///    of each pose, continuing from the previous pose's theoretical solution
///    (branch choice and rotary unwinding need the order);
/// 3. the Newton refinements, independent per block, run in parallel;
/// 4. a last sequential pass applies the failure policy, backlash
///    pre-compensation and records in block order and writes the blocks.
///
/// The stages are pipelined: while the pool refines chunk *k* (stage 3) and
/// parses chunk *k + 2* (stage 1), this thread writes chunk *k − 1* (stage
/// 4), runs the first pass of chunk *k + 1* (stage 2) and reads the lines
/// after, so the in-order work overlaps the parallel work. `records` receives the per-block records after each chunk (memory
/// stays flat: at most four chunks are alive).
///
/// Unlike [`crate::post::post_gcode`] with the solver's
/// [`crate::post::PoseSolver`] interface, which continues each IK from the
/// previous block's *compensated* axes, the IK continues from the previous
/// *theoretical* solution: the two differ by the compensation (micrometres,
/// microradians), which changes neither the branch nor the turn of a rotary
/// except at an exact tie.
pub fn compensate_gcode<R: BufRead, W: Write + ?Sized>(
    machine: &crate::machine::Machine,
    solver: &mut CompensatingSolver<'_>,
    mut input: R,
    out: &mut W,
    opts: &PostOptions,
    mut progress: impl FnMut(u64),
    mut records: impl FnMut(&mut Vec<BlockRecord>) -> crate::error::Result<()>,
) -> crate::error::Result<PostStats> {
    use crate::error::Error;
    use rayon::prelude::*;
    let mut unused = Unused;
    let mut conv = GcodeConverter::new(machine, &mut unused, opts);
    // What the refinements need, apart from the solver's in-order state.
    let chain = solver.actual_chain.clone();
    let errors = solver.errors;
    let options = solver.options;
    let mut raw: Vec<Vec<u8>> = Vec::with_capacity(CHUNK_LINES);
    let mut number = 0usize;
    let mut bytes_read = 0u64;
    let mut previous_th: Option<JointValues> = None;
    let mut buf = Vec::new();
    let mut eof = false;

    // Reads the next chunk's lines into `raw`; how many (0 at the end).
    let mut read = |raw: &mut Vec<Vec<u8>>| -> crate::error::Result<usize> {
        let mut filled = 0;
        while filled < CHUNK_LINES && !eof {
            if raw.len() == filled {
                raw.push(Vec::with_capacity(128));
            }
            let b = &mut raw[filled];
            b.clear();
            match input.read_until(b'\n', b) {
                Ok(0) => eof = true,
                Ok(_) => filled += 1,
                Err(e) => return Err(Error::io(&opts.file_name, e)),
            }
        }
        Ok(filled)
    };
    // Parses the lines of `raw`, the first numbered `first`, into `lines`
    // (stage 1), reusing the lines' buffers.
    // (The lines take the raw buffers, which get the lines' old ones back.)
    let parse = |raw: &mut [Vec<u8>], first: usize, mut lines: Vec<crate::gcode::Line>| {
        lines.resize_with(raw.len(), Default::default);
        for (i, (b, line)) in raw.iter_mut().zip(lines.iter_mut()).enumerate() {
            crate::gcode::parse_line_swap(b, first + i, line);
        }
        lines
    };
    // Line vectors of written chunks, for reuse.
    let mut spare: Vec<Vec<crate::gcode::Line>> = Vec::new();
    // The other buffers of written chunks (cleared), for reuse: a chunk's
    // jobs take a few hundred kB, which a fresh vector would fault in page
    // by page and copy as it grows.
    let mut spare_parts: Vec<ChunkParts> = Vec::new();
    // Stage 2 of a parsed chunk.
    let mut first_pass = |conv: &mut GcodeConverter<'_>,
                          solver: &CompensatingSolver<'_>,
                          lines: Vec<crate::gcode::Line>,
                          parts: ChunkParts|
     -> Chunk {
        let mut chunk = Chunk {
            text: parts.text,
            entries: parts.entries,
            jobs: parts.jobs,
            stop: None,
            lines,
        };
        for (i, line) in chunk.lines.iter().enumerate() {
            if let Some(ahead) = chunk.lines.get(i + PREFETCH_LINES) {
                prefetch_line(ahead);
            }
            bytes_read += line.bytes.len() as u64;
            progress(bytes_read);
            let start = chunk.text.len();
            match conv.begin(line, &mut chunk.text) {
                Err(e) => {
                    chunk.stop = Some(e);
                    break;
                }
                Ok(None) => chunk.entries.push(Entry::Text(start, chunk.text.len())),
                Ok(Some(pending)) => {
                    match solver.theoretical(&pending.pose, previous_th.as_deref()) {
                        Ok(th) => {
                            previous_th = Some(th.clone());
                            chunk.entries.push(Entry::Pose);
                            chunk.jobs.push(Job {
                                line: i,
                                pending,
                                th,
                                refined: None,
                            });
                        }
                        Err(m) => {
                            chunk.stop = Some(conv.solve_error(line, &pending, m));
                            break;
                        }
                    }
                }
            }
        }
        chunk
    };

    // Stage 4 of a refined chunk; its first-pass error, if any, after its
    // lines are written. Gives the chunk's line vector back for reuse.
    let mut write = |conv: &mut GcodeConverter<'_>,
                     solver: &mut CompensatingSolver<'_>,
                     chunk: Chunk|
     -> crate::error::Result<(Vec<crate::gcode::Line>, ChunkParts)> {
        buf.clear();
        let mut done = chunk.jobs.iter().enumerate();
        for entry in &chunk.entries {
            match *entry {
                Entry::Text(a, b) => buf.extend_from_slice(&chunk.text[a..b]),
                Entry::Pose => {
                    let (j, job) = done.next().expect("one job per pose entry");
                    // The refinements were written on other cores.
                    if let Some(ahead) = chunk.jobs.get(j + PREFETCH_LINES) {
                        prefetch_bytes(ahead);
                    }
                    let line = &chunk.lines[job.line];
                    let refined = job.refined.as_ref().expect("refined in stage 3");
                    let solved = solver
                        .commit(&job.pending.pose, &job.th, refined, line.number)
                        .map_err(|m| conv.solve_error(line, &job.pending, m))?;
                    conv.finish(line, &job.pending, &solved, &mut buf)?;
                }
            }
        }
        out.write_all(&buf).map_err(|e| Error::io("<output>", e))?;
        records(&mut solver.records)?;
        match chunk.stop {
            Some(e) => Err(e),
            None => {
                let mut parts = ChunkParts {
                    text: chunk.text,
                    entries: chunk.entries,
                    jobs: chunk.jobs,
                };
                parts.text.clear();
                parts.entries.clear();
                parts.jobs.clear();
                Ok((chunk.lines, parts))
            }
        }
    };

    // The pipeline: while the pool refines chunk k and parses chunk k + 2,
    // this thread writes chunk k − 1 and runs the first pass of chunk k + 1.
    let mut raw_next: Vec<Vec<u8>> = Vec::with_capacity(CHUNK_LINES);
    let mut count = read(&mut raw)?;
    let mut parsed = (count > 0).then(|| parse(&mut raw[..count], 1, Vec::new()));
    number += count;
    count = read(&mut raw)?;
    let mut current: Option<Chunk> = None;
    let mut previous: Option<Chunk> = None;
    let mut stopped = false;
    while parsed.is_some() || current.is_some() || previous.is_some() {
        let first = number + 1;
        number += count;
        let mut parsed_next = None;
        let next = rayon::in_place_scope(|scope| {
            if let Some(c) = current.as_mut() {
                let (chain, options) = (&chain, &options);
                let jobs = &mut c.jobs;
                scope.spawn(move |_| {
                    jobs.par_iter_mut().for_each(|j| {
                        j.refined = Some(refine(chain, errors, &j.pending.pose, &j.th, options))
                    })
                });
            }
            if count > 0 && !stopped {
                let (lines, slot) = (&mut raw[..count], &mut parsed_next);
                let reuse = spare.pop().unwrap_or_default();
                scope.spawn(move |_| *slot = Some(parse(lines, first, reuse)));
            }
            if let Some(p) = previous.take() {
                let (lines, parts) = write(&mut conv, solver, p)?;
                spare.push(lines);
                spare_parts.push(parts);
            }
            let next = match parsed.take() {
                Some(lines) if !stopped => {
                    let parts = spare_parts.pop().unwrap_or_default();
                    Some(first_pass(&mut conv, solver, lines, parts))
                }
                _ => None,
            };
            // Read the chunk after while the pool works (the raw buffers
            // of the chunk being parsed are not touched).
            let n = if stopped { 0 } else { read(&mut raw_next)? };
            Ok::<_, crate::error::Error>((next, n))
        });
        let (next, n) = next?;
        // No chunk after one whose first pass stopped.
        stopped |= next.as_ref().is_some_and(|c| c.stop.is_some());
        previous = current.take();
        current = next;
        parsed = if stopped { None } else { parsed_next };
        std::mem::swap(&mut raw, &mut raw_next);
        count = n;
    }
    Ok(conv.stats)
}

/// Writes the JSON report of a compensation run block by block, in the
/// layout of `serde_json::to_string_pretty` of
/// `{"blocks": [...], "summary": {...}, "warnings": [...]}` (keys in
/// alphabetical order): the blocks stream out as they are computed, the
/// summary and the warnings follow at the end, so memory stays flat.
pub struct ReportWriter<W: std::io::Write> {
    out: W,
    blocks: usize,
    buf: Vec<u8>,
    /// Keys of the per-axis values: the axis and its unit (`X_mm`, `C_deg`).
    axis_keys: Vec<String>,
}

/// `values` (output order) as an object keyed by `keys`.
fn by_axis(keys: &[String], values: serde_json::Value) -> serde_json::Value {
    match values {
        serde_json::Value::Array(a) => keys.iter().cloned().zip(a).collect(),
        other => other,
    }
}

impl<W: std::io::Write> ReportWriter<W> {
    /// Starts the report for `machine` (writes the opening of the blocks
    /// array). Per-axis values are objects keyed by axis and unit
    /// (`{"X_mm": …, "C_deg": …}`).
    pub fn new(mut out: W, machine: &crate::machine::Machine) -> std::io::Result<Self> {
        out.write_all(b"{\n  \"blocks\": [")?;
        let axis_keys = machine
            .axes
            .iter()
            .map(|a| {
                let revolute = machine
                    .chain
                    .joints
                    .get(a.joint)
                    .is_some_and(|j| j.kind == crate::machine::chain::JointKind::Revolute);
                format!("{}_{}", a.name, if revolute { "deg" } else { "mm" })
            })
            .collect();
        Ok(ReportWriter {
            out,
            blocks: 0,
            buf: Vec::with_capacity(512),
            axis_keys,
        })
    }

    /// Appends one block.
    pub fn block(&mut self, r: &BlockRecord) -> std::io::Result<()> {
        self.buf.clear();
        self.buf
            .extend_from_slice(if self.blocks == 0 { b"\n" } else { b",\n" });
        let mut v = serde_json::to_value(r).map_err(std::io::Error::other)?;
        if let Some(c) = v.get_mut("compensation") {
            *c = by_axis(&self.axis_keys, c.take());
        }
        let text = serde_json::to_string_pretty(&v).map_err(std::io::Error::other)?;
        indent(&mut self.buf, &text, "    ", true);
        self.out.write_all(&self.buf)?;
        self.blocks += 1;
        Ok(())
    }

    /// Closes the blocks array and writes the summary and the warnings;
    /// returns the writer.
    pub fn finish(mut self, summary: &RunSummary, warnings: &[String]) -> std::io::Result<W> {
        let mut tail = Vec::new();
        tail.extend_from_slice(if self.blocks == 0 {
            b"]".as_slice()
        } else {
            b"\n  ]".as_slice()
        });
        let mut summary = serde_json::to_value(summary).map_err(std::io::Error::other)?;
        if let Some(obj) = summary.as_object_mut() {
            obj.remove("axes");
            if let Some(c) = obj.get_mut("compensation_range") {
                *c = by_axis(&self.axis_keys, c.take());
            }
        }
        for (key, v) in [
            ("summary", Ok(summary)),
            ("warnings", serde_json::to_value(warnings)),
        ] {
            let v = v.map_err(std::io::Error::other)?;
            let text = serde_json::to_string_pretty(&v).map_err(std::io::Error::other)?;
            tail.extend_from_slice(format!(",\n  \"{key}\": ").as_bytes());
            indent(&mut tail, &text, "  ", false);
        }
        tail.extend_from_slice(b"\n}");
        self.out.write_all(&tail)?;
        Ok(self.out)
    }
}

/// Appends `text` with every line indented by `pad` (the first line too when
/// `first`).
fn indent(out: &mut Vec<u8>, text: &str, pad: &str, first: bool) {
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push(b'\n');
        }
        if i > 0 || first {
            out.extend_from_slice(pad.as_bytes());
        }
        out.extend_from_slice(line.as_bytes());
    }
}

/// Summary of a compensation run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunSummary {
    /// Machine name.
    pub machine: String,
    /// Step method.
    pub method: Method,
    /// Poses compensated.
    pub poses: usize,
    /// Largest tool-tip error before compensation, mm.
    pub tip_error_before_max_mm: f64,
    /// Largest tool-tip residual after compensation, mm.
    pub tip_residual_max_mm: f64,
    /// Largest orientation error before, µrad.
    pub orientation_error_before_max_urad: f64,
    /// Largest orientation residual after, µrad.
    pub orientation_residual_max_urad: f64,
    /// Largest tool-tip error of the words as written, mm.
    pub tip_residual_written_max_mm: f64,
    /// Largest orientation error of the words as written, µrad.
    pub orientation_residual_written_max_urad: f64,
    /// Blocks whose orientation error got worse (by more than 1e-9 µrad).
    pub orientation_worse_blocks: usize,
    /// Largest iteration count.
    pub iterations_max: usize,
    /// Mean iteration count.
    pub iterations_mean: f64,
    /// Per-axis compensation range [min, max], output order, mm / deg.
    pub compensation_range: Vec<[f64; 2]>,
    /// Axis names in output order.
    pub axes: Vec<String>,
}

impl RunSummary {
    /// Summarises per-block records.
    pub fn new(machine: &crate::machine::Machine, method: Method, records: &[BlockRecord]) -> Self {
        let mut s = RunSummary::start(machine, method);
        for r in records {
            s.add(r);
        }
        s.finish()
    }

    /// An empty summary, to be fed block by block with [`RunSummary::add`]
    /// and closed with [`RunSummary::finish`] (memory does not grow with the
    /// length of the program).
    pub fn start(machine: &crate::machine::Machine, method: Method) -> Self {
        RunSummary {
            machine: machine.name.clone(),
            method,
            poses: 0,
            tip_error_before_max_mm: 0.0,
            tip_residual_max_mm: 0.0,
            orientation_error_before_max_urad: 0.0,
            orientation_residual_max_urad: 0.0,
            tip_residual_written_max_mm: 0.0,
            orientation_residual_written_max_urad: 0.0,
            orientation_worse_blocks: 0,
            iterations_max: 0,
            iterations_mean: 0.0,
            compensation_range: vec![[f64::INFINITY, f64::NEG_INFINITY]; machine.axes.len()],
            axes: machine.axes.iter().map(|a| a.name.clone()).collect(),
        }
    }

    /// Adds one block (while open, `iterations_mean` holds the sum).
    pub fn add(&mut self, r: &BlockRecord) {
        let s = self;
        s.poses += 1;
        s.tip_error_before_max_mm = s.tip_error_before_max_mm.max(r.tip_error_before_mm);
        s.tip_residual_max_mm = s.tip_residual_max_mm.max(r.tip_residual_mm);
        s.tip_residual_written_max_mm =
            s.tip_residual_written_max_mm.max(r.tip_residual_written_mm);
        s.orientation_residual_written_max_urad = s
            .orientation_residual_written_max_urad
            .max(r.orientation_residual_written_urad);
        s.orientation_error_before_max_urad = s
            .orientation_error_before_max_urad
            .max(r.orientation_error_before_urad);
        s.orientation_residual_max_urad = s
            .orientation_residual_max_urad
            .max(r.orientation_residual_urad);
        if r.orientation_residual_urad > r.orientation_error_before_urad + 1e-9 {
            s.orientation_worse_blocks += 1;
        }
        s.iterations_max = s.iterations_max.max(r.iterations);
        s.iterations_mean += r.iterations as f64;
        for (k, c) in r.compensation.iter().enumerate() {
            s.compensation_range[k][0] = s.compensation_range[k][0].min(*c);
            s.compensation_range[k][1] = s.compensation_range[k][1].max(*c);
        }
    }

    /// Closes the summary (the mean iteration count, empty ranges).
    pub fn finish(mut self) -> Self {
        if self.poses > 0 {
            self.iterations_mean /= self.poses as f64;
        } else {
            self.compensation_range = vec![[0.0, 0.0]; self.axes.len()];
        }
        self
    }

    /// A report a person can read.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "kinpost compensate — machine {}, {} poses, method {:?}",
            self.machine, self.poses, self.method
        );
        let _ = writeln!(
            t,
            "  tool-tip error:    before max {:.4} µm  →  after max {:.3e} mm as written (solution {:.3e} mm)",
            self.tip_error_before_max_mm * 1e3,
            self.tip_residual_written_max_mm,
            self.tip_residual_max_mm
        );
        let _ = writeln!(
            t,
            "  orientation error: before max {:.4} µrad ({:.4} arcsec)  →  after max {:.4} µrad ({:.4} arcsec); {} blocks worse",
            self.orientation_error_before_max_urad,
            self.orientation_error_before_max_urad * 1e-6 * crate::analyze::ARCSEC_PER_RAD,
            self.orientation_residual_max_urad,
            self.orientation_residual_max_urad * 1e-6 * crate::analyze::ARCSEC_PER_RAD,
            self.orientation_worse_blocks
        );
        let _ = writeln!(
            t,
            "  Newton iterations: max {}, mean {:.2}",
            self.iterations_max, self.iterations_mean
        );
        for (name, r) in self.axes.iter().zip(&self.compensation_range) {
            let (unit, f) = if ["A", "B", "C"].contains(&name.as_str()) {
                ("µrad", 1e6 * std::f64::consts::PI / 180.0)
            } else {
                ("µm", 1e3)
            };
            let _ = writeln!(
                t,
                "  compensation {name}: {:.4} … {:.4} {unit}",
                r[0] * f,
                r[1] * f
            );
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::ErrorMotion;

    fn zhao() -> Chain {
        crate::machine::Machine::embedded("zhao2022-xzbc")
            .expect("embedded fixture")
            .chain
    }

    /// Micrometre-sized smooth errors on X, Z and B (C unmeasured).
    struct Small;
    impl JointErrors for Small {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            match joint {
                1 | 2 => Some(ErrorMotion::new(
                    2e-3 * (q / 60.0).sin(),
                    1e-3 * (q / 40.0).cos(),
                    1.5e-3 * (q / 50.0).sin(),
                    0.0,
                    3e-6 * (q / 70.0).cos(),
                    2e-6 * (q / 30.0).sin(),
                )),
                3 => Some(ErrorMotion::new(
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    5e-6 * (2.0 * q).sin(),
                    0.0,
                )),
                _ => None,
            }
        }
    }

    #[test]
    fn tip_met_exactly_and_axis_optimal_on_four_axis_machine() {
        let c = zhao();
        // A pose on the theoretical machine's cone.
        let q_th = [0.7, 35.0, -12.0, 0.4];
        let target = c.pose(&q_th, &NoErrors);
        let before = c.pose(&q_th, &Small);
        assert!(before.tip_distance(&target) > 1e-3);
        let exact = refine(&c, &Small, &target, &q_th, &Options::default());
        let theo = refine(
            &c,
            &Small,
            &target,
            &q_th,
            &Options {
                method: Method::Theoretical,
                ..Options::default()
            },
        );
        for r in [&exact, &theo] {
            assert!(r.converged);
            assert!(r.tip_residual_mm < 1e-12, "{}", r.tip_residual_mm);
        }
        assert!((exact.axis_residual_rad - theo.axis_residual_rad).abs() < 1e-12);
        assert!(exact.iterations <= theo.iterations);
        // The axis is optimal along the one-parameter family of joint values
        // that meet the tip: fix B a little off and re-meet the tip with X, Z, C.
        for db in [-1e-4, -1e-5, 1e-5, 1e-4] {
            let mut q = exact.q.clone();
            q[3] += db;
            for _ in 0..20 {
                let (p, j) = c.pose_and_jacobian(&q, &Small);
                let r = target.tip - p.tip;
                let m = nalgebra::Matrix3::from_fn(|row, col| j[(row, [0, 1, 2][col])]);
                let d = m.lu().solve(&r).unwrap();
                for (k, dk) in [0, 1, 2].iter().zip(d.iter()) {
                    q[*k] += dk;
                }
            }
            let p = c.pose(&q, &Small);
            assert!(p.tip_distance(&target) < 1e-12);
            assert!(
                p.axis_angle(&target) >= exact.axis_residual_rad - 1e-13,
                "db {db}"
            );
        }
    }

    #[test]
    fn paper_method_trades_tip_for_axis_when_axis_unreachable() {
        let c = zhao();
        let q_th = [0.7, 35.0, -12.0, 0.4];
        let target = c.pose(&q_th, &NoErrors);
        let paper = refine(
            &c,
            &Small,
            &target,
            &q_th,
            &Options {
                method: Method::Paper,
                ..Options::default()
            },
        );
        // Least squares on mixed mm and rad: the tip is not met to nanometres.
        assert!(paper.tip_residual_mm > 1e-7, "{}", paper.tip_residual_mm);
        assert!(paper.tip_residual_mm < 1e-3);
    }
}
