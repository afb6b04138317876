//! Deterministic synthetic error tables for the two fixture machines.
//!
//! Seed 000 (zhao2022-xzbc) measured X, Z and B with a laser
//! interferometer (ISO 230 cycles, several runs) and did not measure C; its
//! figures are not printed as numbers. These generators produce tables of
//! the paper's *sizes*: X and Z over −100…100 mm every 10 mm, B over
//! −90…90° every 10°, 3 runs × 2 directions, smooth error shapes (low-order
//! polynomials plus a sine) of a few µm and a few µrad, a small reversal on
//! the positioning errors, and small pseudo-random noise. The resulting
//! tool-tip error along a lens-like path is about 4 µm, as in the paper's
//! Figure 12.
//!
//! Everything is computed with IEEE basic arithmetic only (a splitmix64
//! generator, Irwin–Hall noise, a polynomial sine), so the output is the same
//! on every platform; the committed fixtures in `fixtures/errors/` are
//! checked against it.

use std::fmt::Write as _;

/// Seed of the committed `fixtures/errors/zhao2022-xzbc.csv`.
pub const ZHAO2022_SEED: u64 = 2022;
/// Seed of the committed `fixtures/errors/wang2023-xyzab.csv`.
pub const WANG2023_SEED: u64 = 2023;

/// splitmix64: a tiny, well-mixed 64-bit generator.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator started at `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Approximately standard normal (Irwin–Hall sum of four uniforms,
    /// rescaled to unit variance).
    pub fn normal(&mut self) -> f64 {
        let s = self.uniform() + self.uniform() + self.uniform() + self.uniform();
        (s - 2.0) * 3f64.sqrt()
    }
}

/// Sine by argument reduction and a Taylor polynomial (basic arithmetic only,
/// so bit-identical on every platform). Error below 1e-13 for |x| < 1e3.
fn sin_det(x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let mut r = x - (x / TAU).round() * TAU;
    if r > FRAC_PI_2 {
        r = PI - r;
    } else if r < -FRAC_PI_2 {
        r = -PI - r;
    }
    let r2 = r * r;
    // r − r³/3! + r⁵/5! − … + r¹⁹/19!
    let mut term = r;
    let mut sum = r;
    let mut k = 1.0;
    while k < 19.0 {
        term = -term * r2 / ((k + 1.0) * (k + 2.0));
        sum += term;
        k += 2.0;
    }
    sum
}

/// A smooth error shape in display units (µm or µrad) of the normalised
/// position `u ∈ [−1, 1]`: `c0 + c1 u + c2 u² + c3 u³ + amp sin(ω u + φ)`.
#[derive(Debug, Clone, Copy)]
struct Shape {
    poly: [f64; 4],
    amp: f64,
    omega: f64,
    phase: f64,
    /// Standard deviation of the per-sample noise.
    noise: f64,
    /// Reversal value: ↑ runs get +rev/2, ↓ runs −rev/2.
    reversal: f64,
}

impl Shape {
    fn eval(&self, u: f64) -> f64 {
        let [c0, c1, c2, c3] = self.poly;
        c0 + u * (c1 + u * (c2 + u * c3)) + self.amp * sin_det(self.omega * u + self.phase)
    }
}

const fn shape(poly: [f64; 4], amp: f64, omega: f64, phase: f64, noise: f64) -> Shape {
    Shape {
        poly,
        amp,
        omega,
        phase,
        noise,
        reversal: 0.0,
    }
}

/// How a column is written in the file.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FileUnit {
    /// Default unit for translations, 7 decimals.
    Mm,
    /// `[um]`, 4 decimals.
    Um,
    /// Default unit for rotations, 6 significant digits.
    Rad,
    /// `[urad]`, 4 decimals.
    Urad,
    /// `[arcsec]`, 4 decimals.
    Arcsec,
}

struct Column {
    name: &'static str,
    unit: FileUnit,
    shape: Shape,
}

struct AxisSpec {
    axis: &'static str,
    lo: f64,
    hi: f64,
    step: f64,
    runs: usize,
    /// Each run a forward and a backward pass (else forward only).
    both_directions: bool,
    columns: Vec<Column>,
}

