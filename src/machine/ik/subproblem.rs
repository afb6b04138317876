//! The geometric subproblems the analytic families reduce to: Paden–Kahan
//! subproblems 1 and 2 (angles that turn a vector onto another about one or
//! two axes) and the small least-squares solve of the linear axes.

use nalgebra::{Matrix3, Matrix4, Vector3};

/// Subproblem 1: the angle θ that turns `p` about unit `k` closest to `q`
/// (exactly onto it when reachable). `None` when `p` or `q` lies along `k`
/// (within `tol`), where every θ is as good.
pub(super) fn subproblem1(
    k: &Vector3<f64>,
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    tol: f64,
) -> Option<f64> {
    let pp = p - k * k.dot(p);
    let qq = q - k * k.dot(q);
    if pp.norm() <= tol || qq.norm() <= tol {
        return None;
    }
    Some(k.dot(&pp.cross(&qq)).atan2(pp.dot(&qq)))
}

/// Subproblem 2: the pairs (θ1, θ2) with `Rot(k1, θ1) Rot(k2, θ2) p = q`
/// (unit `k1`, `k2` not parallel). Two pairs in general, one when the
/// orientation is at the edge of the reachable set. When it is not
/// reachable, the pair through the intersection point with γ = 0 (the
/// nearest the circles come) is returned, and the caller measures the miss.
pub(super) fn subproblem2(
    k1: &Vector3<f64>,
    k2: &Vector3<f64>,
    p: &Vector3<f64>,
    q: &Vector3<f64>,
) -> arrayvec::ArrayVec<(f64, f64), 2> {
    let c12 = k1.dot(k2);
    let denom = c12 * c12 - 1.0;
    let alpha = (c12 * k2.dot(p) - k1.dot(q)) / denom;
    let beta = (c12 * k1.dot(q) - k2.dot(p)) / denom;
    let cross = k1.cross(k2);
    let g2 = gamma_squared(k1, k2, p, q, c12, &cross);
    let gammas: arrayvec::ArrayVec<f64, 2> = if g2 > 0.0 {
        let g = g2.sqrt();
        [g, -g].into_iter().collect()
    } else {
        [0.0].into_iter().collect()
    };
    gammas
        .into_iter()
        .map(|g| {
            let c = k1 * alpha + k2 * beta + cross * g;
            let t2 = subproblem1(k2, p, &c, 0.0).unwrap_or(0.0);
            let t1 = subproblem1(k1, &c, q, 0.0).unwrap_or(0.0);
            (t1, t2)
        })
        .collect()
}

/// γ² of subproblem 2: the squared component, along `k1 × k2`, of the
/// point `c` where the two circles meet, computed without cancellation.
///
/// `c` lies on the circle of `q` about `k1`: its distance from `k1`'s line
/// is `r1 = |k1 × q|`, which a cross product gives to full relative
/// precision even when `q` is within 1e-8 rad of `k1` (where the textbook
/// `|p|² − α² − β² − 2αβ·c12` loses everything: 1 − cos²θ with cos θ
/// rounded to 1). In the plane ⟂ `k1`, `c`'s component towards `k2` is
/// `a = (k2·p − c12·k1·q)/s` (s = |k1 × k2|) and the rest, `γ·s`, is
/// along `k1 × k2`: γ²s² = r1² − a² = (r1 − a)(r1 + a). The same holds
/// from `k2`'s side with `r2 = |k2 × p|`; the side with the smaller radius
/// is the better conditioned one and is used.
pub(super) fn gamma_squared(
    k1: &Vector3<f64>,
    k2: &Vector3<f64>,
    p: &Vector3<f64>,
    q: &Vector3<f64>,
    c12: f64,
    cross: &Vector3<f64>,
) -> f64 {
    let s = cross.norm();
    let r1 = k1.cross(q).norm();
    let r2 = k2.cross(p).norm();
    let (r, a) = if r1 <= r2 {
        (r1, ((k2.dot(p) - c12 * k1.dot(q)) / s).abs())
    } else {
        (r2, ((k1.dot(q) - c12 * k2.dot(p)) / s).abs())
    };
    (r - a) * (r + a) / (s * s)
}

pub(super) fn rot3(m: &Matrix4<f64>) -> Matrix3<f64> {
    m.fixed_view::<3, 3>(0, 0).into_owned()
}

/// Least-squares solution of `Σ_c x_c · dirs[cols[c]] = b` for two or three
/// columns by modified Gram–Schmidt QR, when the columns are certainly far
/// from dependent: `None` for any other column count, and whenever the
/// smallest singular value might be below `1e-6` of the largest (then the
/// caller's SVD decides). With `R` the triangular factor, `σ_max ≤ ‖R‖_F` and
/// `σ_min ≥ |det R| / ‖R‖_F^(m−1)`, so `|det R| ≥ 1e-6 · ‖R‖_F^m` proves
/// `σ_min / σ_max ≥ 1e-6`.
pub(super) fn gram_schmidt_solve(
    dirs: &[[f64; 3]; crate::machine::chain::MAX_JOINTS],
    cols: &[usize],
    b: &Vector3<f64>,
) -> Option<[f64; 3]> {
    let m = cols.len();
    if !(2..=3).contains(&m) {
        return None;
    }
    let mut q = [Vector3::zeros(); 3];
    let mut r = [[0.0f64; 3]; 3];
    for c in 0..m {
        let mut v = Vector3::from(dirs[cols[c]]);
        for (i, qi) in q.iter().enumerate().take(c) {
            r[i][c] = qi.dot(&v);
            v -= r[i][c] * qi;
        }
        r[c][c] = v.norm();
        if r[c][c].is_nan() || r[c][c] <= 0.0 {
            return None;
        }
        q[c] = v / r[c][c];
    }
    let frob2: f64 = r.iter().flatten().map(|v| v * v).sum();
    let det: f64 = (0..m).map(|i| r[i][i]).product();
    // ‖R‖_F^m without `powf` (m is 2 or 3).
    let norm_m = if m == 2 { frob2 } else { frob2 * frob2.sqrt() };
    let bound = 1e-6 * norm_m;
    if !bound.is_finite() || det.is_nan() || det.abs() < bound {
        return None;
    }
    let mut x = [0.0; 3];
    for i in (0..m).rev() {
        let mut v = q[i].dot(b);
        for k in i + 1..m {
            v -= r[i][k] * x[k];
        }
        x[i] = v / r[i][i];
    }
    Some(x)
}
