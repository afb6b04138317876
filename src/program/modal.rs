//! Modal state of an NC program and the poses its blocks describe.
//!
//! The state machine is fed one block at a time (its words, in order, and its
//! bare keywords) and says whether the block carries a tool pose that must be
//! converted, and what that pose is. Rules (documented in `docs/programs.md`):
//!
//! - Motion: `G0` rapid, `G1` linear, `G2`/`G3` arcs, `G80`–`G89` canned
//!   cycles; non-modal `G4 G10 G28 G30 G52 G53 G92` make the block pass through.
//! - `G90`/`G91` absolute / incremental tool tip; the tool axis is always absolute.
//! - `G20`/`G21` (and Siemens `G70`/`G71`, `G700`/`G710`) inch / mm: inch
//!   values are converted to mm for the chain and back for output.
//! - `G93`/`G94`/`G95` feed modes; `F` is modal.
//! - Pose mode is switched on by `G43.4`, `G43.5` (Fanuc TCP) and `TRAORI`
//!   (Sinumerik), off by `G49` and `TRAFOOF`. A linear move that carries
//!   `I J K` or `A3= B3= C3=` is a pose in any case and switches pose mode on.
//!   With [`PoseStart::On`] (the default of `kinpost post`) pose mode is on
//!   from the first block, for CAM programs that carry poses without a TCP code.
//! - In pose mode a `G0`/`G1` block with any of `X Y Z I J K A3 B3 C3` is a
//!   pose; missing coordinates keep their modal values. Under `G43.4`,
//!   `G234` and `TRAORI` so is one with `A B C`: the orientation as rotary
//!   axis positions ([`BlockMeaning::rotaries`]). An arc or a canned
//!   cycle with coordinates in pose mode is an error.
//! - In pose mode these are refused too: `U V W E` axis words, cutter radius
//!   compensation (`G41`, `G42`, `G41.1`–`G42.2`; modal until `G40`, and
//!   pose mode may not start under it), and under `G91` a block-delete
//!   (`/`) pose block. The modes a `/` block changes are checked beside
//!   this state (`block_delete_switch::BlockDeleteSwitch`).

use super::frames;
use super::ijk;
pub use super::rotary_words::{RotaryWord, RotaryWords};
pub use super::tool_vector::{QUIET_NORMALISATION, TOOL_VECTOR_TOLERANCE};
use super::unfollowed;
use nalgebra::Vector3;

mod meaning;
mod modes;
pub use meaning::{BlockError, BlockMeaning, POSE_ITEMS_INLINE, PoseItems, TcpCode};
pub use modes::{FeedMode, Motion, PoseStart, Units};

/// One word of a block, as the modal state needs it.
#[derive(Debug, Clone, Copy)]
pub struct WordRef<'a> {
    /// Upper-case address (`X`, `G`, `A3`, …).
    pub address: &'a str,
    /// Numeric value as written (program units).
    pub value: f64,
    /// Index of the word's item in the parsed line (for error columns and rewriting).
    pub item: usize,
}

