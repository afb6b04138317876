//! The G-code converter: a program's lines, one at a time, in two halves
//! around the solve. The [`BlockReader`] reads a line's modal state and
//! gives its pose ([`BlockReader::begin`]); the [`BlockWriter`] writes the
//! pose block with the solved joint values ([`BlockWriter::finish`]).
//! The driver of `compensate` runs the two on different chunks at the same
//! time, so nothing the reader reads depends on what is written.

mod arc;
mod finish;

pub use super::pending::{ArcPart, Continuation, PendingPose};
use super::position::{
    self, Lost, goes_where_not_known, loses_position, tip_known, turns_rotaries,
};
use super::rotary_pose::RotaryPositions;
use super::{AxisWriter, PoseSolver, PostOptions, PostStats};
use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, Line};
use crate::machine::chain::JointValues;
use crate::machine::{Machine, Pose};
use crate::program::modal::Motion;
use crate::program::opaque::opaque_in_pose_block;
use crate::program::rewrite::rewrite;
use crate::program::{ModalState, WordRef};
use nalgebra::Vector3;

/// A converted pose block.
#[derive(Debug, Clone)]
pub struct Converted {
    /// Joint values (chain order, mm / rad).
    pub q: crate::machine::chain::JointValues,
    /// What the block meant (modal state, items).
    pub meaning: crate::program::BlockMeaning,
}

/// Warnings with the line and half (0: reading, 1: writing) they belong
/// to, sorted into program order at the end.
type Warnings = Vec<((usize, u8), String)>;

/// Converts G-code line by line: the per-line core of `post` and
/// `compensate`, reused by `linkage` on pose programs.
pub struct GcodeConverter<'a> {
    /// The first half: modal state and poses.
    pub reader: BlockReader<'a>,
    /// The second half: what is written.
    pub writer: BlockWriter<'a>,
}

/// The first half of the [`GcodeConverter`]: the program's modal state,
/// line by line, and the position the program continues from.
pub struct BlockReader<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    modal: ModalState,
    /// The modal state with the block-delete switch on, where it differs.
    switch: crate::program::block_delete_switch::BlockDeleteSwitch,
    /// Plain tool length compensation (`G43 Hn`) the program switched on.
    length_comp: crate::program::length_comp::LengthCompensation,
    /// The chain ends at a tool's tip (the machine's or a job tool's
    /// length): the axis words of a pose include the tool.
    tool_in_chain: bool,
    /// The joint values the program continues from: those of the last
    /// pose begun (as the first pass solved it: `post`'s solution,
    /// `compensate`'s theoretical one; [`BlockReader::begun`]) or of the
    /// machine position followed since.
    previous: Continuation,
    /// A line with words was passed through since the last pose begun, or
    /// that pose was a block-delete one: the next pose's axis words are
    /// all written, also with `--modal-axes` ([`PendingPose::after_other`]).
    other_since_pose: bool,
    /// Blocks passed through moved the machine since the last pose begun
    /// ([`PendingPose::moved`]).
    moved_since_pose: bool,
    /// The code or transformation kinpost does not follow in the last line
    /// passed through outside pose mode ([`BlockReader::take_unfollowed`]).
    unfollowed: Option<(usize, String)>,
    /// Machine axis positions (output order, mm / deg) followed through
    /// blocks in machine coordinates (pose mode off); unknown axes are 0.
    machine_ext: Vec<f64>,
    /// `machine_ext` is that of `previous` (a pose block came since it was
    /// last followed) and is recomputed before use.
    machine_ext_stale: bool,
    /// The axes of `machine_ext` whose position is known (bit k: axis k):
    /// none at the start, all after a pose, each absolute word followed
    /// adds its axis, and whatever moves the machine where the program's
    /// coordinates do not say clears them ([`loses_position`]).
    known_axes: u64,
    /// The axes the program has given a position or a move (bit k: axis
    /// k): one it never moved stands where it stood, and a segment's shape
    /// does not depend on where that is.
    programmed_axes: u64,
    /// The rotary positions that orient poses given by `A B C` words.
    rotaries: RotaryPositions,
    /// The arc modes in force (plane, centre mode, direction), and as they
    /// stand with the block delete switch on, when arcs are read as poses.
    arcs: [crate::program::arc::ArcModes; 2],
    /// The points of the arc begun last not given out yet.
    arc_rest: Option<arc::ArcRest>,
    /// The line of the last arc written as `G1` moves while the program's
    /// motion mode is still its `G2`/`G3`.
    arc_written: Option<usize>,
    /// The line last begun selects a work offset other than the one in
    /// force.
    new_offset: bool,
    /// The allocation of the vector of a block's words, kept from block to
    /// block (empty between blocks).
    words: Vec<WordRef<'static>>,
    /// Where the machine is since the last pose.
    start: Start,
    /// Lines read.
    lines: usize,
    /// Largest deviation of a tool vector's length from 1.
    max_vector_deviation: f64,
    /// The line of the main program's end (`M2`, `M30`), once read: what
    /// follows it in the file is a subprogram's body, which runs under the
    /// modes of its call.
    ended_at: Option<usize>,
    /// The line of a LinuxCNC subroutine's definition (`o100 sub`) while
    /// its body is read: the body runs under the modes of each call.
    in_sub: Option<usize>,
    /// The first line of program flow outside pose mode (a jump, branch
    /// or loop): from there on no block in machine axes is known to leave
    /// the machine where its words say.
    flow_at: Option<usize>,
    /// The `%` that ends the program: what follows it is not read.
    tape: crate::program::tape::TapeEnd,
    warnings: Warnings,
}

