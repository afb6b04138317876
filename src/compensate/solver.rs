//! The compensating solver: the theoretical IK, the refinement, and the
//! failure policy (error, theoretical axes, best within bounds), backlash
//! pre-compensation and the per-block record.

use super::refine::{Refined, refine};
use super::step::{Method, Options};
use super::written::{Written, written_residual};
use crate::machine::chain::{Chain, JointErrors, JointValues, Pose};

/// Per-block record of a compensation run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BlockRecord {
    /// 1-based line of the block.
    pub line: usize,
    /// Newton iterations.
    pub iterations: usize,
    /// Tool-tip error before compensation (theoretical axes on the actual machine), mm.
    pub tip_error_before_mm: f64,
    /// Remaining tool-tip error after compensation, mm.
    pub tip_residual_mm: f64,
    /// Orientation error before compensation, µrad.
    pub orientation_error_before_urad: f64,
    /// Remaining orientation error after compensation, µrad.
    pub orientation_residual_urad: f64,
    /// Tool-tip error of the axis words as written (rounded to their
    /// decimals), mm: what the machine really gets.
    pub tip_residual_written_mm: f64,
    /// Orientation error of the axis words as written, µrad.
    pub orientation_residual_written_urad: f64,
    /// The two errors as written are upper bounds, not values: without
    /// [`CompensatingSolver::written_per_block`] a block whose bounds lie
    /// below the largest errors as written so far is not evaluated (it
    /// cannot change them).
    #[serde(skip)]
    pub written_is_bound: bool,
    /// Compensation per axis (compensated − theoretical), output order, mm / deg.
    pub compensation: JointValues,
}

/// What to do with a block that does not converge or breaks a limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnFail {
    /// Stop with an error naming the line (default).
    Error,
    /// Keep the theoretical axes for that block and warn.
    Theoretical,
    /// Keep the best compensation found within bounds and warn.
    Best,
}

/// A [`crate::post::PoseSolver`] that starts from the analytic IK and refines
/// on the error-aware chain.
pub struct CompensatingSolver<'a> {
    /// The machine (theoretical chain, axes, limits).
    pub machine: &'a crate::machine::Machine,
    /// The actual chain (fixed error elements inserted).
    pub actual_chain: Chain,
    /// Position-dependent errors (shared with worker threads).
    pub errors: &'a (dyn JointErrors + Sync),
    /// Analytic IK of the theoretical machine.
    pub ik: crate::machine::IkSolver,
    /// Refinement options.
    pub options: Options,
    /// Policy for failing blocks.
    pub on_fail: OnFail,
    /// Tip tolerance that counts as converged for the policy, mm.
    pub accept_tip_mm: f64,
    /// Largest tool-axis miss of the theoretical solution accepted (a
    /// four-axis machine off its cone), rad; as `post`'s.
    pub axis_tolerance_rad: f64,
    /// Records, one per block.
    pub records: Vec<BlockRecord>,
    /// Warnings.
    pub warnings: Vec<String>,
    /// Decimals of the written axis words, output order (the machine's or
    /// `--decimals`): the miss of the values as written is reported beside
    /// that of the solution. Empty: not rounded.
    pub decimals: Vec<u32>,
    /// Blocks at a singularity where the best compensation within bounds
    /// was kept with a tool-tip residual above `accept_tip_mm`.
    pub singular_blocks: usize,
    /// Backlash to pre-compensate: (joint, reversal value in mm / rad).
    pub backlash: Vec<(usize, f64)>,
    /// Work out every block's errors as written (a report lists them).
    /// Otherwise only the largest are exact: a block whose upper bounds
    /// from the refinement's first-order estimate lie below the largest
    /// so far keeps the bounds (`BlockRecord::written_is_bound`).
    pub written_per_block: bool,
    /// The largest tool-tip (mm) and tool-axis (rad) errors as written so
    /// far, evaluated (start at 0).
    pub written_largest: (f64, f64),
    /// Direction of the last motion of each joint in `backlash`, by the
    /// rule `diagnose` and `simulate` use (a reversal counts once the axis
    /// is back by more than the dead band); filled on the first block.
    pub directions: Vec<crate::geometric::effects::DirectionTracker>,
}

