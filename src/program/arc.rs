//! Circular moves of G-code (`G2`, `G3`) as the points they pass through:
//! the plane (`G17`, `G18`, `G19`), the centre (`I J K`, incremental, or
//! absolute after `G90.1`), or the radius (`R`, Sinumerik `CR=`), helical
//! moves along the plane's normal, LinuxCNC's turns (`P`) and Sinumerik's
//! added turns (`TURN=`).
//!
//! The forms this module does not follow (Sinumerik `CIP`, `CT`, `AR=`,
//! polar arcs) are refused with the word that asks for them, so that no
//! arc is replaced by a path the machine does not take.

use crate::gcode::{ItemKind, Line};

/// The plane of circular moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArcPlane {
    /// `G17`: X and Y, normal Z.
    Xy,
    /// `G18`: Z and X, normal Y.
    Zx,
    /// `G19`: Y and Z, normal X.
    Yz,
}

impl ArcPlane {
    /// The plane's first and second axes and its normal (0 = X, 1 = Y,
    /// 2 = Z), a right-handed frame: a positive angle turns counter-clockwise
    /// seen from the normal's positive side (`G3`).
    pub fn axes(self) -> [usize; 3] {
        match self {
            ArcPlane::Xy => [0, 1, 2],
            ArcPlane::Zx => [2, 0, 1],
            ArcPlane::Yz => [1, 2, 0],
        }
    }

    /// The G code that selects the plane.
    pub fn code(self) -> &'static str {
        match self {
            ArcPlane::Xy => "G17",
            ArcPlane::Zx => "G18",
            ArcPlane::Yz => "G19",
        }
    }
}

/// Which circular move the modal motion is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ArcKind {
    /// `G2`.
    Clockwise,
    /// `G3`.
    CounterClockwise,
    /// A form this module does not follow (Sinumerik `CIP`, `CT`).
    Other(&'static str),
}

/// The arc settings in force, followed from line to line: the plane, the
/// centre mode and the direction of the last circular motion code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArcModes {
    plane: ArcPlane,
    absolute_centre: bool,
    kind: ArcKind,
}

impl Default for ArcModes {
    /// `G17`, incremental centres (`G91.1`), `G2`: the controllers' defaults.
    fn default() -> Self {
        ArcModes {
            plane: ArcPlane::Xy,
            absolute_centre: false,
            kind: ArcKind::Clockwise,
        }
    }
}

/// Largest difference between the radii at the start and the end of an
/// arc given by its centre, mm, when it is also more than
/// [`RADIUS_MISMATCH_RELATIVE`] of the radius: beyond both the arc is
/// refused (its centre is wrong), below either the radius changes evenly
/// along the arc (a spiral, as LinuxCNC moves it).
pub const RADIUS_MISMATCH_MM: f64 = 0.01;
/// See [`RADIUS_MISMATCH_MM`].
pub const RADIUS_MISMATCH_RELATIVE: f64 = 1e-3;

/// Most straight pieces one arc is divided into.
pub const MAX_PIECES: usize = 100_000;

/// A refused arc: the byte column of the word (0 where no word is to blame)
/// and why.
pub type ArcError = (usize, String);

impl ArcModes {
    /// Applies the plane, centre-mode and motion codes of `line`.
    pub fn apply(&mut self, line: &Line) {
        for w in line.words() {
            if !w.is("G") {
                continue;
            }
            match (w.value * 10.0).round() as i64 {
                20 => self.kind = ArcKind::Clockwise,
                30 => self.kind = ArcKind::CounterClockwise,
                170 => self.plane = ArcPlane::Xy,
                180 => self.plane = ArcPlane::Zx,
                190 => self.plane = ArcPlane::Yz,
                901 => self.absolute_centre = true,
                911 => self.absolute_centre = false,
                _ => {}
            }
        }
        for k in line.keywords() {
            match k {
                "CIP" => self.kind = ArcKind::Other("CIP"),
                "CT" => self.kind = ArcKind::Other("CT"),
                _ => {}
            }
        }
    }

