//! `CIRCLE/xc,yc,zc,i,j,k[,r,…]` followed by `GOTO`: the arc, its checks,
//! its linearisation within the chord tolerance, and the [`ArcMove`] the
//! converter turns into `G2`/`G3` when the arc lies in a plane of the
//! machine (`src/post/cl_motion.rs`), else into the linearised moves.

use std::io::BufRead;

use super::state::{Circle, Lowered};
use super::vec3::{add, cross, dot, norm, num, scale, sub};
use super::{ClRecord, ClStatement};
use crate::error::Error;

/// An arc of the tool tip (made by [`super::lower`], never by the reader),
/// in the set-up frame and in CL units.
#[derive(Debug, Clone, PartialEq)]
pub struct ArcMove {
    /// Centre of the circle (on the axis, at the height of the `CIRCLE`
    /// point).
    pub centre: [f64; 3],
    /// Unit axis: the arc runs counter-clockwise about it.
    pub normal: [f64; 3],
    /// End point (the `GOTO`); the start is the position before.
    pub end: [f64; 3],
    /// Angle swept, rad, in (0, 2π]; 2π is a full circle.
    pub sweep_rad: f64,
    /// Radius at the start.
    pub radius: f64,
    /// Tool axis at the end.
    pub tool_axis: [f64; 3],
    /// Whether the tool axis is the same at both ends.
    pub constant_axis: bool,
    /// The arc linearised within the chord tolerance: `GOTO`s (set-up
    /// frame, with the tool axis), the last one at the end point.
    pub moves: Vec<ClStatement>,
}

/// How far two radii of an arc may differ (CL units) when its `points`
/// are written to a number of decimals: the finest step their coordinates
/// show, `q` (a coordinate that happens to be whole shows a coarse one,
/// so the finest is the writer's), rounds each coordinate by up to q/2,
/// and a difference of two radii from three points (start, end, centre;
/// three coordinates each) by up to 2·√3·q. At least 1 µm (full-precision
/// data), at most 10 µm (data in whole units): 4-decimal inch data (q =
/// 2.54 µm) allows 8.8 µm, 3-decimal mm data 3.5 µm.
fn rounding_slack(points: &[[f64; 3]], mm_per_unit: f64) -> f64 {
    let q = points
        .iter()
        .flatten()
        .map(|&x| decimal_step(x))
        .fold(f64::INFINITY, f64::min);
    (2.0 * 3f64.sqrt() * q * mm_per_unit).clamp(1e-3, 1e-2) / mm_per_unit
}

/// The step of the last decimal `x` is written to: 10⁻ᵏ for the least k ≤
/// 9 with x·10ᵏ whole (to the f64 rounding of the decimal text), 0 if
/// none.
fn decimal_step(x: f64) -> f64 {
    (0..=9)
        .find(|&k| {
            let n = x * 10f64.powi(k);
            (n - n.round()).abs() <= 2.0 * f64::EPSILON * n.abs()
        })
        .map_or(0.0, |k| 10f64.powi(-k))
}

