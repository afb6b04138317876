//! Moving a recording's commands to the machine's clock, and dropping
//! samples.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use super::super::prepare::Prepared;
use super::super::recording::{Recording, Sample};
use super::resolution::quantum;

/// `rec` with its command columns moved to the machine's clock: each
/// sample stamped t gets the command of t − `offset_s`, interpolated by a
/// cubic Hermite spline through the recorded commands (three-point
/// tangents; exact for a constant feed and for a constant acceleration
/// within a block, at even or uneven sampling). Samples whose t − offset falls outside
/// the recording are dropped.
///
/// Where a command changes its acceleration between two samples no
/// interpolant knows where, and the aligned command may be off by up to
/// about a quarter of the largest third difference nearby (at the local
/// spacing, `third_difference`) times the shift in samples: that bound
/// is returned per sample and axis (`blur`, mm or deg), so that samples
/// the alignment cannot place within the noise are left out of the fits.
pub fn align(rec: &Recording, offset_s: f64) -> Aligned {
    align_clock(rec, Clock::offset(offset_s))
}

/// The recording's clock against the program's: the sample stamped t
/// shows the machine at t − shift(t), shift(t) = offset + rate·(t − t_ref)
/// (a clock offset, and a clock that runs `rate` fast or slow: two free-
/// running clocks differ by some ppm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clock {
    /// The shift at `t_ref`, s.
    pub offset_s: f64,
    /// How much faster the recording's clock runs, s per s (20 ppm: 2e-5).
    pub rate: f64,
    /// The time the offset is given at, s.
    pub t_ref: f64,
}

impl Clock {
    /// A constant offset.
    pub fn offset(offset_s: f64) -> Clock {
        Clock {
            offset_s,
            rate: 0.0,
            t_ref: 0.0,
        }
    }

    /// The shift at the stamp `t`, s.
    pub fn shift(&self, t: f64) -> f64 {
        self.offset_s + self.rate * (t - self.t_ref)
    }
}

/// [`align`] for a clock that also runs fast or slow: each sample stamped
/// t gets the command of t − `clock.shift(t)`.
pub fn align_clock(rec: &Recording, clock: Clock) -> Aligned {
    let s = &rec.samples;
    let n = s.len();
    let mut out = Recording {
        axes: rec.axes.clone(),
        temp_names: rec.temp_names.clone(),
        samples: Vec::with_capacity(n),
    };
    let mut kept = Vec::with_capacity(n);
    let dof = rec.axes.len();
    let mut blur = Vec::with_capacity(n * dof);
    if n < 2 {
        return Aligned {
            rec: out,
            kept,
            blur,
        };
    }
    // Third difference of the commands over samples k − 1 … k + 2.
    // Rounded commands carry a third difference of their own (its
    // standard deviation is √(20/12)·q for a step q); three of those are
    // not a change of acceleration.
    let rounding: Vec<f64> = (0..dof)
        .map(|j| rounding_allowance(&s.iter().map(|x| x.q[j]).collect::<Vec<f64>>()))
        .collect();
    // Near the ends the tangents are one-sided and nothing bounds the
    // error: such samples count as doubtful (a bound of 1 m).
    let d3 = |k: usize, j: usize| {
        if k == 0 || k + 2 >= n {
            return 4e3;
        }
        let d = third_difference(
            [s[k - 1].t, s[k].t, s[k + 1].t, s[k + 2].t],
            [s[k - 1].q[j], s[k].q[j], s[k + 1].q[j], s[k + 2].q[j]],
        );
        (d - rounding[j]).max(0.0)
    };
    let times: Vec<f64> = s.iter().map(|x| x.t).collect();
    let columns: Vec<Vec<f64>> = (0..dof)
        .map(|j| s.iter().map(|x| x.q[j]).collect())
        .collect();
    let mut k = 0usize;
    for (i, smp) in s.iter().enumerate() {
        let offset_s = clock.shift(smp.t);
        let tt = smp.t - offset_s;
        if tt < s[0].t || tt > s[n - 1].t {
            continue;
        }
        while k + 2 < n && s[k + 1].t <= tt {
            k += 1;
        }
        while k > 0 && s[k].t > tt {
            k -= 1;
        }
        let (t0, t1) = (s[k].t, s[k + 1].t);
        let dt = t1 - t0;
        let u = ((tt - t0) / dt).clamp(0.0, 1.0);
        let q: Vec<f64> = columns
            .iter()
            .map(|y| monotone_hermite(&times, y, k, tt))
            .collect();
        let block = if u < 0.5 { s[k].block } else { s[k + 1].block };
        let shift = (offset_s.abs() / dt).min(1.0);
        for j in 0..dof {
            let worst = (k.saturating_sub(1)..=k + 1)
                .map(|m| d3(m, j))
                .fold(0.0, f64::max);
            blur.push(0.25 * worst * shift);
        }
        out.samples.push(Sample {
            q,
            block,
            ..smp.clone()
        });
        kept.push(i);
    }
    Aligned {
        rec: out,
        kept,
        blur,
    }
}

