//! The catalogue of effects (`formats.md` §4): physics a nominal model
//! commonly leaves out, each a change of a joint's commanded position
//! (`q → q + Δq`) or a fixed error element, passed through the chain.
//!
//! | effect | parameters | Δ |
//! | --- | --- | --- |
//! | `backlash` | `value_mm` / `value_deg` | Δq = −value/2 · (direction of the last motion) |
//! | `servo_lag` | `tau_s` | Δq = −τ · dq/dt |
//! | `thermal_drift` | `amplitude_mm`, `tau_s` | Δq = a · (1 − exp(−(t − t₀)/τ)), t₀ the onset |
//! | `scale` | `ppm` | Δq = s · q |
//! | `squareness` | `angle_urad` | Δq₂ = S · q₁ (pair `XZ`: moving X moves the tool along Z) |
//! | `cyclic` | `amplitude_mm`, `period_mm`, `phase_deg` | Δq = a · sin(2π q / p + φ) |
//! | `zero_offset` | `value_mm` / `value_deg` | Δq = constant |
//! | `rotary_center_offset` | `dx_mm`, `dy_mm`, `dz_mm` | the joint turns about an axis line displaced by d (frame before the joint) |
//! | `pivot_length` | `delta_mm` | the tip sits δ further along the tool axis (i, j, k) |
//! | `vibration` | `amplitude_mm`, `frequency_hz`, `phase_deg` | Δq = a · sin(2π f t + φ), t the recording's time |
//! | `error_motion` | `peak_mm`, terms `EXC_cos1_mm`, … | a rotary axis's error motion over one turn: component c = Σₖ aₖ cos kq + bₖ sin kq |
//!
//! Rotary axes use `_deg` where a linear axis uses `_mm` (`value_deg`,
//! `amplitude_deg`, `period_deg`). The command-line syntax is parsed by
//! [`super::effect_spec::parse_effect_spec`].

use std::collections::BTreeMap;
use std::fmt;

use nalgebra::{Matrix4, Vector3};

pub use super::direction::{DIRECTION_DEAD_BAND, DirectionTracker};
pub use super::error_motion::{
    MotionSpan, MotionTerm, TurnArc, component_name, error_motion_at, error_motion_components,
    error_motion_peaks,
};
pub use super::wander::{wander_at, wander_knot_spacing, wander_range};
use crate::error::{Error, Location, Result};
use crate::machine::chain::{Chain, ErrorMotion, JointKind, translation};

/// The names of the catalogue, in the order of `formats.md` §4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum EffectKind {
    /// Reversal error.
    Backlash,
    /// Following error proportional to speed.
    ServoLag,
    /// Exponential growth with time.
    ThermalDrift,
    /// Linear scale error.
    Scale,
    /// Out-of-squareness of two linear axes.
    Squareness,
    /// Periodic error of an axis (ball-screw pitch error).
    Cyclic,
    /// Constant offset.
    ZeroOffset,
    /// Location error of a rotary axis.
    RotaryCenterOffset,
    /// Tool length / pivot length error.
    PivotLength,
    /// A time-periodic motion at a fixed frequency.
    Vibration,
    /// A position-dependent error motion of a rotary axis.
    ErrorMotion,
    /// Not machine physics: the measuring system registered off the
    /// workpiece frame by a constant vector (a tracker or probe zero, a
    /// workpiece frame set up off). `diagnose` weighs it against the
    /// machine effects and reports it as a measurement fault; it is not
    /// in [`EffectKind::ALL`], so it is never injected or written into a
    /// model.
    Registration,
    /// Not machine physics: the measured tip wandering slowly with time,
    /// whatever the axes do (a tracker's air or mount warming, a probe's
    /// drift). Like [`EffectKind::Registration`] it is weighed against the
    /// machine effects, reported as a measurement fault and never injected
    /// or written into a model.
    Wander,
}

