//! Find the missing physics: where a recording and the model disagree, which
//! effect of the catalogue explains it, its parameters with uncertainties,
//! the proof on held-out data, and the improved model.
//!
//! * [`recording`]: the recording CSV of `formats.md` §2 (reader, writer).
//! * the catalogue of `formats.md` §4 lives in [`crate::geometric::effects`]
//!   (re-exported here as [`effects`]).
//! * [`simulate`](mod@simulate): simulated recordings ([`simulate()`]),
//!   streamed along [`timeline`], the commanded trajectory.
//! * [`untidy`]: what is not machine physics (resolution, outliers, clock
//!   offset), found and removed first.
//! * [`feedback`]: joint-feedback recordings (`formats.md` §2b), diagnosed
//!   on `fb − command` without the chain.
//! * [`fit`]: linearised effect fits, onset profiles, cross-validation.
//! * [`stepwise`]: the forward selection of the effects.
//! * [`report`]: the report ([`Report`]): JSON, text, SVG.
//!
//! See `docs/diagnose.md`.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

mod csv;
mod csv_lines;
mod dynamic;
pub mod feedback;
pub mod fit;
pub mod motion_components;
pub mod plausible;
pub mod prepare;
pub mod programs;
pub mod recording;
pub mod report;
pub mod rng;
pub mod simulate;
pub mod stepwise;
pub mod timeline;
pub mod unexplained;
pub mod untidy;

use std::collections::BTreeMap;

pub use crate::geometric::effect_spec::parse_effect_spec;
pub use crate::geometric::effects::{self, Effect, EffectKind, EffectSpec};
pub use dynamic::{DynamicErrors, compensate_dynamic, dynamic_offsets};
pub use recording::{Recording, RecordingReader, Sample};
pub use report::{Finding, Report, RunnerUp, Where};
pub use simulate::{
    SimOptions, TrajPoint, Waypoint, WaypointPath, central_velocities, evaluate_trajectory,
    sample_waypoints, simulate,
};

use fit::{Family, Fitted, SearchCtx, Selected, Term};
use prepare::{ModelMachine, Prepared, prepare};
use report::{Condition, Locate, Series, Window};

use crate::error::{Error, Location, Result};
use crate::geometric::ErrorModel;
use crate::machine::chain::{Chain, JointKind};

/// Least share of the held-out residual's excess over the noise that an
/// effect must explain to be a finding: a jittered trace's mismatch let a
/// 365 µm error motion in that moved the held-out RMS from 9.740 to
/// 9.739 µm.
const MIN_HOLDOUT_SHARE: f64 = 0.01;

/// Relative standard deviation of a drift's τ above which the report says
/// that τ is only loosely determined (at 10 % a 20 % error is a 2σ event).
const LOOSE_TAU: f64 = 0.1;

/// Options of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiagOptions {
    /// Largest number of effects to report.
    pub max_effects: usize,
    /// A candidate must lower the BIC by more than this (χ² units) after
    /// paying for its parameters and searches.
    pub bic_margin: f64,
    /// Override of the noise floor (mm); estimated robustly when `None`.
    pub noise_floor_mm: Option<f64>,
    /// Restrict the candidates to these kinds (all when empty).
    pub kinds: Vec<EffectKind>,
}

impl Default for DiagOptions {
    fn default() -> Self {
        DiagOptions {
            max_effects: 4,
            bic_margin: 10.0,
            noise_floor_mm: None,
            kinds: Vec::new(),
        }
    }
}

fn rms(r: &[[f64; 3]]) -> f64 {
    if r.is_empty() {
        return 0.0;
    }
    (r.iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sum::<f64>()
        / (3 * r.len()) as f64)
        .sqrt()
}

/// The block of sample `i`.
fn block_of(prep: &Prepared, i: usize) -> Option<u64> {
    prep.block.get(i).copied().flatten()
}

