//! Least-squares cubic B-splines with cross-validated knot count.
//!
//! Seed 000 (Section 6.1) filters the random part of measured geometric
//! errors with a third-order (cubic) B-spline fitted by least squares. This
//! module does exactly that, per error column:
//!
//! * **Basis**: clamped cubic B-splines (Cox–de Boor recursion) on the
//!   measured travel `[a, b]` with `m` *uniform* interior knots
//!   `a + (b − a)·j/(m + 1)`, `j = 1…m`; `m + 4` coefficients.
//! * **Least squares**: repeated positions (runs, directions) are first
//!   aggregated into their mean with weight = number of samples. Minimising
//!   `Σ_p n_p (ȳ_p − s(x_p))²` gives exactly the same spline as minimising
//!   over the raw samples (the within-position scatter is a constant). The
//!   weighted system is solved by SVD (`nalgebra`), which also copes with a
//!   rank-deficient basis (minimum-norm solution) instead of failing.
//! * **Knot count**: by leave-one-position-out cross-validation (each
//!   *interior* measured position is left out in turn, with all its samples;
//!   the knot vector stays that of the full travel so that a left-out
//!   position is interpolated, never extrapolated). The score is the RMS
//!   prediction error of the left-out raw samples. It is computed exactly
//!   from one fit per knot count with the leave-one-out identity of linear
//!   least squares (prediction error = residual / (1 − leverage)), so dense
//!   scans with thousands of positions cost no more than a few fits. The smallest count whose
//!   score is within a tolerance (default 1 %) of the best is chosen. A fixed
//!   count can be given instead.
//! * **Few positions**: with fewer than 4 distinct positions the degree drops
//!   to `positions − 1` (a line through 2 positions, a constant for one).
//! * **Outside the measured travel**: [`Extrapolation::Hold`] (default) keeps
//!   the end value with derivative 0; [`Extrapolation::Linear`] continues
//!   along the end tangent. The polynomial pieces are never extended.
//!
//! Why not the `splinefit` crate (a pure-Rust FITPACK port)? Its public API
//! offers user-placed knots only as `cardinal_spline(dt)`, which snaps the
//! interior knots to integer multiples of `dt` rather than spreading a given
//! count uniformly over the travel; it exposes no derivative evaluation
//! (Newton compensation needs exact derivatives); it requires strictly
//! increasing abscissae; and it asserts (panics) on some bad inputs. The
//! least-squares problem here is tiny (tens of positions, ≤ 24 coefficients),
//! so a compact implementation on `nalgebra` is simpler and fully controlled.

use nalgebra::{DMatrix, DVector};

/// Behaviour outside the measured travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Extrapolation {
    /// Keep the end value; derivative 0 (default).
    #[default]
    Hold,
    /// Continue linearly with the end slope.
    Linear,
}

impl std::fmt::Display for Extrapolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Extrapolation::Hold => "hold end value",
            Extrapolation::Linear => "linear with end slope",
        })
    }
}

/// A fitting or validation failure (without a file location; callers add one).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct SplineError(pub String);

/// A clamped B-spline of degree 0 to 3 on `[lo, hi]`, with a policy outside.
#[derive(Debug, Clone, PartialEq)]
pub struct BSpline {
    degree: usize,
    knots: Vec<f64>,
    coef: Vec<f64>,
    extrapolation: Extrapolation,
    lo: f64,
    hi: f64,
    end_lo: (f64, f64),
    end_hi: (f64, f64),
    /// The same spline as one polynomial per knot span (spans `degree …
    /// coef.len() − 1`), for evaluation.
    pieces: Vec<Piece>,
}

/// One knot span of a spline as a cubic in the span's normalised position
/// `u = (x − t_i) / (t_{i+1} − t_i) ∈ [0, 1]`: `a₀ + a₁u + a₂u² + a₃u³`.
///
/// Built from the spline's values and slopes at both ends of the span
/// (cubic Hermite form), which determine a polynomial of degree ≤ 3 exactly;
/// evaluating it by Horner's rule costs a few multiplications instead of the
/// Cox–de Boor recursion, and agrees with it to rounding.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    start: f64,
    inv_width: f64,
    a: [f64; 4],
}

impl Piece {
    /// Value and derivative at `x` (in the span or at its ends).
    #[inline]
    fn eval(&self, x: f64) -> (f64, f64) {
        let u = (x - self.start) * self.inv_width;
        let [a0, a1, a2, a3] = self.a;
        let v = ((a3 * u + a2) * u + a1) * u + a0;
        let d = ((3.0 * a3 * u + 2.0 * a2) * u + a1) * self.inv_width;
        (v, d)
    }
}

