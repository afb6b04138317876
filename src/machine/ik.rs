//! Inverse kinematics: tool pose → joint values, on the theoretical chain.
//!
//! The solver is chosen from the chain's *structure* (joint kinds, axis
//! directions, offsets), never from joint names:
//!
//! | [`Family`] | structure | method |
//! | --- | --- | --- |
//! | [`Family::FiveAxis2R3T`] | 2 revolute + 3 prismatic (independent), any order | orientation by Paden–Kahan subproblem 2 (≤ 2 branches), then a 3×3 linear solve |
//! | [`Family::FourAxis1R3T`] | 1 revolute + 3 prismatic | rotary by subproblem 1 (closest tool axis), linear solve |
//! | [`Family::FourAxisRTTR`] | revolute first, then 2 prismatic + 1 revolute moving the tool in a plane that holds the first axis | first rotary from the tip azimuth (2 branches), second from the projected tool axis, 2 linear axes by least squares |
//! | [`Family::ThreeAxis`] | 3 prismatic | linear solve |
//! | [`Family::Generic`] | anything else | damped Newton ([`super::newton_ik`]) |
//!
//! The tool axis depends only on the rotations (prismatic joints do not
//! turn anything), so every analytic family solves the rotary joints from the
//! tool axis first; with the rotations fixed the tool tip is affine in the
//! prismatic joints, and those come from one linear solve whose matrix is
//! the prismatic columns of the Jacobian
//! ([`Chain::pose_and_prismatic_directions`], one forward pass).
//!
//! Policy (see `docs/machines.md`): every branch is enumerated; rotary values
//! are unwound towards the previous block ([`super::rotary::choose_turn`]);
//! among the branches within the axis limits, the one nearest the previous
//! block in a weighted joint distance (rotary travel dominates) is chosen.
//! At a singular pose the free rotary keeps its previous value. Machines that
//! cannot reach every tool axis (four-axis machines) meet the tip exactly and
//! report how far the reachable axis misses the programmed one
//! ([`IkSolution::axis_miss_rad`]); the caller decides whether that is an error.

use super::axis::{AxisSpec, RotaryMode};
use super::chain::{Chain, Element, JointKind, JointValues, NoErrors, Pose, rotate};
use super::file::Machine;
pub use super::ik_error::IkError;
use super::newton_ik::{self, NewtonOptions};
use super::rotary::{angle_diff, choose_turn, within_limits};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3};
use std::f64::consts::PI;

mod orient;
mod prepared;
mod subproblem;

pub use prepared::PreparedPose;

use subproblem::{gram_schmidt_solve, rot3, subproblem1, subproblem2};

/// Default largest tool-axis miss a caller should accept silently, rad.
pub const DEFAULT_AXIS_TOLERANCE_RAD: f64 = 1e-6;

/// Default angle (rad) between the tool axis and a rotary axis below which the
/// pose counts as singular and the free rotary keeps its previous value.
pub const DEFAULT_SINGULAR_TOL_RAD: f64 = 1e-9;

/// Weight of a linear axis in the branch distance, per mm (rotary axes count
/// 1 per rad): 1 rad of rotary travel weighs like 10 m of linear travel.
const LINEAR_WEIGHT_PER_MM: f64 = 1e-4;

/// Two branches whose tool-axis misses differ by less than this are equally
/// good (rad).
const MISS_TIE_RAD: f64 = 1e-9;

/// Tolerance of the structural tests (unit directions, dimensionless).
const STRUCT_TOL: f64 = 1e-9;

/// The inverse-kinematics family of a chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Family {
    /// Two revolute and three independent prismatic joints, in any order
    /// (table-table, head-head, head-table five-axis machines).
    FiveAxis2R3T,
    /// One revolute and three independent prismatic joints (XYZ + rotary table).
    FourAxis1R3T,
    /// Revolute, then two prismatic joints and a revolute that move the tool
    /// in a plane holding the first revolute's axis (seed 000's XZBC lens machine).
    FourAxisRTTR,
    /// Three independent prismatic joints.
    ThreeAxis,
    /// Anything else: damped Newton.
    Generic,
}

impl Family {
    /// Short name: `2R3T`, `1R3T`, `RTTR`, `3T` or `generic`.
    pub fn short_name(self) -> &'static str {
        match self {
            Family::FiveAxis2R3T => "2R3T",
            Family::FourAxis1R3T => "1R3T",
            Family::FourAxisRTTR => "RTTR",
            Family::ThreeAxis => "3T",
            Family::Generic => "generic",
        }
    }
}

