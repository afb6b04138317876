//! Block delete (`/`) of blocks that change modes or move the machine
//! before pose mode: the modal state with the block-delete switch on, kept
//! beside the program's where the two differ in a mode the conversion
//! depends on ([`BlockDeleteSwitch`]; docs/programs.md). What a `/` pose
//! block gives is `block_delete.rs`.

use super::modal::{BlockError, BlockMeaning, FeedMode, ModalState, Motion, Units, WordRef};
use crate::gcode::Line;

/// The modes the conversion of a block depends on, as one value to
/// compare between the block-delete switch off and on.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Modes {
    absolute: bool,
    units: Units,
    pose_mode: bool,
    /// The motion mode; `G0` and `G1` count as one unless feeds are
    /// converted.
    motion: Motion,
    frame: bool,
    interpolation_mode: bool,
    cutter_comp: bool,
    machine_orientation: bool,
    /// Feed mode, feed and its units, when feeds are converted (else
    /// `None`).
    feed: Option<(FeedMode, Option<f64>, Units)>,
}

impl Modes {
    fn of(m: &ModalState, converts_feeds: bool) -> Self {
        Modes {
            absolute: m.absolute,
            units: m.units,
            pose_mode: m.pose_mode,
            motion: match m.motion {
                Motion::Rapid if !converts_feeds => Motion::Linear,
                other => other,
            },
            frame: m.frame_seen,
            interpolation_mode: m.interpolation_mode,
            cutter_comp: m.cutter_comp,
            machine_orientation: m.machine_orientation,
            feed: converts_feeds.then_some((m.feed_mode, m.feed, m.feed_units)),
        }
    }

    /// What differs between `self` and `other`, named.
    fn differences(&self, other: &Modes) -> Vec<&'static str> {
        let mut v = Vec::new();
        let mut add = |differs: bool, name| {
            if differs {
                v.push(name)
            }
        };
        add(
            self.absolute != other.absolute,
            "the distance mode (G90/G91)",
        );
        add(
            self.units != other.units,
            "the units (G20/G21, Sinumerik G70/G71, G700/G710)",
        );
        add(
            self.pose_mode != other.pose_mode,
            "tool centre point control (G43.4/G43.5/G234 or TRAORI on, G49 or TRAFOOF off, or a tool vector that starts pose mode)",
        );
        add(
            self.motion != other.motion,
            "the motion mode (G0/G1, G2/G3, cycles, threads and splines)",
        );
        add(
            self.frame != other.frame,
            "a frame (G68…, G51, G51.1, G16, G254, TRANS, ROT, CYCLE800 and their cancels)",
        );
        add(
            self.interpolation_mode != other.interpolation_mode,
            "an interpolation mode (G12.1/G13.1, G7.1, G107, Okuma G169/G168)",
        );
        add(
            self.cutter_comp != other.cutter_comp,
            "cutter radius compensation (G41/G42, G40)",
        );
        add(
            self.machine_orientation != other.machine_orientation,
            "Sinumerik ORIMKS/ORIWKS",
        );
        let (f, g) = (self.feed, other.feed);
        add(
            f.map(|x| x.0) != g.map(|x| x.0),
            "the feed mode (G93/G94/G95)",
        );
        add(f.map(|x| x.1) != g.map(|x| x.1), "the feed (F)");
        add(
            f.map(|x| x.2) != g.map(|x| x.2),
            "the units of the feed (Sinumerik G70/G71 against G700/G710)",
        );
        v
    }
}

/// Where a block-delete (`/`) block is, for a refusal raised at a later
/// block: its line, the column of its `/`, and its text.
#[derive(Debug, Clone, PartialEq)]
pub struct SlashPlace {
    /// 1-based line.
    pub line: usize,
    /// 1-based column of the `/`.
    pub col: usize,
    /// The line's text.
    pub text: String,
}

impl SlashPlace {
    fn of(line: &Line, item: usize) -> Self {
        SlashPlace {
            line: line.number,
            col: line.items.get(item).map_or(0, |i| i.start + 1),
            text: line.text_lossy(),
        }
    }
}

/// Why [`BlockDeleteSwitch::apply`] refuses a block.
#[derive(Debug, Clone, PartialEq)]
pub enum Refused {
    /// The block itself, as [`ModalState::apply`] refuses it.
    Block(BlockError),
    /// A block-delete block before it (or it), at `at`: the block's
    /// conversion depends on the block delete switch.
    Slash {
        /// The `/` block.
        at: SlashPlace,
        /// What is wrong and what to do.
        message: String,
    },
}

