//! The command-line syntax of an effect (`simulate --inject`):
//! `backlash:X=0.003`, `thermal_drift:Z=0.01,tau=600@block=7`, … (see
//! [`parse_effect_spec`] and `docs/diagnose.md`).

use std::collections::BTreeMap;

use super::effects::{Effect, EffectKind, EffectSpec};
use crate::error::{Error, Location, Result};

/// Parses a command-line effect specification:
///
/// ```text
/// backlash:X=0.003              value (mm, or deg on a rotary axis)
/// servo_lag:X=0.02              τ in s
/// thermal_drift:Z=0.01,tau=600  amplitude mm, τ s
/// scale:X=50                    ppm
/// squareness:XZ=20              µrad (moving X moves the tool along Z)
/// cyclic:X=0.002,period=20,phase=0   amplitude, period (mm or deg), phase deg
/// zero_offset:Z=0.005           mm (or deg)
/// rotary_center_offset:C=dx,dy,dz    mm
/// pivot_length:0.01             mm
/// error_motion:C,EXC_cos1=0.0012,EYC_sin2=0.0005   Fourier terms over one
///                               turn: translations mm, tilts (EAC, EBC) µrad
/// error_motion:X,from_mm=-80,to_mm=80,basis=6,EZX_b2=0.0025   a linear axis:
///                               B-spline coefficients over from … to (mm)
/// vibration:X=0.002,f=7,phase=30     amplitude (mm or deg), Hz, phase deg
/// ```
///
/// Any of them may end in `@block=N` (or `@N`): the effect acts from block
/// N on. The parameter names of `formats.md` §4 are accepted as keys too
/// (`tau_s=600`, `period_mm=20`, …).
pub fn parse_effect_spec(s: &str) -> Result<EffectSpec> {
    let bad = |msg: String| Error::input_with(Location::new("--inject", 0, 0), msg, s.to_string());
    let text = s.trim();
    let (body, from_block) = match text.rsplit_once('@') {
        None => (text, None),
        Some((b, tail)) => {
            let tail = tail.trim();
            let num = tail
                .strip_prefix("block=")
                .or_else(|| tail.strip_prefix("block"))
                .unwrap_or(tail)
                .trim()
                .trim_start_matches(['N', 'n']);
            let n: u64 = num.parse().map_err(|_| {
                bad(format!(
                    "`@{tail}`: expected `@block=N` with N a block number"
                ))
            })?;
            (b.trim(), Some(n))
        }
    };
    let (name, rest) = body.split_once(':').ok_or_else(|| {
        bad("expected `effect:AXIS=value[,key=value…]`, e.g. `backlash:X=0.003`".into())
    })?;
    let kind = EffectKind::from_name(name).ok_or_else(|| {
        bad(format!(
            "unknown effect `{}` (known: {})",
            name.trim(),
            EffectKind::ALL.map(|k| k.name()).join(", ")
        ))
    })?;
    let num = |v: &str| -> Result<f64> {
        let x: f64 = v
            .trim()
            .parse()
            .map_err(|_| bad(format!("`{}` is not a number", v.trim())))?;
        if x.is_finite() {
            Ok(x)
        } else {
            Err(bad(format!("`{}` is not a finite number", v.trim())))
        }
    };
    let mut params = BTreeMap::new();
    let mut axis = None;
    match kind {
        EffectKind::ErrorMotion => {
            let mut parts = rest.split(',');
            axis = Some(parts.next().unwrap_or("").trim().to_string());
            for p in parts {
                let (k, v) = p.split_once('=').ok_or_else(|| {
                    bad(format!(
                        "expected `term=value` such as EXC_cos1=0.001, found `{}`",
                        p.trim()
                    ))
                })?;
                params.insert(k.trim().to_string(), num(v)?);
            }
        }
        EffectKind::PivotLength => {
            let v = rest.trim();
            let v = v.split_once('=').map_or(v, |(_, x)| x);
            params.insert("delta_mm".to_string(), num(v)?);
        }
        EffectKind::RotaryCenterOffset => {
            let (a, vals) = rest
                .split_once('=')
                .ok_or_else(|| bad("expected `rotary_center_offset:C=dx,dy,dz` (mm)".into()))?;
            axis = Some(a.trim().to_string());
            let vs: Vec<&str> = vals.split(',').collect();
            if vs.is_empty() || vs.len() > 3 {
                return Err(bad("expected up to three offsets dx,dy,dz (mm)".into()));
            }
            for (k, v) in vs.iter().enumerate() {
                params.insert(["dx_mm", "dy_mm", "dz_mm"][k].to_string(), num(v)?);
            }
        }
        _ => {
            let mut parts = rest.split(',');
            let first = parts.next().unwrap_or("");
            let (a, v) = first.split_once('=').ok_or_else(|| {
                bad(format!(
                    "expected `{}:AXIS=value`, e.g. `{}`",
                    kind.name(),
                    example(kind)
                ))
            })?;
            axis = Some(a.trim().to_string());
            params.insert("value".to_string(), num(v)?);
            for p in parts {
                let (k, v) = p
                    .split_once('=')
                    .ok_or_else(|| bad(format!("expected `key=value`, found `{}`", p.trim())))?;
                let k = k.trim().to_ascii_lowercase();
                if params.insert(k.clone(), num(v)?).is_some() {
                    return Err(bad(format!("`{k}` given twice")));
                }
            }
        }
    }
    let effect = Effect::from_parameters_strict(kind, axis.as_deref(), &params).map_err(bad)?;
    check_size(&effect).map_err(bad)?;
    Ok(EffectSpec { effect, from_block })
}

