//! The diagnosis report: JSON exactly per `formats.md` §3 (plus extra
//! fields), a readable text form with a unit on every number, and the data
//! for the SVG plots.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::geometric::ErrorModel;
use crate::geometric::effects::{Effect, EffectSpec, axis_is_rotary};

/// Where an effect acts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Where {
    /// First and last block in which it acts (`null` without a block column).
    pub blocks: [Option<u64>; 2],
    /// First and last time, s.
    pub t_s: [f64; 2],
    /// When it shows, in words.
    pub condition: String,
}

/// The best alternative explanation of the same mismatch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunnerUp {
    /// Effect name.
    pub effect: String,
    /// Axis label.
    pub axis: Option<String>,
    /// Its parameters when fitted instead.
    pub parameters: BTreeMap<String, f64>,
    /// How much worse it explains the data: BIC difference to the finding
    /// (χ² units; above 10 is decisive).
    pub delta_bic: f64,
}

/// One effect found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// Catalogue name.
    pub effect: String,
    /// Axis letter, pair, or null.
    pub axis: Option<String>,
    /// Fitted parameters, unit-suffixed names.
    pub parameters: BTreeMap<String, f64>,
    /// One standard deviation of each parameter (LSQ covariance scaled by
    /// the noise floor; time constants and periods by their Gauss–Newton
    /// column).
    pub uncertainty: BTreeMap<String, f64>,
    /// Where it acts.
    #[serde(rename = "where")]
    pub where_: Where,
    /// RMS per coordinate of the tool-tip displacement the effect causes
    /// over the recording (exact, through the chain), mm.
    pub rms_explained_mm: f64,
    /// First block in which it acts when it starts part-way, else null.
    pub from_block: Option<u64>,
    /// Standard deviation of the onset time, s: given for a thermal drift
    /// that starts part-way (its onset is a smooth parameter traded off
    /// against τ and the amplitude, and their uncertainties include it);
    /// omitted otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub onset_sd_s: Option<f64>,
    /// BIC decrease when it entered the model (χ² units).
    pub delta_bic: f64,
    /// Held-out RMS before and after it entered, mm.
    pub holdout_rms_mm: [f64; 2],
    /// The best other explanation (a different effect or axis).
    pub runner_up: Option<RunnerUp>,
    /// For an `error_motion`: the components the data show (ISO 230-1
    /// names) with their peaks over one turn.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<ComponentPeak>,
    /// The effect in model-file form.
    #[serde(skip)]
    pub spec: EffectSpec,
}

/// One component of an error motion: a translation (`peak_mm`) or a
/// rotation (`peak_urad`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentPeak {
    /// ISO 230-1 name (`EXC`, `EYC`, … `EAC`, `EBC`, `ECC`).
    pub name: String,
    /// A translation's peak over one turn or the travel, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_mm: Option<f64>,
    /// A rotation's peak over one turn or the travel, µrad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_urad: Option<f64>,
}

impl ComponentPeak {
    /// The peak with its unit, for text (`1.234 µm`, `5.6 µrad`).
    pub fn peak_text(&self) -> String {
        match (self.peak_mm, self.peak_urad) {
            (Some(mm), _) => format!("{:.3} µm", mm * 1e3),
            (None, Some(urad)) => format!("{urad:.2} µrad"),
            (None, None) => "—".into(),
        }
    }
}

/// The components of an error motion worth naming: translations whose peak
/// is at least a quarter of the largest translation's, rotations at least
/// a quarter of the largest rotation's.
pub fn shown_components(effect: &Effect) -> Vec<ComponentPeak> {
    let Effect::ErrorMotion {
        axis,
        terms,
        span,
        arc,
    } = effect
    else {
        return Vec::new();
    };
    let comps = crate::geometric::effects::error_motion_components(terms, span.as_ref(), *arc);
    let top = |rot: bool| {
        comps
            .iter()
            .filter(|c| (c.0 >= 3) == rot)
            .map(|c| c.1)
            .fold(0.0, f64::max)
    };
    let (top_mm, top_rad) = (top(false), top(true));
    comps
        .into_iter()
        .filter(|&(c, peak)| peak >= 0.25 * if c < 3 { top_mm } else { top_rad })
        .map(|(c, peak)| ComponentPeak {
            name: crate::geometric::effects::component_name(c, axis),
            peak_mm: (c < 3).then_some(peak),
            peak_urad: (c >= 3).then_some(peak * 1e6),
        })
        .collect()
}

