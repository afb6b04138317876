//! One machine axis as programs see it: its NC address, joint, limits,
//! rotary behaviour and decimals.

use super::chain::JointKind;

/// How a rotary axis behaves when it turns past a full revolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RotaryMode {
    /// Travel limited by `min`/`max` (required for rotary axes). Linear axes
    /// are always `Limited` (with optional limits).
    Limited,
    /// Unlimited travel; the output is unwound: the value nearest the
    /// previous block, which may exceed ±360°.
    Continuous,
    /// Output wrapped to `[0, 360)`; the controller takes the shortest way.
    Modulo,
    /// LinuxCNC's wrapped rotary (`WRAPPED_ROTARY = 1`): an absolute word
    /// is the position in `[0, 360)` and its sign the direction the
    /// controller turns to it, less than a turn (after `C10`, `C350` turns
    /// +340° and `C-350` −20°). Unlimited travel; kinpost follows the turns
    /// unwound, as for [`RotaryMode::Continuous`], and writes each word
    /// with the sign of its block's turn ([`super::wrapped`]).
    Wrapped,
}

impl RotaryMode {
    /// The name used in machine files.
    pub fn name(self) -> &'static str {
        match self {
            RotaryMode::Limited => "limited",
            RotaryMode::Continuous => "continuous",
            RotaryMode::Modulo => "modulo",
            RotaryMode::Wrapped => "wrapped",
        }
    }
}

impl std::fmt::Display for RotaryMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One machine axis as the NC program sees it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AxisSpec {
    /// NC address (the joint's name in the chain).
    pub name: String,
    /// Index of the joint in the chain (the position in `q`).
    pub joint: usize,
    /// Linear or rotary.
    pub kind: JointKind,
    /// Lower travel limit in file units (mm or degrees), if any.
    pub min: Option<f64>,
    /// Upper travel limit in file units (mm or degrees), if any.
    pub max: Option<f64>,
    /// Rotary behaviour; always [`RotaryMode::Limited`] for linear axes.
    pub rotary: RotaryMode,
    /// Decimals written for this axis (a global `--decimals` overrides it).
    pub decimals: u32,
}

impl AxisSpec {
    /// The unit of the axis in files and programs: `"mm"` or `"deg"`.
    pub fn unit(&self) -> &'static str {
        match self.kind {
            JointKind::Prismatic => "mm",
            JointKind::Revolute => "deg",
        }
    }
}
