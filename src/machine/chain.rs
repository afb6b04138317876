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

use nalgebra::{Matrix3, Matrix4, OMatrix, U6, Unit, Vector3, Vector4, Vector6};

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

/// The small-angle homogeneous error matrix of `kinematics.md`:
///
/// ```text
/// | 1    −εz   εy   δx |
/// | εz    1   −εx   δy |
/// | −εy   εx    1   δz |
/// | 0     0     0    1 |
/// ```
pub fn error_matrix(e: &ErrorMotion) -> Matrix4<f64> {
    Matrix4::new(
        1.0, -e[5], e[4], e[0], //
        e[5], 1.0, -e[3], e[1], //
        -e[4], e[3], 1.0, e[2], //
        0.0, 0.0, 0.0, 1.0,
    )
}

/// Derivative of [`error_matrix`] for a derivative of the error motions
/// (the identity drops out; the map is linear in `e`).
pub fn error_matrix_derivative(de: &ErrorMotion) -> Matrix4<f64> {
    Matrix4::new(
        0.0, -de[5], de[4], de[0], //
        de[5], 0.0, -de[3], de[1], //
        -de[4], de[3], 0.0, de[2], //
        0.0, 0.0, 0.0, 0.0,
    )
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
/// that the evaluators use. A chain whose element or joint list was edited
/// directly with a different length is evaluated element by element.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    /// Elements in order from the workpiece frame to the tool-tip frame.
    pub elements: Vec<Element>,
    /// Joints in chain order (the order of `q`).
    pub joints: Vec<Joint>,
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

/// The sines and cosines of a chain's revolute joints at joint values `q0`
/// ([`Chain::trig_at`]): near `q0` those of `q = q0 + d` follow by the
/// addition theorem, `sin q = sin q0 · cos d + cos q0 · sin d`, with
/// `sin d` and `cos d` from their series, which for |d| ≤ 1e-4 rad are
/// exact to far below an ulp (the first omitted terms are d⁵/120 < 1e-22
/// and d⁶/720 < 2e-27). The Newton refinement's steps are micro-radians,
/// so its trial points cost no `sin_cos` call.
#[derive(Debug, Clone, Copy)]
pub struct NearTrig {
    q0: [f64; MAX_JOINTS],
    sc: [(f64, f64); MAX_JOINTS],
}

impl NearTrig {
    /// Largest |q − q0| handled by the addition theorem, rad.
    const NEAR_RAD: f64 = 1e-4;

    /// The sines and cosines at `q0 + d`, with the offsets `d` (rad for the
    /// revolute joints) taken exactly: they need not be representable as a
    /// change of `q0 + d` in floating point. For a rotary at thousands of
    /// degrees, `q0 + d` resolves only 1e-14 rad or so (1e-12 mm at a
    /// 100 mm radius); the refinement steps by its offsets through this
    /// and loses nothing. Evaluate the chain at `q0 + d` (rounded) with the
    /// result: the rotations come from here, the error motions from the
    /// rounded values, where their resolution does not matter.
    pub fn shifted(&self, d: &[f64]) -> NearTrig {
        let mut t = *self;
        for (j, &dj) in d.iter().enumerate().take(MAX_JOINTS) {
            t.q0[j] = self.q0[j] + dj;
            if dj == 0.0 {
                continue;
            }
            let d = if dj.abs() <= Self::NEAR_RAD {
                small_sin_cos(dj)
            } else {
                dj.sin_cos()
            };
            t.sc[j] = add_angles(self.sc[j], d);
        }
        t
    }

    /// `(sin q, cos q)` of joint `j`.
    #[inline]
    pub fn sin_cos(&self, j: usize, q: f64) -> (f64, f64) {
        let d = q - self.q0[j];
        if d.abs() > Self::NEAR_RAD || d.is_nan() {
            return q.sin_cos();
        }
        if d == 0.0 {
            return self.sc[j];
        }
        add_angles(self.sc[j], small_sin_cos(d))
    }
}

/// `(sin d, cos d)` of a small angle (|d| ≤ 1e-4 rad) from the series, to
/// far below an ulp.
#[inline]
fn small_sin_cos(d: f64) -> (f64, f64) {
    let d2 = d * d;
    (
        d - d * d2 * (1.0 / 6.0),
        1.0 - d2 * (0.5 - d2 * (1.0 / 24.0)),
    )
}

/// `(sin(a + b), cos(a + b))` from those of `a` and `b` (addition theorem).
#[inline]
fn add_angles((sa, ca): (f64, f64), (sb, cb): (f64, f64)) -> (f64, f64) {
    (sa * cb + ca * sb, ca * cb - sa * sb)
}

/// Where [`Chain::pose_backward`] takes the revolute joints' rotations from.
#[derive(Clone, Copy)]
enum Rotations<'a> {
    /// Computed from the joint values.
    Compute,
    /// Given by the caller, by joint index.
    Given(&'a [[[f64; 3]; 3]; MAX_JOINTS]),
    /// From sines and cosines near known ones.
    Near(&'a NearTrig),
}

/// An affine transform `[R | t]` (row-major, the last row `0 0 0 1`
/// implied). Products and point maps sum in the same order as nalgebra's
/// 4×4 products (k = 0, 1, 2, then the translation), skipping only the
/// terms that are exactly zero.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Affine {
    m: [[f64; 4]; 3],
}

impl Affine {
    const IDENTITY: Affine = Affine {
        m: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// The affine part of `m`, if its last row is exactly `0 0 0 1`.
    fn from_matrix4(m: &Matrix4<f64>) -> Option<Affine> {
        if m[(3, 0)] != 0.0 || m[(3, 1)] != 0.0 || m[(3, 2)] != 0.0 || m[(3, 3)] != 1.0 {
            return None;
        }
        let mut a = Affine::IDENTITY;
        for (i, row) in a.m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = m[(i, j)];
            }
        }
        Some(a)
    }

    fn to_matrix4(self) -> Matrix4<f64> {
        let m = &self.m;
        Matrix4::new(
            m[0][0], m[0][1], m[0][2], m[0][3], //
            m[1][0], m[1][1], m[1][2], m[1][3], //
            m[2][0], m[2][1], m[2][2], m[2][3], //
            0.0, 0.0, 0.0, 1.0,
        )
    }

    /// `self · b`.
    #[inline]
    fn mul(&self, b: &Affine) -> Affine {
        let (a, b) = (&self.m, &b.m);
        let mut c = [[0.0; 4]; 3];
        for i in 0..3 {
            for j in 0..4 {
                c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
            }
            c[i][3] += a[i][3];
        }
        Affine { m: c }
    }

    /// `R p + t`.
    #[inline]
    fn point(&self, p: &[f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3])
    }

    /// `R d`.
    #[inline]
    fn dir(&self, d: &[f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|i| m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2])
    }
}