/// Rounds to `decimals` and removes a negative zero.
fn fixed(v: f64, decimals: usize) -> String {
    let p = 10f64.powi(decimals as i32);
    let r = (v * p).round() / p;
    let r = if r == 0.0 { 0.0 } else { r };
    format!("{r:.decimals$}")
}

fn format_value(display: f64, unit: FileUnit) -> String {
    match unit {
        FileUnit::Mm => fixed(display * 1e-3, 7),
        FileUnit::Um => fixed(display, 4),
        FileUnit::Urad => fixed(display, 4),
        FileUnit::Arcsec => fixed(display * 1e-6 / super::table::RAD_PER_ARCSEC, 4),
        FileUnit::Rad => {
            // 6 significant digits in scientific notation, µrad exactly.
            let r = (display * 1e4).round() / 1e4;
            if r == 0.0 {
                "0".to_string()
            } else {
                format!("{:.4e}", r * 1e-6)
            }
        }
    }
}

fn header_name(c: &Column) -> String {
    match c.unit {
        FileUnit::Mm | FileUnit::Rad => c.name.to_string(),
        FileUnit::Um => format!("{}[um]", c.name),
        FileUnit::Urad => format!("{}[urad]", c.name),
        FileUnit::Arcsec => format!("{}[arcsec]", c.name),
    }
}

fn write_axis(out: &mut String, spec: &AxisSpec, rng: &mut SplitMix64) {
    let n = ((spec.hi - spec.lo) / spec.step).round() as usize;
    let targets: Vec<f64> = (0..=n).map(|i| spec.lo + spec.step * i as f64).collect();
    // One decimal for the usual 10 mm / 10° steps, two for finer scans.
    let position_decimals = if spec.step < 1.0 { 2 } else { 1 };
    let mid = 0.5 * (spec.lo + spec.hi);
    let half = 0.5 * (spec.hi - spec.lo);
    out.push_str(spec.axis);
    for c in &spec.columns {
        out.push(',');
        out.push_str(&header_name(c));
    }
    out.push('\n');
    for _run in 0..spec.runs {
        // A small offset per run and column (run-to-run repeatability).
        let run_offsets: Vec<f64> = spec
            .columns
            .iter()
            .map(|c| 0.5 * c.shape.noise * rng.normal())
            .collect();
        let directions: &[i8] = if spec.both_directions { &[1, -1] } else { &[1] };
        for &dir in directions {
            let order: Vec<f64> = if dir > 0 {
                targets.clone()
            } else {
                targets.iter().rev().copied().collect()
            };
            for &p in &order {
                let u = (p - mid) / half;
                let _ = write!(out, "{}", fixed(p, position_decimals));
                for (c, off) in spec.columns.iter().zip(&run_offsets) {
                    let s = &c.shape;
                    let v = s.eval(u)
                        + f64::from(dir) * 0.5 * s.reversal
                        + off
                        + s.noise * rng.normal();
                    out.push(',');
                    out.push_str(&format_value(v, c.unit));
                }
                out.push('\n');
            }
        }
    }
}

fn positioning(mut s: Shape, reversal: f64) -> Shape {
    s.reversal = reversal;
    s
}

fn header_comment(out: &mut String, machine: &str, seed: u64, lines: &[&str]) {
    let _ = writeln!(
        out,
        "# Synthetic geometric error tables for {machine} (kinpost geometric::synth, seed {seed})."
    );
    for l in lines {
        let _ = writeln!(out, "# {l}");
    }
    out.push_str(
        "# Each block: 3 runs, each a forward (increasing) and a backward (decreasing) pass;\n\
         # approach directions follow from the row order.\n",
    );
}