/// Largest length (mm) or angle (deg) an injected effect may have: far
/// above any machine's error, low enough that the arithmetic stays finite.
const MAX_EFFECT: f64 = 10.0;

/// Refuses an effect to inject whose size is beyond what a machine shows
/// (`backlash:X=1e308`, `cyclic:…,period=1e-320`) or of a sign it cannot
/// have (a negative backlash): the recording would hold `inf` or NaN, or
/// nothing like a machine.
fn check_size(effect: &Effect) -> std::result::Result<(), String> {
    let within = |what: &str, v: f64, lo: f64, hi: f64, unit: &str| {
        if (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(format!("{what} {v}: expected {lo} … {hi} {unit}"))
        }
    };
    let size = |what: &str, v: f64| within(what, v, -MAX_EFFECT, MAX_EFFECT, "mm (or deg)");
    match effect {
        Effect::Backlash { value, .. } => {
            within("backlash", *value, 0.0, MAX_EFFECT, "mm (or deg)")
        }
        // A negative lag is a recording that leads its program (a test
        // of what diagnose makes of a clock ahead).
        Effect::ServoLag { tau_s, .. } => within("servo_lag τ", *tau_s, -60.0, 60.0, "s"),
        Effect::ThermalDrift {
            amplitude_mm,
            tau_s,
            ..
        } => {
            size("thermal_drift amplitude", *amplitude_mm)?;
            within("thermal_drift τ", *tau_s, 1e-3, 1e7, "s")
        }
        Effect::Scale { ppm, .. } => within("scale", *ppm, -1e5, 1e5, "ppm"),
        Effect::Squareness { angle_urad, .. } => {
            within("squareness", *angle_urad, -1e5, 1e5, "µrad")
        }
        Effect::Cyclic {
            amplitude, period, ..
        } => {
            size("cyclic amplitude", *amplitude)?;
            within("cyclic period", *period, 1e-3, 1e6, "mm (or deg)")
        }
        Effect::ZeroOffset { value, .. } => size("zero_offset", *value),
        Effect::RotaryCenterOffset { offset_mm, .. } | Effect::Registration { offset_mm } => {
            offset_mm.iter().try_for_each(|v| size("offset", *v))
        }
        Effect::PivotLength { delta_mm } => size("pivot_length", *delta_mm),
        Effect::Vibration {
            amplitude,
            frequency_hz,
            ..
        } => {
            size("vibration amplitude", *amplitude)?;
            within("vibration frequency", *frequency_hz, 1e-6, 1e5, "Hz")
        }
        _ => Ok(()),
    }
}

