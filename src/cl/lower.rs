//! Lowering of APT CL constructs that real CAM systems write (`CIRCLE/`,
//! `CYCLE/`, `CSYS/`, `CUTCOM/`, `LOAD/TOOL`, `SELECT/TOOL`, `UNIT/`,
//! surface-speed `SPINDL`, `DELAY`, `STOP`, `FROM`, `GODLTA`) into the
//! plain statements the converter writes: tool-tip `GOTO`s in the set-up
//! frame, `RAPID`, `FEDRAT`, literal blocks ([`ClStatement::Block`]),
//! warnings ([`ClStatement::Warning`]), arcs ([`ClStatement::Arc`]) and
//! holes ([`ClStatement::Hole`]).
//!
//! Conventions (docs/programs.md, "APT CL"):
//! - `CSYS/r11,r12,r13,tx,r21,r22,r23,ty,r31,r32,r33,tz` gives the set-up
//!   frame in the CL frame: the columns of `R` are the set-up's axes and
//!   `t` its origin. Positions and tool axes that follow are written in the
//!   set-up frame: `p' = Rᵀ (p − t)`, `a' = Rᵀ a`.
//! - `CIRCLE/xc,yc,zc,i,j,k[,r,...]` followed by `GOTO`: an arc from the
//!   current position to the `GOTO` point, counter-clockwise about
//!   `(i,j,k)` (right-hand rule); an end point equal to the start is a full
//!   circle; an axial difference makes a helix (`cl/arc.rs`, also CATIA's
//!   `INDIRV` + `TLON,GOFWD`). It becomes an arc record that carries its
//!   linearisation within the chord tolerance (1 µm).
//! - `CYCLE/...` then `GOTO`s: every `GOTO` is a hole whose top is the
//!   point; `RAPTO` and `RTRCTO` are distances above it along the tool axis,
//!   `FEDTO` the depth below it (`cl/cycle.rs`). Each hole becomes a hole
//!   record with its canned-cycle code and its expansion into moves.

use std::collections::{BTreeMap, VecDeque};
use std::io::BufRead;

pub use super::state::Lowered;

use super::state::{Circle, MAX_FEED_MM_MIN, MAX_FEED_MM_REV, absurd_feed, det};
use super::vec3::{add, norm, num, scale};
use super::{Arg, ClReader, ClRecord, ClStatement, ClUnits, FeedUnit, split_args};
use crate::error::Error;

/// How far a `MOVARC`'s `ANGLE` may differ from the angle its start and
/// end points sweep, degrees (CAM systems print it with 4 to 6 decimals).
pub(super) const ARC_ANGLE_TOLERANCE_DEG: f64 = 1e-3;

/// How far two frames (`MCS/`, `MSYS/`: unit axes, origins in the CL's
/// units) may differ in any number and still be the same frame: CAM
/// systems print them with 4 to 9 decimals.
const FRAME_TOLERANCE: f64 = 1e-6;

/// Default chord tolerance of linearised arcs, mm.
pub const DEFAULT_ARC_TOLERANCE_MM: f64 = 1e-3;

/// Majors that move the tool or change how it moves. One that reaches the
/// end of lowering unconverted is refused, never commented; so is any
/// major that starts with `CYCLE` but is not `CYCLE` (a dialect's
/// `CYCLE81`, `CYCLE83`: drilling written as a controller cycle).
///
/// Besides the APT words, NX's splines (`NURBS`, `KNOT`, `CNTRL`: the path
/// between two `GOTO`s), the moves and settings of ISO 4343 (`RETRCT`,
/// `GOCLER`, `SAFPOS`, `POSTN`, `PREFUN`, `ZSURF`, `PIVOTZ`, `COUPLE`,
/// `OPSKIP`: the following blocks may be skipped) and of other dialects
/// (`TLCOMP`: cutter compensation, `WPLANE`: the working plane, `CALL`,
/// `CALLSUB`: subprograms), and the post-processor words of NX's APT table
/// that move or lock axes, probe, or define and call subroutines
/// (`MOVETO`, `PLUNGE`, `PROBX`, `PROBY`, `PICKUP`, `CLEARP`, `VTLAXS`,
/// `LOCKX`, `ULOCKX`, `CALSUB`, `DEFSUB`, `ENDSUB`: the statements between
/// `DEFSUB` and `ENDSUB` run where `CALSUB` calls them, not where they
/// stand). Before, these were kept as comments (counted
/// in a warning, exit 0): the tool went straight from one `GOTO` to the
/// next past an NX spline of 3 mm sag. NCL's abbreviations of the motion
/// words (`GO`, `GF`, `GL`, `GR`, `GB`, `GU`, `GD`, `IV`, `IP`, `TN`, and
/// a `GT` without its `/`) are refused as the words are; `GT/x,y,z` and
/// `RP` are read as `GOTO` and `RAPID`.
pub const MOTION_MAJORS: &[&str] = &[
    "GOTO", "GODLTA", "GOHOME", "FROM", "CIRCLE", "MOVARC", "CYCLE", "CUTCOM", "CSYS", "TRNTYP",
    "TLAXIS", "MULTAX", "RAPID", "FEDRAT", "SPINDL", "LOAD", "LOADTL", "SELECT", "TURRET", "UNITS",
    "UNIT", "DELAY", "STOP", "OPSTOP", "INDIRV", "INDIRP", "GOFWD", "GOLFT", "GORGT", "GOBACK",
    "GOUP", "GODOWN", "TLON", "TLLFT", "TLRGT", "PSIS", "ROTABL", "ROTATE", "ROTHED", "HEAD",
    "ORIGIN", "TRANS", "REFSYS", "MATRIX", "COPY", "INDEX", "TRACUT", "ARCSLP", "THREAD", "MODE",
    "PITCH", "CLAMP", "COOLNT", "NURBS", "KNOT", "CNTRL", "RETRCT", "GOCLER", "SAFPOS", "POSTN",
    "PREFUN", "ZSURF", "PIVOTZ", "COUPLE", "OPSKIP", "TLCOMP", "WPLANE", "CALL", "CALLSUB",
    "CALSUB", "DEFSUB", "ENDSUB", "MOVETO", "PLUNGE", "PROBX", "PROBY", "PICKUP", "CLEARP",
    "VTLAXS", "LOCKX", "ULOCKX", "GT", "GO", "GF", "GL", "GR", "GB", "GU", "GD", "IV", "IP", "TN",
    "STANDOFF", "SPINDLE",
];