impl std::fmt::Display for Family {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Family::FiveAxis2R3T => {
                "five-axis 2R3T (analytic: Paden–Kahan subproblem 2, then linear solve)"
            }
            Family::FourAxis1R3T => {
                "four-axis 1R3T (analytic: closest tool axis by subproblem 1, then linear solve)"
            }
            Family::FourAxisRTTR => {
                "four-axis RTTR (analytic: rotary from tip azimuth, rotary from projected tool axis, planar linear solve)"
            }
            Family::ThreeAxis => "three-axis (linear solve)",
            Family::Generic => "generic (damped Newton on the chain)",
        })
    }
}

/// One solution of the inverse kinematics.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Joint values, chain order, mm and rad (rotaries unwound towards the
    /// previous block; modulo axes in `[0, 2π)`).
    pub q: JointValues,
    /// Angle between the tool axis the machine reaches with `q` and the
    /// programmed one, rad (≈ 0 for five-axis machines; the cone miss of a
    /// four-axis machine).
    pub axis_miss_rad: f64,
    /// True when a rotary was free at this pose and kept its previous value.
    pub singular: bool,
    /// Which branch of the family's enumeration this is (0 or 1; see
    /// `docs/machines.md`).
    pub branch: u8,
}

/// Largest tool-tip coordinate the solver accepts, mm.
const MAX_COORDINATE_MM: f64 = 1e9;

/// Settings of the inverse kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Angle (rad) between the tool axis and a rotary axis below which the
    /// rotary is free (singular pose) and keeps its previous value.
    pub singular_tol_rad: f64,
    /// Four-axis RTTR machines: weight of the tool axis against the tool tip
    /// when choosing the first rotary, mm per rad. The rotary comes from the
    /// tip azimuth, except within about this distance of its axis, where the
    /// azimuth is lost in the noise of the data and the tool axis decides.
    pub rttr_axis_weight_mm: f64,
    /// Tip distance (mm) from the first rotary axis of an RTTR machine below
    /// which the tip counts as on the axis.
    pub on_axis_tol_mm: f64,
    /// Settings of the damped-Newton fallback.
    pub newton: NewtonOptions,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            singular_tol_rad: DEFAULT_SINGULAR_TOL_RAD,
            rttr_axis_weight_mm: 1e-6,
            on_axis_tol_mm: 1e-9,
            newton: NewtonOptions::default(),
        }
    }
}

/// Frame data of an RTTR machine.
#[derive(Debug, Clone)]
struct RttrFrame {
    /// Inverse of the fixed transform before the first revolute.
    pre_inv: Matrix4<f64>,
    /// Normal of the plane the tool moves in (frame after the first revolute).
    n: Vector3<f64>,
    /// In-plane direction perpendicular to the first revolute's axis
    /// (`u1 × d = n`).
    d: Vector3<f64>,
}

/// The inverse-kinematics solver of one machine.
#[derive(Debug, Clone)]
pub struct IkSolver {
    chain: Chain,
    /// Axis settings by chain joint index.
    axes: Vec<AxisSpec>,
    /// Axis settings in output order (for messages).
    output_order: Vec<usize>,
    family: Family,
    revolutes: Vec<usize>,
    prismatics: Vec<usize>,
    /// Products of the fixed rotations between revolutes: `segs[0]` before
    /// the first, …, `segs[r]` after the last (length = revolutes + 1).
    segs: Vec<Matrix3<f64>>,
    rttr: Option<RttrFrame>,
    options: IkOptions,
    /// The branch [`IkSolver::choose`] chose last: the one
    /// [`IkSolver::prepare`] completes alone ([`prepared::BranchHint`]).
    last_chosen: prepared::BranchHint,
}

/// Most solution branches of any family (subproblem 2 has two).
const MAX_BRANCHES: usize = 2;

/// The solution branches of one pose, inline.
type Branches = arrayvec::ArrayVec<IkSolution, MAX_BRANCHES>;

/// The raw branches of one pose, inline.
type RawBranches = arrayvec::ArrayVec<Raw, MAX_BRANCHES>;

/// A branch before unwinding and the linear solve.
#[derive(Debug, Clone, PartialEq)]
struct Raw {
    /// Joint values (the first `dof` are used).
    q: [f64; super::chain::MAX_JOINTS],
    singular: bool,
    branch: u8,
}