/// The (address, value) pairs of `words`, as `program::ijk` reads them.
fn pairs<'a>(words: &'a [WordRef<'a>]) -> impl ijk::Words<'a> {
    words.iter().map(|w| (w.address, w.value))
}

/// The modal state of a program.
#[derive(Debug, Clone)]
pub struct ModalState {
    /// Motion mode.
    pub motion: Motion,
    /// `G90` (true) or `G91`.
    pub absolute: bool,
    /// Length units.
    pub units: Units,
    /// Units of the feed `F` ([`BlockMeaning::feed_units`]).
    pub feed_units: Units,
    /// Feed mode.
    pub feed_mode: FeedMode,
    /// Modal feed value.
    pub feed: Option<f64>,
    /// Pose mode on.
    pub pose_mode: bool,
    /// Pose mode was switched on by a Fanuc-style TCP code (`G43.4`,
    /// `G43.5`, Haas `G234`): the other codes of its modal group (`G43`,
    /// `G44`, `G43.1`: tool length compensation) end it, as `G49` does.
    pub fanuc_tcp: bool,
    /// A frame statement (G68…, AROT …) has been seen: it stays active on
    /// the controller, where it would move the machine axis words kinpost
    /// writes, so pose mode may not start after it.
    pub frame_seen: bool,
    /// A keyword only Sinumerik has (`TRAORI`, `TRAFOOF`, `ORIWKS`,
    /// `ORIMKS`, a frame statement) came: `G58`/`G59` with axis words are
    /// then its programmable frame's translation, not Fanuc's fifth and
    /// sixth work offsets.
    pub sinumerik: bool,
    /// A shift of the program's coordinates (`G52` with an offset other
    /// than 0, `G92`) is on, until `G52` with offsets 0 or `G92.1`/`G92.2`:
    /// it would move kinpost's linear axis words, so pose mode may not
    /// start under it (as under Sinumerik's `TRANS`, a frame).
    pub shift_seen: bool,
    /// An interpolation mode that changes what later axis words mean
    /// (`unfollowed::interpolation_mode`: Fanuc G12.1, G7.1, Okuma G169) is
    /// on: pose mode may not start under it.
    pub interpolation_mode: bool,
    /// Cutter radius compensation (`G41`, `G42`, `G41.1`–`G42.2`) is on,
    /// until `G40`: the controller would offset kinpost's machine axis
    /// words by the tool radius, so pose mode may not start under it.
    pub cutter_comp: bool,
    /// Sinumerik `ORIMKS` is on, until `ORIWKS`: tool vectors are then in
    /// machine coordinates, not the workpiece frame kinpost converts from.
    pub machine_orientation: bool,
    /// Modal tool tip, mm (None until the program sets the coordinate).
    pub tip: [Option<f64>; 3],
    /// Modal tool axis (programmed components, not normalised).
    pub axis: Vector3<f64>,
    /// Whether the program has set the tool axis (else it is (0, 0, 1) or
    /// seeded from the machine position).
    pub axis_set: bool,
    /// The tool axis is not known since this line: the machine went where
    /// the program does not say ([`ModalState::lose_orientation`]) since the
    /// axis was set or seeded, and a pose must give its orientation.
    pub axis_lost: Option<usize>,
    /// The TCP code in force orients the tool by rotary axis positions
    /// (Fanuc `G43.4` type 1, Haas `G234`, Sinumerik `TRAORI`): `A B C`
    /// words in pose mode are the rotary axes' positions. Not under
    /// `G43.5` (type 2: I J K only), nor in a pose mode started by a tool
    /// vector or `--pose-start on`.
    pub tcp_rotaries: bool,
    /// The orientation of the poses is given by rotary axis positions
    /// (the last pose block that gave one gave rotary words, not a tool
    /// vector).
    pub rotary_orientation: bool,
    /// The work offset selected last (`G54` … as ten times its code, with
    /// the `P` of `G54.1` / `G154`), if the program selected one.
    pub work_offset: Option<(i64, Option<u64>)>,
    /// A pose came since pose mode was last switched on.
    pub posed: bool,
    /// What block-delete (`/`) pose blocks gave that later blocks may not
    /// take over.
    pub skippable: super::block_delete::SkippableCarry,
    /// Circular moves (`G2`/`G3`) in pose mode are poses at their end
    /// point, the tool axis held, for a reader that follows the arc
    /// (`post`, `compensate`); else they are refused.
    pub arcs_as_poses: bool,
}

/// Whether `address` is a word of Sinumerik's reference and fixed point
/// approaches (`G74 Z1=0`, `G75 FP=2 X1=0`): an axis with its channel
/// index, or the fixed point's number.
pub fn point_approach_word(address: &str) -> bool {
    address == "FP" || unfollowed::indexed_axis(address)
}

/// Whether `address` is an axis word of G-code (`X Y Z A B C U V W`).
pub fn is_axis_address(address: &str) -> bool {
    matches!(address, "X" | "Y" | "Z" | "A" | "B" | "C" | "U" | "V" | "W")
}

impl ModalState {
    /// The state at program start.
    pub fn new(start: PoseStart) -> Self {
        ModalState {
            motion: Motion::Rapid,
            absolute: true,
            units: Units::Mm,
            feed_units: Units::Mm,
            feed_mode: FeedMode::PerMinute,
            feed: None,
            pose_mode: start == PoseStart::On,
            fanuc_tcp: false,
            frame_seen: false,
            sinumerik: false,
            shift_seen: false,
            interpolation_mode: false,
            cutter_comp: false,
            machine_orientation: false,
            tip: [None; 3],
            axis: Vector3::z(),
            axis_set: false,
            axis_lost: None,
            tcp_rotaries: false,
            rotary_orientation: false,
            work_offset: None,
            posed: false,
            skippable: Default::default(),
            arcs_as_poses: false,
        }
    }

    /// The machine moved in machine coordinates (pose mode off) to where the
    /// tool tip is `tip` and the tool axis `axis`: a later pose block that
    /// gives only some coordinates continues from there, as a controller
    /// switching TCP on continues from its current position.
    pub fn seed_from_machine(&mut self, tip: Vector3<f64>, axis: Vector3<f64>) {
        self.tip = [Some(tip.x), Some(tip.y), Some(tip.z)];
        self.axis = axis;
        self.axis_set = false;
        self.axis_lost = None;
        self.skippable.reset();
    }

    /// How the tool is oriented is no longer known after line `at` (a
    /// move kinpost does not follow, a move home of the rotaries): a pose
    /// must give its orientation. The first such line since the
    /// orientation was last known is kept, to be named.
    pub fn lose_orientation(&mut self, at: usize) {
        self.axis_lost.get_or_insert(at);
    }

    /// Applies one block and says what it means. `keywords` are the bare
    /// keywords of the block with their items, the calls kinpost reads as
    /// pseudo-keywords (`opaque::known_call`), and `"/"` for block delete.
    pub fn apply(
        &mut self,
        words: &[WordRef<'_>],
        keywords: &[(usize, &str)],
    ) -> Result<BlockMeaning, BlockError> {
        let mut tcp_codes = Vec::new();
        let mut tcp_offset_items = Vec::new();
        let mut non_modal = false;
        let mut feed_item = None;
        let mut fanuc_tcp_here = false;
        let mut frame = None;
        // A pole or a polar move (Sinumerik G110–G112, AP= RP=): refused in
        // pose mode.
        let mut polar = None;
        // A block that changes the coordinate system, or goes home, in pose
        // mode: its item and what it does.
        let mut setup: Option<(usize, &str)> = None;
        // A work offset other than the one in force: its item.
        let mut offset_change = None;
        let was_pose_mode = self.pose_mode;
        // A cutter radius compensation code (G41, G42, G41.1–G42.2): its item.
        let mut cutter_comp = None;
        // Sinumerik `ORIMKS` (tool vectors in machine coordinates): its item.
        let mut orimks = None;
        // Block delete (`/`, a pseudo-keyword): the controller may skip the block.
        let block_delete = keywords.iter().find(|(_, k)| *k == "/").map(|(i, _)| *i);
        let has = |a: &str| words.iter().any(|w| w.address == a);
        // A lathe's cutting cycle (`unfollowed::lathe_cycle`).
        let lathe_cycle = |code: i64| unfollowed::lathe_cycle(code, has);
        let mut unfollowed: Option<(usize, String)> = None; // (`program::unfollowed`)
        for w in words {
            match w.address {
                "G" => {
                    let code = (w.value * 10.0).round() as i64;
                    match code {
                        0 => self.motion = Motion::Rapid,
                        10 => self.motion = Motion::Linear,
                        20 | 30 => self.motion = Motion::Arc,
                        800 => self.motion = Motion::Rapid,
                        // A lathe's cutting cycles (Fanuc G70–G74 with their
                        // P Q U W, LinuxCNC G70–G72 with Q) cut with moves of
                        // their own; without those words G70/G71 are
                        // Sinumerik's inch / mm and G73/G74 a mill's cycles.
                        c if lathe_cycle(c) => {
                            non_modal = true;
                            unfollowed =
                                unfollowed.or(Some((w.item, unfollowed::LATHE_CYCLE.into())));
                        }
                        // Sinumerik's reference and fixed point approaches
                        // (`G74 Z1=0`, `G75 FP=2 Z1=0`: machine axes with
                        // their channel index): not a cycle, the axes go
                        // where the program's coordinates do not say.
                        740 | 750 if words.iter().any(|o| point_approach_word(o.address)) => {
                            non_modal = true
                        }
                        810..=890 => self.motion = Motion::Other,
                        // Threads, tapping and splines: motion modes whose
                        // I J K are not a tool axis (`program::ijk`).
                        c if ijk::other_motion(c, pairs(words)) => self.motion = Motion::Other,
                        50 | 51 => {} // Fanuc G05 P…, G05.1 Q…: a mode, not a motion.
                        // Frames change how every later move lands (refused
                        // in pose mode, passed through outside it): a tilted
                        // or rotated plane (G68…, its I J K angles), G51.1
                        // mirroring, G51 scaling, G16 polar coordinates, Haas
                        // G254 (a work offset that moves with the rotaries).
                        // G16 with axis words in its block: a polar move
                        // at once (`G16 G1 X20 Y0`: radius 20, angle 0).
                        160 if words.iter().any(|o| is_axis_address(o.address)) => {
                            frame = Some(w.item);
                            unfollowed =
                                unfollowed.or(Some((w.item, unfollowed::POLAR_MOVE.into())));
                        }
                        680 | 682 | 683 | 684 | 511 | 510 | 160 | 2540 => frame = Some(w.item),
                        // Fanuc's rotary table dynamic fixture offset
                        // (G54.2 P1–P8; P0 cancels): a work offset that
                        // moves with the rotaries, as Haas G254.
                        542 if words.iter().any(|o| o.address == "P" && o.value == 0.0) => {
                            self.frame_seen = false
                        }
                        542 => frame = Some(w.item),
                        // G69, G50 (scaling off), G50.1 (mirror off), G15
                        // (polar off), Haas G255 (dynamic work offset off).
                        // Fanuc lathe `G50 X Z`: a coordinate system, as G92.
                        500 if words.iter().any(|o| matches!(o.address, "X" | "Y" | "Z")) => {
                            (non_modal, self.frame_seen) = (true, false);
                            setup = setup.or(Some((w.item, unfollowed::LATHE_G50)));
                        }
                        690 | 500 | 501 | 150 | 2550 => self.frame_seen = false,
                        // Sinumerik G110–G112: X Y are the polar pole.
                        1100 | 1110 | 1120 => {
                            non_modal = true;
                            polar = polar.or(Some(w.item));
                        }
                        // Cutter radius compensation: G41/G42 (Fanuc,
                        // LinuxCNC, Sinumerik), G41.1/G42.1 (LinuxCNC
                        // dynamic), G41.2/G42.2 (Fanuc 3-D); G40 cancels.
                        410..=413 | 420..=423 => {
                            self.cutter_comp = true;
                            cutter_comp = cutter_comp.or(Some(w.item));
                        }
                        400 => self.cutter_comp = false,
                        900 => self.absolute = true,
                        910 => self.absolute = false,
                        200 | 7000 => (self.units, self.feed_units) = (Units::Inch, Units::Inch),
                        210 | 7100 => (self.units, self.feed_units) = (Units::Mm, Units::Mm),
                        // Sinumerik G70/G71: the lengths alone; F in the
                        // basic system, taken as metric.
                        700 => (self.units, self.feed_units) = (Units::Inch, Units::Mm),
                        710 => (self.units, self.feed_units) = (Units::Mm, Units::Mm),
                        930 => self.feed_mode = FeedMode::InverseTime,
                        940 => self.feed_mode = FeedMode::PerMinute,
                        950 => self.feed_mode = FeedMode::PerRevolution,
                        // Fanuc G43.4/G43.5, Haas G234 (TCPC).
                        434 | 435 | 2340 => {
                            self.pose_mode = true;
                            self.fanuc_tcp = true;
                            self.tcp_rotaries = code != 435;
                            fanuc_tcp_here = true;
                            tcp_codes.push(TcpCode::FanucOn(w.item));
                        }
                        490 => (self.pose_mode, self.fanuc_tcp) = (false, false),
                        // LinuxCNC's dynamic tool length offset (G43.1 with
                        // axis words) and additional offset (G43.2): the
                        // words are offsets, not a move.
                        431 | 432 if words.iter().any(|o| is_axis_address(o.address)) => {
                            non_modal = true;
                            if self.fanuc_tcp {
                                (self.pose_mode, self.fanuc_tcp) = (false, false);
                            }
                            setup = setup.or(Some((w.item, "changes the tool length offset by axis words (LinuxCNC G43.1, G43.2)")));
                        }
                        // G43, G44, G43.1 after G43.4 / G43.5: the same
                        // modal group (Fanuc, Mitsubishi: G44 is its TCP
                        // cancel), so TCP ends there.
                        430 | 431 | 440 if self.fanuc_tcp => {
                            (self.pose_mode, self.fanuc_tcp) = (false, false)
                        }
                        // Offsets and coordinate systems: under the poses
                        // they would move kinpost's machine axis words.
                        100 | 520 | 920..=923 => {
                            non_modal = true;
                            match code {
                                520 => {
                                    self.shift_seen = words
                                        .iter()
                                        .any(|o| is_axis_address(o.address) && o.value != 0.0)
                                }
                                920 => self.shift_seen = true,
                                921 | 922 => self.shift_seen = false,
                                _ => {}
                            }
                            setup = setup.or(Some((w.item, "changes the coordinate system the poses are given in (G10, G52, G92)")));
                        }
                        // Sinumerik G58/G59 X…: the programmable frame's
                        // translation replaced or added to, as by `TRANS`.
                        580 | 590
                            if self.sinumerik
                                && words.iter().any(|o| is_axis_address(o.address)) =>
                        {
                            frame = Some(w.item)
                        }
                        // G54.1 P (Fanuc), G154 P (Haas): more work offsets.
                        540..=590 | 591..=593 | 1540 | 5000..=5990 => {
                            let p = (code == 541 || code == 1540)
                                .then(|| words.iter().find(|o| o.address == "P"))
                                .flatten()
                                .map(|o| o.value.to_bits());
                            // The offset in force selected again (an NX
                            // post does at every operation) changes nothing.
                            if self.work_offset != Some((code, p)) {
                                self.work_offset = Some((code, p));
                                offset_change = Some(w.item);
                            }
                        }
                        280 | 300 => {
                            non_modal = true;
                            // `G91 G28 Z0`: increments of 0, no intermediate point.
                            let g = |v: f64| words.iter().any(|o| o.address == "G" && o.value == v);
                            let incremental = g(91.0) || (!self.absolute && !g(90.0));
                            if words.iter().any(|o| {
                                matches!(o.address, "X" | "Y" | "Z" | "A" | "B" | "C")
                                    && !(incremental && o.value == 0.0)
                            }) {
                                setup = setup.or(Some((w.item, "moves home through an intermediate point (G28/G30 with axis words) that kinpost would have to convert")));
                            }
                        }
                        40 | 530 | 1530 => non_modal = true,
                        c => {
                            // Fanuc's G53.1 turns the rotaries to a tilted
                            // plane's tool axis: a move to where the program's
                            // coordinates do not say.
                            non_modal |= c == 531;
                            let radius = words.iter().any(|w| w.address == "C" && w.value != 0.0);
                            if let Some(on) = unfollowed::interpolation_mode(c, radius) {
                                self.interpolation_mode = on;
                            }
                            unfollowed = unfollowed.or(unfollowed::g_code(c).map(|m| (w.item, m)));
                        }
                    }
                }
                // Sinumerik `G4 F2`: a dwell of 2 s, and the feed in
                // force stays.
                "F" if words.iter().any(|o| o.address == "G" && o.value == 4.0) => {}
                "F" => {
                    self.feed = Some(w.value);
                    feed_item = Some(w.item);
                }
                "AP" | "RP" => polar = polar.or(Some(w.item)),
                // Heidenhain ISO's tool centre point management (M128/M129).
                "M" if w.value == 128.0 || w.value == 129.0 => {
                    self.interpolation_mode = w.value == 128.0
                }
                _ => {}
            }
        }
        if fanuc_tcp_here {
            tcp_offset_items.extend(words.iter().filter(|w| w.address == "H").map(|w| w.item));
            // A `P` beside the TCP code (`G43.4 P1 H1`: the TCP type on
            // some controls) goes with it, unless another code of the block
            // takes a `P` (a dwell, a subprogram call, an extended work
            // offset `G54.1 P…`).
            if words.iter().all(|w| p_free(w.address, w.value)) {
                tcp_offset_items.extend(words.iter().filter(|w| w.address == "P").map(|w| w.item));
            }
            // Fanuc `G43.5 … Q`: the tool inclined by Q degrees from I J K.
            if let Some(q) = words.iter().find(|w| w.address == "Q") {
                unfollowed = unfollowed.or(Some((q.item, unfollowed::TCP_INCLINATION.into())));
            }
        }
        let frame_values = if keywords.is_empty() {
            frames::FrameValues::default()
        } else {
            frames::values(words.iter().map(|w| (w.address, w.value)))
        };
        for (item, k) in keywords {
            if matches!(*k, "TRAORI" | "TRAORI(…)" | "TRAFOOF" | "ORIWKS" | "ORIMKS")
                || frames::SETTING.contains(k)
                || *k == frames::FRAME_VARIABLE
                || *k == frames::NULL_FRAME_VARIABLE
            {
                self.sinumerik = true;
            }
            match *k {
                "TRAORI" => {
                    self.pose_mode = true;
                    self.tcp_rotaries = true;
                    tcp_codes.push(TcpCode::SiemensOn(*item));
                }
                "TRAFOOF" => self.pose_mode = false,
                "ORIMKS" => {
                    self.machine_orientation = true;
                    orimks = Some(*item);
                }
                "ORIWKS" => self.machine_orientation = false,
                // Sinumerik diameter programming (X a diameter): pose mode
                // may not start under it, and in pose mode it is refused as
                // a transformation kinpost does not apply.
                "DIAMON" | "DIAM90" | "DIAMONA" | "DIAMOF" | "DIAMOFA" => {
                    if k.starts_with("DIAMOF") {
                        self.interpolation_mode = false;
                    } else if !self.pose_mode {
                        self.interpolation_mode = true;
                    }
                    if unfollowed.is_none() {
                        unfollowed = unfollowed::transformation(k).map(|m| (*item, m));
                    }
                }
                // `TRAORI(1,0,1,0)`: TCP on, with a basic tool orientation
                // or rotary offsets kinpost does not apply.
                "TRAORI(…)" => {
                    self.pose_mode = true;
                    tcp_codes.push(TcpCode::SiemensOn(*item));
                    unfollowed =
                        unfollowed.or(Some((*item, super::opaque::TRAORI_ARGUMENTS.into())));
                }
                // Sinumerik's `G53` (also suppressing the other offsets).
                "SUPA" => non_modal = true,
                super::fagor::TCP_ON | super::fagor::TCP_OFF => {
                    self.interpolation_mode = *k == super::fagor::TCP_ON
                }
                // Sinumerik motion modes besides G0–G3 (modal, like G2):
                // circles through a point or tangential, and splines.
                "CIP" | "CT" => self.motion = Motion::Arc,
                "ASPLINE" | "BSPLINE" | "CSPLINE" | "POLY" => self.motion = Motion::Other,
                // Sinumerik frames (`program::frames`): their X Y Z are
                // offsets, angles or factors, never a tool tip. Under
                // TRAORI they would move every later pose, which kinpost
                // does not fold in: refused in pose mode (below), passed
                // through outside it.
                k if let Some(change) = frames::change(k, frame_values) => match change {
                    frames::FrameChange::Set => frame = frame.or(Some(*item)),
                    // Values that change nothing are still no move.
                    frames::FrameChange::Delete | frames::FrameChange::Keep => {
                        self.frame_seen &= change == frames::FrameChange::Keep;
                        non_modal |= frame_values.any;
                    }
                },
                k if unfollowed.is_none() => {
                    unfollowed = unfollowed::transformation(k).map(|m| (*item, m));
                }
                _ => {}
            }
        }

        if !self.pose_mode {
            (self.tcp_rotaries, self.rotary_orientation) = (false, false);
        }
        if !self.pose_mode || !was_pose_mode {
            self.posed = false;
        }
        // A new work offset in pose mode before its first pose is as one
        // set before TCP was switched on; after a pose it would move the
        // later ones.
        // A new work offset in the first pose's block: the coordinates
        // the block does not give are not known in it.
        if offset_change.is_some() && self.pose_mode {
            self.tip = [None; 3];
        }
        if let Some(item) = offset_change
            && self.posed
        {
            setup = setup.or(Some((
                item,
                "changes the work offset (G54–G59.3, G54.1 P, Haas G154 P, Sinumerik G500–G599) after a pose",
            )));
        }
        let is_tip = |a: &str| matches!(a, "X" | "Y" | "Z");
        let is_axis = |a: &str| matches!(a, "I" | "J" | "K" | "A3" | "B3" | "C3");
        // Rotary axis positions orienting the tool (under G43.4, G234,
        // TRAORI; elsewhere refused below as an orientation word).
        let tcp_rotaries = self.tcp_rotaries;
        let is_rotary = |a: &str| tcp_rotaries && matches!(a, "A" | "B" | "C");
        let has_tip = words.iter().any(|w| is_tip(w.address));
        let has_axis = words.iter().any(|w| is_axis(w.address));
        let has_rotary = words.iter().any(|w| is_rotary(w.address));
        let straight = matches!(self.motion, Motion::Rapid | Motion::Linear);
        if let Some((item, what)) = setup
            && self.pose_mode
        {
            return Err(BlockError {
                item: Some(item),
                message: format!(
                    "this block {what}: in pose mode it is not converted, since the controller would apply it to kinpost's machine axis words; set offsets before TCP is switched on, or give the poses in the workpiece frame (--work-offset)"
                ),
            });
        }
        // Where pose mode starts: the TCP code, else the block's first word.
        let start_item = || {
            tcp_codes
                .first()
                .map(|c| match c {
                    TcpCode::FanucOn(i) | TcpCode::SiemensOn(i) => *i,
                })
                .or_else(|| words.first().map(|w| w.item))
        };
        let orimks = orimks.or(start_item().filter(|_| self.machine_orientation));
        if self.pose_mode
            && let Some((item, message)) = [
                (polar, unfollowed::POLAR),
                (orimks, unfollowed::ORIMKS),
                (cutter_comp, unfollowed::CUTTER_COMP),
            ]
            .into_iter()
            .find_map(|(item, message)| Some((item?, message)))
        {
            return Err(BlockError {
                item: Some(item),
                message: message.into(),
            });
        }
        if let Some(item) = frame {
            self.frame_seen = true;
            if self.pose_mode {
                return Err(BlockError {
                    item: Some(item),
                    message: frames::IN_POSE_MODE.into(),
                });
            }
            non_modal = true;
        }
        // The I J K of a code not followed (Haas G12, Fanuc G22) are its own.
        let owned = ijk::owner(pairs(words)).is_some() || unfollowed.is_some();
        if straight && has_axis && !non_modal && !owned {
            self.pose_mode = true;
        }
        if self.pose_mode && (self.frame_seen || self.shift_seen || self.interpolation_mode) {
            return Err(BlockError {
                item: start_item(),
                message: if self.frame_seen {
                    frames::AT_POSE_START
                } else if self.shift_seen {
                    unfollowed::SHIFT_AT_POSE_START
                } else {
                    unfollowed::MODE_AT_POSE_START
                }
                .into(),
            });
        }
        if self.pose_mode && self.cutter_comp {
            return Err(BlockError {
                item: start_item(),
                message: "pose mode starts while cutter radius compensation (G41, G42, G41.1, G42.1, G41.2, G42.2) set earlier is active: the controller would offset kinpost's machine axis words by the tool radius; cancel it with G40 before TCP is switched on".into(),
            });
        }

        let mut meaning = BlockMeaning {
            pose: None,
            pose_items: PoseItems::new(),
            rotaries: None,
            tcp_codes,
            tcp_offset_items,
            motion: self.motion,
            feed_mode: self.feed_mode,
            units: self.units,
            feed_units: self.feed_units,
            absolute: self.absolute,
            feed: self.feed,
            feed_item,
            warnings: Vec::new(),
            vector_deviation: 0.0,
            non_modal,
            unfollowed: None,
        };
        // The orientation given another way than by a tool vector or (under
        // G43.4, G234, TRAORI) rotary axis positions: Euler or
        // RPY angles (A2 B2 C2), lead and tilt angles, the tool's rotation
        // about itself, surface normals for 3-D tool compensation (A4 B4
        // C4, A5 B5 C5). kinpost would keep the previous tool vector and
        // add a second set of rotary words: refused instead.
        // A subprogram or macro call moves the tool in a way kinpost cannot
        // see (Fanuc M98/M198/G65/G66, Sinumerik CALL/PCALL/MCALL/EXTCALL).
        if self.pose_mode {
            let call = words
                .iter()
                .find(|w| unfollowed::call_word(w.address, w.value))
                .map(|w| (w.item, format!("{}{}", w.address, w.value)))
                .or_else(|| {
                    keywords
                        .iter()
                        .find(|(_, k)| unfollowed::CALL_KEYWORDS.contains(k))
                        .map(|(i, k)| (*i, k.to_string()))
                });
            if let Some((item, what)) = call {
                return Err(BlockError {
                    item: Some(item),
                    message: format!(
                        "a subprogram or macro call ({what}) in pose mode is not converted: kinpost cannot see what it moves; call it outside TRAORI / G43.4, or have the CAM system write its moves"
                    ),
                });
            }
        }
        if let Some((item, what)) = unfollowed {
            if self.pose_mode {
                let message = unfollowed::message(&what, true);
                return Err(BlockError {
                    item: Some(item),
                    message,
                });
            }
            meaning.unfollowed = Some((item, what));
        }
        if self.pose_mode
            && !non_modal
            && let Some((w, message)) = words
                .iter()
                .filter(|w| !is_rotary(w.address))
                // A followed arc's radius.
                .filter(|w| {
                    !(w.address == "CR" && self.motion == Motion::Arc && self.arcs_as_poses)
                })
                .find_map(|w| unfollowed::pose_word(w.address).map(|m| (w, m)))
        {
            return Err(BlockError {
                item: Some(w.item),
                message,
            });
        }

        // A secondary linear axis (U V W: a quill along Z, a second slide)
        // or an E axis (the extruder or seventh axis of some dialects) moves
        // the tool too, besides the machine axes kinpost writes: it would
        // move the tool off the converted pose. `X1E5` (an E glued to a pose
        // word) is refused below, as a number with an exponent; Haas
        // `G187 P1 E0.01` is a smoothing tolerance.
        let g187 = words.iter().any(|w| w.address == "G" && w.value == 187.0);
        if self.pose_mode
            && !non_modal
            && let Some(w) = words.iter().find(|w| {
                unfollowed::numbered_axis(w.address)
                    || matches!(w.address, "U" | "V" | "W" | "E")
                        && !(w.address == "E"
                            && (g187
                                || words.iter().any(|p| {
                                    p.item + 1 == w.item
                                        && (is_tip(p.address) || is_axis(p.address))
                                })))
            })
        {
            return Err(BlockError {
                item: Some(w.item),
                message: unfollowed::secondary_axis_message(w.address),
            });
        }

        if !self.pose_mode || non_modal || !(has_tip || has_axis || has_rotary) {
            return Ok(meaning);
        }
        let arc = self.motion == Motion::Arc && self.arcs_as_poses;
        if !straight
            && let Some((item, message)) = super::arc::refusal_in_pose_mode(
                self.motion == Motion::Arc,
                arc,
                words.iter().map(|w| (w.address, w.value, w.item)),
                is_rotary,
                block_delete,
            )
        {
            return Err(BlockError { item, message });
        }
        // An arc's I J K are its centre.
        let has_axis = has_axis && !arc;

        let repeated = words.iter().map(|w| (w.address, w.value, w.item));
        if let Some((item, message)) = super::repeated_words::second(repeated) {
            return Err(BlockError {
                item: Some(item),
                message,
            });
        }
        // The orientation given twice: by a tool vector and by rotary
        // positions.
        if has_axis && let Some(w) = words.iter().find(|w| is_rotary(w.address)) {
            return Err(BlockError {
                item: Some(w.item),
                message: format!(
                    "`{}{}` gives the tool orientation as a rotary axis position, and this block gives it as a tool vector (I J K or A3 B3 C3) too: the block is ambiguous; give one of them",
                    w.address, w.value
                ),
            });
        }
        // A rotary position in a block the controller may skip would be
        // taken over by the blocks after it, as kinpost cannot know.
        if let Some(item) = block_delete
            && has_rotary
        {
            return Err(BlockError {
                item: Some(item),
                message: super::block_delete::TURNS_A_ROTARY.into(),
            });
        }
        // Under G91 the controller adds each block's increments to where the
        // last block left the machine; kinpost's machine-axis increments
        // come from its own chain of poses. A block the controller may skip
        // (block delete switch on) breaks that chain for every block after
        // it. In absolute mode each converted block stands alone.
        if let Some(item) = block_delete
            && !self.absolute
        {
            return Err(BlockError {
                item: Some(item),
                message: super::block_delete::UNDER_G91.into(),
            });
        }

        // Update the modal tip and axis.
        let before = (self.tip, self.axis);
        let mut tip_given = [false; 3];
        let mut axis_given = [false; 3];
        let scale = self.units.mm_per_unit();
        for w in words {
            let slot = match w.address {
                "X" => Some(0),
                "Y" => Some(1),
                "Z" => Some(2),
                _ => None,
            };
            if let Some(i) = slot {
                tip_given[i] = true;
                let v = w.value * scale;
                self.tip[i] = if self.absolute {
                    Some(v)
                } else {
                    match self.tip[i] {
                        Some(old) => Some(old + v),
                        None => {
                            return Err(BlockError {
                                item: Some(w.item),
                                message: format!(
                                    "incremental {} move (G91) but the tool tip {} is not known yet: give an absolute position first",
                                    w.address, w.address
                                ),
                            });
                        }
                    }
                };
                meaning.pose_items.push(w.item);
            }
            let comp = match w.address {
                _ if arc => None,
                "I" | "A3" => Some(0),
                "J" | "B3" => Some(1),
                "K" | "C3" => Some(2),
                _ => None,
            };
            if is_rotary(w.address) {
                let address = match w.address {
                    "A" => "A",
                    "B" => "B",
                    _ => "C",
                };
                meaning.rotaries.get_or_insert_default().push(RotaryWord {
                    address,
                    value: w.value,
                    item: w.item,
                });
                meaning.pose_items.push(w.item);
            }
            if let Some(i) = comp {
                if !axis_given.iter().any(|g| *g) {
                    // A block's first component starts a fresh vector: the
                    // ones it does not give are 0 (Fanuc G43.5, Sinumerik
                    // A3= B3= C3=); a block with none keeps the vector.
                    self.axis = Vector3::zeros();
                    self.axis_set = true;
                }
                axis_given[i] = true;
                self.axis[i] = w.value;
                meaning.pose_items.push(w.item);
            }
        }
        meaning.pose_items.sort_unstable();
        if has_rotary {
            self.rotary_orientation = true;
        } else if has_axis {
            self.rotary_orientation = false;
        } else if self.rotary_orientation {
            meaning.rotaries = Some(RotaryWords::new());
        }
        let gave = super::block_delete::Given {
            tip: tip_given,
            axis_any: axis_given.iter().any(|g| *g),
            axis_all: axis_given.iter().all(|g| *g),
        };
        let now = (self.tip, self.axis);
        self.skippable
            .check(block_delete.is_some(), gave, before, now)
            .map_err(|message| BlockError {
                item: meaning.pose_items.first().copied(),
                message,
            })?;

        let names = ["X", "Y", "Z"];
        let mut tip = Vector3::zeros();
        for i in 0..3 {
            match self.tip[i] {
                Some(v) => tip[i] = v,
                None => {
                    return Err(BlockError {
                        item: meaning.pose_items.first().copied(),
                        message: format!(
                            "the tool tip {} is not known yet: the first pose block must give X, Y and Z (and so must a pose after a move that leaves the machine where the program's coordinates do not say: home, machine coordinates, a new work offset, a tool change, a call, a move under G43, or axes never programmed)",
                            names[i]
                        ),
                    });
                }
            }
        }
        if let Some(i) = (0..3).find(|&i| !tip[i].is_finite()) {
            return Err(BlockError {
                item: meaning.pose_items.first().copied(),
                message: format!(
                    "the tool tip {} is out of range ({}): the incremental moves add up beyond ±1.8e308; expected coordinates in mm or inch",
                    names[i], tip[i]
                ),
            });
        }
        // `X1E5` is X1 and E5: G-code has no exponent. In a pose block an E
        // word glued to a pose word is almost surely meant as one.
        for w in words.iter().filter(|w| w.address == "E") {
            if let Some(p) = words
                .iter()
                .find(|p| p.item + 1 == w.item && (is_tip(p.address) || is_axis(p.address)))
            {
                return Err(BlockError {
                    item: Some(p.item),
                    message: format!(
                        "`{}{}` is followed directly by `E{}`: G-code numbers have no exponent (E is a word of its own), so this is not {}{}e{}; expected a plain decimal number (e.g. 0.0015, not 1.5E-3)",
                        p.address, p.value, w.value, p.address, p.value, w.value
                    ),
                });
            }
        }
        // After a move that may have turned the rotaries, the orientation
        // must be given.
        let oriented = has_rotary || axis_given.iter().any(|g| *g);
        if let Some(at) = self.axis_lost
            && !oriented
        {
            return Err(BlockError {
                item: meaning.pose_items.first().copied(),
                message: format!(
                    "the tool orientation is not known here: line {at} left the machine where the program's coordinates do not say (a move kinpost does not follow or cannot read, home, machine coordinates, program flow before it), and where the rotaries stand is not known; give the tool vector (I J K, A3 B3 C3) or, under G43.4, G234 and TRAORI, the rotary positions in this pose"
                ),
            });
        }
        if oriented {
            self.axis_lost = None;
        }
        let axis_item = words.iter().find(|w| is_axis(w.address)).map(|w| w.item);
        let (unit, norm) =
            super::tool_vector::normalised(self.axis).map_err(|message| BlockError {
                item: axis_item,
                message,
            })?;
        meaning.vector_deviation = (norm - 1.0).abs();
        if meaning.vector_deviation > QUIET_NORMALISATION {
            meaning.warnings.push(format!(
                "tool vector of length {norm:.9} normalised to unit length"
            ));
        }
        meaning.pose = Some((tip, unit));
        self.posed = true;
        Ok(meaning)
    }
}

#[cfg(test)]
mod tests;

/// A word that leaves a block's `P` to its TCP code: anything but a G or M
/// code, or one of the codes that take no `P` (motion, plane, units,
/// distance and feed modes, cancels, and the TCP codes themselves).
fn p_free(address: &str, value: f64) -> bool {
    match address {
        "G" => [
            0.0, 1.0, 17.0, 18.0, 19.0, 20.0, 21.0, 40.0, 43.4, 43.5, 49.0, 80.0, 90.0, 91.0, 93.0,
            94.0, 234.0,
        ]
        .contains(&value),
        "M" => false,
        _ => true,
    }
}
