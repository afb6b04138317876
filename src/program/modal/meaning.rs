//! What one block means to the modal state ([`super::ModalState::apply`]):
//! the pose it commands, the words that give it, the modes it runs under,
//! and the refusal of a block that cannot be converted.

use super::{FeedMode, Motion, RotaryWords, Units};
use nalgebra::Vector3;

/// A TCP code in the block that the emitter must rewrite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TcpCode {
    /// `G43.4` or `G43.5` (word item index).
    FanucOn(usize),
    /// `TRAORI` keyword (keyword item index).
    SiemensOn(usize),
}

/// Pose words a block's [`BlockMeaning::pose_items`] holds without
/// allocating: one of each of the nine pose addresses.
pub const POSE_ITEMS_INLINE: usize = 9;

/// The item indices of a block's pose words.
pub type PoseItems = smallvec::SmallVec<[usize; POSE_ITEMS_INLINE]>;

/// What one block means.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockMeaning {
    /// The tool pose this block commands (tip in mm, unit axis), if it is a pose block.
    pub pose: Option<(Vector3<f64>, Vector3<f64>)>,
    /// Items of the words that describe the pose (X Y Z I J K A3 B3 C3), to
    /// be replaced, in order (inline up to [`POSE_ITEMS_INLINE`]).
    pub pose_items: PoseItems,
    /// `Some` when the pose's tool orientation is given by rotary axis
    /// positions rather than a tool vector: the block's rotary words (the
    /// other rotary axes keep their positions). The pose's axis is then
    /// not the tool axis: the machine's chain gives it at those positions
    /// (`post`). Their items are in [`BlockMeaning::pose_items`].
    pub rotaries: Option<RotaryWords>,
    /// TCP-on codes to be rewritten to their machine-coordinate equivalent.
    pub tcp_codes: Vec<TcpCode>,
    /// Item of the `H` (or `D`) word that goes with a Fanuc TCP code, dropped with it.
    pub tcp_offset_items: Vec<usize>,
    /// Motion mode in force for this block.
    pub motion: Motion,
    /// Feed mode in force.
    pub feed_mode: FeedMode,
    /// Units in force.
    pub units: Units,
    /// Units of the feed `F` (per minute or per revolution): those of the
    /// lengths, except that Sinumerik's `G70`/`G71` switch the lengths
    /// alone and leave F in the control's basic system, taken as metric
    /// (`G700`/`G710` switch both).
    pub feed_units: Units,
    /// Absolute (`G90`) or incremental (`G91`).
    pub absolute: bool,
    /// Feed in force (program units per minute, or 1/min in G93), if any.
    pub feed: Option<f64>,
    /// Item index of an `F` word in this block, if any.
    pub feed_item: Option<usize>,
    /// Warnings (e.g. a tool vector normalised).
    pub warnings: Vec<String>,
    /// How far the programmed tool vector's length was from 1 (0 when it
    /// was not given or exactly 1); normalised quietly up to
    /// [`super::QUIET_NORMALISATION`], with a warning beyond.
    pub vector_deviation: f64,
    /// A non-modal block (`G4`, `G10`, `G28`, `G30`, `G52`, `G53`, `G92`, a
    /// frame, a pole): its axis words are not a move in program
    /// coordinates.
    pub non_modal: bool,
    /// A code or transformation kinpost does not follow (outside pose
    /// mode; in it the block is refused): its item and what it does.
    pub unfollowed: Option<(usize, String)>,
}

/// A problem with a block: message and the item it concerns.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockError {
    /// Item index the problem concerns, if one.
    pub item: Option<usize>,
    /// What is wrong and what was expected.
    pub message: String,
}
