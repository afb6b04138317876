//! The one kinematic chain evaluator.
//!
//! A machine is a serial chain of elements written from the workpiece frame W
//! to the tool-tip frame T (see `../shared/spec/kinematics.md`):
//!
//! ```text
//! T_WT(q) = E1 · E2 · … · En
//! ```
//!
//! Joints may carry six position-dependent error motions `E_j(q)` that enter
//! right after the joint's motion (`M_j(q) · E_j(q)`); position-independent
//! errors are fixed elements of the same small-angle form. The *theoretical*
//! machine is evaluated with [`NoErrors`]; the *actual* machine with an error
//! model implementing [`JointErrors`]. Both go through the same code here:
//! forward kinematics, the analytic Jacobian (including the derivative of the
//! error motions) and everything built on them.
//!
//! Internal units: millimetres for lengths and prismatic joints, radians for
//! revolute joints and angles. Conversion to degrees happens at the edges.

use nalgebra::{Matrix4, OMatrix, U6, Unit, Vector3, Vector6};

mod compiled;
#[cfg(test)]
mod reference;
mod transforms;

pub use compiled::NearTrig;
use compiled::{Compiled, Rotations};
pub use transforms::{
    error_matrix, error_matrix_derivative, rotate, rotation, rotation3, translation,
};

/// Largest number of joints a chain may have (X, Y, Z, A, B, C, plus one spare).
pub const MAX_JOINTS: usize = 7;

/// Joint values of one pose (chain order, mm and rad), held inline: a
/// chain has at most [`MAX_JOINTS`] joints, so the per-pose paths never
/// allocate for them.
pub type JointValues = arrayvec::ArrayVec<f64, MAX_JOINTS>;

/// Whether a joint translates or rotates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Linear axis: `Trans(q · u)`, q in mm.
    Prismatic,
    /// Rotary axis: `Rot(u, q)`, q in rad internally (degrees in files and programs).
    Revolute,
}

/// One element of the chain.
#[derive(Debug, Clone, PartialEq)]
pub enum Element {
    /// Fixed homogeneous transform (a `translate`, a `rotate`, or a
    /// position-independent error element). Stored as a full 4×4 matrix so
    /// that the small-angle error form (not exactly orthonormal) is kept exactly.
    Fixed(Matrix4<f64>),
    /// A joint: index into [`Chain::joints`].
    Joint(usize),
}

/// A joint of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// NC address letter (X, Y, Z, A, B, C, or any other name).
    pub name: String,
    /// Prismatic or revolute.
    pub kind: JointKind,
    /// Unit direction of motion (prismatic) or rotation axis (revolute), in
    /// the frame just before the joint.
    pub axis: Unit<Vector3<f64>>,
    /// Index of this joint's element in [`Chain::elements`].
    pub element: usize,
}

/// The six error motions of one joint at one position (ISO 230-1 style):
/// `[δx, δy, δz, εx, εy, εz]`, mm and rad, in the joint's moving frame.
pub type ErrorMotion = Vector6<f64>;

/// Upper bounds of the slopes of a joint's error motions
/// ([`JointErrors::slope_bounds`]): the motions are Lipschitz with these
/// constants between any two joint values, except across a seam of a
/// rotary's `wrap` range.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SlopeBounds {
    /// `Σ|δ'|`: the three translations' slopes summed, mm per mm or per rad.
    pub translation: f64,
    /// `Σ|ε'|`: the three rotations' slopes summed, rad per mm or per rad.
    pub rotation: f64,
    /// For a rotary joint whose errors are looked up at its angle wrapped
    /// into `[lo, hi]` degrees (the equivalent angle in, or nearest to, the
    /// range): the motions may jump where the wrap changes turn, so the
    /// bounds hold only between two angles wrapped by the same turn.
    pub wrap: Option<(f64, f64)>,
}

/// Source of position-dependent joint errors for the chain evaluator.
///
/// The theoretical machine uses [`NoErrors`]. An error model (fitted tables,
/// diagnosed effects, …) implements this trait; the chain code is the same.
pub trait JointErrors {
    /// Error motions of joint `joint` (chain joint index) at position `q`
    /// (internal units), or `None` if the joint carries no error.
    fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion>;