/// A finding that is not machine physics (`formats.md` §2c): the
/// recording's clock offset (`time_offset`) or its gross outliers
/// (`outliers`). Found and removed before any machine effect is fitted;
/// never written into a model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeasurementFinding {
    /// `time_offset` or `outliers`.
    pub effect: String,
    /// Always null: measurement faults belong to no axis.
    pub axis: Option<String>,
    /// `offset_s`; or `count` and `fraction`.
    pub parameters: BTreeMap<String, f64>,
    /// One standard deviation of each parameter where it has one.
    pub uncertainty: BTreeMap<String, f64>,
    /// Where it shows.
    #[serde(rename = "where")]
    pub where_: Where,
    /// RMS per coordinate of the residual it accounts for, over the whole
    /// recording, mm.
    pub rms_explained_mm: f64,
    /// Always false.
    pub machine_physics: bool,
    /// For outliers: the samples set aside (the first 50), with their
    /// departure from the running median.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub samples: Vec<FlaggedSample>,
}

/// One sample set aside as a gross outlier.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FlaggedSample {
    /// Index in the recording (0 = first data row).
    pub index: usize,
    /// Its time stamp, s.
    pub t_s: f64,
    /// Its block.
    pub block: Option<u64>,
    /// Its departure from the running median of its neighbours, mm.
    pub departure_mm: [f64; 3],
}

/// A candidate that fitted the data but not physics: a negative lag,
/// backlash or time constant, or a size the recording's motion could not
/// reveal. Evidence against that effect, not a finding.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rejected {
    /// Effect name.
    pub effect: String,
    /// Axis label.
    pub axis: Option<String>,
    /// The parameters it wanted.
    pub parameters: BTreeMap<String, f64>,
    /// Why it is not a finding.
    pub reason: String,
}

/// What the residual correlates with, when no effect explains it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Correlation {
    /// `axis position`, `axis velocity`, `time` or `frequency`.
    pub with: String,
    /// The axis, where one applies.
    pub axis: Option<String>,
    /// In words, with units.
    pub detail: String,
    /// Share of the residual's variance it accounts for (0 … 1).
    pub share: f64,
}

/// Where and with what an unexplained mismatch shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unexplained {
    /// First and last block of the windows that depart from the noise.
    pub blocks: [Option<u64>; 2],
    /// The same in time, s.
    pub t_s: [f64; 2],
    /// When it shows, in words.
    pub condition: String,
    /// What it correlates with, strongest first.
    pub correlates_with: Vec<Correlation>,
}

/// A time window of the residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Window {
    /// First and last block.
    pub blocks: [Option<u64>; 2],
    /// First and last time, s.
    pub t_s: [f64; 2],
    /// RMS per coordinate before the fit, mm.
    pub rms_before_mm: f64,
    /// RMS per coordinate after the fit, mm.
    pub rms_after_mm: f64,
    /// Excess over the noise floor before the fit, in standard deviations
    /// of the χ² statistic; above 4 departs from noise.
    pub excess_sigma_before: f64,
    /// The same after the fit.
    pub excess_sigma_after: f64,
}

/// A condition under which the residual departs from zero.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Condition {
    /// Axis.
    pub axis: String,
    /// The condition, e.g. `moving −`, `position 50…100 mm`, `speed > 8 mm/s`.
    pub condition: String,
    /// Samples in it.
    pub samples: usize,
    /// Mean residual along the axis's tool-tip direction, mm.
    pub mean_mm: f64,
    /// Mean divided by its standard error.
    pub z: f64,
}

/// Where model and recording disagree, before any effect is fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Locate {
    /// Windows whose residual departs from the noise floor (all windows
    /// are listed; `excess_sigma_before > 4` marks a departure).
    pub windows: Vec<Window>,
    /// The most significant conditions (|z| > 5), strongest first.
    pub conditions: Vec<Condition>,
}

