//! The inverse kinematics in two parts: a pose's branches, which do not
//! depend on the block before and may be found on any thread
//! ([`IkSolver::prepare`]: the subproblems' trigonometry and every
//! branch's linear axes), and the choice among them, which needs the block
//! before and runs in order ([`IkSolver::choose`]: unwinding, limits,
//! distance). The two give exactly what [`IkSolver::solve`] gives: the same
//! arithmetic on the same angles (a branch's linear axes are found at the
//! rotary angles of the enumeration, before they are unwound, in both),
//! chosen by the same rule. (Completing both branches costs more in all than
//! `solve`'s completing the nearer one alone, but it leaves the part in
//! order a few comparisons; completing the nearer one in order was
//! measured slower on two cores: `docs/performance.md`.)

use super::*;

/// The order-free part of one pose's inverse kinematics
/// ([`IkSolver::prepare`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedPose(Prepared);

#[derive(Debug, Clone, PartialEq)]
enum Prepared {
    /// The pose is refused before any branch is computed.
    Refused(IkError),
    /// The branches depend on the block before (a rotary free at a singular
    /// pose keeps its previous value; the Newton family starts from it):
    /// solved whole, in order.
    InOrder,
    /// Every branch completed, its rotaries not yet unwound (a branch whose
    /// linear axes could not be solved holds its error).
    Branches(arrayvec::ArrayVec<Result<IkSolution, IkError>, MAX_BRANCHES>),
}

impl IkSolver {
    /// The branches of `pose`, found without the block before where they
    /// do not depend on it: any thread may prepare the poses of a program,
    /// and [`IkSolver::choose`] then picks, in order, what
    /// [`IkSolver::solve`] would.
    pub fn prepare(&self, pose: &Pose) -> PreparedPose {
        if let Err(e) = self.check_pose(pose) {
            return PreparedPose(Prepared::Refused(e));
        }
        let target = Pose::new(pose.tip, pose.axis);
        // Only a singular branch reads the reference (the free rotary keeps
        // its previous value): zeros stand in for it, and a singular branch
        // sends the pose to the in-order solve.
        let zeros = [0.0; crate::machine::chain::MAX_JOINTS];
        let raws: RawBranches = match self.family {
            Family::Generic => return PreparedPose(Prepared::InOrder),
            Family::ThreeAxis => RawBranches::from_iter([Raw::fixed()]),
            Family::FourAxis1R3T => self.orient_1r(&target, &zeros),
            Family::FiveAxis2R3T => self.orient_2r(&target, &zeros),
            Family::FourAxisRTTR => match self.rttr_angles(&target, &zeros) {
                Some(a) => (0..a.count)
                    .map(|b| self.rttr_branch(&a, b, &zeros))
                    .collect(),
                None => RawBranches::new(),
            },
        };
        if raws.is_empty() || raws.iter().any(|r| r.singular) {
            return PreparedPose(Prepared::InOrder);
        }
        PreparedPose(Prepared::Branches(
            raws.iter().map(|r| self.complete(r, &target)).collect(),
        ))
    }

    /// The solution of a pose `prepared` by [`IkSolver::prepare`],
    /// continuing from `previous`: what [`IkSolver::solve`] gives for it.
    pub fn choose(
        &self,
        pose: &Pose,
        prepared: &PreparedPose,
        previous: Option<&[f64]>,
    ) -> Result<IkSolution, IkError> {
        let completed = match &prepared.0 {
            Prepared::Refused(e) => return Err(e.clone()),
            Prepared::InOrder => return self.solve(pose, previous),
            Prepared::Branches(b) => b,
        };
        let reference = self.reference(previous);
        let mut cands = Branches::new();
        let mut last_err = None;
        for branch in completed {
            match branch {
                Ok(s) => {
                    let mut s = s.clone();
                    self.unwind(&mut s.q, &reference);
                    cands.push(s);
                }
                Err(e) => last_err = Some(e),
            }
        }
        match (cands.is_empty(), last_err) {
            (true, Some(e)) => Err(e.clone()),
            _ => self.select(cands, previous),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::JointValues;

    /// Joint values of every embedded machine, by a fixed generator, some
    /// rotaries thousands of degrees out and some poses singular.
    fn cases(m: &Machine, rng: &mut crate::test_support::Lcg) -> Vec<JointValues> {
        (0..300)
            .map(|k| {
                m.chain
                    .joints()
                    .iter()
                    .map(|j| {
                        let u = rng.signed();
                        match j.kind {
                            JointKind::Prismatic => 200.0 * u,
                            // Every tenth pose with its rotaries at 0: the
                            // singular tilt of most machines.
                            JointKind::Revolute if k % 10 == 0 => 0.0,
                            JointKind::Revolute => 40.0 * u,
                        }
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn prepare_then_choose_is_solve() {
        let mut rng = crate::test_support::Lcg(17);
        let mut in_order = 0;
        let mut split = 0;
        for name in Machine::embedded_names() {
            let m = Machine::embedded(name).unwrap();
            let s = IkSolver::new(&m);
            let mut previous: Option<JointValues> = None;
            for q in cases(&m, &mut rng) {
                let pose = m.chain.pose(&q, &NoErrors);
                let prepared = s.prepare(&pose);
                match &prepared.0 {
                    Prepared::InOrder => in_order += 1,
                    _ => split += 1,
                }
                let whole = s.solve(&pose, previous.as_deref());
                let chosen = s.choose(&pose, &prepared, previous.as_deref());
                assert_eq!(whole, chosen, "{name}: {q:?} after {previous:?}");
                if let Ok(sol) = whole {
                    previous = Some(sol.q);
                }
            }
        }
        assert!(
            split > 1000 && in_order > 50,
            "{split} split, {in_order} in order"
        );
    }

    #[test]
    fn a_refused_pose_is_refused_by_choose() {
        let m = Machine::embedded("zhao2022-xzbc").unwrap();
        let s = IkSolver::new(&m);
        let pose = Pose::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::z());
        let prepared = s.prepare(&pose);
        assert_eq!(
            s.choose(&pose, &prepared, None).unwrap_err(),
            s.solve(&pose, None).unwrap_err()
        );
    }
}