    /// The plane in force.
    pub fn plane(&self) -> ArcPlane {
        self.plane
    }

    /// The points of the circular move of `line` from `start` to `end`
    /// (X, Y, Z in mm), each with the fraction of the move done there
    /// (0 … 1, by angle), after the start up to and including the end,
    /// no point more than `tolerance_mm` from the arc between its
    /// neighbours. `mm_per_unit` converts the line's `I J K R` to mm.
    pub fn points(
        &self,
        line: &Line,
        start: [f64; 3],
        end: [f64; 3],
        mm_per_unit: f64,
        tolerance_mm: f64,
    ) -> Result<Vec<(f64, [f64; 3])>, ArcError> {
        // The column of the first item `is` picks, if any.
        let col_of = |is: &dyn Fn(&ItemKind) -> bool| {
            line.items.iter().find(|it| is(&it.kind)).map(|it| it.col())
        };
        let find = |address: &str| col_of(&|k| matches!(k, ItemKind::Word(w) if w.is(address)));
        let word_col = |address: &str| find(address).unwrap_or(1);
        let radius_col = || word_col("R").max(word_col("CR"));
        let [a, b, n] = self.plane.axes();
        let letters = ["I", "J", "K"];
        // The first centre word of the plane, where a wrong centre is blamed.
        let centre_col = || match (find(letters[a]), find(letters[b])) {
            (Some(x), Some(y)) => x.min(y),
            (x, y) => x.or(y).unwrap_or(1),
        };
        let clockwise = match self.kind {
            ArcKind::Clockwise => true,
            ArcKind::CounterClockwise => false,
            ArcKind::Other(k) => {
                let col =
                    col_of(&|kind| matches!(kind, ItemKind::Keyword(kw) if kw == k)).unwrap_or(1);
                return Err((
                    col,
                    format!(
                        "the circular move `{k}` is not followed here (only G2/G3 with I J K or R)"
                    ),
                ));
            }
        };
        for refused in ["AR", "AP", "RP", "I1", "J1", "K1"] {
            if line.word(refused).is_some() {
                return Err((
                    word_col(refused),
                    format!("an arc given with `{refused}` is not followed here (only I J K or R)"),
                ));
            }
        }
        let offset = |axis: usize| line.word(letters[axis]).map(|w| w.value * mm_per_unit);
        let radius = line
            .word("R")
            .or_else(|| line.word("CR"))
            .map(|w| w.value * mm_per_unit);
        // LinuxCNC's P: the number of turns (1: less than one); Sinumerik's
        // TURN=: the full turns added.
        let whole = |v: f64, from: f64| v >= from && v.fract() == 0.0 && v <= 1e4;
        let turns = match (line.word("P"), line.word("TURN")) {
            (None, None) => 1,
            (Some(p), None) if whole(p.value, 1.0) => p.value as u32,
            (None, Some(t)) if whole(t.value, 0.0) => t.value as u32 + 1,
            (Some(_), Some(_)) => {
                return Err((word_col("TURN"), "TURN= beside P: give one".into()));
            }
            (Some(p), None) => {
                return Err((
                    word_col("P"),
                    format!(
                        "P{} is not a number of turns (a whole number from 1)",
                        p.value
                    ),
                ));
            }
            (None, Some(t)) => {
                return Err((
                    word_col("TURN"),
                    format!(
                        "TURN={} is not a number of added turns (a whole number from 0)",
                        t.value
                    ),
                ));
            }
        };
        // Fanuc takes R, LinuxCNC refuses the block: which one counts is the
        // control's.
        if radius.is_some() && (offset(a).is_some() || offset(b).is_some()) {
            return Err((
                radius_col(),
                format!(
                    "the arc gives both its centre ({} {}) and its radius (R, CR=): controls differ on which counts; give one",
                    letters[a], letters[b]
                ),
            ));
        }
        let (s, e) = ([start[a], start[b]], [end[a], end[b]]);
        let (centre, radius_given) = match (offset(a), offset(b), radius) {
            (None, None, Some(r)) => (
                centre_from_radius(s, e, r, clockwise).map_err(|m| (radius_col(), m))?,
                true,
            ),
            (None, None, None) => {
                return Err((
                    1,
                    format!(
                        "the arc (G2/G3 in force) gives neither its centre ({} {} in {}) nor its radius (R): some controls stop here, some move straight; write G1 for a straight move",
                        letters[a],
                        letters[b],
                        self.plane.code()
                    ),
                ));
            }
            (ia, ib, _) => {
                let (ia, ib) = (ia.unwrap_or(0.0), ib.unwrap_or(0.0));
                if self.absolute_centre {
                    ([ia, ib], false)
                } else {
                    ([s[0] + ia, s[1] + ib], false)
                }
            }
        };
        let rel = |p: [f64; 2]| [p[0] - centre[0], p[1] - centre[1]];
        let (rs, re) = (rel(s), rel(e));
        let (r0, r1) = (rs[0].hypot(rs[1]), re[0].hypot(re[1]));
        if !(r0.is_finite() && r1.is_finite()) || r0 == 0.0 || r1 == 0.0 {
            return Err((
                centre_col(),
                "the arc's start or end lies on its centre".into(),
            ));
        }
        let mismatched = |r0: f64, r1: f64| {
            let d = (r0 - r1).abs();
            d > RADIUS_MISMATCH_MM && d > RADIUS_MISMATCH_RELATIVE * r0.max(r1)
        };
        if !radius_given && mismatched(r0, r1) {
            // Some controls read I J K as the centre itself: say so where
            // that reading fits.
            let as_centre = [offset(a).unwrap_or(0.0), offset(b).unwrap_or(0.0)];
            let r = |p: [f64; 2]| (p[0] - as_centre[0]).hypot(p[1] - as_centre[1]);
            let hint = if !self.absolute_centre && !mismatched(r(s), r(e)) {
                " (read as the centre itself, as after G90.1, they fit: if this control reads them so, add G90.1)"
            } else {
                ""
            };
            return Err((
                centre_col(),
                format!(
                    "the arc's radius is {r0:.4} mm at its start and {r1:.4} mm at its end: its centre is not where {} {} put it{hint}",
                    letters[a], letters[b]
                ),
            ));
        }
        let (t0, t1) = (rs[1].atan2(rs[0]), re[1].atan2(re[0]));
        let tau = std::f64::consts::TAU;
        // The sweep in the direction of the move, in (0, 2π]: a move back
        // to its start is a full circle (given by its centre).
        let mut sweep = if clockwise { t0 - t1 } else { t1 - t0 }.rem_euclid(tau);
        let closed = (s[0] - e[0]).hypot(s[1] - e[1]) <= 1e-9 * (1.0 + r0);
        if closed {
            if radius_given {
                return Err((
                    radius_col(),
                    "a full circle cannot be given by its radius (R)".into(),
                ));
            }
            sweep = tau;
        } else if sweep == 0.0 {
            sweep = tau;
        }
        sweep += f64::from(turns - 1) * tau;
        let signed = if clockwise { -sweep } else { sweep };
        let r_max = r0.max(r1);
        let step = if tolerance_mm >= r_max {
            std::f64::consts::FRAC_PI_2
        } else {
            (2.0 * (1.0 - tolerance_mm / r_max).acos()).min(std::f64::consts::FRAC_PI_2)
        };
        let pieces = ((sweep / step).ceil() as usize).clamp(1, MAX_PIECES);
        let points = (1..=pieces)
            .map(|k| {
                let f = k as f64 / pieces as f64;
                if k == pieces {
                    return (1.0, end);
                }
                let t = t0 + f * signed;
                let r = r0 + f * (r1 - r0);
                let mut p = [0.0; 3];
                p[a] = centre[0] + r * t.cos();
                p[b] = centre[1] + r * t.sin();
                p[n] = start[n] + f * (end[n] - start[n]);
                (f, p)
            })
            .collect();
        Ok(points)
    }
}

