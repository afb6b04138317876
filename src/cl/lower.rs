//! Lowering of APT CL constructs that real CAM systems write (`CIRCLE/`,
//! `CYCLE/`, `CSYS/`, `CUTCOM/`, `LOAD/TOOL`, `SELECT/TOOL`, `UNIT/`,
//! surface-speed `SPINDL`, `DELAY`, `STOP`, `FROM`, `GODLTA`) into the
//! plain statements the converter writes: tool-tip `GOTO`s in the set-up
//! frame, `RAPID`, `FEDRAT`, literal blocks ([`ClStatement::Block`]) and
//! warnings ([`ClStatement::Warning`]).
//!
//! Conventions (docs/programs.md, "APT CL"):
//! - `CSYS/r11,r12,r13,tx,r21,r22,r23,ty,r31,r32,r33,tz` gives the set-up
//!   frame in the CL frame: the columns of `R` are the set-up's axes and
//!   `t` its origin. Positions and tool axes that follow are written in the
//!   set-up frame: `p' = Rᵀ (p − t)`, `a' = Rᵀ a`.
//! - `CIRCLE/xc,yc,zc,i,j,k[,r,...]` followed by `GOTO`: an arc from the
//!   current position to the `GOTO` point, counter-clockwise about
//!   `(i,j,k)` (right-hand rule); an end point equal to the start is a full
//!   circle; an axial difference makes a helix. It is linearised within the
//!   chord tolerance (1 µm).
//! - `CYCLE/...` then `GOTO`s: every `GOTO` is a hole whose top is the
//!   point; `RAPTO` and `RTRCTO` are distances above it along the tool axis,
//!   `FEDTO` the depth below it. The hole is expanded into moves.

use std::collections::{BTreeMap, VecDeque};

use super::{Arg, ClRecord, ClStatement, ClUnits, FeedUnit, split_args};
use crate::error::{Error, Location};

/// Default chord tolerance of linearised arcs, mm.
pub const DEFAULT_ARC_TOLERANCE_MM: f64 = 1e-3;

/// Largest feed accepted, mm/min (per minute) or mm/rev (per revolution).
const MAX_FEED_MM_MIN: f64 = 1e6;
const MAX_FEED_MM_REV: f64 = 100.0;

/// Majors that move the tool or change how it moves. One that reaches the
/// end of lowering unconverted is refused, never commented.
pub const MOTION_MAJORS: &[&str] = &[
    "GOTO", "GODLTA", "GOHOME", "FROM", "CIRCLE", "MOVARC", "CYCLE", "CUTCOM", "CSYS", "TRNTYP",
    "TLAXIS", "MULTAX", "RAPID", "FEDRAT", "SPINDL", "LOAD", "LOADTL", "SELECT", "TURRET", "UNITS",
    "UNIT", "DELAY", "STOP", "OPSTOP", "INDIRV", "INDIRP", "GOFWD", "GOLFT", "GORGT", "GOBACK",
    "GOUP", "GODOWN", "TLON", "TLLFT", "TLRGT", "PSIS", "ROTABL", "ROTATE", "ROTHED", "HEAD",
    "ORIGIN", "TRANS", "REFSYS", "MATRIX", "COPY", "INDEX", "TRACUT", "ARCSLP", "THREAD", "MODE",
    "PITCH", "CLAMP", "COOLNT",
];

#[derive(Debug, Clone, Copy, PartialEq)]
enum CycleKind {
    Drill,
    Deep,
    BrkChp,
    Bore,
}

#[derive(Debug, Clone)]
struct Cycle {
    kind: CycleKind,
    depth: f64,
    rapto: f64,
    rtrcto: f64,
    feed: Option<(f64, FeedUnit)>,
    dwell: f64,
    first_peck: f64,
    sub_peck: f64,
}

#[derive(Debug, Clone)]
struct Circle {
    center: [f64; 3],
    normal: [f64; 3],
    radius: Option<f64>,
}

