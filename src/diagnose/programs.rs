//! Exercise programs as waypoint lists, for simulations, tests and demos:
//! random point-to-point moves that reverse every axis many times, at
//! varied feeds, so that direction-, speed-, position- and time-dependent
//! effects can be told apart.

use super::rng::Rng;
use super::simulate::{Waypoint, WaypointPath};

/// Travel of one axis for [`random_moves`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Travel {
    /// Lowest position (mm, deg).
    pub lo: f64,
    /// Highest position (mm, deg).
    pub hi: f64,
}

/// `blocks` moves from the middle of the travels: in every block each axis
/// moves, with probability `move_prob`, to a uniformly random position in
/// its travel; the feed is uniform in `feed` (mm/min). Blocks are numbered
/// 1 (the start position), 2, 3, … Deterministic for a seed.
pub fn random_moves(
    travels: &[Travel],
    blocks: usize,
    feed: (f64, f64),
    move_prob: f64,
    seed: u64,
) -> Vec<Waypoint> {
    let mut rng = Rng::new(seed);
    let mut q: Vec<f64> = travels.iter().map(|t| 0.5 * (t.lo + t.hi)).collect();
    let mut out = vec![Waypoint {
        q: q.clone(),
        feed: feed.1,
        block: 1,
        path: WaypointPath::Straight,
    }];
    for b in 0..blocks {
        let mut moved = false;
        for (j, t) in travels.iter().enumerate() {
            if rng.uniform() < move_prob {
                q[j] = t.lo + (t.hi - t.lo) * rng.uniform();
                moved = true;
            }
        }
        if !moved && !travels.is_empty() {
            let j = (rng.next_u64() % travels.len() as u64) as usize;
            let t = travels[j];
            q[j] = t.lo + (t.hi - t.lo) * rng.uniform();
        }
        let f = feed.0 + (feed.1 - feed.0) * rng.uniform();
        out.push(Waypoint {
            q: q.clone(),
            feed: f,
            block: b as u64 + 2,
            path: WaypointPath::Straight,
        });
    }
    out
}
