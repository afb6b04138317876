//! Commands held over several rows: a controller's trace merged onto a
//! faster measurement stream by a logger that forward-fills the slower
//! columns (the last command repeated until the next one arrives). The
//! rows between two commands pair a stale command with a fresh measured
//! tip, which lags it by up to the stream's period times the feed: a
//! saw-tooth at the command stream's rate that is no machine physics (it
//! was read as a vibration, and as hundreds of outliers).

use std::collections::BTreeMap;

use super::super::recording::Recording;
use super::super::report::{MeasurementFinding, Where};

/// The commands are taken as held when at least this share of the
/// intervals between the rows where they change is a whole multiple of
/// the most common interval (at least 2 rows).
const MULTIPLE_SHARE: f64 = 0.95;

/// ... and at least this share is that interval itself.
const MODE_SHARE: f64 = 0.5;

/// Fewest changes of the commands to tell (below it, nothing is said).
const MIN_CHANGES: usize = 20;

/// A recording with the rows of held commands left out.
#[derive(Debug, Clone)]
pub struct HeldCommands {
    /// The rows where the commands were sampled (every `every`-th row
    /// from each change of the commands on).
    pub rec: Recording,
    /// Rows per sample of the command stream.
    pub every: usize,
    /// Rows of the recording as read.
    pub rows: usize,
    /// The command stream's period, s (median over its samples).
    pub period_s: f64,
}

/// The rows of `rec` whose commands were sampled, where the commands
/// change only every N-th row (N ≥ 2) while the rows go on: between two
/// changes of an axis in motion the values repeat exactly, so the
/// intervals between changes are N rows, and whole multiples of N where
/// the axes rest. A recording of commands sampled with every row changes
/// them at consecutive rows while it moves; commands rounded coarsely at a
/// slow feed change at irregular intervals. `None` when the commands are
/// not held.
pub fn held_commands(rec: &Recording) -> Option<HeldCommands> {
    let s = &rec.samples;
    let n = s.len();
    let changes: Vec<usize> = (1..n)
        .filter(|&i| {
            s[i].q.iter().zip(&s[i - 1].q).any(|(a, b)| a != b) || s[i].block != s[i - 1].block
        })
        .collect();
    if changes.len() < MIN_CHANGES {
        return None;
    }
    let gaps: Vec<usize> = changes.windows(2).map(|w| w[1] - w[0]).collect();
    let mut count: BTreeMap<usize, usize> = BTreeMap::new();
    for g in &gaps {
        *count.entry(*g).or_default() += 1;
    }
    let (&every, &at_mode) = count
        .iter()
        .max_by_key(|(g, c)| (**c, std::cmp::Reverse(**g)))?;
    let m = gaps.len() as f64;
    let multiples = gaps.iter().filter(|g| g.is_multiple_of(every)).count() as f64;
    if every < 2 || (at_mode as f64) < MODE_SHARE * m || multiples < MULTIPLE_SHARE * m {
        return None;
    }
    // Each row where the commands change is a sample of their stream, and
    // so is every `every`-th row after it until the next change.
    let mut keep = Vec::with_capacity(n / every + 1);
    let mut last = 0usize;
    let mut next = changes.iter().copied().peekable();
    for i in 0..n {
        if next.peek() == Some(&i) {
            next.next();
            last = i;
        }
        if (i - last).is_multiple_of(every) {
            keep.push(i);
        }
    }
    let mut steps: Vec<f64> = keep.windows(2).map(|w| s[w[1]].t - s[w[0]].t).collect();
    steps.sort_by(f64::total_cmp);
    let period_s = steps.get(steps.len() / 2).copied().unwrap_or(0.0);
    Some(HeldCommands {
        rec: Recording {
            axes: rec.axes.clone(),
            temp_names: rec.temp_names.clone(),
            samples: keep.iter().map(|&i| s[i].clone()).collect(),
        },
        every,
        rows: n,
        period_s,
    })
}

impl HeldCommands {
    /// The note of the report (`formats.md` §2c: repaired and reported;
    /// not a finding, since no effect is fitted to it).
    pub fn note(&self) -> MeasurementFinding {
        let s = &self.rec.samples;
        let (first, last) = (s.first(), s.last());
        MeasurementFinding {
            effect: "held_commands".into(),
            axis: None,
            parameters: BTreeMap::from([
                ("every_rows".to_string(), self.every as f64),
                ("period_s".to_string(), self.period_s),
                ("rows_left_out".to_string(), (self.rows - s.len()) as f64),
            ]),
            uncertainty: BTreeMap::new(),
            where_: Where {
                blocks: [first.and_then(|x| x.block), last.and_then(|x| x.block)],
                t_s: [first.map_or(0.0, |x| x.t), last.map_or(0.0, |x| x.t)],
                condition: format!(
                    "the commands change only every {} rows (every {:.3} ms) while the measured tip is recorded at every row: forward-filled from a slower stream (merged logger streams), so the rows between hold a stale command; only the {} rows where the commands were sampled are fitted, {} of {} left out",
                    self.every,
                    self.period_s * 1e3,
                    s.len(),
                    self.rows - s.len(),
                    self.rows
                ),
            },
            rms_explained_mm: 0.0,
            machine_physics: false,
            samples: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::recording::Sample;

    fn rec(q: &[f64], meas: &[f64]) -> Recording {
        Recording {
            axes: vec!["X".into()],
            temp_names: Vec::new(),
            samples: q
                .iter()
                .enumerate()
                .map(|(i, &x)| Sample {
                    t: i as f64 * 0.01,
                    block: Some(1),
                    q: vec![x],
                    meas: [meas[i], 0.0, 0.0],
                    meas_axis: None,
                    temps: Vec::new(),
                })
                .collect(),
        }
    }

    /// A move, a rest and a move again, its command held for 4 rows: the
    /// rows where the command stream was sampled are kept, at rest too.
    #[test]
    fn held_rows_are_left_out() {
        let fine: Vec<f64> = (0..400)
            .map(|i| match i {
                0..100 => i as f64,
                100..200 => 100.0,
                _ => 100.0 - (i - 200) as f64,
            })
            .collect();
        assert!(held_commands(&rec(&fine, &fine)).is_none());
        let held: Vec<f64> = (0..400).map(|i| fine[i - i % 4]).collect();
        let h = held_commands(&rec(&held, &fine)).expect("held");
        assert_eq!(h.every, 4);
        assert_eq!(h.rec.samples.len(), 100);
        assert!(h.rec.samples.iter().all(|s| s.meas[0] == s.q[0]));
    }
}