/// The lowering iterator: wraps a [`super::ClReader`] (or any iterator of
/// records) and yields records the converter writes directly.
#[derive(Debug)]
pub struct Lowered<I> {
    inner: I,
    file: String,
    out: VecDeque<ClRecord>,
    finished: bool,
    tol_mm: f64,
    mm_per_unit: f64,
    units_seen: bool,
    warned_units: bool,
    csys: Option<([[f64; 3]; 3], [f64; 3])>,
    pos: Option<[f64; 3]>,
    axis: [f64; 3],
    circle: Option<Circle>,
    cycle: Option<Cycle>,
    feed: Option<(f64, FeedUnit)>,
    tool: Option<u32>,
    per_rev: bool,
    commented: BTreeMap<String, usize>,
}

/// Lowers the records of `inner` (see the module documentation); arcs are
/// linearised within `arc_tolerance_mm`.
///
/// `default_units`: the units of a program without `UNITS` (`None`:
/// millimetres, with a warning at the first motion).
pub fn lower<I: Iterator<Item = Result<ClRecord, Error>>>(
    inner: I,
    file: impl Into<String>,
    arc_tolerance_mm: f64,
    default_units: Option<ClUnits>,
) -> Lowered<I> {
    let mut out = VecDeque::new();
    if let Some(u) = default_units {
        out.push_back(ClRecord {
            line: 0,
            col: 0,
            text: b"UNITS (--units)".to_vec(),
            statement: ClStatement::Units(u),
        });
    }
    Lowered {
        inner,
        file: file.into(),
        out,
        finished: false,
        tol_mm: arc_tolerance_mm.max(1e-9),
        mm_per_unit: match default_units {
            Some(ClUnits::Inches) => 25.4,
            _ => 1.0,
        },
        units_seen: default_units.is_some(),
        warned_units: false,
        csys: None,
        pos: None,
        axis: [0.0, 0.0, 1.0],
        circle: None,
        cycle: None,
        feed: None,
        tool: None,
        per_rev: false,
        commented: BTreeMap::new(),
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Whether the feed in `unit` (after units) is absurd.
fn absurd_feed(value: f64, unit: FeedUnit, mm_per_unit: f64) -> bool {
    match unit {
        FeedUnit::Mmpm => value > MAX_FEED_MM_MIN,
        FeedUnit::Ipm => value * 25.4 > MAX_FEED_MM_MIN,
        FeedUnit::Unspecified => value * mm_per_unit > MAX_FEED_MM_MIN,
        FeedUnit::Mmpr => value > MAX_FEED_MM_REV,
        FeedUnit::Ipr => value * 25.4 > MAX_FEED_MM_REV,
    }
}

/// Formats a number for a literal block: at most 4 decimals, no trailing
/// zeros.
fn num(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

impl<I: Iterator<Item = Result<ClRecord, Error>>> Lowered<I> {
    fn err(&self, r: &ClRecord, message: impl Into<String>) -> Error {
        Error::input_with(
            Location::new(self.file.clone(), r.line, r.col),
            message,
            String::from_utf8_lossy(&r.text).trim().to_string(),
        )
    }

    fn emit(&mut self, r: &ClRecord, statement: ClStatement) {
        self.out.push_back(ClRecord {
            line: r.line,
            col: r.col,
            text: r.text.clone(),
            statement,
        });
    }

    fn block(&mut self, r: &ClRecord, b: impl Into<String>) {
        self.emit(r, ClStatement::Block(b.into()));
    }

    /// Emits a move to `tip` (CL frame) with the current tool axis.
    fn go(&mut self, r: &ClRecord, tip: [f64; 3], rapid: bool) {
        if rapid {
            self.emit(r, ClStatement::Rapid);
        }
        let (t, a) = match &self.csys {
            Some((m, o)) => {
                let d = sub(tip, *o);
                let rt = |v: [f64; 3]| {
                    [
                        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
                        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
                        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
                    ]
                };
                (rt(d), rt(self.axis))
            }
            None => (tip, self.axis),
        };
        self.emit(
            r,
            ClStatement::Goto {
                tip: t,
                axis: Some(a),
            },
        );
        self.pos = Some(tip);
    }

    /// A feed: per revolution as `G95` and the value in mm/rev, back to
    /// per minute as `G94`.
    fn feed_record(&mut self, r: &ClRecord, value: f64, unit: FeedUnit) {
        let per_rev = matches!(unit, FeedUnit::Mmpr | FeedUnit::Ipr);
        if per_rev != self.per_rev {
            self.per_rev = per_rev;
            self.block(r, if per_rev { "G95" } else { "G94" });
        }
        let (value, unit) = match unit {
            FeedUnit::Mmpr => (value, FeedUnit::Mmpm),
            FeedUnit::Ipr => (value * 25.4, FeedUnit::Mmpm),
            u => (value, u),
        };
        self.emit(r, ClStatement::Fedrat { value, unit });
    }

    fn numbers(&self, r: &ClRecord, args: &[Arg], what: &str) -> Result<Vec<f64>, Error> {
        args.iter()
            .map(|a| {
                a.number().ok_or_else(|| {
                    self.err(
                        r,
                        format!(
                            "{what}: expected a finite number, found `{}`",
                            String::from_utf8_lossy(a.text)
                        ),
                    )
                })
            })
            .collect()
    }

    fn goto(&mut self, r: &ClRecord, tip: [f64; 3], axis: Option<[f64; 3]>) -> Result<(), Error> {
        if !self.units_seen && !self.warned_units {
            self.warned_units = true;
            self.emit(
                r,
                ClStatement::Warning(format!(
                    "{}:{}:{}: no UNITS statement before the first motion: millimetres assumed",
                    self.file, r.line, r.col
                )),
            );
        }
        let from_axis = self.axis;
        if let Some(a) = axis {
            self.axis = a;
        }
        if let Some(c) = self.circle.take() {
            return self.arc(r, c, tip, from_axis);
        }
        if let Some(c) = self.cycle.clone() {
            return self.hole(r, &c, tip);
        }
        self.go(r, tip, false);
        Ok(())
    }

    /// The arc from the current point to `end`; the tool axis turns from
    /// `from_axis` to the current one in proportion to the angle.
    fn arc(
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
        let slack = 1e-3 / self.mm_per_unit;
        if r0 < tol {
            return Err(self.err(
                r,
                "arc (CIRCLE) starts at its centre: expected a start point on the circle",
            ));
        }
        if (r0 - r1).abs() > slack {
            return Err(self.err(r, format!("arc (CIRCLE) end point is {} from the centre but the start is {}: not on one circle", num(r1), num(r0))));
        }
        if let Some(rad) = c.radius
            && (rad - r0).abs() > slack
        {
            return Err(self.err(
                r,
                format!(
                    "arc (CIRCLE) radius {} but the start point is {} from the centre",
                    num(rad),
                    num(r0)
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
        Ok(())
    }

    fn hole(&mut self, r: &ClRecord, c: &Cycle, top: [f64; 3]) -> Result<(), Error> {
        let na = norm(self.axis);
        let a = scale(self.axis, 1.0 / na);
        let at = |d: f64| add(top, scale(a, d));
        let clear = at(c.rtrcto);
        let r_plane = at(c.rapto);
        // Rapid above the hole at the retract level, then down to RAPTO.
        let here = self.pos;
        if here.is_none_or(|p| norm(sub(p, clear)) > 1e-9) {
            self.go(r, clear, true);
        }
        self.go(r, r_plane, true);
        let old_feed = self.feed;
        if let Some((f, u)) = c.feed {
            self.feed_record(r, f, u);
        }
        let bottom = -c.depth;
        match c.kind {
            CycleKind::Deep | CycleKind::BrkChp if c.first_peck > 0.0 => {
                let mut reached = c.rapto.min(0.0);
                let mut peck = c.first_peck;
                loop {
                    let target = (reached.min(0.0) - peck).max(bottom);
                    if reached < 0.0 {
                        // Back down to just above the last depth.
                        let back = (reached + 0.5_f64.min(c.rapto.max(0.0))).min(c.rapto);
                        self.go(r, at(back), true);
                    }
                    self.go(r, at(target), false);
                    reached = target;
                    if target <= bottom {
                        break;
                    }
                    let up = if c.kind == CycleKind::Deep {
                        c.rapto
                    } else {
                        (target + 0.5).min(c.rapto)
                    };
                    self.go(r, at(up), true);
                    peck = if c.sub_peck > 0.0 {
                        c.sub_peck
                    } else {
                        c.first_peck
                    };
                }
            }
            _ => self.go(r, at(bottom), false),
        }
        if c.dwell > 0.0 {
            self.block(r, format!("G4 P{}", num(c.dwell)));
        }
        if c.kind == CycleKind::Bore {
            self.go(r, r_plane, false);
        }
        self.go(r, clear, true);
        if let Some((f, u)) = old_feed
            && c.feed.is_some()
        {
            self.feed_record(r, f, u);
        }
        Ok(())
    }

    fn cycle(&mut self, r: &ClRecord, args: &[Arg]) -> Result<(), Error> {
        let Some(first) = args.first() else {
            return Err(self.err(
                r,
                "CYCLE expects a cycle type (DRILL, DEEP, BRKCHP, BORE, REAM, OFF, ...)",
            ));
        };
        let kind = match first.upper().as_str() {
            "OFF" => {
                self.cycle = None;
                self.block(r, "(CYCLE/OFF)");
                return Ok(());
            }
            "INIT" | "ON" => {
                self.block(r, format!("({})", String::from_utf8_lossy(&r.text).trim()));
                return Ok(());
            }
            "DRILL" | "FACE" | "CSINK" | "SPOT" => CycleKind::Drill,
            "DEEP" | "DEEP2" => CycleKind::Deep,
            "BRKCHP" => CycleKind::BrkChp,
            "BORE" | "REAM" => CycleKind::Bore,
            other => {
                return Err(self.err(r, format!("CYCLE/{other} is not supported (expanded cycles: DRILL, FACE, CSINK, SPOT, DEEP, DEEP2, BRKCHP, BORE, REAM); the program is refused rather than drilling wrongly")));
            }
        };
        let mut c = Cycle {
            kind,
            depth: f64::NAN,
            rapto: 0.0,
            rtrcto: f64::NAN,
            feed: None,
            dwell: 0.0,
            first_peck: 0.0,
            sub_peck: 0.0,
        };
        let mut k = 1;
        let mut loose = Vec::new();
        while k < args.len() {
            let w = args[k].upper();
            let val = |k: usize| -> Result<f64, Error> {
                args.get(k)
                    .and_then(|a| a.number())
                    .ok_or_else(|| self.err(r, format!("CYCLE: expected a number after {w}")))
            };
            match w.as_str() {
                "FEDTO" | "DEPTH" => c.depth = val(k + 1)?,
                "RAPTO" | "CLEAR" => c.rapto = val(k + 1)?,
                "RTRCTO" => c.rtrcto = val(k + 1)?,
                "DWELL" => c.dwell = val(k + 1)?,
                "1STPECK" | "STEP" => c.first_peck = val(k + 1)?,
                "SUBPECK" => c.sub_peck = val(k + 1)?,
                "MMPM" | "IPM" | "MMPR" | "IPR" => {
                    let u = super::feed_unit(&args[k]).unwrap_or(FeedUnit::Unspecified);
                    let f = val(k + 1)?;
                    if f < 0.0 || absurd_feed(f, u, self.mm_per_unit) {
                        return Err(
                            self.err(r, format!("CYCLE feed {} {w} is out of range", num(f)))
                        );
                    }
                    c.feed = Some((f, u));
                }
                _ => {
                    if args[k].number().is_some() {
                        loose.push(args[k].number().unwrap_or(0.0));
                        k += 1;
                        continue;
                    }
                    return Err(self.err(r, format!("CYCLE: unknown word {w}")));
                }
            }
            k += 2;
        }
        // The classic APT form: CYCLE/DRILL,depth,MMPM,f,clearance.
        if c.depth.is_nan()
            && let Some(&d) = loose.first()
        {
            c.depth = d;
            if let Some(&cl) = loose.get(1) {
                c.rapto = cl;
            }
        }
        if c.depth.is_nan() || c.depth < 0.0 {
            return Err(self.err(r, "CYCLE: expected a depth (FEDTO,d) that is not negative"));
        }
        if c.rtrcto.is_nan() {
            c.rtrcto = c.rapto;
        }
        if c.first_peck < 0.0 || c.sub_peck < 0.0 {
            return Err(self.err(r, "CYCLE: peck depths must not be negative"));
        }
        if c.kind == CycleKind::Deep && c.first_peck == 0.0 {
            c.first_peck = c.depth.max(1e-3);
        }
        self.block(r, format!("({})", String::from_utf8_lossy(&r.text).trim()));
        self.cycle = Some(c);
        Ok(())
    }

    fn other(&mut self, r: &ClRecord, major: &str, text: &str) -> Result<(), Error> {
        let args = split_args(text.as_bytes(), 0);
        let a = |k: usize| args.get(k).map(|a| a.upper()).unwrap_or_default();
        match major {
            "UNIT" => match a(0).as_str() {
                "MM" => {
                    self.units_seen = true;
                    self.mm_per_unit = 1.0;
                    self.emit(r, ClStatement::Units(ClUnits::Mm));
                }
                "INCHES" | "INCH" => {
                    self.units_seen = true;
                    self.mm_per_unit = 25.4;
                    self.emit(r, ClStatement::Units(ClUnits::Inches));
                }
                w => {
                    return Err(
                        self.err(r, format!("expected UNIT/MM or UNIT/INCHES, found `{w}`"))
                    );
                }
            },
            "CIRCLE" => {
                let v = self.numbers(r, &args, "CIRCLE")?;
                if v.len() < 6 {
                    return Err(self.err(r, "CIRCLE expects xc,yc,zc,i,j,k[,r,...]"));
                }
                let normal = [v[3], v[4], v[5]];
                if norm(normal) < 1e-12 {
                    return Err(self.err(r, "CIRCLE axis has zero length"));
                }
                self.circle = Some(Circle {
                    center: [v[0], v[1], v[2]],
                    normal,
                    radius: v.get(6).copied().filter(|&x| x > 0.0),
                });
            }
            "CYCLE" => self.cycle(r, &args)?,
            "CSYS" => {
                let v = self.numbers(r, &args, "CSYS")?;
                if v.len() != 12 {
                    return Err(self.err(r, "CSYS expects 12 numbers (a 3×4 matrix, row by row)"));
                }
                let m = [[v[0], v[1], v[2]], [v[4], v[5], v[6]], [v[8], v[9], v[10]]];
                // Orthonormal within 1e-6.
                for i in 0..3 {
                    for j in 0..3 {
                        let c = (0..3).map(|k| m[k][i] * m[k][j]).sum::<f64>();
                        let want = if i == j { 1.0 } else { 0.0 };
                        if (c - want).abs() > 1e-6 {
                            return Err(self.err(
                                r,
                                "CSYS rotation part is not orthonormal: expected a rigid transform",
                            ));
                        }
                    }
                }
                let ident = (0..3).all(|i| {
                    (0..3).all(|j| (m[i][j] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12)
                }) && v[3] == 0.0
                    && v[7] == 0.0
                    && v[11] == 0.0;
                self.csys = if ident {
                    None
                } else {
                    Some((m, [v[3], v[7], v[11]]))
                };
                self.block(r, format!("({})", String::from_utf8_lossy(&r.text).trim()));
            }
            "TRNTYP" => {
                if a(0) != "WORLD" {
                    return Err(
                        self.err(r, format!("TRNTYP/{} is not supported (only WORLD)", a(0)))
                    );
                }
                self.block(r, format!("({})", String::from_utf8_lossy(&r.text).trim()));
            }
            "CUTCOM" => match a(0).as_str() {
                "LEFT" | "RIGHT" => {
                    let g = if a(0) == "LEFT" { "G41" } else { "G42" };
                    match self.tool {
                        Some(t) => self.block(r, format!("{g} D{t}")),
                        None => self.block(r, g),
                    }
                }
                "OFF" => self.block(r, "G40"),
                w => {
                    return Err(
                        self.err(r, format!("CUTCOM/{w} is not supported (LEFT, RIGHT, OFF)"))
                    );
                }
            },
            "LOAD" | "SELECT" => {
                if a(0) != "TOOL" {
                    return Err(self.err(
                        r,
                        format!(
                            "{major}/{} is not supported (expected {major}/TOOL,n)",
                            a(0)
                        ),
                    ));
                }
                let n = args
                    .get(1)
                    .and_then(|x| x.number())
                    .filter(|n| *n >= 0.0 && n.fract() == 0.0 && *n < 1e9);
                let Some(n) = n else {
                    return Err(self.err(r, format!("{major}/TOOL expects a whole tool number")));
                };
                let n = n as u32;
                if major == "SELECT" {
                    self.block(r, format!("T{n}"));
                } else {
                    let mut h = n;
                    if a(2) == "ADJUST"
                        && let Some(x) = args.get(3).and_then(|x| x.number())
                    {
                        h = x.max(0.0) as u32;
                    }
                    self.tool = Some(n);
                    self.block(r, format!("T{n} M6"));
                    self.block(r, format!("G43 H{h}"));
                }
            }
            "SPINDL" => {
                // Surface speed: SPINDL/SFM|SMM,v[,CLW|CCLW] or v,SFM|SMM,...
                let mut m = "M3";
                let mut speed = None;
                let mut per_ft = false;
                for (k, x) in args.iter().enumerate() {
                    match x.upper().as_str() {
                        "SMM" | "SFM" => {
                            per_ft = x.is("SFM");
                            if speed.is_none() {
                                speed = args.get(k + 1).and_then(|y| y.number());
                            }
                        }
                        "CLW" => m = "M3",
                        "CCLW" => m = "M4",
                        _ => {
                            if k == 0 {
                                speed = x.number();
                            }
                        }
                    }
                }
                let surface = args.iter().any(|x| x.is("SMM") || x.is("SFM"));
                match speed {
                    Some(s) if surface && s >= 0.0 => {
                        let mpm = if per_ft { s * 0.3048 } else { s };
                        self.block(r, format!("G96 S{} {m}", num(mpm)));
                    }
                    _ => return Err(self.err(r, "SPINDL form not understood: expected n,RPM,CLW | RPM,n,CCLW | SMM,v | SFM,v | ON | OFF")),
                }
            }
            "DELAY" => {
                let t = args.first().and_then(|x| x.number()).filter(|t| *t >= 0.0);
                let Some(t) = t else {
                    return Err(self.err(r, "DELAY expects a time in seconds"));
                };
                self.block(r, format!("G4 P{}", num(t)));
            }
            "STOP" => self.block(r, "M0"),
            "OPSTOP" => self.block(r, "M1"),
            "FROM" => {
                let v = self.numbers(r, &args, "FROM")?;
                if v.len() != 3 && v.len() != 6 {
                    return Err(self.err(r, "FROM expects x,y,z[,i,j,k]"));
                }
                if v.len() == 6 {
                    self.axis = [v[3], v[4], v[5]];
                }
                self.go(r, [v[0], v[1], v[2]], true);
            }
            "GODLTA" => {
                let v = self.numbers(r, &args, "GODLTA")?;
                let Some(p) = self.pos else {
                    return Err(self.err(r, "GODLTA with no current position"));
                };
                let d = match v.len() {
                    3 => [v[0], v[1], v[2]],
                    1 => scale(self.axis, v[0] / norm(self.axis)),
                    _ => {
                        return Err(self.err(
                            r,
                            "GODLTA expects dx,dy,dz or a distance along the tool axis",
                        ));
                    }
                };
                self.goto(r, add(p, d), None)?;
            }
            _ if MOTION_MAJORS.contains(&major) => {
                return Err(self.err(r, format!("{major} moves the tool or changes how it moves and kinpost does not convert it; refused rather than kept as a comment")));
            }
            _ => {
                *self.commented.entry(major.to_string()).or_default() += 1;
                self.emit(
                    r,
                    ClStatement::Other {
                        major: major.to_string(),
                        text: text.to_string(),
                    },
                );
            }
        }
        Ok(())
    }

    fn step(&mut self, r: ClRecord) -> Result<(), Error> {
        if self.circle.is_some()
            && !matches!(
                r.statement,
                ClStatement::Goto { .. } | ClStatement::Fedrat { .. } | ClStatement::Comment(_)
            )
        {
            return Err(self.err(&r, "CIRCLE must be followed by the GOTO that ends the arc"));
        }
        match &r.statement {
            ClStatement::Goto { tip, axis } => self.goto(&r, *tip, *axis)?,
            ClStatement::TlAxis(a) => {
                self.axis = *a;
            }
            ClStatement::Fedrat { value, unit } => {
                if absurd_feed(*value, *unit, self.mm_per_unit) {
                    return Err(self.err(&r, format!("feed rate {value:e} is absurd (more than {MAX_FEED_MM_MIN} mm/min or {MAX_FEED_MM_REV} mm/rev)")));
                }
                self.feed = Some((*value, *unit));
                self.feed_record(&r, *value, *unit);
            }
            ClStatement::Units(u) => {
                self.units_seen = true;
                self.mm_per_unit = match u {
                    ClUnits::Mm => 1.0,
                    ClUnits::Inches => 25.4,
                };
                self.out.push_back(r);
            }
            ClStatement::LoadTl(n) => {
                self.tool = Some(*n);
                self.out.push_back(r);
            }
            ClStatement::Other { major, text } => {
                let (major, text) = (major.clone(), text.clone());
                self.other(&r, &major, &text)?;
            }
            ClStatement::Multax(_) => {
                *self.commented.entry("MULTAX".into()).or_default() += 1;
                self.out.push_back(r);
            }
            _ => self.out.push_back(r),
        }
        Ok(())
    }

    fn summary(&mut self) {
        if self.commented.is_empty() {
            return;
        }
        let total: usize = self.commented.values().sum();
        let list: Vec<String> = self
            .commented
            .iter()
            .map(|(m, n)| format!("{m} {n}"))
            .collect();
        let w = format!(
            "{}: {total} CL statement{} that do not move the tool kept as comments ({})",
            self.file,
            if total == 1 { "" } else { "s" },
            list.join(", ")
        );
        self.out.push_back(ClRecord {
            line: 0,
            col: 0,
            text: Vec::new(),
            statement: ClStatement::Warning(w),
        });
    }
}

impl<I: Iterator<Item = Result<ClRecord, Error>>> Iterator for Lowered<I> {
    type Item = Result<ClRecord, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(r) = self.out.pop_front() {
                return Some(Ok(r));
            }
            if self.finished {
                return None;
            }
            match self.inner.next() {
                Some(Ok(r)) => {
                    if let Err(e) = self.step(r) {
                        self.finished = true;
                        self.out.clear();
                        return Some(Err(e));
                    }
                }
                Some(Err(e)) => return Some(Err(e)),
                None => {
                    self.finished = true;
                    self.summary();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cl::ClReader;

    fn run(text: &str) -> Result<Vec<ClStatement>, Error> {
        lower(ClReader::new(text.as_bytes(), "t.apt"), "t.apt", 1e-3, None)
            .map(|r| r.map(|r| r.statement))
            .collect()
    }

    fn gotos(s: &[ClStatement]) -> Vec<[f64; 3]> {
        s.iter()
            .filter_map(|s| match s {
                ClStatement::Goto { tip, .. } => Some(*tip),
                _ => None,
            })
            .collect()
    }

    fn blocks(s: &[ClStatement]) -> Vec<String> {
        s.iter()
            .filter_map(|s| match s {
                ClStatement::Block(b) => Some(b.clone()),
                _ => None,
            })
            .collect()
    }

    fn near(a: [f64; 3], b: [f64; 3]) -> bool {
        norm(sub(a, b)) < 1e-9
    }

    #[test]
    fn spindle_forms() {
        let s = run("SPINDL/12000,RPM,CLW\nSPINDL/RPM,800,CCLW\nSPINDL/SMM,200,CLW\nSPINDL/SFM,100,CCLW\nSPINDL/OFF\n").unwrap();
        assert!(matches!(
            s[0],
            ClStatement::Spindle {
                rpm: Some(12000.0),
                dir: Some(crate::cl::SpindleDir::Clockwise),
                off: false
            }
        ));
        assert!(matches!(
            s[1],
            ClStatement::Spindle {
                rpm: Some(800.0),
                dir: Some(crate::cl::SpindleDir::CounterClockwise),
                off: false
            }
        ));
        assert_eq!(blocks(&s), ["G96 S200 M3", "G96 S30.48 M4"]);
        assert!(matches!(s[4], ClStatement::Spindle { off: true, .. }));
    }

    #[test]
    fn tools_and_cutcom() {
        let s =
            run("LOAD/TOOL,3,ADJUST,13\nSELECT/TOOL,4\nCUTCOM/LEFT\nCUTCOM/RIGHT\nCUTCOM/OFF\n")
                .unwrap();
        assert_eq!(
            blocks(&s),
            ["T3 M6", "G43 H13", "T4", "G41 D3", "G42 D3", "G40"]
        );
    }

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
        let axes: Vec<[f64; 3]> = s
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

    #[test]
    fn bad_circles_are_refused() {
        let e = run("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,11,0\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:4:1"), "{e}");
        let e = run("UNITS/MM\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10,0\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:3:1"), "{e}");
    }

    /// A hole: rapid to the retract level and to RAPTO, feed to FEDTO,
    /// back to the retract level; pecks for DEEP.
    #[test]
    fn cycle_holes_are_expanded() {
        let s = run("UNITS/MM\nGOTO/0,0,30\nCYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,2,RTRCTO,30,DWELL,1\nGOTO/5,5,0\nCYCLE/OFF\nGOTO/0,0,30\n").unwrap();
        let g = gotos(&s);
        let want = [
            [0.0, 0.0, 30.0],
            [5.0, 5.0, 30.0],
            [5.0, 5.0, 2.0],
            [5.0, 5.0, -5.0],
            [5.0, 5.0, 30.0],
            [0.0, 0.0, 30.0],
        ];
        assert_eq!(g.len(), want.len());
        for (a, b) in g.iter().zip(want) {
            assert!(near(*a, b), "{g:?}");
        }
        assert!(blocks(&s).contains(&"G4 P1".to_string()));
        let s =
            run("UNITS/MM\nCYCLE/DEEP,FEDTO,10,1STPECK,4,MMPM,100,RAPTO,2,RTRCTO,20\nGOTO/0,0,0\n")
                .unwrap();
        let z: Vec<f64> = gotos(&s).iter().map(|p| p[2]).collect();
        assert_eq!(z.iter().cloned().fold(f64::INFINITY, f64::min), -10.0);
        assert!(z.contains(&-4.0) && z.contains(&-8.0), "{z:?}");
        let e = run("CYCLE/TAP,FEDTO,5\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:1:1"));
    }

    /// CSYS: the set-up frame's axes are the matrix columns, its origin the
    /// last column; points become `Rᵀ (p − t)`.
    #[test]
    fn csys_translation_and_rotation() {
        let s = run("UNITS/MM\nCSYS/1,0,0,10,0,1,0,20,0,0,1,30\nGOTO/11,22,33\n").unwrap();
        assert!(near(gotos(&s)[0], [1.0, 2.0, 3.0]));
        // Set-up X along CL -Z, Z along CL +X (a quarter turn about Y).
        let s = run("UNITS/MM\nCSYS/0,0,1,0,0,1,0,0,-1,0,0,0\nGOTO/250,5,-12,1,0,0\n").unwrap();
        match &s[2] {
            ClStatement::Goto { tip, axis } => {
                assert!(near(*tip, [12.0, 5.0, 250.0]), "{tip:?}");
                assert!(near(axis.unwrap(), [0.0, 0.0, 1.0]));
            }
            other => panic!("{other:?}"),
        }
        let e = run("CSYS/2,0,0,0,0,1,0,0,0,0,1,0\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:1:1"));
    }

    #[test]
    fn per_revolution_feeds() {
        let s = run("UNITS/MM\nFEDRAT/0.1,MMPR\nFEDRAT/IPR,0.01\nFEDRAT/500,MMPM\n").unwrap();
        assert_eq!(blocks(&s), ["G95", "G94"]);
        let f: Vec<f64> = s
            .iter()
            .filter_map(|s| match s {
                ClStatement::Fedrat {
                    value,
                    unit: FeedUnit::Mmpm,
                } => Some(*value),
                _ => None,
            })
            .collect();
        assert_eq!(f.len(), 3);
        assert!((f[1] - 0.254).abs() < 1e-12);
    }

    #[test]
    fn never_silent() {
        let e = run("UNITS/MM\nGOTO/0,0,0\nGOFWD/S1,TANTO,S2\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:3:1"), "{e}");
        let e = run("UNITS/MM\nFEDRAT/MMPM,1e300\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:2:1"), "{e}");
        // No UNITS: a warning, millimetres; comments are counted.
        let s = run("PARTNO/X\nGOTO/0,0,0\n").unwrap();
        let warnings: Vec<_> = s
            .iter()
            .filter(|s| matches!(s, ClStatement::Warning(_)))
            .collect();
        assert_eq!(warnings.len(), 2, "{s:?}");
    }
}
