//! The tool poses of APT CL data as one stream of events, and the blocks of
//! a program written in machine axes, for the commands that read a program
//! without rewriting it (analyze, simulate). (A G-code pose program is read
//! with `post`'s own reader: `crate::trajectory`.)

use super::arc::ArcModes;
use super::modal::{Motion, PoseStart, TOOL_VECTOR_TOLERANCE, WordRef};
pub use super::pose_program::looks_like_poses;
use super::{ModalState, Units};
use crate::cl::{ClReader, ClStatement, FeedUnit};
use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, LineReader};
use crate::machine::Pose;
use nalgebra::Vector3;
use std::io::BufRead;

/// One pose of a program.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseEvent {
    /// 1-based line number of the block.
    pub line: usize,
    /// The block's N number, if it has one.
    pub n: Option<f64>,
    /// Tool tip (mm) and unit tool axis, workpiece frame.
    pub pose: Pose,
    /// Feed in force, mm/min (None in G93/G95 or when none was given).
    pub feed_mm_min: Option<f64>,
    /// Rapid move (G0 / RAPID).
    pub rapid: bool,
    /// Cutter compensation in force (`CUTCOM/LEFT|RIGHT`, APT CL only).
    pub cutter_comp: Option<CutterComp>,
}

/// Cutter compensation of APT CL that is on: the controller offsets the
/// moves by the tool radius in its X Y plane (`G41`/`G42`, as `post`
/// writes it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CutterComp {
    /// The line of the `CUTCOM/LEFT|RIGHT` statement.
    pub line: usize,
    /// To the left of the path (`G41`), else to the right (`G42`).
    pub left: bool,
}

/// Reads the poses of APT CL data, lowered as `post` lowers them
/// ([`crate::cl::lower`]): `CSYS` set-ups applied, `CIRCLE` arcs as their
/// points within the default chord tolerance (1 µm), `CYCLE` holes as
/// their moves (a hole moves cannot say, such as tapping, as the straight
/// path down to its bottom and back), so that what is analysed is the
/// path `post` writes.
pub fn cl_poses<R: BufRead>(
    input: R,
    file: &str,
    default_units: Option<crate::cl::ClUnits>,
    mut f: impl FnMut(PoseEvent) -> Result<()>,
) -> Result<()> {
    let mut axis = Vector3::z();
    let mut units = Units::Mm;
    let mut feed = None;
    let mut per_rev = false;
    // A feed per revolution (mm/rev) and the spindle's speed that makes it
    // a feed per minute.
    let (mut rev_feed, mut spindle) = (None, super::spindle::Spindle::default());
    let mut rapid = false;
    let mut cutter_comp = None;
    let mut records = crate::cl::lower(
        ClReader::new(input, file),
        file,
        crate::cl::DEFAULT_ARC_TOLERANCE_MM,
        default_units,
    );
    // Moves an arc or a hole stands for, read before the next record.
    let mut pending: std::collections::VecDeque<crate::cl::ClRecord> = Default::default();
    while let Some(record) = pending.pop_front().map(Ok).or_else(|| records.next()) {
        let record = record?;
        let steps: Option<Vec<ClStatement>> = match &record.statement {
            ClStatement::Arc(arc) => Some(arc.moves.clone()),
            ClStatement::Hole(hole) => Some(hole.moves.clone().unwrap_or_else(|| {
                [hole.clear, hole.r_plane, hole.bottom, hole.clear]
                    .into_iter()
                    .map(|tip| ClStatement::Goto {
                        tip,
                        axis: Some(hole.axis),
                    })
                    .collect()
            })),
            _ => None,
        };
        if let Some(steps) = steps {
            for (k, statement) in steps.into_iter().enumerate() {
                pending.insert(
                    k,
                    crate::cl::ClRecord {
                        line: record.line,
                        col: record.col,
                        text: record.text.clone(),
                        statement,
                    },
                );
            }
            continue;
        }
        match record.statement {
            ClStatement::Goto { tip, axis: a } => {
                if let Some(a) = a {
                    axis = Vector3::from(a);
                }
                let norm = axis.norm();
                if norm.is_nan() || norm <= 1e-12 || (norm - 1.0).abs() > TOOL_VECTOR_TOLERANCE {
                    return Err(Error::input_with(
                        Location::new(file, record.line, record.col),
                        format!("tool axis of length {norm:.6}: expected a unit vector"),
                        String::from_utf8_lossy(&record.text).trim().to_string(),
                    ));
                }
                f(PoseEvent {
                    line: record.line,
                    n: None,
                    pose: Pose::new(Vector3::from(tip) * units.mm_per_unit(), axis / norm),
                    feed_mm_min: if per_rev {
                        rev_feed.zip(spindle.rpm()).map(|(f, n)| f * n)
                    } else {
                        feed
                    },
                    rapid,
                    cutter_comp,
                })?;
                rapid = false;
            }
            ClStatement::TlAxis(a) => axis = Vector3::from(a),
            ClStatement::CutterCompensation { ref block, on } => {
                cutter_comp = on.then(|| CutterComp {
                    line: record.line,
                    left: block.starts_with("G41"),
                })
            }
            ClStatement::Rapid => rapid = true,
            ClStatement::Units(u) => {
                units = match u {
                    crate::cl::ClUnits::Inches => Units::Inch,
                    crate::cl::ClUnits::Mm => Units::Mm,
                }
            }
            // The lowering gives a feed per revolution as `G95` and the
            // feed in mm/rev (`cl::lower`): a feed per minute only with the
            // spindle's speed (its `S M3` blocks), until `G94`.
            ClStatement::Block(ref b) if b == "G95" || b == "G94" => {
                per_rev = b == "G95";
                if per_rev {
                    feed = None;
                }
            }
            ClStatement::Block(ref b) => {
                spindle.line(&crate::gcode::parse_line(b.as_bytes(), record.line));
            }
            ClStatement::Spindle { rpm, off, .. } => spindle.apt(rpm, off),
            ClStatement::Fedrat { value, unit } if per_rev => {
                feed = None;
                rev_feed = Some(match unit {
                    FeedUnit::Mmpr | FeedUnit::Mmpm => value,
                    FeedUnit::Ipr | FeedUnit::Ipm => value * 25.4,
                    FeedUnit::Unspecified => value * units.mm_per_unit(),
                });
            }
            ClStatement::Fedrat { value, unit } => {
                feed = match unit {
                    FeedUnit::Mmpm => Some(value),
                    FeedUnit::Ipm => Some(value * 25.4),
                    FeedUnit::Unspecified => Some(value * units.mm_per_unit()),
                    FeedUnit::Mmpr | FeedUnit::Ipr => None,
                }
            }
            _ => {}
        }
        // The next record is read into its text.
        records.recycle(record.text);
    }
    Ok(())
}

