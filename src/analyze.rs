//! `kinpost analyze`: how far the tool would miss each pose on the actual
//! machine, and which error term is to blame.
//!
//! The theoretical axes (analytic IK of the error-free chain) are driven
//! through the error-aware chain (the same chain evaluator with the fitted
//! error motions and the fixed error elements). Per pose:
//! `E = |Pe − Pi|` (tool tip, mm) and `ε = ∠(Oe, Oi)` (tool axis, rad; seed
//! 000's `acos(Oe·Oi)`, computed with atan2 for accuracy at small angles).
//! Contributions: each error term alone (all others zero) driven through the
//! chain, exactly, not linearised.

use crate::error::Result;
use crate::geometric::model::ErrorModel;
use crate::geometric::table::Component;
use crate::machine::chain::{Chain, ErrorMotion, JointErrors, NoErrors, Pose};
use crate::machine::{IkSolver, Machine};
use serde::Serialize;

/// Arc seconds per radian.
pub const ARCSEC_PER_RAD: f64 = 180.0 * 3600.0 / std::f64::consts::PI;

/// One error term of one axis, alone.
struct OnlyTerm<'a> {
    inner: &'a dyn JointErrors,
    joint: usize,
    component: usize,
}

impl JointErrors for OnlyTerm<'_> {
    fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
        if joint != self.joint {
            return None;
        }
        let e = self.inner.error(joint, q)?;
        let mut only = ErrorMotion::zeros();
        only[self.component] = e[self.component];
        Some(only)
    }
}

/// Per-block result.
#[derive(Debug, Clone, Serialize)]
pub struct BlockResult {
    /// 1-based line of the block.
    pub line: usize,
    /// Tool-tip error E, mm.
    pub tip_error_mm: f64,
    /// Tool-tip error vector (actual − programmed), mm, workpiece frame.
    pub tip_error_vector_mm: [f64; 3],
    /// Orientation error ε, µrad.
    pub orientation_error_urad: f64,
    /// Theoretical axis values, output order, mm / deg.
    pub axes: Vec<f64>,
}

/// Summary over the program.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Poses analysed.
    pub poses: usize,
    /// Largest tool-tip error, mm.
    pub tip_error_max_mm: f64,
    /// RMS tool-tip error, mm.
    pub tip_error_rms_mm: f64,
    /// Line of the largest tool-tip error.
    pub tip_error_max_line: usize,
    /// Largest orientation error, µrad.
    pub orientation_error_max_urad: f64,
    /// RMS orientation error, µrad.
    pub orientation_error_rms_urad: f64,
    /// Largest orientation error, arcsec.
    pub orientation_error_max_arcsec: f64,
    /// Line of the largest orientation error.
    pub orientation_error_max_line: usize,
}

/// How much one error term causes.
#[derive(Debug, Clone, Serialize)]
pub struct Contribution {
    /// Axis letter.
    pub axis: String,
    /// Error term name (ISO 230-1 / controller table style), e.g. `EXX`, or
    /// the name of a fixed error element.
    pub term: String,
    /// Largest tool-tip error caused by this term alone, mm.
    pub tip_error_max_mm: f64,
    /// RMS tool-tip error caused by this term alone, mm.
    pub tip_error_rms_mm: f64,
    /// Largest orientation error caused by this term alone, µrad.
    pub orientation_error_max_urad: f64,
    /// Share of the total mean-square tool-tip error, % (terms interact, so
    /// shares need not add to exactly 100).
    pub share_percent: f64,
}

/// The whole analysis.
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    /// Machine name.
    pub machine: String,
    /// Summary.
    pub summary: Summary,
    /// Per-block results in program order.
    pub blocks: Vec<BlockResult>,
    /// Contributions, largest RMS first.
    pub contributions: Vec<Contribution>,
}

/// Name of the term for component `c` of axis `axis` (`EXX`, `EBZ`, …).
pub fn term_name(c: Component, axis: &str) -> String {
    format!("E{}{}", c.letter(), axis)
}

