//! Small dense linear algebra on the stack for the per-pose hot paths
//! (compensation steps, the linear axes of the IK): Householder QR of a tall
//! m×k matrix with m ≤ 7 rows and k ≤ 6 columns, least squares and
//! minimum-norm solutions, and a condition estimate so that callers can fall
//! back to an SVD when a problem is ill-conditioned; [`MinNorm`], minimum-norm
//! least squares of any rank by complete orthogonal decomposition (where
//! nalgebra's SVD can be wrong); and [`rank`], the one rank policy every
//! module follows.

// Dense matrix code reads best with explicit row and column indices.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};

/// The rank policy: where a matrix is treated as rank-deficient. Every
/// pseudo-inverse, SVD solve and dependence test of the crate takes its
/// cut-off from here, by the role of the matrix:
///
/// | role | matrix | a singular value σ counts as zero when |
/// | --- | --- | --- |
/// | [`rank::JACOBIAN`] | a kinematic Jacobian (compensation step, the paper's stacked step) | σ ≤ 1e-12 · max(m, n) · σ_max (LAPACK's rule, ε·max(m,n), with a margin of about 4500) |
/// | [`rank::TIP_SYSTEM_MM`] | a tip system `J δ = r` in mm per mm or rad (the joints free at a bound, the linear axes of a linkage point, the generic IK's Newton step) | σ ≤ 1e-12 mm, absolute: below it a step moves the tip by less than the rounding of its coordinates |
/// | [`rank::FIT`] | a least-squares fit of measured data (B-spline design matrix; the normal matrix of a diagnosis, scaled to unit diagonal, whose eigenvalues are squared singular values) | σ (or λ) ≤ 1e-10 · σ_max (λ_max): noise in the data makes smaller directions meaningless |
/// | [`rank::DEPENDENT_AXES`] | the directions of a machine's linear axes | σ_min ≤ 1e-9 · max(σ_max, 1): the axes do not span the space |
/// | [`rank::DAMPED_FLOOR`] | a Marquardt-damped system (the generic IK's Levenberg–Marquardt step: full rank by its damping) | σ ≤ 1e-15, absolute: a floor against exact zeros only |
/// | [`rank::CONDITION_LIMIT`] | the stack QR and Gram paths of the Newton step | condition estimate above 1e8: the SVD path decides instead |
///
/// Where a solve is by [`MinNorm`] (the polish step of the refinement, the
/// B-spline fit, the generic IK's step), σ stands for the norm of the
/// largest column left at each step of its pivoted QR: the same cut for
/// the matrices these sites see, which have a clear gap between rounding
/// noise and the directions they keep.
///
/// The tolerances differ by role, not by accident: a Jacobian's
/// singular values are exact up to rounding, a fit's only up to the noise
/// of the data. Each has a test at its site.
pub mod rank {
    /// Relative cut-off per dimension for kinematic Jacobians.
    pub const JACOBIAN: f64 = 1e-12;
    /// Absolute cut-off (mm) for tip systems in mm per mm or rad.
    pub const TIP_SYSTEM_MM: f64 = 1e-12;
    /// Relative cut-off for fits of measured data.
    pub const FIT: f64 = 1e-10;
    /// Absolute floor for Marquardt-damped systems.
    pub const DAMPED_FLOOR: f64 = 1e-15;
    /// Relative test of dependent linear axes.
    pub const DEPENDENT_AXES: f64 = 1e-9;
    /// Condition estimate above which a stack factorisation hands over to
    /// the SVD.
    pub const CONDITION_LIMIT: f64 = 1e8;

    /// The cut-off for a Jacobian of `rows × cols` whose largest singular
    /// value is `smax` ([`JACOBIAN`]), never below the smallest positive
    /// number.
    pub fn jacobian_cutoff(smax: f64, rows: usize, cols: usize) -> f64 {
        (smax * JACOBIAN * rows.max(cols) as f64).max(f64::MIN_POSITIVE)
    }

    /// The cut-off for a fit whose largest singular value (or eigenvalue of
    /// its scaled normal matrix) is `largest` ([`FIT`]).
    pub fn fit_cutoff(largest: f64) -> f64 {
        FIT * largest
    }
}

/// Largest number of rows.
pub const ROWS: usize = 7;
/// Largest number of columns.
pub const COLS: usize = 6;

/// A column of at most [`ROWS`] entries.
pub type Col = [f64; ROWS];

