//! The commanded trajectory as it streams: waypoints (the blocks' end
//! points) become segments of a timeline one at a time
//! (`SegmentBuilder`), and a `Window` of the segments still needed
//! gives the commanded position at increasing times. Memory holds the
//! segments between the earliest time still asked for and the latest
//! pushed, not the program.
//!
//! Time comes from the feeds: each segment between two waypoints is one
//! block, run at its feed F (mm/min) along its path length (a circular
//! move along the straight pieces that stand for it, [`WaypointPath`])
//!
//! ```text
//! L = sqrt( Σ Δ(linear axis, mm)² + Σ Δ(rotary axis, deg)² )
//! ```
//!
//! i.e. one degree counts as one millimetre (the usual controller rule for
//! mixed linear/rotary moves; a pure rotary move runs at F deg/min). The
//! speed along the path follows a trapezoid with the acceleration limit
//! (a triangle when the block is too short to reach F), starting and
//! stopping in every block (exact stop). With no acceleration limit the
//! speed is F throughout the block.

use std::collections::VecDeque;

use crate::error::{Error, Location, Result};
use crate::machine::chain::Chain;

/// A commanded machine position: the end point of a block.
#[derive(Debug, Clone, PartialEq)]
pub struct Waypoint {
    /// Axis positions in the machine's joint order (mm, deg).
    pub q: Vec<f64>,
    /// Feed of the block that ends here, mm/min (deg/min for pure rotary
    /// moves). Ignored for the first waypoint, the start position.
    pub feed: f64,
    /// NC block number of the move that ends here.
    pub block: u64,
    /// How the block gets here from the waypoint before.
    pub path: WaypointPath,
}

/// How a block reaches its waypoint from the one before.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum WaypointPath {
    /// A straight move of the axes.
    #[default]
    Straight,
    /// Through these axis positions (mm, deg; joint order), in order, and
    /// straight between them: a circular move as the points it passes.
    Through(Vec<Vec<f64>>),
    /// A move whose path the program does not give (to the reference
    /// point, a canned cycle): the recording leaves it out, and the next
    /// block starts at this waypoint at the time the block before ended.
    Unknown,
}

/// One block of the timeline.
#[derive(Debug, Clone)]
pub(crate) struct Segment {
    t_start: f64,
    duration: f64,
    length: f64,
    v_max: f64,
    accel: Option<f64>,
    /// The path's corners, from the block's start to its end (two for a
    /// straight move).
    corners: Vec<Vec<f64>>,
    /// The path length at each corner (0 at the first).
    at: Vec<f64>,
    block: u64,
}

impl Segment {
    /// The position and the velocity along the path (per unit of path
    /// speed) `p` along it.
    fn position(&self, p: f64, q: &mut [f64], dir: &mut [f64]) {
        let last = self.corners.len() - 1;
        let i = self
            .at
            .partition_point(|&a| a <= p)
            .saturating_sub(1)
            .min(last - 1);
        let (a, b) = (&self.corners[i], &self.corners[i + 1]);
        let piece = self.at[i + 1] - self.at[i];
        let f = if piece > 0.0 {
            ((p - self.at[i]) / piece).clamp(0.0, 1.0)
        } else {
            1.0
        };
        for j in 0..q.len() {
            q[j] = a[j] + f * (b[j] - a[j]);
            dir[j] = if piece > 0.0 {
                (b[j] - a[j]) / piece
            } else {
                0.0
            };
        }
    }

    /// Path position and speed `duration` seconds… at local time `tau`.
    fn s_and_v(&self, tau: f64) -> (f64, f64) {
        let tau = tau.clamp(0.0, self.duration);
        match self.accel {
            None => (self.v_max * tau, self.v_max),
            Some(a) => {
                let ta = self.v_max / a; // time to reach v_max (may be cut short)
                let t_half = 0.5 * self.duration;
                let t_acc = ta.min(t_half);
                let v_top = a * t_acc;
                if tau <= t_acc {
                    (0.5 * a * tau * tau, a * tau)
                } else if tau <= self.duration - t_acc {
                    (0.5 * a * t_acc * t_acc + v_top * (tau - t_acc), v_top)
                } else {
                    let r = self.duration - tau;
                    (self.length - 0.5 * a * r * r, a * r)
                }
            }
        }
    }
}

