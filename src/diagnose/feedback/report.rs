//! The report of a joint-feedback diagnosis: JSON in the shape of
//! `formats.md` §3, and text.

use std::collections::BTreeMap;

use serde::Serialize;

use super::super::report::{MeasurementFinding, Rejected, Where, param_text};
use crate::geometric::effects::EffectSpec;

/// One axis's figures in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisSummary {
    /// Axis letter.
    pub axis: String,
    /// `mm` or `deg`: the unit of this axis's figures.
    pub unit: String,
    /// Noise floor of `fb − command`.
    pub noise_floor: f64,
    /// RMS of `fb − command` before the fit.
    pub rms_before: f64,
    /// RMS after the fit.
    pub rms_after: f64,
    /// Held-out RMS before and after.
    pub holdout_rms: [f64; 2],
    /// Resolution of the feedback values, when rounded.
    pub resolution: Option<f64>,
    /// For the plot: time (s), `fb − command` and what the fit leaves, per
    /// fitted sample (in this axis's unit), thinned to at most
    /// [`PLOT_POINTS`] samples.
    #[serde(skip)]
    pub series: Vec<(f64, f64, f64)>,
}

/// Largest number of samples per axis kept for the plot of a joint trace.
pub const PLOT_POINTS: usize = 1500;

/// A joint-level finding (`formats.md` §3 shape).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointFinding {
    /// Effect name.
    pub effect: String,
    /// Axis letter.
    pub axis: Option<String>,
    /// Parameters with unit suffixes.
    pub parameters: BTreeMap<String, f64>,
    /// One standard deviation each.
    pub uncertainty: BTreeMap<String, f64>,
    /// Where it acts.
    #[serde(rename = "where")]
    pub where_: Where,
    /// RMS of the axis displacement it causes: mm on a linear axis
    /// (`rms_explained_mm`), deg on a rotary one (`rms_explained_deg`).
    #[serde(flatten)]
    pub rms_explained: BTreeMap<String, f64>,
    /// Always true.
    pub machine_physics: bool,
    /// The effect in model-file form.
    #[serde(skip)]
    pub spec: Option<EffectSpec>,
}

/// The report of a joint-feedback diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedbackReport {
    /// Always `joint_feedback`.
    pub recording: String,
    /// Samples read.
    pub samples: usize,
    /// Samples the effects were fitted on.
    pub samples_used: usize,
    /// Quadratic mean of the linear axes' noise floors, mm (0 without a
    /// traced linear axis).
    pub noise_floor_mm: f64,
    /// RMS of `fb − command` over the linear axes before the fit, mm.
    pub rms_before_mm: f64,
    /// The same after.
    pub rms_after_mm: f64,
    /// Held-out RMS over the linear axes, before, mm.
    pub holdout_rms_before_mm: f64,
    /// The same after.
    pub holdout_rms_after_mm: f64,
    /// Measurement findings (`time_offset`, `outliers`) first, then the
    /// machine effects by importance.
    #[serde(skip)]
    pub measurement: Vec<MeasurementFinding>,
    /// Where the recording's sampling stops and goes on, when it does:
    /// reported, not a finding.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gaps: Option<MeasurementFinding>,
    /// Machine effects found.
    pub findings: Vec<JointFinding>,
    /// Per-axis figures (in each axis's unit).
    pub axes: Vec<AxisSummary>,
    /// Candidates that fitted the data but not physics.
    pub rejected: Vec<Rejected>,
    /// Verdict in words.
    pub verdict: String,
}

impl FeedbackReport {
    /// JSON: `findings` lists the measurement findings first.
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or(serde_json::Value::Null);
        let mut all: Vec<serde_json::Value> = self
            .measurement
            .iter()
            .filter_map(|m| serde_json::to_value(m).ok())
            .collect();
        all.extend(
            self.findings
                .iter()
                .filter_map(|f| serde_json::to_value(f).ok()),
        );
        if let Some(o) = v.as_object_mut() {
            o.insert("findings".into(), serde_json::Value::Array(all));
        }
        v
    }

    /// Pretty JSON text.
    pub fn to_json_string(&self) -> String {
        serde_json::to_string_pretty(&self.to_json()).unwrap_or_default()
    }

    /// A readable report; every number with its unit.
    pub fn to_text(&self) -> String {
        let mut s =
            String::from("Diagnosis: joint feedback versus command (fb − command, no chain)\n");
        s.push_str(&format!(
            "  {} samples ({} used)\n",
            self.samples, self.samples_used
        ));
        for a in &self.axes {
            let (k, u) = if a.unit == "deg" {
                (1.0, "deg")
            } else {
                (1000.0, "µm")
            };
            s.push_str(&format!(
                "  {}: noise floor {:.4} {u}, RMS before {:.4} {u}, after {:.4} {u}; held-out {:.4} → {:.4} {u}{}\n",
                a.axis,
                a.noise_floor * k,
                a.rms_before * k,
                a.rms_after * k,
                a.holdout_rms[0] * k,
                a.holdout_rms[1] * k,
                a.resolution
                    .map_or(String::new(), |q| format!("; values rounded to {q} {}", a.unit))
            ));
        }
        if let Some(g) = &self.gaps {
            s.push_str(&format!(
                "  gaps in the recording, not machine physics: {}\n",
                g.where_.condition
            ));
        }
        // Parameters with their units (`formats.md` suffixes), as the
        // tool-tip report writes them; before, the measurement faults were
        // written as a map (`time_offset {"offset_s": 0.014998560076253355}`)
        // and the findings' values without units.
        let params = |p: &BTreeMap<String, f64>, sd: &BTreeMap<String, f64>| {
            p.iter()
                .map(|(n, v)| param_text(n, *v, sd.get(n).copied()))
                .collect::<Vec<_>>()
                .join(", ")
        };
        for m in &self.measurement {
            s.push_str(&format!(
                "  measurement fault, not machine physics: {}: {}: {}\n",
                m.effect,
                params(&m.parameters, &m.uncertainty),
                m.where_.condition
            ));
        }
        for (k, f) in self.findings.iter().enumerate() {
            let ps = params(&f.parameters, &f.uncertainty);
            s.push_str(&format!(
                "  {}. {} {}: {}\n     {}\n",
                k + 1,
                f.effect,
                f.axis.as_deref().unwrap_or(""),
                ps,
                f.where_.condition
            ));
        }
        for r in &self.rejected {
            s.push_str(&format!(
                "  not a finding: {} {}: {}\n",
                r.effect,
                r.axis.as_deref().unwrap_or(""),
                r.reason
            ));
        }
        s.push_str(&format!("  verdict: {}\n", self.verdict));
        s
    }

    /// The improved model: `base` plus the effects found.
    pub fn improved_model(
        &self,
        base: Option<&crate::geometric::ErrorModel>,
    ) -> crate::geometric::ErrorModel {
        let mut m = base.cloned().unwrap_or_default();
        for f in &self.findings {
            if let Some(spec) = &f.spec {
                m.effects.push(spec.clone());
            }
        }
        m
    }
}