/// Accumulates the analysis pose by pose.
pub struct Analyzer<'a> {
    machine: &'a Machine,
    actual_chain: Chain,
    errors: &'a dyn JointErrors,
    terms: Vec<(String, String, usize, usize)>,
    fixed_chains: Vec<(String, Chain)>,
    solver: IkSolver,
    previous: Option<Vec<f64>>,
    /// The per-block results, when they are kept ([`Analyzer::keep_blocks`]).
    blocks: Vec<BlockResult>,
    keep_blocks: bool,
    /// The summary so far (its RMS fields hold sums of squares until
    /// [`Analyzer::finish`]).
    summary: Summary,
    term_stats: Vec<(f64, f64, f64)>,
    fixed_stats: Vec<(f64, f64, f64)>,
}

impl<'a> Analyzer<'a> {
    /// An analyzer for `machine` with the error model `model` bound as `errors`.
    pub fn new(
        machine: &'a Machine,
        model: &ErrorModel,
        errors: &'a dyn JointErrors,
    ) -> Result<Self> {
        let actual_chain = model.apply_fixed(&machine.chain)?;
        let mut terms = Vec::new();
        for a in &model.axes {
            if let Some(j) = machine.chain.joint_index(&a.axis) {
                for col in &a.columns {
                    let c = col.component;
                    terms.push((a.axis.clone(), term_name(c, &a.axis), j, c.index()));
                }
            }
        }
        let mut fixed_chains = Vec::new();
        for f in &model.fixed {
            fixed_chains.push((f.name.clone(), f.apply(&machine.chain)?));
        }
        let n_terms = terms.len();
        let n_fixed = fixed_chains.len();
        Ok(Analyzer {
            machine,
            actual_chain,
            errors,
            terms,
            fixed_chains,
            solver: IkSolver::new(machine),
            previous: None,
            blocks: Vec::new(),
            keep_blocks: true,
            summary: Summary {
                poses: 0,
                tip_error_max_mm: 0.0,
                tip_error_rms_mm: 0.0,
                tip_error_max_line: 0,
                orientation_error_max_urad: 0.0,
                orientation_error_rms_urad: 0.0,
                orientation_error_max_arcsec: 0.0,
                orientation_error_max_line: 0,
            },
            term_stats: vec![(0.0, 0.0, 0.0); n_terms],
            fixed_stats: vec![(0.0, 0.0, 0.0); n_fixed],
        })
    }

    /// Whether the per-block results are kept for [`Analysis::blocks`]
    /// (default); without them memory does not grow with the program and
    /// the blocks of the analysis are empty.
    pub fn keep_blocks(mut self, keep: bool) -> Self {
        self.keep_blocks = keep;
        self
    }

    /// Analyses one programmed pose at `line`; returns its result (kept
    /// too when [`Analyzer::keep_blocks`]).
    pub fn add(&mut self, line: usize, target: &Pose) -> std::result::Result<BlockResult, String> {
        let sol = self
            .solver
            .solve(target, self.previous.as_deref())
            .map_err(|e| e.to_string())?;
        let q = sol.q;
        // Contributions are measured against what the theoretical machine does
        // at these axes (the target, up to a four-axis machine's cone miss).
        let ideal = self.machine.chain.pose(&q, &NoErrors);
        let actual = self.actual_chain.pose(&q, self.errors);
        // Seed 000's E and ε are against the designed pose.
        let d = actual.tip - target.tip;
        let b = BlockResult {
            line,
            tip_error_mm: d.norm(),
            tip_error_vector_mm: [d.x, d.y, d.z],
            orientation_error_urad: actual.axis_angle(target) * 1e6,
            axes: self.machine.to_external(&q).to_vec(),
        };
        let s = &mut self.summary;
        s.poses += 1;
        s.tip_error_rms_mm += b.tip_error_mm * b.tip_error_mm;
        s.orientation_error_rms_urad += b.orientation_error_urad * b.orientation_error_urad;
        if b.tip_error_mm > s.tip_error_max_mm || s.tip_error_max_line == 0 {
            s.tip_error_max_mm = b.tip_error_mm;
            s.tip_error_max_line = b.line;
        }
        if b.orientation_error_urad > s.orientation_error_max_urad
            || s.orientation_error_max_line == 0
        {
            s.orientation_error_max_urad = b.orientation_error_urad;
            s.orientation_error_max_line = b.line;
        }
        if self.keep_blocks {
            self.blocks.push(b.clone());
        }
        for (k, (_, _, joint, component)) in self.terms.iter().enumerate() {
            let only = OnlyTerm {
                inner: self.errors,
                joint: *joint,
                component: *component,
            };
            let p = self.machine.chain.pose(&q, &only);
            let e = p.tip_distance(&ideal);
            let s = &mut self.term_stats[k];
            s.0 = s.0.max(e);
            s.1 += e * e;
            s.2 = s.2.max(p.axis_angle(&ideal) * 1e6);
        }
        for (k, (_, chain)) in self.fixed_chains.iter().enumerate() {
            let p = chain.pose(&q, &NoErrors);
            let e = p.tip_distance(&ideal);
            let s = &mut self.fixed_stats[k];
            s.0 = s.0.max(e);
            s.1 += e * e;
            s.2 = s.2.max(p.axis_angle(&ideal) * 1e6);
        }
        self.previous = Some(q.to_vec());
        Ok(b)
    }