/// Householder QR `A = Q R` of a tall `m × k` matrix (`k ≤ m`).
#[derive(Debug, Clone)]
pub struct Qr {
    m: usize,
    k: usize,
    /// Householder vectors (entries `j..m` of `v[j]`).
    v: [Col; COLS],
    beta: [f64; COLS],
    /// Upper triangle, `r[i][c]` for `i ≤ c`.
    r: [[f64; COLS]; COLS],
}

impl Qr {
    /// An empty factorisation (to be filled by [`Qr::factor`]).
    pub const EMPTY: Qr = Qr {
        m: 0,
        k: 0,
        v: [[0.0; ROWS]; COLS],
        beta: [0.0; COLS],
        r: [[0.0; COLS]; COLS],
    };

    /// Factors the matrix whose columns are `a` (each with `m` valid rows).
    pub fn new(a: &[Col], m: usize) -> Qr {
        let mut qr = Qr::EMPTY;
        qr.factor(a, m);
        qr
    }

    /// [`Qr::new`] in place.
    pub fn factor(&mut self, a: &[Col], m: usize) {
        let k = a.len();
        assert!(k <= COLS && k <= m && m <= ROWS, "QR of a {m}×{k} matrix");
        let mut w = [[0.0; ROWS]; COLS];
        w[..k].copy_from_slice(a);
        self.m = m;
        self.k = k;
        for j in 0..k {
            self.beta[j] = 0.0;
            let norm = w[j][j..m].iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 0.0 {
                let alpha = if w[j][j] > 0.0 { -norm } else { norm };
                let mut v = [0.0; ROWS];
                v[j..m].copy_from_slice(&w[j][j..m]);
                v[j] -= alpha;
                let vv = v[j..m].iter().map(|x| x * x).sum::<f64>();
                if vv > 0.0 {
                    let beta = 2.0 / vv;
                    for col in w.iter_mut().take(k).skip(j) {
                        let s = beta * dot(&v[j..m], &col[j..m]);
                        for (x, vi) in col[j..m].iter_mut().zip(&v[j..m]) {
                            *x -= s * vi;
                        }
                    }
                    self.v[j] = v;
                    self.beta[j] = beta;
                }
                // Exactly the reflected value; the entries below are zero.
                w[j][j] = alpha;
            }
            for c in j..k {
                self.r[j][c] = w[c][j];
            }
        }
    }

    fn reflect(&self, j: usize, x: &mut Col) {
        let (m, beta) = (self.m, self.beta[j]);
        if beta == 0.0 {
            return;
        }
        let v = &self.v[j];
        let s = beta * dot(&v[j..m], &x[j..m]);
        for (xi, vi) in x[j..m].iter_mut().zip(&v[j..m]) {
            *xi -= s * vi;
        }
    }

    /// `Qᵀ x`.
    pub fn qt(&self, x: &mut Col) {
        for j in 0..self.k {
            self.reflect(j, x);
        }
    }

    /// `Q x`.
    pub fn q(&self, x: &mut Col) {
        for j in (0..self.k).rev() {
            self.reflect(j, x);
        }
    }

    /// Condition number estimate `‖R‖_F ‖R⁻¹‖_F` (∞ when R is singular).
    pub fn condition(&self) -> f64 {
        let k = self.k;
        let mut norm_r = 0.0;
        let mut norm_inv = 0.0;
        for c in 0..k {
            // Column c of R⁻¹: solve R x = e_c.
            let mut e = [0.0; COLS];
            e[c] = 1.0;
            let x = self.solve_r(&e);
            for i in 0..k {
                norm_inv += x[i] * x[i];
                if i <= c {
                    norm_r += self.r[i][c] * self.r[i][c];
                }
            }
        }
        let cond = (norm_r * norm_inv).sqrt();
        if cond.is_finite() {
            cond
        } else {
            f64::INFINITY
        }
    }

    /// Solves `R x = b` (back substitution).
    pub fn solve_r(&self, b: &[f64; COLS]) -> [f64; COLS] {
        let mut x = [0.0; COLS];
        for i in (0..self.k).rev() {
            let mut s = b[i];
            for c in i + 1..self.k {
                s -= self.r[i][c] * x[c];
            }
            x[i] = s / self.r[i][i];
        }
        x
    }

    /// Solves `Rᵀ y = b` (forward substitution).
    pub fn solve_rt(&self, b: &[f64; COLS]) -> [f64; COLS] {
        let mut y = [0.0; COLS];
        for i in 0..self.k {
            let mut s = b[i];
            for c in 0..i {
                s -= self.r[c][i] * y[c];
            }
            y[i] = s / self.r[i][i];
        }
        y
    }

