//! From fitted coefficients back to effects: a term's coefficients as the
//! effect's physical parameters, their standard deviations, and the
//! derivatives of the columns with respect to the non-linear parameter and
//! the onset (for the joint covariance).

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::*;

/// Converts fitted coefficients of a term into an effect (and the Jacobian
/// of its reported parameters with respect to the coefficients, for the
/// uncertainties).
pub fn term_effect(prep: &Prepared, term: &Term, beta: &[f64]) -> Effect {
    let name = |j: usize| prep.names[j].clone();
    match term.family {
        Family::Backlash(j) => Effect::Backlash {
            axis: name(j),
            value: beta[0],
        },
        Family::ServoLag(j) => Effect::ServoLag {
            axis: name(j),
            tau_s: beta[0],
        },
        Family::ThermalDrift(j) => Effect::ThermalDrift {
            axis: name(j),
            amplitude_mm: beta[0],
            tau_s: term.nl,
        },
        Family::Scale(j) => Effect::Scale {
            axis: name(j),
            ppm: beta[0],
        },
        Family::Squareness(a, b) => Effect::Squareness {
            axes: [name(a), name(b)],
            angle_urad: beta[0],
        },
        Family::Cyclic(j) => {
            let (c, s) = (beta[0], beta[1]);
            Effect::Cyclic {
                axis: name(j),
                amplitude: c.hypot(s),
                period: term.nl,
                phase_deg: s.atan2(c).to_degrees(),
            }
        }
        Family::ZeroOffset(j) => Effect::ZeroOffset {
            axis: name(j),
            value: beta[0],
        },
        Family::RotaryCenterOffset(j) => {
            let d = prep.rco[j]
                .as_ref()
                .map(|b| b.dirs[0] * beta[0] + b.dirs[1] * beta[1])
                .unwrap_or_default();
            Effect::RotaryCenterOffset {
                axis: name(j),
                offset_mm: [d.x, d.y, d.z],
            }
        }
        Family::PivotLength => Effect::PivotLength { delta_mm: beta[0] },
        Family::Registration | Family::RegistrationStep => Effect::Registration {
            offset_mm: [beta[0], beta[1], beta[2]],
        },
        Family::Wander => Effect::Wander {
            span: wander_span(prep)
                .unwrap_or_else(|| MotionSpan::new(0.0, 1.0, WANDER_BASIS).expect("a valid basis")),
            coef_mm: (0..WANDER_BASIS)
                .map(|b| [0, 1, 2].map(|c| beta[c * WANDER_BASIS + b]))
                .collect(),
        },
        Family::ErrorMotion(j, mask) => {
            let mut terms = Vec::new();
            for (p, c) in mask_components(mask).enumerate() {
                for k in 1..=MOTION_HARMONICS {
                    let base = (p * MOTION_HARMONICS as usize + (k as usize - 1)) * 2;
                    terms.push((c, k, beta[base], beta[base + 1]));
                }
            }
            Effect::ErrorMotion {
                axis: name(j),
                terms,
                span: None,
                arc: covered_arc(prep, j),
            }
        }
        Family::LinearMotion(j, mask) => {
            let mut terms = Vec::new();
            for (p, c) in mask_components(mask).enumerate() {
                for k in 0..MOTION_BASIS {
                    terms.push((c, k as u32, beta[p * MOTION_BASIS + k], 0.0));
                }
            }
            Effect::ErrorMotion {
                axis: name(j),
                terms,
                span: motion_span(prep, j),
                arc: None,
            }
        }
        Family::Vibration(j) => {
            let (c, s) = (beta[0], beta[1]);
            Effect::Vibration {
                axis: name(j),
                amplitude: c.hypot(s),
                frequency_hz: term.nl,
                phase_deg: s.atan2(c).to_degrees(),
            }
        }
    }
}