impl<R: BufRead> Lowered<R> {
    /// The arc from the current point to `end`; the tool axis turns from
    /// `from_axis` to the current one in proportion to the angle.
    pub(super) fn arc(
        &mut self,
        r: &ClRecord,
        c: Circle,
        end: [f64; 3],
        from_axis: [f64; 3],
    ) -> Result<(), Error> {
        let to_axis = self.axis;
        let Some(start) = self.pos else {
            return Err(self.err(
                r,
                "arc (CIRCLE) with no start position: expected a GOTO before CIRCLE",
            ));
        };
        let n = scale(c.normal, 1.0 / norm(c.normal));
        let s = sub(start, c.center);
        let e = sub(end, c.center);
        let hs = dot(s, n);
        let he = dot(e, n);
        let sp = sub(s, scale(n, hs));
        let ep = sub(e, scale(n, he));
        let r0 = norm(sp);
        let r1 = norm(ep);
        let tol = self.tol_mm / self.mm_per_unit;
        let slack = rounding_slack(&[start, c.center, end], self.mm_per_unit);
        if r0 < tol {
            return Err(self.err(
                r,
                "arc (CIRCLE) starts at its centre: expected a start point on the circle",
            ));
        }
        let units = if self.mm_per_unit == 1.0 { "mm" } else { "in" };
        let beyond = |d: f64| {
            format!(
                "{:.2} µm apart, more than the {:.2} µm its points' decimals allow",
                d * self.mm_per_unit * 1e3,
                slack * self.mm_per_unit * 1e3
            )
        };
        if (r0 - r1).abs() > slack {
            return Err(self.err(
                r,
                format!(
                    "arc (CIRCLE) end point is {} {units} from the centre but the start is {} {units} ({}): not on one circle",
                    num(r1),
                    num(r0),
                    beyond((r0 - r1).abs())
                ),
            ));
        }
        if let Some(rad) = c.radius
            && (rad - r0).abs() > slack
        {
            return Err(self.err(
                r,
                format!(
                    "arc (CIRCLE) radius {} {units} but the start point is {} {units} from the centre ({})",
                    num(rad),
                    num(r0),
                    beyond((rad - r0).abs())
                ),
            ));
        }
        let u = scale(sp, 1.0 / r0);
        let v = cross(n, u);
        let mut sweep = dot(ep, v).atan2(dot(ep, u));
        if sweep < 0.0 {
            sweep += std::f64::consts::TAU;
        }
        if sweep * r0.max(r1) < 1e-7 / self.mm_per_unit || sweep > std::f64::consts::TAU - 1e-12 {
            sweep = std::f64::consts::TAU;
        }
        if let Some(a) = c.sweep_deg
            && (sweep.to_degrees() - a).abs() > super::lower::ARC_ANGLE_TOLERANCE_DEG
        {
            return Err(self.err(
                r,
                format!(
                    "MOVARC gives an angle of {}° but its start and end points sweep {}° about its axis: refused rather than guessed",
                    num(a),
                    num(sweep.to_degrees())
                ),
            ));
        }
        let rmax = r0.max(r1);
        let step = if tol >= rmax {
            std::f64::consts::PI / 2.0
        } else {
            (2.0 * (1.0 - tol / rmax).acos()).min(std::f64::consts::PI / 2.0)
        };
        let count = (sweep / step).ceil().max(1.0);
        if count > 1e6 {
            return Err(self.err(
                r,
                "arc (CIRCLE) would need more than 1000000 segments within the arc tolerance",
            ));
        }
        let count = count as usize;
        let mark = self.out.len();
        for k in 1..=count {
            let f = k as f64 / count as f64;
            let p = if k == count {
                end
            } else {
                let th = sweep * f;
                let rad = r0 + (r1 - r0) * f;
                let h = hs + (he - hs) * f;
                add(
                    c.center,
                    add(
                        scale(n, h),
                        add(scale(u, rad * th.cos()), scale(v, rad * th.sin())),
                    ),
                )
            };
            let mix = add(scale(from_axis, 1.0 - f), scale(to_axis, f));
            self.axis = if norm(mix) > 1e-9 {
                scale(mix, norm(to_axis) / norm(mix))
            } else {
                to_axis
            };
            self.go(r, p, false);
        }
        self.axis = to_axis;
        let moves: Vec<ClStatement> = self.out.drain(mark..).map(|m| m.statement).collect();
        let unit = |a: [f64; 3]| scale(a, 1.0 / norm(a));
        let constant_axis = norm(sub(unit(from_axis), unit(to_axis))) < 1e-12;
        let arc = ArcMove {
            centre: self.to_setup(c.center),
            normal: self.dir_to_setup(n),
            end: self.to_setup(end),
            sweep_rad: sweep,
            radius: r0,
            tool_axis: self.dir_to_setup(to_axis),
            constant_axis,
            moves,
        };
        self.emit(r, ClStatement::Arc(Box::new(arc)));
        Ok(())
    }
}

