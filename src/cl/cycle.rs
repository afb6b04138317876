//! `CYCLE/…` then `GOTO`s: holes. Every `GOTO` is a hole whose top is the
//! point; `RAPTO` and `RTRCTO` are distances above it along the tool axis,
//! `FEDTO` the depth below it. Each hole becomes a [`HoleMove`]: the
//! converter writes it as a canned cycle (`G81`…`G89`, `G73`) when the tool
//! is along the machine's Z axis, else as the expansion into moves.

use std::io::BufRead;

use super::state::{Cycle, CycleKind, Lowered, absurd_feed, feed_statements};
use super::vec3::{add, dot, norm, num, scale, sub};
use super::{Arg, ClRecord, ClStatement, FeedUnit};
use crate::error::Error;

/// One hole of a canned cycle (made by [`super::lower`], never by the
/// reader), in the set-up frame and in CL units.
#[derive(Debug, Clone, PartialEq)]
pub struct HoleMove {
    /// The canned cycle that drills it when the tool is along the
    /// machine's Z axis: 81, 82, 83, 73, 84, 85, 86 or 89 (`G81`…); `None`
    /// when no canned cycle says the same (e.g. a second peck depth).
    pub code: Option<u8>,
    /// The retract level: `RTRCTO` above the top.
    pub clear: [f64; 3],
    /// The `R` level: `RAPTO` above the top.
    pub r_plane: [f64; 3],
    /// The bottom: `FEDTO` below the top.
    pub bottom: [f64; 3],
    /// Tool axis.
    pub axis: [f64; 3],
    /// Peck depth (`Q`), 0 when none.
    pub peck: f64,
    /// Dwell at the bottom (`P`), s.
    pub dwell_s: f64,
    /// `RTRCTO` equals `RAPTO`: retract to `R` (`G99`), else to the
    /// retract level (`G98`).
    pub retract_to_r: bool,
    /// The feed statements before the hole (the cycle's feed), for the
    /// canned form.
    pub feed_before: Vec<ClStatement>,
    /// The feed statements after it (the previous feed back).
    pub feed_after: Vec<ClStatement>,
    /// The hole as moves (with the feed statements), `None` when moves
    /// cannot say it (tapping, a spindle stop at the bottom): then a tool
    /// not along the machine's Z axis refuses the program.
    pub moves: Option<Vec<ClStatement>>,
    /// Set by the converter once the tool is at the retract level above
    /// the hole (the canned block is written next).
    pub positioned: bool,
}

impl Cycle {
    /// The canned cycle for holes of this cycle, if one says the same.
    fn canned_code(&self) -> Option<u8> {
        if self.rtrcto < self.rapto {
            return None;
        }
        let dwell = self.dwell > 0.0;
        let one_peck = self.sub_peck == 0.0 || self.sub_peck == self.first_peck;
        match self.kind {
            CycleKind::Drill if dwell => Some(82),
            CycleKind::Drill => Some(81),
            CycleKind::BrkChp if self.first_peck == 0.0 && dwell => Some(82),
            CycleKind::BrkChp if self.first_peck == 0.0 => Some(81),
            CycleKind::Deep | CycleKind::BrkChp if dwell || !one_peck => None,
            CycleKind::Deep => Some(83),
            CycleKind::BrkChp => Some(73),
            CycleKind::Bore if dwell => Some(89),
            CycleKind::Bore => Some(85),
            CycleKind::BoreDrag => Some(86),
            CycleKind::Tap => Some(84),
        }
    }
}