/// Standard deviations of the fitted parameters (in the order of
/// [`Effect::parameters`], those chosen rather than fitted left out:
/// [`Effect::is_chosen_parameter`]) from the covariance of `[β…, nl]`.
pub fn parameter_sd(prep: &Prepared, term: &Term, beta: &[f64], cov: &DMatrix<f64>) -> Vec<f64> {
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    match term.family {
        Family::ThermalDrift(_) => vec![sd(0), sd(1)],
        Family::Cyclic(_) | Family::Vibration(_) => {
            let (c, s) = (beta[0], beta[1]);
            let a = c.hypot(s).max(1e-300);
            let ga = [c / a, s / a];
            let gp = [-s / (a * a), c / (a * a)];
            let q = |g: [f64; 2]| {
                (g[0] * g[0] * cov[(0, 0)]
                    + 2.0 * g[0] * g[1] * cov[(0, 1)]
                    + g[1] * g[1] * cov[(1, 1)])
                    .max(0.0)
                    .sqrt()
            };
            vec![q(ga), sd(2), q(gp).to_degrees()]
        }
        Family::RotaryCenterOffset(j) => {
            let Some(b) = prep.rco[j].as_ref() else {
                return vec![0.0; 3];
            };
            (0..3)
                .map(|x| {
                    let g = [b.dirs[0][x], b.dirs[1][x]];
                    (g[0] * g[0] * cov[(0, 0)]
                        + 2.0 * g[0] * g[1] * cov[(0, 1)]
                        + g[1] * g[1] * cov[(1, 1)])
                        .max(0.0)
                        .sqrt()
                })
                .collect()
        }
        Family::ErrorMotion(_, mask) | Family::LinearMotion(_, mask) => {
            // The peaks' uncertainty: the largest coefficient's of their
            // kind (rotations in µrad, as reported); a spline's span (from,
            // to, basis count) is chosen, not fitted.
            let n = beta.len();
            let per = n / (mask.count_ones() as usize).max(1);
            let comp = |p: usize| mask_components(mask).nth(p / per.max(1)).unwrap_or(0);
            let scaled = |p: usize| if comp(p) < 3 { sd(p) } else { sd(p) * 1e6 };
            let peak = |rot: bool| {
                (0..n)
                    .filter(|&p| (comp(p) >= 3) == rot)
                    .map(scaled)
                    .fold(0.0, f64::max)
            };
            let mut v = vec![peak(false)];
            if mask & !TRANSLATIONS != 0 {
                v.push(peak(true));
            }
            v.extend((0..n).map(scaled));
            v
        }
        Family::Registration | Family::RegistrationStep => vec![sd(0), sd(1), sd(2)],
        // A range's uncertainty: about √2 times its coordinate's largest
        // coefficient's; the knots are chosen, not fitted.
        Family::Wander => {
            let coord = |c: usize| {
                (0..WANDER_BASIS)
                    .map(|b| sd(c * WANDER_BASIS + b))
                    .fold(0.0, f64::max)
                    * std::f64::consts::SQRT_2
            };
            vec![coord(0), coord(1), coord(2)]
        }
        _ => vec![sd(0)],
    }
}

/// Derivative of a term's (onset-masked) columns times its coefficients
/// with respect to its non-linear parameter (numerical, relative step
/// 1e-4): the Gauss–Newton column of that parameter.
pub fn nl_derivative(prep: &Prepared, term: &Term, beta: &[f64]) -> Cols {
    let h = term.nl * 1e-4;
    let mut tp = *term;
    let mut tm = *term;
    tp.nl += h;
    tm.nl -= h;
    let cp = term_columns(prep, &tp);
    let cm = term_columns(prep, &tm);
    let k = cp.k;
    let rows = prep.rows();
    let mut out = Cols::zeros(rows, 1);
    for r in 0..rows {
        let mut s = 0.0;
        for p in 0..k {
            s += (cp.data[r * k + p] - cm.data[r * k + p]) * beta[p];
        }
        out.data[r] = s / (2.0 * h);
    }
    out
}

/// For a thermal drift that starts part-way, the Gauss–Newton column of its
/// onset time t₀: `∂/∂t₀ [a·J·(1 − e^−(t−t₀)/τ)] = −(a/τ)·e^−(t−t₀)/τ·J`
/// from the onset on (the drift is continuous at its onset, so the
/// likelihood is smooth in a continuous t₀ and this column gives t₀ a
/// standard deviation, and lets the onset's trade-off with τ and the
/// amplitude enter theirs). `None` for other terms and for a drift from
/// the start of the recording (whose onset is not a free parameter).
pub fn onset_derivative(prep: &Prepared, term: &Term, beta: &[f64]) -> Option<Cols> {
    let Family::ThermalDrift(j) = term.family else {
        return None;
    };
    if term.onset == 0 || term.onset >= prep.n {
        return None;
    }
    let t0 = prep.t[term.onset];
    let mut out = Cols::zeros(prep.rows(), 1);
    for i in term.onset..prep.n {
        let g = -beta[0] / term.nl * (-(prep.t[i] - t0) / term.nl).exp();
        let jj = prep.jj(i, j);
        for a in 0..3 {
            out.data[3 * i + a] = g * jj[a];
        }
    }
    Some(out)
}

/// An effect found, with everything the report needs.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The term.
    pub term: Term,
    /// The effect with fitted parameters (from its onset block).
    pub spec: EffectSpec,
    /// Standard deviations of the parameters (order of `Effect::parameters`).
    pub sd: Vec<f64>,
    /// Standard deviation of a drift's onset time, s (when it starts
    /// part-way).
    pub onset_sd_s: Option<f64>,
    /// The candidate score when it entered.
    pub score: f64,
    /// Held-out RSS before / after it entered, mm².
    pub holdout: (f64, f64),
    /// The runner-up of its round: term, score, fitted effect.
    pub runner_up: Option<(Term, f64, Effect)>,
}