/// Maximum supported degree.
pub const MAX_DEGREE: usize = 3;

impl BSpline {
    /// Builds a spline from its full (clamped) knot vector and coefficients.
    ///
    /// Requirements: `degree ≤ 3`; `knots.len() == coef.len() + degree + 1`;
    /// the first and last `degree + 1` knots equal (clamped ends), knots
    /// non-decreasing, all values finite, `lo < hi` unless degree 0 with one
    /// coefficient (a constant).
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        coef: Vec<f64>,
        extrapolation: Extrapolation,
    ) -> Result<Self, SplineError> {
        let err = |m: &str| Err(SplineError(m.to_string()));
        if degree > MAX_DEGREE {
            return Err(SplineError(format!(
                "degree {degree} not supported (at most {MAX_DEGREE})"
            )));
        }
        if coef.is_empty() {
            return err("no coefficients");
        }
        if knots.len() != coef.len() + degree + 1 {
            return Err(SplineError(format!(
                "{} knots for {} coefficients of degree {degree}: expected {}",
                knots.len(),
                coef.len(),
                coef.len() + degree + 1
            )));
        }
        if knots.iter().chain(&coef).any(|v| !v.is_finite()) {
            return err("knots and coefficients must be finite numbers");
        }
        if knots.windows(2).any(|w| w[1] < w[0]) {
            return err("knots must be non-decreasing");
        }
        let lo = knots[degree];
        let hi = knots[knots.len() - 1 - degree];
        if knots[..=degree].iter().any(|&t| t != lo)
            || knots[knots.len() - 1 - degree..].iter().any(|&t| t != hi)
        {
            return err("the first and last degree+1 knots must be equal (clamped spline)");
        }
        if hi <= lo && !(degree == 0 && coef.len() == 1) {
            return err("the spline's range is empty (first knot ≥ last knot)");
        }
        // Multiplicity of interior knots must not exceed the degree (else the
        // basis breaks into discontinuous pieces); repeated knots could give
        // zero-length spans at which the recursion divides by zero.
        let interior = &knots[degree + 1..knots.len() - 1 - degree];
        if interior.iter().any(|&t| t <= lo || t >= hi) {
            return err("interior knots must lie strictly inside the range");
        }
        if interior.windows(2).any(|w| w[1] <= w[0]) {
            return err("interior knots must be strictly increasing");
        }
        let n = coef.len();
        let pieces = (degree..n)
            .map(|span| {
                let (t0, t1) = (knots[span], knots[span + 1]);
                let ends = |x: f64| {
                    let (vals, ders) = basis_in_span(&knots, degree, span, x, true);
                    combine(&coef, degree, span, &vals, &ders)
                };
                let ((v0, d0), (v1, d1)) = (ends(t0), ends(t1));
                let h = t1 - t0;
                Piece {
                    start: t0,
                    inv_width: 1.0 / h,
                    a: [
                        v0,
                        d0 * h,
                        3.0 * (v1 - v0) - (2.0 * d0 + d1) * h,
                        2.0 * (v0 - v1) + (d0 + d1) * h,
                    ],
                }
            })
            .collect();
        let mut s = BSpline {
            degree,
            knots,
            coef,
            extrapolation,
            lo,
            hi,
            end_lo: (0.0, 0.0),
            end_hi: (0.0, 0.0),
            pieces,
        };
        s.end_lo = s.inside(lo);
        s.end_hi = s.inside(hi);
        Ok(s)
    }

    /// A constant spline with value `v` at position `at` (degree 0).
    pub fn constant(v: f64, at: f64, extrapolation: Extrapolation) -> Self {
        BSpline {
            degree: 0,
            knots: vec![at, at],
            coef: vec![v],
            extrapolation,
            lo: at,
            hi: at,
            end_lo: (v, 0.0),
            end_hi: (v, 0.0),
            pieces: Vec::new(),
        }
    }

    /// Polynomial degree (3 for cubic).
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Full clamped knot vector.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// The interior knots only.
    pub fn interior_knots(&self) -> &[f64] {
        if self.knots.len() < 2 * (self.degree + 1) {
            return &[];
        }
        &self.knots[self.degree + 1..self.knots.len() - 1 - self.degree]
    }

    /// B-spline coefficients.
    pub fn coefficients(&self) -> &[f64] {
        &self.coef
    }

    /// The fitted range `[lo, hi]` (the measured travel).
    pub fn range(&self) -> (f64, f64) {
        (self.lo, self.hi)
    }

    /// Policy outside the range.
    pub fn extrapolation(&self) -> Extrapolation {
        self.extrapolation
    }

    /// Changes the policy outside the range.
    pub fn set_extrapolation(&mut self, e: Extrapolation) {
        self.extrapolation = e;
    }

    /// Value at `x`.
    pub fn value(&self, x: f64) -> f64 {
        self.value_and_derivative(x).0
    }

    /// First derivative at `x` (per unit of `x`).
    pub fn derivative(&self, x: f64) -> f64 {
        self.value_and_derivative(x).1
    }

    /// Value and first derivative at `x`, with the extrapolation policy
    /// applied outside `[lo, hi]`.
    pub fn value_and_derivative(&self, x: f64) -> (f64, f64) {
        if self.degree == 0 && self.coef.len() == 1 {
            return (self.coef[0], 0.0);
        }
        let (end, at) = if x < self.lo {
            (self.end_lo, self.lo)
        } else if x > self.hi {
            (self.end_hi, self.hi)
        } else if x.is_nan() {
            return (f64::NAN, f64::NAN);
        } else {
            return self.inside(x);
        };
        match self.extrapolation {
            Extrapolation::Hold => (end.0, 0.0),
            Extrapolation::Linear => (end.0 + end.1 * (x - at), end.1),
        }
    }

    /// Value and derivative for `x` within `[lo, hi]`: the polynomial of
    /// the knot span that holds `x`.
    #[inline]
    fn inside(&self, x: f64) -> (f64, f64) {
        if self.pieces.len() == 1 {
            return self.pieces[0].eval(x);
        }
        let span = find_span(&self.knots, self.degree, self.coef.len(), x);
        self.pieces[span - self.degree].eval(x)
    }
}