impl Raw {
    /// The one branch of a machine without rotaries.
    fn fixed() -> Self {
        Raw {
            q: [0.0; super::chain::MAX_JOINTS],
            singular: false,
            branch: 0,
        }
    }
}

impl IkSolver {
    /// The solver for `machine` with default options.
    pub fn new(machine: &Machine) -> Self {
        IkSolver::with_options(machine, IkOptions::default())
    }

    /// The solver for `machine` with `options`.
    pub fn with_options(machine: &Machine, options: IkOptions) -> Self {
        let chain = machine.chain.clone();
        let n = chain.dof();
        let axes: Vec<AxisSpec> = (0..n)
            .map(|j| {
                machine
                    .axis_of_joint(j)
                    .cloned()
                    .unwrap_or_else(|| AxisSpec {
                        name: chain.joints()[j].name.clone(),
                        joint: j,
                        kind: chain.joints()[j].kind,
                        min: None,
                        max: None,
                        rotary: if chain.joints()[j].kind == JointKind::Revolute {
                            RotaryMode::Continuous
                        } else {
                            RotaryMode::Limited
                        },
                        decimals: 4,
                    })
            })
            .collect();
        let mut output_order: Vec<usize> = machine
            .axes
            .iter()
            .map(|a| a.joint)
            .filter(|&j| j < n)
            .collect();
        for j in 0..n {
            if !output_order.contains(&j) {
                output_order.push(j);
            }
        }
        let revolutes: Vec<usize> = (0..n)
            .filter(|&j| chain.joints()[j].kind == JointKind::Revolute)
            .collect();
        let prismatics: Vec<usize> = (0..n)
            .filter(|&j| chain.joints()[j].kind == JointKind::Prismatic)
            .collect();
        let mut segs = Vec::with_capacity(revolutes.len() + 1);
        let mut cur = Matrix3::identity();
        for el in chain.elements() {
            match el {
                Element::Fixed(m) => cur *= rot3(m),
                Element::Joint(j) if chain.joints()[*j].kind == JointKind::Revolute => {
                    segs.push(cur);
                    cur = Matrix3::identity();
                }
                Element::Joint(_) => {}
            }
        }
        segs.push(cur);
        let mut solver = IkSolver {
            chain,
            axes,
            output_order,
            family: Family::Generic,
            revolutes,
            prismatics,
            segs,
            rttr: None,
            options,
            last_chosen: prepared::BranchHint::default(),
        };
        solver.family = solver.detect();
        solver
    }

    /// The family recognised for this machine.
    pub fn family(&self) -> Family {
        self.family
    }

    /// The options in use.
    pub fn options(&self) -> &IkOptions {
        &self.options
    }

    fn u(&self, j: usize) -> Vector3<f64> {
        self.chain.joints()[j].axis.into_inner()
    }

    /// Prismatic directions in the workpiece frame at joint values `q`.
    fn prismatic_columns(&self, q: &[f64]) -> Vec<Vector3<f64>> {
        let (_, jac) = self.chain.pose_and_jacobian(q, &NoErrors);
        self.prismatics
            .iter()
            .map(|&j| Vector3::new(jac[(0, j)], jac[(1, j)], jac[(2, j)]))
            .collect()
    }

    fn independent(cols: &[Vector3<f64>]) -> bool {
        match cols.len() {
            3 => cols[0].cross(&cols[1]).dot(&cols[2]).abs() > STRUCT_TOL,
            2 => cols[0].cross(&cols[1]).norm() > STRUCT_TOL,
            1 => cols[0].norm() > STRUCT_TOL,
            _ => false,
        }
    }

