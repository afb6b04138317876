//! ISO 230-2 positioning figures of an axis from a bidirectional test.
//!
//! Definitions (ISO 230-2:2014, Clause 3), for target positions `P_i` and
//! runs `j` approaching in direction ↑ (positive) or ↓ (negative); the
//! positional deviation `x_ij` is the reached position minus the target,
//! which is exactly the positioning error column (`EXX`, `EZZ`, `EBB`, …):
//!
//! * mean unidirectional positional deviation `x̄_i↑ = (1/n) Σ_j x_ij↑` (same ↓);
//! * mean bidirectional positional deviation `x̄_i = (x̄_i↑ + x̄_i↓) / 2`;
//! * reversal value at a position `B_i = x̄_i↑ − x̄_i↓`; of the axis
//!   `B = max |B_i|`; mean reversal value `B̄ = (1/m) Σ B_i`;
//! * estimator of the unidirectional repeatability
//!   `s_i↑ = sqrt( Σ_j (x_ij↑ − x̄_i↑)² / (n − 1) )`;
//! * unidirectional repeatability `R_i↑ = 4 s_i↑`; bidirectional
//!   `R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)`; of the axis
//!   `R↑ = max R_i↑`, `R↓ = max R_i↓`, `R = max R_i`;
//! * systematic positional deviation `E↑ = max x̄_i↑ − min x̄_i↑` (same ↓),
//!   bidirectional `E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)`;
//! * range of the mean bidirectional positional deviation
//!   `M = max x̄_i − min x̄_i`;
//! * accuracy `A↑ = max(x̄_i↑ + 2 s_i↑) − min(x̄_i↑ − 2 s_i↑)` (same ↓),
//!   bidirectional `A = max(x̄_i↑ + 2s_i↑, x̄_i↓ + 2s_i↓) − min(x̄_i↑ − 2s_i↑, x̄_i↓ − 2s_i↓)`.
//!
//! Only targets measured in both directions enter the figures. The
//! repeatability and accuracy need at least two runs per target and
//! direction (the standard asks for five); with fewer they are `None`.
//! Values are reported in µm for linear axes and µrad for rotary axes
//! (with arc-second copies of the axis figures).

use super::bspline::Grouped;
use super::table::{Component, ErrorTable, RAD_PER_ARCSEC, positioning_component};

/// Statistics at one target position.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TargetStats {
    /// Target position (mm, or deg for rotary axes).
    pub position: f64,
    /// Number of runs approaching in the positive direction.
    pub n_up: usize,
    /// Number of runs approaching in the negative direction.
    pub n_down: usize,
    /// Mean unidirectional positional deviation ↑ (report unit).
    pub mean_up: f64,
    /// Mean unidirectional positional deviation ↓.
    pub mean_down: f64,
    /// Estimator of the repeatability ↑ (`None` with fewer than 2 runs).
    pub s_up: Option<f64>,
    /// Estimator of the repeatability ↓.
    pub s_down: Option<f64>,
    /// Mean bidirectional positional deviation.
    pub mean: f64,
    /// Reversal value `B_i = x̄↑ − x̄↓`.
    pub reversal: f64,
}

/// ISO 230-2 figures of one axis.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Iso230_2 {
    /// Axis letter.
    pub axis: String,
    /// The positioning column used (e.g. `EXX`).
    pub column: String,
    /// Unit of every deviation below: `"µm"` (linear) or `"µrad"` (rotary).
    pub unit: String,
    /// Unit of the target positions: `"mm"` or `"deg"`.
    pub position_unit: String,
    /// Per-target statistics (targets measured in both directions).
    pub targets: Vec<TargetStats>,
    /// Fewest runs at any target in either direction.
    pub min_runs: usize,
    /// Reversal value of the axis `B = max |B_i|`.
    pub reversal_b: f64,
    /// Mean reversal value `B̄`.
    pub mean_reversal: f64,
    /// Bidirectional repeatability `R`.
    pub repeatability_r: Option<f64>,
    /// Unidirectional repeatability `R↑`.
    pub repeatability_up: Option<f64>,
    /// Unidirectional repeatability `R↓`.
    pub repeatability_down: Option<f64>,
    /// Bidirectional systematic positional deviation `E`.
    pub systematic_e: f64,
    /// Unidirectional systematic positional deviation `E↑`.
    pub systematic_up: f64,
    /// Unidirectional systematic positional deviation `E↓`.
    pub systematic_down: f64,
    /// Range of the mean bidirectional positional deviation `M`.
    pub mean_range_m: f64,
    /// Bidirectional accuracy `A`.
    pub accuracy_a: Option<f64>,
    /// Unidirectional accuracy `A↑`.
    pub accuracy_up: Option<f64>,
    /// Unidirectional accuracy `A↓`.
    pub accuracy_down: Option<f64>,
}

