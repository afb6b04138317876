//! Least-squares fits of a spline to samples: samples grouped by position,
//! the banded design and its normal equations (a rank-revealing
//! orthogonal factorisation where they are ill-conditioned), and the knot count chosen by leave-one-out
//! cross-validation.

use super::*;
use crate::linalg::{MinNorm, RankCut};

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
    // The rank policy of a fit (`linalg::rank::FIT`): what is left of the
    // design below 1e-10 of its largest column counts as zero
    // (minimum-norm solution for a deficient basis). Not by nalgebra's SVD,
    // whose solve misses the least-squares optimum where the design is
    // exactly rank-deficient (clustered positions; `linalg::MinNorm`).
    let f = MinNorm::new(&a, RankCut::Relative(crate::linalg::rank::FIT))?;
    let c: Vec<f64> = f.solve(&b).iter().copied().collect();
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    // H = Q₁ Q₁ᵀ, the projector onto the range of the design.
    let q = f.range_basis();
    let hat = (0..rows.len()).map(|r| q.row(r).norm_squared()).collect();
    Some((c, hat))
}

/// Fitted values and leverages at every grouped position, from the
/// rank-revealing factorisation of the weighted design matrix ([`solve_rows`]).
fn orthogonal_fit(
    g: &Grouped,
    knots: &[f64],
    k: usize,
    rows: &[usize],
) -> Option<(Vec<f64>, Vec<f64>)> {
    let (c, hat) = solve_rows(g, knots, k, rows)?;
    let s = BSpline::new(k, knots.to_vec(), c, Extrapolation::Hold).ok()?;
    Some((g.x.iter().map(|&x| s.value(x)).collect(), hat))
}

/// Smallest ratio of the Cholesky factor's diagonal (square root of the
/// normal matrix's conditioning) accepted for the normal equations; below
/// it the rank-revealing factorisation of the design decides the rank.
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
    /// `O(k²)` per position, against the dense factorisation's
    /// `O(positions · n²)`.
    ///
    /// `None` when `N` is not clearly positive definite (a knot interval
    /// without data): the caller falls back to the dense rank-revealing
    /// factorisation ([`solve_rows`]), which handles the rank-deficient case.
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
        // when they are well conditioned, else from the dense factorisation.
        let design = design_for(g, k, m);
        let normal = design
            .as_ref()
            .as_ref()
            .and_then(|d| Some((d.fitted(g, k)?, d.hat.clone())));
        let Some((fitted, hat)) = normal.or_else(|| {
            let knots = uniform_knots(a, b, k, m);
            orthogonal_fit(g, &knots, k, &all)
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
    fn normal_equations_agree_with_the_dense_factorisation() {
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
                let (f2, h2) = orthogonal_fit(&g, &knots, 3, &all).unwrap();
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

    /// The weighted design matrix and right-hand side of [`solve_rows`].
    fn design(g: &Grouped, knots: &[f64], k: usize) -> (DMatrix<f64>, DVector<f64>) {
        let n = knots.len() - k - 1;
        let mut a = DMatrix::zeros(g.positions(), n);
        let mut b = DVector::zeros(g.positions());
        for i in 0..g.positions() {
            let w = (g.count[i] as f64).sqrt();
            let (span, vals, _) = basis_at(knots, k, n, g.x[i], false);
            for s in 0..=k {
                a[(i, span - k + s)] = w * vals[s];
            }
            b[i] = w * g.mean[i];
        }
        (a, b)
    }

    /// Clustered positions (three groups of four measurements 0.5 mm apart,
    /// one stray) with five interior knots, a count cross-validation tries
    /// and `KnotChoice::Fixed` accepts: the 12 × 9 design has full column
    /// rank, condition about 3e3, yet nalgebra's SVD of it is wrong (its
    /// bidiagonal form has a diagonal entry at rounding level) and its
    /// solve missed the least-squares optimum: the normal equations
    /// `Aᵀ (A c − b) = 0` violated by 2e-3 relative. Checked against the
    /// normal equations and against an LU solve of them.
    #[test]
    fn clustered_design_is_solved_exactly() {
        let x = [
            34.954935667588586,
            35.454935667588586,
            35.954935667588586,
            36.454935667588586,
            52.86457053873285,
            53.36457053873285,
            53.86457053873285,
            58.054759109625806,
            73.3762202231308,
            73.8762202231308,
            74.3762202231308,
            74.8762202231308,
        ];
        let y: Vec<f64> = x.iter().map(|v: &f64| 1e-3 * (v / 17.0).sin()).collect();
        let g = Grouped::new(&x, &y).unwrap();
        let knots = uniform_knots(x[0], x[11], 3, 5);
        let all: Vec<usize> = (0..12).collect();
        let (c, hat) = solve_rows(&g, &knots, 3, &all).unwrap();
        let (a, b) = design(&g, &knots, 3);
        let c = DVector::from_vec(c);
        let normal = (a.transpose() * (&a * &c - &b)).norm() / (a.norm() * b.norm());
        assert!(normal < 1e-14, "normal equations miss by {normal:e}");
        let exact = (a.transpose() * &a)
            .lu()
            .solve(&(a.transpose() * &b))
            .unwrap();
        assert!((&c - &exact).norm() < 1e-9 * exact.norm());
        // The leverages are the diagonal of A (AᵀA)⁻¹ Aᵀ; their sum is the
        // rank, 9.
        let h = &a * (a.transpose() * &a).try_inverse().unwrap() * a.transpose();
        for (p, &hp) in hat.iter().enumerate() {
            assert!((hp - h[(p, p)]).abs() < 1e-9, "leverage {p}");
        }
        assert!((hat.iter().sum::<f64>() - 9.0).abs() < 1e-12);
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