    fn detect(&mut self) -> Family {
        let n = self.chain.dof();
        let (nr, np) = (self.revolutes.len(), self.prismatics.len());
        if n == 0 || n > super::chain::MAX_JOINTS {
            return Family::Generic;
        }
        let zero = vec![0.0; n];
        let cols = self.prismatic_columns(&zero);
        let z = Vector3::z();
        match (nr, np) {
            (0, 3) if Self::independent(&cols) => Family::ThreeAxis,
            (1, 3) if Self::independent(&cols) => {
                let p = self.segs[1] * z;
                if self.u(self.revolutes[0]).cross(&p).norm() > STRUCT_TOL {
                    Family::FourAxis1R3T
                } else {
                    Family::Generic
                }
            }
            (2, 3) if Self::independent(&cols) => {
                let k1 = self.u(self.revolutes[0]);
                let k2 = self.segs[1] * self.u(self.revolutes[1]);
                let p = self.segs[1] * self.segs[2] * z;
                if k1.cross(&k2).norm() > STRUCT_TOL && k2.cross(&p).norm() > STRUCT_TOL {
                    Family::FiveAxis2R3T
                } else {
                    Family::Generic
                }
            }
            (2, 2) if self.revolutes[0] == 0 && Self::independent(&cols) => {
                match self.rttr_frame(&cols) {
                    Some(f) => {
                        self.rttr = Some(f);
                        Family::FourAxisRTTR
                    }
                    None => Family::Generic,
                }
            }
            _ => Family::Generic,
        }
    }

    /// Every solution branch of `pose` (chain order, internal units), with
    /// rotaries unwound towards `previous` (or towards 0 without one). Limits
    /// are not applied here (see [`IkSolver::check_limits`]); an empty list
    /// means no branch could be computed (see [`IkSolver::solve`] for why).
    pub fn branches(&self, pose: &Pose, previous: Option<&[f64]>) -> Vec<IkSolution> {
        self.candidates(pose, previous, false)
            .map(|c| c.into_iter().collect())
            .unwrap_or_default()
    }

    /// The solution for `pose` nearest the previous block's joint values
    /// `previous` (chain order, internal units), within the axis limits.
    pub fn solve(&self, pose: &Pose, previous: Option<&[f64]>) -> Result<IkSolution, IkError> {
        let cands = self.candidates(pose, previous, true)?;
        self.select(cands, previous)
    }

    /// The choice among the unwound branches `cands` of a pose: the one
    /// with the least tool-axis miss nearest `previous` within the limits,
    /// else the nearest one's limit error.
    fn select(&self, mut cands: Branches, previous: Option<&[f64]>) -> Result<IkSolution, IkError> {
        // A single branch within the limits is the choice.
        if cands.len() == 1 && self.within_all_limits(&cands[0].q) {
            return Ok(cands.remove(0));
        }
        let reference = self.reference(previous);
        let valid: [bool; MAX_BRANCHES] =
            std::array::from_fn(|i| cands.get(i).is_some_and(|s| self.within_all_limits(&s.q)));
        let distance: [f64; MAX_BRANCHES] = std::array::from_fn(|i| {
            cands
                .get(i)
                .map_or(f64::INFINITY, |s| self.distance(&s.q, &reference))
        });
        // The branch with the least axis miss (ties within MISS_TIE_RAD)
        // nearest the reference, among those `keep` admits.
        let pick = |keep: &dyn Fn(usize) -> bool| -> Option<usize> {
            let set = || cands.iter().enumerate().filter(|(i, _)| keep(*i));
            let best_miss = set()
                .map(|(_, s)| s.axis_miss_rad)
                .fold(f64::INFINITY, f64::min);
            set()
                .filter(|(_, s)| s.axis_miss_rad <= best_miss + MISS_TIE_RAD)
                .min_by(|(i, a), (j, b)| {
                    distance[*i]
                        .total_cmp(&distance[*j])
                        .then(a.branch.cmp(&b.branch))
                })
                .map(|(i, _)| i)
        };
        if let Some(i) = pick(&|i| valid[i]) {
            return Ok(cands.swap_remove(i));
        }
        match pick(&|_| true) {
            Some(i) => Err(self
                .check_limits(&cands[i].q)
                .err()
                .unwrap_or(IkError::Unreachable {
                    reason: "no solution branch".into(),
                })),
            None => Err(IkError::Unreachable {
                reason: "no solution branch".into(),
            }),
        }
    }

    /// Whether every joint of `q` (chain order, internal units) is within
    /// its axis limits: [`IkSolver::check_limits`] without building the error.
    pub fn within_all_limits(&self, q: &[f64]) -> bool {
        self.output_order
            .iter()
            .all(|&j| within_limits(&self.axes[j], q.get(j).copied().unwrap_or(f64::NAN)))
    }

