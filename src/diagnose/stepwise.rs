//! Forward stepwise selection of the effects that explain a residual:
//! each round searches every candidate family (on every core), and the
//! best candidate that is physically plausible, resolved by the values'
//! rounding and better on held-out data enters the model. Then a term
//! that the later ones made redundant leaves again.
//!
//! Greedy selection prefers one many-parameter term that explains a sum
//! of simple effects at once: an error motion of Y (a spline per
//! component) or a registration of the measurement for zero offsets of X
//! and Z; and a wrong first step stays (an error motion of the table
//! taken for a registration, then kept for what it fits beside a
//! backlash). So when the greedy model holds such a term, the selection
//! runs again with the simple families first ([`Order`]), and a model
//! without an error motion replaces the greedy one when its BIC is lower
//! by more than the margin a candidate must clear. (A model that still
//! needs the error motion, or tells a rotary axis's error motion again as
//! a centre offset and a cyclic error of that axis, is not preferred: the
//! motion's harmonics split off that way save parameters, not a cause.
//! The margin keeps, say, a registration from being traded for a rotary
//! centre offset plus a zero offset that fit exactly as well.)

use rayon::prelude::*;

use super::fit::{self, Candidate, Family, SearchCtx, Selected, Term};
use super::prepare::Prepared;
use super::report::Rejected;
use super::{DiagOptions, MIN_HOLDOUT_SHARE, plausible, reject};
use crate::machine::chain::Chain;

/// The outcome of one stepwise selection.
#[derive(Debug, Clone)]
pub struct Stepwise {
    /// The terms, in the order they entered.
    pub terms: Vec<Term>,
    /// For each term: its score when it entered, and the held-out RSS
    /// before and after (mm²).
    pub meta: Vec<(f64, (f64, f64))>,
    /// For each term: the candidates of its round, best first.
    pub rounds: Vec<Vec<Candidate>>,
    /// The candidates of the first round, best first.
    pub first_round: Vec<Candidate>,
    /// Candidates set aside, with the reason.
    pub rejected: Vec<Rejected>,
    /// Held-out RSS of the residual without any effect, mm².
    pub hold_before: f64,
    /// χ² of the residual left plus the penalties of the terms.
    pub bic: f64,
}

/// The order in which the families are searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Every family in every round.
    Greedy,
    /// Only simple families ([`Family::is_simple`]) until none enters,
    /// then every family.
    SimpleFirst,
    /// Simple families and the registration until none enters, then
    /// every family.
    SimpleAndRegistrationFirst,
    /// Simple families, the registration and a step of it until none
    /// enters, then every family.
    SimpleAndRegistrationStepFirst,
}

impl Order {
    /// Whether `f` is searched in the first phase.
    fn first(self, f: Family) -> bool {
        match self {
            Order::Greedy => true,
            Order::SimpleFirst => f.is_simple(),
            Order::SimpleAndRegistrationFirst => f.is_simple() || f == Family::Registration,
            Order::SimpleAndRegistrationStepFirst => {
                f.is_simple() || matches!(f, Family::Registration | Family::RegistrationStep)
            }
        }
    }
}

