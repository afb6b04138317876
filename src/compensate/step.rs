//! The linear algebra of one Newton step: the methods, their options, and
//! the factorisations that solve the step (closed-form Gram, Householder QR,
//! SVD where ill-conditioned).

use crate::linalg::{self, Col, Qr};
use crate::machine::chain::{JacobianColumns, MAX_JOINTS, Pose};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

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

pub(super) fn residual(target: &Pose, p: &Pose) -> (Vector3<f64>, Vector3<f64>) {
    (target.tip - p.tip, target.axis - p.axis)
}

/// The minimum-norm least-squares solution `m⁺ b`, the rank cut as for a
/// kinematic Jacobian ([`crate::linalg::rank::JACOBIAN`] per dimension,
/// relative): by complete orthogonal decomposition
/// ([`crate::linalg::MinNorm`]), since nalgebra's SVD can miss the
/// pseudo-inverse of a rank-deficient matrix (the steps here are taken
/// where the Jacobian is ill-conditioned). Zero for a matrix with a
/// non-finite entry.
pub(super) fn min_norm(m: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
    let cut = crate::linalg::rank::JACOBIAN * m.nrows().max(m.ncols()) as f64;
    crate::linalg::MinNorm::new(m, crate::linalg::RankCut::Relative(cut))
        .map_or_else(|| DVector::zeros(m.ncols()), |f| f.solve(b))
}

/// Damped least-squares solution of `J Δ = r` with joint scaling `scale`
/// (Δ = S (J S)ᵀ ((J S)(J S)ᵀ + λ² I)⁻¹ r): λ = 0 is the minimum-norm
/// solution; a larger λ shortens the step along ill-conditioned directions.
pub(super) fn damped(
    j: &DMatrix<f64>,
    r: &DVector<f64>,
    scale: &[f64],
    lambda: f64,
) -> DVector<f64> {
    let n = j.ncols();
    let js = DMatrix::from_fn(j.nrows(), n, |row, c| j[(row, c)] * scale[c]);
    let sol = if lambda == 0.0 {
        min_norm(&js, r)
    } else {
        let a = &js * js.transpose() + DMatrix::identity(j.nrows(), j.nrows()) * (lambda * lambda);
        match a.lu().solve(r) {
            Some(y) => js.transpose() * y,
            None => DVector::zeros(n),
        }
    };
    DVector::from_fn(n, |k, _| sol[k] * scale[k])
}

/// Largest change of a linear axis per Newton step, mm.
pub(super) const STEP_LINEAR_MM: f64 = 0.05;
/// Largest change of a rotary axis per Newton step, rad.
pub(super) const STEP_ROTARY_RAD: f64 = 5e-4;

/// A direction of the axis part of the step (in the null space of the tip
/// rows) is used only where it turns the tool axis by at least this much
/// per radian of joint motion, linear axes counted at 100 mm a radian
/// (the ratio of the trust-region caps): see [`cheap_directions`].
pub const AXIS_GAIN_MIN: f64 = 1e-2;

/// Per joint, radians of motion per unit of the joint, from the trust-region
/// caps (1 for a rotary, 0.01 per mm for a linear axis).
fn per_unit(caps: &[f64]) -> Vec<f64> {
    caps.iter().map(|c| STEP_ROTARY_RAD / c).collect()
}