    /// `Ok` when every joint of `q` (chain order, internal units) is within
    /// its axis limits; otherwise the first violation in output order.
    pub fn check_limits(&self, q: &[f64]) -> Result<(), IkError> {
        for &j in &self.output_order {
            let axis = &self.axes[j];
            let v = q.get(j).copied().unwrap_or(f64::NAN);
            if !within_limits(axis, v) {
                let file = match axis.kind {
                    JointKind::Prismatic => v,
                    JointKind::Revolute => v.to_degrees(),
                };
                return Err(IkError::Limit {
                    axis: axis.name.clone(),
                    value: file,
                    min: axis.min.unwrap_or(f64::NEG_INFINITY),
                    max: axis.max.unwrap_or(f64::INFINITY),
                    unit: axis.unit(),
                });
            }
        }
        Ok(())
    }

    /// Weighted joint distance used to choose between branches: rotary
    /// travel in rad (shortest way for modulo axes), linear travel scaled by
    /// `LINEAR_WEIGHT_PER_MM`; squared sum.
    pub fn distance(&self, q: &[f64], reference: &[f64]) -> f64 {
        self.weighted_distance(q, reference, LINEAR_WEIGHT_PER_MM)
    }

    /// [`IkSolver::distance`] with linear travel weighted by `per_mm`.
    fn weighted_distance(&self, q: &[f64], reference: &[f64], per_mm: f64) -> f64 {
        q.iter()
            .zip(reference)
            .enumerate()
            .map(|(j, (&a, &b))| self.distance_term(j, a, b, per_mm))
            .sum()
    }

    /// Joint `j`'s term of [`IkSolver::weighted_distance`].
    #[inline]
    fn distance_term(&self, j: usize, a: f64, b: f64, per_mm: f64) -> f64 {
        let d = match self.axes[j].kind {
            JointKind::Prismatic => (a - b) * per_mm,
            JointKind::Revolute if self.axes[j].rotary == RotaryMode::Modulo => angle_diff(a, b),
            JointKind::Revolute => a - b,
        };
        d * d
    }

    /// The reference branches are compared with: the previous block, or the
    /// neutral position (all joints 0) for the first block.
    fn reference(&self, previous: Option<&[f64]>) -> [f64; super::chain::MAX_JOINTS] {
        let mut r = [0.0; super::chain::MAX_JOINTS];
        match previous {
            Some(p) if p.len() == self.chain.dof() && p.iter().all(|v| v.is_finite()) => {
                r[..p.len()].copy_from_slice(p);
            }
            _ => {}
        }
        r
    }

    /// Refuses a pose no branch can be computed for: not finite, a zero
    /// tool axis, a tip beyond any travel, or a chain the evaluator does
    /// not handle.
    fn check_pose(&self, pose: &Pose) -> Result<(), IkError> {
        let axis_norm = pose.axis.norm();
        if !pose.tip.iter().all(|v| v.is_finite())
            || axis_norm.is_nan()
            || axis_norm <= 1e-12
            || !axis_norm.is_finite()
        {
            return Err(IkError::Unreachable {
                reason: "the pose is not finite or its tool axis is a zero vector".into(),
            });
        }
        // Far beyond any travel the chain's arithmetic overflows (NaN in the
        // SVD below); 1e9 mm = 1000 km is no machine's work space.
        if let Some(v) = pose.tip.iter().find(|v| v.abs() > MAX_COORDINATE_MM) {
            return Err(IkError::Unreachable {
                reason: format!(
                    "the tool tip coordinate {v:.3e} mm is beyond any machine's travel (|coordinate| ≤ {MAX_COORDINATE_MM:.0e} mm)"
                ),
            });
        }
        let n = self.chain.dof();
        if n == 0 || n > super::chain::MAX_JOINTS {
            return Err(IkError::Unreachable {
                reason: format!(
                    "the chain has {n} joints; the evaluator handles 1 to {}",
                    super::chain::MAX_JOINTS
                ),
            });
        }
        Ok(())
    }