    /// Least squares `min |A x − b|` (A of full column rank).
    pub fn least_squares(&self, b: &Col) -> [f64; COLS] {
        let mut c = *b;
        self.qt(&mut c);
        let mut top = [0.0; COLS];
        top[..self.k].copy_from_slice(&c[..self.k]);
        self.solve_r(&top)
    }

    /// Minimum-norm solution of the wide system `Aᵀ x = b` (A of full column
    /// rank): `x = Q [R⁻ᵀ b; 0]`.
    pub fn min_norm_transposed(&self, b: &[f64; COLS]) -> Col {
        let y = self.solve_rt(b);
        let mut x = [0.0; ROWS];
        x[..self.k].copy_from_slice(&y[..self.k]);
        self.q(&mut x);
        x
    }

    /// Column `i` of Q (`i < m`): for `i ≥ k` an orthonormal basis of the
    /// null space of `Aᵀ`.
    pub fn q_column(&self, i: usize) -> Col {
        let mut e = [0.0; ROWS];
        e[i] = 1.0;
        self.q(&mut e);
        e
    }
}

/// How [`MinNorm`] decides the numerical rank: the pivoted QR stops when
/// the largest norm of a remaining column (the next diagonal entry of R, in
/// magnitude) is at or below the cut-off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RankCut {
    /// An absolute cut-off, in the units of the matrix entries (for a tip
    /// system, mm per mm or rad: [`rank::TIP_SYSTEM_MM`]).
    Absolute(f64),
    /// A cut-off relative to the largest column norm of the matrix (for a
    /// fit, [`rank::FIT`]).
    Relative(f64),
}

/// Minimum-norm least squares `x = A⁺ b` of a small dense matrix of any
/// shape and rank, by complete orthogonal decomposition (Golub and Van
/// Loan, section 5.4; LAPACK's `xGELSY`): a Householder QR with column
/// pivoting `A P = Q [R₁₁ R₁₂; 0 R₂₂]` stops at the rank `r` where the
/// largest remaining column is at the cut-off ([`RankCut`]), `R₂₂` is
/// dropped, and the minimum-norm solution of the wide `[R₁₁ R₁₂] z = (Qᵀ b)₁..ᵣ`
/// is taken on the QR of its transpose.
///
/// This replaces nalgebra's SVD where a wrong solution would be returned or
/// reported. nalgebra 0.35's `SVD` gives singular values accurate to
/// rounding, but where its bidiagonal form has a diagonal entry at
/// rounding level its factors often do not reproduce the matrix (`U Σ Vᵀ`
/// misses `A` by up to 0.8 relative, U and V still orthogonal), and
/// `solve` and `pseudo_inverse` miss by as much (dimforge/nalgebra issues
/// #1172 and #1313; not fixed upstream as of 0.35.0). That happens for
/// about 2 % of exactly rank-deficient matrices (rank 1 or 2 of 3 × n and
/// n × 3, as computed, with or without noise of 1e-16; the test
/// `min_norm_is_exact_where_nalgebra_svd_is_not`), and also for sparse
/// matrices of full rank (a clustered B-spline design, 12 × 9, condition
/// about 3e3: `lsq::tests::clustered_design_is_solved_exactly`). Dense
/// full-rank matrices and exact zero rows or columns were not affected in
/// the characterisation.
///
/// nalgebra's own `ColPivQR` is not used: it pivots on the largest single
/// entry of the remaining matrix, not on the largest column norm, which
/// does not reveal the rank reliably.
///
/// The rank decision is made on the pivoted diagonal of R instead of the
/// singular values: `σ_{r+1} ≤ √(n − r) · cut-off`, and for the matrices
/// of this crate (a clear gap between rounding noise and the kept
/// directions) the two agree.
#[derive(Debug, Clone)]
pub struct MinNorm {
    /// Householder vectors below the diagonal (their first entry is 1 and
    /// not stored), R on and above it, of `A P`.
    qr: DMatrix<f64>,
    /// Householder coefficients (`H = I − β v vᵀ`).
    beta: Vec<f64>,
    /// Column `j` of `A P` is column `perm[j]` of `A`.
    perm: Vec<usize>,
    rank: usize,
    /// QR of `[R₁₁ R₁₂]ᵀ` (n × rank) when the rank is below the number of
    /// columns.
    wide: Option<nalgebra::linalg::QR<f64, nalgebra::Dyn, nalgebra::Dyn>>,
}

