//! The position-dependent errors of one axis: its fitted error columns
//! (B-splines of the ISO 230-1 components over the axis position), and
//! their evaluation, rotary positions wrapped into the measured travel.

use super::bspline::BSpline;
use super::table::Component;
use crate::error::{Error, Location};
use crate::machine::chain::ErrorMotion;

/// One fitted error column of an axis.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSpline {
    /// Which error motion.
    pub component: Component,
    /// Column name (e.g. `EXX`).
    pub name: String,
    /// The fitted function: position (mm, or deg for rotary axes) → error
    /// (mm or rad).
    pub spline: BSpline,
}

/// The position-dependent errors of one axis: up to six fitted splines.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisErrors {
    /// Axis letter (upper-case), matched case-insensitively to chain joints.
    pub axis: String,
    /// Rotary axis: spline positions are degrees.
    pub rotary: bool,
    /// Fitted columns, at most one per component.
    pub columns: Vec<ColumnSpline>,
    /// Where the axis was given (table header or model JSON), for messages.
    pub origin: Origin,
}

/// Where something was read from: a location and the text found there.
/// Only for messages: two origins always compare equal, so a model read
/// back from JSON equals the model fitted from its tables.
#[derive(Debug, Clone, Default)]
pub struct Origin(pub Option<(Location, String)>);

impl PartialEq for Origin {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Origin {
    /// An input error at this origin (or at `fallback` when unknown).
    pub(crate) fn error(&self, fallback: &str, message: String) -> Error {
        match &self.0 {
            Some((loc, text)) => Error::input_with(loc.clone(), message, text.clone()),
            None => Error::input(Location::new(fallback, 0, 0), message),
        }
    }
}

impl AxisErrors {
    /// Error motions and their derivatives with respect to the position in
    /// table units (per mm, or per degree for rotary axes). Rotary positions
    /// outside a column's measured range are first replaced by the equivalent
    /// angle (± k·360°) nearest to that range; then the column's
    /// extrapolation policy applies.
    pub fn error_at(&self, pos: f64) -> (ErrorMotion, ErrorMotion) {
        let mut e = ErrorMotion::zeros();
        let mut d = ErrorMotion::zeros();
        for c in &self.columns {
            let p = if self.rotary {
                wrap_angle(pos, c.spline.range())
            } else {
                pos
            };
            let (v, dv) = c.spline.value_and_derivative(p);
            e[c.component.index()] = v;
            d[c.component.index()] = dv;
        }
        (e, d)
    }

    /// The column of component `c`, if fitted.
    pub fn column(&self, c: Component) -> Option<&ColumnSpline> {
        self.columns.iter().find(|s| s.component == c)
    }
}

/// The angle equivalent to `deg` (mod 360) that lies in, or nearest to, `[lo, hi]`.
pub(crate) fn wrap_angle(deg: f64, (lo, hi): (f64, f64)) -> f64 {
    if !deg.is_finite() || (lo..=hi).contains(&deg) {
        return deg;
    }
    let p = deg - 360.0 * ((deg - lo) / 360.0).floor(); // in [lo, lo + 360)
    if p <= hi {
        return p;
    }
    let below = p - 360.0;
    if (lo - below) < (p - hi) { below } else { p }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wraps_angles_to_nearest_equivalent() {
        assert_eq!(wrap_angle(10.0, (-90.0, 90.0)), 10.0);
        assert_eq!(wrap_angle(370.0, (-90.0, 90.0)), 10.0);
        assert_eq!(wrap_angle(-350.0, (-90.0, 90.0)), 10.0);
        assert_eq!(wrap_angle(200.0, (-90.0, 90.0)), -160.0);
        assert_eq!(wrap_angle(100.0, (-90.0, 90.0)), 100.0);
        assert_eq!(wrap_angle(-10.0, (0.0, 360.0)), 350.0);
    }
}