/// The selection: greedy over `families`, and again in the other
/// [`Order`]s when the greedy model holds a term that is not simple; a
/// model of another order without an error motion, and without a centre
/// offset or cyclic error of a rotary axis whose error motion the greedy
/// model holds, replaces the greedy one when its BIC is lower by more
/// than [`DiagOptions::bic_margin`] (the first round of the report is
/// always the greedy one's).
pub fn select(
    prep: &Prepared,
    families: &[Family],
    ctx: &SearchCtx,
    opts: &DiagOptions,
    unresolved: f64,
    chain: &Chain,
) -> Stepwise {
    let run = |order| forward(prep, families, ctx, opts, unresolved, chain, order);
    let greedy = run(Order::Greedy);
    if greedy.terms.iter().all(|t| t.family.is_simple()) {
        return greedy;
    }
    let motion = |s: &Stepwise| {
        s.terms
            .iter()
            .any(|t| matches!(t.family, Family::ErrorMotion(..) | Family::LinearMotion(..)))
    };
    // A rotary axis's error motion told again as a centre offset and a
    // cyclic error of that axis is the same geometry in other words; the
    // error motion is kept (it is written back whole).
    let retold = |s: &Stepwise| {
        s.terms.iter().any(|t| match t.family {
            Family::RotaryCenterOffset(j) | Family::Cyclic(j) => greedy
                .terms
                .iter()
                .any(|g| matches!(g.family, Family::ErrorMotion(m, _) if m == j)),
            _ => false,
        })
    };
    let best = [
        Order::SimpleFirst,
        Order::SimpleAndRegistrationFirst,
        Order::SimpleAndRegistrationStepFirst,
    ]
    .into_iter()
    .map(run)
    .filter(|s| !motion(s) && !retold(s) && s.bic < greedy.bic - opts.bic_margin)
    .min_by(|a, b| a.bic.total_cmp(&b.bic));
    match best {
        Some(s) => Stepwise {
            first_round: greedy.first_round,
            ..s
        },
        None => greedy,
    }
}

