//! Gross outliers of a residual: samples that depart from their
//! neighbours far beyond the noise (a broken beam, a misread probe).

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::prepare::Prepared;

/// A sample departs from its neighbours by more than this many noise
/// floors to be a gross outlier.
pub const OUTLIER_SIGMAS: f64 = 10.0;

/// Half-width of the running median the outliers are measured against.
const MEDIAN_HALF: usize = 3;

/// More flagged samples than this fraction are not gross faults but a
/// signal the running median cannot follow: none is called an outlier.
const MAX_OUTLIER_FRACTION: f64 = 0.05;

/// Gross outliers of a residual: samples whose residual, without each
/// axis's apparent lag ([`super::offset::lag_free`]), departs from its
/// neighbours ([`departure`]) by more than [`OUTLIER_SIGMAS`] noise floors
/// in some coordinate (samples `skip` marks are not looked at). A smooth
/// effect, a kink, a step at a reversal or an onset is never flagged. When
/// most flagged samples sit within two samples of a reversal (more than
/// chance would put there), those are a following error at reversals,
/// machine physics, and stay in. More than 5 % flagged is not a fault
/// but a signal the running median cannot follow: then none is flagged.
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
    let mut out = Vec::new();
    let mut column = vec![0.0; n];
    let mut dev = vec![[0.0; 3]; n];
    let mut far = vec![false; n];
    // Without each axis's apparent lag: where the feed changes, a lag
    // moves the tip by more between two samples than the running median
    // follows, and those samples are physics, not faults.
    let r = super::offset::lag_free(prep);
    for c in 0..3 {
        for i in 0..n {
            column[i] = r[i][c];
        }
        for i in 0..n {
            if skip.get(i).copied().unwrap_or(false) {
                continue;
            }
            let d = departure(&column, i);
            dev[i][c] = d;
            if d.abs() > OUTLIER_SIGMAS * sigma_xyz[c].max(1e-9) {
                far[i] = true;
            }
        }
    }
    for i in 0..n {
        if far[i] {
            out.push((i, dev[i]));
        }
    }
    // Spikes that come with reversals are a following error, machine
    // physics: when most flagged samples sit at reversals, more than
    // chance would put there, those are kept in the fits.
    let near = out.iter().filter(|(i, _)| near_reversal(prep, *i)).count();
    let base = (0..n).filter(|&i| near_reversal(prep, i)).count() as f64 / n as f64;
    if out.len() >= 5 && near as f64 >= 0.6 * out.len() as f64 && base < 0.3 {
        out.retain(|(i, _)| !near_reversal(prep, *i));
    }
    if out.len() as f64 > MAX_OUTLIER_FRACTION * n as f64 {
        return Vec::new();
    }
    out
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