/// `r d` for a 3×3 `r` (row-major).
#[inline]
fn rot3_apply(r: &[[f64; 3]; 3], d: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2])
}

/// `a · b` for 3×3 matrices (row-major), nalgebra's summation order.
#[inline]
fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// `a · [r | t]` for a 3×3 `a` and an affine `[r | t]`.
#[inline]
fn mul3_affine(a: &[[f64; 3]; 3], b: &Affine) -> Affine {
    let b = &b.m;
    Affine {
        m: std::array::from_fn(|i| {
            std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
        }),
    }
}

/// Per-joint constants: the axis, its cross matrix `K = [u]ₓ` and `K²`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct JointConst {
    kind: JointKind,
    u: [f64; 3],
    k: [[f64; 3]; 3],
    kk: [[f64; 3]; 3],
}

impl JointConst {
    fn new(joint: &Joint) -> Self {
        let u = joint.axis.into_inner();
        let k = joint.axis.cross_matrix();
        let kk = k * k;
        let arr = |m: &Matrix3<f64>| std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
        JointConst {
            kind: joint.kind,
            u: [u.x, u.y, u.z],
            k: arr(&k),
            kk: arr(&kk),
        }
    }

    /// Rodrigues `I + sinθ K + (1 − cosθ) K²`, as [`rotation3`] computes it.
    #[inline]
    fn rotation(&self, theta: f64) -> [[f64; 3]; 3] {
        let (s, c) = theta.sin_cos();
        self.rotation_sc(s, c)
    }