    /// The solution branches of `pose`, rotaries unwound towards
    /// `previous`. With `nearest_only`, a second branch is not completed when
    /// it cannot be chosen: the first (the one whose rotaries are nearer the
    /// reference) is within the limits, meets the tool axis (miss within
    /// `MISS_TIE_RAD`), and is nearer than the second's rotaries alone.
    fn candidates(
        &self,
        pose: &Pose,
        previous: Option<&[f64]>,
        nearest_only: bool,
    ) -> Result<Branches, IkError> {
        self.check_pose(pose)?;
        let target = Pose::new(pose.tip, pose.axis);
        let reference = self.reference(previous);
        if self.family == Family::Generic {
            let start: Vec<f64> = match previous {
                Some(p) if p.len() == self.chain.dof() && p.iter().all(|v| v.is_finite()) => {
                    p.to_vec()
                }
                _ => self.neutral(),
            };
            let r = newton_ik::solve(
                &self.chain,
                &target,
                &start,
                &self.bounds(),
                &self.options.newton,
            )?;
            let mut q: JointValues = r.q.into_iter().collect();
            self.unwind(&mut q, &reference);
            let mut one = Branches::new();
            one.push(IkSolution {
                q,
                axis_miss_rad: r.axis_residual_rad,
                singular: false,
                branch: 0,
            });
            return Ok(one);
        }
        let complete = |raw: &Raw| self.complete_unwound(raw, &target, &reference);
        let nearest = |first, lower| self.nearest(first, lower, &reference);
        let mut done: [Option<Result<IkSolution, IkError>>; MAX_BRANCHES] = [None, None];
        // Whether `complete_branches` may still try the nearer branch alone.
        let mut nearest_only = nearest_only;
        let raws = match self.family {
            Family::ThreeAxis => RawBranches::from_iter([Raw::fixed()]),
            Family::FourAxis1R3T => self.orient_1r(&target, &reference),
            Family::FiveAxis2R3T => self.orient_2r(&target, &reference),
            Family::FourAxisRTTR => match self.rttr_angles(&target, &reference) {
                // The second rotary of a branch costs a subproblem: the
                // branches are ordered by their first rotary alone, whose
                // term bounds the distance from below.
                Some(a) if nearest_only && a.count == 2 => {
                    let lower = [0, 1].map(|b| self.rttr_lower(&a, b, &reference));
                    let (first, other) = if lower[1] < lower[0] { (1, 0) } else { (0, 1) };
                    let raw_first = self.rttr_branch(&a, first, &reference);
                    match nearest(complete(&raw_first), lower[other]) {
                        Ok(s) => return Ok(Branches::from_iter([s])),
                        Err(sol) => done[first] = Some(sol),
                    }
                    nearest_only = false;
                    let raw_other = self.rttr_branch(&a, other, &reference);
                    let mut raws = [Some(raw_first), Some(raw_other)];
                    raws.swap(0, first);
                    raws.into_iter().flatten().collect()
                }
                Some(a) => (0..a.count)
                    .map(|b| self.rttr_branch(&a, b, &reference))
                    .collect(),
                None => RawBranches::new(),
            },
            Family::Generic => RawBranches::new(),
        };
        self.complete_branches(&raws, done, &target, &reference, nearest_only)
    }

    /// The linear axes and the miss of one branch, its rotaries unwound
    /// towards `reference`.
    fn complete_unwound(
        &self,
        raw: &Raw,
        target: &Pose,
        reference: &[f64],
    ) -> Result<IkSolution, IkError> {
        let mut s = self.complete(raw, target)?;
        self.unwind(&mut s.q, reference);
        Ok(s)
    }

    /// With `nearest_only`, a branch `first` is completed alone and
    /// returned when it is certainly the one chosen: it meets the axis, is
    /// within the limits, and is nearer `reference` than `lower`, a lower
    /// bound of the other branch's distance. Otherwise the branch is given
    /// back as `Err`.
    fn nearest(
        &self,
        first: Result<IkSolution, IkError>,
        lower: f64,
        reference: &[f64],
    ) -> Result<IkSolution, Result<IkSolution, IkError>> {
        match first {
            Ok(s)
                if s.axis_miss_rad <= MISS_TIE_RAD
                    && self.within_all_limits(&s.q)
                    && self.distance(&s.q, reference) < lower =>
            {
                Ok(s)
            }
            other => Err(other),
        }
    }

