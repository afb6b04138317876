//! The rotary axis words of a pose block whose tool orientation is given
//! by rotary axis positions (Fanuc `G43.4` type 1, Haas `G234`, Sinumerik
//! `TRAORI` with `A B C`), as the modal state reads them; `post` turns
//! them into a tool axis with the machine's chain.

/// A rotary axis word of a pose block whose orientation is given by
/// rotary axis positions (Fanuc `G43.4` type 1, Haas `G234`, Sinumerik
/// `TRAORI` with `A B C`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryWord {
    /// `A`, `B` or `C`.
    pub address: &'static str,
    /// The value as written (degrees; an increment under `G91`).
    pub value: f64,
    /// The word's item in the parsed line.
    pub item: usize,
}

/// The rotary words of a block that orients the tool by rotary axis
/// positions (none: the positions are kept from the blocks before).
pub type RotaryWords = smallvec::SmallVec<[RotaryWord; 3]>;
