//! The chain's one evaluator: the precomputed form of a chain (consecutive
//! fixed elements multiplied out into affine 3×4 transforms, per-joint
//! constants) and the passes over it — the forward product, the pose by one
//! backward pass of the tip and axis vectors, and the pose with its
//! analytic Jacobian.

use nalgebra::{Matrix3, Matrix4, Vector3};

use super::{
    Element, ErrorMotion, JacobianColumns, Joint, JointErrors, JointKind, MAX_JOINTS, NoErrors,
    Pose,
};

/// The sines and cosines of a chain's revolute joints at joint values `q0`
/// ([`super::Chain::trig_at`]): near `q0` those of `q = q0 + d` follow by the
/// addition theorem, `sin q = sin q0 · cos d + cos q0 · sin d`, with
/// `sin d` and `cos d` from their series, which for |d| ≤ 1e-4 rad are
/// exact to far below an ulp (the first omitted terms are d⁵/120 < 1e-22
/// and d⁶/720 < 2e-27). The Newton refinement's steps are micro-radians,
/// so its trial points cost no `sin_cos` call.
#[derive(Debug, Clone, Copy)]
pub struct NearTrig {
    q0: [f64; MAX_JOINTS],
    sc: [(f64, f64); MAX_JOINTS],
    /// Which joints are revolute (the others have no angle).
    revolute: [bool; MAX_JOINTS],
}

impl NearTrig {
    /// Those of `joints` at `q0` ([`super::Chain::trig_at`]).
    pub(super) fn at(joints: &[Joint], q0: &[f64]) -> NearTrig {
        let mut t = NearTrig {
            q0: [0.0; MAX_JOINTS],
            sc: [(0.0, 1.0); MAX_JOINTS],
            revolute: [false; MAX_JOINTS],
        };
        for (j, joint) in joints.iter().enumerate().take(MAX_JOINTS) {
            t.q0[j] = q0[j];
            if joint.kind == JointKind::Revolute {
                t.sc[j] = q0[j].sin_cos();
                t.revolute[j] = true;
            }
        }
        t
    }

    /// Largest |q − q0| handled by the addition theorem, rad.
    const NEAR_RAD: f64 = 1e-4;

    /// `(sin, cos)` of joint `j` at `q0 + d`, with the offset `d` (rad)
    /// taken exactly: it need not be representable as a change of
    /// `q0 + d` in floating point. For a rotary at thousands of degrees,
    /// `q0 + d` resolves only 1e-14 rad or so (1e-12 mm at a 100 mm
    /// radius); the refinement steps by its offsets through this and loses
    /// nothing ([`super::Chain::pose_at_offsets`]: the rotations come from
    /// here, the error motions from the rounded `q0 + d`, where their
    /// resolution does not matter).
    #[inline]
    pub fn sin_cos_offset(&self, j: usize, d: f64) -> (f64, f64) {
        if d == 0.0 {
            return self.sc[j];
        }
        let sd = if d.abs() <= Self::NEAR_RAD {
            small_sin_cos(d)
        } else {
            d.sin_cos()
        };
        add_angles(self.sc[j], sd)
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

/// Where [`pose_backward`] takes the revolute joints' rotations from.
#[derive(Clone, Copy)]
pub(super) enum Rotations<'a> {
    /// Computed from the joint values.
    Compute,
    /// Given by the caller, by joint index.
    Given(&'a [[[f64; 3]; 3]; MAX_JOINTS]),
    /// From sines and cosines near known ones.
    Near(&'a NearTrig),
    /// From those at `q0` and the exact offsets from it, by joint index
    /// ([`NearTrig::sin_cos_offset`]).
    Offsets(&'a NearTrig, &'a [f64]),
}

impl Rotations<'_> {
    /// `(sin q, cos q)` of revolute joint `j` at `q` when they come from
    /// known ones; `None`: compute them from `q`.
    #[inline]
    fn sin_cos(&self, j: usize, q: f64) -> Option<(f64, f64)> {
        match self {
            Rotations::Near(near) => Some(near.sin_cos(j, q)),
            Rotations::Offsets(near, d) => Some(near.sin_cos_offset(j, d[j])),
            Rotations::Compute | Rotations::Given(_) => None,
        }
    }
}

/// An affine transform `[R | t]` (row-major, the last row `0 0 0 1`
/// implied). Products and point maps sum in the same order as nalgebra's
/// 4×4 products (k = 0, 1, 2, then the translation), skipping only the
/// terms that are exactly zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Affine {
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

    /// The affine part of `m` (its first three rows; every fixed element
    /// of a chain is affine, its last row `0 0 0 1`).
    fn from_matrix4(m: &Matrix4<f64>) -> Affine {
        debug_assert!(
            m[(3, 0)] == 0.0 && m[(3, 1)] == 0.0 && m[(3, 2)] == 0.0 && m[(3, 3)] == 1.0,
            "a fixed element that is not affine: {m}"
        );
        let mut a = Affine::IDENTITY;
        for (i, row) in a.m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = m[(i, j)];
            }
        }
        a
    }

    /// As a 4×4 matrix.
    pub(super) fn to_matrix4(self) -> Matrix4<f64> {
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
    /// For an axis along a coordinate axis (`u = ±e_k`, the usual machine
    /// axis): the plane `(i, j)` it turns (`(k+1, k+2)` cyclically) and the
    /// sign of `u`, so that a rotation turns two coordinates only
    /// ([`JointConst::rotate_sc`]).
    plane: Option<(usize, usize, f64)>,
}