impl EffectKind {
    /// Every kind, in catalogue order.
    pub const ALL: [EffectKind; 11] = [
        EffectKind::Backlash,
        EffectKind::ServoLag,
        EffectKind::ThermalDrift,
        EffectKind::Scale,
        EffectKind::Squareness,
        EffectKind::Cyclic,
        EffectKind::ZeroOffset,
        EffectKind::RotaryCenterOffset,
        EffectKind::PivotLength,
        EffectKind::Vibration,
        EffectKind::ErrorMotion,
    ];

    /// The catalogue name (`backlash`, `servo_lag`, …).
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::Backlash => "backlash",
            EffectKind::ServoLag => "servo_lag",
            EffectKind::ThermalDrift => "thermal_drift",
            EffectKind::Scale => "scale",
            EffectKind::Squareness => "squareness",
            EffectKind::Cyclic => "cyclic",
            EffectKind::ZeroOffset => "zero_offset",
            EffectKind::RotaryCenterOffset => "rotary_center_offset",
            EffectKind::PivotLength => "pivot_length",
            EffectKind::Vibration => "vibration",
            EffectKind::ErrorMotion => "error_motion",
            EffectKind::Registration => "registration",
            EffectKind::Wander => "wander",
        }
    }

    /// Whether it is a fault of the measurement rather than machine
    /// physics (`formats.md` §2c).
    pub fn is_measurement(self) -> bool {
        matches!(self, EffectKind::Registration | EffectKind::Wander)
    }

    /// The kind called `name` (case-insensitive; `-` may stand for `_`).
    pub fn from_name(name: &str) -> Option<EffectKind> {
        let n = name.trim().to_ascii_lowercase().replace('-', "_");
        let n = match n.as_str() {
            "rotary_centre_offset" => "rotary_center_offset",
            other => other,
        };
        EffectKind::ALL.into_iter().find(|k| k.name() == n)
    }

    /// Dynamic effects depend on the direction of motion, the speed or the
    /// time, not on the position alone.
    pub fn is_dynamic(self) -> bool {
        matches!(
            self,
            EffectKind::Backlash
                | EffectKind::ServoLag
                | EffectKind::ThermalDrift
                | EffectKind::Vibration
        )
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One effect with its parameters. Values are in the axis's units: mm for
/// linear axes, degrees for rotary axes (so `value`, `amplitude` and
/// `period` are `_mm` or `_deg` in files).
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// Lags the command by value/2 against the direction of the last motion.
    Backlash {
        /// Axis letter.
        axis: String,
        /// Reversal value, mm or deg.
        value: f64,
    },
    /// Δq = −τ · dq/dt.
    ServoLag {
        /// Axis letter.
        axis: String,
        /// Time constant, s.
        tau_s: f64,
    },
    /// Δq = a · (1 − exp(−(t − t₀)/τ)) (linear axes).
    ThermalDrift {
        /// Axis letter.
        axis: String,
        /// Final amplitude, mm.
        amplitude_mm: f64,
        /// Time constant, s.
        tau_s: f64,
    },
    /// Δq = s · q.
    Scale {
        /// Axis letter.
        axis: String,
        /// Scale error, ppm (µm/m).
        ppm: f64,
    },
    /// Δq₂ = S · q₁ for the pair `[first, second]` (both linear).
    Squareness {
        /// `[first, second]` axis letters.
        axes: [String; 2],
        /// Angle, µrad.
        angle_urad: f64,
    },
    /// Δq = a · sin(2π q / p + φ).
    Cyclic {
        /// Axis letter.
        axis: String,
        /// Amplitude, mm or deg.
        amplitude: f64,
        /// Period, mm or deg.
        period: f64,
        /// Phase, deg.
        phase_deg: f64,
    },
    /// Δq = constant.
    ZeroOffset {
        /// Axis letter.
        axis: String,
        /// Offset, mm or deg.
        value: f64,
    },
    /// The rotary axis turns about a line displaced by `offset_mm`, in the
    /// frame just before the joint.
    RotaryCenterOffset {
        /// Rotary axis letter.
        axis: String,
        /// Displacement `[dx, dy, dz]`, mm.
        offset_mm: [f64; 3],
    },
    /// The tool tip sits `delta_mm` further along the tool axis (i, j, k):
    /// a positive value moves the tip towards the spindle, i.e. the real
    /// tool (pivot) length is `delta_mm` shorter than modelled.
    PivotLength {
        /// Displacement along the tool axis, mm.
        delta_mm: f64,
    },
    /// The error motion of a rotary axis over one turn, as a Fourier series
    /// of its components (ISO 230-1: `EXC`, `EYC`, `EZC` translations in mm,
    /// `EAC`, `EBC` tilts in rad), in the joint's frame.
    ErrorMotion {
        /// Rotary axis letter.
        axis: String,
        /// `(component 0…5, harmonic k ≥ 1, cos coefficient, sin
        /// coefficient)`: component c moves by a·cos(kq) + b·sin(kq); with a
        /// `span`, `(component, basis index, coefficient, 0)`.
        terms: Vec<MotionTerm>,
        /// For a linear axis: the B-spline basis over its travel.
        span: Option<MotionSpan>,
        /// For a rotary axis found over part of a turn: that arc (rad),
        /// beyond which the motion is held; `None` for a whole turn.
        arc: TurnArc,
    },
    /// Δq = a · sin(2π f t + φ), t the recording's time.
    Vibration {
        /// Axis letter.
        axis: String,
        /// Amplitude, mm or deg.
        amplitude: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase at t = 0, deg.
        phase_deg: f64,
    },
    /// Not machine physics: every measured tip is `offset_mm` off in the
    /// workpiece frame (the measuring system's registration).
    Registration {
        /// The offset `[dx, dy, dz]` of the measured tip, workpiece frame, mm.
        offset_mm: [f64; 3],
    },
    /// Not machine physics: the measured tip wanders with time (a smooth
    /// function of time in each workpiece coordinate).
    Wander {
        /// The cubic B-spline basis in time (its `lo` and `hi` in s).
        span: MotionSpan,
        /// The coefficient of each basis function, `[x, y, z]` in the
        /// workpiece frame, mm.
        coef_mm: Vec<[f64; 3]>,
    },
}