    /// The branches `raws` completed and unwound towards `reference` (those
    /// in `done` completed and unwound already); with `nearest_only` only
    /// the nearer one where it is certainly the choice
    /// ([`IkSolver::nearest`]; tried while the other is not completed).
    fn complete_branches(
        &self,
        raws: &RawBranches,
        mut done: [Option<Result<IkSolution, IkError>>; MAX_BRANCHES],
        target: &Pose,
        reference: &[f64],
        nearest_only: bool,
    ) -> Result<Branches, IkError> {
        let n = self.chain.dof();
        let complete = |raw: &Raw| self.complete_unwound(raw, target, reference);
        let lower = |i: usize| {
            let mut q: JointValues = raws[i].q[..n].iter().copied().collect();
            self.unwind(&mut q, reference);
            self.rotary_distance(&q, reference)
        };
        // The branch tried alone (the one completed already, else the one
        // whose rotaries are nearer) and the lower bound of the other's
        // distance.
        let alone = match (&done[0], &done[1]) {
            _ if !nearest_only || raws.len() != 2 => None,
            (None, None) => {
                let bounds = [lower(0), lower(1)];
                Some(if bounds[1] < bounds[0] {
                    (1, bounds[0])
                } else {
                    (0, bounds[1])
                })
            }
            (Some(_), None) => Some((0, lower(1))),
            (None, Some(_)) => Some((1, lower(0))),
            (Some(_), Some(_)) => None,
        };
        if let Some((first, bound)) = alone {
            let s = done[first].take().unwrap_or_else(|| complete(&raws[first]));
            match self.nearest(s, bound, reference) {
                Ok(s) => return Ok(Branches::from_iter([s])),
                Err(sol) => done[first] = Some(sol),
            }
        }
        let mut out = Branches::new();
        let mut last_err = None;
        for (slot, raw) in done.iter_mut().zip(raws) {
            match slot.take().unwrap_or_else(|| complete(raw)) {
                Ok(s) => out.push(s),
                Err(e) => last_err = Some(e),
            }
        }
        match (out.is_empty(), last_err) {
            (true, Some(e)) => Err(e),
            _ => Ok(out),
        }
    }

    /// The linear axes and the tool-axis miss of a branch at the rotary
    /// angles of its enumeration (before they are unwound: a turn more or
    /// less leaves the linear axes where they are, and the angle nearer 0
    /// keeps every bit of their precision).
    fn complete(&self, raw: &Raw, target: &Pose) -> Result<IkSolution, IkError> {
        let mut q: JointValues = raw.q[..self.chain.dof()].iter().copied().collect();
        // The tool axis does not depend on the linear axes.
        let reached = self.solve_prismatics(&mut q, target)?;
        Ok(IkSolution {
            q,
            axis_miss_rad: reached.axis_angle(target),
            singular: raw.singular,
            branch: raw.branch,
        })
    }

    /// The rotary part of [`IkSolver::distance`]: a lower bound of it (the
    /// same non-negative terms in the same order, the linear ones zero).
    fn rotary_distance(&self, q: &[f64], reference: &[f64]) -> f64 {
        self.weighted_distance(q, reference, 0.0)
    }

    /// Start of the Newton fallback without a previous block: 0, moved into
    /// the limits where 0 is outside them.
    fn neutral(&self) -> Vec<f64> {
        self.axes
            .iter()
            .map(|a| {
                let (lo, hi) = (
                    a.min.unwrap_or(f64::NEG_INFINITY),
                    a.max.unwrap_or(f64::INFINITY),
                );
                let v = if a.rotary == RotaryMode::Modulo {
                    0.0
                } else {
                    0f64.clamp(lo, hi.max(lo))
                };
                match a.kind {
                    JointKind::Prismatic => v,
                    JointKind::Revolute => v.to_radians(),
                }
            })
            .collect()
    }

    /// Joint limits in internal units (infinite where there are none).
    fn bounds(&self) -> Vec<(f64, f64)> {
        self.axes
            .iter()
            .map(|a| {
                let limited = a.rotary == RotaryMode::Limited;
                let lo = a.min.filter(|_| limited).unwrap_or(f64::NEG_INFINITY);
                let hi = a.max.filter(|_| limited).unwrap_or(f64::INFINITY);
                match a.kind {
                    JointKind::Prismatic => (lo, hi),
                    JointKind::Revolute => (lo.to_radians(), hi.to_radians()),
                }
            })
            .collect()
    }

    fn unwind(&self, q: &mut [f64], reference: &[f64]) {
        for &j in &self.revolutes {
            q[j] = choose_turn(&self.axes[j], q[j], reference[j]);
        }
    }