/// Where the machine is before the next pose, as far as the program says
/// ([`BlockReader::start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// At the last pose.
    AtPose,
    /// Where blocks in machine coordinates (pose mode off) moved it since
    /// the last pose: [`BlockReader::previous`].
    Followed,
    /// Not known: a move home or in machine coordinates (`G28`, `G30`,
    /// `G53`) or a new origin (`G92`) came since the last pose.
    Unknown,
}

/// The second half of the [`GcodeConverter`]: the axis words and feed
/// mode written.
pub struct BlockWriter<'a> {
    machine: &'a Machine,
    opts: &'a PostOptions,
    axes: AxisWriter<'a>,
    /// The feed mode written (`--feed inverse-time`).
    feed: crate::program::inverse_time::InverseTime,
    /// Pose blocks written.
    poses: usize,
    /// Largest tool-axis miss, rad.
    max_axis_miss_rad: f64,
    /// The joint values of the last pose written.
    last: Option<JointValues>,
    /// The rotary axes' values at the first point of the arc written last.
    arc_rotaries: Vec<f64>,
    warnings: Warnings,
}

impl<'a> GcodeConverter<'a> {
    /// A converter for `machine`. It does not solve poses: a driver solves
    /// each pose [`BlockReader::begin`] gives and hands the joint values
    /// to [`BlockWriter::finish`] ([`GcodeConverter::convert`] does both
    /// with a [`PoseSolver`]).
    pub fn new(machine: &'a Machine, opts: &'a PostOptions) -> Self {
        GcodeConverter {
            reader: BlockReader {
                machine,
                opts,
                modal: ModalState::new(opts.pose_start),
                switch: crate::program::block_delete_switch::BlockDeleteSwitch::new(
                    opts.inverse_time,
                ),
                length_comp: Default::default(),
                tool_in_chain: machine.tool_length_mm != 0.0
                    || opts
                        .tool_machines
                        .iter()
                        .any(|(_, m)| m.tool_length_mm != 0.0),
                previous: Continuation::Nowhere,
                other_since_pose: false,
                moved_since_pose: false,
                unfollowed: None,
                machine_ext: vec![0.0; machine.axes.len()],
                machine_ext_stale: false,
                known_axes: 0,
                programmed_axes: 0,
                rotaries: RotaryPositions::new(machine),
                arcs: Default::default(),
                arc_rest: None,
                arc_written: None,
                new_offset: false,
                words: Vec::with_capacity(16),
                start: Start::AtPose,
                lines: 0,
                max_vector_deviation: 0.0,
                ended_at: None,
                in_sub: None,
                flow_at: None,
                tape: Default::default(),
                warnings: Vec::new(),
            },
            writer: BlockWriter {
                machine,
                opts,
                axes: AxisWriter::new(machine, opts.decimals),
                feed: Default::default(),
                poses: 0,
                max_axis_miss_rad: 0.0,
                last: None,
                arc_rotaries: Vec::new(),
                warnings: Vec::new(),
            },
        }
    }

    /// Converts one line with `solver`, appending the bytes to write to
    /// `out`; returns the joint values when the line was a pose.
    pub fn convert(
        &mut self,
        line: &Line,
        solver: &mut dyn PoseSolver,
        out: &mut Vec<u8>,
    ) -> Result<Option<Converted>> {
        let Some(pending) = self.reader.begin(Some(&mut self.writer), line, out)? else {
            return Ok(None);
        };
        let solved = solver
            .solve(
                &pending.pose,
                pending.solve_from(self.reader.previous()),
                line.number,
            )
            .map_err(|m| self.reader.solve_error(line, &pending, m))?;
        self.reader.begun(&solved.q);
        self.writer.finish(line, &pending, &solved, out)?;
        Ok(Some(Converted {
            q: solved.q,
            meaning: pending.meaning,
        }))
    }