impl<R: BufRead> Lowered<R> {
    /// CATIA's circular move: `INDIRV/i,j,k` (the direction at the start),
    /// then `TLON,GOFWD/(CIRCLE/xc,yc,zc,r),ON,(LINE/xc,yc,zc,xe,ye,ze)`:
    /// along the circle about the tool axis through the centre, starting in
    /// the `INDIRV` direction, until the tool is on the line (the first
    /// crossing; `ON,2,INTOF` the second, which makes a whole circle when
    /// the start is on the line). Lowered as a `CIRCLE` with its `GOTO`.
    pub(super) fn tlon_gofwd(&mut self, r: &ClRecord, text: &str) -> Result<(), Error> {
        let refuse = |m: &str| {
            self.err(r, format!("TLON,GOFWD: {m}; kinpost converts only the form INDIRV/i,j,k then TLON,GOFWD/(CIRCLE/xc,yc,zc,r),ON[,2,INTOF],(LINE/xc,yc,zc,xe,ye,ze)"))
        };
        let upper = text.to_ascii_uppercase();
        let body = upper
            .trim_start()
            .strip_prefix(',')
            .map(str::trim_start)
            .and_then(|x| x.strip_prefix("GOFWD"))
            .map(str::trim_start)
            .and_then(|x| x.strip_prefix('/'));
        let Some(body) = body else {
            return Err(refuse("expected GOFWD/ after TLON"));
        };
        let toks: Vec<&str> = body
            .split([',', '(', ')', '/'])
            .map(str::trim)
            .filter(|x| !x.is_empty())
            .collect();
        let nums = |from: usize, n: usize| -> Option<Vec<f64>> {
            let v: Option<Vec<f64>> = toks
                .get(from..from + n)?
                .iter()
                .map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite()))
                .collect();
            v
        };
        if toks.first() != Some(&"CIRCLE") {
            return Err(refuse("expected (CIRCLE/…) after GOFWD/"));
        }
        let Some(circle) = nums(1, 4) else {
            return Err(refuse("expected CIRCLE/xc,yc,zc,r"));
        };
        if toks.get(5) != Some(&"ON") {
            return Err(refuse("expected ON after the circle"));
        }
        let (nth, at_line) = match (toks.get(6), toks.get(7)) {
            (Some(n), Some(&"INTOF")) => match n.parse::<f64>() {
                Ok(1.0) => (1, 8),
                Ok(2.0) => (2, 8),
                _ => return Err(refuse("expected 1 or 2 before INTOF")),
            },
            _ => (1, 6),
        };
        if toks.get(at_line) != Some(&"LINE") || toks.len() != at_line + 7 {
            return Err(refuse("expected (LINE/xc,yc,zc,xe,ye,ze) at the end"));
        }
        let Some(line) = nums(at_line + 1, 6) else {
            return Err(refuse("expected LINE/xc,yc,zc,xe,ye,ze"));
        };
        let Some(start) = self.pos else {
            return Err(refuse("no start position (expected a GOTO before)"));
        };
        let Some(dir) = self.indirv else {
            return Err(refuse("no INDIRV before it gives the direction"));
        };
        let centre = [circle[0], circle[1], circle[2]];
        let radius = circle[3];
        let a = scale(self.axis, 1.0 / norm(self.axis));
        let slack = rounding_slack(&[start, centre], self.mm_per_unit);
        let s = sub(start, centre);
        let hs = dot(s, a);
        let sp = sub(s, scale(a, hs));
        if radius <= 0.0 || (norm(sp) - radius).abs() > slack || hs.abs() > slack {
            return Err(refuse(&format!(
                "the start point is not on the circle (radius {}, start {} from the centre in its plane, {} off the plane)",
                num(radius),
                num(norm(sp)),
                num(hs)
            )));
        }
        let turn = dot(cross(sp, dir), a);
        if turn.abs() < 1e-9 * norm(sp) * norm(dir) {
            return Err(refuse(
                "INDIRV points along the radius: the direction of turn is not known",
            ));
        }
        let n = scale(a, turn.signum());
        let e = sub([line[3], line[4], line[5]], [line[0], line[1], line[2]]);
        let d = sub(e, scale(a, dot(e, a)));
        if norm(d) < 1e-9 || norm(sub([line[0], line[1], line[2]], centre)) > slack {
            return Err(refuse("the LINE must run from the centre to the end point"));
        }
        let u = scale(sp, 1.0 / norm(sp));
        let v = cross(n, u);
        let mut crossings: Vec<(f64, [f64; 3])> = [1.0, -1.0]
            .iter()
            .map(|k| {
                let p = scale(d, k * radius / norm(d));
                let mut th = dot(p, v).atan2(dot(p, u)).rem_euclid(std::f64::consts::TAU);
                if th < 1e-9 {
                    th = std::f64::consts::TAU;
                }
                (th, add(centre, add(p, scale(a, hs))))
            })
            .collect();
        crossings.sort_by(|x, y| x.0.total_cmp(&y.0));
        let end = crossings[nth - 1].1;
        self.indirv = None;
        self.circle = Some(Circle {
            center: centre,
            normal: n,
            radius: Some(radius),
            sweep_deg: None,
        });
        self.goto(r, end, None)
    }
}

#[cfg(test)]
mod tests {
    use crate::cl::lower::tests::{flat, gotos, near, run};
    use crate::cl::vec3::{add, norm, scale};
    use crate::cl::{ArcMove, ClStatement};

    /// A quarter circle counter-clockwise about +Z: every point on the
    /// circle, the chord error within the tolerance, the end exact.
    #[test]
    fn circle_is_linearised_within_tolerance() {
        let s = run("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n").unwrap();
        let g = gotos(&s);
        assert!(near(*g.last().unwrap(), [0.0, 10.0, 0.0]));
        assert!(g.len() > 20);
        for w in g.windows(2) {
            assert!((norm(w[1]) - 10.0).abs() < 1e-9);
            // Counter-clockwise: y grows, x falls.
            assert!(w[1][1] > w[0][1] && w[1][0] < w[0][0]);
            let mid = scale(add(w[0], w[1]), 0.5);
            assert!(10.0 - norm(mid) <= 1e-3 + 1e-12);
        }
        // About -Z the same end point is three quarters clockwise.
        let s = run("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1\nGOTO/0,10,0\n").unwrap();
        assert!(gotos(&s).iter().any(|p| p[0] < -9.9));
        // A full circle: start equal to end.
        let s = run("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/10,0,0\n").unwrap();
        assert!(gotos(&s).iter().any(|p| p[0] < -9.99));
    }