/// The corners of a block's path, from `from` through the points of
/// `path` ([`WaypointPath::Through`]; none for the others) to `to`, and the
/// path length at each ([`path_length`] summed; 0 at the first).
pub fn path_corners(
    chain: &Chain,
    from: &[f64],
    path: &WaypointPath,
    to: &[f64],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut corners = vec![from.to_vec()];
    if let WaypointPath::Through(points) = path {
        corners.extend(points.iter().cloned());
    }
    corners.push(to.to_vec());
    let mut at = vec![0.0];
    for pair in corners.windows(2) {
        at.push(at[at.len() - 1] + path_length(chain, &pair[0], &pair[1]));
    }
    (corners, at)
}

/// Path length of a move (mm, with 1° counted as 1 mm).
pub fn path_length(chain: &Chain, from: &[f64], to: &[f64]) -> f64 {
    chain
        .joints()
        .iter()
        .zip(from.iter().zip(to))
        .map(|(_, (a, b))| (b - a) * (b - a))
        .sum::<f64>()
        .sqrt()
}

/// Turns waypoints, pushed in order, into the timeline's segments: a block
/// of zero length, or whose path is unknown, takes no time and gives none.
pub(crate) struct SegmentBuilder<'c> {
    chain: &'c Chain,
    accel: Option<f64>,
    /// The last waypoint pushed (its axis values), and how many were.
    last: Option<Vec<f64>>,
    count: usize,
    /// Where the next segment starts, s.
    t: f64,
}

impl<'c> SegmentBuilder<'c> {
    /// A timeline of `chain`'s axes with the acceleration limit `accel`
    /// (mm/s², `None`: constant feed in each block).
    pub(crate) fn new(chain: &'c Chain, accel: Option<f64>) -> Self {
        SegmentBuilder {
            chain,
            accel,
            last: None,
            count: 0,
            t: 0.0,
        }
    }

    /// How many waypoints were pushed.
    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// The next waypoint; the segment that ends there, if it takes time.
    pub(crate) fn push(&mut self, w: &Waypoint) -> Result<Option<Segment>> {
        let loc = || Location::new("<waypoints>", 0, 0);
        let (k, chain) = (self.count, self.chain);
        if w.q.len() != chain.dof() {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}) has {} axis values; the machine has {} joints",
                    w.block,
                    w.q.len(),
                    chain.dof()
                ),
            ));
        }
        if w.q.iter().any(|v| !v.is_finite()) {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}) has a non-finite axis value",
                    w.block
                ),
            ));
        }
        self.count += 1;
        let Some(from) = self.last.replace(w.q.clone()) else {
            return Ok(None);
        };
        match &w.path {
            WaypointPath::Straight => {}
            WaypointPath::Through(points) => {
                if let Some(p) = points
                    .iter()
                    .find(|p| p.len() != chain.dof() || p.iter().any(|v| !v.is_finite()))
                {
                    return Err(Error::input(
                        loc(),
                        format!(
                            "waypoint {k} (block {}) passes a point of {} values, not {} finite axis values",
                            w.block,
                            p.len(),
                            chain.dof()
                        ),
                    ));
                }
            }
            WaypointPath::Unknown => return Ok(None),
        }
        let (corners, at) = path_corners(chain, &from, &w.path, &w.q);
        let length = at[at.len() - 1];
        if length == 0.0 {
            return Ok(None);
        }
        if !(w.feed.is_finite() && w.feed > 0.0) {
            return Err(Error::input(
                loc(),
                format!(
                    "waypoint {k} (block {}): feed {} mm/min must be positive",
                    w.block, w.feed
                ),
            ));
        }
        let v = w.feed / 60.0;
        let duration = match self.accel {
            None => length / v,
            Some(a) => {
                if length >= v * v / a {
                    length / v + v / a
                } else {
                    2.0 * (length / a).sqrt()
                }
            }
        };
        let seg = Segment {
            t_start: self.t,
            duration,
            length,
            v_max: v,
            accel: self.accel,
            corners,
            at,
            block: w.block,
        };
        self.t += duration;
        Ok(Some(seg))
    }
}