impl CompensatingSolver<'_> {
    /// Backlash of the model's diagnosed effects, for pre-compensation, and
    /// a warning for the dynamic effects a block-wise post cannot apply.
    pub fn dynamic_effects(
        model: &crate::geometric::model::ErrorModel,
        chain: &Chain,
    ) -> (Vec<(usize, f64)>, Vec<String>) {
        use crate::geometric::effects::Effect;
        let mut backlash = Vec::new();
        let mut warnings = Vec::new();
        for e in &model.effects {
            match &e.effect {
                Effect::Backlash { axis, value } => {
                    if let Some(j) = chain.joint_index(axis) {
                        let v = if chain.joints()[j].kind == crate::machine::chain::JointKind::Revolute {
                            value.to_radians()
                        } else {
                            *value
                        };
                        backlash.push((j, v));
                    }
                }
                Effect::ServoLag { axis, .. }
                | Effect::ThermalDrift { axis, .. }
                | Effect::Vibration { axis, .. } => warnings.push(format!(
                    "the model's {} of {axis} depends on speed or time along the run; compensate does not apply it (it is a controller feed-forward or a thermal model's job)",
                    e.effect.kind().name()
                )),
                _ => {}
            }
        }
        (backlash, warnings)
    }
}

impl crate::post::PoseSolver for CompensatingSolver<'_> {
    fn solve(
        &mut self,
        pose: &Pose,
        previous: Option<&[f64]>,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        let th = self.theoretical(pose, previous)?;
        let r = self.refine_block(pose, &th);
        self.commit(pose, &th, &r, None, line)
    }
}

/// The analytic IK of `machine` (by `ik`) for `pose`, continuing from
/// `previous`; a tool axis missed by more than `axis_tolerance_rad` is
/// refused (a four-axis machine off its cone), as by `post`.
pub fn theoretical(
    ik: &crate::machine::IkSolver,
    machine: &crate::machine::Machine,
    axis_tolerance_rad: f64,
    pose: &Pose,
    previous: Option<&[f64]>,
) -> std::result::Result<JointValues, String> {
    let s = ik.solve(pose, previous).map_err(|e| e.to_string())?;
    if s.axis_miss_rad > axis_tolerance_rad {
        return Err(crate::post::unreachable_axis(
            &machine.name,
            s.axis_miss_rad,
            axis_tolerance_rad,
        ));
    }
    Ok(s.q)
}