impl Iso230_2 {
    /// Factor from [`Iso230_2::unit`] to arc seconds (rotary axes), else `None`.
    pub fn arcsec_factor(&self) -> Option<f64> {
        (self.unit == "µrad").then_some(1e-6 / RAD_PER_ARCSEC)
    }

    /// Human-readable summary with units.
    pub fn to_text(&self) -> String {
        let u = &self.unit;
        let fmt = |v: f64| match self.arcsec_factor() {
            Some(f) => format!("{v:.3} {u} ({:.3} arcsec)", v * f),
            None => format!("{v:.3} {u}"),
        };
        let opt = |v: Option<f64>| v.map_or("n/a (fewer than 2 runs)".to_string(), fmt);
        let mut s = String::new();
        s.push_str(&format!(
            "ISO 230-2, axis {} ({}), {} targets, {} runs per direction (fewest):\n",
            self.axis,
            self.column,
            self.targets.len(),
            self.min_runs
        ));
        s.push_str(&format!(
            "  reversal B            {}\n",
            fmt(self.reversal_b)
        ));
        s.push_str(&format!(
            "  mean reversal B̄       {}\n",
            fmt(self.mean_reversal)
        ));
        s.push_str(&format!(
            "  repeatability R       {}\n",
            opt(self.repeatability_r)
        ));
        s.push_str(&format!(
            "  repeatability R↑/R↓   {} / {}\n",
            opt(self.repeatability_up),
            opt(self.repeatability_down)
        ));
        s.push_str(&format!(
            "  systematic dev. E     {}\n",
            fmt(self.systematic_e)
        ));
        s.push_str(&format!(
            "  mean dev. range M     {}\n",
            fmt(self.mean_range_m)
        ));
        s.push_str(&format!(
            "  accuracy A            {}\n",
            opt(self.accuracy_a)
        ));
        s
    }
}

fn max_of(it: impl Iterator<Item = f64>) -> f64 {
    it.fold(f64::NEG_INFINITY, f64::max)
}

fn min_of(it: impl Iterator<Item = f64>) -> f64 {
    it.fold(f64::INFINITY, f64::min)
}

/// Computes the figures from samples: positions (mm or deg), deviations
/// (in the report unit) and directions (+1 / −1; other values ignored).
/// `None` when no target was measured in both directions.
pub fn compute(
    axis: &str,
    column: &str,
    unit: &str,
    position_unit: &str,
    positions: &[f64],
    deviations: &[f64],
    directions: &[i8],
) -> Option<Iso230_2> {
    let n = positions.len().min(deviations.len()).min(directions.len());
    let split = |d: i8| -> Option<Grouped> {
        let (x, y): (Vec<f64>, Vec<f64>) = (0..n)
            .filter(|&i| directions[i] == d)
            .map(|i| (positions[i], deviations[i]))
            .unzip();
        Grouped::new(&x, &y).ok()
    };
    let up = split(1)?;
    let down = split(-1)?;
    let range = max_of(positions.iter().copied()) - min_of(positions.iter().copied());
    let tol = 1e-6 * range.abs().max(1.0);
    let mut targets = Vec::new();
    for (i, &p) in up.x.iter().enumerate() {
        let Some(j) = down.x.iter().position(|&q| (q - p).abs() <= tol) else {
            continue;
        };
        let s = |g: &Grouped, k: usize| {
            (g.count[k] >= 2).then(|| (g.ss_within[k] / (g.count[k] - 1) as f64).sqrt())
        };
        targets.push(TargetStats {
            position: 0.5 * (p + down.x[j]),
            n_up: up.count[i],
            n_down: down.count[j],
            mean_up: up.mean[i],
            mean_down: down.mean[j],
            s_up: s(&up, i),
            s_down: s(&down, j),
            mean: 0.5 * (up.mean[i] + down.mean[j]),
            reversal: up.mean[i] - down.mean[j],
        });
    }
    if targets.is_empty() {
        return None;
    }
    let t = &targets;
    let min_runs = t.iter().map(|t| t.n_up.min(t.n_down)).min().unwrap_or(0);
    let all_s = t.iter().all(|t| t.s_up.is_some() && t.s_down.is_some());
    let su = |t: &TargetStats| t.s_up.unwrap_or(0.0);
    let sd = |t: &TargetStats| t.s_down.unwrap_or(0.0);
    let r_up = max_of(t.iter().map(|t| 4.0 * su(t)));
    let r_down = max_of(t.iter().map(|t| 4.0 * sd(t)));
    let r = max_of(t.iter().map(|t| {
        (2.0 * su(t) + 2.0 * sd(t) + t.reversal.abs())
            .max(4.0 * su(t))
            .max(4.0 * sd(t))
    }));
    let e_up = max_of(t.iter().map(|t| t.mean_up)) - min_of(t.iter().map(|t| t.mean_up));
    let e_down = max_of(t.iter().map(|t| t.mean_down)) - min_of(t.iter().map(|t| t.mean_down));
    let e = max_of(t.iter().map(|t| t.mean_up.max(t.mean_down)))
        - min_of(t.iter().map(|t| t.mean_up.min(t.mean_down)));
    let m = max_of(t.iter().map(|t| t.mean)) - min_of(t.iter().map(|t| t.mean));
    let a_up = max_of(t.iter().map(|t| t.mean_up + 2.0 * su(t)))
        - min_of(t.iter().map(|t| t.mean_up - 2.0 * su(t)));
    let a_down = max_of(t.iter().map(|t| t.mean_down + 2.0 * sd(t)))
        - min_of(t.iter().map(|t| t.mean_down - 2.0 * sd(t)));
    let a = max_of(
        t.iter()
            .map(|t| (t.mean_up + 2.0 * su(t)).max(t.mean_down + 2.0 * sd(t))),
    ) - min_of(
        t.iter()
            .map(|t| (t.mean_up - 2.0 * su(t)).min(t.mean_down - 2.0 * sd(t))),
    );
    let when = |v: f64| all_s.then_some(v);
    Some(Iso230_2 {
        axis: axis.to_string(),
        column: column.to_string(),
        unit: unit.to_string(),
        position_unit: position_unit.to_string(),
        min_runs,
        reversal_b: max_of(t.iter().map(|t| t.reversal.abs())),
        mean_reversal: t.iter().map(|t| t.reversal).sum::<f64>() / t.len() as f64,
        repeatability_r: when(r),
        repeatability_up: when(r_up),
        repeatability_down: when(r_down),
        systematic_e: e,
        systematic_up: e_up,
        systematic_down: e_down,
        mean_range_m: m,
        accuracy_a: when(a),
        accuracy_up: when(a_up),
        accuracy_down: when(a_down),
        targets,
    })
}