/// What the rounding of a column of values alone can give as a third
/// difference: three standard deviations of it (√(20/12)·q for a step q,
/// [`quantum`]); 0 where the values are not rounded.
pub(super) fn rounding_allowance(values: &[f64]) -> f64 {
    quantum(values).map_or(0.0, |q| 3.0 * (20.0f64 / 12.0).sqrt() * q)
}

/// The third difference of four samples `y` at the increasing times `t`,
/// as it would be at their mean spacing h: `6·h³` times the third divided
/// difference (`y₃ − 3y₂ + 3y₁ − y₀` where the samples are evenly spaced).
/// Zero for a constant feed and a constant acceleration however unevenly
/// the samples fall, where the plain difference of unevenly spaced samples
/// of a steady feed is the feed times the jitter.
pub(super) fn third_difference(t: [f64; 4], y: [f64; 4]) -> f64 {
    let d1: [f64; 3] = std::array::from_fn(|i| (y[i + 1] - y[i]) / (t[i + 1] - t[i]));
    let d2: [f64; 2] = std::array::from_fn(|i| (d1[i + 1] - d1[i]) / (t[i + 2] - t[i]));
    let d3 = (d2[1] - d2[0]) / (t[3] - t[0]);
    let h = (t[3] - t[0]) / 3.0;
    (6.0 * h * h * h * d3).abs()
}

/// The value at `tt` (within interval `k` of the increasing times `t`) of
/// the cubic Hermite spline through `y` with three-point tangents (the
/// slope of the parabola through a sample and its neighbours),
/// limited so that it never overshoots (Fritsch–Carlson): a tangent is 0
/// where the data turns or stands still, and at most three times the
/// smaller neighbouring slope. Exact for a constant feed and a constant
/// acceleration away from stops; a command that stands still stays still
/// (an overshoot there would fake a reversal).
pub fn monotone_hermite(t: &[f64], y: &[f64], k: usize, tt: f64) -> f64 {
    let n = t.len();
    let slope = |i: usize| (y[i + 1] - y[i]) / (t[i + 1] - t[i]);
    let tangent = |i: usize| -> f64 {
        if i == 0 {
            return slope(0);
        }
        if i == n - 1 {
            return slope(n - 2);
        }
        let (a, b) = (slope(i - 1), slope(i));
        if a * b <= 0.0 {
            return 0.0;
        }
        // The slope at t[i] of the parabola through the three samples
        // (the central difference where they are evenly spaced).
        let (h0, h1) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        let m = (h1 * a + h0 * b) / (h0 + h1);
        let cap = 3.0 * a.abs().min(b.abs());
        m.clamp(-cap, cap)
    };
    let h = t[k + 1] - t[k];
    let (m0, m1) = if y[k + 1] == y[k] {
        (0.0, 0.0)
    } else {
        (tangent(k), tangent(k + 1))
    };
    let u = ((tt - t[k]) / h).clamp(0.0, 1.0);
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0) * y[k]
        + (u3 - 2.0 * u2 + u) * h * m0
        + (-2.0 * u3 + 3.0 * u2) * y[k + 1]
        + (u3 - u2) * h * m1
}

/// A recording moved to the machine's clock ([`align`]).
#[derive(Debug, Clone)]
pub struct Aligned {
    /// The aligned recording.
    pub rec: Recording,
    /// Per sample, its index in the original recording.
    pub kept: Vec<usize>,
    /// Per sample and axis (`kept.len() × dof`), a bound of the
    /// interpolation error of the aligned command (mm or deg).
    pub blur: Vec<f64>,
}