/// An effect with an optional start: it acts from the first sample of block
/// `from_block` on (from the start when `None`).
#[derive(Debug, Clone, PartialEq)]
pub struct EffectSpec {
    /// The effect.
    pub effect: Effect,
    /// First block in which it acts.
    pub from_block: Option<u64>,
}

impl From<Effect> for EffectSpec {
    fn from(effect: Effect) -> Self {
        EffectSpec {
            effect,
            from_block: None,
        }
    }
}

/// True when `axis` names a rotary axis on `chain` (revolute joint), or —
/// without a chain — when it is A, B or C.
pub fn axis_is_rotary(chain: Option<&Chain>, axis: &str) -> bool {
    match chain.and_then(|c| c.joint_index(axis).map(|j| c.joints()[j].kind)) {
        Some(k) => k == JointKind::Revolute,
        None => matches!(axis.to_ascii_uppercase().as_str(), "A" | "B" | "C"),
    }
}

impl Effect {
    /// Its kind.
    pub fn kind(&self) -> EffectKind {
        match self {
            Effect::Backlash { .. } => EffectKind::Backlash,
            Effect::ServoLag { .. } => EffectKind::ServoLag,
            Effect::ThermalDrift { .. } => EffectKind::ThermalDrift,
            Effect::Scale { .. } => EffectKind::Scale,
            Effect::Squareness { .. } => EffectKind::Squareness,
            Effect::Cyclic { .. } => EffectKind::Cyclic,
            Effect::ZeroOffset { .. } => EffectKind::ZeroOffset,
            Effect::RotaryCenterOffset { .. } => EffectKind::RotaryCenterOffset,
            Effect::PivotLength { .. } => EffectKind::PivotLength,
            Effect::Vibration { .. } => EffectKind::Vibration,
            Effect::ErrorMotion { .. } => EffectKind::ErrorMotion,
            Effect::Registration { .. } => EffectKind::Registration,
            Effect::Wander { .. } => EffectKind::Wander,
        }
    }

