//! The direction of an axis's last motion, with a dead band against
//! trace jitter (backlash and reversal effects read it).

/// Tracks the direction of the last motion of one axis, with a dead band so
/// that trace jitter does not count as a reversal: the direction changes
/// only once the axis has moved back by more than the dead band from its
/// turning point. Before the first motion the direction is 0.
#[derive(Debug, Clone, Copy)]
pub struct DirectionTracker {
    dead_band: f64,
    dir: f64,
    extreme: Option<f64>,
}

/// Default dead band of [`DirectionTracker`] (mm or deg).
pub const DIRECTION_DEAD_BAND: f64 = 1e-4;

impl DirectionTracker {
    /// A tracker with the given dead band (mm or deg).
    pub fn new(dead_band: f64) -> Self {
        DirectionTracker {
            dead_band,
            dir: 0.0,
            extreme: None,
        }
    }

    /// Feeds the next commanded position; returns the direction of the last
    /// motion (−1, 0 or +1).
    pub fn update(&mut self, q: f64) -> f64 {
        match self.extreme {
            None => self.extreme = Some(q),
            Some(e) => {
                if self.dir > 0.0 {
                    if q > e {
                        self.extreme = Some(q);
                    } else if q < e - self.dead_band {
                        self.dir = -1.0;
                        self.extreme = Some(q);
                    }
                } else if self.dir < 0.0 {
                    if q < e {
                        self.extreme = Some(q);
                    } else if q > e + self.dead_band {
                        self.dir = 1.0;
                        self.extreme = Some(q);
                    }
                } else if (q - e).abs() > self.dead_band {
                    self.dir = (q - e).signum();
                    self.extreme = Some(q);
                }
            }
        }
        self.dir
    }
}
