//! A slow wander of the measured tip with time: every measured tip off by
//! a smooth function of time, whatever the axes do (a laser tracker's air
//! path or mount warming, a probe's drift, a workpiece frame that creeps).
//! It is not machine physics, but on a recording whose program moves an
//! axis through its travel as time goes on it looks like that axis's
//! error motion, which differs in what it predicts where the axis returns
//! later. So the diagnosis weighs it as a candidate among the machine
//! effects (a cubic B-spline in time per workpiece coordinate), and a
//! wander that wins is reported here, with the measurement faults, and
//! never written into a model.

use super::super::report::{Finding, MeasurementFinding};
use super::registration::measurement_term;

/// The measurement finding of a fitted wander (`finding` as the stepwise
/// selection reported it).
pub fn wander_finding(finding: &Finding) -> MeasurementFinding {
    let p = |k: &str| finding.parameters.get(k).copied().unwrap_or(0.0);
    let condition = format!(
        "with time: the measured tip wanders by ({:.3}, {:.3}, {:.3}) µm peak to peak in the workpiece frame whatever the axes do (a curve with knots every {:.0} s) — the measuring system's drift (a tracker's air path or mount warming, a probe's drift), not machine physics",
        p("range_x_mm") * 1e3,
        p("range_y_mm") * 1e3,
        p("range_z_mm") * 1e3,
        p("knot_spacing_s"),
    );
    measurement_term(finding, "wander", condition)
}
