//! The state of the lowering iterator ([`Lowered`]) and the helpers every
//! lowering module uses: errors, emitted records, the set-up frame, feeds.

use std::collections::{BTreeMap, VecDeque};
use std::io::BufRead;

use arrayvec::ArrayVec;

use super::vec3::sub;
use super::{Arg, ClReader, ClRecord, ClStatement, ClUnits, FeedUnit};
use crate::error::{Error, Location};

/// Largest feed accepted, mm/min (per minute) or mm/rev (per revolution).
/// A `CIRCLE` waiting for the `GOTO` that ends it (CL frame).
#[derive(Debug, Clone)]
pub(super) struct Circle {
    pub(super) center: [f64; 3],
    pub(super) normal: [f64; 3],
    pub(super) radius: Option<f64>,
    /// The angle the arc sweeps, as given (`MOVARC/…,ANGLE,a`), degrees.
    pub(super) sweep_deg: Option<f64>,
}

/// The kinds of hole the cycles make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum CycleKind {
    /// `DRILL`, `FACE`, `CSINK`, `SPOT`: feed down, (dwell,) rapid out.
    Drill,
    /// `DEEP`, `DEEP2`: pecks with full retraction.
    Deep,
    /// `BRKCHP`: pecks with a short retraction (chip breaking).
    BrkChp,
    /// `BORE`, `REAM`: feed down, (dwell,) feed out.
    Bore,
    /// `BORE,DRAG`: feed down, spindle stop, rapid out.
    BoreDrag,
    /// `TAP`: tapping (the spindle reverses at the bottom).
    Tap,
}

/// The cycle in force (`CYCLE/…` until `CYCLE/OFF`), CL units.
#[derive(Debug, Clone)]
pub(super) struct Cycle {
    pub(super) kind: CycleKind,
    pub(super) depth: f64,
    pub(super) rapto: f64,
    pub(super) rtrcto: f64,
    /// `RTRCTO,AUTO` (NX): back to the level the tool came from.
    pub(super) rtrcto_auto: bool,
    pub(super) feed: Option<(f64, FeedUnit)>,
    pub(super) dwell: f64,
    pub(super) first_peck: f64,
    pub(super) sub_peck: f64,
}

/// Largest feed accepted, mm/min (per minute) or mm/rev (per revolution).
pub(super) const MAX_FEED_MM_MIN: f64 = 1e6;
pub(super) const MAX_FEED_MM_REV: f64 = 100.0;

/// A `CSYS` set-up frame in the CL frame: the rotation (its columns the
/// set-up's axes) and the origin.
pub(super) type SetupFrame = ([[f64; 3]; 3], [f64; 3]);

/// The lowering iterator: wraps a [`ClReader`] and yields records the
/// converter writes directly.
#[derive(Debug)]
pub struct Lowered<R: BufRead> {
    /// The reader; it also keeps the texts given back
    /// ([`Lowered::recycle`]), for its records and those emitted here.
    pub(super) inner: ClReader<R>,
    pub(super) file: String,
    pub(super) out: VecDeque<ClRecord>,
    pub(super) finished: bool,
    pub(super) tol_mm: f64,
    pub(super) mm_per_unit: f64,
    pub(super) units_seen: bool,
    /// `--units`, the units of a program without `UNITS`, until the
    /// program's own statement says otherwise (a warning then, once).
    pub(super) default_units: Option<ClUnits>,
    pub(super) warned_units: bool,
    pub(super) csys: Option<SetupFrame>,
    pub(super) pos: Option<[f64; 3]>,
    pub(super) axis: [f64; 3],
    pub(super) circle: Option<Circle>,
    /// `INDIRV/i,j,k`: the direction the next motion starts in.
    pub(super) indirv: Option<[f64; 3]>,
    /// Cutter compensation is on (`CUTCOM/LEFT|RIGHT`): controllers refuse
    /// canned cycles then, so holes are moves.
    pub(super) cutcom: bool,
    pub(super) cycle: Option<Cycle>,
    /// Per `SETUP/START,n` number seen: the `CSYS` in force there and the
    /// line (a number started again under another `CSYS` is refused).
    pub(super) setups: Vec<(f64, Option<SetupFrame>, usize)>,
    /// The line of the `CYCLE` statement that put the cycle in force.
    pub(super) cycle_line: usize,
    pub(super) feed: Option<(f64, FeedUnit)>,
    pub(super) tool: Option<u32>,
    pub(super) per_rev: bool,
    pub(super) commented: BTreeMap<String, usize>,
    /// Major words a `SYN/'WORD','$$…'` commented out: their statements
    /// are kept as comments.
    pub(super) silenced: std::collections::BTreeSet<String>,
    /// A `RAPID` waits for the motion it applies to.
    pub(super) rapid_pending: bool,
    /// The first `MSYS/` and `ZERO/`: major word, numbers and line (the
    /// frame of the program's points).
    pub(super) first_frames: Vec<(String, Vec<f64>, usize)>,
    /// The line of a `CUTCOM/ON` whose side (`CUTCOM/LEFT|RIGHT`) has not
    /// come yet.
    pub(super) cutcom_announced: Option<usize>,
    /// A Siemens NX statement was read ([`super::lower::NX_MAJORS`]): a
    /// `CIRCLE`'s axis is that of a clockwise arc.
    pub(super) clockwise_circles: bool,
}