/// Error tables for `zhao2022-xzbc` (seed 000): X, Z (−100…100 mm every
/// 10 mm) and B (−90…90° every 10°, positioning error EBB only); C not
/// measured. Values in the default units (mm, rad).
pub fn zhao2022_tables(seed: u64) -> String {
    let mut rng = SplitMix64::new(seed);
    let mut out = String::new();
    header_comment(
        &mut out,
        "zhao2022-xzbc",
        seed,
        &[
            "Laser-interferometer style measurement of X, Z and B as in seed 000 Section 6.1;",
            "C not measured. Translations in mm, rotations in rad (the defaults).",
        ],
    );
    // Shapes in µm / µrad.
    let x = AxisSpec {
        axis: "X",
        lo: -100.0,
        hi: 100.0,
        step: 10.0,
        runs: 3,
        both_directions: true,
        columns: vec![
            Column {
                name: "EXX",
                unit: FileUnit::Mm,
                shape: positioning(shape([0.45, 1.2, -0.6, 0.2], 0.3, 3.0, 0.4, 0.04), 0.25),
            },
            Column {
                name: "EYX",
                unit: FileUnit::Mm,
                shape: shape([-0.06, 0.0, 0.18, 0.0], 0.05, 2.5, 0.0, 0.03),
            },
            Column {
                name: "EZX",
                unit: FileUnit::Mm,
                shape: shape([-0.4, -0.5, 0.9, 0.0], 0.15, 4.0, 1.0, 0.05),
            },
            Column {
                name: "EBX",
                unit: FileUnit::Rad,
                shape: shape([0.0, 2.0, -1.0, 0.0], 0.5, 2.0, 0.0, 0.15),
            },
            Column {
                name: "ECX",
                unit: FileUnit::Rad,
                shape: shape([0.3, -1.5, 0.0, 0.8], 0.4, 3.0, 0.7, 0.15),
            },
        ],
    };
    let z = AxisSpec {
        axis: "Z",
        lo: -100.0,
        hi: 100.0,
        step: 10.0,
        runs: 3,
        both_directions: true,
        columns: vec![
            Column {
                name: "EZZ",
                unit: FileUnit::Mm,
                shape: positioning(shape([-4.1, 1.5, 0.5, 0.0], 0.3, 2.7, 0.3, 0.05), 0.3),
            },
            Column {
                name: "EXZ",
                unit: FileUnit::Mm,
                shape: shape([-0.3, 0.4, 0.6, 0.0], 0.2, 3.3, 0.0, 0.05),
            },
            Column {
                name: "EYZ",
                unit: FileUnit::Mm,
                shape: shape([-0.04, 0.0, 0.12, 0.0], 0.04, 2.0, 2.0, 0.03),
            },
            Column {
                name: "EAZ",
                unit: FileUnit::Rad,
                shape: shape([0.0, 1.2, -0.6, 0.0], 0.3, 3.0, 0.0, 0.15),
            },
            Column {
                name: "EBZ",
                unit: FileUnit::Rad,
                shape: shape([0.5, -1.8, 0.7, 0.0], 0.4, 2.2, 0.5, 0.15),
            },
        ],
    };
    let b = AxisSpec {
        axis: "B",
        lo: -90.0,
        hi: 90.0,
        step: 10.0,
        runs: 3,
        both_directions: true,
        columns: vec![Column {
            name: "EBB",
            unit: FileUnit::Rad,
            shape: positioning(shape([2.0, 4.0, -1.5, 0.0], 1.2, 3.0, 0.0, 0.3), 1.0),
        }],
    };
    for (i, spec) in [x, z, b].iter().enumerate() {
        if i > 0 {
            out.push('\n');
        }
        write_axis(&mut out, spec, &mut rng);
    }
    out
}