impl MinNorm {
    /// Factors `a` (m × n, any shape), treating as zero what is left once
    /// the largest remaining column norm is at or below `cut`. `None` when
    /// `a` has a non-finite entry.
    pub fn new(a: &DMatrix<f64>, cut: RankCut) -> Option<MinNorm> {
        if a.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let (m, n) = a.shape();
        let mut qr = a.clone();
        let mut perm: Vec<usize> = (0..n).collect();
        let mut beta = Vec::with_capacity(m.min(n));
        let col_norm =
            |qr: &DMatrix<f64>, j: usize, from: usize| qr.view((from, j), (m - from, 1)).norm();
        let largest = (0..n).map(|j| col_norm(&qr, j, 0)).fold(0.0, f64::max);
        let cut = match cut {
            RankCut::Absolute(c) => c,
            RankCut::Relative(c) => c * largest,
        };
        let mut rank = 0;
        for j in 0..m.min(n) {
            // The remaining column of largest norm (norms recomputed: the
            // matrices are small, and downdated norms lose accuracy).
            let (p, norm) = (j..n)
                .map(|c| (c, col_norm(&qr, c, j)))
                .fold((j, -1.0), |best, c| if c.1 > best.1 { c } else { best });
            if norm <= cut || norm == 0.0 {
                break;
            }
            qr.swap_columns(j, p);
            perm.swap(j, p);
            // Householder reflection of column j onto ∓norm e_j.
            let alpha = if qr[(j, j)] > 0.0 { -norm } else { norm };
            let v0 = qr[(j, j)] - alpha;
            for i in j + 1..m {
                qr[(i, j)] /= v0;
            }
            let b = -v0 / alpha;
            qr[(j, j)] = alpha;
            for c in j + 1..n {
                let mut s = qr[(j, c)];
                for i in j + 1..m {
                    s += qr[(i, j)] * qr[(i, c)];
                }
                s *= b;
                qr[(j, c)] -= s;
                for i in j + 1..m {
                    let vi = qr[(i, j)];
                    qr[(i, c)] -= s * vi;
                }
            }
            beta.push(b);
            rank = j + 1;
        }
        let wide = (0 < rank && rank < n)
            .then(|| DMatrix::from_fn(n, rank, |c, i| if c >= i { qr[(i, c)] } else { 0.0 }).qr());
        Some(MinNorm {
            qr,
            beta,
            perm,
            rank,
            wide,
        })
    }

    /// The numerical rank.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Applies reflection `j` (`H_j = I − β_j v_j v_jᵀ`, its own inverse)
    /// to `x` in place.
    fn reflect(&self, j: usize, x: &mut DVector<f64>) {
        let m = self.qr.nrows();
        let mut s = x[j];
        for i in j + 1..m {
            s += self.qr[(i, j)] * x[i];
        }
        s *= self.beta[j];
        x[j] -= s;
        for i in j + 1..m {
            x[i] -= s * self.qr[(i, j)];
        }
    }

    /// Applies `Qᵀ = H_{r−1} ⋯ H_0` (the first `rank` reflections) to `x` in
    /// place.
    fn apply_qt(&self, x: &mut DVector<f64>) {
        for j in 0..self.beta.len() {
            self.reflect(j, x);
        }
    }

    /// Applies `Q = H_0 ⋯ H_{r−1}` to `x` in place.
    fn apply_q(&self, x: &mut DVector<f64>) {
        for j in (0..self.beta.len()).rev() {
            self.reflect(j, x);
        }
    }