    /// Error motions and their derivative with respect to `q` (per mm or per
    /// rad). The default differentiates [`JointErrors::error`] numerically
    /// (central difference); models with analytic derivatives override it.
    fn error_and_derivative(&self, joint: usize, q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
        let e = self.error(joint, q)?;
        let h = 1e-6 * (1.0 + q.abs());
        let ep = self.error(joint, q + h).unwrap_or(e);
        let em = self.error(joint, q - h).unwrap_or(e);
        Some((e, (ep - em) / (2.0 * h)))
    }

    /// True when no joint carries an error (lets the evaluator skip work).
    fn is_empty(&self) -> bool {
        false
    }

    /// Upper bounds of the slopes of joint `joint`'s error motions
    /// ([`SlopeBounds`]), or `None` when the source cannot give them (the
    /// default). Lets a caller bound a first-order estimate of the pose
    /// instead of evaluating it.
    fn slope_bounds(&self, _joint: usize) -> Option<SlopeBounds> {
        None
    }
}

/// The theoretical machine: no joint errors.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoErrors;

impl JointErrors for NoErrors {
    fn error(&self, _joint: usize, _q: f64) -> Option<ErrorMotion> {
        None
    }
    fn error_and_derivative(&self, _joint: usize, _q: f64) -> Option<(ErrorMotion, ErrorMotion)> {
        None
    }
    fn is_empty(&self) -> bool {
        true
    }
    fn slope_bounds(&self, _joint: usize) -> Option<SlopeBounds> {
        Some(SlopeBounds::default())
    }
}

/// Tool pose in the workpiece frame: tool tip (mm) and unit tool axis
/// (pointing from the tip towards the spindle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Tool tip position, mm.
    pub tip: Vector3<f64>,
    /// Tool axis direction (unit for a rigid chain; within 1e-12 of unit with
    /// small-angle error matrices).
    pub axis: Vector3<f64>,
}

impl Pose {
    /// Builds a pose from tip and axis; the axis is normalised.
    pub fn new(tip: Vector3<f64>, axis: Vector3<f64>) -> Self {
        Pose {
            tip,
            axis: axis.normalize(),
        }
    }

    /// Distance between tool tips, mm.
    pub fn tip_distance(&self, other: &Pose) -> f64 {
        (self.tip - other.tip).norm()
    }

    /// Angle between tool axes, rad (robust near zero: uses atan2 of the
    /// cross and dot products rather than acos). The angle does not depend
    /// on the lengths, so the axes are not normalised; NaN when one is zero.
    ///
    /// Below 1e-3 rad (residual orientation errors are micro-radians) the
    /// arctangent of `t = |a × b| / (a · b)` is its series
    /// `t − t³/3 + t⁵/5`: the first omitted term, t⁷/7, is relatively
    /// t⁶/7 < 1.5e-19 of it, far under an ulp.
    #[inline]
    pub fn axis_angle(&self, other: &Pose) -> f64 {
        let (a, b) = (&self.axis, &other.axis);
        if a.norm_squared() == 0.0 || b.norm_squared() == 0.0 {
            return f64::NAN;
        }
        let s = a.cross(b).norm();
        let c = a.dot(b);
        if c > 0.0 && s <= 1e-3 * c {
            let t = s / c;
            let t2 = t * t;
            t - t * t2 * (1.0 / 3.0 - t2 * (1.0 / 5.0))
        } else {
            s.atan2(c)
        }
    }
}

/// 6×n Jacobian of `[tip; axis]` with respect to the joints (chain order):
/// rows 0–2 are d(tip)/dq (mm per mm or mm per rad), rows 3–5 d(axis)/dq.
pub type Jacobian = OMatrix<f64, U6, nalgebra::Dyn>;

/// Columns of the 6×n Jacobian on the stack (`[tip; axis]` per joint, chain
/// order; entries past the chain's dof are unused): the allocation-free form
/// of [`Jacobian`] filled by [`Chain::pose_and_jacobian_into`].
pub type JacobianColumns = [[f64; 6]; MAX_JOINTS];

