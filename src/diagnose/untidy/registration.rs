//! A registration of the measuring system: every measured tip a constant
//! vector off in the workpiece frame (a tracker or probe zeroed off, a
//! workpiece frame set up off). It is not machine physics, but on a
//! machine whose workpiece turns with a rotary table it is exactly the
//! once-per-turn radial error motion of that table (ISO 230-7 removes
//! that harmonic as the centring of the artefact for the same reason), and
//! a constant along one linear axis is that axis's zero offset. So the
//! diagnosis weighs it as a candidate with three parameters among the
//! machine effects, and a registration that wins is reported here, with
//! the measurement faults, and never written into a model.

use super::super::report::{Finding, MeasurementFinding};

/// The measurement finding of a fitted registration (`finding` as the
/// stepwise selection reported it).
pub fn registration_finding(finding: &Finding) -> MeasurementFinding {
    let p = |k: &str| finding.parameters.get(k).copied().unwrap_or(0.0) * 1e3;
    let condition = format!(
        "everywhere: the measured tip is ({:.3}, {:.3}, {:.3}) µm off in the workpiece frame whatever the axes do — the registration of the measuring system (a tracker or probe zeroed off, a workpiece frame set up off), not machine physics",
        p("dx_mm"),
        p("dy_mm"),
        p("dz_mm"),
    );
    measurement_term(finding, "registration", condition)
}

/// The measurement finding of a fitted registration step (`finding` as
/// the stepwise selection reported it, its `where_` from the onset on).
pub fn registration_step_finding(finding: &Finding) -> MeasurementFinding {
    let p = |k: &str| finding.parameters.get(k).copied().unwrap_or(0.0) * 1e3;
    let condition = format!(
        "from {:.3} s on: the measured tip moves by ({:.3}, {:.3}, {:.3}) µm in the workpiece frame at once, whatever the axes do — the measuring system registered anew part-way (a tracker that re-acquired its target after a beam break, a probe re-zeroed), not machine physics",
        finding.where_.t_s[0],
        p("dx_mm"),
        p("dy_mm"),
        p("dz_mm"),
    );
    measurement_term(finding, "registration_step", condition)
}

/// A measurement term the selection fitted (a registration, a wander) as
/// a measurement finding: `condition` says what it is; the note that it is
/// never written into a model and the best machine explanation it beat
/// are added.
pub fn measurement_term(finding: &Finding, effect: &str, condition: String) -> MeasurementFinding {
    let alternative = finding.runner_up.as_ref().map_or(String::new(), |r| {
        format!(
            "; the best machine explanation, {}{}, fits it worse by ΔBIC {:.1}",
            r.effect,
            r.axis
                .as_deref()
                .map_or(String::new(), |a| format!(" of {a}")),
            r.delta_bic
        )
    });
    let mut where_ = finding.where_.clone();
    where_.condition = format!(
        "{condition}; fitted with the machine effects and never written into a model{alternative}"
    );
    MeasurementFinding {
        effect: effect.into(),
        axis: None,
        parameters: finding.parameters.clone(),
        uncertainty: finding.uncertainty.clone(),
        where_,
        rms_explained_mm: finding.rms_explained_mm,
        machine_physics: false,
        samples: Vec::new(),
    }
}