/// The centre of the arc from `s` to `e` (plane coordinates, mm) of radius
/// `r` (mm; negative: the arc of more than half a turn), in the direction
/// `clockwise`.
fn centre_from_radius(
    s: [f64; 2],
    e: [f64; 2],
    r: f64,
    clockwise: bool,
) -> Result<[f64; 2], String> {
    let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
    let d = dx.hypot(dy);
    if d == 0.0 {
        return Err(
            "a full circle cannot be given by its radius (R): give its centre (I J K)".into(),
        );
    }
    if !(d.is_finite() && r.is_finite()) || r == 0.0 {
        return Err("an arc given by its radius needs a radius other than 0".into());
    }
    let half = 0.5 * d;
    let h2 = r * r - half * half;
    // A radius short of half the chord by no more than the tolerance of a
    // centre (the rounding of the words) is a half circle.
    let h = if h2 >= 0.0 {
        h2.sqrt()
    } else if half - r.abs() <= RADIUS_MISMATCH_MM.max(RADIUS_MISMATCH_RELATIVE * half) {
        0.0
    } else {
        return Err(format!(
            "the radius R {:.4} mm is shorter than half the distance to the end ({half:.4} mm)",
            r.abs()
        ));
    };
    // The centre lies left of the chord (seen along it) for a short arc
    // counter-clockwise, right of it for a short arc clockwise.
    let left = [-dy / d, dx / d];
    let side = if clockwise == (r > 0.0) { -1.0 } else { 1.0 };
    Ok([
        s[0] + half * dx / d + side * h * left[0],
        s[1] + half * dy / d + side * h * left[1],
    ])
}