impl CompensatingSolver<'_> {
    /// Stage 1 of [`crate::post::PoseSolver::solve`] (in block order): the
    /// analytic IK of the theoretical machine, continuing from `previous`.
    pub fn theoretical(
        &self,
        pose: &Pose,
        previous: Option<&[f64]>,
    ) -> std::result::Result<JointValues, String> {
        theoretical(
            &self.ik,
            self.machine,
            self.axis_tolerance_rad,
            pose,
            previous,
        )
    }

    /// Stage 2 (independent per block, any thread): the Newton refinement
    /// from the theoretical joint values `th`.
    pub fn refine_block(&self, pose: &Pose, th: &[f64]) -> Refined {
        refine(&self.actual_chain, self.errors, pose, th, &self.options)
    }

    /// Stage 3 (in block order): the failure policy, backlash
    /// pre-compensation and the block's record.
    pub fn commit(
        &mut self,
        pose: &Pose,
        th: &JointValues,
        r: &Refined,
        written: Option<Written>,
        line: usize,
    ) -> std::result::Result<crate::post::SolvedPose, String> {
        // A tip within the accepted residual is met, whether or not the
        // tool axis had settled. Where the machine is singular, the best
        // compensation within bounds is kept, and said.
        let singular = r.best_within_bounds && r.tip_residual_mm <= r.start_tip_mm;
        // The paper's step stops where its least squares balances tip and
        // axis (picometres of tip on a four-axis machine): that point is
        // its answer, whatever the tip tolerance.
        let paper_fixed_point = r.converged && self.options.method == Method::Paper;
        let failure = if r.tip_residual_mm > self.accept_tip_mm && !singular && !paper_fixed_point {
            Some(format!(
                "compensation did not converge: tool-tip residual {:.3e} mm after {} iterations, more than the accepted {:.1e} mm",
                r.tip_residual_mm, r.iterations, self.accept_tip_mm
            ))
        } else if self.ik.within_all_limits(&r.q) {
            if r.tip_residual_mm > self.accept_tip_mm && !paper_fixed_point {
                self.singular_blocks += 1;
                self.warnings.push(format!(
                    "line {line}: the machine is singular here (for a four-axis lens machine: the tool tip on or next to the C axis); {:.4} µm of the {:.4} µm tool-tip error lie where no move within the compensation bounds reaches; the best compensation is kept",
                    r.tip_residual_mm * 1e3,
                    r.start_tip_mm * 1e3
                ));
            }
            None
        } else {
            self.ik
                .check_limits(&r.q)
                .err()
                .map(|e| format!("compensated axes break a limit: {e}"))
        };
        let q = match failure {
            None => r.q.clone(),
            Some(msg) => match self.on_fail {
                OnFail::Error => return Err(msg),
                OnFail::Theoretical => {
                    self.warnings
                        .push(format!("line {line}: {msg}; theoretical axes kept"));
                    th.clone()
                }
                OnFail::Best if self.ik.within_all_limits(&r.q) => {
                    self.warnings.push(format!(
                        "line {line}: {msg}; best compensation within bounds kept"
                    ));
                    r.q.clone()
                }
                OnFail::Best => {
                    self.warnings.push(format!(
                        "line {line}: {msg}; theoretical axes kept (limits)"
                    ));
                    th.clone()
                }
            },
        };
        // Backlash: the axis lags its command by value/2 against the direction
        // of its last motion, so command value/2 further in that direction.
        // Where the machine really goes (after its backlash): what the record reports.
        let (after_tip, after_axis) = if q == r.q {
            (r.tip_residual_mm, r.axis_residual_rad)
        } else {
            let after = self.actual_chain.pose(&q, self.errors);
            (after.tip_distance(pose), after.axis_angle(pose))
        };
        // The direction is that of the commanded targets, in the units of the
        // program (mm, degrees), with the dead band of the effect catalogue.
        let mut q = q;
        if self.directions.len() != self.backlash.len() {
            use crate::geometric::effects::{DIRECTION_DEAD_BAND, DirectionTracker};
            self.directions = vec![DirectionTracker::new(DIRECTION_DEAD_BAND); self.backlash.len()];
        }
        let mut lag = [0.0; crate::machine::chain::MAX_JOINTS];
        for (k, &(j, value)) in self.backlash.iter().enumerate() {
            let revolute =
                self.machine.chain.joints()[j].kind == crate::machine::chain::JointKind::Revolute;
            let file_units = if revolute { q[j].to_degrees() } else { q[j] };
            lag[j] = 0.5 * value * self.directions[k].update(file_units);
            q[j] += lag[j];
        }
        // Where the machine goes with the words as written: rounded to their
        // decimals, less the backlash it lags by.
        let mut written_is_bound = false;
        let (written_tip, written_axis) = if self.decimals.is_empty() {
            (after_tip, after_axis)
        } else {
            // Worked out (or bounded) beside the refinement, for these very axes.
            let beside = written.filter(|_| q == r.q && lag.iter().all(|&l| l == 0.0));
            let largest = self.written_largest;
            let w = match beside {
                Some(Written::Exact(tip, axis)) => (tip, axis),
                Some(Written::Bound(tip, axis))
                    if !self.written_per_block && tip < largest.0 && axis < largest.1 =>
                {
                    written_is_bound = true;
                    (tip, axis)
                }
                // As beside the refinement, near the theoretical solution.
                Some(Written::Bound(..)) => written_residual(
                    self.machine,
                    &self.actual_chain,
                    self.errors,
                    &self.decimals,
                    pose,
                    &r.q,
                    &[],
                    Some(&self.actual_chain.trig_at(th)),
                ),
                None => written_residual(
                    self.machine,
                    &self.actual_chain,
                    self.errors,
                    &self.decimals,
                    pose,
                    &q,
                    &lag,
                    None,
                ),
            };
            if !written_is_bound {
                self.written_largest = (largest.0.max(w.0), largest.1.max(w.1));
            }
            w
        };
        let ext_c = self.machine.to_external(&q);
        let ext_t = self.machine.to_external(th);
        self.records.push(BlockRecord {
            line,
            iterations: r.iterations,
            tip_error_before_mm: r.start_tip_mm,
            tip_residual_mm: after_tip,
            orientation_error_before_urad: r.start_axis_rad * 1e6,
            orientation_residual_urad: after_axis * 1e6,
            tip_residual_written_mm: written_tip,
            orientation_residual_written_urad: written_axis * 1e6,
            written_is_bound,
            compensation: ext_c
                .iter()
                .zip(&ext_t)
                .zip(&self.machine.axes)
                .map(|((c, t), a)| {
                    let d = c - t;
                    if a.rotary == crate::machine::RotaryMode::Modulo {
                        (d + 180.0).rem_euclid(360.0) - 180.0
                    } else {
                        d
                    }
                })
                .collect(),
        });
        Ok(crate::post::SolvedPose {
            axis_miss_rad: 0.0,
            q,
            theoretical: Some(th.clone()),
        })
    }
}