/// ISO 230-2 figures of a table's positioning column (`EXX` on X, `EBB` on
/// B, …), when the table has that column and known approach directions.
pub fn from_table(table: &ErrorTable) -> Option<Iso230_2> {
    let comp: Component = positioning_component(&table.axis)?;
    let col = table.column(comp)?;
    let dirs = table.direction.as_ref()?;
    let factor = comp.display_factor();
    let dev: Vec<f64> = col.values.iter().map(|v| v * factor).collect();
    compute(
        &table.axis,
        &col.name,
        comp.display_unit(),
        if table.rotary { "deg" } else { "mm" },
        &table.positions,
        &dev,
        dirs,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_two_targets() {
        // Target 0: ↑ 1, 3 (mean 2, s √2); ↓ 0, 0 (mean 0, s 0).
        // Target 10: ↑ 4, 4 (mean 4, s 0); ↓ 5, 7 (mean 6, s √2).
        let p = [0.0, 10.0, 10.0, 0.0, 0.0, 10.0, 10.0, 0.0];
        let x = [1.0, 4.0, 5.0, 0.0, 3.0, 4.0, 7.0, 0.0];
        let d = [1, 1, -1, -1, 1, 1, -1, -1];
        let r = compute("X", "EXX", "µm", "mm", &p, &x, &d).unwrap();
        let s2 = 2f64.sqrt();
        assert_eq!(r.targets.len(), 2);
        assert_eq!(r.reversal_b, 2.0); // B_0 = 2, B_10 = −2
        assert_eq!(r.mean_reversal, 0.0);
        assert!((r.repeatability_up.unwrap() - 4.0 * s2).abs() < 1e-12);
        // R_0 = max(2√2 + 0 + 2, 4√2, 0) = 2 + 2√2 ≈ 4.83 < 4√2 ≈ 5.66.
        assert!((r.repeatability_r.unwrap() - 4.0 * s2).abs() < 1e-12);
        assert_eq!(r.systematic_up, 2.0);
        assert_eq!(r.systematic_down, 6.0);
        assert_eq!(r.systematic_e, 6.0);
        assert_eq!(r.mean_range_m, 4.0); // means 1 and 5
        // A = max(2+2√2, 0, 4, 6+2√2) − min(2−2√2, 0, 4, 6−2√2) = 6+2√2 − (2−2√2).
        assert!((r.accuracy_a.unwrap() - (4.0 + 4.0 * s2)).abs() < 1e-12);
    }
}