impl<R: BufRead> Lowered<R> {
    pub(super) fn hole(&mut self, r: &ClRecord, c: &Cycle, top: [f64; 3]) -> Result<(), Error> {
        let per_rev_before = self.per_rev;
        let mark = self.out.len();
        let na = norm(self.axis);
        let a = scale(self.axis, 1.0 / na);
        let at = |d: f64| add(top, scale(a, d));
        // RTRCTO,AUTO: back to the level the tool comes from (at least R).
        let rtrcto = match (c.rtrcto_auto, self.pos) {
            (true, Some(p)) => dot(sub(p, top), a).max(c.rapto),
            (true, None) => c.rapto,
            (false, _) => c.rtrcto,
        };
        let c = &Cycle {
            rtrcto,
            ..c.clone()
        };
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
                // The pecks count from the R level (RAPTO), as the canned
                // form's Q does on the controllers: the same hole drills
                // alike as G83 / G73 and as moves.
                let mut reached = c.rapto;
                let mut peck = c.first_peck;
                // The clearance above the last depth (down again, and the
                // chip-breaking retract): 0.5 mm in the CL's units.
                let clearance = 0.5 / self.mm_per_unit;
                loop {
                    let mut target = (reached - peck).max(bottom);
                    // Pecks that add up to the depth but for rounding
                    // (0.3 + 3 × 0.2 = 0.9000000000000001) reach it.
                    if target - bottom <= 1e-9 * (1.0 + bottom.abs()) {
                        target = bottom;
                    }
                    if reached < c.rapto {
                        // Back down to just above the last depth.
                        let back = (reached + clearance).min(c.rapto);
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
                        (target + clearance).min(c.rapto)
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
        let moves: Vec<ClStatement> = self.out.drain(mark..).map(|m| m.statement).collect();
        // The same feed changes for the canned form.
        let mut per_rev = per_rev_before;
        let feed_before = match c.feed {
            Some((f, u)) => feed_statements(&mut per_rev, f, u).into_iter().collect(),
            None => Vec::new(),
        };
        let feed_after = match (old_feed, c.feed) {
            (Some((f, u)), Some(_)) => feed_statements(&mut per_rev, f, u).into_iter().collect(),
            _ => Vec::new(),
        };
        let hole = HoleMove {
            code: c.canned_code().filter(|_| !self.cutcom),
            clear: self.to_setup(clear),
            r_plane: self.to_setup(r_plane),
            bottom: self.to_setup(at(bottom)),
            axis: self.dir_to_setup(a),
            peck: c.first_peck,
            dwell_s: c.dwell,
            retract_to_r: c.rtrcto == c.rapto,
            feed_before,
            feed_after,
            moves: match c.kind {
                CycleKind::Tap | CycleKind::BoreDrag => None,
                _ => Some(moves),
            },
            positioned: false,
        };
        self.emit(r, ClStatement::Hole(Box::new(hole)));
        Ok(())
    }

    pub(super) fn cycle(&mut self, r: &ClRecord, args: &[Arg]) -> Result<(), Error> {
        let Some(first) = args.first() else {
            return Err(self.err(
                r,
                "CYCLE expects a cycle type (DRILL, DEEP, BRKCHP, BORE, REAM, TAP, ON, OFF, ...)",
            ));
        };
        let comment = super::state::as_comment(&r.text);
        let mut k = 1;
        let mut c = match first.upper().as_str() {
            "OFF" => {
                self.cycle = None;
                self.block(r, "G80");
                return Ok(());
            }
            // CAMWorks writes CYCLE/CLEAR before a cycle: its parameters
            // reset, no motion (as INIT).
            "INIT" | "CLEAR" if args.len() == 1 => {
                self.block(r, comment);
                return Ok(());
            }
            "INIT" => {
                self.block(r, comment);
                return Ok(());
            }
            "ON" if args.len() == 1 => {
                self.block(r, comment);
                return Ok(());
            }
            // NX: CYCLE/ON,words changes the cycle in force.
            "ON" => match self.cycle.clone() {
                Some(c) => c,
                None => {
                    return Err(self.err(
                        r,
                        "CYCLE/ON with words changes the cycle in force, but no cycle is in force",
                    ));
                }
            },
            w => {
                let kind = match w {
                    "DRILL" | "FACE" | "CSINK" | "SPOT" => CycleKind::Drill,
                    "DEEP" | "DEEP2" => CycleKind::Deep,
                    "BRKCHP" => CycleKind::BrkChp,
                    "BORE" | "REAM" => CycleKind::Bore,
                    "TAP" => CycleKind::Tap,
                    other => {
                        return Err(self.err(r, format!("CYCLE/{other} is not supported (cycles: DRILL, FACE, CSINK, SPOT, DEEP, DEEP2, BRKCHP, BORE, REAM, TAP); the program is refused rather than drilling wrongly")));
                    }
                };
                Cycle {
                    kind,
                    depth: f64::NAN,
                    rapto: 0.0,
                    rtrcto: f64::NAN,
                    rtrcto_auto: false,
                    feed: None,
                    dwell: 0.0,
                    first_peck: 0.0,
                    sub_peck: 0.0,
                }
            }
        };
        // NX writes the kind as DRILL followed by a modifier
        // (CYCLE/DRILL,DEEP,...); BORE,DRAG stops the spindle at the bottom.
        while let Some(m) = args.get(k) {
            c.kind = match (c.kind, m.upper().as_str()) {
                (CycleKind::Drill, "DEEP") => CycleKind::Deep,
                (CycleKind::Drill, "BRKCHP") => CycleKind::BrkChp,
                (CycleKind::Drill, "TAP") => CycleKind::Tap,
                (CycleKind::Drill, "BORE") => CycleKind::Bore,
                (CycleKind::Bore, "DRAG") => CycleKind::BoreDrag,
                _ => break,
            };
            k += 1;
        }
        // A number no word names: the classic positional form.
        let mut loose = false;
        // Creo's couplet form: DEPTH, and CLEAR and RAPTO in one statement.
        let (mut creo_depth, mut clear, mut rapid_to) = (false, None, None);
        let mut rtrcto_given = false;
        while k < args.len() {
            let w = args[k].upper();
            let val = |k: usize| -> Result<f64, Error> {
                args.get(k)
                    .and_then(|a| a.number())
                    .ok_or_else(|| self.err(r, format!("CYCLE: expected a number after {w}")))
            };
            match w.as_str() {
                // A signed depth (NX: negative below the point) or a depth
                // below the point (SolidWorks CAM: positive).
                "FEDTO" | "DEPTH" => {
                    c.depth = val(k + 1)?.abs();
                    creo_depth = w == "DEPTH";
                }
                "RAPTO" | "CLEAR" => {
                    c.rapto = val(k + 1)?;
                    if w == "CLEAR" {
                        clear = Some(c.rapto);
                    } else {
                        rapid_to = Some(c.rapto);
                    }
                }
                "RTRCTO" if args.get(k + 1).is_some_and(|a| a.is("AUTO")) => {
                    c.rtrcto_auto = true;
                    rtrcto_given = true;
                }
                "RTRCTO" => {
                    c.rtrcto = val(k + 1)?;
                    c.rtrcto_auto = false;
                    rtrcto_given = true;
                }
                // NX: RTRCTO,r,MANUAL (the level given).
                "MANUAL" => {
                    k += 1;
                    continue;
                }
                "DWELL" => c.dwell = val(k + 1)?,
                // CAMWorks: INCR, the peck increment of CYCLE/DEEP.
                "1STPECK" | "STEP" | "INCR" => c.first_peck = val(k + 1)?,
                "SUBPECK" => c.sub_peck = val(k + 1)?,
                "MMPM" | "IPM" | "MMPR" | "IPR" => {
                    let u = super::statement::feed_unit(&args[k]).unwrap_or(FeedUnit::Unspecified);
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
                        loose = true;
                        k += 1;
                        continue;
                    }
                    return Err(self.err(r, format!("CYCLE: unknown word {w}")));
                }
            }
            k += 2;
        }
        // The classic positional form `CYCLE/DRILL,d,MMPM,f,c`: CAM systems
        // write it with different meanings. Autodesk's common ISO 4343 APT
        // post writes the hole's bottom as the point, `c` the clearance
        // height and `RAPTO` its distance to the retract plane; the
        // CAMplete-style post the hole's top, `c` the clearance's height
        // above the bottom; APT's own reading is the top and a clearance
        // above it. The depth drilled would differ by the hole's depth.
        if loose {
            return Err(self.err(
                r,
                "CYCLE with numbers no word names (the positional form CYCLE/DRILL,d,MMPM,f,c) is not converted: CAM posts write it with the point at the hole's top or at its bottom and c as a distance or a height, so the depth drilled is not known; write the cycle with FEDTO, RAPTO (or CLEAR) and RTRCTO, or have the CAM system expand the holes into moves",
            ));
        }
        // Creo writes `CYCLE/DRILL, DEPTH, a, IPM, b, CLEAR, c, RAPTO, d`:
        // `c` the clearance above the point (where the hole starts and the
        // tool returns to), `d` a further rapid from there towards the
        // point (PTC, "CL Output for Holemaking Cycles"). The R level is
        // then `c − d` above the point, the retract level `c`. (The other
        // posts write FEDTO and take RAPTO as the R level: below.)
        if creo_depth && let (Some(cl), Some(rt)) = (clear, rapid_to) {
            if rt > cl {
                return Err(self.err(
                    r,
                    format!(
                        "CYCLE: RAPTO,{} rapids beyond the point from CLEAR,{} (Creo measures RAPTO from the clearance towards the point)",
                        num(rt),
                        num(cl)
                    ),
                ));
            }
            c.rapto = cl - rt;
            if !rtrcto_given {
                c.rtrcto = cl;
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
            // No step: one peck from the R level to the bottom (NX writes
            // `CYCLE/DRILL,DEEP,RAPTO,3,FEDTO,0` for a countersink; with
            // the depth alone as the peck that was Q0.001, 3,000 pecks).
            c.first_peck = (c.depth + c.rapto.max(0.0)).max(1e-3);
        }
        self.block(r, comment);
        self.cycle = Some(c);
        self.cycle_line = r.line;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::HoleMove;
    use crate::cl::lower::tests::{blocks, gotos, near, run};
    use crate::cl::{ClStatement, FeedUnit};

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
        // Pecks of 4 from the R level (2): down to -2, -6 and the bottom,
        // as G83 Q4 R2 drills.
        let z: Vec<f64> = gotos(&s).iter().map(|p| p[2]).collect();
        assert_eq!(z.iter().cloned().fold(f64::INFINITY, f64::min), -10.0);
        assert!(z.contains(&-2.0) && z.contains(&-6.0), "{z:?}");
        assert!(!z.contains(&-4.0), "{z:?}");
        let e = run("CYCLE/THREAD,FEDTO,5\n").unwrap_err();
        assert!(e.to_string().contains("t.apt:1:1"));
    }

    /// Which canned cycle each CL cycle gives, and the hole's levels.
    #[test]
    fn canned_codes() {
        let hole = |cycle: &str| -> HoleMove {
            let text = format!("UNITS/MM\nGOTO/0,0,50\nCYCLE/{cycle}\nGOTO/1,2,3\n");
            run(&text)
                .unwrap()
                .into_iter()
                .find_map(|s| match s {
                    ClStatement::Hole(h) => Some(*h),
                    _ => None,
                })
                .unwrap()
        };
        let cases = [
            ("DRILL,FEDTO,5,RAPTO,2,RTRCTO,10", Some(81)),
            ("SPOT,FEDTO,5,RAPTO,2,DWELL,0.5", Some(82)),
            ("DEEP,FEDTO,5,RAPTO,2,STEP,1", Some(83)),
            ("DEEP,FEDTO,5,1STPECK,2,SUBPECK,1", None),
            ("DEEP,FEDTO,5,STEP,1,DWELL,1", None),
            ("BRKCHP,FEDTO,5,STEP,1", Some(73)),
            ("BRKCHP,FEDTO,5", Some(81)),
            ("TAP,FEDTO,5,MMPR,1.25,RAPTO,3", Some(84)),
            ("BORE,FEDTO,5", Some(85)),
            ("BORE,DRAG,FEDTO,5", Some(86)),
            ("REAM,FEDTO,5,DWELL,2", Some(89)),
            ("DRILL,FEDTO,5,RAPTO,4,RTRCTO,2", None),
        ];
        for (c, code) in cases {
            assert_eq!(hole(c).code, code, "{c}");
        }
        let h = hole("DRILL,FEDTO,5,MMPM,80,RAPTO,2,RTRCTO,10");
        assert!(near(h.clear, [1.0, 2.0, 13.0]) && near(h.r_plane, [1.0, 2.0, 5.0]));
        assert!(near(h.bottom, [1.0, 2.0, -2.0]) && !h.retract_to_r);
        assert_eq!(
            h.feed_before,
            [ClStatement::Fedrat {
                value: 80.0,
                unit: FeedUnit::Mmpm
            }]
        );
        assert!(h.moves.is_some() && hole("TAP,FEDTO,5").moves.is_none());
        assert!(hole("DRILL,FEDTO,5,RAPTO,2").retract_to_r);
        // CYCLE/OFF cancels the cycle: G80.
        let s = run("UNITS/MM\nCYCLE/DRILL,FEDTO,5\nCYCLE/OFF\n").unwrap();
        assert!(blocks(&s).contains(&"G80".to_string()));
    }

    /// Under cutter compensation a hole is moves (controllers refuse a
    /// canned cycle with G41/G42 on).
    #[test]
    fn no_canned_cycle_under_cutter_compensation() {
        let code = |text: &str| {
            run(text)
                .unwrap()
                .into_iter()
                .find_map(|s| match s {
                    ClStatement::Hole(h) => Some(h.code),
                    _ => None,
                })
                .unwrap()
        };
        let hole = "CYCLE/DRILL,FEDTO,5\nGOTO/0,0,0\n";
        assert_eq!(code(&format!("UNITS/MM\nCUTCOM/LEFT\n{hole}")), None);
        assert_eq!(
            code(&format!("UNITS/MM\nCUTCOM/LEFT\nCUTCOM/OFF\n{hole}")),
            Some(81)
        );
    }
}