/// `Σ c_{span−k+r} · (vals[r], ders[r])`: value and derivative of the spline
/// with coefficients `coef` from the basis functions of knot span `span`.
fn combine(coef: &[f64], k: usize, span: usize, vals: &[f64; 4], ders: &[f64; 4]) -> (f64, f64) {
    let mut v = 0.0;
    let mut d = 0.0;
    for r in 0..=k {
        let c = coef[span - k + r];
        v += c * vals[r];
        d += c * ders[r];
    }
    (v, d)
}

/// The knot span of `x` for a spline of degree `k` with `n` coefficients:
/// the largest `i` in `k..n` with `t_i ≤ x` (`x` clamped to `[t_k, t_n]`).
///
/// Guessed from the position of `x` in the range as if the knots were
/// uniform (exact for the fitted splines), then corrected by stepping, so
/// any knot vector works.
#[inline]
fn find_span(knots: &[f64], k: usize, n: usize, x: f64) -> usize {
    let x = x.clamp(knots[k], knots[n]);
    let (lo, hi) = (knots[k], knots[n]);
    let guess = if hi > lo {
        k + ((x - lo) / (hi - lo) * (n - k) as f64) as usize
    } else {
        k
    };
    let mut span = guess.clamp(k, n - 1);
    while span > k && knots[span] > x {
        span -= 1;
    }
    while span < n - 1 && knots[span + 1] <= x {
        span += 1;
    }
    span
}

/// The non-zero basis functions of degree `k` at `x` and their derivatives.
///
/// Returns the knot span `i` (`t_i ≤ x < t_{i+1}`, `k ≤ i < n`, see
/// [`find_span`]) and the values of `N_{i−k,k} … N_{i,k}` and their first
/// derivatives. `x` must lie within `[t_k, t_n]`; it is clamped to that
/// range otherwise. Without `derivative` the derivatives are left at 0.
fn basis_at(
    knots: &[f64],
    k: usize,
    n: usize,
    x: f64,
    derivative: bool,
) -> (usize, [f64; 4], [f64; 4]) {
    let x = x.clamp(knots[k], knots[n]);
    let span = find_span(knots, k, n, x);
    let (vals, ders) = basis_in_span(knots, k, span, x, derivative);
    (span, vals, ders)
}