/// One block of a program written in machine axes.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisEvent {
    /// 1-based line number of the block.
    pub line: usize,
    /// Joint values after the block, chain order, mm / rad.
    pub q: Vec<f64>,
    /// Feed in force, mm/min (G94) or None.
    pub feed_mm_min: Option<f64>,
    /// Millimetres per unit of the feed's length (25.4 in G20): a move of
    /// rotaries alone runs at `feed_mm_min / feed_unit_mm` deg/min.
    pub feed_unit_mm: f64,
    /// Inverse-time feed in force (G93), 1/min, or None.
    pub inverse_time: Option<f64>,
    /// Rapid move (G0).
    pub rapid: bool,
    /// The block does not start where the previous event ended: it follows
    /// a move whose end the program's coordinates do not give (G28, G30,
    /// G53), or a move that is not followed (a canned cycle), so the
    /// segment between the two is not known.
    pub restart: bool,
    /// A circular move (`G2`, `G3`): not a straight move of the joints.
    pub arc: bool,
    /// The joint values a circular move passes through between the
    /// previous event and `q` (both excluded), in order
    /// ([`arc_joint_path`]), where asked for; empty otherwise.
    pub via: Vec<Vec<f64>>,
}

/// Largest distance of the straight pieces that stand for a circular move
/// ([`arc_joint_path`]) from the arc, mm.
pub const ARC_TOLERANCE_MM: f64 = 1e-4;

/// The joint values (chain order, mm / rad) a circular move (`G2`/`G3`)
/// of `line` passes through from `from` to `to`, both excluded: the
/// machine's X, Y and Z along the arc ([`ArcModes::points`], no piece more
/// than [`ARC_TOLERANCE_MM`] from it), its other joints evenly with the
/// arc's angle. `mm_per_unit` converts the line's `I J K R` to mm. Refused
/// at the line of `file` and the word to blame where the arc is not one
/// [`ArcModes::points`] follows, or the machine lacks an axis of its plane.
pub fn arc_joint_path(
    machine: &crate::machine::Machine,
    modes: &ArcModes,
    line: &crate::gcode::Line,
    file: &str,
    from: &[f64],
    to: &[f64],
    mm_per_unit: f64,
) -> Result<Vec<Vec<f64>>> {
    let refused = |(col, message): super::arc::ArcError| {
        Error::input_with(
            Location::new(file, line.number, col),
            message,
            line.text_lossy(),
        )
    };
    let joint_of = |name: &str| {
        machine
            .axis(name)
            .filter(|a| a.kind == crate::machine::JointKind::Prismatic)
            .map(|a| a.joint)
    };
    let joints = [joint_of("X"), joint_of("Y"), joint_of("Z")];
    let names = ["X", "Y", "Z"];
    let [a, b, _] = modes.plane().axes();
    for k in [a, b] {
        if joints[k].is_none() {
            // The block as a whole: the plane may be set lines before.
            return Err(refused((
                1,
                format!(
                    "the arc in {} moves {} and {}, and machine {} has no {} axis",
                    modes.plane().code(),
                    names[a],
                    names[b],
                    machine.name,
                    names[k]
                ),
            )));
        }
    }
    let at = |q: &[f64]| joints.map(|j| j.map_or(0.0, |j| q[j]));
    let points = modes
        .points(line, at(from), at(to), mm_per_unit, ARC_TOLERANCE_MM)
        .map_err(refused)?;
    let inner = &points[..points.len().saturating_sub(1)];
    Ok(inner
        .iter()
        .map(|(f, p)| {
            let mut q: Vec<f64> = from.iter().zip(to).map(|(a, b)| a + f * (b - a)).collect();
            for (k, j) in joints.iter().enumerate() {
                if let Some(j) = j {
                    q[*j] = p[k];
                }
            }
            q
        })
        .collect())
}