/// Majors only Siemens NX writes (each operation of its CLSF starts with
/// `TOOL PATH/` and `TLDATA/`, its frame is `MSYS/`): after one, a
/// `CIRCLE`'s axis is that of a clockwise arc, as NX's CLSF manual gives it.
/// Before, NX's arcs were read by the right-hand rule: each the rest of
/// its circle (a 90° lead-in cut as 270° through the part).
pub const NX_MAJORS: &[&str] = &["TOOL PATH", "TLDATA", "MSYS"];

/// Majors of APT and NCL part programs that change which statements run or
/// in what order: jumps (`JUMPTO`, arithmetic `IF`), loops (`LOOPST`,
/// `LOOPND`, NCL's `DO`) and macros (`name=MACRO/…` to `TERMAC`). Before,
/// these were kept as comments and the file run from top to bottom: a
/// loop body once, a skipped branch run, a macro's motions where it is
/// defined. Refused.
/// CATIA's `LOOP/START,n` … `LOOP/END` (a post-processor word some sites
/// add) is a loop too.
pub const FLOW_MAJORS: &[&str] = &[
    "JUMPTO", "IF", "LOOPST", "LOOPND", "DO", "TERMAC", "MACRO", "LOOP", "SUBPROG",
];

/// The minor words naming a tool's length-offset register in `LOADTL` and
/// `LOAD/TOOL`: `ADJUST` (APT), `OFFSET` (NCL), `OSETNO` (Creo).
pub const LENGTH_REGISTER: [&str; 3] = ["ADJUST", "OFFSET", "OSETNO"];

/// Whether the text after a major word defines a macro (`M1=MACRO/…`).
fn is_macro_definition(text: &str) -> bool {
    text.trim_start()
        .strip_prefix('=')
        .is_some_and(|t| t.trim_start().to_ascii_uppercase().starts_with("MACRO"))
}

/// Lowers the records of `inner` (see the module documentation); arcs are
/// linearised within `arc_tolerance_mm`.
///
/// `default_units`: the units of a program without `UNITS` (`None`:
/// millimetres, with a warning at the first motion).
pub fn lower<R: BufRead>(
    inner: ClReader<R>,
    file: impl Into<String>,
    arc_tolerance_mm: f64,
    default_units: Option<ClUnits>,
) -> Lowered<R> {
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
        default_units,
        warned_units: false,
        csys: None,
        pos: None,
        axis: [0.0, 0.0, 1.0],
        circle: None,
        indirv: None,
        cutcom: false,
        cycle: None,
        cycle_line: 0,
        setups: Vec::new(),
        feed: None,
        tool: None,
        per_rev: false,
        commented: BTreeMap::new(),
        silenced: Default::default(),
        rapid_pending: false,
        first_frames: Vec::new(),
        cutcom_announced: None,
        clockwise_circles: false,
    }
}

