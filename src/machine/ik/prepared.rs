//! The inverse kinematics in two parts: a pose's branches, which do not
//! depend on the block before and may be found on any thread
//! ([`IkSolver::prepare`]: the subproblems' trigonometry and the linear
//! axes of the branch likely to be chosen), and the choice among them,
//! which needs the block before and runs in order ([`IkSolver::choose`]:
//! unwinding, limits, distance, and the other branch's linear axes where
//! the choice needs them). The two give exactly what [`IkSolver::solve`]
//! gives: the same arithmetic on the same angles (a branch's linear axes
//! are found at the rotary angles of the enumeration, before they are
//! unwound, in both), chosen by the same rule.
//!
//! The branch likely to be chosen is the one chosen last
//! ([`BranchHint`]): along a path the choice keeps to one branch of the
//! enumeration, so `choose` seldom completes a branch itself. Which branch
//! `prepare` completes never changes what `choose` gives, only where the
//! work is done. (Completing the nearer branch in order, without a guess,
//! was measured slower on two cores; completing both in `prepare` costs a
//! linear solve a pose that is then thrown away: `docs/performance.md`.)

use super::*;
use std::sync::atomic::{AtomicU8, Ordering};

/// The branch of the enumeration [`IkSolver::choose`] chose last, shared
/// by the threads that prepare poses and the one that chooses: a guess of
/// the branch the next poses will be given, and nothing else (a wrong or
/// stale guess costs one linear solve in order, never a different
/// answer).
#[derive(Debug, Default)]
pub(super) struct BranchHint(AtomicU8);

impl BranchHint {
    /// No branch chosen yet: `prepare` completes every branch.
    const NONE: u8 = u8::MAX;

    fn get(&self) -> Option<u8> {
        Some(self.0.load(Ordering::Relaxed)).filter(|&b| b != Self::NONE)
    }

    /// Notes `branch` as chosen; written only when it changes, so that the
    /// threads reading it keep their copy.
    fn set(&self, branch: u8) {
        if self.0.load(Ordering::Relaxed) != branch {
            self.0.store(branch, Ordering::Relaxed);
        }
    }
}

impl Clone for BranchHint {
    fn clone(&self) -> Self {
        BranchHint(AtomicU8::new(self.0.load(Ordering::Relaxed)))
    }
}

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
    /// Every branch's rotaries, and the linear axes of those completed
    /// (their rotaries not yet unwound; a branch whose linear axes could
    /// not be solved holds its error).
    Branches {
        raws: RawBranches,
        completed: [Option<Result<IkSolution, IkError>>; MAX_BRANCHES],
    },
    /// An RTTR machine's two first-rotary angles, and of their branches
    /// only the one guessed (its second rotary and linear axes; the other
    /// branch's second rotary costs a subproblem, left to `choose`).
    Rttr {
        angles: orient::RttrAngles,
        guessed: Raw,
        completed: Result<IkSolution, IkError>,
    },
}

impl IkSolver {
    /// The branches of `pose`, found without the block before where they
    /// do not depend on it: any thread may prepare the poses of a program,
    /// and [`IkSolver::choose`] then picks, in order, what
    /// [`IkSolver::solve`] would. Of two branches only the one chosen last
    /// is completed (both before the first choice).
    pub fn prepare(&self, pose: &Pose) -> PreparedPose {
        self.prepare_guessing(pose, self.last_chosen.get())
    }