/// The basis functions of knot span `span` (and, with `derivative`, their
/// first derivatives) evaluated at `x`, which may also be either end of the
/// span: the polynomial pieces of that span, whatever span `x` falls in.
fn basis_in_span(
    knots: &[f64],
    k: usize,
    span: usize,
    x: f64,
    derivative: bool,
) -> ([f64; 4], [f64; 4]) {
    let mut vals = [0.0; 4];
    let mut low = [0.0; 4]; // degree k − 1 values
    let mut left = [0.0; 4];
    let mut right = [0.0; 4];
    vals[0] = 1.0;
    if k == 0 {
        return (vals, [0.0; 4]);
    }
    for j in 1..=k {
        if j == k {
            low = vals;
        }
        left[j] = x - knots[span + 1 - j];
        right[j] = knots[span + j] - x;
        let mut saved = 0.0;
        for r in 0..j {
            let denom = right[r + 1] + left[j - r];
            let temp = if denom > 0.0 { vals[r] / denom } else { 0.0 };
            vals[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        vals[j] = saved;
    }
    if !derivative {
        return (vals, [0.0; 4]);
    }
    // N'_{i,k} = k (N_{i,k−1}/(t_{i+k} − t_i) − N_{i+1,k−1}/(t_{i+k+1} − t_{i+1})),
    // with i = span − k + r; low[s] holds N_{span−k+1+s, k−1}.
    let mut ders = [0.0; 4];
    let kf = k as f64;
    for (r, d) in ders.iter_mut().enumerate().take(k + 1) {
        let i = span - k + r;
        let mut v = 0.0;
        if r >= 1 {
            let den = knots[i + k] - knots[i];
            if den > 0.0 {
                v += low[r - 1] / den;
            }
        }
        if r < k {
            let den = knots[i + k + 1] - knots[i + 1];
            if den > 0.0 {
                v -= low[r] / den;
            }
        }
        *d = kf * v;
    }
    (vals, ders)
}

/// Clamped knot vector of degree `k` on `[a, b]` with `m` uniform interior knots.
pub fn uniform_knots(a: f64, b: f64, k: usize, m: usize) -> Vec<f64> {
    let mut t = Vec::with_capacity(m + 2 * (k + 1));
    t.extend(std::iter::repeat_n(a, k + 1));
    for j in 1..=m {
        t.push(a + (b - a) * j as f64 / (m + 1) as f64);
    }
    t.extend(std::iter::repeat_n(b, k + 1));
    t
}

/// Samples grouped by position: the sufficient statistics of least squares.
#[derive(Debug, Clone, PartialEq)]
pub struct Grouped {
    /// Distinct positions, increasing.
    pub x: Vec<f64>,
    /// Mean value at each position.
    pub mean: Vec<f64>,
    /// Number of samples at each position.
    pub count: Vec<usize>,
    /// Sum of squared deviations from the mean at each position.
    pub ss_within: Vec<f64>,
}

impl Grouped {
    /// Groups samples `(x_i, y_i)`. Positions closer than `1e-9 · max(1, range)`
    /// are treated as the same position. Non-finite samples are an error.
    pub fn new(x: &[f64], y: &[f64]) -> Result<Self, SplineError> {
        if x.len() != y.len() {
            return Err(SplineError(format!(
                "{} positions but {} values",
                x.len(),
                y.len()
            )));
        }
        if x.is_empty() {
            return Err(SplineError("no samples".into()));
        }
        if x.iter().chain(y).any(|v| !v.is_finite()) {
            return Err(SplineError("samples must be finite numbers".into()));
        }
        let mut idx: Vec<usize> = (0..x.len()).collect();
        idx.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
        let range = x[idx[idx.len() - 1]] - x[idx[0]];
        let tol = 1e-9 * range.abs().max(1.0);
        let mut g = Grouped {
            x: Vec::new(),
            mean: Vec::new(),
            count: Vec::new(),
            ss_within: Vec::new(),
        };
        let mut i = 0;
        while i < idx.len() {
            let mut j = i + 1;
            while j < idx.len() && x[idx[j]] - x[idx[i]] <= tol {
                j += 1;
            }
            let members = &idx[i..j];
            let n = members.len() as f64;
            let mx = members.iter().map(|&m| x[m]).sum::<f64>() / n;
            let my = members.iter().map(|&m| y[m]).sum::<f64>() / n;
            let ss = members.iter().map(|&m| (y[m] - my).powi(2)).sum::<f64>();
            g.x.push(mx);
            g.mean.push(my);
            g.count.push(members.len());
            g.ss_within.push(ss);
            i = j;
        }
        Ok(g)
    }

    /// Number of distinct positions.
    pub fn positions(&self) -> usize {
        self.x.len()
    }

    /// Total number of samples.
    pub fn samples(&self) -> usize {
        self.count.iter().sum()
    }
}

/// Weighted least-squares fit on the given knots using the grouped positions
/// listed in `rows`: the coefficients, and the diagonal of the hat matrix
/// (leverage) of each of those rows.
fn solve_rows(
    g: &Grouped,
    knots: &[f64],
    k: usize,
    rows: &[usize],
) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = knots.len() - k - 1;
    if rows.is_empty() {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(rows.len(), n);
    let mut b = DVector::<f64>::zeros(rows.len());
    for (r, &i) in rows.iter().enumerate() {
        let w = (g.count[i] as f64).sqrt();
        let (span, vals, _) = basis_at(knots, k, n, g.x[i], false);
        for s in 0..=k {
            a[(r, span - k + s)] = w * vals[s];
        }
        b[r] = w * g.mean[i];
    }
    // Scale-aware rank tolerance: singular values below 1e-10 of the largest
    // are treated as zero (minimum-norm solution for a deficient basis).
    let svd = a.svd(true, true);
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let eps = 1e-10 * smax.max(f64::MIN_POSITIVE);
    let x = svd.solve(&b, eps).ok()?;
    let c: Vec<f64> = x.iter().copied().collect();
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    // H = U_r U_rᵀ over the retained singular vectors.
    let u = svd.u.as_ref()?;
    let hat = (0..rows.len())
        .map(|r| {
            (0..svd.singular_values.len())
                .filter(|&j| svd.singular_values[j] > eps)
                .map(|j| u[(r, j)] * u[(r, j)])
                .sum()
        })
        .collect();
    Some((c, hat))
}

/// Fitted values and leverages at every grouped position, from the SVD of
/// the weighted design matrix ([`solve_rows`]).
fn svd_fit(g: &Grouped, knots: &[f64], k: usize, rows: &[usize]) -> Option<(Vec<f64>, Vec<f64>)> {
    let (c, hat) = solve_rows(g, knots, k, rows)?;
    let s = BSpline::new(k, knots.to_vec(), c, Extrapolation::Hold).ok()?;
    Some((g.x.iter().map(|&x| s.value(x)).collect(), hat))
}

/// Smallest ratio of the Cholesky factor's diagonal (square root of the
/// normal matrix's conditioning) accepted for the normal equations; below
/// it the SVD decides the rank.
const NORMAL_PIVOT_RATIO: f64 = 1e-6;

/// The normal equations of one knot vector over one set of positions:
/// everything of a least-squares fit that does not depend on the values,
/// so that the columns of one table (same positions) share it.
struct Design {
    /// Per position: the first non-zero basis function and the `k + 1` values.
    bases: Vec<(usize, [f64; 4])>,
    /// Cholesky factor of `N = Σ n_p b_p b_pᵀ`.
    chol: nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>,
    /// Leverage of each position, `h_p = n_p b_pᵀ N⁻¹ b_p`.
    hat: Vec<f64>,
}

impl Design {
    /// The design of `knots` (degree `k`) over the positions of `g`: each
    /// position touches only its `k + 1` non-zero basis functions, so
    /// forming `N` costs `O(positions · k²)` and the leverages another
    /// `O(k²)` per position, against the SVD's `O(positions · n²)`.
    ///
    /// `None` when `N` is not clearly positive definite (a knot interval
    /// without data): the caller falls back to the SVD, which handles the
    /// rank-deficient case.
    fn new(g: &Grouped, knots: &[f64], k: usize) -> Option<Design> {
        let n = knots.len() - k - 1;
        let mut normal = DMatrix::<f64>::zeros(n, n);
        let mut bases = Vec::with_capacity(g.positions());
        for p in 0..g.positions() {
            let w = g.count[p] as f64;
            let (span, vals, _) = basis_at(knots, k, n, g.x[p], false);
            let first = span - k;
            for i in 0..=k {
                for j in 0..=k {
                    normal[(first + i, first + j)] += w * vals[i] * vals[j];
                }
            }
            bases.push((first, vals));
        }
        let chol = normal.cholesky()?;
        let diag = chol.l_dirty().diagonal();
        let (lo, hi) = diag.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
        if lo.is_nan() || lo <= NORMAL_PIVOT_RATIO * hi {
            return None;
        }
        let inv = chol.inverse();
        let hat: Vec<f64> = bases
            .iter()
            .zip(&g.count)
            .map(|((first, vals), &count)| {
                let mut h = 0.0;
                for i in 0..=k {
                    for j in 0..=k {
                        h += vals[i] * inv[(first + i, first + j)] * vals[j];
                    }
                }
                count as f64 * h
            })
            .collect();
        hat.iter()
            .all(|h| h.is_finite())
            .then_some(Design { bases, chol, hat })
    }

    /// Fitted values at every position for the position means of `g`.
    fn fitted(&self, g: &Grouped, k: usize) -> Option<Vec<f64>> {
        let mut rhs = DVector::<f64>::zeros(self.chol.l_dirty().nrows());
        for ((first, vals), (&count, &mean)) in self.bases.iter().zip(g.count.iter().zip(&g.mean)) {
            for i in 0..=k {
                rhs[first + i] += count as f64 * vals[i] * mean;
            }
        }
        let c = self.chol.solve(&rhs);
        let fitted: Vec<f64> = self
            .bases
            .iter()
            .map(|(first, vals)| (0..=k).map(|i| vals[i] * c[first + i]).sum())
            .collect();
        fitted.iter().all(|f| f.is_finite()).then_some(fitted)
    }
}

/// Fitted values and leverages at every grouped position from the normal
/// equations ([`Design`]).
#[cfg(test)]
fn normal_fit(g: &Grouped, knots: &[f64], k: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let d = Design::new(g, knots, k)?;
    Some((d.fitted(g, k)?, d.hat))
}

/// A design shared between the columns that cross-validate on one thread.
type SharedDesign = std::rc::Rc<Option<Design>>;

/// The designs of the last positions cross-validated on this thread, by
/// interior knot count: the error motions of one table share their
/// positions, so each design is built once per table instead of once per
/// column.
#[derive(Default)]
struct DesignCache {
    x: Vec<f64>,
    count: Vec<usize>,
    k: usize,
    designs: Vec<Option<SharedDesign>>,
}

thread_local! {
    static DESIGNS: std::cell::RefCell<DesignCache> = std::cell::RefCell::default();
}

/// The design for `m` uniform interior knots over the positions of `g`.
fn design_for(g: &Grouped, k: usize, m: usize) -> SharedDesign {
    DESIGNS.with(|cache| {
        let mut cache = cache.borrow_mut();
        if cache.k != k || cache.x != g.x || cache.count != g.count {
            *cache = DesignCache {
                x: g.x.clone(),
                count: g.count.clone(),
                k,
                designs: Vec::new(),
            };
        }
        if cache.designs.len() <= m {
            cache.designs.resize(m + 1, None);
        }
        cache.designs[m]
            .get_or_insert_with(|| {
                let knots = uniform_knots(g.x[0], g.x[g.positions() - 1], k, m);
                std::rc::Rc::new(Design::new(g, &knots, k))
            })
            .clone()
    })
}

/// Least-squares coefficients using every grouped position.
fn solve_lsq(g: &Grouped, knots: &[f64], k: usize) -> Option<Vec<f64>> {
    let rows: Vec<usize> = (0..g.positions()).collect();
    solve_rows(g, knots, k, &rows).map(|(c, _)| c)
}

/// How the number of interior knots is chosen.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KnotChoice {
    /// Leave-one-position-out cross-validation over `0..=max` interior knots.
    CrossValidation {
        /// Largest interior knot count tried (further limited by the data).
        max: usize,
        /// Relative tolerance: the smallest count whose score is at most
        /// `(1 + tolerance) ·` the best score is chosen.
        tolerance: f64,
    },
    /// A fixed number of uniform interior knots.
    Fixed(usize),
}

impl Default for KnotChoice {
    fn default() -> Self {
        KnotChoice::CrossValidation {
            max: 20,
            tolerance: 0.01,
        }
    }
}

/// Options for fitting one column.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SplineOptions {
    /// Knot count: cross-validated (default) or fixed.
    pub knots: KnotChoice,
    /// Behaviour outside the measured travel (default: hold).
    pub extrapolation: Extrapolation,
}