/// A serial kinematic chain from workpiece to tool tip.
///
/// Build and change a chain through its methods ([`Chain::joint`],
/// [`Chain::translate`], [`Chain::rotate`], [`Chain::fixed_error`],
/// [`Chain::with_fixed_inserted`]): they keep a precomputed form of the
/// chain (consecutive fixed elements multiplied out, per-joint constants)
/// that the one evaluator uses. The element and joint lists are read
/// through [`Chain::elements`] and [`Chain::joints`].
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    /// Elements in order from the workpiece frame to the tool-tip frame.
    elements: Vec<Element>,
    /// Joints in chain order (the order of `q`).
    joints: Vec<Joint>,
    compiled: Compiled,
}

/// One part of a chain for [`Chain::from_parts`].
#[derive(Debug, Clone, PartialEq)]
pub enum ChainPart {
    /// A joint ([`Chain::joint`]).
    Joint {
        /// NC address.
        name: String,
        /// Linear or rotary.
        kind: JointKind,
        /// Direction (normalised when built).
        axis: Vector3<f64>,
    },
    /// A fixed translation, mm ([`Chain::translate`]).
    Translate(Vector3<f64>),
    /// A fixed rotation by `angle` rad about `axis` ([`Chain::rotate`]).
    Rotate {
        /// Direction (normalised when built).
        axis: Vector3<f64>,
        /// Angle, rad.
        angle: f64,
    },
}

impl Chain {
    /// An empty chain (identity).
    pub fn new() -> Self {
        Chain {
            elements: Vec::new(),
            joints: Vec::new(),
            compiled: Compiled::default(),
        }
    }

    /// Rebuilds the precomputed form after a change.
    fn recompile(&mut self) {
        self.compiled = Compiled::new(&self.elements, &self.joints);
    }

    /// The elements, in order from the workpiece frame to the tool-tip
    /// frame.
    pub fn elements(&self) -> &[Element] {
        &self.elements
    }

    /// The joints, in chain order (the order of `q`).
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// A chain built from `parts`, in order from the workpiece to the tool
    /// tip. Appending part by part rebuilds the precomputed form after
    /// every element (quadratic in the chain length); this builds it once.
    pub fn from_parts(parts: impl IntoIterator<Item = ChainPart>) -> Chain {
        let mut c = Chain::new();
        for part in parts {
            match part {
                ChainPart::Joint { name, kind, axis } => {
                    let index = c.joints.len();
                    c.joints.push(Joint {
                        name,
                        kind,
                        axis: Unit::new_normalize(axis),
                        element: c.elements.len(),
                    });
                    c.elements.push(Element::Joint(index));
                }
                ChainPart::Translate(v) => c.elements.push(Element::Fixed(translation(&v))),
                ChainPart::Rotate { axis, angle } => c
                    .elements
                    .push(Element::Fixed(rotation(&Unit::new_normalize(axis), angle))),
            }
        }
        c.recompile();
        c
    }

    /// Appends a fixed translation (mm).
    pub fn translate(&mut self, v: Vector3<f64>) -> &mut Self {
        self.elements.push(Element::Fixed(translation(&v)));
        self.recompile();
        self
    }

    /// Appends a fixed rotation by `angle` rad about `axis`.
    pub fn rotate(&mut self, axis: Vector3<f64>, angle: f64) -> &mut Self {
        self.elements
            .push(Element::Fixed(rotation(&Unit::new_normalize(axis), angle)));
        self.recompile();
        self
    }

    /// Appends a fixed error element (position-independent error, such as
    /// squareness or an axis location error) of the small-angle form.
    pub fn fixed_error(&mut self, e: ErrorMotion) -> &mut Self {
        self.elements.push(Element::Fixed(error_matrix(&e)));
        self.recompile();
        self
    }