/// Error tables for `wang2023-xyzab` (seed 003): X 0…1000, Y −300…300,
/// Z −500…0 mm (20 steps each), A −180…180° every 15°, B −90…90° every 10°,
/// with explicit units in the headers (`[um]`, `[urad]`, `[arcsec]`).
pub fn wang2023_tables(seed: u64) -> String {
    let mut rng = SplitMix64::new(seed);
    let mut out = String::new();
    header_comment(
        &mut out,
        "wang2023-xyzab",
        seed,
        &[
            "Five-axis swing-head / tilting-table machine of seed 003: X, Y, Z, A, B.",
            "Units are given in the headers.",
        ],
    );
    let col = |name: &'static str, unit: FileUnit, shape: Shape| Column { name, unit, shape };
    use FileUnit::{Arcsec, Um, Urad};
    use std::f64::consts::PI;
    let specs = [
        AxisSpec {
            axis: "X",
            lo: 0.0,
            hi: 1000.0,
            step: 50.0,
            runs: 3,
            both_directions: true,
            columns: vec![
                col(
                    "EXX",
                    Um,
                    positioning(shape([2.0, 6.0, -2.5, 1.0], 1.0, 3.5, 0.2, 0.2), 1.5),
                ),
                col("EYX", Um, shape([0.0, 1.0, 3.0, -0.5], 0.6, 2.6, 0.3, 0.2)),
                col("EZX", Um, shape([0.0, -1.5, 2.0, 0.0], 0.5, 3.1, 1.1, 0.2)),
                col(
                    "EAX",
                    Urad,
                    shape([0.0, 3.0, -2.0, 0.0], 1.0, 2.0, 0.0, 0.4),
                ),
                col(
                    "EBX",
                    Urad,
                    shape([1.0, -6.0, 2.0, 1.0], 1.5, 2.4, 0.6, 0.4),
                ),
                col("ECX", Urad, shape([0.0, 4.0, 1.5, 0.0], 1.2, 3.0, 1.3, 0.4)),
            ],
        },
        AxisSpec {
            axis: "Y",
            lo: -300.0,
            hi: 300.0,
            step: 30.0,
            runs: 3,
            both_directions: true,
            columns: vec![
                col("EXY", Um, shape([0.0, 0.8, 2.2, 0.0], 0.4, 2.8, 0.5, 0.2)),
                col(
                    "EYY",
                    Um,
                    positioning(shape([-1.0, 4.5, 1.5, -0.8], 0.8, 3.2, 0.0, 0.2), 1.2),
                ),
                col("EZY", Um, shape([0.0, -1.2, 1.8, 0.0], 0.5, 2.2, 0.9, 0.2)),
                col(
                    "EAY",
                    Urad,
                    shape([0.0, -5.0, 1.0, 0.0], 1.0, 2.5, 0.3, 0.4),
                ),
                col(
                    "EBY",
                    Urad,
                    shape([0.5, 2.0, -1.5, 0.0], 0.8, 3.0, 0.0, 0.4),
                ),
                col(
                    "ECY",
                    Urad,
                    shape([0.0, 3.0, 0.0, -1.0], 1.0, 2.0, 0.8, 0.4),
                ),
            ],
        },
        AxisSpec {
            axis: "Z",
            lo: -500.0,
            hi: 0.0,
            step: 25.0,
            runs: 3,
            both_directions: true,
            columns: vec![
                col("EXZ", Um, shape([0.0, 1.5, 1.0, 0.0], 0.5, 2.4, 0.0, 0.2)),
                col("EYZ", Um, shape([0.0, -0.8, 2.0, 0.0], 0.4, 3.0, 0.4, 0.2)),
                col(
                    "EZZ",
                    Um,
                    positioning(shape([-3.0, 5.0, -1.0, 0.5], 1.0, 2.9, 0.7, 0.25), 2.0),
                ),
                col(
                    "EAZ",
                    Urad,
                    shape([0.0, 4.0, -1.0, 0.0], 1.2, 2.0, 0.2, 0.4),
                ),
                col(
                    "EBZ",
                    Urad,
                    shape([0.0, -3.0, 2.0, 0.0], 0.9, 2.7, 1.0, 0.4),
                ),
            ],
        },
        AxisSpec {
            axis: "A",
            lo: -180.0,
            hi: 180.0,
            step: 15.0,
            runs: 3,
            both_directions: true,
            columns: vec![
                // A turns fully: its errors are periodic (one harmonic per
                // revolution), so -180° and 180° agree.
                col(
                    "EAA",
                    Arcsec,
                    positioning(shape([3.0, 0.0, 0.0, 0.0], 25.0, PI, 0.3, 1.0), 4.0),
                ),
                col("EYA", Um, shape([0.0, 0.0, 0.0, 0.0], 2.0, PI, 0.5, 0.15)),
                col("EZA", Um, shape([0.5, 0.0, 0.0, 0.0], 1.5, PI, 2.1, 0.15)),
                col("EBA", Urad, shape([0.0, 0.0, 0.0, 0.0], 4.0, PI, 0.3, 0.5)),
                col("ECA", Urad, shape([1.0, 0.0, 0.0, 0.0], 3.0, PI, 1.9, 0.5)),
            ],
        },
        AxisSpec {
            axis: "B",
            lo: -90.0,
            hi: 90.0,
            step: 10.0,
            runs: 3,
            both_directions: true,
            columns: vec![
                col(
                    "EBB",
                    Arcsec,
                    positioning(shape([1.0, 15.0, -4.0, 0.0], 5.0, 3.0, 0.4, 1.0), 5.0),
                ),
                col("EXB", Um, shape([0.0, 2.0, 1.0, 0.0], 0.8, 2.5, 0.0, 0.15)),
                col("EZB", Um, shape([0.5, 0.0, -1.5, 0.0], 0.6, 3.0, 0.8, 0.15)),
                col("EAB", Urad, shape([0.0, 3.0, 0.0, 0.0], 2.0, 2.0, 0.0, 0.5)),
                col(
                    "ECB",
                    Urad,
                    shape([0.0, -2.0, 1.0, 0.0], 1.5, 2.6, 1.2, 0.5),
                ),
            ],
        },
    ];
    for (i, spec) in specs.iter().enumerate() {
        if i > 0 {
            out.push('\n');
        }
        write_axis(&mut out, spec, &mut rng);
    }
    out
}

