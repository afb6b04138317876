//! Physical signs and plausibility (`formats.md` §4): a fit that wants a
//! negative lag, backlash or time constant, or a size that the recording's
//! motion could not reveal, is evidence against that effect, not a finding.

use super::prepare::Prepared;
use crate::geometric::effects::Effect;
use crate::machine::chain::JointKind;

/// Largest servo lag a real servo loop has, s (they lie at 1 … 100 ms).
pub const MAX_LAG_S: f64 = 1.0;
/// Largest scale error, ppm (1 %).
pub const MAX_SCALE_PPM: f64 = 10_000.0;
/// Largest squareness error, µrad (0.57°).
pub const MAX_SQUARENESS_URAD: f64 = 10_000.0;
/// Largest location error of a rotary axis line, mm.
pub const MAX_CENTER_OFFSET_MM: f64 = 10.0;
/// Largest backlash, zero offset or cyclic amplitude, mm or deg.
pub const MAX_OFFSET: f64 = 10.0;

/// Largest tilt of an error motion (rad) taken for a bearing's or a
/// guideway's: 1 mrad (0.06°) is far beyond any axis in service.
pub const MAX_MOTION_TILT_RAD: f64 = 1e-3;
/// Largest pivot-length error, mm.
pub const MAX_PIVOT_MM: f64 = 100.0;
/// Largest thermal drift, mm.
pub const MAX_DRIFT_MM: f64 = 1.0;
/// Least turn of a rotary axis over which its error motion is fitted, deg.
pub const MIN_TURN_FOR_MOTION_DEG: f64 = 90.0;
/// Least turn of a rotary axis that reveals where its axis line is, deg.
pub const MIN_TURN_DEG: f64 = 2.0;