/// The statements of a feed change: `G95` or `G94` when the feed mode
/// (`per_rev`) changes, then the feed (per revolution in mm/rev).
pub(super) fn feed_statements(
    per_rev: &mut bool,
    value: f64,
    unit: FeedUnit,
) -> ArrayVec<ClStatement, 2> {
    let mut out = ArrayVec::new();
    let rev = matches!(unit, FeedUnit::Mmpr | FeedUnit::Ipr);
    if rev != *per_rev {
        *per_rev = rev;
        out.push(ClStatement::Block(if rev { "G95" } else { "G94" }.into()));
    }
    let (value, unit) = match unit {
        FeedUnit::Mmpr => (value, FeedUnit::Mmpm),
        FeedUnit::Ipr => (value * 25.4, FeedUnit::Mmpm),
        u => (value, u),
    };
    out.push(ClStatement::Fedrat { value, unit });
    out
}

/// Whether the feed in `unit` (after units) is absurd.
pub(super) fn absurd_feed(value: f64, unit: FeedUnit, mm_per_unit: f64) -> bool {
    match unit {
        FeedUnit::Mmpm => value > MAX_FEED_MM_MIN,
        FeedUnit::Ipm => value * 25.4 > MAX_FEED_MM_MIN,
        FeedUnit::Unspecified => value * mm_per_unit > MAX_FEED_MM_MIN,
        FeedUnit::Mmpr => value > MAX_FEED_MM_REV,
        FeedUnit::Ipr => value * 25.4 > MAX_FEED_MM_REV,
    }
}

impl<R: BufRead> Lowered<R> {
    pub(super) fn err(&self, r: &ClRecord, message: impl Into<String>) -> Error {
        Error::input_with(
            Location::new(self.file.clone(), r.line, r.col),
            message,
            String::from_utf8_lossy(&r.text).trim().to_string(),
        )
    }

    /// Emits `statement` with the place and text of `r` (its text copied
    /// into one given back, so that no allocation is made in the steady
    /// state).
    pub(super) fn emit(&mut self, r: &ClRecord, statement: ClStatement) {
        let mut text = self.inner.text_buffer();
        text.extend_from_slice(&r.text);
        self.out.push_back(ClRecord {
            line: r.line,
            col: r.col,
            text,
            statement,
        });
    }

    /// Takes back the text of a record done with (one this iterator gave
    /// out): a record read or emitted later reuses its memory.
    pub fn recycle(&mut self, text: Vec<u8>) {
        self.inner.recycle(text);
    }

    pub(super) fn block(&mut self, r: &ClRecord, b: impl Into<String>) {
        self.emit(r, ClStatement::Block(b.into()));
    }

    /// A point of the CL frame in the set-up frame (`CSYS`).
    pub(super) fn to_setup(&self, p: [f64; 3]) -> [f64; 3] {
        match &self.csys {
            Some((_, o)) => self.dir_to_setup(sub(p, *o)),
            None => p,
        }
    }

    /// A direction of the CL frame in the set-up frame (`CSYS`).
    pub(super) fn dir_to_setup(&self, v: [f64; 3]) -> [f64; 3] {
        match &self.csys {
            Some((m, _)) => [
                m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
                m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
                m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
            ],
            None => v,
        }
    }