/// Diagnoses a recording against the model: `chain` with the known error
/// model `errors` (its tables, fixed elements and effects).
pub fn diagnose(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    rec: &Recording,
    opts: &DiagOptions,
) -> Result<Report> {
    if rec.samples.len() < 20 {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "the recording has {} samples; a diagnosis needs at least 20",
                rec.samples.len()
            ),
        ));
    }
    let machine = ModelMachine::new(chain, errors)?;
    // Commands forward-filled from a slower stream: only the rows where
    // they were sampled.
    let held = untidy::held_commands(rec);
    let rec = held.as_ref().map_or(rec, |h| &h.rec);
    // Stamps rounded or jittered off the fixed rate the samples were taken
    // at: the samples are placed at the rate's times.
    let regular = untidy::regular_clock(rec);
    let rec = regular.as_ref().map_or(rec, |r| &r.rec);
    let n_all = rec.samples.len();
    let ln_rows = ((3 * n_all) as f64).ln();
    let tidy = untidy::tidy(
        &machine,
        rec,
        opts.noise_floor_mm.filter(|s| *s > 0.0),
        ln_rows + opts.bic_margin,
    )?;
    if tidy.rec.samples.len() < 20 {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "only {} of the {n_all} samples are left once the clock offset and the outliers are removed; a diagnosis needs at least 20",
                tidy.rec.samples.len()
            ),
        ));
    }
    let original = rec;
    let rec = &tidy.rec;
    let prep = prepare(&machine, rec)?;
    let (per, sigma) = untidy::floor_of(
        &prep,
        tidy.rounding_xyz,
        opts.noise_floor_mm.filter(|s| *s > 0.0),
    );
    let s2 = sigma * sigma;
    // What the rounding of the values alone can leave as structure.
    let unresolved = {
        let (meas, cmd) = tidy.rounding_xyz;
        let pooled = |v: [f64; 3]| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) / 3.0).sqrt();
        let meas = pooled(meas);
        let cmd = pooled(cmd);
        // Rounding of the measured tip is dithered by noise larger than it.
        let noise = pooled(per);
        if meas > 0.5 * noise {
            cmd.hypot(meas)
        } else {
            cmd
        }
    };
    let n_rows = prep.rows() as f64;
    let ctx = SearchCtx {
        sigma,
        ln_n: n_rows.ln(),
        min_after: (prep.n / 50).max(20),
    };
    let families: Vec<Family> = Family::all(&prep)
        .into_iter()
        .filter(|f| {
            // A registration of the measurement is always weighed: left
            // out, a machine effect would take its place.
            f.kind().is_measurement() || opts.kinds.is_empty() || opts.kinds.contains(&f.kind())
        })
        .collect();

    // Forward stepwise selection.
    let stepwise::Stepwise {
        mut terms,
        meta: mut fitted_meta,
        mut rounds,
        first_round,
        mut rejected,
        hold_before,
        ..
    } = stepwise::select(&prep, &families, &ctx, opts, unresolved, &machine.chain);
    // Back-fitting: re-search each term's non-linear parameter and onset
    // with the others in the model.
    if terms.len() > 1 {
        for k in 0..terms.len() {
            let others: Vec<Term> = terms
                .iter()
                .enumerate()
                .filter(|(m, _)| *m != k)
                .map(|(_, t)| *t)
                .collect();
            let sel = Selected::new(&prep, fit::design(&prep, &others));
            if let Some(c) = fit::search_family(&prep, &sel, terms[k].family, &ctx) {
                terms[k] = c.term;
            }
        }
    }

    // Final joint fit with covariance (non-linear parameters by their
    // Gauss–Newton columns). A term that the joint fit pushes to
    // parameters physics does not allow leaves the model.
    let (all, beta, offsets) = loop {
        let all = fit::design(&prep, &terms);
        let (beta, _) = fit::lsq(&prep, &all, &|_| true);
        let mut offsets = Vec::with_capacity(terms.len());
        let mut off = 0;
        for t in &terms {
            offsets.push(off);
            off += t.family.linear_params();
        }
        let bad = terms.iter().enumerate().find_map(|(k, t)| {
            let b = &beta.as_slice()[offsets[k]..offsets[k] + t.family.linear_params()];
            let e = fit::term_effect(&prep, t, b);
            plausible::implausible(&e, &prep).map(|r| (k, e, r))
        });
        match bad {
            None => break (all, beta, offsets),
            Some((k, e, reason)) => {
                reject(&mut rejected, &e, &machine.chain, reason);
                terms.remove(k);
                fitted_meta.remove(k);
                rounds.remove(k);
            }
        }
    };
    let mut full = all.clone();
    let mut nl_index = vec![None; terms.len()];
    let mut onset_index = vec![None; terms.len()];
    for (k, t) in terms.iter().enumerate() {
        let b: Vec<f64> = (0..t.family.linear_params())
            .map(|p| beta[offsets[k] + p])
            .collect();
        if t.family.has_nonlinear() {
            nl_index[k] = Some(full.k);
            full = full.hcat(&fit::nl_derivative(&prep, t, &b));
        }
        if let Some(c) = fit::onset_derivative(&prep, t, &b) {
            onset_index[k] = Some(full.k);
            full = full.hcat(&c);
        }
    }
    let (_, g) = fit::lsq(&prep, &full, &|_| true);
    let cov = fit::pinv_sym(&g) * s2;

    let mut fitted: Vec<Fitted> = Vec::new();
    for (k, t) in terms.iter().enumerate() {
        let kl = t.family.linear_params();
        let b: Vec<f64> = (0..kl).map(|p| beta[offsets[k] + p]).collect();
        let mut idx: Vec<usize> = (offsets[k]..offsets[k] + kl).collect();
        if let Some(i) = nl_index[k] {
            idx.push(i);
        }
        let sub = nalgebra::DMatrix::from_fn(idx.len(), idx.len(), |a, c| cov[(idx[a], idx[c])]);
        let sd = fit::parameter_sd(&prep, t, &b, &sub);
        let onset_sd_s = onset_index[k].map(|i| cov[(i, i)].max(0.0).sqrt());
        let effect = fit::term_effect(&prep, t, &b);
        let from_block = if t.onset > 0 {
            block_of(&prep, t.onset)
        } else {
            None
        };
        let (score, hold) = fitted_meta[k];
        // Runner-up: the best candidate of the same round that is not one
        // of the effects found (a different effect, or the same on another
        // axis): the best alternative explanation of this mismatch.
        let runner = rounds[k]
            .iter()
            .find(|o| {
                !terms.iter().any(|t| {
                    t.family.kind() == o.term.family.kind()
                        && t.family.axis_label(&prep.names) == o.term.family.axis_label(&prep.names)
                })
            })
            .map(|o| (o.term, score - o.score));
        let runner_up = runner.map(|(rt, d)| {
            let sel = Selected::new(&prep, fit::design(&prep, &[rt]));
            let (rb, _) = fit::lsq(&prep, &sel.cols, &|_| true);
            (rt, d, fit::term_effect(&prep, &rt, rb.as_slice()))
        });
        fitted.push(Fitted {
            term: *t,
            spec: EffectSpec { effect, from_block },
            sd,
            onset_sd_s,
            score,
            holdout: hold,
            runner_up,
        });
    }

    // Exact re-evaluation through the chain.
    let specs: Vec<EffectSpec> = fitted.iter().map(|f| f.spec.clone()).collect();
    let onsets: Vec<usize> = fitted.iter().map(|f| f.term.onset).collect();
    let tips_all = exact_tips(chain, errors, &prep, &specs, &onsets)?;
    let after: Vec<[f64; 3]> = (0..prep.n)
        .map(|i| {
            let m = rec.samples[i].meas;
            let p = tips_all[i];
            [m[0] - p[0], m[1] - p[1], m[2] - p[2]]
        })
        .collect();
    let mut explained = Vec::with_capacity(fitted.len());
    for (k, f) in fitted.iter().enumerate() {
        let tips = if fitted.len() == 1 {
            tips_all.clone()
        } else {
            exact_tips(
                chain,
                errors,
                &prep,
                std::slice::from_ref(&f.spec),
                &[onsets[k]],
            )?
        };
        let d: Vec<[f64; 3]> = (0..prep.n)
            .map(|i| {
                let a = tips[i];
                let b = prep.model_tip[i];
                [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
            })
            .collect();
        explained.push(rms(&d));
    }

    let rms_before = rms(&prep.r);
    let rms_after = rms(&after);
    if rms_after > untidy::MISFIT_AFTER_MM {
        return Err(Error::input(
            Location::new("<recording>", 0, 0),
            format!(
                "the recording does not fit this machine: even with the effects that fit best the measured tool tip stays {:.3} mm RMS from the model (more than {} mm). Is it a recording of this machine, with its axes in mm and degrees and the tip in the workpiece frame?",
                rms_after,
                untidy::MISFIT_AFTER_MM
            ),
        ));
    }
    // With a wander of the measurement in the model, a function of time,
    // the held-out residual is read on short stretches of time (a
    // contiguous fifth of the recording takes away what fixes the wander
    // there).
    let wander = terms.iter().any(|t| t.family == Family::Wander);
    let (hold_before, hold_after) = if wander {
        (
            fit::holdout_rss_chunked(&prep, &fit::design(&prep, &[])),
            fit::holdout_rss_chunked(&prep, &all),
        )
    } else {
        (hold_before, fit::holdout_rss(&prep, &all))
    };
    let to_rms = |rss: f64| (rss / n_rows).sqrt();
    let t_span = [prep.t[0], prep.t[prep.n - 1]];
    let blocks = [block_of(&prep, 0), block_of(&prep, prep.n - 1)];

    let mut findings: Vec<Finding> = fitted
        .iter()
        .zip(&explained)
        .map(|(f, &ex)| {
            let rotary = report::effect_is_rotary(&f.spec.effect, &machine.chain);
            let params = f.spec.effect.parameters(rotary);
            let parameters: BTreeMap<String, f64> = params.iter().cloned().collect();
            let uncertainty: BTreeMap<String, f64> = params
                .iter()
                .filter(|(n, _)| !Effect::is_chosen_parameter(n))
                .zip(&f.sd)
                .map(|((n, _), s)| (n.clone(), *s))
                .collect();
            let mut condition = report::condition_text(&f.spec.effect, rotary);
            if let Some(b) = f.spec.from_block {
                let sd = f
                    .onset_sd_s
                    .map_or(String::new(), |s| format!(" ± {s:.1}"));
                condition.push_str(&format!(
                    "; from block {b} on (t = {:.1}{sd} s)",
                    prep.t[f.term.onset]
                ));
            }
            if let Effect::ThermalDrift { tau_s, .. } = &f.spec.effect {
                let rel = f.sd.get(1).copied().unwrap_or(0.0) / tau_s;
                if rel > LOOSE_TAU {
                    let covered = (t_span[1] - prep.t[f.term.onset]) / tau_s;
                    condition.push_str(&format!(
                        "; τ only loosely determined (± {:.0} %): the recording runs {covered:.1} τ after the onset, and a longer recording would narrow it",
                        rel * 100.0
                    ));
                }
            }
            Finding {
                effect: f.spec.effect.kind().name().to_string(),
                axis: f.spec.effect.axis_label(),
                parameters,
                uncertainty,
                where_: Where {
                    blocks: [block_of(&prep, f.term.onset), blocks[1]],
                    t_s: [prep.t[f.term.onset], t_span[1]],
                    condition,
                },
                rms_explained_mm: ex,
                from_block: f.spec.from_block,
                onset_sd_s: f.onset_sd_s,
                delta_bic: f.score,
                holdout_rms_mm: [to_rms(f.holdout.0), to_rms(f.holdout.1)],
                runner_up: f.runner_up.as_ref().map(|(rt, d, e)| RunnerUp {
                    effect: rt.family.kind().name().to_string(),
                    axis: rt.family.axis_label(&prep.names),
                    parameters: e
                        .parameters(report::effect_is_rotary(e, &machine.chain))
                        .into_iter()
                        .collect(),
                    delta_bic: *d,
                }),
                components: report::shown_components(&f.spec.effect),
                spec: f.spec.clone(),
            }
        })
        .collect();
    let order: Vec<usize> = {
        let mut o: Vec<usize> = (0..findings.len()).collect();
        o.sort_by(|a, b| explained[*b].total_cmp(&explained[*a]));
        o
    };
    // A registration of the measurement is reported with the other
    // measurement faults, never as machine physics.
    let (mut registration, order): (Vec<usize>, Vec<usize>) = order
        .into_iter()
        .partition(|&k| fitted[k].term.family.kind().is_measurement());
    // Several registration steps (beam breaks) are told in the order they
    // happened, in the places the largest of them took.
    let is_step = |k: usize| fitted[k].term.family == fit::Family::RegistrationStep;
    let mut steps: Vec<usize> = registration
        .iter()
        .copied()
        .filter(|&k| is_step(k))
        .collect();
    steps.sort_by_key(|&k| fitted[k].term.onset);
    let mut in_time = steps.into_iter();
    for k in registration.iter_mut().filter(|k| is_step(**k)) {
        *k = in_time.next().expect("as many steps");
    }
    let top_term = order.first().map(|&k| fitted[k].term);
    let registration: Vec<report::MeasurementFinding> = registration
        .iter()
        .map(|&k| match fitted[k].term.family {
            fit::Family::Wander => untidy::wander_finding(&findings[k]),
            fit::Family::RegistrationStep => untidy::registration_step_finding(&findings[k]),
            _ => untidy::registration_finding(&findings[k]),
        })
        .collect();
    findings = order.iter().map(|&k| findings[k].clone()).collect();

    let chi2 = |r: &[[f64; 3]]| rms(r).powi(2) / s2;
    let chi_before = chi2(&prep.r);
    let chi_after = chi2(&after);
    let locate = locate(&prep, &after, sigma);
    let mut measurement = tidy.findings(original);
    measurement.extend(registration);
    let faults = if measurement.is_empty() {
        String::new()
    } else {
        let parts: Vec<String> = measurement
            .iter()
            .map(|m| match m.effect.as_str() {
                "time_offset" => {
                    let offset = format!(
                        "a clock offset of {:.3} ms",
                        m.parameters.get("offset_s").copied().unwrap_or(0.0) * 1e3
                    );
                    match m.parameters.get("drift_ppm") {
                        Some(ppm) => format!("{offset} at the start, drifting {ppm:.2} ppm"),
                        None => offset,
                    }
                }
                "registration" => {
                    let p = |k: &str| m.parameters.get(k).copied().unwrap_or(0.0) * 1e3;
                    format!(
                        "a registration offset of the measured tip of ({:.3}, {:.3}, {:.3}) µm",
                        p("dx_mm"),
                        p("dy_mm"),
                        p("dz_mm")
                    )
                }
                "registration_step" => {
                    let p = |k: &str| m.parameters.get(k).copied().unwrap_or(0.0) * 1e3;
                    format!(
                        "a step of the measured tip's registration of ({:.3}, {:.3}, {:.3}) µm at {:.3} s",
                        p("dx_mm"),
                        p("dy_mm"),
                        p("dz_mm"),
                        m.where_.t_s[0]
                    )
                }
                "wander" => {
                    let p = |k: &str| m.parameters.get(k).copied().unwrap_or(0.0) * 1e3;
                    format!(
                        "a wander of the measured tip of ({:.3}, {:.3}, {:.3}) µm peak to peak",
                        p("range_x_mm"),
                        p("range_y_mm"),
                        p("range_z_mm")
                    )
                }
                _ => format!(
                    "{} gross outlier(s)",
                    m.parameters.get("count").copied().unwrap_or(0.0)
                ),
            })
            .collect();
        format!(
            " once the measurement faults are removed ({})",
            parts.join(", ")
        )
    };
    // Significantly above the noise: χ² per degree of freedom 10 % above 1
    // and more than 4 standard deviations above it, counting the
    // uncertainty of the noise floor itself (a median of first differences:
    // a relative variance of about 1.36 / n per coordinate, 5.4 / n_rows in
    // χ), which on a short trace is the larger part (30 samples: χ above
    // 2.0 rather than 1.34; a clean 30-sample trace had been an
    // "unexplained mismatch" at χ = 1.42).
    let above = |chi: f64| chi > 1.1 && (chi - 1.0) > 4.0 * ((1.0 / 1.5 + 5.4) / n_rows).sqrt();
    // A residual white and steady in time is noise whatever its tails,
    // which the robust floor reads low (`unexplained::white_level`): the
    // RMS its first differences give, then.
    let white = |r: &[[f64; 3]]| {
        unexplained::white_level(r)
            .filter(|(v, steady)| *steady && !above(rms(r).powi(2) / v))
            .map(|(v, _)| v.sqrt())
    };
    let beyond = |r: &[[f64; 3]], chi: f64| above(chi) && white(r).is_none();
    let unexplained = if beyond(&after, chi_after) {
        unexplained::unexplained(&prep, &after, sigma, &locate.windows)
    } else {
        None
    };
    let where_text = unexplained
        .as_ref()
        .map_or(String::new(), |u| format!(": it shows {}", u.condition));
    // The residual the machine effects are judged on: after the
    // measurement faults fitted with them (a registration, a wander).
    let (chi_physics, rms_physics, r_physics) = if measurement.iter().any(|m| {
        matches!(
            m.effect.as_str(),
            "registration" | "registration_step" | "wander"
        )
    }) {
        (chi_after, rms_after, &after)
    } else {
        (chi_before, rms_before, &prep.r)
    };
    let verdict = if findings.is_empty() {
        if let Some(w) = white(r_physics).filter(|_| above(chi_physics)) {
            format!(
                "consistent with measurement noise{faults}: the residual RMS {:.3} µm is above the robust noise floor {:.3} µm, but white and steady in time (its first differences give {:.3} µm): noise with heavier tails than a normal distribution's; no missing physics found",
                rms_physics * 1e3,
                sigma * 1e3,
                w * 1e3
            )
        } else if !above(chi_physics) {
            format!(
                "consistent with measurement noise{faults}: the residual RMS {:.3} µm is at the noise floor {:.3} µm; no missing physics found",
                rms_physics * 1e3,
                sigma * 1e3
            )
        } else {
            format!(
                "unexplained mismatch{faults}: the residual RMS {:.3} µm exceeds the noise floor {:.3} µm, but no effect of the catalogue explains it on held-out data{where_text}",
                rms_physics * 1e3,
                sigma * 1e3
            )
        }
    } else {
        let names: Vec<String> = findings
            .iter()
            .map(|f| {
                format!(
                    "{}{}",
                    f.effect,
                    f.axis
                        .as_deref()
                        .map_or(String::new(), |a| format!(" of {a}"))
                )
            })
            .collect();
        let rest = if beyond(&after, chi_after) {
            format!(
                "; a mismatch above the noise remains (RMS {:.3} µm vs floor {:.3} µm){where_text}",
                rms_after * 1e3,
                sigma * 1e3
            )
        } else {
            "; what remains is consistent with measurement noise".to_string()
        };
        format!(
            "missing physics found{faults}: {}; held-out RMS {:.3} → {:.3} µm{rest}",
            names.join(", "),
            to_rms(hold_before) * 1e3,
            to_rms(hold_after) * 1e3
        )
    };

    let series = series(&prep, &after, top_term.as_ref(), &tips_all);
    Ok(Report {
        samples: original.samples.len(),
        noise_floor_mm: sigma,
        rms_before_mm: rms_before,
        rms_after_mm: rms_after,
        holdout_rms_before_mm: to_rms(hold_before),
        holdout_rms_after_mm: to_rms(hold_after),
        holdout_folds: if wander {
            "5 folds of 10 short stretches of time, as a wander is in the model"
        } else {
            "5 contiguous time folds"
        },
        findings,
        verdict,
        noise_floor_xyz_mm: per,
        chi2_per_dof_before: chi_before,
        chi2_per_dof_after: chi_after,
        t_s: t_span,
        blocks,
        // The best of each slot: an axis's error-motion variants (which
        // components) are one candidate.
        candidates: first_round
            .iter()
            .enumerate()
            .filter(|(k, c)| {
                !first_round[..*k]
                    .iter()
                    .any(|o| o.term.family.same_slot(c.term.family))
            })
            .map(|(_, c)| c)
            .take(10)
            .map(|c| report::Candidate {
                effect: c.term.family.kind().name().to_string(),
                axis: c.term.family.axis_label(&prep.names),
                delta_bic: c.score,
            })
            .collect(),
        locate,
        method: format!(
            "forward stepwise over {} candidate effects; a candidate enters when it lowers the BIC (noise floor σ, ln n = {:.2} per parameter, plus search penalties) by more than {} and the held-out residual sum of squares (5 contiguous time folds) by more than ln n · σ² and 1 % of its excess over the noise",
            families.len(),
            ctx.ln_n,
            opts.bic_margin
        ),
        series,
        measurement,
        gaps: untidy::gaps_finding(original),
        time_stamps: regular.as_ref().map(untidy::RegularClock::note),
        held_commands: held.as_ref().map(untidy::HeldCommands::note),
        samples_used: prep.n,
        // Rounding far below the noise (an export with many decimals) is
        // not worth a line.
        resolution: if unresolved.max(tidy.rounding_xyz.0[0]) > 0.1 * sigma {
            tidy.resolution_keys(&prep)
        } else {
            BTreeMap::new()
        },
        rejected,
        unexplained,
    })
}