impl JointConst {
    fn new(joint: &Joint) -> Self {
        let u = joint.axis.into_inner();
        let k = joint.axis.cross_matrix();
        let kk = k * k;
        let arr = |m: &Matrix3<f64>| std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
        let u = [u.x, u.y, u.z];
        let plane = (0..3)
            .find(|&a| u[a].abs() == 1.0 && u[(a + 1) % 3] == 0.0 && u[(a + 2) % 3] == 0.0)
            .map(|a| ((a + 1) % 3, (a + 2) % 3, u[a]));
        JointConst {
            kind: joint.kind,
            u,
            k: arr(&k),
            kk: arr(&kk),
            plane,
        }
    }

    /// `a` and `b` turned by [`JointConst::rotation_sc`]`(s, c)`, the same
    /// numbers: for an axis along a coordinate axis only the two
    /// coordinates of its plane change, `i' = (1 − (1 − c)) x_i ∓ s x_j`,
    /// `j' = ± s x_i + (1 − (1 − c)) x_j` (the matrix's entries as Rodrigues
    /// gives them; its zero entries add nothing but the sign of a zero).
    #[inline]
    fn rotate_sc(&self, s: f64, c: f64, a: &mut [f64; 3], b: &mut [f64; 3]) {
        match self.plane {
            Some((i, j, sign)) => {
                let cc = 1.0 - (1.0 - c);
                let ss = sign * s;
                for x in [a, b] {
                    let (xi, xj) = (x[i], x[j]);
                    x[i] = cc * xi + (-ss) * xj;
                    x[j] = ss * xi + cc * xj;
                }
            }
            None => {
                let r = self.rotation_sc(s, c);
                *a = rot3_apply(&r, a);
                *b = rot3_apply(&r, b);
            }
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

/// The precomputed form of a chain (see [`super::Chain`]).
#[derive(Clone, Default)]
pub(super) struct Compiled {
    steps: Vec<Step>,
    joints: Vec<JointConst>,
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
    /// The precomputed form of a chain's elements and joints (at most
    /// [`MAX_JOINTS`] joints).
    pub(super) fn new(elements: &[Element], joints: &[Joint]) -> Self {
        debug_assert!(joints.len() <= MAX_JOINTS);
        let mut c = Compiled {
            steps: Vec::with_capacity(elements.len()),
            joints: joints.iter().map(JointConst::new).collect(),
        };
        for el in elements {
            match el {
                Element::Fixed(m) => {
                    let a = Affine::from_matrix4(m);
                    match c.steps.last_mut() {
                        Some(Step::Fixed(prev)) => *prev = prev.mul(&a),
                        _ => c.steps.push(Step::Fixed(a)),
                    }
                }
                Element::Joint(j) => c.steps.push(Step::Joint(*j)),
            }
        }
        c
    }
}

/// The forward product on the precomputed chain.
pub(super) fn forward(c: &Compiled, q: &[f64], errors: &dyn JointErrors) -> Affine {
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

/// See [`super::Chain::frame_reach`].
pub(super) fn frame_reach(c: &Compiled, q: &[f64]) -> f64 {
    c.steps
        .iter()
        .map(|step| match step {
            Step::Fixed(m) => (m.m[0][3].powi(2) + m.m[1][3].powi(2) + m.m[2][3].powi(2)).sqrt(),
            Step::Joint(j) => match c.joints[*j].kind {
                JointKind::Prismatic => q.get(*j).map_or(0.0, |v| v.abs()),
                JointKind::Revolute => 0.0,
            },
        })
        .sum()
}

/// The tool tip and axis of the precomputed chain by one backward pass
/// of the two vectors (`T·[0,0,0,1]`, `T·[0,0,1,0]`): each element maps
/// a point and a direction instead of multiplying 3×4 matrices.
/// `rots`: the revolute joints' rotations when the caller has them
/// already (by joint index), else each is computed here.
pub(super) fn pose_backward(
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
                    JointKind::Revolute => match rots {
                        Rotations::Given(rots) => {
                            tip = rot3_apply(&rots[*j], &tip);
                            ax = rot3_apply(&rots[*j], &ax);
                        }
                        _ => {
                            let (s, c) = rots.sin_cos(*j, v).unwrap_or_else(|| v.sin_cos());
                            jc.rotate_sc(s, c, &mut tip, &mut ax);
                        }
                    },
                }
            }
        }
    }
    Pose {
        tip: Vector3::new(tip[0], tip[1], tip[2]),
        axis: Vector3::new(ax[0], ax[1], ax[2]),
    }
}