/// The null-space directions `z` (columns, n rows) of the axis part and
/// their effects `b = W J_o z` (columns, 3 rows), reduced to the span that
/// turns the tool axis by at least [`AXIS_GAIN_MIN`] per radian of joint
/// motion (`per`: radians per unit of each joint). Next to a singular pose
/// one direction buys microradians of tool axis with a large turn of a
/// rotary and the linear moves that keep the tip with it (`ΔC ≈ δ /
/// sin(tilt)` on a table-table machine near tilt 0: a scenario at a tilt
/// of 0.027° moved C by 0.28° and X by 0.5 mm for 1 µrad, and the tool
/// left the programmed path between the blocks); such a direction is
/// dropped and that part of the tool-axis error stays, reported.
///
/// The motion of `Σ yᵢ zᵢ` is measured by `|P Z y|` (`P = diag(per)`): with
/// `G = (P Z)ᵀ (P Z)` and `A = Bᵀ B`, the gains are the square roots of the
/// generalised eigenvalues of `A y = λ G y`. `None` when every direction
/// gains enough (the common case: nothing changes); otherwise the kept
/// directions `Z y` and `B y`, possibly none.
pub(super) fn cheap_directions(
    z: &DMatrix<f64>,
    b: &DMatrix<f64>,
    per: &[f64],
) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
    let f = z.ncols();
    if f == 0 {
        return None;
    }
    let pz = DMatrix::from_fn(z.nrows(), f, |r, c| z[(r, c)] * per[r]);
    let g = pz.transpose() * &pz;
    let a = b.transpose() * b;
    let cut = AXIS_GAIN_MIN * AXIS_GAIN_MIN;
    // G = L Lᵀ; the eigenvalues of L⁻¹ A L⁻ᵀ are those of A y = λ G y.
    let l = g.cholesky()?.l();
    let l_inv = l.clone().try_inverse()?;
    let sym = &l_inv * &a * l_inv.transpose();
    let eig = nalgebra::SymmetricEigen::new(sym);
    if eig.eigenvalues.iter().all(|&e| e >= cut) {
        return None;
    }
    let keep: Vec<usize> = (0..f).filter(|&i| eig.eigenvalues[i] >= cut).collect();
    // y = L⁻ᵀ v for each kept eigenvector v.
    let y =
        l_inv.transpose() * DMatrix::from_fn(f, keep.len(), |r, c| eig.eigenvectors[(r, keep[c])]);
    Some((z * &y, b * &y))
}

/// Joint-space vectors of the refinement (entries past the dof unused).
pub(super) type Joints = [f64; MAX_JOINTS];

/// Largest condition estimate of the Gram matrix `(J_p S)(J_p S)ᵀ` for
/// the closed-form tip step ([`Factored::factor_gram`]); above it the QR path.
pub(super) const GRAM_CONDITION_LIMIT: f64 = crate::linalg::rank::CONDITION_LIMIT;

/// Problems whose (small) matrices have a condition number above this are
/// handed to the SVD path; below it the Householder QR solution is accurate
/// to far better than the next Newton step needs.
pub(super) const QR_CONDITION_LIMIT: f64 = crate::linalg::rank::CONDITION_LIMIT;