impl<R: BufRead> Lowered<R> {
    pub(super) fn goto(
        &mut self,
        r: &ClRecord,
        tip: [f64; 3],
        axis: Option<[f64; 3]>,
    ) -> Result<(), Error> {
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
        if let Some(line) = self.cutcom_announced {
            return Err(self.err(r, format!("a motion after CUTCOM/ON (line {line}) and before CUTCOM/LEFT or CUTCOM/RIGHT: the side the tool is offset to is not known; give the side (CUTCOM/LEFT|RIGHT) before the motion")));
        }
        self.rapid_pending = false;
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

    /// Lowers `r`, an [`ClStatement::Other`] `major`/`text`; `true` when it
    /// is kept as it is (a statement that does not move the tool, written
    /// as a comment).
    fn other(&mut self, r: &ClRecord, major: &str, text: &str) -> Result<bool, Error> {
        let args = split_args(text.as_bytes(), 0);
        let a = |k: usize| args.get(k).map(|a| a.upper()).unwrap_or_default();
        if NX_MAJORS.contains(&major) {
            self.clockwise_circles = true;
        }
        if major == "CUTCOM" && args.len() > 1 && (a(0) == "ON" || a(0) == "OFF") {
            // HSMWorks' `CUTCOM/ON,LEFT,d`: `CUTCOM/LEFT,d`.
            if a(0) == "ON" && (a(1) == "LEFT" || a(1) == "RIGHT") {
                let rest = &text[args[1].offset..];
                return self.other(r, major, rest);
            }
            // DMG MORI's `CUTCOM/ON,LENGTH,h` (tool length compensation,
            // register h) and `CUTCOM/OFF,LENGTH`: kinpost writes `G43 H`
            // with the tool's number at the tool change.
            if a(1) == "LENGTH" {
                if a(0) == "ON" {
                    let register = args.get(2).and_then(Arg::number);
                    self.same_register(r, "CUTCOM/ON,LENGTH", register, self.tool.map(f64::from))?;
                }
                self.count_commented(major);
                return Ok(true);
            }
        }
        match major {
            "UNIT" => match a(0).as_str() {
                "MM" => {
                    self.own_units(r, ClUnits::Mm);
                    self.emit(r, ClStatement::Units(ClUnits::Mm));
                }
                "INCHES" | "INCH" => {
                    self.own_units(r, ClUnits::Inches);
                    self.emit(r, ClStatement::Units(ClUnits::Inches));
                }
                w => {
                    return Err(
                        self.err(r, format!("expected UNIT/MM or UNIT/INCHES, found `{w}`"))
                    );
                }
            },
            "CIRCLE" => {
                self.refuse_arc_here(r, "CIRCLE")?;
                if args.iter().any(|a| a.is("TIMES")) {
                    return Err(self.err(r, "CIRCLE/…,TIMES,n: NX's helix of n turns is not converted; refused rather than cut as a single turn; have the CAM system write the helix as one CIRCLE per turn or as GOTO points"));
                }
                let v = self.numbers(r, &args, "CIRCLE")?;
                if v.len() < 6 {
                    return Err(self.err(r, "CIRCLE expects xc,yc,zc,i,j,k[,r,...]"));
                }
                self.start_arc(r, "CIRCLE", &v, None)?;
            }
            // Autodesk's ISO 4343 APT: `MOVARC/xc,yc,zc,i,j,k,r,ANGLE,a`
            // then the `GOTO` that ends it: a `CIRCLE` whose swept angle
            // about (i,j,k) must be `a`.
            "MOVARC" => {
                self.refuse_arc_here(r, "MOVARC")?;
                let form = "MOVARC expects xc,yc,zc,i,j,k,r,ANGLE,a (degrees)";
                if args.len() != 9 || !args[7].is("ANGLE") {
                    return Err(self.err(r, form));
                }
                let mut numbers = args[..7].to_vec();
                numbers.push(args[8]);
                let v = self.numbers(r, &numbers, "MOVARC")?;
                self.start_arc(r, "MOVARC", &v[..7], Some(v[7]))?;
            }
            "CYCLE" => self.cycle(r, &args)?,
            "SYN" => {
                self.synonyms(r)?;
                self.count_commented(major);
                return Ok(true);
            }
            "INDIRV" => {
                let v = self.numbers(r, &args, "INDIRV")?;
                if v.len() != 3 || norm([v[0], v[1], v[2]]) < 1e-12 {
                    return Err(self.err(r, "INDIRV expects a direction i,j,k that is not zero"));
                }
                self.indirv = Some([v[0], v[1], v[2]]);
                self.block(r, super::state::as_comment(&r.text));
            }
            "TLON" => self.tlon_gofwd(r, text)?,
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
                if self.cutcom && (det(m) < 0.0) != self.mirrored() {
                    return Err(self.err(r, "CSYS changes between a right- and a left-handed frame while cutter compensation is on: the side the tool is offset to would change mid-path; switch it off (CUTCOM/OFF) before"));
                }
                self.csys = if ident {
                    None
                } else {
                    Some((m, [v[3], v[7], v[11]]))
                };
                // An operation's frame: its tool axis is the frame's Z axis
                // (the third column) until a GOTO or TLAXIS gives another.
                // SolidWorks CAM writes three-value GOTOs for an operation
                // along its frame's Z after six-value ones along another
                // frame's; the axis left from those would tilt the tool.
                self.axis = [m[0][2], m[1][2], m[2][2]];
                self.block(r, super::state::as_comment(&r.text));
            }
            "TRNTYP" => {
                if a(0) != "WORLD" {
                    return Err(
                        self.err(r, format!("TRNTYP/{} is not supported (only WORLD)", a(0)))
                    );
                }
                self.block(r, super::state::as_comment(&r.text));
            }
            "SETUP" if a(0) == "START" && args.len() == 2 => {
                if let Some(n) = args[1].number() {
                    self.setup_start(r, n)?;
                }
                self.count_commented(major);
                return Ok(true);
            }
            // `MODE/MILL` (Autodesk's ISO 4343 APT starts with it): the
            // milling mode kinpost converts in. Lathe modes are refused.
            "MODE" if args.len() == 1 && a(0) == "MILL" => {
                self.count_commented(major);
                return Ok(true);
            }
            "CUTCOM" => match a(0).as_str() {
                "LEFT" | "RIGHT" => {
                    // G41/G42 compensate in the plane in force, G17 (X Y):
                    // the plane XYPLAN names. Another plane is not written.
                    if let Some(p) = args
                        .iter()
                        .skip(1)
                        .find(|x| x.is("YZPLAN") || x.is("ZXPLAN"))
                    {
                        return Err(self.err(r, format!("CUTCOM/{},{} asks for cutter compensation in another plane than X Y, and kinpost writes G41/G42 in G17 (X Y) only: have the CAM system output the tool-centre path for this operation", a(0), p.upper())));
                    }
                    // A mirrored (left-handed) set-up turns the path the
                    // other way round: the tool's left is the path's right.
                    let g = if (a(0) == "LEFT") != self.mirrored() {
                        "G41"
                    } else {
                        "G42"
                    };
                    // `CUTCOM/LEFT[,XYPLAN][,n]`: n is the offset register
                    // (Autodesk writes the tool's diameter offset there).
                    let mut register = self.tool;
                    for x in &args[1..] {
                        match (x.upper().as_str(), x.number()) {
                            ("XYPLAN", _) => {}
                            (_, Some(n)) if n >= 0.0 && n.fract() == 0.0 && n < 1e9 => {
                                register = Some(n as u32);
                            }
                            (w, _) => {
                                return Err(self.err(
                                    r,
                                    format!("CUTCOM/{},{w} is not supported (expected CUTCOM/LEFT|RIGHT[,XYPLAN][,register]: compensation in the XY plane)", a(0)),
                                ));
                            }
                        }
                    }
                    self.cutcom = true;
                    self.cutcom_announced = None;
                    let block = match register {
                        Some(t) => format!("{g} D{t}"),
                        None => g.to_string(),
                    };
                    self.emit(r, ClStatement::CutterCompensation { block, on: true });
                }
                // CAMplete's `CUTCOM/ON`, then `CUTCOM/LEFT|RIGHT[,n]`: the
                // side comes with the second; a motion before it is refused.
                "ON" if args.len() == 1 => {
                    self.cutcom_announced = Some(r.line);
                    self.count_commented(major);
                    return Ok(true);
                }
                "OFF" => {
                    self.cutcom = false;
                    self.cutcom_announced = None;
                    let block = "G40".to_string();
                    self.emit(r, ClStatement::CutterCompensation { block, on: false });
                }
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
                    self.refuse_tool_change_in_mode(r, "LOAD/TOOL")?;
                    let mut h = n;
                    if LENGTH_REGISTER.contains(&a(2).as_str())
                        && let Some(x) = args.get(3).and_then(|x| x.number())
                    {
                        h = x.max(0.0) as u32;
                    }
                    self.tool = Some(n);
                    self.block(r, format!("T{n} M6"));
                    self.block(r, format!("G43 H{h}"));
                }
            }
            // A gear range alone: the spindle is not started.
            "SPINDL" if args.len() == 2 && a(0) == "RANGE" => {
                self.count_commented(major);
                return Ok(true);
            }
            "SPINDL" if args.iter().any(|x| x.is("MAXRPM")) => {
                return Err(self.err(r, "SPINDL with MAXRPM: a spindle speed clamp, which matters under a constant surface speed, and kinpost does not write one (its form depends on the controller: G50 S, G92 S, LIMS=, G96 D); set it at the program's start and give SPINDL without it"));
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
                let (Some(t), 1) = (t, args.len()) else {
                    return Err(self.err(r, "DELAY expects a time in seconds (DELAY/s); other forms (DELAY/s,REV: revolutions of the spindle) are not converted"));
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
                // FROM declares where the tool starts (ISO 4343); before
                // the first tool change (CATIA writes it before LOADTL) no
                // tool length is compensated yet, and a rapid to the tip's
                // point would leave the tip a tool length past it: it is
                // kept as a comment there, and the first GOTO moves.
                if self.tool.is_none() {
                    self.block(r, super::state::as_comment(&r.text));
                } else {
                    self.go(r, [v[0], v[1], v[2]], true);
                }
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
            // A site's word for inverse-time feeds (CATIA `INVERSE/ON`):
            // the FEDRATs after it are no feeds per minute.
            "INVERSE" if a(0) != "OFF" => {
                return Err(self.err(r, format!("INVERSE/{}: inverse-time feeds by a post-processor word kinpost does not read; the feeds after it would be written as mm/min: refused rather than kept as a comment; write FEDRAT/INVERS,f in the CAM system, or give feeds per minute", a(0))));
            }
            "NURBS" | "KNOT" | "CNTRL" => {
                return Err(self.err(r, format!("{major}: a NURBS spline (the path between two GOTO points) is not converted; refused rather than kept as a comment, which would move the tool straight past it; have the CAM system write the path as GOTO points")));
            }
            // The tool length register by a statement of its own: ISO
            // 4343's `OFSTNO/h`, DMG MORI's `TOOLNO/n,…,OSETNO,h,d`. kinpost
            // writes `G43 H` with the tool's number (or `LOADTL`'s ADJUST):
            // another register would be another tool length.
            "OFSTNO" | "TOOLNO" => {
                let register = if major == "OFSTNO" {
                    args.first().and_then(Arg::number)
                } else {
                    let at = args.iter().position(|x| x.is("OSETNO"));
                    at.and_then(|k| args.get(k + 1)).and_then(Arg::number)
                };
                let tool = if major == "OFSTNO" {
                    self.tool.map(f64::from)
                } else {
                    args.first().and_then(Arg::number)
                };
                self.same_register(r, &format!("{major}/"), register, tool)?;
                self.count_commented(major);
                return Ok(true);
            }
            // DMG MORI's APT (Autodesk's "Mori APT (MfgSuite)" post):
            // `MCSYS/ NUM, n, POINT, origin, VECTOR, x axis, VECTOR, y axis`,
            // the work plane the points after it are in.
            "MCSYS" => {
                if !Self::mori_identity_frame(&args) {
                    return Err(self.err(r, "MCSYS/ with a rotation or an origin (or of a form kinpost does not read): the points after it are in that work plane's frame (POINT its origin, the VECTORs its x and y axes), not in the set-up frame kinpost converts; refused rather than kept as a comment, which would move the tool in the wrong frame; have the CAM system write the points in the set-up (WCS) frame (docs/programs.md)"));
                }
                self.count_commented(major);
                return Ok(true);
            }
            "MCS" | "MSYS" | "ZERO" => {
                if let Some(why) = self.frame_change(r, major, &args) {
                    return Err(self.err(r, why));
                }
                self.count_commented(major);
                return Ok(true);
            }
            _ if FLOW_MAJORS.contains(&major) || is_macro_definition(text) => {
                return Err(self.err(r, format!("{} changes which statements run, or in what order (a jump, a loop, a macro); kinpost reads CL data from top to bottom and does not follow it: refused rather than kept as a comment; have the CAM system write the path it stands for", if FLOW_MAJORS.contains(&major) { major.to_string() } else { format!("{major}=MACRO") })));
            }
            _ if MOTION_MAJORS.contains(&major)
                || (major.starts_with("CYCLE") && major != "CYCLE") =>
            {
                return Err(self.err(r, format!("{major} moves the tool or changes how it moves and kinpost does not convert it; refused rather than kept as a comment")));
            }
            // A statement word written with blanks in it (`GO TO/`, `RAPID
            // GOTO/`, `CUTCOM LEFT/1`): APT ignores blanks, kinpost reads the
            // words of motion written together.
            _ if major.contains(' ') && Self::spaced_motion_word(major) => {
                return Err(self.err(r, format!("`{major}/`: a statement word of motion written with blanks in it, or two statements on a line (APT ignores blanks); kinpost reads each statement word written together, one statement a line (`GOTO/`, `RAPID` on a line of its own), and does not convert this one: refused rather than kept as a comment")));
            }
            _ => {
                self.count_commented(major);
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Refuses `what` (a statement that selects the tool length
    /// `register`) where the register is not the tool's number, with which
    /// kinpost writes `G43 H`: the tool's length would come from another
    /// register.
    fn same_register(
        &self,
        r: &ClRecord,
        what: &str,
        register: Option<f64>,
        tool: Option<f64>,
    ) -> Result<(), Error> {
        match register {
            Some(h) if Some(h) != tool => Err(self.err(r, format!("{what} selects the tool length register {} where kinpost writes G43 H with the tool's number{}: the tool's length would be taken from another register; refused rather than kept as a comment; give the register in LOADTL/n,ADJUST,h (or LOAD/TOOL,n,ADJUST,h)", num(h), tool.map(|t| format!(" ({})", num(t))).unwrap_or_default()))),
            _ => Ok(()),
        }
    }

    /// Whether a Mori `MCSYS/` (`NUM, n, POINT, x, y, z, VECTOR, xx, xy, xz,
    /// VECTOR, yx, yy, yz`) is the set-up frame: origin 0, axes x and y.
    fn mori_identity_frame(args: &[Arg]) -> bool {
        let after = |word: &str, nth: usize| -> Option<Vec<f64>> {
            let at = args
                .iter()
                .enumerate()
                .filter(|(_, a)| a.is(word))
                .nth(nth)?
                .0;
            args.get(at + 1..at + 4)?.iter().map(Arg::number).collect()
        };
        let near = |v: Option<Vec<f64>>, w: [f64; 3]| {
            v.is_some_and(|v| {
                v.iter()
                    .zip(w)
                    .all(|(a, b)| (a - b).abs() <= FRAME_TOLERANCE)
            })
        };
        near(after("POINT", 0), [0.0, 0.0, 0.0])
            && near(after("VECTOR", 0), [1.0, 0.0, 0.0])
            && near(after("VECTOR", 1), [0.0, 1.0, 0.0])
    }

    /// Whether a major word written with blanks (`GO TO`, `RAPID GOTO`,
    /// `CUTCOM LEFT`) spells, or starts with, a statement that moves the tool
    /// or changes how it moves once its blanks are removed.
    fn spaced_motion_word(major: &str) -> bool {
        const MOVING: [&str; 12] = [
            "GOTO", "GODLTA", "FROM", "RAPID", "CIRCLE", "MOVARC", "CYCLE", "CUTCOM", "FEDRAT",
            "LOADTL", "TLAXIS", "MULTAX",
        ];
        let compact: String = major.split_whitespace().collect();
        let first = major.split_whitespace().next().unwrap_or_default();
        compact.contains("GOTO") || MOVING.iter().any(|m| compact == *m || first == *m)
    }

    /// Refuses an arc (`CIRCLE`, `MOVARC`) under a cycle (the `GOTO` that
    /// ends it would be a hole) or after a `RAPID` (an arc at the rapid
    /// rate has no G-code form). Checked before the arc's numbers are read.
    fn refuse_arc_here(&self, r: &ClRecord, major: &str) -> Result<(), Error> {
        if self.cycle.is_some() {
            return Err(self.err(r, format!("{major} while the cycle of line {} is in force (no CYCLE/OFF): the GOTO that ends the arc would be drilled as a hole; end the cycle with CYCLE/OFF before the arc", self.cycle_line)));
        }
        if self.rapid_pending {
            return Err(self.err(r, format!("{major} after RAPID: an arc at the rapid rate has no G-code form (G0 moves straight, and each axis at its own rate); give the arc a feed, or remove the RAPID")));
        }
        Ok(())
    }

    /// Refuses a tool change (`what`) while a cycle is in force (its holes
    /// would go on with the new tool, and a CAM system that leaves out
    /// `CYCLE/OFF` before the next operation, CAMWorks, means them to end)
    /// or cutter compensation is on (`G41`/`G42 D` would keep the old
    /// tool's radius; LinuxCNC refuses the tool change then).
    fn refuse_tool_change_in_mode(&self, r: &ClRecord, what: &str) -> Result<(), Error> {
        if self.cycle.is_some() {
            return Err(self.err(r, format!("{what} while the cycle of line {} is in force (no CYCLE/OFF): every GOTO after it would be drilled as a hole with the new tool; end the cycle with CYCLE/OFF before the tool change", self.cycle_line)));
        }
        if self.cutcom {
            return Err(self.err(r, format!("{what} while cutter compensation is on (CUTCOM/LEFT or RIGHT, no CUTCOM/OFF): the new tool would be offset by the radius of the old one's register; switch it off (CUTCOM/OFF) before the tool change")));
        }
        Ok(())
    }

    /// Starts the arc that the next `GOTO` ends, from `xc,yc,zc,i,j,k[,r]`
    /// (`v`) and, for `MOVARC`, the angle it must sweep (degrees).
    fn start_arc(
        &mut self,
        r: &ClRecord,
        major: &str,
        v: &[f64],
        sweep_deg: Option<f64>,
    ) -> Result<(), Error> {
        // Siemens NX gives the axis of a clockwise arc ("i,j,k is the
        // circle or helix axis vector in the MCS (assuming a clockwise
        // direction)", NX's CLSF manual); APT and the other CAM systems
        // that of a counter-clockwise one (right-hand rule).
        let sign = if self.clockwise_circles && major == "CIRCLE" {
            -1.0
        } else {
            1.0
        };
        let normal = [sign * v[3], sign * v[4], sign * v[5]];
        if norm(normal) < 1e-12 {
            return Err(self.err(r, format!("{major} axis has zero length")));
        }
        if let Some(a) = sweep_deg
            && !(a > 0.0 && a <= 360.0 + ARC_ANGLE_TOLERANCE_DEG)
        {
            return Err(self.err(
                r,
                format!(
                    "{major} sweeps {}°: expected more than 0° and at most one turn",
                    num(a)
                ),
            ));
        }
        self.circle = Some(Circle {
            center: [v[0], v[1], v[2]],
            normal,
            radius: v.get(6).copied().filter(|&x| x > 0.0),
            sweep_deg,
        });
        Ok(())
    }

    /// Why a frame statement (`MCS/`, `MSYS/`, `ZERO/`) cannot be kept as a
    /// comment:
    /// the points after it would be in another frame than the set-up frame
    /// kinpost converts (docs/programs.md, "APT CL"). `None` for one that
    /// changes nothing, or of a form not known (kept as a comment).
    ///
    /// - `MCS/` with 12 numbers (CAMplete's and Autodesk's APT: the work
    ///   plane's x, y and z axes row by row, then its origin; the points
    ///   are in that frame): anything but the identity and the origin 0.
    /// - `MSYS/` (Siemens NX: the MCS the points are written in, its origin
    ///   and axes in the part's absolute frame) and `ZERO/n` (CAMplete: the
    ///   work offset the points are measured from): the first one is the
    ///   frame of the program; a later one that differs is another frame.
    fn frame_change(&mut self, r: &ClRecord, major: &str, args: &[Arg]) -> Option<String> {
        let v: Vec<f64> = args.iter().map(Arg::number).collect::<Option<_>>()?;
        let same_frame = |a: &[f64], b: &[f64]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| (x - y).abs() <= FRAME_TOLERANCE)
        };
        if major == "MCS" {
            let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
            return (v.len() == 12 && !same_frame(&v, &identity)).then(|| {
                "MCS/ with a rotation or an origin: the points after it are in that work plane's frame (the x, y and z axes row by row, then the origin), not in the set-up frame kinpost converts; refused rather than kept as a comment, which would move the tool in the wrong frame; have the CAM system write the points in the set-up (WCS) frame, or give the frame as CSYS/ (docs/programs.md)".to_string()
            });
        }
        let Some((_, first, line)) = self.first_frames.iter().find(|(m, ..)| m == major) else {
            self.first_frames.push((major.to_string(), v, r.line));
            return None;
        };
        let same = same_frame(first, &v);
        let what = if major == "ZERO" {
            "the work offset"
        } else {
            "the machine coordinate system"
        };
        (!same).then(|| format!("{major}/ changes {what} from that of line {line}: the points after it are in another frame than those before, and kinpost converts one; refused rather than kept as a comment, which would move the tool in the wrong frame; post the operations of each frame as a program of their own (with its --work-offset)"))
    }

    /// Lowers `r`: kept as it is, or turned into the records it stands for
    /// (none, one or more); its text is given back to the reader when not
    /// kept.
    fn step(&mut self, r: ClRecord) -> Result<(), Error> {
        if self.circle.is_some()
            && !matches!(
                r.statement,
                ClStatement::Goto { .. } | ClStatement::Fedrat { .. } | ClStatement::Comment(_)
            )
        {
            return Err(self.err(&r, "CIRCLE must be followed by the GOTO that ends the arc"));
        }
        // A statement whose major word a `SYN` commented out.
        if !self.silenced.is_empty() && !matches!(r.statement, ClStatement::Comment(_)) {
            let text = String::from_utf8_lossy(&r.text);
            // The first word, as the statement grammar reads it.
            let major = super::major_word(text.trim_start().as_bytes())
                .map(|(_, w)| String::from_utf8_lossy(w).to_ascii_uppercase())
                .unwrap_or_default();
            if self.silenced.contains(&major) {
                let comment = ClStatement::Comment(format!("{} (SYN: a comment)", text.trim()));
                self.count_commented(&major);
                self.out.push_back(ClRecord {
                    statement: comment,
                    ..r
                });
                return Ok(());
            }
        }
        // Whether `r` is kept as it is.
        let keep = match &r.statement {
            ClStatement::Goto { tip, axis } => {
                // The last line of a file cut short: a point cut mid-number
                // (`GOTO/40,20,3` of `GOTO/40,20,35`) would put the tool
                // elsewhere.
                if !r.text.ends_with(b"\n") {
                    return Err(self.err(&r, "the file ends inside this GOTO, without a line end: a truncated file? A point cut short would put the tool elsewhere; if the file is complete, end it with a line break (and FINI)"));
                }
                self.goto(&r, *tip, *axis)?;
                false
            }
            ClStatement::TlAxis(a) => {
                self.axis = *a;
                false
            }
            ClStatement::Fedrat { value, unit } => {
                if absurd_feed(*value, *unit, self.mm_per_unit) {
                    return Err(self.err(&r, format!("feed rate {value:e} is absurd (more than {MAX_FEED_MM_MIN} mm/min or {MAX_FEED_MM_REV} mm/rev)")));
                }
                if matches!(unit, FeedUnit::Ipm | FeedUnit::Ipr) && !self.units_seen {
                    return Err(self.err(&r, "a feed in inches (IPM, IPR) with no UNITS statement before it: kinpost would take the lengths as millimetres and the feed as inches; say which the program is with --units inch (or --units mm)"));
                }
                self.feed = Some((*value, *unit));
                self.feed_record(&r, *value, *unit);
                false
            }
            ClStatement::Units(u) => {
                self.own_units(&r, *u);
                true
            }
            // As `LOAD/TOOL,n[,ADJUST,h]`: the tool change and its length
            // compensation (h defaults to n).
            ClStatement::LoadTl { tool, adjust } => {
                self.refuse_tool_change_in_mode(&r, "LOADTL")?;
                let (n, h) = (*tool, adjust.unwrap_or(*tool));
                self.tool = Some(n);
                self.block(&r, format!("T{n} M6"));
                self.block(&r, format!("G43 H{h}"));
                false
            }
            ClStatement::Other { major, text } => self.other(&r, major, text)?,
            ClStatement::Multax(_) => {
                self.count_commented("MULTAX");
                true
            }
            ClStatement::Rapid => {
                self.rapid_pending = true;
                true
            }
            _ => true,
        };
        if keep {
            self.out.push_back(r);
        } else {
            self.inner.recycle(r.text);
        }
        Ok(())
    }

    /// `SYN/'WORD','$$…',…`: pairs of a word and what it stands for. A word
    /// that stands for a comment (`$$…`, as CATIA's ICAM output writes
    /// `SYN/'TLAXIS','$$*TLAXIS'`) makes its statements comments; any
    /// other synonym, or one that would comment out a statement of the
    /// tool's path, is refused: kinpost does not apply it.
    fn synonyms(&mut self, r: &ClRecord) -> Result<(), Error> {
        // From the record's text: a `$$` in a quoted word is not a comment.
        let text = String::from_utf8_lossy(&r.text);
        let after = text.split_once('/').map_or("", |(_, a)| a);
        let mut args: Vec<String> = Vec::new();
        let (mut quote, mut current) = (None, String::new());
        let mut chars = after.chars().peekable();
        while let Some(c) = chars.next() {
            match (quote, c) {
                (None, '\'' | '"') => quote = Some(c),
                (Some(q), _) if c == q => quote = None,
                (None, ',') => args.push(std::mem::take(&mut current)),
                // A `$$` comment to the line's end; a continuation `$`
                // and the line ends are not part of the words.
                (None, '$') if chars.peek() == Some(&'$') => {
                    chars.by_ref().take_while(|&c| c != '\n').for_each(drop);
                }
                (None, '$' | '\r' | '\n') => {}
                _ => current.push(c),
            }
        }
        args.push(current);
        let args: Vec<String> = args.iter().map(|a| a.trim().to_ascii_uppercase()).collect();
        if args.is_empty() || !args.len().is_multiple_of(2) {
            return Err(self.err(r, "SYN expects pairs of a word and what it stands for"));
        }
        for pair in args.chunks(2) {
            let (name, meaning) = (pair[0].clone(), pair[1].clone());
            let path = [
                "GOTO", "GODLTA", "GOHOME", "FROM", "CIRCLE", "CYCLE", "MOVARC",
            ];
            if !meaning.starts_with("$$") || path.contains(&name.as_str()) {
                return Err(self.err(
                    r,
                    format!(
                        "SYN makes `{name}` stand for `{meaning}`: kinpost applies a synonym only where it comments out a statement that is not part of the tool's path (`SYN/'TLAXIS','$$*TLAXIS'`); replace the synonyms in the CL data first"
                    ),
                ));
            }
            self.silenced.insert(name);
        }
        Ok(())
    }

    /// Counts a statement of `major` kept as a comment (for [`Self::summary`]).
    fn count_commented(&mut self, major: &str) {
        match self.commented.get_mut(major) {
            Some(n) => *n += 1,
            None => {
                self.commented.insert(major.to_string(), 1);
            }
        }
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
            "{}: {total} CL {} not move the tool kept as comments ({})",
            self.file,
            if total == 1 {
                "statement that does"
            } else {
                "statements that do"
            },
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

impl<R: BufRead> Iterator for Lowered<R> {
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
pub(super) mod tests;