/// The pose and the analytic Jacobian of the precomputed chain (see
/// [`super::Chain::pose_and_jacobian`]); revolute sines and cosines from
/// `rots` where it has them (computed from `q` for
/// [`Rotations::Compute`] and [`Rotations::Given`]).
pub(super) fn pose_jacobian(
    c: &Compiled,
    q: &[f64],
    errors: &dyn JointErrors,
    jac: &mut JacobianColumns,
    rots: Rotations<'_>,
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
        let sc = if c.joints[j].kind == JointKind::Revolute {
            rots.sin_cos(j, q[j])
        } else {
            None
        };
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

/// The theoretical pose and the prismatic joints' directions of motion
/// (see [`super::Chain::pose_and_prismatic_directions`]).
pub(super) fn pose_and_prismatic_directions(
    c: &Compiled,
    q: &[f64],
    dirs: &mut [[f64; 3]; MAX_JOINTS],
) -> Pose {
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
    let last = c
        .steps
        .iter()
        .rposition(|s| matches!(s, Step::Joint(j) if c.joints[*j].kind == JointKind::Prismatic));
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
    pose_backward(c, q, &NoErrors, Rotations::Given(&rots))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Unit, Vector3};

    /// A revolute joint along a coordinate axis turns a vector to the very
    /// numbers of the Rodrigues matrix (`==`: a zero's sign aside), for
    /// every coordinate axis and both signs; a skew axis has no plane.
    #[test]
    fn plane_rotation_is_the_matrix_rotation() {
        let joint = |axis: Vector3<f64>| {
            JointConst::new(&Joint {
                name: "A".into(),
                kind: JointKind::Revolute,
                axis: Unit::new_normalize(axis),
                element: 0,
            })
        };
        let mut rng = crate::test_support::Lcg(7);
        let mut next = || rng.signed();
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut u = Vector3::zeros();
                u[k] = sign;
                let jc = joint(u);
                assert!(jc.plane.is_some(), "axis {k} sign {sign}");
                for _ in 0..200 {
                    let theta = next() * 1e3;
                    let (s, c) = theta.sin_cos();
                    let mut a = [next() * 100.0, next() * 100.0, next() * 100.0];
                    let mut b = [next(), next(), next()];
                    let r = jc.rotation_sc(s, c);
                    let (ra, rb) = (rot3_apply(&r, &a), rot3_apply(&r, &b));
                    jc.rotate_sc(s, c, &mut a, &mut b);
                    assert_eq!((a, b), (ra, rb), "axis {k} sign {sign} θ {theta}");
                }
            }
        }
        assert!(joint(Vector3::new(0.0, 0.6, 0.8)).plane.is_none());
    }
}
