//! A plotted series thinned as it grows, so that a plot of a program of
//! any length takes a fixed amount of memory and its SVG a fixed size,
//! and no peak is lost: the points fall into buckets of equal count, and
//! each bucket keeps its lowest and its highest point.

/// Buckets kept at most: a series draws at most twice as many points.
pub const MAX_BUCKETS: usize = 1024;

/// The lowest and highest point of a run of consecutive points.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bucket {
    low: (f64, f64),
    high: (f64, f64),
}

impl Bucket {
    fn merged(a: Bucket, b: Bucket) -> Bucket {
        // The earlier point of equal values, as pushing them one by one.
        let low = if b.low.1 < a.low.1 { b.low } else { a.low };
        let high = if b.high.1 > a.high.1 { b.high } else { a.high };
        Bucket { low, high }
    }
}

/// A series of `(x, y)` points pushed in order of `x`, kept as at most
/// [`MAX_BUCKETS`] buckets of `width` consecutive points each (a power of
/// two: when the buckets are all full, neighbours merge in pairs and the
/// width doubles). Up to [`MAX_BUCKETS`] points every point is kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Envelope {
    buckets: Vec<Bucket>,
    /// Points per bucket.
    width: usize,
    /// Points in the last bucket.
    filled: usize,
}

impl Default for Envelope {
    fn default() -> Self {
        Envelope {
            buckets: Vec::new(),
            width: 1,
            filled: 0,
        }
    }
}

impl Envelope {
    /// An empty series.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a point. A point whose `y` is not finite is not drawn (it would
    /// hide the others' scale) and is skipped.
    pub fn push(&mut self, x: f64, y: f64) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        match self.buckets.last_mut() {
            Some(b) if self.filled < self.width => {
                if y < b.low.1 {
                    b.low = (x, y);
                }
                if y > b.high.1 {
                    b.high = (x, y);
                }
                self.filled += 1;
            }
            _ => {
                if self.buckets.len() == MAX_BUCKETS {
                    self.buckets = self
                        .buckets
                        .chunks_exact(2)
                        .map(|p| Bucket::merged(p[0], p[1]))
                        .collect();
                    self.width *= 2;
                }
                self.buckets.push(Bucket {
                    low: (x, y),
                    high: (x, y),
                });
                self.filled = 1;
            }
        }
    }

    /// The points to draw, in order of `x`: of each bucket its lowest and
    /// highest point (one, where they are the same point).
    pub fn points(&self) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(2 * self.buckets.len());
        for b in &self.buckets {
            let (first, second) = if b.high.0 < b.low.0 {
                (b.high, b.low)
            } else {
                (b.low, b.high)
            };
            out.push(first);
            if second != first {
                out.push(second);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A series that wanders with a few sharp peaks, as per-block errors do.
    fn series(n: usize) -> Vec<(f64, f64)> {
        (0..n)
            .map(|i| {
                let x = i as f64;
                let spike = if i % 9973 == 17 { 50.0 } else { 0.0 };
                (
                    x,
                    (x * 0.001).sin() + 0.01 * ((i * 7919) % 101) as f64 + spike,
                )
            })
            .collect()
    }

    #[test]
    fn a_short_series_is_kept_whole() {
        let pts = series(MAX_BUCKETS);
        let mut e = Envelope::new();
        for &(x, y) in &pts {
            e.push(x, y);
        }
        assert_eq!(e.points(), pts);
    }

    #[test]
    fn a_long_series_keeps_every_peak_and_a_bounded_size() {
        for n in [MAX_BUCKETS + 1, 5_000, 65_536, 300_001] {
            let pts = series(n);
            let mut e = Envelope::new();
            for &(x, y) in &pts {
                e.push(x, y);
            }
            let drawn = e.points();
            assert!(
                drawn.len() <= 2 * MAX_BUCKETS,
                "{n}: {} points",
                drawn.len()
            );
            assert!(drawn.len() > MAX_BUCKETS / 2, "{n}: {} points", drawn.len());
            // In order of x, each one a point of the series.
            assert!(drawn.windows(2).all(|w| w[0].0 < w[1].0), "{n}");
            assert!(drawn.iter().all(|&(x, y)| pts[x as usize].1 == y), "{n}");
            // The bucket width (a power of two) found from the count, and
            // the extremes of every run of that many points drawn.
            let mut width = 1;
            while n.div_ceil(width) > MAX_BUCKETS {
                width *= 2;
            }
            for run in pts.chunks(width) {
                let lo = run.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
                let hi = run.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
                let (x0, x1) = (run[0].0, run[run.len() - 1].0);
                let inside: Vec<f64> = drawn
                    .iter()
                    .filter(|p| p.0 >= x0 && p.0 <= x1)
                    .map(|p| p.1)
                    .collect();
                assert!(
                    inside.contains(&lo) && inside.contains(&hi),
                    "{n}: run at {x0}"
                );
            }
        }
    }

    #[test]
    fn points_that_are_not_finite_are_skipped() {
        let mut e = Envelope::new();
        e.push(0.0, 1.0);
        e.push(1.0, f64::NAN);
        e.push(2.0, f64::INFINITY);
        e.push(3.0, 2.0);
        assert_eq!(e.points(), vec![(0.0, 1.0), (3.0, 2.0)]);
    }
}