    /// [`JointConst::rotation`] from the sine `s` and cosine `c` of θ.
    #[inline]
    fn rotation_sc(&self, s: f64, c: f64) -> [[f64; 3]; 3] {
        let omc = 1.0 - c;
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let id = if i == j { 1.0 } else { 0.0 };
                (id + self.k[i][j] * s) + self.kk[i][j] * omc
            })
        })
    }

    /// `G = M(q) · E` (the joint's motion after its error motion `e`) and
    /// the rotation of `M(q)` (the identity for a prismatic joint); `sc`:
    /// the sine and cosine of `q` when the caller has them (revolute joints).
    #[inline]
    fn motion(
        &self,
        q: f64,
        sc: Option<(f64, f64)>,
        e: Option<&ErrorMotion>,
    ) -> (Affine, [[f64; 3]; 3]) {
        const I3: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let e_aff = |e: &ErrorMotion| Affine {
            m: [
                [1.0, -e[5], e[4], e[0]],
                [e[5], 1.0, -e[3], e[1]],
                [-e[4], e[3], 1.0, e[2]],
            ],
        };
        match self.kind {
            JointKind::Prismatic => {
                let mut g = match e {
                    Some(e) => e_aff(e),
                    None => Affine::IDENTITY,
                };
                for (row, u) in g.m.iter_mut().zip(self.u) {
                    row[3] += u * q;
                }
                (g, I3)
            }
            JointKind::Revolute => {
                let (sn, cs) = sc.unwrap_or_else(|| q.sin_cos());
                let r = self.rotation_sc(sn, cs);
                let g = match e {
                    Some(e) => mul3_affine(&r, &e_aff(e)),
                    None => Affine {
                        m: std::array::from_fn(|i| [r[i][0], r[i][1], r[i][2], 0.0]),
                    },
                };
                (g, r)
            }
        }
    }
}

/// One step of the precomputed chain.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    /// Consecutive fixed elements multiplied out.
    Fixed(Affine),
    /// A joint (index into the joints).
    Joint(usize),
}

/// The precomputed form of a chain (see [`Chain`]).
#[derive(Clone, Default)]
struct Compiled {
    steps: Vec<Step>,
    joints: Vec<JointConst>,
    /// Number of elements it was built from (a staleness check).
    elements: usize,
    /// Some fixed element is not affine: evaluate with full 4×4 matrices.
    general: bool,
}

impl std::fmt::Debug for Compiled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Compiled")
    }
}

impl PartialEq for Compiled {
    /// Derived data: equal elements give equal compiled forms.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Compiled {
    fn new(elements: &[Element], joints: &[Joint]) -> Self {
        let mut c = Compiled {
            steps: Vec::with_capacity(elements.len()),
            joints: joints.iter().map(JointConst::new).collect(),
            elements: elements.len(),
            general: false,
        };
        for el in elements {
            match el {
                Element::Fixed(m) => match Affine::from_matrix4(m) {
                    Some(a) => match c.steps.last_mut() {
                        Some(Step::Fixed(prev)) => *prev = prev.mul(&a),
                        _ => c.steps.push(Step::Fixed(a)),
                    },
                    None => c.general = true,
                },
                Element::Joint(j) => c.steps.push(Step::Joint(*j)),
            }
        }
        c
    }

    fn fits(&self, chain: &Chain) -> bool {
        !self.general
            && self.elements == chain.elements.len()
            && self.joints.len() == chain.joints.len()
            && chain.joints.len() <= MAX_JOINTS
    }
}

