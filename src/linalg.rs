//! Small dense linear algebra on the stack for the per-pose hot paths
//! (compensation steps, the linear axes of the IK): Householder QR of a tall
//! m×k matrix with m ≤ 7 rows and k ≤ 6 columns, least squares and
//! minimum-norm solutions, and a condition estimate so that callers can fall
//! back to an SVD when a problem is ill-conditioned; and [`rank`], the one
//! rank policy every module follows.

// Dense matrix code reads best with explicit row and column indices.
#![allow(clippy::needless_range_loop)]

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

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn matrix(m: usize, k: usize, seed: u64) -> Vec<Col> {
        let mut s = seed;
        (0..k)
            .map(|_| {
                let mut c = [0.0; ROWS];
                for x in c.iter_mut().take(m) {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    *x = ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0;
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

    #[test]
    fn singular_matrices_report_infinite_condition() {
        let mut a = matrix(4, 3, 5);
        a[2] = a[0];
        assert!(Qr::new(&a, 4).condition() > 1e14);
        let z = [[0.0; ROWS]; 2];
        assert!(Qr::new(&z, 3).condition().is_infinite());
    }
}
