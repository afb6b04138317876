//! Gross outliers of a residual: samples that depart from their
//! neighbours far beyond the noise (a broken beam, a misread probe).

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::prepare::{Prepared, noise_floor};

/// A sample departs from its neighbours by more than this many noise
/// floors to be a gross outlier.
pub const OUTLIER_SIGMAS: f64 = 10.0;

/// Passes of the search, each over the samples not flagged before.
const MAX_PASSES: usize = 4;

/// Half-width of the running median the outliers are measured against.
const MEDIAN_HALF: usize = 3;

/// Up to this fraction of the samples flagged are gross faults wherever
/// they fall.
const MAX_OUTLIER_FRACTION: f64 = 0.05;

/// Up to this fraction flagged are gross faults when they fall apart from
/// each other as faults at random do ([`are_faults`]); more is not a
/// trace with faults but a fault with a trace.
const MAX_SCATTERED_FRACTION: f64 = 1.0 / 3.0;

/// Whether the samples `flagged` (increasing indices among `n`) are gross
/// faults rather than a signal the running median cannot follow: up to
/// 5 % of the samples always; up to a third when they are scattered as
/// faults at random are, that is when not many more of them sit next to
/// each other than chance puts there (`m` faults at random among `n`
/// samples give about `m²/n` neighbouring pairs, Poisson-distributed; half
/// as many again are allowed, since a clean sample among several faults
/// may be flagged beside them; a signal flags runs of samples, nearly
/// every one beside another).
pub fn are_faults(flagged: &[usize], n: usize) -> bool {
    let m = flagged.len() as f64;
    let share = m / n.max(1) as f64;
    if share <= MAX_OUTLIER_FRACTION {
        return true;
    }
    if share > MAX_SCATTERED_FRACTION {
        return false;
    }
    let pairs = flagged.windows(2).filter(|w| w[1] == w[0] + 1).count() as f64;
    let chance = m * share;
    pairs <= 1.5 * chance + 3.0 * chance.sqrt() + 1.0
}

/// The samples a per-sample search flags, searched for in passes: `flag`
/// gets the samples not flagged so far (increasing indices among `n`) and
/// returns those of them it flags. Faults side by side hide each other
/// from the line predictions of [`departure`], so each pass looks again
/// without the samples flagged before, until one flags none (at most
/// four). Returns the samples flagged, increasing.
pub fn flag_in_passes(n: usize, mut flag: impl FnMut(&[usize]) -> Vec<usize>) -> Vec<usize> {
    let mut far = vec![false; n];
    for _ in 0..MAX_PASSES {
        let series: Vec<usize> = (0..n).filter(|&i| !far[i]).collect();
        let flagged = flag(&series);
        if flagged.is_empty() {
            break;
        }
        for i in flagged {
            far[i] = true;
        }
    }
    (0..n).filter(|&i| far[i]).collect()
}

/// Whether more of the samples `flagged` (among `n`) sit at reversals
/// (`at_reversal`) than chance puts there: more than the Poisson mean
/// `m · r / n` (m flagged, r of all samples at reversals) plus three of its
/// standard deviations and one. Such spikes are a following error at
/// reversals, machine physics, not faults.
pub fn beyond_chance_at_reversals(
    flagged: &[usize],
    n: usize,
    at_reversal: impl Fn(usize) -> bool,
) -> bool {
    let near = flagged.iter().filter(|&&i| at_reversal(i)).count() as f64;
    let share = (0..n).filter(|&i| at_reversal(i)).count() as f64 / n.max(1) as f64;
    let chance = flagged.len() as f64 * share;
    near > chance + 3.0 * chance.sqrt() + 1.0
}