/// The segments a stream of times still needs. Times asked for must not
/// go below the one last given to [`Window::trim`].
pub(crate) struct Window {
    segs: VecDeque<Segment>,
    /// No segment comes after the last pushed.
    ended: bool,
    /// The first waypoint (axis values, block): where the commanded
    /// trajectory stays when no block takes time.
    first: Option<(Vec<f64>, u64)>,
    /// Where the last segment pushed ends, s.
    end: f64,
}

impl Window {
    /// An empty window.
    pub(crate) fn new() -> Self {
        Window {
            segs: VecDeque::new(),
            ended: false,
            first: None,
            end: 0.0,
        }
    }

    /// Takes the first waypoint (the others are ignored here).
    pub(crate) fn start(&mut self, w: &Waypoint) {
        if self.first.is_none() {
            self.first = Some((w.q.clone(), w.block));
        }
    }

    /// The next segment of the timeline.
    pub(crate) fn push(&mut self, seg: Segment) {
        self.end = seg.t_start + seg.duration;
        self.segs.push_back(seg);
    }

    /// No more segments come.
    pub(crate) fn end(&mut self) {
        self.ended = true;
    }

    /// How many segments are kept.
    #[cfg(test)]
    pub(crate) fn kept(&self) -> usize {
        self.segs.len()
    }

    /// Whether all segments are pushed.
    pub(crate) fn ended(&self) -> bool {
        self.ended
    }

    /// Where the segments pushed so far end, s (the whole timeline's end
    /// once [`Window::end`] was called).
    pub(crate) fn end_time(&self) -> f64 {
        self.end
    }

    /// Whether the commanded position at `t` is known: no segment still
    /// to come can start at or before it.
    pub(crate) fn settled(&self, t: f64) -> bool {
        self.ended || self.segs.back().is_some_and(|s| s.t_start > t)
    }

    /// Drops the segments no time from `t` on needs.
    pub(crate) fn trim(&mut self, t: f64) {
        while self.segs.len() > 1 && self.segs[1].t_start <= t {
            self.segs.pop_front();
        }
    }

    /// The commanded position (mm, deg; chain order) and velocity (mm/s,
    /// deg/s) at `t`, from the last segment that starts at or before it
    /// (before the start at the first waypoint, after the end at the
    /// last); `t` must be [`Window::settled`]. `n`: the number of axes.
    pub(crate) fn point_at(&self, t: f64, n: usize) -> TrajPoint {
        let mut q = vec![0.0; n];
        let mut v = vec![0.0; n];
        let i = self
            .segs
            .partition_point(|s| s.t_start <= t)
            .saturating_sub(1);
        let block = match self.segs.get(i) {
            Some(s) => {
                let (p, sp) = s.s_and_v(t - s.t_start);
                s.position(p, &mut q, &mut v);
                for x in v.iter_mut() {
                    *x *= sp;
                }
                s.block
            }
            None => match &self.first {
                Some((first, block)) => {
                    q.copy_from_slice(first);
                    *block
                }
                None => 0,
            },
        };
        TrajPoint { t, block, q, v }
    }
}

/// One sample of a commanded trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajPoint {
    /// Time, s.
    pub t: f64,
    /// NC block.
    pub block: u64,
    /// Commanded positions (mm, deg), chain order.
    pub q: Vec<f64>,
    /// Commanded velocities (mm/s, deg/s).
    pub v: Vec<f64>,
}
