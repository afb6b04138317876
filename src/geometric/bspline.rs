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

mod lsq;

pub use lsq::{CrossValidation, Grouped, KnotChoice, SplineFit, SplineOptions, fit};

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