/// Notes a rejected candidate (once per effect and axis).
fn reject(list: &mut Vec<report::Rejected>, effect: &Effect, chain: &Chain, reason: String) {
    let name = effect.kind().name().to_string();
    let axis = effect.axis_label();
    if list.iter().any(|r| r.effect == name && r.axis == axis) {
        return;
    }
    list.push(report::Rejected {
        effect: name,
        axis,
        parameters: effect
            .parameters(report::effect_is_rotary(effect, chain))
            .into_iter()
            .collect(),
        reason,
    });
}

/// Exact tool tips of the model plus `specs`, each acting from its onset
/// sample, at the recorded motion states.
fn exact_tips(
    chain: &Chain,
    errors: Option<&ErrorModel>,
    prep: &Prepared,
    specs: &[EffectSpec],
    onsets: &[usize],
) -> Result<Vec<[f64; 3]>> {
    let mut m = simulate::TrueMachine::new(chain, errors, specs)?;
    let n_model = m.effects.len() - specs.len();
    for (k, &o) in onsets.iter().enumerate() {
        m.effects[n_model + k].t0 = prep.t[o.min(prep.n - 1)];
    }
    let mut active = 0u64;
    let mut out = Vec::with_capacity(prep.n);
    for i in 0..prep.n {
        for k in 0..n_model {
            if active & (1 << k) == 0
                && m.effects[k]
                    .spec
                    .from_block
                    .is_none_or(|b| prep.block[i].is_none_or(|bi| bi >= b))
            {
                active |= 1 << k;
                m.effects[k].t0 = prep.t[i];
            }
        }
        for (k, &o) in onsets.iter().enumerate() {
            if i >= o {
                active |= 1 << (n_model + k);
            }
        }
        let tip = m.tip(&prep.state(i), active);
        out.push([tip.x, tip.y, tip.z]);
    }
    Ok(out)
}