/// Gross outliers of a residual: samples whose residual, without each
/// axis's apparent lag ([`super::offset::lag_free`]), departs from its
/// neighbours ([`departure`]) by more than [`OUTLIER_SIGMAS`] noise floors
/// in some coordinate (samples `skip` marks are not looked at). A smooth
/// effect, a kink, a step at a reversal or an onset is never flagged. When
/// more flagged samples sit within two samples of a reversal than chance
/// would put there ([`beyond_chance_at_reversals`]), those are a following
/// error at reversals, machine physics, and stay in. Flags that are not scattered as faults
/// are ([`are_faults`]) are a signal the running median cannot follow:
/// then none is flagged.
/// Returns the flagged sample indices and each one's departure (mm).
pub fn gross_outliers(
    prep: &Prepared,
    sigma_xyz: [f64; 3],
    skip: &[bool],
) -> Vec<(usize, [f64; 3])> {
    let n = prep.n;
    if n < 2 * MEDIAN_HALF + 1 {
        return Vec::new();
    }
    let mut dev = vec![[0.0; 3]; n];
    // Without each axis's apparent lag: where the feed changes, a lag
    // moves the tip by more between two samples than the running median
    // follows, and those samples are physics, not faults.
    let r = super::offset::lag_free(prep);
    // Many faults raise the noise floor they are measured against: from
    // the second pass on, the floor is lowered by what its estimate loses
    // without the samples flagged.
    let (all, _) = noise_floor(&r);
    let mut limit: [f64; 3] = std::array::from_fn(|c| OUTLIER_SIGMAS * sigma_xyz[c].max(1e-9));
    let far = flag_in_passes(n, |series| {
        if series.len() < n {
            let (clean, _) = noise_floor(&series.iter().map(|&i| r[i]).collect::<Vec<_>>());
            for c in 0..3 {
                if all[c] > 0.0 {
                    limit[c] = limit[c].min(
                        OUTLIER_SIGMAS * sigma_xyz[c].max(1e-9) * (clean[c] / all[c]).min(1.0),
                    );
                }
            }
        }
        let columns: [Vec<f64>; 3] =
            std::array::from_fn(|c| series.iter().map(|&i| r[i][c]).collect());
        let mut flagged = Vec::new();
        for (k, &i) in series.iter().enumerate() {
            if skip.get(i).copied().unwrap_or(false) {
                continue;
            }
            let d: [f64; 3] = std::array::from_fn(|c| departure(&columns[c], k));
            if (0..3).any(|c| d[c].abs() > limit[c]) {
                dev[i] = d;
                flagged.push(i);
            }
        }
        flagged
    });
    // Spikes that come with reversals are a following error, machine
    // physics: when more flagged samples sit at reversals than chance
    // would put there, those are kept in the fits.
    let mut flagged = far;
    if beyond_chance_at_reversals(&flagged, n, |i| near_reversal(prep, i)) {
        flagged.retain(|&i| !near_reversal(prep, i));
    }
    if !are_faults(&flagged, n) {
        return Vec::new();
    }
    flagged.into_iter().map(|i| (i, dev[i])).collect()
}

/// How far sample `i` of a series departs from its neighbours: the
/// smaller of its departures from the running median of the 7 samples
/// around it (which follows a step) and from the median of three straight-
/// line predictions from its neighbours (from the left pair, the right
/// pair, and the two beside it; which follow a kink). A gross fault departs
/// from both; a step, a kink or a slope from at most one.
pub fn departure(e: &[f64], i: usize) -> f64 {
    let n = e.len();
    let a = i.saturating_sub(MEDIAN_HALF);
    let b = (i + MEDIAN_HALF + 1).min(n);
    let mut w: arrayvec::ArrayVec<f64, 7> = e[a..b].iter().copied().collect();
    let mid = w.len() / 2;
    w.select_nth_unstable_by(mid, f64::total_cmp);
    let from_median = e[i] - w[mid];
    let mut p: arrayvec::ArrayVec<f64, 3> = arrayvec::ArrayVec::new();
    if i >= 2 {
        p.push(2.0 * e[i - 1] - e[i - 2]);
    }
    if i + 2 < n {
        p.push(2.0 * e[i + 1] - e[i + 2]);
    }
    if i >= 1 && i + 1 < n {
        p.push(0.5 * (e[i - 1] + e[i + 1]));
    }
    if p.is_empty() {
        return from_median;
    }
    p.sort_by(f64::total_cmp);
    let from_line = e[i] - p[p.len() / 2];
    if from_median.abs() < from_line.abs() {
        from_median
    } else {
        from_line
    }
}