/// Series for the plots (not serialised).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Time, s.
    pub t: Vec<f64>,
    /// Residual before, mm.
    pub before: Vec<[f64; 3]>,
    /// Residual after, mm.
    pub after: Vec<[f64; 3]>,
    /// Label of the x axis of the second plot (with unit).
    pub x_label: String,
    /// X values of the second plot.
    pub x: Vec<f64>,
    /// Label of the projected residual.
    pub y_label: String,
    /// Residual before, projected on the top finding's direction, mm.
    pub proj_before: Vec<f64>,
    /// The same after.
    pub proj_after: Vec<f64>,
}

/// The diagnosis report (`formats.md` §3).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Number of samples.
    pub samples: usize,
    /// Robust per-coordinate noise floor, mm.
    pub noise_floor_mm: f64,
    /// Residual RMS per coordinate before the fit, mm.
    pub rms_before_mm: f64,
    /// Residual RMS per coordinate after the fit (exact evaluation), mm.
    pub rms_after_mm: f64,
    /// Held-out RMS of the model without the effects found (nothing is
    /// fitted, so it equals `rms_before_mm`), mm.
    pub holdout_rms_before_mm: f64,
    /// Held-out RMS with the effects found, from 5 contiguous time folds
    /// each predicted from a fit on the other four (with a wander of the
    /// measurement in the model: 5 folds of 10 short stretches of time
    /// each, as [`Report::holdout_folds`] says), mm.
    pub holdout_rms_after_mm: f64,
    /// The folds of the held-out RMS, in words.
    #[serde(skip)]
    pub holdout_folds: &'static str,
    /// Effects found, most important first.
    pub findings: Vec<Finding>,
    /// Verdict in words.
    pub verdict: String,
    /// Per-coordinate noise floors `[x, y, z]`, mm.
    pub noise_floor_xyz_mm: [f64; 3],
    /// Residual χ² per degree of freedom against the noise floor, before.
    pub chi2_per_dof_before: f64,
    /// The same after.
    pub chi2_per_dof_after: f64,
    /// Recording span `[t0, t1]`, s.
    pub t_s: [f64; 2],
    /// First and last block.
    pub blocks: [Option<u64>; 2],
    /// Candidates of the first round, best first (effect, axis, ΔBIC).
    pub candidates: Vec<Candidate>,
    /// Where the residual departs from noise.
    pub locate: Locate,
    /// Selection rule, in words.
    pub method: String,
    /// Plot data.
    #[serde(skip)]
    pub series: Series,
    /// Findings that are not machine physics (clock offset, outliers);
    /// the JSON lists them first in `findings`, marked
    /// `"machine_physics": false`.
    #[serde(skip)]
    pub measurement: Vec<MeasurementFinding>,
    /// Where the recording's sampling stops and goes on (`gaps`: count,
    /// longest, samples missing), when it does: reported, not a finding.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gaps: Option<MeasurementFinding>,
    /// Where the time stamps stray from the regular clock the samples
    /// were taken at (`time_stamps`: its period, the largest and RMS
    /// stray), and the clock's times were used: reported, not a finding.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_stamps: Option<MeasurementFinding>,
    /// Where the commands were forward-filled from a slower stream
    /// (`held_commands`: rows per command sample, its period, rows left
    /// out), and only the rows where they were sampled were fitted:
    /// reported, not a finding.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_commands: Option<MeasurementFinding>,
    /// Samples the machine effects were fitted on (without outliers and
    /// the ends a clock offset leaves without a command).
    pub samples_used: usize,
    /// Resolution of the recording's values where they are rounded enough
    /// to matter (the rounding's noise above a tenth of the floor):
    /// `meas_mm`, and per axis `X_mm`, `C_deg`, …; the noise floor is never
    /// below the rounding's q²/12.
    pub resolution: BTreeMap<String, f64>,
    /// Candidates that fitted the data with parameters physics does not
    /// allow.
    pub rejected: Vec<Rejected>,
    /// Where and with what the mismatch shows when no effect explains it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unexplained: Option<Unexplained>,
}

/// A scored candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    /// Effect name.
    pub effect: String,
    /// Axis label.
    pub axis: Option<String>,
    /// BIC decrease it would bring (χ² units; negative: not worth it).
    pub delta_bic: f64,
}

fn um(mm: f64) -> String {
    format!("{:.3} µm", mm * 1000.0)
}