    /// [`IkSolver::prepare`] completing branch `guess` alone (every branch
    /// with `None`, or where `guess` is not one of them).
    fn prepare_guessing(&self, pose: &Pose, guess: Option<u8>) -> PreparedPose {
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
                Some(a) if a.count == 2 && guess.is_some_and(|g| g < 2) => {
                    let g = usize::from(guess.unwrap_or(0));
                    let guessed = self.rttr_branch(&a, g, &zeros);
                    if guessed.singular {
                        return PreparedPose(Prepared::InOrder);
                    }
                    let completed = self.complete(&guessed, &target);
                    return PreparedPose(Prepared::Rttr {
                        angles: a,
                        guessed,
                        completed,
                    });
                }
                Some(a) => (0..a.count)
                    .map(|b| self.rttr_branch(&a, b, &zeros))
                    .collect(),
                None => RawBranches::new(),
            },
        };
        if raws.is_empty() || raws.iter().any(|r| r.singular) {
            return PreparedPose(Prepared::InOrder);
        }
        let only = guess.filter(|&g| raws.len() == 2 && raws.iter().any(|r| r.branch == g));
        let mut completed = [None, None];
        for (slot, raw) in completed.iter_mut().zip(&raws) {
            if only.is_none_or(|g| raw.branch == g) {
                *slot = Some(self.complete(raw, &target));
            }
        }
        PreparedPose(Prepared::Branches { raws, completed })
    }

    /// The solution of a pose `prepared` by [`IkSolver::prepare`],
    /// continuing from `previous`: what [`IkSolver::solve`] gives for it.
    pub fn choose(
        &self,
        pose: &Pose,
        prepared: &PreparedPose,
        previous: Option<&[f64]>,
    ) -> Result<IkSolution, IkError> {
        let chosen = match &prepared.0 {
            Prepared::Refused(e) => Err(e.clone()),
            Prepared::InOrder => self.solve(pose, previous),
            Prepared::Branches { raws, completed } => {
                self.choose_among(pose, raws, completed, previous)
            }
            Prepared::Rttr {
                angles,
                guessed,
                completed,
            } => self.choose_rttr(pose, angles, guessed, completed, previous),
        };
        if let Ok(s) = &chosen {
            self.last_chosen.set(s.branch);
        }
        chosen
    }

    /// [`IkSolver::choose`] for a pose with branches: those `completed`
    /// unwound, the others completed where the choice needs them.
    fn choose_among(
        &self,
        pose: &Pose,
        raws: &RawBranches,
        completed: &[Option<Result<IkSolution, IkError>>; MAX_BRANCHES],
        previous: Option<&[f64]>,
    ) -> Result<IkSolution, IkError> {
        let reference = self.reference(previous);
        let done = completed.clone().map(|slot| {
            slot.map(|branch| {
                branch.map(|mut s| {
                    self.unwind(&mut s.q, &reference);
                    s
                })
            })
        });
        let target = Pose::new(pose.tip, pose.axis);
        let cands = self.complete_branches(raws, done, &target, &reference, true)?;
        self.select(cands, previous)
    }

    /// [`IkSolver::choose`] for an RTTR pose with one branch found: that
    /// one where it is certainly the choice (bounding the other's distance
    /// by its first rotary, as [`IkSolver::solve`] does), else both.
    fn choose_rttr(
        &self,
        pose: &Pose,
        angles: &orient::RttrAngles,
        guessed: &Raw,
        completed: &Result<IkSolution, IkError>,
        previous: Option<&[f64]>,
    ) -> Result<IkSolution, IkError> {
        let reference = self.reference(previous);
        let g = usize::from(guessed.branch);
        let other = 1 - g;
        let unwound = completed.clone().map(|mut s| {
            self.unwind(&mut s.q, &reference);
            s
        });
        let done = match self.nearest(
            unwound,
            self.rttr_lower(angles, other, &reference),
            &reference,
        ) {
            Ok(s) => return Ok(s),
            Err(sol) => sol,
        };
        // The other branch as `solve` finds it: at this reference (a second
        // rotary free there keeps its previous value).
        let raw_other = self.rttr_branch(angles, other, &reference);
        let mut raws = [guessed.clone(), raw_other];
        let mut slots = [Some(done), None];
        if g == 1 {
            raws.swap(0, 1);
            slots.swap(0, 1);
        }
        let target = Pose::new(pose.tip, pose.axis);
        let cands =
            self.complete_branches(&RawBranches::from(raws), slots, &target, &reference, false)?;
        self.select(cands, previous)
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
        let mut guessed = 0;
        let mut rttr = 0;
        for name in Machine::embedded_names() {
            let m = Machine::embedded(name).unwrap();
            let s = IkSolver::new(&m);
            let mut previous: Option<JointValues> = None;
            for q in cases(&m, &mut rng) {
                let pose = m.chain.pose(&q, &NoErrors);
                let whole = s.solve(&pose, previous.as_deref());
                // Whichever branch is completed first: none yet, the one
                // chosen, the other.
                for guess in [None, Some(0), Some(1)] {
                    let prepared = s.prepare_guessing(&pose, guess);
                    match &prepared.0 {
                        Prepared::InOrder => in_order += 1,
                        Prepared::Branches { completed, .. } => {
                            split += 1;
                            let n = completed.iter().flatten().count();
                            if guess.is_some() && n == 1 {
                                guessed += 1;
                            }
                        }
                        Prepared::Rttr { .. } => {
                            split += 1;
                            guessed += 1;
                            rttr += 1;
                        }
                        Prepared::Refused(_) => {}
                    }
                    let chosen = s.choose(&pose, &prepared, previous.as_deref());
                    assert_eq!(whole, chosen, "{name}: {q:?} after {previous:?}, {guess:?}");
                }
                // What `prepare` guesses is the branch chosen last.
                if let Ok(sol) = &whole {
                    assert_eq!(s.last_chosen.get(), Some(sol.branch));
                }
                if let Ok(sol) = whole {
                    previous = Some(sol.q);
                }
            }
        }
        assert!(
            split > 3000 && in_order > 150 && guessed > 2000 && rttr > 200,
            "{split} split, {in_order} in order, {guessed} with one branch completed ({rttr} RTTR)"
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