/// The block-delete switch and modal state (docs/programs.md, "Block
/// delete"): a `/` block the controller skips with the switch on leaves the
/// blocks after it in the modes before it. Beside the program's modal
/// state (every block applied: the switch off) this keeps the state with
/// the switch on (the `/` blocks skipped) while a `/` block has made the
/// two differ in a mode the conversion depends on — the distance mode,
/// the units, pose mode (TCP on or off), the motion mode (`G0` and `G1` as
/// one), a frame, cutter radius compensation, Sinumerik `ORIMKS`; with
/// converted feeds also `G0`/`G1`, the feed mode and the feed — and refuses
/// at that `/` a block without `/` that is converted under the difference:
/// a pose in either state, or a block refused in one state only. `/`
/// blocks themselves run all or none (one switch), so they are not
/// compared. Once a block without `/` sets the mode again, the two agree
/// and the state with the switch on is dropped.
///
/// It also follows where the machine-axis moves before pose mode leave the
/// tool ([`BlockDeleteSwitch::followed_move`]): a `/` move, or one under a
/// distance mode or units a `/` block changed, leaves it elsewhere with the
/// switch on, and a later pose that does not give X, Y, Z and its tool
/// vector is refused at that `/`.
#[derive(Debug, Clone, Default)]
pub struct BlockDeleteSwitch {
    /// The state with the switch on and the `/` block that made it differ.
    on: Option<Box<(ModalState, SlashPlace)>>,
    /// The position followed before pose mode depends on the switch since
    /// this `/` block: why, and where.
    position: Option<(&'static str, SlashPlace)>,
    /// Feeds are converted (`post --feed inverse-time`): the feed mode, the
    /// feed and `G0`/`G1` count among the modes.
    converts_feeds: bool,
}

impl BlockDeleteSwitch {
    /// The switch of a program whose feeds are converted
    /// (`converts_feeds`, `post --feed inverse-time`) or not.
    pub fn new(converts_feeds: bool) -> Self {
        BlockDeleteSwitch {
            converts_feeds,
            ..Default::default()
        }
    }

    /// [`ModalState::apply`] of one block of `line` (its `words` and
    /// `keywords`, `"/"` for block delete) on `modal`, the state with the
    /// switch off, with the refusals of the type documentation.
    pub fn apply(
        &mut self,
        modal: &mut ModalState,
        words: &[WordRef<'_>],
        keywords: &[(usize, &str)],
        line: &Line,
    ) -> Result<BlockMeaning, Refused> {
        let slash = keywords.iter().find(|(_, k)| *k == "/");
        // The common block: no `/`, and no `/` block before makes anything
        // depend on the switch.
        if slash.is_none() && self.on.is_none() && self.position.is_none() {
            return modal.apply(words, keywords).map_err(Refused::Block);
        }
        let feeds = self.converts_feeds;
        if let Some(&(item, _)) = slash {
            // With the switch on the block is skipped: the state stays the
            // one before it (or the one kept already).
            let before = self.on.is_none().then(|| modal.clone());
            let meaning = modal.apply(words, keywords).map_err(Refused::Block)?;
            if let Some(before) = before
                && Modes::of(&before, feeds) != Modes::of(modal, feeds)
            {
                self.on = Some(Box::new((before, SlashPlace::of(line, item))));
            }
            return Ok(meaning);
        }
        let off = modal.apply(words, keywords);
        if let Some(on) = self.on.as_mut() {
            let other = on.0.apply(words, keywords);
            let differs = Modes::of(modal, feeds).differences(&Modes::of(&on.0, feeds));
            if differs.is_empty() {
                self.on = None;
            } else {
                let pose = |r: &Result<BlockMeaning, BlockError>| {
                    r.as_ref().is_ok_and(|m| m.pose.is_some())
                };
                if pose(&off) || pose(&other) || off.is_ok() != other.is_ok() {
                    let at = on.1.clone();
                    return Err(Refused::Slash {
                        message: format!(
                            "this block-delete (`/`) block changes {}, and line {} is converted under it: with the block delete switch on the controller skips this block and runs line {} in the mode before it, and kinpost cannot write both; write the change without `/`, or set the mode again without `/` before line {}",
                            differs.join(" and "),
                            line.number,
                            line.number,
                            line.number
                        ),
                        at,
                    });
                }
            }
        }
        let meaning = off.map_err(Refused::Block)?;
        if meaning.pose.is_some()
            && let Some((why, at)) = &self.position
        {
            let given = |a: &[&str]| words.iter().any(|w| a.contains(&w.address));
            let whole = modal.absolute
                && given(&["X"])
                && given(&["Y"])
                && given(&["Z"])
                && given(&["I", "J", "K", "A3", "B3", "C3"]);
            if !whole {
                return Err(Refused::Slash {
                    message: format!(
                        "{why}, and the pose at line {} continues from where the machine-axis moves before it left the tool (it does not give X, Y, Z and the tool vector in G90): with the block delete switch on the tool is elsewhere there; give X, Y, Z and the tool vector in that pose, or write this block without `/`",
                        line.number
                    ),
                    at: at.clone(),
                });
            }
            self.position = None;
        }
        Ok(meaning)
    }

    /// A machine-axis move of `line` was followed (pose mode off) in
    /// `modal`, the state with the switch off: `slash`, the item of its `/`
    /// if it has one; `whole`, it gave every machine axis in G90. The
    /// position then depends on the switch where the block has `/`, or runs
    /// in a distance mode or units a `/` block changed; a later move that
    /// gives every axis in G90, without either, makes it known again.
    pub fn followed_move(
        &mut self,
        modal: &ModalState,
        line: &Line,
        slash: Option<usize>,
        whole: bool,
    ) {
        if let Some(item) = slash {
            self.position = Some((
                "this block-delete (`/`) block moves the machine before pose mode",
                SlashPlace::of(line, item),
            ));
        } else if let Some(on) = &self.on
            && (on.0.absolute != modal.absolute || on.0.units != modal.units)
        {
            self.position = Some((
                "this block-delete (`/`) block changes the distance mode (G90/G91) or the units of the machine-axis moves after it",
                on.1.clone(),
            ));
        } else if whole {
            self.position = None;
        }
    }
}