    /// What ends the program: a last `G94` when the output is in `G93`.
    pub fn end(&mut self) -> Option<&'static str> {
        self.writer.feed.end()
    }

    /// What was done, the warnings in program order.
    pub fn stats(self) -> PostStats {
        let (r, w) = (self.reader, self.writer);
        super::stats_of_halves(
            (r.lines, r.max_vector_deviation, r.warnings),
            (w.poses, w.max_axis_miss_rad, w.warnings),
        )
    }
}

impl BlockReader<'_> {
    /// The modal state and the pose of `line`. A line that is not a pose
    /// is written to `out` and `None` returned; a pose is returned for
    /// solving. `writer`: the second half, for the feed mode written under
    /// `--feed inverse-time` (a line that is not a pose may have to go back
    /// to `G94` first); without it (the driver's first pass beside its last)
    /// that option must be off.
    pub fn begin(
        &mut self,
        writer: Option<&mut BlockWriter<'_>>,
        line: &Line,
        out: &mut Vec<u8>,
    ) -> Result<Option<PendingPose>> {
        if self.arc_rest.is_some() {
            return Ok(self.next_arc_point());
        }
        let opts = self.opts;
        self.lines += 1;
        // After the program's closing `%` a controller reads nothing.
        match self.tape.read(line) {
            crate::program::tape::TapeLine::Program => {}
            after => {
                if let crate::program::tape::TapeLine::FirstText(at) = after {
                    self.warnings.push(((line.number, 0), format!(
                        "{}: text after the program's closing `%` (line {at}) passed on unread: a controller reads nothing after it",
                        Location::new(&opts.file_name, line.number, 1)
                    )));
                }
                out.extend_from_slice(&line.bytes);
                return Ok(None);
            }
        }
        let loc = |item: Option<usize>| {
            let col = item.map(|i| line.items[i].start + 1).unwrap_or(0);
            Location::new(&opts.file_name, line.number, col)
        };
        crate::program::integrity::check_line(line, &opts.file_name, self.modal.pose_mode)?;
        self.follow_arc_modes(line);
        let mut words = recycle(std::mem::take(&mut self.words));
        let mut keywords = Vec::new();
        crate::program::block_words::block_words(line, &mut words, &mut keywords);
        let opaque_error = |i: usize| {
            Error::input_with(
                loc(Some(i)),
                crate::program::opaque::describe_opaque(line.item_bytes(&line.items[i])),
                String::from_utf8_lossy(&line.bytes),
            )
        };
        // Only G codes of a plain move (no cycle, no non-modal code): the
        // blocks whose unreadable text may still be a tool vector.
        let plain_move = words.iter().all(|w| {
            w.address != "G"
                || [
                    0.0, 1.0, 17.0, 18.0, 19.0, 20.0, 21.0, 40.0, 49.0, 90.0, 91.0, 93.0, 94.0,
                ]
                .contains(&w.value)
        });
        let has_words = !words.is_empty() || !keywords.is_empty();
        let start_tip = self.modal.tip;
        let offset_before = self.modal.work_offset;
        let applied = self.switch.apply(&mut self.modal, &words, &keywords, line);
        self.new_offset = self.modal.work_offset != offset_before;
        let traori = keywords.iter().any(|(_, k)| k.starts_with("TRAORI"));
        self.length_comp.block(&words, line, traori);
        self.words = recycle(words);
        let ended_at = self.ended_at;
        let mut meaning = applied.map_err(|e| match e {
            crate::program::block_delete_switch::Refused::Slash { at, message } => {
                Error::input_with(
                    Location::new(&opts.file_name, at.line, at.col),
                    message,
                    at.text,
                )
            }
            // Text not understood in the block explains the failure best.
            crate::program::block_delete_switch::Refused::Block(e) => {
                match opaque_in_pose_block(line, true, true, true) {
                    Some(i) => opaque_error(i),
                    None => Error::input_with(
                        loc(e.item),
                        match ended_at {
                            // A subprogram's block runs under the modes of
                            // its call, not those the main program ended with.
                            Some(end) => format!(
                                "{} (this block comes after the end of the main program, M2/M30 at line {end}: a subprogram's, which runs under the units, G90/G91 and offsets in force where it is called, and kinpost does not follow calls)",
                                e.message
                            ),
                            None => e.message,
                        },
                        String::from_utf8_lossy(&line.bytes),
                    ),
                }
            }
        })?;
        for w in &meaning.warnings {
            let at = loc(meaning.pose_items.first().copied());
            self.warnings.push(((line.number, 0), format!("{at}: {w}")));
        }
        self.max_vector_deviation = self.max_vector_deviation.max(meaning.vector_deviation);
        let straight = plain_move && matches!(meaning.motion, Motion::Rapid | Motion::Linear);
        if let Some(i) =
            opaque_in_pose_block(line, self.modal.pose_mode, meaning.pose.is_some(), straight)
        {
            return Err(opaque_error(i));
        }
        if (self.modal.pose_mode || meaning.pose.is_some())
            && let Some((at, what)) = crate::program::flow::flow_statement(line)
        {
            return Err(Error::input_with(
                Location::new(&opts.file_name, line.number, at + 1),
                format!(
                    "program flow (`{what}`: a jump, branch, loop or label) in pose mode: kinpost does not evaluate it, so it cannot know which pose blocks run, how often, or from where; have the CAM system write the moves without flow control, or keep it outside G43.4 / TRAORI"
                ),
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        let Some((tip, axis)) = meaning.pose else {
            let text = String::from_utf8_lossy(&line.bytes);
            let unended = !line.bytes.ends_with(b"\n")
                && !text.trim().is_empty()
                && !crate::program::integrity::ends_program(line);
            if unended {
                self.warnings.push(((line.number, 0), format!(
                    "{}: the file ends without a line end after `{}`: a truncated file? (passed on unchanged)",
                    Location::new(&opts.file_name, line.number, 1),
                    crate::error::visible(text.trim())
                )));
            }
            self.inherited_arc(line)?;
            if !self.modal.pose_mode {
                self.follow_machine_words(line, &meaning)?;
                self.unfollowed = meaning.unfollowed.take();
            } else if (meaning.non_modal && goes_where_not_known(line))
                || loses_position(line, self.new_offset).is_some()
            {
                // `G28`, `G53 G0 Z0`, a tool change between poses: the next
                // pose starts where the program does not say, and must give
                // X Y Z (and its orientation if the rotaries went too).
                self.lose_position();
                if turns_rotaries(line, self.machine) {
                    self.modal.lose_orientation(line.number);
                }
            }
            // It may move the machine (a pass-through move, G28, a tool
            // change) or change the controlled point (G43).
            self.other_since_pose |= has_words;
            if self.ended_at.is_none() && crate::program::integrity::ends_main_program(line) {
                self.ended_at = Some(line.number);
            }
            if let Some(sub) = subroutine_bound(line) {
                self.in_sub = sub.then_some(line.number);
            }
            let crlf = line.bytes.ends_with(b"\r\n");
            if opts.inverse_time
                && let Some(w) = writer
                && let Some(s) = w.feed.before_other(has_words, meaning.feed, crlf)
            {
                out.extend_from_slice(s.as_bytes());
            }
            if meaning.tcp_codes.is_empty() {
                out.extend_from_slice(&line.bytes);
            } else {
                rewrite(
                    line,
                    &[],
                    b"",
                    &meaning.tcp_codes,
                    &meaning.tcp_offset_items,
                    out,
                );
            }
            return Ok(None);
        };
        // A pose after the main program's end belongs to a subprogram
        // (Fanuc `O1000` … `M99` called by `M98 P1000`, Haas `M97 P100`),
        // and one in a LinuxCNC subroutine's body (`o100 sub`) to the
        // subroutine: it runs under the modes of each call (units,
        // G90/G91, offsets, where the machine is), not those where it
        // stands in the file.
        let elsewhere = match (self.ended_at, self.in_sub) {
            (Some(end), _) => Some(format!(
                "a pose after the end of the main program (M2/M30 at line {end}): a subprogram's, which runs under the units, G90/G91 and offsets in force where it is called, and kinpost does not follow calls; convert the subprogram as a program of its own, or have the CAM system write its poses in the main program"
            )),
            (None, Some(sub)) => Some(format!(
                "a pose in the body of a subroutine (o-word `sub` at line {sub}): it runs under the units, G90/G91 and offsets in force where it is called, and from where the machine is then, and kinpost does not follow calls; write the subroutine's poses where it is called (have the CAM post expand it), or convert it as a program of its own"
            )),
            (None, None) => None,
        };
        if let Some(message) = elsewhere {
            return Err(Error::input_with(
                loc(meaning.pose_items.first().copied()),
                message,
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        // Only the last line of a file can lack its line end. A pose block
        // there may have been cut mid-number (`X12.3` of `X12.345`).
        if !line.bytes.ends_with(b"\n") {
            return Err(Error::input_with(
                Location::new(&opts.file_name, line.number, line.bytes.len() + 1),
                "the file ends inside this pose block, without a line end: a truncated file? A block cut short would put the tool elsewhere; if the program is complete, end it with a line break (and M30)",
                String::from_utf8_lossy(&line.bytes),
            ));
        }
        // The chain ends at the tool's tip: a G43 of the program's own
        // would add the tool's length to axis words that include it.
        if self.tool_in_chain
            && let Some((at, what)) = self.length_comp.on()
        {
            return Err(Error::input_with(
                Location::new(&opts.file_name, at.line, at.col),
                format!(
                    "{what} while the pose at line {} is converted, and the machine's chain ends at the tool's tip (--tool-length, --tool-table or the machine file's tool_length): the axis words include the tool, and the controller would add its length again; switch it off (G49; on a Sinumerik D0) before the poses, or start them with G43.4 (written as G49)",
                    line.number
                ),
                at.text.clone(),
            ));
        }
        // The orientation by rotary positions: the tool axis from the chain,
        // the solution pinned to them.
        let (axis, pinned) =
            self.rotary_orientation(line, &meaning, axis)
                .map_err(|(item, m)| {
                    let item = item.or(meaning.pose_items.first().copied());
                    Error::input_with(loc(item), m, String::from_utf8_lossy(&line.bytes))
                })?;
        // After a block-delete pose the controller may stand where the
        // block before left it.
        let block_delete = line.bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'/');
        let after_other = std::mem::replace(&mut self.other_since_pose, block_delete);
        let mut pending = PendingPose {
            after_other,
            moved: std::mem::take(&mut self.moved_since_pose),
            pose: Pose::new(tip, axis),
            pinned,
            continues: self.previous.clone(),
            start_known: self.start != Start::Unknown,
            start_tip: match start_tip {
                [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
                _ => None,
            },
            meaning,
            arc: ArcPart::None,
        };
        if pending.meaning.motion == Motion::Arc {
            self.begin_arc(line, &mut pending)?;
        }
        Ok(Some(pending))
    }

    /// Reads circular moves (`G2`/`G3`) in pose mode as poses, whose
    /// points [`BlockReader::begin`] gives one by one
    /// ([`BlockReader::line_done`]); without this they are refused.
    pub fn read_arcs(&mut self) {
        self.modal.arcs_as_poses = true;
    }

    /// Whether the feed is converted to inverse time (`--feed
    /// inverse-time`): [`BlockReader::begin`] then needs the writer.
    pub fn inverse_time(&self) -> bool {
        self.opts.inverse_time
    }

    /// The modal state after the last line begun.
    pub fn modal(&self) -> &ModalState {
        &self.modal
    }

    /// The joint values the program continues from.
    pub fn previous(&self) -> Option<&[f64]> {
        self.previous.resolve(None)
    }

    /// The tool axis of the pose of `meaning` (`axis`: the programmed
    /// vector's) and, for a pose oriented by rotary positions, the joint
    /// values to solve it from ([`super::rotary_pose::orientation`]).
    fn rotary_orientation(
        &mut self,
        line: &Line,
        meaning: &crate::program::BlockMeaning,
        axis: Vector3<f64>,
    ) -> std::result::Result<(Vector3<f64>, Option<JointValues>), super::rotary_pose::Refusal> {
        let chain = &machine_at(self.machine, self.opts, line.number).chain;
        let previous = self.previous.resolve(None);
        super::rotary_pose::orientation(
            &mut self.rotaries,
            self.machine,
            chain,
            line,
            meaning,
            axis,
            previous,
        )
    }

    /// Whether `line` holds a word of one of the machine's axes.
    fn has_axis_word(&self, line: &Line) -> bool {
        line.words()
            .any(|w| self.machine.axes.iter().any(|a| a.name == w.address))
    }

    /// Whether `line` needs the joint values of the last pose while they
    /// are not known yet ([`BlockReader::deferred`]): a block in machine
    /// coordinates (pose mode off, or switched off in the line) with an axis
    /// word, whose other axes stay where that pose put them.
    pub fn needs_committed(&self, line: &Line) -> bool {
        self.previous == Continuation::LastPose
            && (!self.modal.pose_mode
                || line.words().any(|w| {
                    w.address == "G"
                        && (w.value == 49.0
                            || (self.modal.fanuc_tcp && [43.0, 43.1, 44.0].contains(&w.value)))
                })
                || line.keywords().any(|k| k == "TRAFOOF"))
            && self.has_axis_word(line)
    }

    /// The error of a failed solve of `pending` (programmed at `line`).
    pub fn solve_error(&self, line: &Line, pending: &PendingPose, message: String) -> Error {
        solve_error(&self.opts.file_name, line, pending, message)
    }
}

/// The error of a failed solve of `pending` (programmed at `line` of
/// `file`).
fn solve_error(file: &str, line: &Line, pending: &PendingPose, message: String) -> Error {
    let col = pending
        .meaning
        .pose_items
        .first()
        .map(|&i| line.items[i].start + 1)
        .unwrap_or(0);
    Error::input_with(
        Location::new(file, line.number, col),
        message,
        String::from_utf8_lossy(&line.bytes),
    )
}

impl BlockReader<'_> {
    /// The pose last begun was solved to `q` in the first pass (`post`'s
    /// solution, `compensate`'s theoretical one): the blocks after it
    /// continue from there. Called between [`BlockReader::begin`] and the
    /// next `begin`; [`BlockWriter::finish`] may come later (under
    /// `compensate` a chunk's poses are written after the next chunk is
    /// begun), so nothing `begin` reads depends on it.
    pub fn begun(&mut self, q: &[f64]) {
        self.previous = Continuation::At(q.iter().copied().collect());
        // `machine_ext` follows from `previous` when next needed.
        self.machine_ext_stale = true;
        self.known_axes = u64::MAX;
        self.programmed_axes = u64::MAX;
        self.start = Start::AtPose;
    }

    /// The pose last begun is solved later, in order (`post`'s driver
    /// solves in its last pass): the blocks after it continue from its
    /// joint values, which [`BlockWriter::last_joints`] gives once it is
    /// written. A block that needs them before
    /// ([`BlockReader::needs_committed`]) waits for [`BlockReader::sync`].
    pub fn deferred(&mut self) {
        self.previous = Continuation::LastPose;
        self.machine_ext_stale = true;
        self.known_axes = u64::MAX;
        self.programmed_axes = u64::MAX;
        self.start = Start::AtPose;
    }

    /// Every pose begun is written, the last with the joint values `last`:
    /// the blocks after it continue from there.
    pub fn sync(&mut self, last: Option<&[f64]>) {
        if self.previous == Continuation::LastPose {
            self.previous = match last {
                Some(q) => Continuation::At(q.iter().copied().collect()),
                None => Continuation::Nowhere,
            };
        }
    }

    /// The code or transformation kinpost does not follow, with its item,
    /// in the line [`BlockReader::begin`] last passed through outside pose
    /// mode (the modal state's part of
    /// [`crate::program::unfollowed::check_line`]): `post` passes it on,
    /// the commands that follow motion refuse it.
    pub fn take_unfollowed(&mut self) -> Option<(usize, String)> {
        self.unfollowed.take()
    }

    /// Where the machine is before the next pose: at the last pose, where
    /// blocks in machine coordinates since moved it, or not known.
    pub fn start(&self) -> Start {
        self.start
    }

    /// A block in machine coordinates (pose mode off): follow its axis words
    /// and tell the modal state where the tool tip now is, so that a pose
    /// block after `G43.4`/`TRAORI` that gives only some coordinates
    /// continues from the machine's position.
    fn follow_machine_words(
        &mut self,
        line: &Line,
        meaning: &crate::program::BlockMeaning,
    ) -> Result<()> {
        // A LinuxCNC subroutine's definition (`o100 sub` … `o100 endsub`)
        // does not run where it stands: its moves are not followed (a call
        // of it loses the position, as any call does).
        if self.in_sub.is_some() || subroutine_bound(line).is_some() {
            return Ok(());
        }
        // Program flow (a jump, branch, loop) outside pose mode: which of
        // the blocks after it run, how often and from where is not known,
        // so none of their moves is known to have left the machine where
        // its words say.
        if self.flow_at.is_none() && crate::program::flow::flow_statement(line).is_some() {
            self.flow_at = Some(line.number);
        }
        self.follow_words(line, meaning)?;
        let turns = match position::not_followed(line, meaning, self.machine) {
            Some(turns) => turns,
            None if self.flow_at.is_some() && self.has_axis_word(line) => true,
            None => return Ok(()),
        };
        self.moved_since_pose = true;
        self.lose_position_since_start();
        if turns {
            self.modal.lose_orientation(line.number);
        }
        Ok(())
    }

    /// [`BlockReader::follow_machine_words`] of a block whose axis words
    /// say where the machine goes.
    fn follow_words(&mut self, line: &Line, meaning: &crate::program::BlockMeaning) -> Result<()> {
        match loses_position(line, self.new_offset) {
            // A call: its words are its arguments (`G65 P9000 A5. B20.`),
            // and it moves the machine where this file does not say.
            Some(Lost::Call) => {
                self.moved_since_pose = true;
                self.lose_position_since_start();
                return Ok(());
            }
            // A tool change, a new work offset: the block's own absolute
            // words are where the machine then is, the other axes are not
            // known.
            Some(Lost::Before) => {
                self.moved_since_pose = true;
                self.lose_position_since_start();
            }
            None => {}
        }
        if meaning.non_modal {
            let g = |v: f64| {
                line.words()
                    .any(|w| w.address == "G" && (w.value - v).abs() < 1e-9)
            };
            if goes_where_not_known(line) {
                self.moved_since_pose = true;
                // Home, machine coordinates, offsets reset: where the tool
                // is in program coordinates is no longer known, so the
                // next pose must give X, Y and Z (and its orientation if
                // the rotaries went too).
                self.lose_position();
                if turns_rotaries(line, self.machine) {
                    self.modal.lose_orientation(line.number);
                }
            }
            if g(92.0) {
                // A new origin: the machine stays, its words change.
                self.known_axes = 0;
                self.start = Start::Unknown;
            } else {
                // `G10 L2 P1 X100`, `G52 X5`, `G68 X10 Y10 R30`, `G111 X0
                // Y0`: data, not a position. `G92 X100` says where the tool
                // is now, and is followed.
                return Ok(());
            }
        }
        if !self.has_axis_word(line) {
            return Ok(());
        }
        if self.previous == Continuation::LastPose {
            return Err(Error::input_with(
                Location::new(&self.opts.file_name, line.number, 1),
                "internal error: a block in machine coordinates was followed before the pose before it was solved; please report it",
                line.text_lossy(),
            ));
        }
        if std::mem::take(&mut self.machine_ext_stale)
            && let Continuation::At(q) = &self.previous
        {
            for (e, axis) in self.machine_ext.iter_mut().zip(&self.machine.axes) {
                *e = crate::machine::output_value(axis, q.get(axis.joint).copied().unwrap_or(0.0));
            }
        }
        let mut moved = false;
        // Axes given a word (a machine of more than 64 axes counts the
        // first 64: its blocks are never whole, as its positions never
        // known, which only asks more of its poses).
        let mut given = 0u64;
        for (item, w) in line.items.iter().filter_map(|i| match &i.kind {
            ItemKind::Word(w) => Some((i, w)),
            _ => None,
        }) {
            if let Some(k) = self.machine.axes.iter().position(|a| a.name == w.address) {
                let bit = if k < 64 { 1u64 << k } else { 0 };
                given |= bit;
                self.programmed_axes |= bit;
                if meaning.absolute {
                    self.known_axes |= bit;
                }
                self.machine_ext[k] = crate::machine::rotary::follow_word(
                    &self.machine.axes[k],
                    w.value,
                    meaning.units.mm_per_unit(),
                    meaning.absolute,
                    self.machine_ext[k],
                )
                .ok_or_else(|| {
                    Error::input_with(
                        Location::new(&self.opts.file_name, line.number, item.start + 1),
                        crate::machine::wrapped::word_too_large(&w.address, w.value),
                        line.text_lossy(),
                    )
                })?;
                moved = true;
            }
        }
        if moved {
            self.moved_since_pose = true;
            let slash = line
                .items
                .iter()
                .position(|i| matches!(i.kind, ItemKind::BlockDelete));
            let whole = meaning.absolute && given.count_ones() as usize == self.machine.axes.len();
            // Under plain tool length compensation the controller puts the
            // tool's tip, not the gauge line, where the words say: the
            // machine's axes are then not where kinpost follows them.
            let rotaries: u64 = (self.machine.axes.iter().enumerate())
                .filter(|(_, a)| a.kind == crate::machine::JointKind::Revolute)
                .fold(0, |m, (k, _)| m | if k < 64 { 1 << k } else { 0 });
            if self.length_comp.plain_on() {
                self.known_axes &= rotaries;
            }
            // A move (not a new origin) to a position of every axis, or from
            // a known one, is followed (where an axis the program never
            // moved stands does not change a segment's shape).
            let all = u64::MAX >> (64 - self.machine.axes.len().clamp(1, 64));
            let settled = (self.known_axes | !self.programmed_axes) & all == all;
            if !meaning.non_modal && (whole || settled || self.start != Start::Unknown) {
                self.start = Start::Followed;
            }
            // But the tool tip's coordinates that an axis not known moves
            // (never programmed, or lost since) are not known: a pose must
            // give them (an axis never programmed is not at 0).
            let known = self.known_axes & all == all;
            let rotaries_known = self.known_axes & rotaries == rotaries;
            self.switch.followed_move(&self.modal, line, slash, whole);
            let q = self.machine.to_internal(&self.machine_ext);
            let chain = &machine_at(self.machine, self.opts, line.number).chain;
            let pose = chain.pose(&q, &crate::machine::NoErrors);
            self.modal.seed_from_machine(pose.tip, pose.axis);
            if !known {
                self.modal.tip = if rotaries_known {
                    tip_known(self.machine, self.known_axes, chain, &q, pose.tip)
                } else {
                    [None; 3]
                };
            }
            self.previous = Continuation::At(q);
            let known = self.known_axes;
            self.rotaries
                .followed(self.machine, &self.machine_ext, known);
            // A move under a frame (G68, TRANS, …) goes where its words do
            // not say: the position is not known after it.
            if self.modal.frame_seen || self.modal.shift_seen {
                self.lose_position();
            }
        }
        Ok(())
    }

    /// As [`BlockReader::lose_position`], but before the first move or pose
    /// (a program's header: `G54`, `T1 M6`) the start stays as it is: no
    /// segment starts there, and the blocks after it are followed as
    /// before.
    fn lose_position_since_start(&mut self) {
        if self.previous == Continuation::Nowhere {
            self.known_axes = 0;
            self.modal.tip = [None; 3];
            self.rotaries.forget();
        } else {
            self.lose_position();
        }
    }

    /// Where the machine is in program coordinates is no longer known:
    /// the next pose must give X, Y and Z.
    fn lose_position(&mut self) {
        self.rotaries.forget();
        self.known_axes = 0;
        self.modal.tip = [None; 3];
        self.start = Start::Unknown;
    }
}

/// The machine in force at `line` (the tool of that part of the job).
fn machine_at<'m>(machine: &'m Machine, opts: &'m PostOptions, line: usize) -> &'m Machine {
    let tools = &opts.tool_machines;
    match tools.iter().rposition(|(from, _)| *from <= line) {
        Some(k) => &tools[k].1,
        None => tools.first().map_or(machine, |t| &t.1),
    }
}

/// `v` emptied, keeping its allocation, as a vector whose elements borrow
/// for another lifetime: the words of each block borrow from that block's
/// line, and one allocation serves them all. (Collecting a vector's
/// `into_iter` into a vector of a type of the same size and alignment reuses
/// its buffer; the map never runs, `v` being empty.)
fn recycle<'x, 'y>(mut v: Vec<WordRef<'x>>) -> Vec<WordRef<'y>> {
    v.clear();
    v.into_iter()
        .map(|w| WordRef {
            address: "",
            value: w.value,
            item: w.item,
        })
        .collect()
}

/// The separator between words in this line's style: nothing when the first
/// replaced word is glued to the item before it (`G1X1Y2`), else a space.
fn separator(line: &Line, replace: &[usize]) -> &'static str {
    match replace.first() {
        Some(&i) if i > 0 && !matches!(line.items[i - 1].kind, ItemKind::Space) => "",
        _ => " ",
    }
}

/// Whether `line` opens (`Some(true)`: `o100 sub`) or closes
/// (`Some(false)`: `o100 endsub`) a LinuxCNC subroutine's definition.
fn subroutine_bound(line: &Line) -> Option<bool> {
    let first = line.bytes.iter().find(|b| !b.is_ascii_whitespace())?;
    if !matches!(first, b'o' | b'O') {
        return None;
    }
    let text = std::str::from_utf8(&line.bytes).ok()?;
    let statement = crate::program::opaque::o_word_statement(text)?;
    let keyword = statement.rsplit(' ').next()?;
    if keyword.eq_ignore_ascii_case("sub") {
        Some(true)
    } else if keyword.eq_ignore_ascii_case("endsub") {
        Some(false)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recycle_keeps_the_allocation() {
        let text = String::from("X");
        let mut v = Vec::with_capacity(16);
        v.push(WordRef {
            address: text.as_str(),
            value: 1.0,
            item: 0,
        });
        let ptr = v.as_ptr() as usize;
        let r: Vec<WordRef<'static>> = recycle(v);
        assert!(r.is_empty());
        assert_eq!(r.capacity(), 16);
        assert_eq!(r.as_ptr() as usize, ptr);
    }
}
