//! NC programs as sequences of blocks: modal state, poses, output formatting.

pub mod arc;
mod block_delete;
pub mod block_delete_switch;
pub mod block_words;
pub mod fagor;
pub mod flow;
pub mod format;
pub mod frames;
pub mod heidenhain;
pub mod ijk;
pub mod integrity;
pub mod inverse_time;
pub mod length_comp;
pub mod modal;
pub mod opaque;
pub mod pose_program;
pub mod repeated_words;
pub mod rewrite;
pub mod rotary_words;
pub mod source;
pub mod spindle;
pub mod tape;
pub mod tool_vector;
pub mod unfollowed;

pub use modal::{
    BlockError, BlockMeaning, FeedMode, ModalState, Motion, PoseStart, RotaryWord, RotaryWords,
    TcpCode, Units, WordRef,
};
