//! The error splines of one axis merged into one piecewise polynomial.
//!
//! Every fitted column of an axis is a cubic spline on the same measured
//! travel; between consecutive knots of *any* column, every column is one
//! cubic. [`MergedAxis`] stores, per interval of the union of the knots, the
//! six components' cubics side by side, so that the error motions of an axis
//! and their derivatives cost one interval search and six Horner
//! evaluations instead of one knot-span search and evaluation per column.
//! The numbers agree with [`AxisErrors::error_at`] to rounding (the cubics
//! are rebuilt from each column's values and slopes at the interval ends).

use super::axis_errors::{AxisErrors, wrap_angle};
use super::bspline::Extrapolation;
use crate::machine::chain::ErrorMotion;

/// The error motions of one axis as one piecewise cubic (see the module).
#[derive(Debug, Clone, PartialEq)]
pub struct MergedAxis {
    rotary: bool,
    lo: f64,
    hi: f64,
    extrapolation: Extrapolation,
    /// Interior breakpoints, increasing: interval `i` runs from
    /// `starts[i]` to the next start (or `hi`).
    starts: Vec<f64>,
    /// Per interval: `1 / width`, and per component the cubic's
    /// coefficients in `u = (x − start) / width`.
    pieces: Vec<(f64, [[f64; 4]; 6])>,
    /// Values and slopes at `lo` and at `hi` (for outside the travel).
    end_lo: (ErrorMotion, ErrorMotion),
    end_hi: (ErrorMotion, ErrorMotion),
}