/// Cross-validation scores: `(interior knots, RMS prediction error)` in the
/// units of the data.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CrossValidation {
    /// Score per candidate interior knot count.
    pub scores: Vec<(usize, f64)>,
    /// The chosen count.
    pub chosen: usize,
    /// Its score.
    pub score: f64,
}

/// A fitted column: the spline and its fit statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct SplineFit {
    /// The fitted spline.
    pub spline: BSpline,
    /// Number of interior knots used.
    pub interior_knots: usize,
    /// Cross-validation details when the count was chosen that way.
    pub cv: Option<CrossValidation>,
    /// Number of samples.
    pub points: usize,
    /// Number of distinct positions.
    pub positions: usize,
    /// RMS of the residuals `y_i − s(x_i)` over all samples (data units).
    pub rms: f64,
    /// Largest absolute residual (data units).
    pub max: f64,
}

/// Largest interior knot count the data supports for degree `k` with
/// `positions` distinct positions (one position to spare for cross-validation).
fn max_supported_knots(positions: usize, k: usize, for_cv: bool) -> Option<usize> {
    let spare = if for_cv { 1 } else { 0 };
    positions.checked_sub(k + 1 + spare)
}

/// Fits a least-squares B-spline to samples `(x_i, y_i)` (repeats allowed).
pub fn fit(x: &[f64], y: &[f64], opts: &SplineOptions) -> Result<SplineFit, SplineError> {
    let g = Grouped::new(x, y)?;
    let u = g.positions();
    let (spline, m, cv) = if u == 1 {
        if let KnotChoice::Fixed(m) = opts.knots
            && m > 0
        {
            return Err(SplineError(format!(
                "{m} interior knots requested, but all samples are at one position"
            )));
        }
        let s = BSpline::constant(g.mean[0], g.x[0], opts.extrapolation);
        (s, 0, None)
    } else {
        let k = MAX_DEGREE.min(u - 1);
        let (a, b) = (g.x[0], g.x[u - 1]);
        let (m, cv) = match opts.knots {
            KnotChoice::Fixed(m) => {
                let limit = max_supported_knots(u, k, false).unwrap_or(0);
                if m > limit {
                    return Err(SplineError(format!(
                        "{m} interior knots requested, but {u} distinct positions support at most {limit}"
                    )));
                }
                (m, None)
            }
            KnotChoice::CrossValidation { max, tolerance } => {
                match cross_validate(&g, k, max, tolerance) {
                    Some(cv) => (cv.chosen, Some(cv)),
                    None => (0, None),
                }
            }
        };
        let knots = uniform_knots(a, b, k, m);
        let coef = solve_lsq(&g, &knots, k)
            .ok_or_else(|| SplineError("least-squares solution failed".into()))?;
        let s = BSpline::new(k, knots, coef, opts.extrapolation)?;
        (s, m, cv)
    };
    let mut ss = 0.0;
    let mut max: f64 = 0.0;
    for (&xi, &yi) in x.iter().zip(y) {
        let r = yi - spline.value(xi);
        ss += r * r;
        max = max.max(r.abs());
    }
    Ok(SplineFit {
        spline,
        interior_knots: m,
        cv,
        points: x.len(),
        positions: u,
        rms: (ss / x.len() as f64).sqrt(),
        max,
    })
}