/// Why `effect`, fitted to `prep`, is not physics; `None` when it may be.
pub fn implausible(effect: &Effect, prep: &Prepared) -> Option<String> {
    let joint = |name: &str| prep.names.iter().position(|n| n == name);
    let unit = |j: usize| {
        if prep.kinds[j] == JointKind::Revolute {
            "deg"
        } else {
            "mm"
        }
    };
    let range = |j: usize| {
        let (lo, hi) = (0..prep.n).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
            (a.min(prep.qj(i, j)), b.max(prep.qj(i, j)))
        });
        (hi - lo).max(0.0)
    };
    let reversals = |j: usize| {
        (1..prep.n)
            .filter(|&i| prep.dirj(i, j) * prep.dirj(i - 1, j) < 0.0)
            .count()
    };
    match effect {
        Effect::Backlash { axis, value } => {
            let j = joint(axis)?;
            if *value <= 0.0 {
                return Some(format!(
                    "a negative backlash ({value:.6} {}): the axis would lead its command after a reversal",
                    unit(j)
                ));
            }
            if *value > MAX_OFFSET {
                return Some(format!(
                    "a backlash of {value:.3} {} is not a real drive's",
                    unit(j)
                ));
            }
            if reversals(j) == 0 {
                return Some(format!(
                    "{axis} never reverses in the recording, so a backlash cannot show"
                ));
            }
            None
        }
        Effect::ServoLag { axis, tau_s } => {
            if *tau_s <= 0.0 {
                return Some(format!(
                    "a negative lag ({:.3} ms): {axis} would move before its command",
                    tau_s * 1e3
                ));
            }
            (*tau_s > MAX_LAG_S)
                .then(|| format!("a lag of {tau_s:.3} s is far beyond any servo loop (1 … 100 ms)"))
        }
        Effect::ThermalDrift {
            tau_s,
            amplitude_mm,
            ..
        } => {
            if *tau_s <= 0.0 {
                return Some(format!("a negative time constant ({tau_s:.1} s)"));
            }
            (amplitude_mm.abs() > MAX_DRIFT_MM).then(|| {
                format!("a thermal drift of {amplitude_mm:.3} mm is not a machine's (at most {MAX_DRIFT_MM} mm)")
            })
        }
        Effect::Scale { axis, ppm } => {
            let j = joint(axis)?;
            if ppm.abs() > MAX_SCALE_PPM {
                return Some(format!(
                    "a scale error of {ppm:.0} ppm (more than 1 %) is not a measuring system's"
                ));
            }
            (range(j) < 1.0).then(|| {
                format!(
                    "{axis} moves only {:.3} {} in the recording, too little to reveal a scale error",
                    range(j),
                    unit(j)
                )
            })
        }
        Effect::Squareness { axes, angle_urad } => {
            let j = joint(&axes[0])?;
            if angle_urad.abs() > MAX_SQUARENESS_URAD {
                return Some(format!(
                    "a squareness error of {angle_urad:.0} µrad is not an assembly's"
                ));
            }
            (range(j) < 1.0).then(|| {
                format!(
                    "{} moves only {:.3} {} in the recording, too little to reveal a squareness error",
                    axes[0],
                    range(j),
                    unit(j)
                )
            })
        }
        Effect::Cyclic {
            axis,
            amplitude,
            period,
            ..
        } => {
            let j = joint(axis)?;
            if amplitude.abs() > MAX_OFFSET || *period <= 0.0 {
                return Some(format!(
                    "a cyclic error of amplitude {amplitude:.3} {} and period {period:.3} {} is not a drive's",
                    unit(j),
                    unit(j)
                ));
            }
            (range(j) < 0.5 * period).then(|| {
                format!(
                    "{axis} moves {:.3} {}, less than half the period {period:.3}",
                    range(j),
                    unit(j)
                )
            })
        }
        Effect::ZeroOffset { axis, value } => {
            let j = joint(axis)?;
            (value.abs() > MAX_OFFSET).then(|| {
                format!(
                    "a zero offset of {value:.3} {} is not a reference error",
                    unit(j)
                )
            })
        }
        Effect::RotaryCenterOffset { axis, offset_mm } => {
            let j = joint(axis)?;
            let d = offset_mm.iter().map(|x| x * x).sum::<f64>().sqrt();
            if range(j) < MIN_TURN_DEG {
                return Some(format!(
                    "{axis} turns only {:.3}° in the recording: the location of its axis line does not show",
                    range(j)
                ));
            }
            (d > MAX_CENTER_OFFSET_MM).then(|| {
                format!("an axis line {d:.3} mm from the modelled one is not a location error")
            })
        }
        Effect::Vibration {
            amplitude,
            frequency_hz,
            axis,
            ..
        } => {
            let j = joint(axis)?;
            if *frequency_hz <= 0.0 {
                return Some(format!("a negative frequency ({frequency_hz:.4} Hz)"));
            }
            (amplitude.abs() > MAX_OFFSET).then(|| {
                format!(
                    "a vibration of amplitude {amplitude:.3} {} is not a structure's",
                    unit(j)
                )
            })
        }
        Effect::ErrorMotion {
            axis,
            terms,
            span,
            arc,
        } => {
            let j = joint(axis)?;
            let (peak, tilt) =
                crate::geometric::effects::error_motion_peaks(terms, span.as_ref(), *arc);
            if tilt > MAX_MOTION_TILT_RAD {
                return Some(format!(
                    "an error motion that tilts by {:.0} µrad is not a bearing's or a guideway's",
                    tilt * 1e6
                ));
            }
            if span.is_some() {
                return (peak > MAX_OFFSET)
                    .then(|| format!("an error motion of {peak:.3} mm is not a guideway's"));
            }
            if range(j) < MIN_TURN_FOR_MOTION_DEG {
                return Some(format!(
                    "{axis} turns only {:.1}° in the recording: an error motion over a turn does not show",
                    range(j)
                ));
            }
            (peak > MAX_OFFSET)
                .then(|| format!("an error motion of {peak:.3} mm is not a bearing's"))
        }
        Effect::PivotLength { delta_mm } => (delta_mm.abs() > MAX_PIVOT_MM)
            .then(|| format!("a pivot length {delta_mm:.3} mm off is another tool, not an error")),
        // The misfit check bounds it (a median miss of 5 mm is another
        // machine or another frame).
        Effect::Registration { .. } | Effect::Wander { .. } => None,
    }
}