impl Aligned {
    /// Samples whose interpolation error, carried to the tip by the
    /// Jacobian of `prep` (prepared from this recording), may exceed
    /// `limit_mm`.
    pub fn doubtful(&self, prep: &Prepared, limit_mm: f64) -> Vec<bool> {
        let dof = prep.dof;
        (0..prep.n)
            .map(|i| {
                let e: f64 = (0..dof)
                    .map(|j| {
                        let jj = prep.jj(i, j);
                        (jj[0] * jj[0] + jj[1] * jj[1] + jj[2] * jj[2]).sqrt()
                            * self.blur[i * dof + j]
                    })
                    .sum();
                e > limit_mm
            })
            .collect()
    }
}

/// `rec` without the samples at `drop` (sorted indices); with the indices
/// of the samples kept.
pub fn without(rec: &Recording, drop: &[usize]) -> (Recording, Vec<usize>) {
    let mut out = Recording {
        axes: rec.axes.clone(),
        temp_names: rec.temp_names.clone(),
        samples: Vec::with_capacity(rec.samples.len()),
    };
    let mut kept = Vec::with_capacity(rec.samples.len());
    let mut d = drop.iter().peekable();
    for (i, s) in rec.samples.iter().enumerate() {
        if d.peek() == Some(&&i) {
            d.next();
            continue;
        }
        out.samples.push(s.clone());
        kept.push(i);
    }
    (out, kept)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recording of one axis X commanded `q(t)` at the times `t`.
    fn one_axis(t: impl Iterator<Item = f64>, q: impl Fn(f64) -> f64) -> Recording {
        let samples = t
            .map(|t| Sample {
                t,
                block: Some(1),
                q: vec![q(t)],
                meas: [0.0; 3],
                meas_axis: None,
                temps: Vec::new(),
            })
            .collect();
        Recording {
            axes: vec!["X".into()],
            temp_names: Vec::new(),
            samples,
        }
    }

    #[test]
    fn alignment_reproduces_a_quadratic_command() {
        // q(t) = 3 + 2t + 0.5t²: the Hermite spline with central tangents
        // is exact for it away from the ends.
        let q = |t: f64| 3.0 + 2.0 * t + 0.5 * t * t;
        let rec = one_axis((0..40).map(|i| i as f64 * 0.1), q);
        let al = align(&rec, 0.015);
        let (a, kept) = (&al.rec, &al.kept);
        assert_eq!(
            kept.first(),
            Some(&1),
            "the first sample has no command 15 ms before"
        );
        for (s, &i) in a.samples.iter().zip(kept).skip(1).take(30) {
            let want = q(rec.samples[i].t - 0.015);
            assert!((s.q[0] - want).abs() < 1e-12, "{} vs {want}", s.q[0]);
        }
    }

    /// Samples at uneven intervals (the stamps correct, the interval
    /// 0.1 s ± 5 ms): the alignment is exact for a constant acceleration,
    /// and no sample of it is doubtful. Before, the tangents were central
    /// differences (off by the acceleration times the jitter) and the
    /// third differences were taken as if evenly spaced (the feed times
    /// the jitter), which left most samples of such a recording out.
    #[test]
    fn uneven_sampling_aligns_a_quadratic_command_exactly() {
        let q = |t: f64| 3.0 + 20.0 * t + 5.0 * t * t;
        let jitter = [0.0, 0.004, -0.005, 0.002, -0.003, 0.005, -0.001];
        let rec = one_axis(
            (0..40).map(|i| i as f64 * 0.1 + jitter[i % jitter.len()]),
            q,
        );
        let al = align(&rec, 0.015);
        // Away from the ends, where the tangents are one-sided.
        let mut checked = 0;
        for (m, (s, &i)) in al.rec.samples.iter().zip(&al.kept).enumerate() {
            if i < 3 || i + 3 >= rec.samples.len() {
                continue;
            }
            let want = q(rec.samples[i].t - 0.015);
            assert!((s.q[0] - want).abs() < 1e-11, "{} vs {want}", s.q[0]);
            assert!(al.blur[m] < 1e-9, "sample {i}: blur {}", al.blur[m]);
            checked += 1;
        }
        assert_eq!(checked, 34);
    }
}