    /// The minimum-norm least-squares solution `x = A⁺ b` (`b` of m rows).
    pub fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let n = self.qr.ncols();
        let r = self.rank;
        if r == 0 {
            return DVector::zeros(n);
        }
        let mut c = b.clone();
        self.apply_qt(&mut c);
        let c = c.rows(0, r).into_owned();
        let z = match &self.wide {
            // Full column rank: R₁₁ z = c.
            None => self
                .qr
                .view((0, 0), (r, r))
                .upper_triangle()
                .solve_upper_triangular(&c)
                .expect("the pivoted diagonal is above the cut-off"),
            // [R₁₁ R₁₂] = R₂ᵀ Q₂ᵀ: z = Q₂ R₂⁻ᵀ c.
            Some(w) => {
                let y = w
                    .r()
                    .tr_solve_upper_triangular(&c)
                    .expect("the pivoted diagonal is above the cut-off");
                w.q() * y
            }
        };
        // z has n entries either way (r = n without the second QR).
        let mut x = DVector::zeros(n);
        for (j, &p) in self.perm.iter().enumerate() {
            x[p] = z[j];
        }
        x
    }

    /// An orthonormal basis of the range of A (m × rank): the first `rank`
    /// columns of Q. `A A⁺ = Q₁ Q₁ᵀ`, whose diagonal is the leverage of each
    /// row in a least-squares fit.
    pub fn range_basis(&self) -> DMatrix<f64> {
        let m = self.qr.nrows();
        let mut q = DMatrix::zeros(m, self.rank);
        for j in 0..self.rank {
            let mut e = DVector::zeros(m);
            e[j] = 1.0;
            self.apply_q(&mut e);
            q.set_column(j, &e);
        }
        q
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{Lcg, left_inverse, right_inverse};

    fn matrix(m: usize, k: usize, seed: u64) -> Vec<Col> {
        let mut rng = Lcg(seed);
        (0..k)
            .map(|_| {
                let mut c = [0.0; ROWS];
                for x in c.iter_mut().take(m) {
                    *x = rng.signed();
                }
                c
            })
            .collect()
    }

    #[test]
    fn least_squares_and_min_norm_match_svd() {
        for (m, k) in [(3, 1), (4, 3), (5, 3), (6, 4), (7, 3), (6, 6), (3, 3)] {
            let a = matrix(m, k, (m * 10 + k) as u64);
            let dm = DMatrix::from_fn(m, k, |r, c| a[c][r]);
            let qr = Qr::new(&a, m);
            assert!(qr.condition() < 1e6);
            let b = matrix(m, 1, 99)[0];
            let x = qr.least_squares(&b);
            let bv = nalgebra::DVector::from_fn(m, |r, _| b[r]);
            let xs = dm.clone().svd(true, true).solve(&bv, 0.0).unwrap();
            for c in 0..k {
                assert!((x[c] - xs[c]).abs() < 1e-12, "{m}×{k}");
            }
            // Minimum norm of Aᵀ x = c.
            let cvec = [0.3, -0.2, 0.7, 0.1, -0.5, 0.25];
            let x = qr.min_norm_transposed(&cvec);
            let at = dm.transpose();
            let cv = nalgebra::DVector::from_fn(k, |r, _| cvec[r]);
            let xs = at.pseudo_inverse(1e-14).unwrap() * cv;
            for r in 0..m {
                assert!((x[r] - xs[r]).abs() < 1e-12, "{m}×{k}");
            }
            // The trailing columns of Q span the null space of Aᵀ.
            for i in k..m {
                let z = qr.q_column(i);
                for col in &a {
                    assert!(dot(&col[..m], &z[..m]).abs() < 1e-14);
                }
            }
        }
    }

    /// Entries uniform in [-1, 1), deterministic.
    fn uniform(rows: usize, cols: usize, rng: &mut Lcg) -> DMatrix<f64> {
        DMatrix::from_fn(rows, cols, |_, _| rng.signed())
    }

    /// The rank-deficient products `A = 50 B C` (B m × r, C r × n, entries
    /// in mm-like sizes) of the characterisation, with and without noise of
    /// 1e-16 relative, skipping those whose kept part is ill-conditioned
    /// (σ_r < 1e-3 σ_1, where the reference below loses accuracy); each with
    /// its pseudo-inverse evaluated independently from the factors:
    /// `A⁺ = C⁺ B⁺ / 50 = Cᵀ (C Cᵀ)⁻¹ (Bᵀ B)⁻¹ Bᵀ / 50` (LU of the r × r
    /// Gram matrices).
    fn rank_deficient_products() -> Vec<(DMatrix<f64>, DMatrix<f64>)> {
        let mut state = Lcg(17);
        let mut out = Vec::new();
        let shapes = [(3, 2), (3, 3), (3, 4), (3, 6), (4, 3), (6, 3), (6, 6)];
        for (m, n) in shapes {
            for r in 1..m.min(n) {
                for noise in [0.0, 1e-16] {
                    for _ in 0..200 {
                        let b = uniform(m, r, &mut state);
                        let c = uniform(r, n, &mut state);
                        let a = (&b * &c + uniform(m, n, &mut state) * noise) * 50.0;
                        let sv = a.clone().svd(false, false).singular_values;
                        let mut sv: Vec<f64> = sv.iter().copied().collect();
                        sv.sort_by(|x, y| y.total_cmp(x));
                        if sv[r - 1] < 1e-3 * sv[0] {
                            continue;
                        }
                        out.push((a, right_inverse(&c) * left_inverse(&b) / 50.0));
                    }
                }
            }
        }
        out
    }

    /// The characterisation of nalgebra 0.35's SVD on exactly
    /// rank-deficient matrices (3 × n and n × 3 of ranks 1 and 2, 6 × 6 of
    /// ranks 1 to 5, with and without noise): in about 2 % of them its
    /// `solve` misses the independently evaluated `A⁺ b` by more than 1e-8
    /// relative (the worst by more than the size of `A⁺ b`), while
    /// [`MinNorm`] meets it to 1e-9 everywhere. The nalgebra count is
    /// printed, not asserted: should it reach zero with a new nalgebra, the
    /// workaround could go.
    #[test]
    fn min_norm_is_exact_where_nalgebra_svd_is_not() {
        let mut state = Lcg(5);
        let (mut svd_misses, mut worst_svd, mut worst) = (0, 0.0f64, 0.0f64);
        let cases = rank_deficient_products();
        for (a, pinv) in &cases {
            let (m, n) = a.shape();
            let b = uniform(m, 1, &mut state).column(0).into_owned();
            let reference = pinv * &b;
            let relative = |x: &DVector<f64>| (x - &reference).norm() / reference.norm();
            let cut = rank::jacobian_cutoff(a.norm(), m, n);
            let min_norm = MinNorm::new(a, RankCut::Absolute(cut)).unwrap();
            assert!(relative(&min_norm.solve(&b)) < 1e-9, "{a}");
            worst = worst.max(relative(&min_norm.solve(&b)));
            let svd = a.clone().svd(true, true).solve(&b, cut).unwrap();
            worst_svd = worst_svd.max(relative(&svd));
            if relative(&svd) > 1e-8 {
                svd_misses += 1;
            }
            // A A⁺ is the orthogonal projector Q₁ Q₁ᵀ onto the range.
            let q = min_norm.range_basis();
            let projector = a * pinv;
            assert!((&q * q.transpose() - projector).norm() < 1e-9);
        }
        eprintln!(
            "{} rank-deficient matrices: nalgebra's SVD solve misses A⁺ b by more than 1e-8 \
             relative in {svd_misses} (worst {worst_svd:.1e}), MinNorm by at most {worst:.1e}",
            cases.len()
        );
    }

    #[test]
    fn min_norm_of_full_rank_and_zero_matrices() {
        let mut state = Lcg(3);
        for (m, n) in [(3, 3), (5, 3), (3, 5), (7, 6), (1, 4), (4, 1)] {
            let a = uniform(m, n, &mut state) * 20.0;
            let b = uniform(m, 1, &mut state).column(0).into_owned();
            let f = MinNorm::new(&a, RankCut::Relative(rank::FIT)).unwrap();
            assert_eq!(f.rank(), m.min(n));
            let x = f.solve(&b);
            // Least squares: the residual is orthogonal to the columns;
            // minimum norm: x lies in the row space (A⁺ A x = x).
            let residual = &a * &x - &b;
            assert!((a.transpose() * residual).norm() < 1e-12 * a.norm() * b.norm());
            let ata = a.transpose() * &a;
            if m >= n {
                let exact = ata.lu().solve(&(a.transpose() * &b)).unwrap();
                assert!((&x - exact).norm() < 1e-12 * x.norm(), "{m}×{n}");
            } else {
                let y = (&a * a.transpose()).lu().solve(&b).unwrap();
                assert!(
                    (&x - a.transpose() * y).norm() < 1e-12 * x.norm(),
                    "{m}×{n}"
                );
            }
        }
        let zero = DMatrix::zeros(3, 4);
        let f = MinNorm::new(&zero, RankCut::Absolute(rank::TIP_SYSTEM_MM)).unwrap();
        assert_eq!(f.rank(), 0);
        assert_eq!(f.solve(&DVector::from_element(3, 1.0)), DVector::zeros(4));
        assert_eq!(f.range_basis().shape(), (3, 0));
        let mut nan = DMatrix::zeros(2, 2);
        nan[(0, 1)] = f64::NAN;
        assert!(MinNorm::new(&nan, RankCut::Absolute(1e-12)).is_none());
    }

    #[test]
    fn singular_matrices_report_infinite_condition() {
        let mut a = matrix(4, 3, 5);
        a[2] = a[0];
        assert!(Qr::new(&a, 4).condition() > 1e14);
        let z = [[0.0; ROWS]; 2];
        assert!(Qr::new(&z, 3).condition().is_infinite());
    }
}