/// Windows and conditions where the residual departs from noise.
fn locate(prep: &Prepared, after: &[[f64; 3]], sigma: f64) -> Locate {
    let n = prep.n;
    let w = 20.min(n);
    let s2 = sigma * sigma;
    let mut windows = Vec::new();
    for k in 0..w {
        let a = k * n / w;
        let b = ((k + 1) * n / w).max(a + 1);
        let m = (b - a) as f64 * 3.0;
        let rb = rms(&prep.r[a..b]);
        let ra = rms(&after[a..b]);
        let z = |r: f64| (r * r * m / s2 - m) / (2.0 * m).sqrt();
        windows.push(Window {
            blocks: [block_of(prep, a), block_of(prep, b - 1)],
            t_s: [prep.t[a], prep.t[b - 1]],
            rms_before_mm: rb,
            rms_after_mm: ra,
            excess_sigma_before: z(rb),
            excess_sigma_after: z(ra),
        });
    }
    let mut conds: Vec<Condition> = Vec::new();
    for j in 0..prep.dof {
        let unit = if prep.kinds[j] == JointKind::Revolute {
            "deg"
        } else {
            "mm"
        };
        // Projection of the residual on the joint's tip direction.
        let proj: Vec<Option<f64>> = (0..n)
            .map(|i| {
                let jj = prep.jj(i, j);
                let norm = (jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]).sqrt();
                (norm > 1e-9).then(|| {
                    (prep.r[i][0] * jj[0] + prep.r[i][1] * jj[1] + prep.r[i][2] * jj[2]) / norm
                })
            })
            .collect();
        let mut push = |label: String, sel: &dyn Fn(usize) -> bool| {
            let (mut s, mut c) = (0.0, 0usize);
            for i in 0..n {
                if let Some(p) = proj[i]
                    && sel(i)
                {
                    s += p;
                    c += 1;
                }
            }
            if c >= 10 {
                let mean = s / c as f64;
                let z = mean * (c as f64).sqrt() / sigma;
                if z.abs() > 5.0 {
                    conds.push(Condition {
                        axis: prep.names[j].clone(),
                        condition: label,
                        samples: c,
                        mean_mm: mean,
                        z,
                    });
                }
            }
        };
        push("moving +".into(), &|i| prep.vj(i, j) > 1e-9);
        push("moving −".into(), &|i| prep.vj(i, j) < -1e-9);
        push("after a + motion (direction +)".into(), &|i| {
            prep.dirj(i, j) > 0.0
        });
        push("after a − motion (direction −)".into(), &|i| {
            prep.dirj(i, j) < 0.0
        });
        let mut speeds: Vec<f64> = (0..n)
            .map(|i| prep.vj(i, j).abs())
            .filter(|v| *v > 1e-9)
            .collect();
        if !speeds.is_empty() {
            let mid = speeds.len() / 2;
            speeds.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            let med = speeds[mid];
            // At a constant feed many samples sit at the median speed; they
            // count as not above it whatever their last bits (a relative
            // margin of 1e-6 keeps rounding from choosing their side).
            let above = med * (1.0 + 1e-6);
            push(format!("speed > {med:.3} {unit}/s"), &|i| {
                prep.vj(i, j).abs() > above
            });
        }
        let (lo, hi) = (0..n).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
            (a.min(prep.qj(i, j)), b.max(prep.qj(i, j)))
        });
        if hi > lo {
            for bin in 0..4 {
                let a = lo + (hi - lo) * bin as f64 / 4.0;
                let b = lo + (hi - lo) * (bin + 1) as f64 / 4.0;
                push(format!("position {a:.1}…{b:.1} {unit}"), &|i| {
                    let q = prep.qj(i, j);
                    q >= a && (q < b || bin == 3)
                });
            }
        }
    }
    conds.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
    conds.truncate(12);
    Locate {
        windows,
        conditions: conds,
    }
}