    /// The axis label of the report: one letter, a pair (`XZ`), or `None`.
    pub fn axis_label(&self) -> Option<String> {
        match self {
            Effect::Backlash { axis, .. }
            | Effect::ServoLag { axis, .. }
            | Effect::ThermalDrift { axis, .. }
            | Effect::Scale { axis, .. }
            | Effect::Cyclic { axis, .. }
            | Effect::ZeroOffset { axis, .. }
            | Effect::RotaryCenterOffset { axis, .. }
            | Effect::Vibration { axis, .. }
            | Effect::ErrorMotion { axis, .. } => Some(axis.clone()),
            Effect::Squareness { axes, .. } => Some(format!("{}{}", axes[0], axes[1])),
            Effect::PivotLength { .. } | Effect::Registration { .. } | Effect::Wander { .. } => {
                None
            }
        }
    }

    /// Whether the parameter `name` of [`Effect::parameters`] was chosen
    /// rather than fitted (it has no uncertainty): the range an error
    /// motion or a wander was fitted over, its number of basis functions
    /// and its knot spacing.
    pub fn is_chosen_parameter(name: &str) -> bool {
        matches!(
            name,
            "from_deg"
                | "to_deg"
                | "from_mm"
                | "to_mm"
                | "basis"
                | "from_s"
                | "to_s"
                | "knot_spacing_s"
        )
    }

    /// Parameters with unit-suffixed names (`formats.md` §4); `rotary` says
    /// whether the axis is rotary (`_deg` instead of `_mm`).
    pub fn parameters(&self, rotary: bool) -> Vec<(String, f64)> {
        let u = if rotary { "deg" } else { "mm" };
        let p = |n: &str, v: f64| (n.to_string(), v);
        match self {
            Effect::Backlash { value, .. } | Effect::ZeroOffset { value, .. } => {
                vec![p(&format!("value_{u}"), *value)]
            }
            Effect::ServoLag { tau_s, .. } => vec![p("tau_s", *tau_s)],
            Effect::ThermalDrift {
                amplitude_mm,
                tau_s,
                ..
            } => vec![p("amplitude_mm", *amplitude_mm), p("tau_s", *tau_s)],
            Effect::Scale { ppm, .. } => vec![p("ppm", *ppm)],
            Effect::Squareness { angle_urad, .. } => vec![p("angle_urad", *angle_urad)],
            Effect::Cyclic {
                amplitude,
                period,
                phase_deg,
                ..
            } => vec![
                p(&format!("amplitude_{u}"), *amplitude),
                p(&format!("period_{u}"), *period),
                p("phase_deg", *phase_deg),
            ],
            Effect::RotaryCenterOffset { offset_mm, .. } | Effect::Registration { offset_mm } => {
                vec![
                    p("dx_mm", offset_mm[0]),
                    p("dy_mm", offset_mm[1]),
                    p("dz_mm", offset_mm[2]),
                ]
            }
            Effect::PivotLength { delta_mm } => vec![p("delta_mm", *delta_mm)],
            Effect::Wander { span, coef_mm } => {
                let range = wander_range(span, coef_mm);
                vec![
                    p("range_x_mm", range[0]),
                    p("range_y_mm", range[1]),
                    p("range_z_mm", range[2]),
                    p("from_s", span.lo),
                    p("to_s", span.hi),
                    p("knot_spacing_s", wander_knot_spacing(span)),
                ]
            }
            Effect::Vibration {
                amplitude,
                frequency_hz,
                phase_deg,
                ..
            } => vec![
                p(&format!("amplitude_{u}"), *amplitude),
                p("frequency_hz", *frequency_hz),
                p("phase_deg", *phase_deg),
            ],
            Effect::ErrorMotion {
                axis,
                terms,
                span,
                arc,
            } => {
                let (peak_mm, peak_rad) = error_motion_peaks(terms, span.as_ref(), *arc);
                let mut v = vec![p("peak_mm", peak_mm)];
                if terms.iter().any(|t| t.0 >= 3) {
                    v.push(p("peak_urad", peak_rad * 1e6));
                }
                if let Some([lo, hi]) = arc {
                    v.push(p("from_deg", lo.to_degrees()));
                    v.push(p("to_deg", hi.to_degrees()));
                }
                if let Some(sp) = span {
                    v.push(p("from_mm", sp.lo));
                    v.push(p("to_mm", sp.hi));
                    v.push(p("basis", sp.basis.len() as f64));
                }
                for &(c, k, a, b) in terms {
                    let (unit, scale) = if c < 3 { ("mm", 1.0) } else { ("urad", 1e6) };
                    let name = component_name(c, axis);
                    if span.is_some() {
                        v.push(p(&format!("{name}_b{k}_{unit}"), a * scale));
                    } else {
                        v.push(p(&format!("{name}_cos{k}_{unit}"), a * scale));
                        v.push(p(&format!("{name}_sin{k}_{unit}"), b * scale));
                    }
                }
                v
            }
        }
    }
}