    /// `SETUP/START,n` (CAMWorks): a set-up number started again under
    /// another `CSYS` than before is a copy of that set-up (a pattern)
    /// whose points CAMWorks writes placed already, in the CL frame, while
    /// other posts write a set-up's points in its `CSYS` frame: which one
    /// a file means cannot be told, so it is refused rather than guessed.
    pub(super) fn setup_start(&mut self, r: &ClRecord, n: f64) -> Result<(), Error> {
        // The frame as twelve numbers (no CSYS: the identity).
        let parts = |c: &Option<SetupFrame>| -> Vec<f64> {
            let (m, t) = c.unwrap_or((
                [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                [0.0; 3],
            ));
            m.iter().flatten().chain(&t).copied().collect()
        };
        let same = |a: &Option<SetupFrame>, b: &Option<SetupFrame>| {
            parts(a)
                .iter()
                .zip(parts(b))
                .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + x.abs()))
        };
        match self.setups.iter().find(|(k, _, _)| *k == n) {
            Some((_, csys, line)) if !same(csys, &self.csys) => Err(self.err(r, format!("SETUP/START,{} again under another CSYS than at line {line}: a copy of the set-up (a pattern), whose points CAMWorks writes already placed, in the CL frame, where kinpost reads a set-up's points in its CSYS frame (as for a part turned over): read that way, every copy would be cut where the first one is; refused rather than guessed: have the CAM system write the copies without a CSYS of their own, or post them as programs of their own", crate::numeric::readable(n)))),
            Some(_) => Ok(()),
            None => {
                self.setups.push((n, self.csys, r.line));
                Ok(())
            }
        }
    }

    /// The program's own `UNITS`/`UNIT` statement `u` (at `r`): followed;
    /// where `--units` said other units, a warning (once).
    pub(super) fn own_units(&mut self, r: &ClRecord, u: ClUnits) {
        self.units_seen = true;
        self.mm_per_unit = match u {
            ClUnits::Mm => 1.0,
            ClUnits::Inches => 25.4,
        };
        if let Some(given) = self.default_units.take()
            && given != u
        {
            let name = |u: ClUnits| if u == ClUnits::Mm { "mm" } else { "inch" };
            self.emit(
                r,
                ClStatement::Warning(format!(
                    "{}:{}:{}: the program says its units ({}), which it follows; --units {} applies to a program without a UNITS statement",
                    self.file, r.line, r.col, name(u), name(given)
                )),
            );
        }
    }

    /// Whether the set-up in force (`CSYS`) is a left-handed frame, which
    /// mirrors the path.
    pub(super) fn mirrored(&self) -> bool {
        self.csys.is_some_and(|(m, _)| det(m) < 0.0)
    }

    /// Emits a move to `tip` (CL frame) with the current tool axis.
    pub(super) fn go(&mut self, r: &ClRecord, tip: [f64; 3], rapid: bool) {
        self.rapid_pending = false;
        if rapid {
            self.emit(r, ClStatement::Rapid);
        }
        let (t, a) = (self.to_setup(tip), self.dir_to_setup(self.axis));
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
    pub(super) fn feed_record(&mut self, r: &ClRecord, value: f64, unit: FeedUnit) {
        for s in feed_statements(&mut self.per_rev, value, unit) {
            self.emit(r, s);
        }
    }

    pub(super) fn numbers(
        &self,
        r: &ClRecord,
        args: &[Arg],
        what: &str,
    ) -> Result<Vec<f64>, Error> {
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
}

/// The determinant of a 3×3 matrix (rows).
pub(super) fn det(m: [[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// A statement's text as a G-code comment, `(…)`: its lines (a statement
/// continued with `$`) joined by a blank, parentheses turned into
/// brackets, so that the comment stays on one line and closes where it
/// should.
pub(super) fn as_comment(text: &[u8]) -> String {
    let joined: Vec<String> = String::from_utf8_lossy(text)
        .lines()
        .map(|l| l.trim().replace('(', "[").replace(')', "]"))
        .filter(|l| !l.is_empty())
        .collect();
    format!("({})", joined.join(" "))
}
