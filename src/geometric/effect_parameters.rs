//! An effect from its kind, axis label and named parameters: the form
//! of `--inject` and of the effects in a model file.

use std::collections::BTreeMap;

use super::effects::{Effect, EffectKind};
use super::error_motion::motion_from_parameters;

impl Effect {
    /// Builds an effect from its kind, axis label and named parameters (the
    /// inverse of [`Effect::parameters`]; `_mm` and `_deg` are both accepted).
    /// Errors are plain messages; callers add the location.
    pub fn from_parameters(
        kind: EffectKind,
        axis: Option<&str>,
        params: &BTreeMap<String, f64>,
    ) -> std::result::Result<Effect, String> {
        Self::from_parameters_with(kind, axis, params, false)
    }

    /// [`Effect::from_parameters`], refusing besides a parameter the
    /// effect does not have (`phse=90`: a typing error that would leave
    /// the phase at its default), as given on a command line.
    pub fn from_parameters_strict(
        kind: EffectKind,
        axis: Option<&str>,
        params: &BTreeMap<String, f64>,
    ) -> std::result::Result<Effect, String> {
        Self::from_parameters_with(kind, axis, params, true)
    }

    fn from_parameters_with(
        kind: EffectKind,
        axis: Option<&str>,
        params: &BTreeMap<String, f64>,
        strict: bool,
    ) -> std::result::Result<Effect, String> {
        // The names asked for, to tell the parameters given that no one
        // asked for.
        let asked: std::cell::RefCell<Vec<&str>> = Default::default();
        let effect = Self::from_known_parameters(kind, axis, params, &asked)?;
        if strict && kind != EffectKind::ErrorMotion {
            let asked = asked.borrow();
            if let Some(k) = params.keys().find(|k| !asked.contains(&k.as_str())) {
                return Err(format!(
                    "{kind} has no parameter `{k}` (its parameters: {})",
                    asked.join(", ")
                ));
            }
        }
        Ok(effect)
    }

    fn from_known_parameters<'n>(
        kind: EffectKind,
        axis: Option<&str>,
        params: &BTreeMap<String, f64>,
        asked: &std::cell::RefCell<Vec<&'n str>>,
    ) -> std::result::Result<Effect, String> {
        let get = |names: &[&'n str]| -> std::result::Result<f64, String> {
            asked.borrow_mut().extend_from_slice(names);
            let given: Vec<&&str> = names.iter().filter(|n| params.contains_key(**n)).collect();
            if given.len() > 1 {
                // `value` is what follows the axis (`X=0.002`).
                let other = given.iter().find(|n| ***n != "value").unwrap_or(&given[0]);
                return Err(if given.contains(&&"value") {
                    format!(
                        "{kind}: `{other}` given besides the value after the axis (`X=…`), which is the same parameter; give one"
                    )
                } else {
                    format!(
                        "{kind}: `{}` and `{}` name the same parameter; give one",
                        given[0], given[1]
                    )
                });
            }
            for n in names {
                if let Some(v) = params.get(*n) {
                    return if v.is_finite() {
                        Ok(*v)
                    } else {
                        Err(format!("parameter `{n}` must be a finite number"))
                    };
                }
            }
            Err(format!(
                "{kind} needs the parameter `{}` (parameters given: {})",
                names[0],
                params.keys().cloned().collect::<Vec<_>>().join(", ")
            ))
        };
        let opt = |names: &[&'n str], default: f64| -> std::result::Result<f64, String> {
            asked.borrow_mut().extend_from_slice(names);
            if names.iter().any(|n| params.contains_key(*n)) {
                get(names)
            } else {
                Ok(default)
            }
        };
        let one_axis = || -> std::result::Result<String, String> {
            match axis.map(str::trim) {
                Some(a) if !a.is_empty() && a.chars().all(|c| c.is_ascii_alphabetic()) => {
                    Ok(a.to_ascii_uppercase())
                }
                _ => Err(format!("{kind} needs one axis letter")),
            }
        };
        Ok(match kind {
            EffectKind::Backlash => Effect::Backlash {
                axis: one_axis()?,
                value: get(&["value_mm", "value_deg", "value"])?,
            },
            EffectKind::ServoLag => Effect::ServoLag {
                axis: one_axis()?,
                tau_s: get(&["tau_s", "tau", "value"])?,
            },
            EffectKind::ThermalDrift => {
                let tau_s = get(&["tau_s", "tau"])?;
                if tau_s <= 0.0 {
                    return Err("thermal_drift: tau_s must be positive".into());
                }
                Effect::ThermalDrift {
                    axis: one_axis()?,
                    amplitude_mm: get(&["amplitude_mm", "amplitude", "value"])?,
                    tau_s,
                }
            }
            EffectKind::Scale => Effect::Scale {
                axis: one_axis()?,
                ppm: get(&["ppm", "value"])?,
            },
            EffectKind::Squareness => {
                let a = one_axis()?;
                let letters: Vec<char> = a.chars().collect();
                if letters.len() != 2 || letters[0] == letters[1] {
                    return Err(format!(
                        "squareness needs a pair of two different axes such as XZ, not `{a}`"
                    ));
                }
                Effect::Squareness {
                    axes: [letters[0].to_string(), letters[1].to_string()],
                    angle_urad: get(&["angle_urad", "value"])?,
                }
            }
            EffectKind::Cyclic => {
                let period = get(&["period_mm", "period_deg", "period"])?;
                if period <= 0.0 {
                    return Err("cyclic: the period must be positive".into());
                }
                Effect::Cyclic {
                    axis: one_axis()?,
                    amplitude: get(&["amplitude_mm", "amplitude_deg", "amplitude", "value"])?,
                    period,
                    phase_deg: opt(&["phase_deg", "phase"], 0.0)?,
                }
            }
            EffectKind::ZeroOffset => Effect::ZeroOffset {
                axis: one_axis()?,
                value: get(&["value_mm", "value_deg", "value"])?,
            },
            EffectKind::RotaryCenterOffset => Effect::RotaryCenterOffset {
                axis: one_axis()?,
                offset_mm: [
                    opt(&["dx_mm", "dx"], 0.0)?,
                    opt(&["dy_mm", "dy"], 0.0)?,
                    opt(&["dz_mm", "dz"], 0.0)?,
                ],
            },
            EffectKind::PivotLength => Effect::PivotLength {
                delta_mm: get(&["delta_mm", "delta", "value"])?,
            },
            EffectKind::Registration => Effect::Registration {
                offset_mm: [
                    opt(&["dx_mm", "dx"], 0.0)?,
                    opt(&["dy_mm", "dy"], 0.0)?,
                    opt(&["dz_mm", "dz"], 0.0)?,
                ],
            },
            EffectKind::Wander => {
                return Err(
                    "wander is what diagnose reports of a measurement, not an effect to inject"
                        .into(),
                );
            }
            EffectKind::ErrorMotion => {
                let axis = one_axis()?;
                let (terms, span, arc) = motion_from_parameters(&axis, params)?;
                Effect::ErrorMotion {
                    axis,
                    terms,
                    span,
                    arc,
                }
            }
            EffectKind::Vibration => {
                let frequency_hz = get(&["frequency_hz", "frequency", "f"])?;
                if frequency_hz <= 0.0 {
                    return Err("vibration: the frequency must be positive".into());
                }
                Effect::Vibration {
                    axis: one_axis()?,
                    amplitude: get(&["amplitude_mm", "amplitude_deg", "amplitude", "value"])?,
                    frequency_hz,
                    phase_deg: opt(&["phase_deg", "phase"], 0.0)?,
                }
            }
        })
    }
}