fn example(kind: EffectKind) -> &'static str {
    match kind {
        EffectKind::Backlash => "backlash:X=0.003",
        EffectKind::ServoLag => "servo_lag:X=0.02",
        EffectKind::ThermalDrift => "thermal_drift:Z=0.01,tau=600",
        EffectKind::Scale => "scale:X=50",
        EffectKind::Squareness => "squareness:XZ=20",
        EffectKind::Cyclic => "cyclic:X=0.002,period=20,phase=0",
        EffectKind::ZeroOffset => "zero_offset:Z=0.005",
        EffectKind::RotaryCenterOffset => "rotary_center_offset:C=0.01,0.005,0",
        EffectKind::PivotLength => "pivot_length:0.01",
        EffectKind::Vibration => "vibration:X=0.002,f=7,phase=0",
        EffectKind::ErrorMotion => "error_motion:C,EXC_cos1=0.0012,EYC_sin1=0.0012",
        EffectKind::Registration => "registration (not an effect to inject)",
        EffectKind::Wander => "wander (not an effect to inject)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_documented_spec() {
        let cases = [
            "backlash:X=0.003",
            "servo_lag:X=0.02",
            "thermal_drift:Z=0.01,tau=600",
            "scale:X=50",
            "squareness:XZ=20",
            "cyclic:X=0.002,period=20,phase=0",
            "zero_offset:Z=0.005",
            "rotary_center_offset:C=0.01,0.02,0",
            "pivot_length:0.01",
            "vibration:X=0.002,f=7,phase=30",
            "error_motion:C,EXC_cos1=0.0012,EYC_sin2=0.0005,EAC_cos1=3",
            "error_motion:X,from_mm=-80,to_mm=80,basis=6,EZX_b2=0.0025",
            "backlash:X=0.003@block=120",
        ];
        for c in cases {
            let s = parse_effect_spec(c).unwrap_or_else(|e| panic!("{c}: {e}"));
            let back = EffectSpec::from_json(&s.to_json(None)).unwrap();
            assert_eq!(back, s, "{c}");
        }
        // A parameter the effect does not have, one given twice, or under
        // two names: refused (each was ignored, or the first one won).
        for (spec, want) in [
            (
                "cyclic:X=0.002,period=20,phse=90",
                "cyclic has no parameter `phse`",
            ),
            (
                "cyclic:X=0.002,period=20,phase=10,phase=90",
                "`phase` given twice",
            ),
            (
                "cyclic:X=0.002,period=20,amplitude=0.003",
                "`amplitude` given besides the value",
            ),
            (
                "thermal_drift:Z=0.01,tau=600,tau_s=60",
                "`tau_s` and `tau` name the same",
            ),
            ("backlash:X=0.003,tau=1", "backlash has no parameter `tau`"),
        ] {
            let e = parse_effect_spec(spec).unwrap_err().to_string();
            assert!(e.contains(want), "{spec}: {e}");
        }
        let s = parse_effect_spec("thermal_drift:Z=0.01,tau=600@block=7").unwrap();
        assert_eq!(s.from_block, Some(7));
        assert_eq!(
            s.effect,
            Effect::ThermalDrift {
                axis: "Z".into(),
                amplitude_mm: 0.01,
                tau_s: 600.0
            }
        );
        for bad in [
            "nonsense:X=1",
            "backlash",
            "backlash:X=abc",
            "cyclic:X=0.002",
            "squareness:X=3",
            "backlash:X=1@blk",
            "thermal_drift:Z=0.01",
            "scale:X=inf",
        ] {
            assert!(parse_effect_spec(bad).is_err(), "{bad}");
        }
    }
}