/// Formats a parameter with its unit from the suffix.
pub(crate) fn param_text(name: &str, v: f64, sd: Option<f64>) -> String {
    if name == "count" {
        return format!("count = {v:.0}");
    }
    if name == "fraction" {
        return format!("fraction = {:.3} %", v * 100.0);
    }
    if name == "basis" {
        return format!("basis = {v:.0} functions");
    }
    let (base, unit, scale, dec) = if let Some(b) = name.strip_suffix("_mm") {
        (b, "µm", 1000.0, 3)
    } else if let Some(b) = name.strip_suffix("_deg") {
        (b, "deg", 1.0, 5)
    } else if let Some(b) = name.strip_suffix("_s") {
        (b, "s", 1.0, 4)
    } else if let Some(b) = name.strip_suffix("_hz") {
        (b, "Hz", 1.0, 4)
    } else if let Some(b) = name.strip_suffix("_urad") {
        (b, "µrad", 1.0, 2)
    } else if name == "ppm" {
        ("scale", "ppm", 1.0, 2)
    } else if let Some(b) = name.strip_suffix("_ppm") {
        (b, "ppm", 1.0, 3)
    } else {
        (name, "", 1.0, 6)
    };
    // Periods and the ends of a range of positions are not small.
    let (unit, scale, dec) = if matches!(base, "period" | "from" | "to") && unit == "µm" {
        ("mm", 1.0, 3)
    } else {
        (unit, scale, dec)
    };
    // Enough decimals for four significant digits of small values.
    let mag = (v * scale).abs().max(sd.unwrap_or(0.0) * scale);
    let dec = if mag > 0.0 && mag.is_finite() {
        dec.max((3.0 - mag.log10().floor()).clamp(0.0, 12.0) as usize)
    } else {
        dec
    };
    match sd {
        Some(s) => format!("{base} = {:.dec$} ± {:.dec$} {unit}", v * scale, s * scale),
        None => format!("{base} = {:.dec$} {unit}", v * scale),
    }
}