/// Why a block that moves other than straight cannot be a pose in pose
/// mode, with the item to blame: always, unless it is an arc (`G2`/`G3`)
/// read as one (`arc`, [`super::ModalState::arcs_as_poses`]). Such an arc
/// holds the tool axis: rotary words or a tool vector in its block
/// (`is_rotary`) would turn it along the way, and a block the controller
/// may skip (`block_delete`) would take all its moves with it. `circular`:
/// the motion is a circular one (else a cycle, a thread or a spline);
/// `words`: the block's (address, value, item).
pub fn refusal_in_pose_mode<'a>(
    circular: bool,
    arc: bool,
    words: impl Iterator<Item = (&'a str, f64, usize)> + Clone,
    is_rotary: impl Fn(&str) -> bool,
    block_delete: Option<usize>,
) -> Option<(Option<usize>, String)> {
    let turns = |a: &str| is_rotary(a) || matches!(a, "A3" | "B3" | "C3");
    if arc {
        if let Some((address, value, item)) = words.clone().find(|w| turns(w.0)) {
            // `A3=0`, not `A30`.
            let eq = if address.len() > 1 { "=" } else { "" };
            return Some((
                Some(item),
                format!(
                    "`{}{eq}{}` gives the tool orientation in a circular move (G2/G3, CIP, CT) in pose mode: kinpost converts an arc with the tool axis held (that of the pose before) and takes no orientation in it; give the orientation in a straight move (G1) before the arc, or have the CAM system linearise it",
                    address, value
                ),
            ));
        }
        return block_delete.map(|item| {
            (
                Some(item),
                "a circular move (G2/G3) in pose mode in a block the controller may skip (`/`): kinpost writes it as several straight moves, which the block delete switch would not skip together; take the `/` off, or have the CAM system linearise the arc".into(),
            )
        });
    }
    let item = words
        .clone()
        .find(|w| matches!(w.0, "X" | "Y" | "Z") || is_rotary(w.0))
        .or(words.clone().find(|w| w.0 != "N"))
        .map(|w| w.2);
    let what = if circular {
        "circular interpolation (G2/G3; Sinumerik CIP, CT)"
    } else {
        "a canned cycle, a thread or a spline (G81–G89, G33, G5, Sinumerik ASPLINE, BSPLINE, CSPLINE, POLY)"
    };
    Some((
        item,
        format!(
            "{what} cannot be converted in pose mode here: tool poses must be straight G0/G1 moves (post, compensate, analyze and simulate convert G2/G3 arcs: run `kinpost post` first and this command on its output, or linearise the arcs in the CAM system)"
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_line;

    fn line(text: &str) -> Line {
        parse_line(text.as_bytes(), 1)
    }

    fn arc(
        modes_lines: &[&str],
        text: &str,
        start: [f64; 3],
        end: [f64; 3],
    ) -> Result<Vec<(f64, [f64; 3])>, ArcError> {
        let mut m = ArcModes::default();
        for l in modes_lines {
            m.apply(&line(l));
        }
        let l = line(text);
        m.apply(&l);
        m.points(&l, start, end, 1.0, 1e-4)
    }

    /// Every point lies on the circle about `c` (plane XY) and the points
    /// advance the way the arc turns.
    fn on_circle(points: &[(f64, [f64; 3])], c: [f64; 2], r: f64) {
        for (_, p) in points {
            let d = (p[0] - c[0]).hypot(p[1] - c[1]);
            assert!((d - r).abs() < 1e-9, "{p:?} is {d} from the centre");
        }
    }

    #[test]
    fn quarter_circles_both_ways_by_centre_and_by_radius() {
        // From (10, 0) to (0, 10) about the origin: counter-clockwise a
        // quarter turn through (7.07, 7.07); clockwise three quarters
        // through (-7.07, -7.07).
        let (s, e) = ([10.0, 0.0, 0.0], [0.0, 10.0, 0.0]);
        let ccw = arc(&[], "G3 X0 Y10 I-10 J0", s, e).unwrap();
        on_circle(&ccw, [0.0, 0.0], 10.0);
        let mid = ccw
            .iter()
            .min_by(|a, b| (a.0 - 0.5).abs().total_cmp(&(b.0 - 0.5).abs()))
            .unwrap();
        assert!(
            (mid.1[0] - 10.0 / 2f64.sqrt()).abs() < 1e-3 && mid.1[1] > 7.0,
            "{mid:?}"
        );
        let cw = arc(&[], "G2 X0 Y10 I-10 J0", s, e).unwrap();
        on_circle(&cw, [0.0, 0.0], 10.0);
        let mid = cw
            .iter()
            .min_by(|a, b| (a.0 - 0.5).abs().total_cmp(&(b.0 - 0.5).abs()))
            .unwrap();
        assert!(mid.1[0] < -7.0 && mid.1[1] < -7.0, "{mid:?}");
        // The same arcs by radius: R10 the short one, R-10 the long one.
        let short = arc(&[], "G3 X0 Y10 R10", s, e).unwrap();
        on_circle(&short, [0.0, 0.0], 10.0);
        let long = arc(&[], "G2 X0 Y10 R-10", s, e).unwrap();
        on_circle(&long, [0.0, 0.0], 10.0);
        assert_eq!(long.len(), cw.len());
        // Pieces: no chord more than 0.1 µm from the arc.
        let sagitta = |n: usize, sweep: f64| 10.0 * (1.0 - (sweep / n as f64 / 2.0).cos());
        assert!(sagitta(ccw.len(), std::f64::consts::FRAC_PI_2) <= 1e-4);
        assert_eq!(ccw.last().unwrap(), &(1.0, e));
    }

    #[test]
    fn planes_helices_full_turns_and_absolute_centres() {
        // G18: Z is the first axis, X the second (Z × X = Y); seen from +Y
        // (RS274), G3 turns counter-clockwise, from Z=10 to X=10 (centre
        // at the origin) a quarter turn through Z = X = 7.07, and G2 the
        // three quarters the other way, through Z = X = -7.07.
        let (s, e) = ([0.0, 0.0, 10.0], [10.0, 0.0, 0.0]);
        let p = arc(&["G18"], "G3 X10 Z0 I0 K-10", s, e).unwrap();
        let mid = p[p.len() / 2].1;
        assert!(mid[0] > 7.0 && mid[2] > 7.0, "{mid:?}");
        let p = arc(&["G18"], "G2 X10 Z0 I0 K-10", s, e).unwrap();
        let mid = p[p.len() / 2].1;
        assert!(mid[0] < -7.0 && mid[2] < -7.0, "{mid:?}");
        // G19: Y first, Z second (Y × Z = X).
        let p = arc(
            &["G19"],
            "G3 Y0 Z10 J-10 K0",
            [0.0, 10.0, 0.0],
            [0.0, 0.0, 10.0],
        )
        .unwrap();
        let mid = p[p.len() / 2].1;
        assert!(mid[1] > 7.0 && mid[2] > 7.0, "{mid:?}");
        // A helix: two full turns with P2, Z down 4 mm evenly.
        let h = arc(
            &[],
            "G3 X10 Y0 Z-4 I-10 J0 P2",
            [10.0, 0.0, 0.0],
            [10.0, 0.0, -4.0],
        )
        .unwrap();
        on_circle(&h, [0.0, 0.0], 10.0);
        for (f, p) in &h {
            let turned = (f * 2.0 * std::f64::consts::TAU).rem_euclid(std::f64::consts::TAU);
            let at = p[1].atan2(p[0]).rem_euclid(std::f64::consts::TAU);
            let off = (turned - at).abs();
            assert!(off.min(std::f64::consts::TAU - off) < 1e-9, "{f}: {p:?}");
            assert!((p[2] + 4.0 * f).abs() < 1e-12, "{f}: {p:?}");
        }
        // G90.1: I J are the centre itself.
        let abs = arc(
            &["G90.1"],
            "G3 X20 Y10 I10 J10",
            [10.0, 0.0, 0.0],
            [20.0, 10.0, 0.0],
        )
        .unwrap();
        on_circle(&abs, [10.0, 10.0], 10.0);
    }

    #[test]
    fn arcs_not_followed_are_refused_at_their_word() {
        let s = [10.0, 0.0, 0.0];
        let e = [0.0, 10.0, 0.0];
        for (text, col, says) in [
            ("G3 X0 Y10 I-9 J0", 11, "radius"),
            ("G3 X0 Y10", 1, "neither"),
            ("G3 X0 Y10 R2", 11, "shorter"),
            ("G3 X0 Y10 CR=-10 AR=270", 18, "AR"),
            ("CIP X0 Y10 I1=5 J1=5", 1, "CIP"),
            ("G3 X0 Y10 I-10 J0 P0", 19, "turns"),
        ] {
            let err = arc(&[], text, s, e).unwrap_err();
            assert_eq!(err.0, col, "{text}: {err:?}");
            assert!(err.1.contains(says), "{text}: {err:?}");
        }
        let err = arc(&[], "G2 X10 Y0 R5", s, s).unwrap_err();
        assert!(err.1.contains("full circle"), "{err:?}");
        // A centre that fits as absolute coordinates is pointed out.
        let err = arc(&[], "G3 X1 Y10 I1 J1", [10.0, 1.0, 0.0], [1.0, 10.0, 0.0]).unwrap_err();
        assert!(err.1.contains("G90.1"), "{err:?}");
    }

    #[test]
    fn sinumerik_turns_and_a_radius_rounded_short_of_half_the_chord() {
        // TURN=1: one full turn added, as P2.
        let s = [10.0, 0.0, 0.0];
        let end = [10.0, 0.0, -4.0];
        let turn = arc(&[], "G3 X10 Y0 Z-4 I-10 J0 TURN=1", s, end).unwrap();
        let p2 = arc(&[], "G3 X10 Y0 Z-4 I-10 J0 P2", s, end).unwrap();
        assert_eq!(turn, p2);
        // R written to four decimals, 0.00005 short of half the chord: the
        // half circle about the chord's middle, clockwise through (0, -10).
        let half = arc(&[], "G2 X-10 Y0 R9.99995", s, [-10.0, 0.0, 0.0]).unwrap();
        on_circle(&half[..half.len() - 1], [0.0, 0.0], 10.0);
        let low = half.iter().map(|p| p.1[1]).fold(f64::INFINITY, f64::min);
        assert!((low + 10.0).abs() < 1e-6, "lowest Y {low}");
    }
}