impl MergedAxis {
    /// Merges the columns of `axis`, or `None` when they cannot be merged
    /// exactly: no columns, different travels or extrapolation policies,
    /// or a spline whose slope may jump at an interior knot (degree below
    /// 3 with interior knots).
    pub fn new(axis: &AxisErrors) -> Option<Self> {
        let first = &axis.columns.first()?.spline;
        let (lo, hi) = first.range();
        let extrapolation = first.extrapolation();
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return None;
        }
        let mut starts = vec![lo];
        for c in &axis.columns {
            let s = &c.spline;
            let kinks = s.degree() < 3 && !s.interior_knots().is_empty();
            if s.range() != (lo, hi) || s.extrapolation() != extrapolation || kinks {
                return None;
            }
            starts.extend_from_slice(s.interior_knots());
        }
        starts.sort_by(f64::total_cmp);
        starts.dedup();
        let at = |x: f64| -> (ErrorMotion, ErrorMotion) {
            let mut e = ErrorMotion::zeros();
            let mut d = ErrorMotion::zeros();
            for c in &axis.columns {
                let (v, dv) = c.spline.value_and_derivative(x);
                e[c.component.index()] = v;
                d[c.component.index()] = dv;
            }
            (e, d)
        };
        let pieces = starts
            .iter()
            .enumerate()
            .map(|(i, &a)| {
                let b = starts.get(i + 1).copied().unwrap_or(hi);
                let h = b - a;
                let ((v0, d0), (v1, d1)) = (at(a), at(b));
                let cubics = std::array::from_fn(|k| {
                    let (v0, v1, d0, d1) = (v0[k], v1[k], d0[k] * h, d1[k] * h);
                    [
                        v0,
                        d0,
                        3.0 * (v1 - v0) - (2.0 * d0 + d1),
                        2.0 * (v0 - v1) + (d0 + d1),
                    ]
                });
                (1.0 / h, cubics)
            })
            .collect();
        Some(MergedAxis {
            rotary: axis.rotary,
            lo,
            hi,
            extrapolation,
            end_lo: at(lo),
            end_hi: at(hi),
            starts,
            pieces,
        })
    }

    /// Error motions and their derivatives at `pos` (mm, or degrees for a
    /// rotary axis); [`AxisErrors::error_at`] to rounding.
    pub fn error_at(&self, pos: f64) -> (ErrorMotion, ErrorMotion) {
        self.evaluate(pos, true)
    }

    /// Upper bounds of the error motions' slopes anywhere, beyond the
    /// travel too: `(Σ|δ'|, Σ|ε'|)`, the sums of the absolute slopes of the
    /// three translations (mm per mm or per degree) and of the three
    /// rotations (rad per mm or per degree). On a piece the slope of a
    /// cubic in `u = (x − start)/w` is `(a₁ + 2a₂u + 3a₃u²)/w`, at most
    /// `(|a₁| + 2|a₂| + 3|a₃|)/w` for `u` in `[0, 1]`; beyond the travel
    /// it is the end slope (linear extrapolation) or zero (hold). The
    /// pieces join with equal values (and slopes), so the motions are
    /// Lipschitz with these constants over the whole line (of positions as
    /// evaluated: a rotary's position is wrapped first).
    pub fn slope_bounds(&self) -> (f64, f64) {
        let mut bound = [0.0f64; 2];
        for (inv_w, cubics) in &self.pieces {
            let mut piece = [0.0f64; 2];
            for (k, [_, a1, a2, a3]) in cubics.iter().enumerate() {
                piece[k / 3] += (a1.abs() + 2.0 * a2.abs() + 3.0 * a3.abs()) * inv_w;
            }
            bound = [bound[0].max(piece[0]), bound[1].max(piece[1])];
        }
        if self.extrapolation == Extrapolation::Linear {
            for (_, slope) in [&self.end_lo, &self.end_hi] {
                let ends = [
                    slope[0].abs() + slope[1].abs() + slope[2].abs(),
                    slope[3].abs() + slope[4].abs() + slope[5].abs(),
                ];
                bound = [bound[0].max(ends[0]), bound[1].max(ends[1])];
            }
        }
        (bound[0], bound[1])
    }

    /// The measured travel `(lo, hi)` (mm or degrees).
    pub fn range(&self) -> (f64, f64) {
        (self.lo, self.hi)
    }

    /// Whether positions are in degrees (a rotary axis).
    pub fn is_rotary(&self) -> bool {
        self.rotary
    }

    /// The error motions alone at `pos` (the first half of
    /// [`MergedAxis::error_at`], without the derivatives).
    pub fn value_at(&self, pos: f64) -> ErrorMotion {
        self.evaluate(pos, false).0
    }

    fn evaluate(&self, pos: f64, derivative: bool) -> (ErrorMotion, ErrorMotion) {
        let x = if self.rotary {
            wrap_angle(pos, (self.lo, self.hi))
        } else {
            pos
        };
        let (end, from) = if x < self.lo {
            (&self.end_lo, self.lo)
        } else if x > self.hi {
            (&self.end_hi, self.hi)
        } else if x.is_nan() {
            let nan = ErrorMotion::repeat(f64::NAN);
            return (nan, nan);
        } else {
            let i = self.starts.partition_point(|&s| s <= x).saturating_sub(1);
            let (inv_w, cubics) = &self.pieces[i];
            let u = (x - self.starts[i]) * inv_w;
            let mut e = ErrorMotion::zeros();
            let mut d = ErrorMotion::zeros();
            for (k, [a0, a1, a2, a3]) in cubics.iter().enumerate() {
                e[k] = ((a3 * u + a2) * u + a1) * u + a0;
                if derivative {
                    d[k] = ((3.0 * a3 * u + 2.0 * a2) * u + a1) * inv_w;
                }
            }
            return (e, d);
        };
        match self.extrapolation {
            Extrapolation::Hold => (end.0, ErrorMotion::zeros()),
            Extrapolation::Linear => (end.0 + end.1 * (x - from), end.1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometric::ErrorModel;

    /// The merged form gives the columns' own numbers over and beyond the
    /// travel, for every axis of both fixture error tables.
    #[test]
    fn agrees_with_the_columns() {
        for table in [
            include_str!("../../fixtures/errors/zhao2022-xzbc.csv"),
            include_str!("../../fixtures/errors/wang2023-xyzab.csv"),
        ] {
            let model = ErrorModel::from_str_auto(table, "table.csv").unwrap();
            for axis in &model.axes {
                let m = MergedAxis::new(axis).expect("fitted columns merge");
                let (lo, hi) = axis.columns[0].spline.range();
                for i in 0..=2000 {
                    let x = lo - 0.1 * (hi - lo) + 1.2 * (hi - lo) * i as f64 / 2000.0;
                    let (e1, d1) = axis.error_at(x);
                    let (e2, d2) = m.error_at(x);
                    for k in 0..6 {
                        let scale_e = 1e-12 * (1.0 + e1.amax());
                        let scale_d = 1e-12 * (1.0 + d1.amax());
                        assert!(
                            (e1[k] - e2[k]).abs() <= scale_e,
                            "{} x={x} k={k}",
                            axis.axis
                        );
                        assert!(
                            (d1[k] - d2[k]).abs() <= scale_d,
                            "{} x={x} k={k}",
                            axis.axis
                        );
                    }
                }
            }
        }
    }
}