impl EffectSpec {
    /// The effect as JSON: `{"effect", "axis", "parameters", "from_block"}`.
    pub fn to_json(&self, chain: Option<&Chain>) -> serde_json::Value {
        let label = self.effect.axis_label();
        let rotary = label
            .as_deref()
            .is_some_and(|a| a.len() == 1 && axis_is_rotary(chain, a));
        let mut params = serde_json::Map::new();
        for (n, v) in self.effect.parameters(rotary) {
            params.insert(n, serde_json::json!(v));
        }
        serde_json::json!({
            "effect": self.effect.kind().name(),
            "axis": label,
            "parameters": params,
            "from_block": self.from_block,
        })
    }

    /// Reads an effect from its JSON form ([`EffectSpec::to_json`]).
    pub fn from_json(v: &serde_json::Value) -> std::result::Result<EffectSpec, String> {
        let name = v
            .get("effect")
            .and_then(|e| e.as_str())
            .ok_or("an effect needs a string field `effect`")?;
        let kind = EffectKind::from_name(name).ok_or_else(|| {
            format!(
                "unknown effect `{name}` (known: {})",
                EffectKind::ALL.map(|k| k.name()).join(", ")
            )
        })?;
        let axis = v.get("axis").and_then(|a| a.as_str());
        let mut params = BTreeMap::new();
        if let Some(map) = v.get("parameters").and_then(|p| p.as_object()) {
            for (k, val) in map {
                let x = val
                    .as_f64()
                    .ok_or_else(|| format!("{name}: parameter `{k}` must be a number"))?;
                params.insert(k.clone(), x);
            }
        }
        let effect = Effect::from_parameters(kind, axis, &params)?;
        let from_block = match v.get("from_block") {
            None | Some(serde_json::Value::Null) => None,
            Some(b) => Some(
                b.as_u64()
                    .ok_or_else(|| format!("{name}: `from_block` must be a block number"))?,
            ),
        };
        Ok(EffectSpec { effect, from_block })
    }
}

/// The motion state of the machine at one instant, in file units.
#[derive(Debug, Clone, Copy)]
pub struct MotionState<'a> {
    /// Time since the start, s.
    pub t: f64,
    /// Commanded positions (mm, deg), chain order.
    pub q: &'a [f64],
    /// Commanded velocities (mm/s, deg/s), chain order.
    pub v: &'a [f64],
    /// Direction of the last motion per joint (−1, 0, +1).
    pub dir: &'a [f64],
}

/// An effect resolved against a chain: joint indices checked.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundEffect {
    /// The effect.
    pub spec: EffectSpec,
    /// Joint the effect moves (`None` for `pivot_length`).
    pub joint: Option<usize>,
    /// Source joint of a squareness (the first axis of the pair).
    pub source: Option<usize>,
    /// Time at which the effect starts acting (thermal drift clock), s.
    pub t0: f64,
}