impl Report {
    /// The report as JSON (`formats.md` §3 plus extra fields). `findings`
    /// lists the measurement findings first (`"machine_physics": false`),
    /// then the machine effects by importance (`"machine_physics": true`).
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or(serde_json::Value::Null);
        let mut all: Vec<serde_json::Value> = self
            .measurement
            .iter()
            .filter_map(|m| serde_json::to_value(m).ok())
            .collect();
        for f in &self.findings {
            if let Ok(mut x) = serde_json::to_value(f) {
                if let Some(o) = x.as_object_mut() {
                    o.insert("machine_physics".into(), serde_json::Value::Bool(true));
                }
                all.push(x);
            }
        }
        if let Some(o) = v.as_object_mut() {
            o.insert("findings".into(), serde_json::Value::Array(all));
        }
        v
    }

    /// Pretty-printed JSON text.
    pub fn to_json_string(&self) -> String {
        serde_json::to_string_pretty(&self.to_json()).unwrap_or_default()
    }

    /// A readable report; every number carries its unit.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        s.push_str("Diagnosis: recording versus model\n");
        s.push_str(&format!(
            "  {} samples, t = {:.3} … {:.3} s, blocks {} … {}\n",
            self.samples,
            self.t_s[0],
            self.t_s[1],
            self.blocks[0].map_or("-".into(), |b| b.to_string()),
            self.blocks[1].map_or("-".into(), |b| b.to_string()),
        ));
        s.push_str(&format!(
            "  noise floor {} per coordinate (x {}, y {}, z {}; robust: MAD of first differences)\n",
            um(self.noise_floor_mm),
            um(self.noise_floor_xyz_mm[0]),
            um(self.noise_floor_xyz_mm[1]),
            um(self.noise_floor_xyz_mm[2]),
        ));
        s.push_str(&format!(
            "  residual RMS per coordinate: before {}, after {} (χ²/dof {:.3} → {:.3})\n",
            um(self.rms_before_mm),
            um(self.rms_after_mm),
            self.chi2_per_dof_before,
            self.chi2_per_dof_after
        ));
        s.push_str(&format!(
            "  held-out RMS ({}): before {}, after {}\n",
            self.holdout_folds,
            um(self.holdout_rms_before_mm),
            um(self.holdout_rms_after_mm)
        ));
        if !self.resolution.is_empty() {
            let r: Vec<String> = self
                .resolution
                .iter()
                .map(|(k, v)| param_text(k, *v, None))
                .collect();
            s.push_str(&format!(
                "  values rounded: {} (the noise floor is never below the rounding's q²/12)\n",
                r.join(", ")
            ));
        }
        if self.samples_used != self.samples {
            s.push_str(&format!(
                "  machine effects fitted on {} of the {} samples\n",
                self.samples_used, self.samples
            ));
        }
        if let Some(g) = &self.gaps {
            s.push_str(&format!(
                "  gaps in the recording, not machine physics: {}\n",
                g.where_.condition
            ));
        }
        if let Some(g) = &self.held_commands {
            s.push_str(&format!(
                "  commands held over several rows, not machine physics: {}\n",
                g.where_.condition
            ));
        }
        if let Some(g) = &self.time_stamps {
            s.push_str(&format!(
                "  time stamps off a regular clock, not machine physics: {}\n",
                g.where_.condition
            ));
        }
        for m in &self.measurement {
            let ps: Vec<String> = m
                .parameters
                .iter()
                .map(|(n, v)| param_text(n, *v, m.uncertainty.get(n).copied()))
                .collect();
            s.push_str(&format!(
                "  measurement fault, not machine physics: {}: {}\n     {}\n",
                m.effect,
                ps.join(", "),
                m.where_.condition
            ));
        }
        let departs: Vec<&Window> = self
            .locate
            .windows
            .iter()
            .filter(|w| w.excess_sigma_before > 4.0)
            .collect();
        if departs.is_empty() {
            s.push_str("  where: no time window departs from the noise floor\n");
        } else {
            s.push_str(&format!(
                "  where: {} of {} time windows depart from the noise floor:\n",
                departs.len(),
                self.locate.windows.len()
            ));
            for w in departs.iter().take(8) {
                s.push_str(&format!(
                    "    blocks {}…{}, t {:.1}…{:.1} s: RMS {} ({:.1} σ above noise), after the fit {}\n",
                    w.blocks[0].map_or("-".into(), |b| b.to_string()),
                    w.blocks[1].map_or("-".into(), |b| b.to_string()),
                    w.t_s[0],
                    w.t_s[1],
                    um(w.rms_before_mm),
                    w.excess_sigma_before,
                    um(w.rms_after_mm)
                ));
            }
        }
        for c in self.locate.conditions.iter().take(6) {
            s.push_str(&format!(
                "    {} {}: mean residual along {} {} over {} samples (z = {:.1})\n",
                c.axis,
                c.condition,
                c.axis,
                um(c.mean_mm),
                c.samples,
                c.z
            ));
        }
        if self.findings.is_empty() {
            s.push_str("  findings: none\n");
        }
        for (k, f) in self.findings.iter().enumerate() {
            s.push_str(&format!(
                "  {}. {}{}: ",
                k + 1,
                f.effect,
                f.axis.as_deref().map_or(String::new(), |a| format!(" {a}"))
            ));
            let ps: Vec<String> = f
                .parameters
                .iter()
                .map(|(n, v)| param_text(n, *v, f.uncertainty.get(n).copied()))
                .collect();
            s.push_str(&ps.join(", "));
            s.push_str(&format!(
                "\n     acts in blocks {}…{}, t {:.1}…{:.1} s: {}\n     explains {} RMS; ΔBIC {:.1}; held-out RMS {} → {}\n",
                f.where_.blocks[0].map_or("-".into(), |b| b.to_string()),
                f.where_.blocks[1].map_or("-".into(), |b| b.to_string()),
                f.where_.t_s[0],
                f.where_.t_s[1],
                f.where_.condition,
                um(f.rms_explained_mm),
                f.delta_bic,
                um(f.holdout_rms_mm[0]),
                um(f.holdout_rms_mm[1]),
            ));
            if let Some(r) = &f.runner_up {
                s.push_str(&format!(
                    "     runner-up: {}{} (ΔBIC {:.1} worse)\n",
                    r.effect,
                    r.axis.as_deref().map_or(String::new(), |a| format!(" {a}")),
                    r.delta_bic
                ));
            }
        }
        for r in &self.rejected {
            let ps: Vec<String> = r
                .parameters
                .iter()
                .map(|(n, v)| param_text(n, *v, None))
                .collect();
            s.push_str(&format!(
                "  not a finding: {}{} ({}): {}\n",
                r.effect,
                r.axis.as_deref().map_or(String::new(), |a| format!(" {a}")),
                ps.join(", "),
                r.reason
            ));
        }
        if let Some(u) = &self.unexplained {
            s.push_str("  the remaining mismatch correlates with:\n");
            if u.correlates_with.is_empty() {
                s.push_str(
                    "    none of the axis positions, velocities, time or a single frequency\n",
                );
            }
            for c in &u.correlates_with {
                s.push_str(&format!("    {}\n", c.detail));
            }
        }
        s.push_str(&format!("  verdict: {}\n", self.verdict));
        s
    }

    /// The effects found, as model-file effects.
    pub fn effects(&self) -> Vec<EffectSpec> {
        self.findings.iter().map(|f| f.spec.clone()).collect()
    }

    /// The improved model: `base` (or an empty model) plus the effects
    /// found. Static effects act through [`ErrorModel::bind`] and
    /// [`ErrorModel::apply_fixed`], so `compensate` and `analyze` use them
    /// unchanged; dynamic ones are applied along a trajectory by
    /// [`crate::diagnose::compensate_dynamic`]. The model describes the
    /// machine as it is at the end of the recording: an effect that started
    /// part-way is kept from then on (its `from_block` is dropped).
    ///
    /// An `error_motion` is written as error-table columns of its axis
    /// (`formats.md` §4): its components tabulated every degree over a turn
    /// (added to the axis's columns where it has them) and fitted like any
    /// table, so the model reads as if the axis had been measured. A motion
    /// found over part of a turn is held beyond that arc at its nearer end.
    /// Nothing is claimed of the part the recording did not turn through.
    pub fn improved_model(&self, base: Option<&ErrorModel>) -> ErrorModel {
        let mut m = base.cloned().unwrap_or_default();
        for f in &self.findings {
            if let Effect::ErrorMotion {
                axis,
                terms,
                span,
                arc,
            } = &f.spec.effect
                && add_motion_columns(&mut m, axis, terms, span.as_ref(), *arc)
            {
                continue;
            }
            let mut spec = f.spec.clone();
            spec.from_block = None;
            m.effects.push(spec);
        }
        let note = format!(
            "{} effect(s) added by kinpost diagnose: {}",
            self.findings.len(),
            self.findings
                .iter()
                .map(|f| format!(
                    "{}{}",
                    f.effect,
                    f.axis.as_deref().map_or(String::new(), |a| format!(" {a}"))
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
        m.meta.description = Some(match &m.meta.description {
            Some(d) if !d.is_empty() => format!("{d}; {note}"),
            _ => note,
        });
        m.meta.generator = Some(format!("kinpost {}", env!("CARGO_PKG_VERSION")));
        m
    }
}

/// Adds a rotary axis's error motion to the model as error-table columns:
/// every component it moves, tabulated every degree from −180° to 180°
/// (plus the axis's existing column there), fitted as a table is. `false`
/// when the fit fails (the caller then keeps the effect instead).
fn add_motion_columns(
    m: &mut ErrorModel,
    axis: &str,
    terms: &[crate::geometric::effects::MotionTerm],
    span: Option<&crate::geometric::effects::MotionSpan>,
    arc: crate::geometric::effects::TurnArc,
) -> bool {
    use crate::geometric::table::{Component, ErrorColumn, ErrorTable};
    // A turn every degree, or the travel in 200 steps.
    let positions: Vec<f64> = match span {
        None => (-180..=180).map(f64::from).collect(),
        Some(sp) => (0..=200)
            .map(|i| sp.lo + (sp.hi - sp.lo) * i as f64 / 200.0)
            .collect(),
    };
    let internal = |p: f64| if span.is_some() { p } else { p.to_radians() };
    let existing = m
        .axes
        .iter()
        .find(|a| a.axis.eq_ignore_ascii_case(axis))
        .cloned();
    let mut comps: Vec<usize> = terms.iter().map(|t| t.0).collect();
    comps.sort_unstable();
    comps.dedup();
    let columns: Vec<ErrorColumn> = comps
        .iter()
        .map(|&c| ErrorColumn {
            component: Component::ALL[c.min(5)],
            name: crate::geometric::effects::component_name(c, axis),
            values: positions
                .iter()
                .map(|&d| {
                    let own =
                        crate::geometric::effects::error_motion_at(terms, span, arc, internal(d))
                            [c];
                    let old = existing.as_ref().map_or(0.0, |a| a.error_at(d).0[c]);
                    own + old
                })
                .collect(),
        })
        .collect();
    let n = positions.len();
    let table = ErrorTable {
        axis: axis.to_ascii_uppercase(),
        rotary: span.is_none(),
        columns,
        positions,
        direction: None,
        source_line: vec![0; n],
        file: "kinpost diagnose (error_motion)".into(),
        header_line: 0,
        header_text: String::new(),
    };
    let Ok((fitted, _)) = ErrorModel::fit(&[table], &Default::default()) else {
        return false;
    };
    let Some(new_axis) = fitted.axes.into_iter().next() else {
        return false;
    };
    match m
        .axes
        .iter_mut()
        .find(|a| a.axis.eq_ignore_ascii_case(axis))
    {
        Some(a) => {
            for col in new_axis.columns {
                a.columns.retain(|c| c.component != col.component);
                a.columns.push(col);
            }
        }
        None => m.axes.push(new_axis),
    }
    true
}

/// The condition text of an effect.
pub fn condition_text(effect: &Effect, rotary: bool) -> String {
    let u = if rotary { "deg" } else { "mm" };
    match effect {
        Effect::Backlash { axis, .. } => format!(
            "at reversals of {axis}: the error changes sign with the direction of its last motion"
        ),
        Effect::ServoLag { axis, .. } => {
            format!("while {axis} moves, proportional to its speed, against the motion")
        }
        Effect::ThermalDrift { axis, tau_s, .. } => {
            format!("grows with time along {axis} (time constant {tau_s:.0} s)")
        }
        Effect::Scale { axis, .. } => format!("proportional to the {axis} position"),
        Effect::Squareness { axes, .. } => format!(
            "the tool moves along {} in proportion to the {} position",
            axes[1], axes[0]
        ),
        Effect::Cyclic { axis, period, .. } => {
            format!("periodic in the {axis} position, period {period:.3} {u}")
        }
        Effect::ZeroOffset { axis, .. } => format!("everywhere: a constant shift of {axis}"),
        Effect::RotaryCenterOffset { axis, .. } => {
            format!("varies with the {axis} angle: {axis} turns about a displaced line")
        }
        Effect::PivotLength { .. } => "along the tool axis, showing as the tool tilts".to_string(),
        Effect::Registration { .. } => "everywhere: a constant offset of the measured tip in the workpiece frame, whatever the axes do".to_string(),
        Effect::Wander { span, .. } => format!("with time: a slow wander of the measured tip in the workpiece frame (a curve with knots every {:.0} s), whatever the axes do", crate::geometric::effects::wander_knot_spacing(span)),
        Effect::ErrorMotion {
            axis, terms, span, ..
        } => {
            let names: Vec<String> = shown_components(effect)
                .into_iter()
                .map(|c| format!("{} peak {}", c.name, c.peak_text()))
                .collect();
            if let Some(sp) = span {
                return format!(
                    "varies with the {axis} position: an error motion of {axis} ({}) over {:.1} … {:.1} mm, neither linear nor periodic",
                    names.join(", "),
                    sp.lo,
                    sp.hi
                );
            }
            let mut ks: Vec<u32> = terms.iter().map(|t| t.1).collect();
            ks.sort_unstable();
            ks.dedup();
            format!(
                "varies with the {axis} angle: an error motion of {axis} ({}) at {} per turn",
                names.join(", "),
                ks.iter()
                    .map(|k| format!("{k}×"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }
        Effect::Vibration {
            axis, frequency_hz, ..
        } => format!(
            "in time, along {axis}: an oscillation at {frequency_hz:.4} Hz whatever the position"
        ),
    }
}

/// `rotary` for an effect's parameters on `chain`.
pub fn effect_is_rotary(effect: &Effect, chain: &crate::machine::Chain) -> bool {
    effect
        .axis_label()
        .is_some_and(|a| a.len() == 1 && axis_is_rotary(Some(chain), &a))
}
