//! Machines: the kinematic chain, machine files, inverse kinematics and rotary handling.
//!
//! - [`chain`]: the one chain evaluator (forward kinematics, Jacobian).
//! - [`mod@file`]: machine files (JSON) and the [`Machine`] type.
//! - [`ik`]: analytic inverse kinematics per family, branch choice, limits.
//! - [`linuxcnc`]: machine files from LinuxCNC configurations.
//! - [`midblock`]: how far the tool leaves the programmed line within a block.
//! - [`newton_ik`]: the damped-Newton fallback for other chains.
//! - [`rotary`]: limited, continuous and modulo rotary axes; unwinding.
//! - [`template`]: starting machine files per family; the list of embedded machines.

pub mod axis;
pub mod chain;
pub mod file;
pub mod ik;
pub mod ik_error;
pub mod job;
pub(crate) mod jsonpos;
pub mod linuxcnc;
pub mod midblock;
pub mod newton_ik;
pub mod rotary;
pub mod template;
pub mod wrapped;

pub use axis::{AxisSpec, RotaryMode};
pub use chain::{
    Chain, ChainPart, ErrorMotion, JointErrors, JointKind, JointValues, NoErrors, Pose,
};
pub use file::Machine;
pub use ik::{Family, IkError, IkOptions, IkSolution, IkSolver, PreparedPose};
pub use rotary::output_value;