fn effect_err(spec: &EffectSpec, msg: String) -> Error {
    Error::input(
        Location::new("<effect>", 0, 0),
        format!("{}: {msg}", spec.effect.kind().name()),
    )
}

impl BoundEffect {
    /// Resolves `spec` on `chain`: the axes must be joints of the right kind
    /// (thermal drift and squareness on linear axes, a rotary centre offset
    /// on a rotary axis; squareness pairs must not have a rotary joint
    /// between them).
    pub fn new(spec: &EffectSpec, chain: &Chain) -> Result<BoundEffect> {
        let find = |a: &str| {
            chain.joint_index(a).ok_or_else(|| {
                effect_err(
                    spec,
                    format!(
                        "axis {a} is not a joint of the machine (joints: {})",
                        chain.joint_names()
                    ),
                )
            })
        };
        let kind_of = |j: usize| chain.joints()[j].kind;
        let (joint, source) = match &spec.effect {
            Effect::Backlash { axis, .. }
            | Effect::ServoLag { axis, .. }
            | Effect::Scale { axis, .. }
            | Effect::Cyclic { axis, .. }
            | Effect::ZeroOffset { axis, .. }
            | Effect::Vibration { axis, .. } => (Some(find(axis)?), None),
            Effect::ErrorMotion { axis, span, .. } => {
                let j = find(axis)?;
                if (kind_of(j) == JointKind::Revolute) == span.is_some() {
                    return Err(effect_err(
                        spec,
                        format!(
                            "axis {axis}: a rotary axis's error motion is a Fourier series (EXC_cos1 …), a linear axis's a spline over its travel (from_mm, to_mm, basis, EYX_b0 …)"
                        ),
                    ));
                }
                (Some(j), None)
            }
            Effect::ThermalDrift { axis, .. } => {
                let j = find(axis)?;
                if kind_of(j) != JointKind::Prismatic {
                    return Err(effect_err(
                        spec,
                        format!("axis {axis} is not a linear axis"),
                    ));
                }
                (Some(j), None)
            }
            Effect::Squareness { axes, .. } => {
                let a = find(&axes[0])?;
                let b = find(&axes[1])?;
                if kind_of(a) != JointKind::Prismatic || kind_of(b) != JointKind::Prismatic {
                    return Err(effect_err(
                        spec,
                        "squareness needs two linear axes".to_string(),
                    ));
                }
                if revolute_between(chain, a, b) {
                    return Err(effect_err(
                        spec,
                        format!(
                            "a rotary axis lies between {} and {} in the chain",
                            axes[0], axes[1]
                        ),
                    ));
                }
                (Some(b), Some(a))
            }
            Effect::RotaryCenterOffset { axis, .. } => {
                let j = find(axis)?;
                if kind_of(j) != JointKind::Revolute {
                    return Err(effect_err(
                        spec,
                        format!("axis {axis} is not a rotary axis"),
                    ));
                }
                (Some(j), None)
            }
            Effect::PivotLength { .. } | Effect::Registration { .. } | Effect::Wander { .. } => {
                (None, None)
            }
        };
        Ok(BoundEffect {
            spec: spec.clone(),
            joint,
            source,
            t0: 0.0,
        })
    }

    /// Change of the commanded position of [`BoundEffect::joint`] (file
    /// units), or 0 for effects that are not joint shifts.
    pub fn delta_q(&self, s: &MotionState) -> f64 {
        let Some(j) = self.joint else { return 0.0 };
        match &self.spec.effect {
            Effect::Backlash { value, .. } => -0.5 * value * s.dir[j],
            Effect::ServoLag { tau_s, .. } => -tau_s * s.v[j],
            Effect::ThermalDrift {
                amplitude_mm,
                tau_s,
                ..
            } => {
                let dt = (s.t - self.t0).max(0.0);
                amplitude_mm * (1.0 - (-dt / tau_s).exp())
            }
            Effect::Scale { ppm, .. } => ppm * 1e-6 * s.q[j],
            Effect::Squareness { angle_urad, .. } => {
                let a = self.source.unwrap_or(j);
                angle_urad * 1e-6 * s.q[a]
            }
            Effect::Cyclic {
                amplitude,
                period,
                phase_deg,
                ..
            } => {
                amplitude * (std::f64::consts::TAU * s.q[j] / period + phase_deg.to_radians()).sin()
            }
            Effect::ZeroOffset { value, .. } => *value,
            Effect::Vibration {
                amplitude,
                frequency_hz,
                phase_deg,
                ..
            } => {
                amplitude
                    * (std::f64::consts::TAU * frequency_hz * s.t + phase_deg.to_radians()).sin()
            }
            Effect::RotaryCenterOffset { .. }
            | Effect::PivotLength { .. }
            | Effect::Registration { .. }
            | Effect::Wander { .. }
            | Effect::ErrorMotion { .. } => 0.0,
        }
    }