/// One forward selection in `order`.
fn forward(
    prep: &Prepared,
    families: &[Family],
    ctx: &SearchCtx,
    opts: &DiagOptions,
    unresolved: f64,
    chain: &Chain,
    order: Order,
) -> Stepwise {
    let s2 = ctx.sigma * ctx.sigma;
    let n_rows = prep.rows() as f64;
    let mut rejected: Vec<Rejected> = Vec::new();
    let mut terms: Vec<Term> = Vec::new();
    let mut meta: Vec<(f64, (f64, f64))> = Vec::new();
    let mut pens: Vec<f64> = Vec::new();
    let mut rounds: Vec<Vec<Candidate>> = Vec::new();
    let mut first_round: Vec<Candidate> = Vec::new();
    let mut first_phase = order != Order::Greedy;
    let rss0: f64 = prep
        .r
        .iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sum();
    // The residual sum of squares a selection leaves.
    let left = |sel: &Selected| rss0 - sel.h.dot(&(&sel.ginv * &sel.h));
    let mut hold_prev = fit::holdout_rss(prep, &fit::design(prep, &[]));
    let hold_before = hold_prev;
    while terms.len() < opts.max_effects {
        let sel = Selected::new(prep, fit::design(prep, &terms));
        // The vibration search scans thousands of frequencies: it runs in
        // the first round, then only while the residual left by the terms
        // so far is above the noise, or for an axis whose vibration was a
        // candidate in the first round (a vibration near the Nyquist
        // frequency raises the noise floor estimate itself).
        let rss_now = left(&sel);
        let chi_now = rss_now / (s2 * n_rows);
        let above_noise = chi_now > 1.05 && (chi_now - 1.0) * (1.5 * n_rows).sqrt() > 4.0;
        // The families are searched on every core, the candidates taken
        // in the families' order.
        let searched: Vec<Family> = families
            .iter()
            .copied()
            .filter(|f| !terms.iter().any(|t| t.family.same_slot(*f)))
            .filter(|f| {
                *f != Family::RegistrationStep
                    || terms.iter().filter(|t| t.family == *f).count() < fit::MAX_REGISTRATION_STEPS
            })
            .filter(|f| !first_phase || order.first(*f))
            .filter(|f| {
                !matches!(f, Family::Vibration(_))
                    || terms.is_empty()
                    || above_noise
                    || first_round
                        .iter()
                        .any(|c| c.term.family == *f && c.score >= opts.bic_margin)
            })
            .collect();
        let mut cands: Vec<Candidate> = searched
            .par_iter()
            .filter_map(|f| fit::search_family(prep, &sel, *f, ctx))
            .collect();
        cands.sort_by(|a, b| b.score.total_cmp(&a.score));
        if terms.is_empty() {
            first_round = cands.clone();
        }
        let mut accepted = None;
        let mut tried = 0;
        for c in &cands {
            if c.score < opts.bic_margin || tried == 3 {
                break;
            }
            let mut trial = terms.clone();
            trial.push(c.term);
            let cols = fit::design(prep, &trial);
            // Physical signs and plausibility, with the others in the fit.
            let (beta, _) = fit::lsq(prep, &cols, &|_| true);
            let own = &beta.as_slice()[beta.len() - c.term.family.linear_params()..];
            let effect = fit::term_effect(prep, &c.term, own);
            if let Some(reason) = plausible::implausible(&effect, prep) {
                reject(&mut rejected, &effect, chain, reason);
                continue;
            }
            // Rounded commands leave a residual that follows the axes
            // where they stop; an effect smaller than it is not resolved.
            let size = (c.delta_rss / n_rows).sqrt();
            if size < unresolved {
                reject(
                    &mut rejected,
                    &effect,
                    chain,
                    format!(
                        "it moves the tip by {:.3} µm RMS, less than the {:.3} µm the rounding of the recorded values leaves",
                        size * 1e3,
                        unresolved * 1e3
                    ),
                );
                continue;
            }
            tried += 1;
            // A wander of the measurement is a function of time: judged on
            // short stretches of time. A term after a wander is judged on
            // contiguous folds with and without it, as every machine
            // effect is (the carried `hold_prev` was read on stretches).
            let (hold_prev, hold) = if c.term.family == Family::Wander {
                (
                    fit::holdout_rss_chunked(prep, &fit::design(prep, &terms)),
                    fit::holdout_rss_chunked(prep, &cols),
                )
            } else if terms.iter().any(|t| t.family == Family::Wander) {
                (
                    fit::holdout_rss(prep, &fit::design(prep, &terms)),
                    fit::holdout_rss(prep, &cols),
                )
            } else {
                (hold_prev, fit::holdout_rss(prep, &cols))
            };
            let gain = hold_prev - hold;
            // What the held-out residual has above the noise: an effect
            // that explains a sliver of it describes something else.
            let excess = (hold_prev - n_rows * s2).max(0.0);
            if gain >= ctx.ln_n * s2 && gain < MIN_HOLDOUT_SHARE * excess {
                reject(
                    &mut rejected,
                    &effect,
                    chain,
                    format!(
                        "it explains {:.2} % of the held-out mismatch above the noise, less than {:.0} %: a mismatch it does not describe dominates (timing jitter, an effect outside the catalogue)",
                        100.0 * gain / excess,
                        100.0 * MIN_HOLDOUT_SHARE
                    ),
                );
                continue;
            }
            if gain >= ctx.ln_n * s2 {
                accepted = Some((*c, hold));
                break;
            }
        }
        let Some((c, hold)) = accepted else {
            if first_phase {
                first_phase = false;
                continue;
            }
            break;
        };
        rounds.push(cands.clone());
        terms.push(c.term);
        meta.push((c.score, (hold_prev, hold)));
        pens.push(c.penalty);
        hold_prev = hold;
    }
    // Backward elimination: a term that the later ones made redundant
    // (taking it out raises χ² by less than it paid to enter) leaves, the
    // least needed first.
    let rss_of = |terms: &[Term]| left(&Selected::new(prep, fit::design(prep, terms)));
    let mut removed = false;
    while terms.len() > 1 {
        let rss_all = rss_of(&terms);
        let least = (0..terms.len())
            .map(|k| {
                let mut others = terms.clone();
                others.remove(k);
                ((rss_of(&others) - rss_all) / s2 - pens[k], k)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k)) = least.filter(|(gain, _)| *gain < 0.0) else {
            break;
        };
        terms.remove(k);
        meta.remove(k);
        rounds.remove(k);
        pens.remove(k);
        removed = true;
    }
    if removed {
        // The held-out residual before and after each term, in the order
        // of the terms kept.
        let mut prev = hold_before;
        for k in 0..terms.len() {
            let hold = fit::holdout_rss(prep, &fit::design(prep, &terms[..=k]));
            meta[k].1 = (prev, hold);
            prev = hold;
        }
    }
    Stepwise {
        bic: rss_of(&terms) / s2 + pens.iter().sum::<f64>(),
        terms,
        meta,
        rounds,
        first_round,
        rejected,
        hold_before,
    }
}