    /// With the rotary joints of `q` fixed, sets its prismatic joints so that
    /// the tip meets `target` (least squares when there are fewer than 3);
    /// returns the pose with the linear axes at 0 (whose tool axis is that
    /// of the solution: linear axes turn nothing).
    fn solve_prismatics(&self, q: &mut [f64], target: &Pose) -> Result<Pose, IkError> {
        for &j in &self.prismatics {
            q[j] = 0.0;
        }
        let mut dirs = [[0.0; 3]; super::chain::MAX_JOINTS];
        let p0 = self.chain.pose_and_prismatic_directions(q, &mut dirs);
        let b = target.tip - p0.tip;
        let dependent = || IkError::Unreachable {
            reason: "the linear axes are dependent at these rotary positions".into(),
        };
        let failed = |e: &str| IkError::Unreachable {
            reason: format!("linear solve failed: {e}"),
        };
        // Well-conditioned linear axes (every real machine): a least-squares
        // solve by Gram–Schmidt QR on the stack.
        if let Some(x) = gram_schmidt_solve(&dirs, &self.prismatics, &b) {
            for (c, &j) in self.prismatics.iter().enumerate() {
                q[j] = x[c];
            }
            return Ok(p0);
        }
        // Otherwise (nearly dependent axes, other counts): by SVD, which
        // also decides whether the axes are dependent.
        let m = self.prismatics.len();
        let a = DMatrix::from_fn(3, m, |r, c| dirs[self.prismatics[c]][r]);
        // nalgebra's SVD panics on a NaN; one comes from an overflow far
        // beyond any travel (a work offset of 1e155 mm squared).
        if !(a.iter().all(|v| v.is_finite()) && b.iter().all(|v| v.is_finite())) {
            return Err(IkError::Unreachable {
                reason: "the pose is beyond any machine's travel: its arithmetic overflows".into(),
            });
        }
        let b = DVector::from_column_slice(b.as_slice());
        let svd = a.svd(true, true);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        if smin.is_nan() || smin <= crate::linalg::rank::DEPENDENT_AXES * smax.max(1.0) {
            return Err(dependent());
        }
        let x = svd.solve(&b, 0.0).map_err(failed)?;
        for (c, &j) in self.prismatics.iter().enumerate() {
            q[j] = x[c];
        }
        Ok(p0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::rotation3;
    use nalgebra::Unit;

    fn solver(name: &str) -> (Machine, IkSolver) {
        let m = Machine::embedded(name).unwrap();
        let s = IkSolver::new(&m);
        (m, s)
    }

    #[test]
    fn families_are_recognised_from_structure() {
        for (name, fam) in [
            ("zhao2022-xzbc", Family::FourAxisRTTR),
            ("wang2023-xyzab", Family::FiveAxis2R3T),
            ("xyzac-trt", Family::FiveAxis2R3T),
            ("xyzbc-trt", Family::FiveAxis2R3T),
            ("xyzac-head", Family::FiveAxis2R3T),
            ("xyzbc-nutating", Family::FiveAxis2R3T),
            ("xyza-4axis", Family::FourAxis1R3T),
            ("xyz-3axis", Family::ThreeAxis),
        ] {
            assert_eq!(solver(name).1.family(), fam, "{name}");
        }
    }

    #[test]
    fn subproblem2_solves_orthogonal_axes() {
        let k1 = Vector3::new(0.0, 0.0, -1.0);
        let k2 = Vector3::new(-1.0, 0.0, 0.0);
        let p = Vector3::z();
        let (a, c) = (0.4f64, 1.1f64);
        let q = rotation3(&Unit::new_unchecked(k1), c) * rotation3(&Unit::new_unchecked(k2), a) * p;
        let sols = subproblem2(&k1, &k2, &p, &q);
        assert_eq!(sols.len(), 2);
        for (t1, t2) in sols {
            let r = rotation3(&Unit::new_unchecked(k1), t1)
                * rotation3(&Unit::new_unchecked(k2), t2)
                * p;
            assert!((r - q).norm() < 1e-14);
        }
    }

    #[test]
    fn zhao_round_trip_and_both_branches() {
        let (m, s) = solver("zhao2022-xzbc");
        let q = m.to_internal(&[30.0, -12.0, 25.0, 40.0]);
        let pose = m.chain.pose(&q, &NoErrors);
        let sol = s.solve(&pose, Some(&q)).unwrap();
        for (a, b) in sol.q.iter().zip(&q) {
            assert!((a - b).abs() < 1e-12, "{:?} vs {:?}", sol.q, q);
        }
        let br = s.branches(&pose, Some(&q));
        assert_eq!(br.len(), 2);
        for b in &br {
            let p = m.chain.pose(&b.q, &NoErrors);
            assert!(p.tip_distance(&pose) < 1e-12 && p.axis_angle(&pose) < 1e-12);
        }
    }
}