    /// Finishes the analysis.
    pub fn finish(self) -> Analysis {
        let mut s = self.summary;
        let n = s.poses.max(1) as f64;
        let (se, so) = (s.tip_error_rms_mm, s.orientation_error_rms_urad);
        s.tip_error_rms_mm = (se / n).sqrt();
        s.orientation_error_rms_urad = (so / n).sqrt();
        s.orientation_error_max_arcsec = s.orientation_error_max_urad * 1e-6 * ARCSEC_PER_RAD;
        let total_ms = se / n;
        let share = |sum_sq: f64| {
            if total_ms > 0.0 {
                100.0 * (sum_sq / n) / total_ms
            } else {
                0.0
            }
        };
        let mut contributions: Vec<Contribution> = self
            .terms
            .iter()
            .zip(&self.term_stats)
            .map(|((axis, term, _, _), st)| Contribution {
                axis: axis.clone(),
                term: term.clone(),
                tip_error_max_mm: st.0,
                tip_error_rms_mm: (st.1 / n).sqrt(),
                orientation_error_max_urad: st.2,
                share_percent: share(st.1),
            })
            .chain(
                self.fixed_chains
                    .iter()
                    .zip(&self.fixed_stats)
                    .map(|((name, _), st)| Contribution {
                        axis: String::new(),
                        term: name.clone(),
                        tip_error_max_mm: st.0,
                        tip_error_rms_mm: (st.1 / n).sqrt(),
                        orientation_error_max_urad: st.2,
                        share_percent: share(st.1),
                    }),
            )
            .collect();
        contributions.sort_by(|a, b| b.tip_error_rms_mm.total_cmp(&a.tip_error_rms_mm));
        Analysis {
            machine: self.machine.name.clone(),
            summary: s,
            blocks: self.blocks,
            contributions,
        }
    }
}

impl Analysis {
    /// The report as JSON.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }

    /// A report a person can read (units on every number).
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let s = &self.summary;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "kinpost analyze — machine {}, {} poses",
            self.machine, s.poses
        );
        let _ = writeln!(t, "theoretical axes driven through the error-aware chain");
        let _ = writeln!(
            t,
            "  tool-tip error E:      max {:.4} µm (line {}), RMS {:.4} µm",
            s.tip_error_max_mm * 1e3,
            s.tip_error_max_line,
            s.tip_error_rms_mm * 1e3
        );
        let _ = writeln!(
            t,
            "  orientation error ε:   max {:.4} µrad = {:.4} arcsec (line {}), RMS {:.4} µrad",
            s.orientation_error_max_urad,
            s.orientation_error_max_arcsec,
            s.orientation_error_max_line,
            s.orientation_error_rms_urad
        );
        let _ = writeln!(t, "contributions (each term alone through the chain):");
        let _ = writeln!(
            t,
            "  {:<18} {:>12} {:>12} {:>14} {:>8}",
            "term", "max E µm", "RMS E µm", "max ε µrad", "share %"
        );
        for c in &self.contributions {
            let _ = writeln!(
                t,
                "  {:<18} {:>12.4} {:>12.4} {:>14.4} {:>8.1}",
                c.term,
                c.tip_error_max_mm * 1e3,
                c.tip_error_rms_mm * 1e3,
                c.orientation_error_max_urad,
                c.share_percent
            );
        }
        t
    }
}