/// Homogeneous translation.
pub fn translation(v: &Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m[(0, 3)] = v.x;
    m[(1, 3)] = v.y;
    m[(2, 3)] = v.z;
    m
}

/// Rodrigues rotation `R = I + sinθ [u]x + (1 − cosθ)[u]x²` as a 3×3 matrix.
pub fn rotation3(u: &Unit<Vector3<f64>>, theta: f64) -> Matrix3<f64> {
    let k = u.cross_matrix();
    let (s, c) = theta.sin_cos();
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// `v` turned by `theta` (rad) about the unit axis `u` (Rodrigues on the
/// vector: `v cos θ + (u × v) sin θ + u (u·v)(1 − cos θ)`).
pub fn rotate(u: &Vector3<f64>, theta: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = theta.sin_cos();
    v * c + u.cross(v) * s + u * (u.dot(v) * (1.0 - c))
}

/// Homogeneous rotation by `theta` (rad) about unit axis `u` through the origin.
pub fn rotation(u: &Unit<Vector3<f64>>, theta: f64) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&rotation3(u, theta));
    m
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

    /// Runs `f` with the precomputed form, rebuilding it when the chain was
    /// edited directly; `None` when the chain needs the general 4×4 path.
    fn with_compiled<T>(&self, f: impl FnOnce(&Compiled) -> T) -> Option<T> {
        if self.compiled.fits(self) {
            return Some(f(&self.compiled));
        }
        let c = Compiled::new(&self.elements, &self.joints);
        c.fits(self).then(|| f(&c))
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

    /// Appends a joint; returns its joint index.
    pub fn joint(&mut self, name: &str, kind: JointKind, axis: Vector3<f64>) -> usize {
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

    /// The joints' names, comma-separated (for messages).
    pub fn joint_names(&self) -> String {
        self.joints
            .iter()
            .map(|j| j.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Returns a copy of this chain with a fixed element inserted at element
    /// position `at` (0 = before everything, `elements.len()` = at the tool).
    /// Joint element indices are kept consistent.
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

    /// Derivative `dM_j/dq` of the joint motion.
    fn joint_motion_derivative(&self, j: usize, q: f64) -> Matrix4<f64> {
        let joint = &self.joints[j];
        match joint.kind {
            JointKind::Prismatic => {
                let mut m = Matrix4::zeros();
                let u = joint.axis.into_inner();
                m[(0, 3)] = u.x;
                m[(1, 3)] = u.y;
                m[(2, 3)] = u.z;
                m
            }
            JointKind::Revolute => {
                let mut m = Matrix4::zeros();
                let r = joint.axis.cross_matrix() * rotation3(&joint.axis, q);
                m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
                m
            }
        }
    }

    /// Transform of joint `j` including its error motion: `M_j(q) · E_j(q)`.
    fn joint_transform(&self, j: usize, q: f64, errors: &dyn JointErrors) -> Matrix4<f64> {
        let m = self.joint_motion(j, q);
        match errors.error(j, q) {
            Some(e) => m * error_matrix(&e),
            None => m,
        }
    }

    /// Forward kinematics: `T_WT(q)` for joint values `q` (chain order,
    /// internal units) on the machine described by `errors`.
    pub fn transform(&self, q: &[f64], errors: &dyn JointErrors) -> Matrix4<f64> {
        debug_assert_eq!(q.len(), self.joints.len());
        self.with_compiled(|c| Self::forward(c, q, errors).to_matrix4())
            .unwrap_or_else(|| self.transform_general(q, errors))
    }

    /// [`Chain::transform`] with full 4×4 matrices, element by element.
    fn transform_general(&self, q: &[f64], errors: &dyn JointErrors) -> Matrix4<f64> {
        let mut t = Matrix4::identity();
        for el in &self.elements {
            match el {
                Element::Fixed(m) => t *= m,
                Element::Joint(j) => t *= self.joint_transform(*j, q[*j], errors),
            }
        }
        t
    }

    /// The forward product on the precomputed chain.
    fn forward(c: &Compiled, q: &[f64], errors: &dyn JointErrors) -> Affine {
        let skip = errors.is_empty();
        let mut t: Option<Affine> = None;
        for step in &c.steps {
            let m = match step {
                Step::Fixed(m) => *m,
                Step::Joint(j) => {
                    let e = if skip { None } else { errors.error(*j, q[*j]) };
                    c.joints[*j].motion(q[*j], None, e.as_ref()).0
                }
            };
            t = Some(match t {
                None => m,
                Some(t) => t.mul(&m),
            });
        }
        t.unwrap_or(Affine::IDENTITY)
    }

    /// The tool tip and axis of the precomputed chain by one backward pass
    /// of the two vectors (`T·[0,0,0,1]`, `T·[0,0,1,0]`): each element maps
    /// a point and a direction instead of multiplying 3×4 matrices.
    /// `rots`: the revolute joints' rotations when the caller has them
    /// already (by joint index), else each is computed here.
    fn pose_backward(
        c: &Compiled,
        q: &[f64],
        errors: &dyn JointErrors,
        rots: Rotations<'_>,
    ) -> Pose {
        let skip = errors.is_empty();
        let mut tip = [0.0; 3];
        let mut ax = [0.0, 0.0, 1.0];
        for step in c.steps.iter().rev() {
            match step {
                Step::Fixed(m) => {
                    tip = m.point(&tip);
                    ax = m.dir(&ax);
                }
                Step::Joint(j) => {
                    let jc = &c.joints[*j];
                    let v = q[*j];
                    if !skip && let Some(e) = errors.error(*j, v) {
                        // E = [I + [ε]ₓ | δ] (small-angle form, as `transform`).
                        let d = |x: &[f64; 3]| {
                            [
                                x[0] - e[5] * x[1] + e[4] * x[2],
                                e[5] * x[0] + x[1] - e[3] * x[2],
                                -e[4] * x[0] + e[3] * x[1] + x[2],
                            ]
                        };
                        let t = d(&tip);
                        tip = [t[0] + e[0], t[1] + e[1], t[2] + e[2]];
                        ax = d(&ax);
                    }
                    match jc.kind {
                        JointKind::Prismatic => {
                            for (t, u) in tip.iter_mut().zip(jc.u) {
                                *t += u * v;
                            }
                        }
                        JointKind::Revolute => {
                            let r = match rots {
                                Rotations::Given(rots) => rots[*j],
                                Rotations::Near(near) => {
                                    let (s, c) = near.sin_cos(*j, v);
                                    jc.rotation_sc(s, c)
                                }
                                Rotations::Compute => jc.rotation(v),
                            };
                            let rot = |x: &[f64; 3]| -> [f64; 3] {
                                std::array::from_fn(|i| {
                                    r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2]
                                })
                            };
                            tip = rot(&tip);
                            ax = rot(&ax);
                        }
                    }
                }
            }
        }
        Pose {
            tip: Vector3::new(tip[0], tip[1], tip[2]),
            axis: Vector3::new(ax[0], ax[1], ax[2]),
        }
    }

    /// Forward kinematics: tool tip `T·[0,0,0,1]` and tool axis `T·[0,0,1,0]`.
    pub fn pose(&self, q: &[f64], errors: &dyn JointErrors) -> Pose {
        debug_assert_eq!(q.len(), self.joints.len());
        match self.with_compiled(|c| Self::pose_backward(c, q, errors, Rotations::Compute)) {
            Some(pose) => pose,
            None => {
                let t = self.transform_general(q, errors);
                Pose {
                    tip: Vector3::new(t[(0, 3)], t[(1, 3)], t[(2, 3)]),
                    axis: Vector3::new(t[(0, 2)], t[(1, 2)], t[(2, 2)]),
                }
            }
        }
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
        match self.with_compiled(|c| Self::pose_jacobian_compiled(c, q, errors, &mut cols, None)) {
            Some(pose) => {
                let jac = Jacobian::from_fn(n, |r, c| cols[c][r]);
                (pose, jac)
            }
            None => self.pose_and_jacobian_general(q, errors),
        }
    }

    /// [`Chain::pose_and_jacobian`] without allocating: column `k` of
    /// `jac` receives `d[tip; axis]/dq_k` (columns past the dof are left
    /// as they are). Needs a chain of at most [`MAX_JOINTS`] joints.
    pub fn pose_and_jacobian_into(
        &self,
        q: &[f64],
        errors: &dyn JointErrors,
        jac: &mut JacobianColumns,
    ) -> Pose {
        match self.with_compiled(|c| Self::pose_jacobian_compiled(c, q, errors, jac, None)) {
            Some(pose) => pose,
            None => {
                let (pose, j) = self.pose_and_jacobian_general(q, errors);
                for (k, col) in jac.iter_mut().enumerate().take(j.ncols()) {
                    for (r, v) in col.iter_mut().enumerate() {
                        *v = j[(r, k)];
                    }
                }
                pose
            }
        }
    }

    /// The sines and cosines of the revolute joints at `q0`, for poses and
    /// Jacobians near `q0` (see [`NearTrig`]).
    pub fn trig_at(&self, q0: &[f64]) -> NearTrig {
        let mut t = NearTrig {
            q0: [0.0; MAX_JOINTS],
            sc: [(0.0, 1.0); MAX_JOINTS],
        };
        for (j, joint) in self.joints.iter().enumerate().take(MAX_JOINTS) {
            t.q0[j] = q0[j];
            if joint.kind == JointKind::Revolute {
                t.sc[j] = q0[j].sin_cos();
            }
        }
        t
    }

    /// [`Chain::pose`] with the revolute joints' sines and cosines taken
    /// from `near` where `q` is near its `q0` (the refinement's trial points).
    pub fn pose_near(&self, q: &[f64], errors: &dyn JointErrors, near: &NearTrig) -> Pose {
        let compiled =
            self.with_compiled(|c| Self::pose_backward(c, q, errors, Rotations::Near(near)));
        compiled.unwrap_or_else(|| self.pose(q, errors))
    }

    /// [`Chain::pose_and_jacobian_into`] with the revolute joints' sines
    /// and cosines taken from `near` where `q` is near its `q0`.
    pub fn pose_and_jacobian_near(
        &self,
        q: &[f64],
        errors: &dyn JointErrors,
        jac: &mut JacobianColumns,
        near: &NearTrig,
    ) -> Pose {
        match self.with_compiled(|c| Self::pose_jacobian_compiled(c, q, errors, jac, Some(near))) {
            Some(pose) => pose,
            None => self.pose_and_jacobian_into(q, errors, jac),
        }
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
        let compiled = self.with_compiled(|c| {
            // Each revolute joint's rotation, once.
            let mut rots = [[[0.0; 3]; 3]; MAX_JOINTS];
            for (j, jc) in c.joints.iter().enumerate() {
                if jc.kind == JointKind::Revolute {
                    rots[j] = jc.rotation(q[j]);
                }
            }
            // The directions need the rotation of the prefix before each
            // prismatic joint: a forward pass of 3×3 rotations up to the
            // last one.
            let last = c.steps.iter().rposition(
                |s| matches!(s, Step::Joint(j) if c.joints[*j].kind == JointKind::Prismatic),
            );
            let mut rot: Option<[[f64; 3]; 3]> = None;
            for step in &c.steps[..last.map_or(0, |l| l + 1)] {
                let r = match step {
                    Step::Fixed(m) => std::array::from_fn(|i| [m.m[i][0], m.m[i][1], m.m[i][2]]),
                    Step::Joint(j) => {
                        let jc = &c.joints[*j];
                        if jc.kind == JointKind::Prismatic {
                            dirs[*j] = match &rot {
                                Some(p) => std::array::from_fn(|i| {
                                    p[i][0] * jc.u[0] + p[i][1] * jc.u[1] + p[i][2] * jc.u[2]
                                }),
                                None => jc.u,
                            };
                            continue;
                        }
                        rots[*j]
                    }
                };
                rot = Some(match rot {
                    None => r,
                    Some(p) => mul3(&p, &r),
                });
            }
            // The pose: one backward pass of the tip and the axis.
            Self::pose_backward(c, q, &NoErrors, Rotations::Given(&rots))
        });
        match compiled {
            Some(pose) => pose,
            None => {
                let (pose, jac) = self.pose_and_jacobian_general(q, &NoErrors);
                for (j, joint) in self.joints.iter().enumerate() {
                    if joint.kind == JointKind::Prismatic {
                        dirs[j] = [jac[(0, j)], jac[(1, j)], jac[(2, j)]];
                    }
                }
                pose
            }
        }
    }

    fn pose_jacobian_compiled(
        c: &Compiled,
        q: &[f64],
        errors: &dyn JointErrors,
        jac: &mut JacobianColumns,
        near: Option<&NearTrig>,
    ) -> Pose {
        let n = c.joints.len();
        debug_assert_eq!(q.len(), n);
        let skip = errors.is_empty();
        // Per joint: G = M E, the rotation of M, and the derivative E' of
        // the error motion.
        let mut g = [Affine::IDENTITY; MAX_JOINTS];
        let mut rot = [[[0.0; 3]; 3]; MAX_JOINTS];
        let mut de: [Option<ErrorMotion>; MAX_JOINTS] = [None; MAX_JOINTS];
        for j in 0..n {
            let e = if skip {
                None
            } else {
                errors.error_and_derivative(j, q[j])
            };
            let sc = near
                .filter(|_| c.joints[j].kind == JointKind::Revolute)
                .map(|t| t.sin_cos(j, q[j]));
            (g[j], rot[j]) = c.joints[j].motion(q[j], sc, e.as_ref().map(|(e, _)| e));
            de[j] = e.map(|(_, d)| d);
        }
        // Backward pass: the tip point `s` and axis direction `a` carried
        // from the tool through each element; at joint k the column before
        // its prefix is G'_k applied to them, from vectors alone:
        //   revolute:  M' = [u]ₓ M, so M' E s = u × (G s);
        //   prismatic: M' = [0 | u], so M' E s = u (points), 0 (directions);
        //   both:      M E' s = R (ε' × s + δ') (points), R (ε' × a).
        let cross = |a: &[f64; 3], b: &[f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let mut s_tip = [0.0, 0.0, 0.0];
        let mut s_ax = [0.0, 0.0, 1.0];
        let mut local = [([0.0; 3], [0.0; 3]); MAX_JOINTS];
        for step in c.steps.iter().rev() {
            match step {
                Step::Fixed(m) => {
                    s_tip = m.point(&s_tip);
                    s_ax = m.dir(&s_ax);
                }
                Step::Joint(j) => {
                    let jc = &c.joints[*j];
                    let (st, sa) = (s_tip, s_ax);
                    s_tip = g[*j].point(&st);
                    s_ax = g[*j].dir(&sa);
                    let (mut dt, mut da) = match jc.kind {
                        JointKind::Revolute => (cross(&jc.u, &s_tip), cross(&jc.u, &s_ax)),
                        JointKind::Prismatic => (jc.u, [0.0; 3]),
                    };
                    if let Some(d) = &de[*j] {
                        let eps = [d[3], d[4], d[5]];
                        let et = cross(&eps, &st);
                        let et = [et[0] + d[0], et[1] + d[1], et[2] + d[2]];
                        let ea = cross(&eps, &sa);
                        let (et, ea) = match jc.kind {
                            JointKind::Revolute => {
                                (rot3_apply(&rot[*j], &et), rot3_apply(&rot[*j], &ea))
                            }
                            JointKind::Prismatic => (et, ea),
                        };
                        for k in 0..3 {
                            dt[k] += et[k];
                            da[k] += ea[k];
                        }
                    }
                    local[*j] = (dt, da);
                }
            }
        }
        // Forward pass: the rotation part of the prefix products (the
        // columns map directions only); column k = P_k · (G_k' · S_k).
        let last = c.steps.iter().rposition(|s| matches!(s, Step::Joint(_)));
        let mut prefix: Option<[[f64; 3]; 3]> = None;
        for (i, step) in c.steps.iter().enumerate() {
            let m = match step {
                Step::Fixed(m) => m,
                Step::Joint(j) => {
                    let (mut dt, mut da) = local[*j];
                    if let Some(p) = &prefix {
                        dt = rot3_apply(p, &dt);
                        da = rot3_apply(p, &da);
                    }
                    jac[*j] = [dt[0], dt[1], dt[2], da[0], da[1], da[2]];
                    &g[*j]
                }
            };
            if Some(i) == last {
                break;
            }
            let r: [[f64; 3]; 3] = std::array::from_fn(|i| [m.m[i][0], m.m[i][1], m.m[i][2]]);
            prefix = Some(match prefix {
                None => r,
                Some(p) => mul3(&p, &r),
            });
        }
        // The pose: the backward pass carried the tip and axis through.
        Pose {
            tip: Vector3::new(s_tip[0], s_tip[1], s_tip[2]),
            axis: Vector3::new(s_ax[0], s_ax[1], s_ax[2]),
        }
    }

    /// [`Chain::pose_and_jacobian`] with full 4×4 matrices, element by element
    /// (chains with a fixed element that is not affine).
    fn pose_and_jacobian_general(&self, q: &[f64], errors: &dyn JointErrors) -> (Pose, Jacobian) {
        let n = self.joints.len();
        debug_assert_eq!(q.len(), n);
        // Per-joint transforms and derivatives.
        let mut g = [Matrix4::<f64>::identity(); MAX_JOINTS];
        let mut dg = [Matrix4::<f64>::zeros(); MAX_JOINTS];
        for j in 0..n {
            let m = self.joint_motion(j, q[j]);
            let dm = self.joint_motion_derivative(j, q[j]);
            match errors.error_and_derivative(j, q[j]) {
                Some((e, de)) => {
                    let em = error_matrix(&e);
                    g[j] = m * em;
                    dg[j] = dm * em + m * error_matrix_derivative(&de);
                }
                None => {
                    g[j] = m;
                    dg[j] = dm;
                }
            }
        }
        let elem = |el: &Element| -> Matrix4<f64> {
            match el {
                Element::Fixed(m) => *m,
                Element::Joint(j) => g[*j],
            }
        };
        // Backward pass: suffix applied to tip point and axis direction.
        let ne = self.elements.len();
        let mut s_tip = Vector4::new(0.0, 0.0, 0.0, 1.0);
        let mut s_ax = Vector4::new(0.0, 0.0, 1.0, 0.0);
        let mut suffix = [(Vector4::zeros(), Vector4::zeros()); MAX_JOINTS];
        for i in (0..ne).rev() {
            if let Element::Joint(j) = self.elements[i] {
                suffix[j] = (s_tip, s_ax);
            }
            let m = elem(&self.elements[i]);
            s_tip = m * s_tip;
            s_ax = m * s_ax;
        }
        // Forward pass: prefix products.
        let mut jac = Jacobian::zeros(n);
        let mut prefix = Matrix4::<f64>::identity();
        for el in &self.elements {
            if let Element::Joint(j) = el {
                let d = prefix * dg[*j];
                let (st, sa) = suffix[*j];
                let dt = d * st;
                let da = d * sa;
                jac[(0, *j)] = dt[0];
                jac[(1, *j)] = dt[1];
                jac[(2, *j)] = dt[2];
                jac[(3, *j)] = da[0];
                jac[(4, *j)] = da[1];
                jac[(5, *j)] = da[2];
            }
            prefix *= elem(el);
        }
        let pose = Pose {
            tip: Vector3::new(prefix[(0, 3)], prefix[(1, 3)], prefix[(2, 3)]),
            axis: Vector3::new(prefix[(0, 2)], prefix[(1, 2)], prefix[(2, 2)]),
        };
        (pose, jac)
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