    /// Whether this effect changes the chain (rotary centre offset, pivot
    /// length, registration) rather than a joint position.
    pub fn modifies_chain(&self) -> bool {
        matches!(
            self.spec.effect,
            Effect::RotaryCenterOffset { .. }
                | Effect::PivotLength { .. }
                | Effect::Registration { .. }
        )
    }
}

/// A static effect turned into an error motion of one joint, so that it
/// acts through the chain's [`crate::machine::JointErrors`] without knowing
/// the motion: a shift along (or about) the joint's own axis for scale,
/// zero offset and cyclic; for squareness a shift of the *first* joint of
/// the pair along the second axis; for a rotary centre offset the
/// translation `Rᵀd − d` (since `Trans(d)·Rot(q)·Trans(−d) = Rot(q)·Trans(Rᵀd − d)`).
#[derive(Debug, Clone, PartialEq)]
pub struct StaticTerm {
    /// Joint whose error motion carries the effect.
    pub joint: usize,
    rotary: bool,
    axis: nalgebra::Unit<Vector3<f64>>,
    /// Squareness: direction of the second axis in the first joint's frame.
    along: Vector3<f64>,
    effect: Effect,
}

impl StaticTerm {
    /// The error-motion form of a bound static effect (`None` for dynamic
    /// effects and for the pivot length, which is a fixed element).
    pub fn new(b: &BoundEffect, chain: &Chain) -> Option<StaticTerm> {
        let (joint, along) = match &b.spec.effect {
            Effect::Scale { .. }
            | Effect::ZeroOffset { .. }
            | Effect::Cyclic { .. }
            | Effect::RotaryCenterOffset { .. }
            | Effect::ErrorMotion { .. } => (b.joint?, Vector3::zeros()),
            Effect::Squareness { .. } => {
                let a = b.source?;
                (a, direction_in_frame_of(chain, a, b.joint?))
            }
            _ => return None,
        };
        let jt = &chain.joints()[joint];
        Some(StaticTerm {
            joint,
            rotary: jt.kind == JointKind::Revolute,
            axis: jt.axis,
            along,
            effect: b.spec.effect.clone(),
        })
    }

    /// The error motion at joint position `q` (mm or rad).
    pub fn error_motion(&self, q: f64) -> ErrorMotion {
        let to_file = |x: f64| if self.rotary { x.to_degrees() } else { x };
        let to_int = |x: f64| if self.rotary { x.to_radians() } else { x };
        let u = self.axis.into_inner();
        let shift = |dq_file: f64| -> ErrorMotion {
            let d = to_int(dq_file);
            let mut e = ErrorMotion::zeros();
            let o = if self.rotary { 3 } else { 0 };
            e[o] = d * u.x;
            e[o + 1] = d * u.y;
            e[o + 2] = d * u.z;
            e
        };
        match &self.effect {
            Effect::Scale { ppm, .. } => shift(ppm * 1e-6 * to_file(q)),
            Effect::ZeroOffset { value, .. } => shift(*value),
            Effect::Cyclic {
                amplitude,
                period,
                phase_deg,
                ..
            } => shift(
                amplitude
                    * (std::f64::consts::TAU * to_file(q) / period + phase_deg.to_radians()).sin(),
            ),
            Effect::Squareness { angle_urad, .. } => {
                let d = angle_urad * 1e-6 * q * self.along;
                ErrorMotion::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
            }
            Effect::ErrorMotion {
                terms, span, arc, ..
            } => error_motion_at(terms, span.as_ref(), *arc, q),
            Effect::RotaryCenterOffset { offset_mm, .. } => {
                let d = Vector3::from_column_slice(offset_mm);
                let r = crate::machine::chain::rotation3(&self.axis, q);
                let t = r.transpose() * d - d;
                ErrorMotion::new(t.x, t.y, t.z, 0.0, 0.0, 0.0)
            }
            _ => ErrorMotion::zeros(),
        }
    }
}

