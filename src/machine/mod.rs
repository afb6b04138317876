//! Machines: the kinematic chain, machine files, inverse kinematics and rotary handling.

pub mod chain;

pub use chain::{Chain, ErrorMotion, JointErrors, JointKind, NoErrors, Pose};
