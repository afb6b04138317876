//! The modes of a program that its blocks set and later blocks are read
//! under: motion, units, feed, and whether poses start at once.

/// Motion mode (G-code group 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// `G0`.
    Rapid,
    /// `G1`.
    Linear,
    /// `G2` / `G3`.
    Arc,
    /// Canned cycles and anything else that moves but is not a straight line.
    Other,
}

/// Units of lengths in the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// `G21` / `G71` / `G710`.
    Mm,
    /// `G20` / `G70` / `G700`.
    Inch,
}

impl Units {
    /// Millimetres per program unit.
    pub fn mm_per_unit(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
        }
    }
}

/// Feed mode (G-code group 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedMode {
    /// `G94`: F in units per minute.
    PerMinute,
    /// `G93`: F is the inverse of the block's time in minutes.
    InverseTime,
    /// `G95`: F in units per revolution.
    PerRevolution,
}

/// Whether pose mode is on before the program says anything.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseStart {
    /// Poses from the first block (CAM pose programs without a TCP code).
    On,
    /// Only `G43.4`/`G43.5`/`TRAORI` or a move with a tool axis switch it on.
    Off,
}