/// A dense scan for `zhao2022-xzbc`, the kind a modern laser or
/// interferometer campaign gives: X and Z every 0.1 mm over −100…100 mm and
/// B every 0.09° over −90…90°, one forward pass each, all six error motions
/// of every axis (6,003 rows). The shapes are those of
/// [`zhao2022_tables`] where it has them. Used by the benchmarks to show
/// that fitting stays cheap when the tables grow.
pub fn zhao2022_dense_tables(seed: u64) -> String {
    zhao2022_dense_tables_finer(seed, 1)
}

/// [`zhao2022_dense_tables`] with the spacing divided by `finer` (1: 6,003
/// rows; 4: 24,003; 16: 96,003): the benchmarks' measure of the speed as
/// the tables grow.
pub fn zhao2022_dense_tables_finer(seed: u64, finer: u32) -> String {
    let finer = f64::from(finer.max(1));
    let mut rng = SplitMix64::new(seed);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Dense synthetic error tables for zhao2022-xzbc (kinpost geometric::synth, seed {seed})."
    );
    out.push_str("# One forward pass per axis; translations in mm, rotations in rad.\n");
    let translation = |poly: [f64; 4], amp: f64, omega: f64| shape(poly, amp, omega, 0.3, 0.04);
    let rotation = |poly: [f64; 4], amp: f64, omega: f64| shape(poly, amp, omega, 0.7, 0.15);
    let columns = |names: [&'static str; 6]| -> Vec<Column> {
        let shapes = [
            (FileUnit::Mm, translation([0.45, 1.2, -0.6, 0.2], 0.3, 3.0)),
            (
                FileUnit::Mm,
                translation([-0.06, 0.0, 0.18, 0.0], 0.05, 2.5),
            ),
            (FileUnit::Mm, translation([-0.4, -0.5, 0.9, 0.0], 0.15, 4.0)),
            (FileUnit::Rad, rotation([0.0, 1.2, -0.6, 0.0], 0.3, 3.0)),
            (FileUnit::Rad, rotation([0.0, 2.0, -1.0, 0.0], 0.5, 2.0)),
            (FileUnit::Rad, rotation([0.3, -1.5, 0.0, 0.8], 0.4, 3.0)),
        ];
        names
            .into_iter()
            .zip(shapes)
            .map(|(name, (unit, shape))| Column { name, unit, shape })
            .collect()
    };
    let specs = [
        (
            "X",
            -100.0,
            100.0,
            0.1,
            ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"],
        ),
        (
            "Z",
            -100.0,
            100.0,
            0.1,
            ["EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ"],
        ),
        (
            "B",
            -90.0,
            90.0,
            0.09,
            ["EXB", "EYB", "EZB", "EAB", "EBB", "ECB"],
        ),
    ];
    for (i, (axis, lo, hi, step, names)) in specs.into_iter().enumerate() {
        if i > 0 {
            out.push('\n');
        }
        let spec = AxisSpec {
            axis,
            lo,
            hi,
            step: step / finer,
            runs: 1,
            both_directions: false,
            columns: columns(names),
        };
        write_axis(&mut out, &spec, &mut rng);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomial_sine_is_accurate() {
        for i in -2000..2000 {
            let x = i as f64 * 0.0137;
            assert!((sin_det(x) - x.sin()).abs() < 1e-13, "x={x}");
        }
    }

    #[test]
    fn generator_is_deterministic_and_seeded() {
        assert_eq!(zhao2022_tables(1), zhao2022_tables(1));
        assert_ne!(zhao2022_tables(1), zhao2022_tables(2));
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
    }
}