/// Smallest damping (in decades from 1e-6) of the tip step `S (J S)ᵀ ((J S)
/// (J S)ᵀ + λ² I)⁻¹ r` that keeps it within `caps`, starting from the
/// undamped step `dq1`; `jp` holds the three tip rows. 3×3 solves on the stack.
pub(super) fn damp_into_caps(
    jp: &[Col],
    rp: &Vector3<f64>,
    caps: &Joints,
    n: usize,
    dq1: &mut Joints,
) {
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
pub(super) struct Factored {
    /// The last [`Factored::factor`] succeeded.
    pub(super) usable: bool,
    pub(super) n: usize,
    /// The paper's stacked 6×n problem (factored in `scaled`).
    pub(super) paper: bool,
    /// QR of `(J_p S)ᵀ` (of the stacked Jacobian for the paper's step).
    pub(super) scaled: Qr,
    /// Joint scaling `S` (the trust-region caps).
    pub(super) caps: Joints,
    /// The tip rows of the Jacobian (for the damped tip step).
    pub(super) jp_rows: [Col; 3],
    /// The axis rows of the Jacobian.
    pub(super) jo_rows: [Col; 3],
    /// Axis weights `W`.
    pub(super) weights: [f64; 3],
    /// Dimension of the null space of `J_p` the axis part may use (0 when
    /// the axis cannot move in it).
    pub(super) free: usize,
    /// Orthonormal basis of that null space.
    pub(super) z: [Col; 3],
    /// `B = W J_o Z` (3 × free).
    pub(super) b: [Col; 3],
    /// QR of `J_pᵀ` (null-space basis), then of `B`, when `free > 1`.
    pub(super) aux: Qr,
    /// The tip step is solved through the Gram matrix (see
    /// [`Factored::factor_gram`]) instead of `scaled`.
    pub(super) gram: bool,
    /// Gram path: the tip step's matrix `S Aᵀ (A Aᵀ)⁻¹` (n × 3), so that
    /// `Δ₁ = T r_p`.
    pub(super) tip_map: [[f64; 3]; MAX_JOINTS],
    /// One free direction: the axis part is `Δ₂ = z (cᵀ r_o − fᵀ Δ₁)`
    /// with `c = W b / |b|²` and `fᵀ = bᵀ W J_o / |b|²` (`b = W J_o z`).
    pub(super) axis_c: [f64; 3],
    /// See `axis_c`.
    pub(super) axis_f: Col,
}

impl Factored {
    /// Nothing factored yet.
    pub(super) const EMPTY: Factored = Factored {
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
        tip_map: [[0.0; 3]; MAX_JOINTS],
        axis_c: [0.0; 3],
        axis_f: [0.0; linalg::ROWS],
    };

    /// Factors the step for the Jacobian `jac` (columns, chain order), in
    /// place; `false` (and `usable` false) when a matrix is too
    /// ill-conditioned for the QR path (the caller then uses [`step_svd`]).
    pub(super) fn factor(
        &mut self,
        jac: &JacobianColumns,
        n: usize,
        opts: &Options,
        caps: &Joints,
    ) -> bool {
        self.usable = self.factor_qr(jac, n, opts, caps);
        if self.usable && self.free > 0 && !self.paper {
            self.usable = self.keep_cheap_directions();
        }
        if self.usable && self.free == 1 {
            self.factor_one_free();
        }
        self.usable
    }

    /// Drops the axis-part directions that turn the tool axis too little for
    /// the joint motion they cost ([`cheap_directions`]); `false` when the
    /// reduced problem is too ill-conditioned for the QR path.
    fn keep_cheap_directions(&mut self) -> bool {
        let (n, free) = (self.n, self.free);
        // One direction, the common case: the gain |b| / |P z| directly.
        if free == 1 {
            let motion: f64 = (0..n)
                .map(|k| (self.z[0][k] * STEP_ROTARY_RAD / self.caps[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            let gain = self.b[0][..3].iter().map(|x| x * x).sum::<f64>().sqrt();
            if gain < AXIS_GAIN_MIN * motion {
                self.free = 0;
            }
            return true;
        }
        // Two directions (five joints): the smaller gain in closed form,
        // λ_min of det(A − λ G) = 0, and nothing to do when it is enough.
        if free == 2 {
            let pz = |i: usize, k: usize| self.z[i][k] * STEP_ROTARY_RAD / self.caps[k];
            let dot_pz = |i: usize, j: usize| (0..n).map(|k| pz(i, k) * pz(j, k)).sum::<f64>();
            let dot_b =
                |i: usize, j: usize| (0..3).map(|r| self.b[i][r] * self.b[j][r]).sum::<f64>();
            let (g11, g12, g22) = (dot_pz(0, 0), dot_pz(0, 1), dot_pz(1, 1));
            let (a11, a12, a22) = (dot_b(0, 0), dot_b(0, 1), dot_b(1, 1));
            let det_g = g11 * g22 - g12 * g12;
            let det_a = a11 * a22 - a12 * a12;
            let mid = a11 * g22 + a22 * g11 - 2.0 * a12 * g12;
            let root = (mid * mid - 4.0 * det_g * det_a).max(0.0).sqrt();
            // The smaller root without cancellation: 2 det A / (mid + root).
            let lambda_min = 2.0 * det_a / (mid + root);
            if det_g > 0.0 && lambda_min >= AXIS_GAIN_MIN * AXIS_GAIN_MIN {
                return true;
            }
        }
        let z = DMatrix::from_fn(n, free, |r, c| self.z[c][r]);
        let b = DMatrix::from_fn(3, free, |r, c| self.b[c][r]);
        let Some((z2, b2)) = cheap_directions(&z, &b, &per_unit(&self.caps[..n])) else {
            return true;
        };
        self.free = z2.ncols();
        for i in 0..self.free {
            self.z[i] = [0.0; linalg::ROWS];
            self.b[i] = [0.0; linalg::ROWS];
            for k in 0..n {
                self.z[i][k] = z2[(k, i)];
            }
            for r in 0..3 {
                self.b[i][r] = b2[(r, i)];
            }
        }
        if self.free > 1 {
            self.aux.factor(&self.b[..self.free], 3);
            return self.aux.condition() <= QR_CONDITION_LIMIT;
        }
        true
    }

    /// The linear map of the axis part for one free direction (`axis_c`,
    /// `axis_f`): `y = bᵀ W (r_o − J_o Δ₁) / |b|²`, `Δ₂ = z y`.
    fn factor_one_free(&mut self) {
        let b = &self.b[0];
        let nn: f64 = b[..3].iter().map(|x| x * x).sum();
        let w = self.weights;
        self.axis_c = std::array::from_fn(|r| w[r] * b[r] / nn);
        self.axis_f = [0.0; linalg::ROWS];
        for k in 0..self.n {
            self.axis_f[k] = (0..3)
                .map(|r| b[r] * w[r] * self.jo_rows[r][k])
                .sum::<f64>()
                / nn;
        }
    }

    pub(super) fn factor_qr(
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
    pub(super) fn factor_gram(&mut self, a: &[Col; 3], n: usize) -> bool {
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
        for (k, (t, cap)) in self.tip_map.iter_mut().zip(self.caps).take(n).enumerate() {
            *t = std::array::from_fn(|j| {
                cap * (a[0][k] * inv[0][j] + a[1][k] * inv[1][j] + a[2][k] * inv[2][j])
            });
        }
        self.gram = true;
        true
    }

    /// Row `r` of `W J_o` applied to `v`.
    pub(super) fn jo(&self, r: usize, v: &Col) -> f64 {
        self.weights[r] * (0..self.n).map(|c| self.jo_rows[r][c] * v[c]).sum::<f64>()
    }

    /// The step for the residuals `rp` (tip) and `ro` (axis), split into its
    /// tip part and its axis part; the tip part damped just enough to stay
    /// inside the trust region (the caps).
    pub(super) fn step(&self, rp: &Vector3<f64>, ro: &Vector3<f64>) -> (Joints, Joints) {
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
        if self.gram {
            // S Aᵀ (A Aᵀ)⁻¹ r_p.
            for (d, t) in d1.iter_mut().zip(&self.tip_map).take(n) {
                *d = t[0] * rp.x + t[1] * rp.y + t[2] * rp.z;
            }
        } else {
            let x = self
                .scaled
                .min_norm_transposed(&[rp.x, rp.y, rp.z, 0.0, 0.0, 0.0]);
            for k in 0..n {
                d1[k] = x[k] * self.caps[k];
            }
        }
        damp_into_caps(&self.jp_rows, rp, &self.caps, n, &mut d1);
        let free = self.free;
        if free == 0 {
            return (d1, d2);
        }
        if free == 1 {
            let c = &self.axis_c;
            let y = c[0] * ro.x + c[1] * ro.y + c[2] * ro.z
                - (0..n).map(|k| self.axis_f[k] * d1[k]).sum::<f64>();
            for (d, z) in d2.iter_mut().zip(&self.z[0]).take(n) {
                *d = z * y;
            }
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

/// One step of the chosen method with heap matrices (the null space of
/// `J_p` from an SVD, minimum-norm solves by [`min_norm`]), split into its
/// tip part and its axis part (the paper's stacked step is
/// all "tip part"). The tip part is damped just enough to stay inside the
/// trust region `caps` (Levenberg–Marquardt). The reference form of
/// the QR path of [`Factored`], used where that one declines
/// (ill-conditioned matrices).
pub(super) fn step_svd(
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
        return (out(&min_norm(&j, &r)), [0.0; MAX_JOINTS]);
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
    // An orthonormal basis Z of the null space of J_p: the right singular
    // vectors of its singular values at the cut-off or below (J_p padded
    // with zero rows to n × n, so that the SVD gives all n of them). The
    // axis part is then Δ₂ = Z (W J_o Z)⁺ W (r_o − J_o Δ₁). (Not with the
    // projector N = I − J_p⁺ J_p: (W J_o N)⁺ is the pseudo-inverse of a
    // rank-deficient matrix, which nalgebra's SVD gets wrong by up to
    // 1e-4 relative, and with no null space N is rounding noise.)
    let mut padded = DMatrix::zeros(n.max(3), n);
    padded.rows_mut(0, 3).copy_from(&jp);
    let svd = padded.svd(false, true);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let cut = crate::linalg::rank::jacobian_cutoff(smax, 3, n);
    let v_t = svd.v_t.expect("right singular vectors were asked for");
    let null: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&i| svd.singular_values[i] <= cut)
        .collect();
    if null.is_empty() {
        return (out(&dq1), [0.0; MAX_JOINTS]);
    }
    let mut z = DMatrix::from_fn(n, null.len(), |r, c| v_t[(null[c], r)]);
    if let Some((cheap, _)) = cheap_directions(&z, &(&jo * &z), &per_unit(caps)) {
        z = cheap;
    }
    if z.ncols() == 0 {
        return (out(&dq1), [0.0; MAX_JOINTS]);
    }
    let dq2 = &z * min_norm(&(&jo * &z), &(ro - &jo * &dq1));
    (out(&dq1), out(&dq2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A well-conditioned Jacobian of `n` joints with entries of either
    /// sign, deterministic (the tip rows millimetres per unit, the axis
    /// rows smaller, as on a machine).
    fn jacobian(n: usize, seed: u64) -> JacobianColumns {
        let mut rng = crate::test_support::Lcg(seed);
        let mut jac = [[0.0; 6]; MAX_JOINTS];
        for col in jac.iter_mut().take(n) {
            for (r, x) in col.iter_mut().enumerate() {
                *x = rng.signed() * if r < 3 { 50.0 } else { 0.5 };
            }
        }
        jac
    }

    /// The task-priority step by its definition, with LU solves only:
    /// the tip part is the minimum-norm solution of `J_p Δ₁ = r_p` in the
    /// metric of the caps (`Δ₁ = S Aᵀ (A Aᵀ)⁻¹ r_p`, `A = J_p S`); the axis
    /// part minimises `|W (r_o − J_o (Δ₁ + Δ₂))|` over `J_p Δ₂ = 0` (the
    /// KKT system), or, where a direction of that null space turns the tool
    /// axis by less than [`AXIS_GAIN_MIN`] per radian of joint motion, over
    /// the span of the others: found here by the SVD of `W J_o N R⁻¹`
    /// (`N` the null space from the SVD of `J_p`, `P N = Q R`, `P` the
    /// radians per unit of each joint; not the Cholesky and symmetric
    /// eigenproblem of [`cheap_directions`]) and solved by the normal
    /// equations. The paper's step: least squares on the stacked 6×n
    /// Jacobian (normal equations).
    fn by_definition(
        jac: &JacobianColumns,
        n: usize,
        rp: &Vector3<f64>,
        ro: &Vector3<f64>,
        opts: &Options,
        caps: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        if opts.method == Method::Paper {
            let j = DMatrix::from_fn(6, n, |r, c| jac[c][r]);
            let r = DVector::from_vec(vec![rp.x, rp.y, rp.z, ro.x, ro.y, ro.z]);
            let x = (j.transpose() * &j)
                .lu()
                .solve(&(j.transpose() * r))
                .unwrap();
            return (x.as_slice().to_vec(), vec![0.0; n]);
        }
        let a = DMatrix::from_fn(3, n, |r, c| jac[c][r] * caps[c]);
        let y = (&a * a.transpose()).lu().solve(rp).unwrap();
        let x = a.transpose() * y;
        let d1: Vec<f64> = (0..n).map(|k| x[k] * caps[k]).collect();
        let w = opts.axis_weights;
        let wjo = DMatrix::from_fn(3, n, |r, c| w[r] * jac[c][r + 3]);
        let v = DVector::from_fn(3, |r, _| {
            w[r] * (ro[r] - (0..n).map(|k| jac[k][r + 3] * d1[k]).sum::<f64>())
        });
        if n > 3 {
            // The null space of J_p and the gain of its directions.
            let mut padded = DMatrix::zeros(n, n);
            for r in 0..3 {
                for c in 0..n {
                    padded[(r, c)] = jac[c][r];
                }
            }
            let svd = padded.svd(false, true);
            let v_t = svd.v_t.unwrap();
            let null: Vec<usize> = (0..n)
                .filter(|&i| svd.singular_values[i] < 1e-9 * svd.singular_values.max())
                .collect();
            let nm = DMatrix::from_fn(n, null.len(), |r, c| v_t[(null[c], r)]);
            let per = DMatrix::from_fn(n, n, |r, c| {
                if r == c {
                    STEP_ROTARY_RAD / caps[r]
                } else {
                    0.0
                }
            });
            let qr = (&per * &nm).qr();
            let r_inv = qr.r().try_inverse().unwrap();
            let gains = (&wjo * &nm * &r_inv).svd(false, true);
            let gv_t = gains.v_t.unwrap();
            let kept: Vec<usize> = (0..gains.singular_values.len())
                .filter(|&i| gains.singular_values[i] >= AXIS_GAIN_MIN)
                .collect();
            if kept.len() < null.len() {
                let basis = &nm
                    * &r_inv
                    * DMatrix::from_fn(null.len(), kept.len(), |r, c| gv_t[(kept[c], r)]);
                let b = &wjo * &basis;
                let coef = (b.transpose() * &b)
                    .lu()
                    .solve(&(b.transpose() * &v))
                    .unwrap();
                let d2 = &basis * coef;
                return (d1, d2.as_slice().to_vec());
            }
        }
        let mut kkt = DMatrix::zeros(n + 3, n + 3);
        kkt.view_mut((0, 0), (n, n))
            .copy_from(&(wjo.transpose() * &wjo));
        for r in 0..3 {
            for c in 0..n {
                kkt[(n + r, c)] = jac[c][r];
                kkt[(c, n + r)] = jac[c][r];
            }
        }
        let mut rhs = DVector::zeros(n + 3);
        rhs.rows_mut(0, n).copy_from(&(wjo.transpose() * v));
        let sol = kkt.lu().solve(&rhs).unwrap();
        (d1, sol.as_slice()[..n].to_vec())
    }

    /// Asserts that a step's tip and axis parts are `reference`'s to 1e-8
    /// of the step's size (`n` joints; `what` names the case).
    fn assert_same_step(
        (d1, d2): &(Joints, Joints),
        (e1, e2): &(Vec<f64>, Vec<f64>),
        n: usize,
        what: &str,
    ) {
        let scale = (0..n).fold(0.0f64, |m, k| m.max(e1[k].abs() + e2[k].abs()));
        for k in 0..n {
            assert!(
                (d1[k] - e1[k]).abs() <= 1e-8 * scale && (d2[k] - e2[k]).abs() <= 1e-8 * scale,
                "{what} joint {k}: {:e} {:e} against {:e} {:e}",
                d1[k],
                d2[k],
                e1[k],
                e2[k]
            );
        }
    }

    /// The stack-based step (closed-form Gram for three or four joints,
    /// Householder QR otherwise, the axis part's linear map for one free
    /// direction) is the task-priority step by its definition, tip part
    /// and axis part, for three to six joints, and the paper's stacked
    /// step is its least squares.
    #[test]
    fn factored_step_is_the_step_by_definition() {
        let caps = [5e-2, 5e-4, 5e-2, 5e-4, 5e-2, 5e-4, 5e-2];
        let rp = Vector3::new(3e-4, -2e-4, 1e-4);
        let ro = Vector3::new(-2e-6, 1e-6, 3e-6);
        for method in [Method::Exact, Method::Paper] {
            let opts = Options {
                method,
                axis_weights: [1.0, 0.5, 2.0],
                ..Options::default()
            };
            for n in 3..=6 {
                for seed in 1..20 {
                    let jac = jacobian(n, seed * 7 + n as u64);
                    let mut f = Factored::EMPTY;
                    assert!(f.factor(&jac, n, &opts, &caps), "n {n} seed {seed}");
                    let step = f.step(&rp, &ro);
                    let reference = by_definition(&jac, n, &rp, &ro, &opts, &caps[..n]);
                    assert_same_step(
                        &step,
                        &reference,
                        n,
                        &format!("{method:?} n {n} seed {seed}"),
                    );
                }
            }
        }
    }

    /// Next to the singular pose of a table-table machine (xyzac-trt at a
    /// tilt of 0.027°) a tool-axis error across the tilt can only be
    /// removed by turning C about δ / sin(A) and moving X and Y with it to
    /// keep the tip. That direction is dropped; the other (A, which turns
    /// the axis directly) is kept. Before, the axis part of the step turned
    /// C by 1.7e-2 rad for an error of 8 µrad (and a scenario's refinement
    /// ended with C 0.28° and X 0.5 mm away, the tool off the path between
    /// the blocks).
    #[test]
    fn a_costly_axis_direction_next_to_a_singular_pose_is_dropped() {
        let m = crate::machine::Machine::embedded("xyzac-trt").unwrap();
        let n = m.chain.dof();
        let order: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
        // Output order X Y Z A C; A at 0.027°, C at 30°.
        let values: Vec<f64> = order
            .iter()
            .map(|a| match *a {
                "X" => 80.0,
                "Y" => -40.0,
                "Z" => -60.0,
                "A" => 0.027,
                _ => 30.0,
            })
            .collect();
        let q = m.to_internal(&values);
        let mut jac = [[0.0; 6]; MAX_JOINTS];
        let pose = m
            .chain
            .pose_and_jacobian_into(&q, &crate::machine::chain::NoErrors, &mut jac);
        let caps: Vec<f64> = m
            .chain
            .joints()
            .iter()
            .map(|j| {
                if j.kind == crate::machine::chain::JointKind::Revolute {
                    STEP_ROTARY_RAD
                } else {
                    STEP_LINEAR_MM
                }
            })
            .collect();
        let mut cap_arr = [0.0; MAX_JOINTS];
        cap_arr[..n].copy_from_slice(&caps);
        // 8 µrad across the tool axis, in both directions across it.
        let axis = pose.axis;
        let across1 = axis.cross(&Vector3::x()).normalize();
        let across2 = axis.cross(&across1).normalize();
        let opts = Options::default();
        let c = m.chain.joints().iter().position(|j| j.name == "C").unwrap();
        for ro in [across1 * 8e-6, across2 * 8e-6, (across1 + across2) * 6e-6] {
            let rp = Vector3::zeros();
            let mut f = Factored::EMPTY;
            assert!(f.factor(&jac, n, &opts, &cap_arr));
            let step = f.step(&rp, &ro);
            let reference = by_definition(&jac, n, &rp, &ro, &opts, &caps);
            assert_same_step(&step, &reference, n, "xyzac-trt at A 0.027°");
            let svd = step_svd(&jac, n, &rp, &ro, &opts, &caps);
            assert_same_step(&svd, &reference, n, "xyzac-trt at A 0.027°, SVD form");
            // The C turn is at most what the gain limit allows for the error.
            assert!(
                step.1[c].abs() <= ro.norm() / AXIS_GAIN_MIN,
                "C turned by {:e} rad for {:e} rad",
                step.1[c],
                ro.norm()
            );
        }
    }

    /// The SVD form (the fallback where the Jacobian is ill-conditioned)
    /// is the step by its definition too. Before, it inverted the
    /// rounding noise of the null-space projection where there is no null
    /// space (three joints: an axis part larger than the tip part), and
    /// its axis part missed by up to 2e-4 relative elsewhere (the
    /// pseudo-inverse of the rank-deficient projected axis rows).
    #[test]
    fn svd_step_is_the_step_by_definition() {
        let caps = [5e-2, 5e-4, 5e-2, 5e-4, 5e-2, 5e-4, 5e-2];
        let rp = Vector3::new(3e-4, -2e-4, 1e-4);
        let ro = Vector3::new(-2e-6, 1e-6, 3e-6);
        let opts = Options {
            axis_weights: [1.0, 0.5, 2.0],
            ..Options::default()
        };
        for n in 3..=6 {
            for seed in 1..20 {
                let jac = jacobian(n, seed * 7 + n as u64);
                let step = step_svd(&jac, n, &rp, &ro, &opts, &caps[..n]);
                let reference = by_definition(&jac, n, &rp, &ro, &opts, &caps[..n]);
                assert_same_step(&step, &reference, n, &format!("n {n} seed {seed}"));
            }
        }
    }
}