/// Whether some axis reverses within two samples of sample `i`.
fn near_reversal(prep: &Prepared, i: usize) -> bool {
    let a = i.saturating_sub(2);
    let b = (i + 2).min(prep.n - 1);
    (0..prep.dof).any(|j| (a..b).any(|k| prep.dirj(k, j) * prep.dirj(k + 1, j) < 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One sample at a pseudo-random place in each run of `step` samples
    /// of `n` (so that some fall side by side, as faults at random do).
    fn scattered(n: usize, step: usize) -> Vec<usize> {
        let mut state = 12345u64;
        let mut out: Vec<usize> = (0..n / step)
            .map(|k| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                k * step + (state >> 33) as usize % step
            })
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    #[test]
    fn scattered_flags_are_faults_and_runs_are_a_signal() {
        let n = 5000;
        // Up to 5 % anywhere, even in one run.
        assert!(are_faults(&(100..350).collect::<Vec<_>>(), n));
        // 10 % and 25 % scattered: faults; the same numbers in runs of
        // ten samples: a signal.
        for step in [10, 4] {
            let flags = scattered(n, step);
            assert!(are_faults(&flags, n), "1 in {step} scattered");
            let runs: Vec<usize> = (0..n).filter(|i| (i / 10) % step == 0).collect();
            assert!(!are_faults(&runs, n), "1 in {step} in runs");
        }
        // Every sample of a third and more: never faults.
        let every_second: Vec<usize> = (0..n).step_by(2).collect();
        assert!(!are_faults(&every_second, n));
    }

    #[test]
    fn spikes_at_reversals_beyond_chance_are_a_following_error() {
        // Reversals every 100 samples, each marking the 5 samples about
        // it: 5 % of the samples are at a reversal.
        let n = 5000;
        let at = |i: usize| i % 100 < 5;
        // A spike after every reversal (50 of them, all at reversals).
        let spikes: Vec<usize> = (0..n).filter(|i| i % 100 == 2).collect();
        assert!(beyond_chance_at_reversals(&spikes, n, at));
        // Faults scattered at random: about 5 % of them at reversals.
        let faults = scattered(n, 10);
        let near = faults.iter().filter(|&&i| at(i)).count();
        assert!(near > 0, "some faults fall at reversals");
        assert!(!beyond_chance_at_reversals(&faults, n, at));
        // Three spikes, all at reversals: too many for chance (0.15).
        assert!(beyond_chance_at_reversals(&[2, 102, 202], n, at));
        // One alone is not.
        assert!(!beyond_chance_at_reversals(&[2], n, at));
    }

    #[test]
    fn passes_find_faults_that_hide_each_other() {
        // A search that flags one sample a pass (the largest above 1)
        // finds two faults in two passes, each without those flagged
        // before; the third pass finds none and ends the search.
        let mut e = vec![0.0; 50];
        e[20] = 10.0;
        e[21] = 9.0;
        let mut passes = 0;
        let flagged = flag_in_passes(e.len(), |series| {
            passes += 1;
            let column: Vec<f64> = series.iter().map(|&i| e[i]).collect();
            let worst = (0..series.len())
                .max_by(|&a, &b| column[a].abs().total_cmp(&column[b].abs()))
                .filter(|&k| column[k].abs() > 1.0);
            worst.map(|k| series[k]).into_iter().collect()
        });
        assert_eq!(flagged, vec![20, 21]);
        assert_eq!(passes, 3, "two passes flag, the third finds none");
    }
}