    /// A tool axis that changes over an arc turns with it, not at once.
    #[test]
    fn arc_turns_the_tool_axis_gradually() {
        let s =
            run("UNITS/MM\nGOTO/10,0,0,0,0,1\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10,0,0,1,0\n").unwrap();
        let axes: Vec<[f64; 3]> = flat(&s)
            .iter()
            .filter_map(|s| match s {
                ClStatement::Goto { axis, .. } => *axis,
                _ => None,
            })
            .collect();
        let mid = axes[axes.len() / 2];
        assert!(mid[1] > 0.3 && mid[2] > 0.3, "{mid:?}");
        assert!((norm(mid) - 1.0).abs() < 1e-12);
        assert!(near(*axes.last().unwrap(), [0.0, 1.0, 0.0]));
    }

    /// NX writes inch CL to 4 decimals (2.54 µm): an arc of its (the
    /// twentieth hunt) has radii 1.4 µm apart, and its radius word differs
    /// as much; a fixed 1 µm refused it. The slack follows the finest
    /// decimal of the points, from 1 µm to 10 µm.
    #[test]
    fn the_slack_follows_the_decimals_of_the_data() {
        use super::{decimal_step, rounding_slack};
        assert!((decimal_step(2.1643) - 1e-4).abs() < 1e-18);
        assert!((decimal_step(-0.5) - 0.1).abs() < 1e-18);
        assert_eq!(decimal_step(3.0), 1.0);
        assert_eq!(decimal_step(std::f64::consts::PI), 0.0);
        let inch = rounding_slack(&[[2.36, 2.2749, 3.1], [2.0, 0.0, 1.0]], 25.4);
        assert!(
            (inch * 25.4e3 - 2.0 * 3f64.sqrt() * 2.54).abs() < 1e-9,
            "{inch}"
        );
        assert_eq!(rounding_slack(&[[1.0, 2.0, 3.0]], 1.0), 1e-2);
        assert_eq!(
            rounding_slack(&[[1.0, std::f64::consts::E, 3.0]], 1.0),
            1e-3
        );
        let nx = "UNITS/INCHES\nGOTO/2.3600,2.2749,3.1000\nCIRCLE/2.1643,2.0000,2.9020,0.0000000,0.0000000,-1.0000000,0.3375,0.0060,0.5000,0.7500,0.1200\nGOTO/1.8268,2.0000,2.9020\n";
        let g = gotos(&run(nx).unwrap());
        assert!(near(*g.last().unwrap(), [1.8268, 2.0, 2.902]));
        // An end point 22 µm off the circle is still refused, in µm.
        let e = run(&nx.replace("GOTO/1.8268", "GOTO/1.8260")).unwrap_err();
        assert!(
            e.to_string()
                .contains("(21.74 µm apart, more than the 8.80 µm its points' decimals allow)"),
            "{e}"
        );
        // Points of full precision keep 1 µm: 2 µm apart is refused.
        let e = run("UNITS/MM\nGOTO/10.0000000001,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10.002,0\n");
        assert!(e.unwrap_err().to_string().contains("not on one circle"));
    }

    #[test]
    fn bad_circles_are_refused() {
        let e = run("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,11,0\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:4:1"), "{e}");
        let e = run("UNITS/MM\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10,0\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:3:1"), "{e}");
    }

    /// The arc record: centre, axis, sweep and end in the set-up frame; a
    /// full circle sweeps 2π; a changing tool axis is marked.
    #[test]
    fn arc_record() {
        let arcs = |text: &str| -> Vec<ArcMove> {
            run(text)
                .unwrap()
                .into_iter()
                .filter_map(|s| match s {
                    ClStatement::Arc(a) => Some(*a),
                    _ => None,
                })
                .collect()
        };
        let a = &arcs(
            "UNITS/MM\nCSYS/1,0,0,1,0,1,0,2,0,0,1,3\nGOTO/11,2,3\nCIRCLE/1,2,3,0,0,-1\nGOTO/1,12,3\n",
        )[0];
        assert!(near(a.centre, [0.0, 0.0, 0.0]) && near(a.end, [0.0, 10.0, 0.0]));
        assert!(near(a.normal, [0.0, 0.0, -1.0]));
        assert!((a.sweep_rad - 1.5 * std::f64::consts::PI).abs() < 1e-12);
        assert!(a.constant_axis && (a.radius - 10.0).abs() < 1e-12);
        let a = &arcs("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/10,0,0\n")[0];
        assert_eq!(a.sweep_rad, std::f64::consts::TAU);
        let a = &arcs("UNITS/MM\nGOTO/10,0,0,0,0,1\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10,0,0,1,0\n")[0];
        assert!(!a.constant_axis);
    }
}