/// True when a revolute joint lies between joints `a` and `b` in the chain.
fn revolute_between(chain: &Chain, a: usize, b: usize) -> bool {
    let (lo, hi) = {
        let ea = chain.joints()[a].element;
        let eb = chain.joints()[b].element;
        (ea.min(eb), ea.max(eb))
    };
    chain.elements()[lo + 1..hi].iter().any(|el| {
        matches!(el, crate::machine::chain::Element::Joint(k) if chain.joints()[*k].kind == JointKind::Revolute)
    })
}

/// The direction of prismatic joint `b`, expressed in the moving frame of
/// joint `a` (the fixed rotations between them applied; no revolute joint
/// may lie between them).
fn direction_in_frame_of(chain: &Chain, a: usize, b: usize) -> Vector3<f64> {
    use crate::machine::chain::Element;
    let ea = chain.joints()[a].element;
    let eb = chain.joints()[b].element;
    let rot = |m: &Matrix4<f64>| m.fixed_view::<3, 3>(0, 0).into_owned();
    let u = chain.joints()[b].axis.into_inner();
    if ea < eb {
        // Frame after a → frame before b: product of elements in between.
        let mut r = nalgebra::Matrix3::identity();
        for el in &chain.elements()[ea + 1..eb] {
            if let Element::Fixed(m) = el {
                r *= rot(m);
            }
        }
        r * u
    } else {
        // b comes first: the direction of b in a's moving frame is the
        // inverse rotation of the elements from b up to a.
        let mut r = nalgebra::Matrix3::identity();
        for el in &chain.elements()[eb + 1..ea] {
            if let Element::Fixed(m) = el {
                r *= rot(m);
            }
        }
        r.transpose() * u
    }
}

/// Returns `chain` with the chain-modifying effects inserted: a rotary
/// centre offset as `Trans(d)` before and `Trans(−d)` after its joint, a
/// pivot length as a translation along the tool axis at the tip, a
/// registration as a translation at the workpiece frame (the chain's
/// first element).
pub fn chain_with_effects(chain: &Chain, effects: &[&BoundEffect]) -> Chain {
    let mut c = chain.clone();
    for e in effects {
        match &e.spec.effect {
            Effect::RotaryCenterOffset { offset_mm, .. } => {
                if let Some(j) = e.joint {
                    let d = Vector3::from_column_slice(offset_mm);
                    let el = c.joints()[j].element;
                    c = c.with_fixed_inserted(el + 1, translation(&(-d)));
                    c = c.with_fixed_inserted(el, translation(&d));
                }
            }
            Effect::PivotLength { delta_mm } => {
                c.translate(Vector3::new(0.0, 0.0, *delta_mm));
            }
            Effect::Registration { offset_mm } => {
                c = c.with_fixed_inserted(0, translation(&Vector3::from_column_slice(offset_mm)));
            }
            _ => {}
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_tracker_ignores_jitter() {
        let mut t = DirectionTracker::new(1e-3);
        let qs = [0.0, 0.0005, 0.002, 0.003, 0.0029, 0.0025, 0.001, 0.0012];
        let dirs: Vec<f64> = qs.iter().map(|&q| t.update(q)).collect();
        assert_eq!(dirs, vec![0.0, 0.0, 1.0, 1.0, 1.0, 1.0, -1.0, -1.0]);
    }
}