    /// Appends a joint; returns its joint index. A chain has at most
    /// [`MAX_JOINTS`] joints (machine files are checked for it).
    pub fn joint(&mut self, name: &str, kind: JointKind, axis: Vector3<f64>) -> usize {
        assert!(
            self.joints.len() < MAX_JOINTS,
            "a chain has at most {MAX_JOINTS} joints"
        );
        let index = self.joints.len();
        self.joints.push(Joint {
            name: name.to_string(),
            kind,
            axis: Unit::new_normalize(axis),
            element: self.elements.len(),
        });
        self.elements.push(Element::Joint(index));
        self.recompile();
        index
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Joint index of the joint called `name` (case-insensitive).
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints
            .iter()
            .position(|j| j.name.eq_ignore_ascii_case(name))
    }

    /// The joints' names, chain order.
    pub fn names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// The joints' names, comma-separated (for messages).
    pub fn joint_names(&self) -> String {
        self.joints
            .iter()
            .map(|j| j.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Returns a copy of this chain with a fixed element inserted at element
    /// position `at` (0 = before everything, `elements().len()` = at the
    /// tool). Joint element indices are kept consistent. `m` is affine
    /// (last row `0 0 0 1`), as every transform of a chain is.
    pub fn with_fixed_inserted(&self, at: usize, m: Matrix4<f64>) -> Chain {
        let mut c = self.clone();
        c.elements.insert(at, Element::Fixed(m));
        for j in &mut c.joints {
            if j.element >= at {
                j.element += 1;
            }
        }
        c.recompile();
        c
    }

    /// Motion transform `M_j(q)` of joint `j`.
    pub fn joint_motion(&self, j: usize, q: f64) -> Matrix4<f64> {
        let joint = &self.joints[j];
        match joint.kind {
            JointKind::Prismatic => translation(&(joint.axis.into_inner() * q)),
            JointKind::Revolute => rotation(&joint.axis, q),
        }
    }

    /// Forward kinematics: `T_WT(q)` for joint values `q` (chain order,
    /// internal units) on the machine described by `errors`.
    pub fn transform(&self, q: &[f64], errors: &dyn JointErrors) -> Matrix4<f64> {
        debug_assert_eq!(q.len(), self.joints.len());
        compiled::forward(&self.compiled, q, errors).to_matrix4()
    }

    /// Forward kinematics: tool tip `T·[0,0,0,1]` and tool axis `T·[0,0,1,0]`.
    pub fn pose(&self, q: &[f64], errors: &dyn JointErrors) -> Pose {
        debug_assert_eq!(q.len(), self.joints.len());
        compiled::pose_backward(&self.compiled, q, errors, Rotations::Compute)
    }

    /// Forward kinematics and the analytic 6×n Jacobian of `[tip; axis]`.
    ///
    /// For joint `k` with `T = P · G_k(q_k) · S`, `dT/dq_k = P · G_k' · S`
    /// where `G_k' = M_k' E_k + M_k E_k'`. The suffix is only needed applied to
    /// the tip point and the axis direction, so one backward pass of vectors
    /// and one forward pass of prefixes suffice. See
    /// [`Chain::pose_and_jacobian_into`] for the allocation-free form.
    pub fn pose_and_jacobian(&self, q: &[f64], errors: &dyn JointErrors) -> (Pose, Jacobian) {
        let n = self.joints.len();
        let mut cols = [[0.0; 6]; MAX_JOINTS];
        let pose =
            compiled::pose_jacobian(&self.compiled, q, errors, &mut cols, Rotations::Compute);
        (pose, Jacobian::from_fn(n, |r, c| cols[c][r]))
    }

    /// [`Chain::pose_and_jacobian`] without allocating: column `k` of
    /// `jac` receives `d[tip; axis]/dq_k` (columns past the dof are left
    /// as they are).
    pub fn pose_and_jacobian_into(
        &self,
        q: &[f64],
        errors: &dyn JointErrors,
        jac: &mut JacobianColumns,
    ) -> Pose {
        compiled::pose_jacobian(&self.compiled, q, errors, jac, Rotations::Compute)
    }

    /// An upper bound of the distance between any two frames of the chain
    /// at joint values `q` (mm), the origin and the tool tip among them:
    /// the lengths of the fixed translations and of the prismatic joints'
    /// displacements summed (rotations change no length). Error motions
    /// move the frames by their translations on top of this.
    pub fn frame_reach(&self, q: &[f64]) -> f64 {
        compiled::frame_reach(&self.compiled, q)
    }

    /// The sines and cosines of the revolute joints at `q0`, for poses and
    /// Jacobians near `q0` (see [`NearTrig`]).
    pub fn trig_at(&self, q0: &[f64]) -> NearTrig {
        NearTrig::at(&self.joints, q0)
    }

    /// [`Chain::pose`] with the revolute joints' sines and cosines taken
    /// from `near` where `q` is near its `q0` (the refinement's trial points).
    pub fn pose_near(&self, q: &[f64], errors: &dyn JointErrors, near: &NearTrig) -> Pose {
        compiled::pose_backward(&self.compiled, q, errors, Rotations::Near(near))
    }

    /// [`Chain::pose`] at `q0 + d`, where `q0` is `near`'s and `q` holds
    /// `q0 + d` rounded: the revolute joints' sines and cosines follow from
    /// `near`'s by the addition theorem with the exact offsets `d`
    /// ([`NearTrig::sin_cos_offset`]), the error motions from `q`. The
    /// Newton refinement's trial points, which move from `q0` by offsets
    /// far below the resolution of a rotary at thousands of degrees.
    pub fn pose_at_offsets(
        &self,
        q: &[f64],
        errors: &dyn JointErrors,
        near: &NearTrig,
        d: &[f64],
    ) -> Pose {
        compiled::pose_backward(&self.compiled, q, errors, Rotations::Offsets(near, d))
    }

    /// [`Chain::pose_and_jacobian_into`] at `q0 + d`, as
    /// [`Chain::pose_at_offsets`].
    pub fn pose_and_jacobian_at_offsets(
        &self,
        q: &[f64],
        errors: &dyn JointErrors,
        jac: &mut JacobianColumns,
        near: &NearTrig,
        d: &[f64],
    ) -> Pose {
        compiled::pose_jacobian(&self.compiled, q, errors, jac, Rotations::Offsets(near, d))
    }

    /// Theoretical forward kinematics (no errors) and, for each prismatic
    /// joint `j`, its direction of motion in the workpiece frame in
    /// `dirs[j]` (the tip rows of its Jacobian column; other entries are left
    /// as they are): what an IK needs to solve the linear axes, for the cost
    /// of one forward pass.
    pub fn pose_and_prismatic_directions(
        &self,
        q: &[f64],
        dirs: &mut [[f64; 3]; MAX_JOINTS],
    ) -> Pose {
        compiled::pose_and_prismatic_directions(&self.compiled, q, dirs)
    }
}

impl Default for Chain {
    fn default() -> Self {
        Chain::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zhao() -> Chain {
        crate::machine::Machine::embedded("zhao2022-xzbc")
            .expect("embedded fixture")
            .chain
    }

    /// Error model used to check the Jacobian's error-derivative terms.
    struct Wavy;
    impl JointErrors for Wavy {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            let s = (joint as f64 + 1.0) * 1e-3;
            Some(ErrorMotion::new(
                s * (0.1 * q).sin(),
                s * (0.07 * q).cos(),
                s * q * 0.01,
                s * 1e-2 * (0.05 * q).sin(),
                s * 1e-2 * q,
                s * 1e-2 * (0.3 * q).cos(),
            ))
        }
    }

    /// Sines and cosines by the addition theorem near a known point are
    /// those of `sin_cos` to an ulp; far from it they are `sin_cos`'s own.
    #[test]
    fn near_trig_matches_sin_cos() {
        let c = zhao();
        let b = c.joint_index("B").unwrap();
        for q0 in [0.0, 0.3, -1.2, 3.1, 1e3] {
            let mut q = vec![0.0; c.dof()];
            q[b] = q0;
            let near = c.trig_at(&q);
            for d in [0.0, 1e-12, -3e-9, 2.5e-6, -7e-5, 1e-4, 2e-4, 0.5] {
                let (s, co) = near.sin_cos(b, q0 + d);
                let (s1, c1) = (q0 + d).sin_cos();
                assert!((s - s1).abs() <= 2.3e-16, "sin at {q0} + {d}: {s} vs {s1}");
                assert!(
                    (co - c1).abs() <= 2.3e-16,
                    "cos at {q0} + {d}: {co} vs {c1}"
                );
            }
            // The pose near q0 is the pose.
            q[b] = q0 + 3e-6;
            let (p, p1) = (c.pose_near(&q, &NoErrors, &near), c.pose(&q, &NoErrors));
            assert!((p.tip - p1.tip).amax() < 1e-12 && (p.axis - p1.axis).amax() < 1e-15);
        }
    }

    /// The axis angle's small-angle series agrees with atan2 of the
    /// normalised axes, across the switch at 1e-3 rad, and scale does not
    /// matter.
    #[test]
    fn axis_angle_small_and_large() {
        let z = Pose::new(Vector3::zeros(), Vector3::z());
        for t in [
            0.0f64, 1e-15, 3e-9, 7.1e-7, 2e-5, 9.99e-4, 1.001e-3, 0.2, 3.0,
        ] {
            let p = Pose::new(Vector3::zeros(), Vector3::new(t.sin(), 0.0, t.cos()) * 3.5);
            let a = p.axis_angle(&z);
            assert!(
                (a - t).abs() <= 4.0 * f64::EPSILON * t.max(1e-300),
                "{t}: {a}"
            );
        }
        let zero = Pose::new(Vector3::zeros(), Vector3::zeros());
        assert!(zero.axis_angle(&z).is_nan());
    }

    #[test]
    fn zhao_pose_matches_hand_derivation() {
        // At C=0: tip = (X - 20 sin B, 0, Z - 20 cos B), axis = (sin B, 0, cos B).
        let c = zhao();
        let b: f64 = 0.3;
        let p = c.pose(&[0.0, 10.0, 5.0, b], &NoErrors);
        assert!(
            (p.tip - Vector3::new(10.0 - 20.0 * b.sin(), 0.0, 5.0 - 20.0 * b.cos())).norm() < 1e-12
        );
        assert!((p.axis - Vector3::new(b.sin(), 0.0, b.cos())).norm() < 1e-15);
        // A positive C command turns the part by +C about +z, so a point fixed
        // in the machine appears turned by −C in the workpiece frame.
        let p = c.pose(&[std::f64::consts::FRAC_PI_2, 10.0, 0.0, 0.0], &NoErrors);
        assert!((p.tip - Vector3::new(0.0, -10.0, -20.0)).norm() < 1e-12);
    }

    #[test]
    fn jacobian_matches_finite_differences_with_errors() {
        let c = zhao();
        let q = [0.4, 12.0, -7.0, 0.6];
        for errors in [&NoErrors as &dyn JointErrors, &Wavy] {
            let (p0, jac) = c.pose_and_jacobian(&q, errors);
            let p1 = c.pose(&q, errors);
            assert!((p0.tip - p1.tip).norm() < 1e-12);
            for k in 0..4 {
                let h = 1e-6;
                let mut qp = q;
                let mut qm = q;
                qp[k] += h;
                qm[k] -= h;
                let pp = c.pose(&qp, errors);
                let pm = c.pose(&qm, errors);
                let dt = (pp.tip - pm.tip) / (2.0 * h);
                let da = (pp.axis - pm.axis) / (2.0 * h);
                for r in 0..3 {
                    assert!((jac[(r, k)] - dt[r]).abs() < 1e-6, "tip row {r} col {k}");
                    assert!(
                        (jac[(r + 3, k)] - da[r]).abs() < 1e-8,
                        "axis row {r} col {k}"
                    );
                }
            }
        }
    }

    #[test]
    fn error_matrix_layout_follows_spec() {
        let e = ErrorMotion::new(1.0, 2.0, 3.0, 0.1, 0.2, 0.3);
        let m = error_matrix(&e);
        assert_eq!(m[(0, 1)], -0.3);
        assert_eq!(m[(0, 2)], 0.2);
        assert_eq!(m[(1, 0)], 0.3);
        assert_eq!(m[(1, 2)], -0.1);
        assert_eq!(m[(2, 0)], -0.2);
        assert_eq!(m[(2, 1)], 0.1);
        assert_eq!(m[(0, 3)], 1.0);
        assert_eq!(m[(2, 3)], 3.0);
    }
}