/// A motion block of a program in machine axes.
#[derive(Debug, Clone)]
pub struct MachineBlock {
    /// Joint values after the block, chain order, mm / rad.
    pub q: Vec<f64>,
    /// The modal state in force for the block.
    pub meaning: super::BlockMeaning,
    /// Items of the machine-axis words in the line.
    pub axis_items: Vec<usize>,
    /// Whether every axis was at a known position (in program coordinates)
    /// where the block starts: not after `G28`, `G30`, `G53` or
    /// `G92.1`–`G92.3` until each axis they moved is programmed again.
    pub start_known: bool,
    /// Whether every axis is at a known position where the block ends.
    pub end_known: bool,
    /// Whether the block's segment can be measured (its nonlinear error,
    /// the points `linkage` inserts): where it starts is known, or no
    /// rotary axis turns (none moves, none not known is programmed): the
    /// tool tip then moves on a straight line whatever the start.
    pub measurable: bool,
}

/// Whether `words` hold the G code `code`.
fn g_word(words: &[WordRef<'_>], code: f64) -> bool {
    words
        .iter()
        .any(|w| w.address == "G" && (w.value - code).abs() < 1e-6)
}

/// The addresses of axis words: a block's motion.
const MOTION_AXES: [&str; 9] = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"];

/// Follows the axis positions and modal state of a program in machine axes
/// (absolute or incremental, mm or inch). Axes not yet programmed are 0
/// (mm / deg).
#[derive(Debug, Clone)]
pub struct MachineAxisTracker {
    modal: ModalState,
    /// Where a Sinumerik frame that turns, scales or mirrors the
    /// coordinates, or a LinuxCNC rotated coordinate system, was set, while
    /// it is active: the line and what it is. Moves under it are refused.
    frame: Option<(usize, String)>,
    /// The line of the G-code frame the modal state has active.
    gcode_frame: Option<usize>,
    ext: Vec<f64>,
    /// Axes whose position in program coordinates is not known (after a
    /// move to the reference point or in machine coordinates, or a canned
    /// cycle).
    unknown: Vec<bool>,
    /// A canned cycle is the motion mode (`G73`, `G74`, `G76`, `G81`–`G89`,
    /// until `G80` or another motion).
    cycle: bool,
    /// The axis a canned cycle drills along: normal to the plane (`G17`
    /// Z, `G18` Y, `G19` X).
    cycle_axis: &'static str,
    /// The `%` that ends the program: what follows it is not read.
    tape: super::tape::TapeEnd,
}

impl MachineAxisTracker {
    /// A tracker at program start for `machine`.
    pub fn new(machine: &crate::machine::Machine) -> Self {
        MachineAxisTracker {
            modal: ModalState::new(PoseStart::Off),
            frame: None,
            gcode_frame: None,
            ext: vec![0.0; machine.axes.len()],
            unknown: vec![false; machine.axes.len()],
            cycle: false,
            cycle_axis: "Z",
            tape: Default::default(),
        }
    }

    /// Refuses a move whose motion words cannot be followed: an axis word
    /// the machine does not have (`B45` on an A/C machine: the program is
    /// for another machine), and a motion word holding what kinpost does
    /// not evaluate (`Y#1`, `Y[#1*4]`, `X=R1`, `I[-#104]`, `F#3`: a
    /// parameter, an expression or a malformed number, whose text also
    /// hides the rest of the block).
    fn check_motion_words(
        &self,
        machine: &crate::machine::Machine,
        line: &crate::gcode::Line,
        file: &str,
    ) -> Result<()> {
        let refuse = |item: &crate::gcode::Item, message: String| {
            Err(Error::input_with(
                Location::new(file, line.number, item.start + 1),
                message,
                line.text_lossy(),
            ))
        };
        for (index, item) in line.items.iter().enumerate() {
            match &item.kind {
                ItemKind::Word(w)
                    if MOTION_AXES.contains(&w.address.as_str())
                        && !machine.axes.iter().any(|a| a.name == w.address) =>
                {
                    let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
                    // On a Fanuc lathe (G code system A) U and W are X
                    // and Z given as increments.
                    let lathe = match w.address.as_str() {
                        "U" => {
                            " (or a lathe program, where U is an increment of X, which kinpost does not read)"
                        }
                        "W" => {
                            " (or a lathe program, where W is an increment of Z, which kinpost does not read)"
                        }
                        _ => "",
                    };
                    return refuse(
                        item,
                        format!(
                            "axis word {} in a move, and machine {} has no {} axis (its axes: {}): the program is for another machine{lathe}, and this move cannot be followed",
                            w.address,
                            machine.name,
                            w.address,
                            names.join(" ")
                        ),
                    );
                }
                // A machine axis named by its number (`Z1=5`, `AX4=30`),
                // outside a reference or fixed point approach (`G74 Z1=0`).
                ItemKind::Word(w)
                    if super::unfollowed::numbered_axis(&w.address)
                        && !line
                            .words()
                            .any(|g| g.is("G") && [74.0, 75.0].contains(&g.value)) =>
                {
                    return refuse(
                        item,
                        format!(
                            "`{}=` names a machine axis by its number (Sinumerik X1, Z1, AX4): this command follows the axes by their names ({}) and would not follow it; write the axis by its name",
                            w.address,
                            machine
                                .axes
                                .iter()
                                .map(|a| a.name.as_str())
                                .collect::<Vec<_>>()
                                .join(" ")
                        ),
                    );
                }
                // (`CR=`, an arc's radius, and `AR=` are `program::arc`'s.)
                ItemKind::Word(w)
                    if super::unfollowed::PATH_WORDS.contains(&w.address.as_str())
                        && !matches!(w.address.as_str(), "CR" | "AR") =>
                {
                    return refuse(
                        item,
                        format!(
                            "`{}=` {}: this command follows the axis words as straight moves and arcs, and would not follow it; have the CAM system write the path",
                            w.address,
                            super::unfollowed::path_word(&w.address)
                        ),
                    );
                }
                ItemKind::Opaque => {
                    let text = String::from_utf8_lossy(line.item_bytes(item));
                    let text = text.trim();
                    if text.starts_with(',') {
                        return refuse(item, super::opaque::describe_opaque(text.as_bytes()));
                    }
                    if text.starts_with(['@', '^']) {
                        return refuse(
                            item,
                            format!(
                                "polar coordinates (`{}`: LinuxCNC `@` radius, `^` angle; or a Sinumerik 840C `@` instruction): this command follows X Y Z as Cartesian axis words and would not follow it; write Cartesian coordinates in the CAM post",
                                crate::error::visible(text)
                            ),
                        );
                    }
                    if super::opaque::unreadable_motion_at(line, index) {
                        return refuse(
                            item,
                            format!(
                                "this move holds syntax kinpost does not evaluate (`{}`: a parameter, an expression or a malformed number): where the axes go is not known; evaluate it first (in the CAM system or the controller's simulation)",
                                crate::error::visible(text)
                            ),
                        );
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Follows the frames `line` sets or cancels: the G codes the modal
    /// state reads (`G68`…, `G51`, `G51.1`, `G16`, `G254`, their cancels),
    /// LinuxCNC's rotation of a coordinate system (`G10 L2`/`L20` with
    /// `R`), and the Sinumerik frame keywords (`program::frames`) but
    /// translations alone (`TRANS`, `ATRANS`), which move the program's
    /// origin as a work offset does, which this command leaves to
    /// `--work-offset`.
    fn follow_frames(
        &mut self,
        line: &crate::gcode::Line,
        modal_words: &[WordRef<'_>],
        keywords: &[(usize, &str)],
    ) {
        let word = |a: &str| line.words().find(|w| w.address == a).map(|w| w.value);
        let rotation = g_word(modal_words, 10.0)
            && matches!(word("L"), Some(l) if l == 2.0 || l == 20.0)
            && word("R").is_some();
        let values = super::frames::values(line.words().map(|w| (w.address.as_str(), w.value)));
        let mut set = None;
        for &(_, k) in keywords {
            match super::frames::change(k, values) {
                Some(super::frames::FrameChange::Delete) => self.frame = None,
                Some(super::frames::FrameChange::Set) if !["TRANS", "ATRANS"].contains(&k) => {
                    set = Some(if k == super::fagor::FRAME_ON {
                        "a Fagor coordinate system or transformation (#CS, #ACS, #MCS, #FACE, #CYL, #TOOL AX)".to_string()
                    } else {
                        format!("the Sinumerik frame {k}")
                    });
                }
                _ => {}
            }
        }
        if rotation {
            if word("R") == Some(0.0) {
                self.frame = None;
            } else {
                set = Some("a rotated coordinate system (G10 L2 R)".into());
            }
        }
        if let Some(what) = set {
            self.frame = Some((line.number, what));
        }
        // The G-code frames, from the modal state: where the first of them
        // was set, while any is active.
        self.gcode_frame =
            super::frames::frame_since(self.modal.frame_seen, self.gcode_frame, line.number);
    }

    /// The active frame a move may not be made under: where it was set and
    /// what it is.
    fn active_frame(&self) -> Option<(usize, String)> {
        self.gcode_frame
            .map(|at| (at, super::frames::GCODE_FRAMES.to_string()))
            .or_else(|| self.frame.clone())
    }

    /// Applies one line; returns the block when it carries machine-axis words.
    pub fn line(
        &mut self,
        machine: &crate::machine::Machine,
        line: &crate::gcode::Line,
        file: &str,
    ) -> Result<Option<MachineBlock>> {
        // After the program's closing `%` a controller reads nothing.
        if self.tape.after_end(line) {
            return Ok(None);
        }
        super::heidenhain::check_machine_block(&line.bytes, file, line.number)?;
        // Keywords, and the calls and instructions read from opaque text
        // (`TRAORI(…)`, `CYCLE800(…)`, Fagor `#RTCP ON`), as the modal state
        // reads them.
        let (mut words, mut keywords) = (Vec::new(), Vec::new());
        super::block_words::block_words(line, &mut words, &mut keywords);
        let mut modal_words = Vec::new();
        let mut axis_items = Vec::new();
        for (i, item) in line.items.iter().enumerate() {
            let ItemKind::Word(w) = &item.kind else {
                continue;
            };
            let machine_axis = machine.axes.iter().any(|a| a.name == w.address);
            // The words that tell a lathe's cutting cycle
            // (`unfollowed::lathe_cycle`) and cancel G54.2 (P0) go to the
            // modal state too.
            let cycle_word =
                !machine_axis && matches!(w.address.as_str(), "P" | "Q" | "U" | "W" | "D");
            if w.address == "G" || w.address == "F" || cycle_word {
                modal_words.push(WordRef {
                    address: w.address.as_str(),
                    value: w.value,
                    item: i,
                });
            } else if machine_axis {
                // The same axis twice (`X1 … X2`): which one a controller
                // takes is not for kinpost to guess; LinuxCNC and Fanuc
                // refuse the block.
                let same = |k: &usize| match &line.items[*k].kind {
                    ItemKind::Word(f) => f.address == w.address,
                    _ => false,
                };
                if let Some(&first) = axis_items.iter().find(|k| same(k)) {
                    return Err(Error::input_with(
                        Location::new(file, line.number, item.start + 1),
                        format!(
                            "axis word {} is given twice in this block ({} and {}): the block is ambiguous (LinuxCNC and Fanuc refuse it too); give each axis once",
                            w.address,
                            String::from_utf8_lossy(line.item_bytes(&line.items[first])).trim(),
                            String::from_utf8_lossy(line.item_bytes(item)).trim()
                        ),
                        line.text_lossy(),
                    ));
                }
                axis_items.push(i);
            }
        }
        for w in modal_words.iter().filter(|w| w.address == "G") {
            let c = (w.value * 10.0).round() as i64;
            match c {
                0 | 10 | 20 | 30 | 800 => self.cycle = false,
                170 => self.cycle_axis = "Z",
                180 => self.cycle_axis = "Y",
                190 => self.cycle_axis = "X",
                c if super::pose_program::is_canned_cycle(c) => self.cycle = true,
                _ => {}
            }
        }
        let meaning = self.modal.apply(&modal_words, &[]).map_err(|e| {
            let col = e.item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Error::input(Location::new(file, line.number, col), e.message)
        })?;
        // Tool centre point control switched on past the start of the
        // program (where the program was taken for one in machine axes):
        // from here its X Y Z are tool-tip positions, not axes.
        let tcp = meaning
            .tcp_codes
            .first()
            .map(|c| match c {
                super::modal::TcpCode::FanucOn(i) | super::modal::TcpCode::SiemensOn(i) => *i,
            })
            .or_else(|| {
                let keyword = keywords
                    .iter()
                    .find(|(_, k)| matches!(*k, "TRAORI" | "TRAORI(…)" | super::fagor::TCP_ON))
                    .map(|&(i, _)| i);
                // Heidenhain ISO's tool centre point management.
                let m128 = line.items.iter().position(
                    |it| matches!(&it.kind, ItemKind::Word(w) if w.address == "M" && w.value == 128.0),
                );
                keyword.into_iter().chain(m128).min()
            });
        if let Some(i) = tcp {
            // `post` converts the poses of the others; M128's are the
            // control's to convert, and `post` passes them on.
            let m128 = matches!(&line.items[i].kind, ItemKind::Word(w) if w.address == "M");
            let advice = if m128 {
                "the control converts them itself (M128), and `kinpost post` passes them on unconverted; give this command the program in machine axes (without M128)"
            } else {
                "convert the program with `kinpost post` first, or give a program that switches TCP on at its start"
            };
            return Err(Error::input_with(
                Location::new(file, line.number, line.items[i].start + 1),
                format!(
                    "tool centre point control (G43.4, G43.5, G234, TRAORI, Heidenhain ISO M128, Fagor #RTCP ON) in a program read as machine axes: from here its X Y Z are tool-tip positions, which this command does not read as axes; {advice}"
                ),
                line.text_lossy(),
            ));
        }
        // The modal state sees the G words alone here: a polar move in
        // the block of `G16` (`G16 G1 X20 Y0`) is refused as one under it.
        let polar_move = (g_word(&modal_words, 16.0) && !axis_items.is_empty())
            .then(|| (axis_items[0], super::unfollowed::POLAR_MOVE.to_string()));
        super::unfollowed::check_line(line, file, meaning.unfollowed.clone().or(polar_move))?;
        // A block that is not a move in program coordinates: data (G10,
        // G52, a frame, a pole, a dwell such as Fanuc's `G4 X1.5`) leaves
        // the position as it is; G92 says where the axes it names are now;
        // after G28, G30 or G53 the axes they move (G28/G30 alone: all),
        // after G92.1–G92.3 all axes, are somewhere the program's
        // coordinates do not say, until programmed again.
        self.follow_frames(line, &modal_words, &keywords);
        let frame = line.items.iter().any(
            |it| matches!(&it.kind, ItemKind::Keyword(k) if super::frames::SETTING.contains(&k.as_str())),
        );
        // Sinumerik `SUPA` (and `G153`): machine coordinates, as `G53`.
        let supa = line.keywords().any(|k| k == "SUPA");
        // Fanuc lathe `G50 X Z` sets the coordinate system, as `G92`.
        let lathe_g50 = g_word(&modal_words, 50.0) && !axis_items.is_empty();
        // LinuxCNC's G43.1 / G43.2 with axis words: tool length offsets,
        // not a move ("G43.1 does not cause any motion").
        let tool_offset = g_word(&modal_words, 43.1) || g_word(&modal_words, 43.2);
        if meaning.non_modal || frame || supa || lathe_g50 || tool_offset {
            let g = |c: f64| {
                g_word(&modal_words, c) || (c == 53.0 && (supa || g_word(&modal_words, 153.0)))
            };
            let named = |k: usize| {
                axis_items.iter().any(|&i| {
                    matches!(&line.items[i].kind, ItemKind::Word(w) if w.address == machine.axes[k].name)
                })
            };
            // kinpost writes rotary words as the chain's joint angles: a
            // rotary axis's program and machine coordinates are one (no
            // rotary work offset). So G53 puts a rotary where its word says,
            // and G28 at its reference point, 0°; linear axes there, and
            // any axis after G30, are not known.
            let rotary = |k: usize| machine.axes[k].kind == crate::machine::JointKind::Revolute;
            // G28/G30 without any axis word send every axis home.
            let all = !g(53.0)
                && !line.words().any(|w| {
                    matches!(
                        w.address.as_str(),
                        "X" | "Y" | "Z" | "A" | "B" | "C" | "U" | "V" | "W"
                    )
                });
            for k in 0..machine.axes.len() {
                if g(92.1) || g(92.2) || g(92.3) {
                    self.unknown[k] = true;
                } else if g(28.0) && rotary(k) && (all || named(k)) {
                    self.ext[k] = 0.0;
                    self.unknown[k] = false;
                } else if (g(28.0) || g(30.0) || g(53.0)) && !(g(53.0) && rotary(k)) {
                    self.unknown[k] |= all || named(k);
                }
            }
            if g(92.0) || lathe_g50 {
                self.set_axes(machine, line, &axis_items, &meaning, true);
            } else if g(53.0) {
                let rotaries: Vec<usize> = axis_items
                    .iter()
                    .copied()
                    .filter(|&i| {
                        (0..machine.axes.len()).any(|k| {
                            rotary(k)
                                && matches!(&line.items[i].kind, ItemKind::Word(w) if w.address == machine.axes[k].name)
                        })
                    })
                    .collect();
                self.set_axes(machine, line, &rotaries, &meaning, true);
                self.check_rotary_limits(machine, line, &rotaries, file)?;
            }
            return Ok(None);
        }
        self.check_motion_words(machine, line, file)?;
        // A full circle may give its centre alone (`G2 I-10`): it ends
        // where it starts.
        let full_circle = meaning.motion == Motion::Arc
            && line
                .words()
                .any(|w| ["I", "J", "K"].iter().any(|a| w.is(a)));
        if let Some((at, what)) = self.active_frame()
            && (!axis_items.is_empty() || full_circle)
        {
            return Err(Error::input_with(
                Location::new(
                    file,
                    line.number,
                    line.items[axis_items.first().copied().unwrap_or(0)].start + 1,
                ),
                super::frames::move_under(&what, at),
                line.text_lossy(),
            ));
        }
        if axis_items.is_empty() && !full_circle {
            return Ok(None);
        }
        let start_known = !self.unknown.contains(&true);
        let rotary = |k: usize| machine.axes[k].kind == crate::machine::JointKind::Revolute;
        // Only where the start is not known: the positions before, and
        // which axes were not known.
        let before = (!start_known).then(|| (self.ext.clone(), self.unknown.clone()));
        if meaning.absolute {
            check_wrapped_words(machine, line, &axis_items, file)?;
        }
        self.set_axes(machine, line, &axis_items, &meaning, meaning.absolute);
        // A canned cycle ends at its R level or where it started (G99,
        // G98, and each controller its own rule): along its axis the
        // position after it is not known until programmed again.
        if self.cycle {
            for (k, axis) in machine.axes.iter().enumerate() {
                self.unknown[k] |= axis.name == self.cycle_axis;
            }
        }
        self.check_rotary_limits(machine, line, &axis_items, file)?;
        // A rotary that turns, or one not known that is programmed to a
        // position (it may turn), makes the tip's path depend on the start.
        let rotary_still = before.as_ref().is_none_or(|(ext, unknown)| {
            (0..ext.len()).all(|k| {
                let programmed_from_unknown = unknown[k] && !self.unknown[k];
                let turns = ext[k] != self.ext[k] || programmed_from_unknown;
                !rotary(k) || !turns
            })
        });
        Ok(Some(MachineBlock {
            q: machine.to_internal(&self.ext).to_vec(),
            meaning,
            axis_items,
            start_known,
            end_known: !self.unknown.contains(&true),
            measurable: start_known || rotary_still,
        }))
    }

    /// Refuses a block that puts a rotary axis it names beyond the
    /// machine's limits of that axis. A rotary's program and machine
    /// coordinates are one (kinpost writes rotary words as joint angles),
    /// so its limits apply to the program's words; a linear axis's
    /// program coordinates are shifted by a work offset kinpost does not
    /// know, and are not checked.
    fn check_rotary_limits(
        &self,
        machine: &crate::machine::Machine,
        line: &crate::gcode::Line,
        axis_items: &[usize],
        file: &str,
    ) -> Result<()> {
        for (i, k, _) in axis_words(machine, line, axis_items) {
            let axis = &machine.axes[k];
            if axis.kind != crate::machine::JointKind::Revolute
                || crate::machine::rotary::within_limits(axis, self.ext[k].to_radians())
            {
                continue;
            }
            let bound =
                |b: Option<f64>, sign: &str| b.map_or(format!("{sign}∞"), |v| format!("{v}"));
            return Err(Error::input_with(
                Location::new(file, line.number, line.items[i].start + 1),
                format!(
                    "axis {} would move to {:.4}°, outside its limits {} … {}° on machine {}: the machine cannot follow this move (a program for another machine, or the wrong machine file)",
                    axis.name,
                    self.ext[k],
                    bound(axis.min, "−"),
                    bound(axis.max, "+"),
                    machine.name
                ),
                line.text_lossy(),
            ));
        }
        Ok(())
    }

    /// Puts the axes of `axis_items` where the line's words say (`absolute`:
    /// at their values, else moved by them).
    fn set_axes(
        &mut self,
        machine: &crate::machine::Machine,
        line: &crate::gcode::Line,
        axis_items: &[usize],
        meaning: &super::BlockMeaning,
        absolute: bool,
    ) {
        for (_, k, w) in axis_words(machine, line, axis_items) {
            // (`check_wrapped_words` refused a wrapped word of 360° or more.)
            self.ext[k] = crate::machine::rotary::follow_word(
                &machine.axes[k],
                w.value,
                meaning.units.mm_per_unit(),
                absolute,
                self.ext[k],
            )
            .unwrap_or(w.value);
            if absolute {
                self.unknown[k] = false;
            }
        }
    }
}

/// The machine axis words among `axis_items` of `line`: each word's item
/// index, its axis (index in `machine.axes`) and the word.
fn axis_words<'l>(
    machine: &'l crate::machine::Machine,
    line: &'l crate::gcode::Line,
    axis_items: &'l [usize],
) -> impl Iterator<Item = (usize, usize, &'l crate::gcode::Word)> + 'l {
    axis_items.iter().filter_map(move |&i| {
        let ItemKind::Word(w) = &line.items[i].kind else {
            return None;
        };
        let k = machine.axes.iter().position(|a| a.name == w.address)?;
        Some((i, k, w))
    })
}

/// Refuses an absolute word of a wrapped rotary axis
/// ([`crate::machine::RotaryMode::Wrapped`]) of 360° or more in size,
/// which LinuxCNC refuses: where it would take the axis is not defined.
fn check_wrapped_words(
    machine: &crate::machine::Machine,
    line: &crate::gcode::Line,
    axis_items: &[usize],
    file: &str,
) -> Result<()> {
    for (i, k, w) in axis_words(machine, line, axis_items) {
        if machine.axes[k].rotary == crate::machine::RotaryMode::Wrapped && w.value.abs() >= 360.0 {
            return Err(Error::input_with(
                Location::new(file, line.number, line.items[i].start + 1),
                crate::machine::wrapped::word_too_large(&w.address, w.value),
                line.text_lossy(),
            ));
        }
    }
    Ok(())
}

/// Reads the axis positions of a program in machine axes; blocks that carry
/// none of the machine's axis words, and moves other than G0, G1, G2 and
/// G3, are skipped (the block after a skipped move restarts). With
/// `arc_points` each circular move comes with the points it passes
/// through ([`arc_joint_path`]; an arc it cannot follow is refused at its
/// line).
pub fn machine_axis_blocks<R: BufRead>(
    machine: &crate::machine::Machine,
    input: R,
    file: &str,
    arc_points: bool,
    mut f: impl FnMut(AxisEvent) -> Result<()>,
) -> Result<()> {
    let mut tracker = MachineAxisTracker::new(machine);
    let mut lines = LineReader::new(input);
    let mut arcs = ArcModes::default();
    // A block was left out since the last event because its end is not
    // known, or its path is not followed (a canned cycle).
    let mut gap = false;
    // Where the last event ended.
    let mut last: Option<Vec<f64>> = None;
    let mut spindle = super::spindle::Spindle::default();
    while let Some(line) = lines.next_line() {
        let line = line.map_err(|e| Error::io(file, e))?;
        arcs.apply(line);
        spindle.line(line);
        let Some(b) = tracker.line(machine, line, file)? else {
            continue;
        };
        let m = &b.meaning;
        if !b.end_known || !matches!(m.motion, Motion::Rapid | Motion::Linear | Motion::Arc) {
            gap = true;
            continue;
        }
        let restart = std::mem::take(&mut gap) || !b.start_known;
        let via = match (&last, m.motion) {
            (Some(from), Motion::Arc) if arc_points && !restart => {
                let units = m.units.mm_per_unit();
                arc_joint_path(machine, &arcs, line, file, from, &b.q, units)?
            }
            _ => Vec::new(),
        };
        last = Some(b.q.clone());
        f(AxisEvent {
            arc: m.motion == Motion::Arc,
            via,
            restart,
            line: line.number,
            feed_mm_min: spindle.feed_mm_min(m.feed_mode, m.feed, m.feed_units),
            feed_unit_mm: m.feed_units.mm_per_unit(),
            inverse_time: match m.feed_mode {
                super::FeedMode::InverseTime => m.feed,
                _ => None,
            },
            rapid: m.motion == Motion::Rapid,
            q: b.q,
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::cl_poses;

    /// The tool tips of the poses `cl_poses` reads from `text`.
    fn tips(text: &str) -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        cl_poses(text.as_bytes(), "t.cls", None, |e| {
            v.push([e.pose.tip.x, e.pose.tip.y, e.pose.tip.z]);
            Ok(())
        })
        .unwrap();
        v
    }

    #[test]
    fn cl_poses_follow_arcs_set_ups_and_holes_as_post_does() {
        // A quarter circle of radius 10 about Z: its points, each on the
        // circle (checked here, not by the lowering's own geometry), not
        // the chord from (10,0,0) to (0,10,0) that the reader used to give.
        let arc = tips("UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n");
        assert!(arc.len() > 10, "{arc:?}");
        for p in &arc {
            let r = p[0].hypot(p[1]);
            assert!((r - 10.0).abs() < 1e-9 && p[2] == 0.0, "{p:?}");
        }
        // The arc's middle lies 10 − 5√2 = 2.93 mm beyond the chord x + y = 10.
        let beyond_chord = arc
            .iter()
            .map(|p| (p[0] + p[1] - 10.0) / std::f64::consts::SQRT_2)
            .fold(0.0, f64::max);
        assert!(beyond_chord > 2.9, "{beyond_chord}");
        // A set-up shifted by (100, 0, 0): points are written in it.
        let set_up = tips("UNITS/MM\nCSYS/1,0,0,100,0,1,0,0,0,0,1,0\nGOTO/105,0,0\n");
        assert_eq!(set_up, vec![[5.0, 0.0, 0.0]]);
        // A drilled hole 5 deep goes down to its bottom and back up.
        let hole = tips(
            "UNITS/MM\nGOTO/0,0,30\nCYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,2,RTRCTO,30\nGOTO/7,8,0\nCYCLE/OFF\n",
        );
        assert!(hole.contains(&[7.0, 8.0, -5.0]), "{hole:?}");
        assert!(hole.contains(&[7.0, 8.0, 30.0]), "{hole:?}");
    }
}