/// Leave-one-position-out cross-validation for degree `k`; `None` when the
/// data has too few positions to leave one out.
fn cross_validate(g: &Grouped, k: usize, max: usize, tolerance: f64) -> Option<CrossValidation> {
    let u = g.positions();
    if u < 3 {
        return None;
    }
    let limit = max_supported_knots(u, k, true)?.min(max);
    let (a, b) = (g.x[0], g.x[u - 1]);
    let held = 1..u - 1;
    let n_held: f64 = held.clone().map(|p| g.count[p] as f64).sum();
    let ss_held: f64 = held.clone().map(|p| g.ss_within[p]).sum();
    let all: Vec<usize> = (0..u).collect();
    let mut scores = Vec::new();
    for m in 0..=limit {
        // Fitted values and leverages: from the banded normal equations
        // when they are well conditioned, else from the SVD.
        let design = design_for(g, k, m);
        let normal = design
            .as_ref()
            .as_ref()
            .and_then(|d| Some((d.fitted(g, k)?, d.hat.clone())));
        let Some((fitted, hat)) = normal.or_else(|| {
            let knots = uniform_knots(a, b, k, m);
            svd_fit(g, &knots, k, &all)
        }) else {
            continue;
        };
        // Exact leave-one-out identity of linear least squares: the
        // prediction error at a left-out row is its residual / (1 − h).
        let mut sse = ss_held;
        let mut ok = true;
        for p in held.clone() {
            let h = hat[p];
            if h.is_nan() || h >= 1.0 - 1e-9 {
                ok = false; // the position cannot be predicted without itself
                break;
            }
            let e = (g.mean[p] - fitted[p]) / (1.0 - h);
            sse += g.count[p] as f64 * e * e;
        }
        if ok && sse.is_finite() {
            scores.push((m, (sse / n_held).sqrt()));
        }
    }
    let best = scores.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return None;
    }
    let tol = tolerance.max(0.0);
    let &(chosen, score) = scores.iter().find(|s| s.1 <= best * (1.0 + tol))?;
    Some(CrossValidation {
        scores,
        chosen,
        score,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_a_cubic_exactly() {
        let x: Vec<f64> = (0..11).map(|i| i as f64 * 10.0 - 50.0).collect();
        let f = |x: f64| 1e-3 + 2e-5 * x - 3e-7 * x * x + 4e-9 * x * x * x;
        let y: Vec<f64> = x.iter().map(|&v| f(v)).collect();
        for m in 0..5 {
            let opts = SplineOptions {
                knots: KnotChoice::Fixed(m),
                ..Default::default()
            };
            let r = fit(&x, &y, &opts).unwrap();
            for t in [-50.0, -33.3, 0.0, 12.5, 50.0] {
                assert!((r.spline.value(t) - f(t)).abs() < 1e-13, "m={m} t={t}");
                let df = 2e-5 - 6e-7 * t + 12e-9 * t * t;
                assert!((r.spline.derivative(t) - df).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn leave_one_out_identity_matches_refits() {
        let x: Vec<f64> = (0..30).map(|i| (i % 10) as f64 * 7.0).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, &v)| (v / 9.0).sin() + 0.01 * ((i * 7919) % 13) as f64)
            .collect();
        let g = Grouped::new(&x, &y).unwrap();
        let u = g.positions();
        for m in 0..=3 {
            let knots = uniform_knots(g.x[0], g.x[u - 1], 3, m);
            let all: Vec<usize> = (0..u).collect();
            let (c, hat) = solve_rows(&g, &knots, 3, &all).unwrap();
            let s = BSpline::new(3, knots.clone(), c, Extrapolation::Hold).unwrap();
            for (p, &h) in hat.iter().enumerate().take(u - 1).skip(1) {
                let rows: Vec<usize> = (0..u).filter(|&i| i != p).collect();
                let (c2, _) = solve_rows(&g, &knots, 3, &rows).unwrap();
                let s2 = BSpline::new(3, knots.clone(), c2, Extrapolation::Hold).unwrap();
                let brute = g.mean[p] - s2.value(g.x[p]);
                let fast = (g.mean[p] - s.value(g.x[p])) / (1.0 - h);
                assert!(
                    (brute - fast).abs() < 1e-9,
                    "m={m} p={p}: {brute} vs {fast}"
                );
            }
        }
    }

    #[test]
    fn normal_equations_agree_with_the_svd() {
        // A dense scan (2001 positions, two passes) and a sparse one.
        for (positions, step) in [(2001usize, 0.1), (21, 10.0)] {
            let mut x = Vec::new();
            let mut y = Vec::new();
            for pass in 0..2 {
                for i in 0..positions {
                    let xi = -100.0 + step * i as f64;
                    x.push(xi);
                    let wiggle = ((i * 7919 + pass * 104729) % 1000) as f64 * 1e-7;
                    y.push(1e-3 * (xi / 40.0).sin() + 2e-4 * (xi / 13.0).cos() + wiggle);
                }
            }
            let g = Grouped::new(&x, &y).unwrap();
            let all: Vec<usize> = (0..g.positions()).collect();
            for m in [0usize, 3, 10, 16]
                .into_iter()
                .filter(|&m| m + 5 <= positions)
            {
                let knots = uniform_knots(-100.0, x[positions - 1], 3, m);
                let (f1, h1) = normal_fit(&g, &knots, 3).expect("well conditioned");
                let (f2, h2) = svd_fit(&g, &knots, 3, &all).unwrap();
                for p in 0..g.positions() {
                    assert!(
                        (f1[p] - f2[p]).abs() < 1e-15,
                        "m {m} p {p}: {} vs {}",
                        f1[p],
                        f2[p]
                    );
                    assert!(
                        (h1[p] - h2[p]).abs() < 1e-12,
                        "m {m} p {p}: {} vs {}",
                        h1[p],
                        h2[p]
                    );
                }
            }
        }
        // A knot interval without data: the normal equations decline.
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, 96.0, 97.0, 98.0, 99.0, 100.0];
        let y: Vec<f64> = x.iter().map(|v| v * 1e-3).collect();
        let g = Grouped::new(&x, &y).unwrap();
        assert!(normal_fit(&g, &uniform_knots(0.0, 100.0, 3, 6), 3).is_none());
    }

    #[test]
    fn degree_drops_with_few_positions() {
        let r = fit(
            &[0.0, 10.0, 0.0, 10.0],
            &[1.0, 3.0, 1.0, 3.0],
            &Default::default(),
        )
        .unwrap();
        assert_eq!(r.spline.degree(), 1);
        assert!((r.spline.value(5.0) - 2.0).abs() < 1e-12);
        assert!((r.spline.derivative(5.0) - 0.2).abs() < 1e-12);
        let r = fit(&[2.0, 2.0], &[1.0, 3.0], &Default::default()).unwrap();
        assert_eq!(r.spline.value(100.0), 2.0);
        assert_eq!(r.spline.derivative(100.0), 0.0);
    }

    #[test]
    fn rejects_bad_splines() {
        assert!(BSpline::new(3, vec![0.0; 8], vec![0.0; 4], Extrapolation::Hold).is_err());
        assert!(
            BSpline::new(
                3,
                vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
                vec![0.0; 4],
                Extrapolation::Hold
            )
            .is_err()
        );
        assert!(fit(&[0.0, f64::NAN], &[1.0, 2.0], &Default::default()).is_err());
        assert!(fit(&[], &[], &Default::default()).is_err());
    }
}