/// Data for the plots.
fn series(prep: &Prepared, after: &[[f64; 3]], top: Option<&Term>, tips: &[[f64; 3]]) -> Series {
    let n = prep.n;
    let mut s = Series {
        t: prep.t.clone(),
        before: prep.r.clone(),
        after: after.to_vec(),
        ..Default::default()
    };
    let Some(term) = top else {
        s.x_label = "time (s)".into();
        s.x = prep.t.clone();
        s.y_label = "|residual| (µm)".into();
        s.proj_before = prep
            .r
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .collect();
        s.proj_after = after
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .collect();
        return s;
    };
    let unit = |j: usize| {
        if prep.kinds[j] == JointKind::Revolute {
            "deg"
        } else {
            "mm"
        }
    };
    let fam = term.family;
    // Direction to project on, per sample.
    let dir: Vec<[f64; 3]> = (0..n)
        .map(|i| match fam {
            Family::RotaryCenterOffset(_) | Family::PivotLength => {
                let d = [
                    tips[i][0] - prep.model_tip[i][0],
                    tips[i][1] - prep.model_tip[i][1],
                    tips[i][2] - prep.model_tip[i][2],
                ];
                let nn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if nn > 1e-12 && !matches!(fam, Family::PivotLength) {
                    [d[0] / nn, d[1] / nn, d[2] / nn]
                } else {
                    prep.tool_axis[i]
                }
            }
            f => {
                let j = f.joint().unwrap_or(0);
                let jj = prep.jj(i, j);
                let nn = (jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2])
                    .sqrt()
                    .max(1e-12);
                [jj[0] / nn, jj[1] / nn, jj[2] / nn]
            }
        })
        .collect();
    let name = |j: usize| prep.names[j].clone();
    let (label, x): (String, Vec<f64>) = match fam {
        Family::ThermalDrift(_) => ("time (s)".into(), prep.t.clone()),
        Family::Squareness(a, _) => (
            format!("{} ({})", name(a), unit(a)),
            (0..n).map(|i| prep.qj(i, a)).collect(),
        ),
        Family::PivotLength => (
            "tool tilt from +z (deg)".into(),
            prep.tool_axis
                .iter()
                .map(|a| a[2].clamp(-1.0, 1.0).acos().to_degrees())
                .collect(),
        ),
        f => {
            let j = f.joint().unwrap_or(0);
            (
                format!("{} ({})", name(j), unit(j)),
                (0..n).map(|i| prep.qj(i, j)).collect(),
            )
        }
    };
    let what = match fam.axis_label(&prep.names) {
        Some(a) => format!(
            "residual along the {} {a} direction (µm)",
            fam.kind().name()
        ),
        None => format!("residual along the {} direction (µm)", fam.kind().name()),
    };
    s.x_label = label;
    s.x = x;
    s.y_label = what;
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    s.proj_before = (0..n).map(|i| dot(&prep.r[i], &dir[i])).collect();
    s.proj_after = (0..n).map(|i| dot(&after[i], &dir[i])).collect();
    s
}
