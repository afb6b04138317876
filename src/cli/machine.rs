//! What `kinpost machine` prints about a machine.

use crate::machine::{IkSolver, JointKind, Machine};

/// A human-readable summary: chain, axes, and the IK family chosen.
pub fn summary_text(machine: &Machine, solver: &IkSolver) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "machine {}", machine.name);
    if !machine.description.is_empty() {
        let _ = writeln!(s, "  {}", machine.description);
    }
    if !machine.source.is_empty() {
        let _ = writeln!(s, "  source: {}", machine.source);
    }
    let _ = writeln!(s, "inverse kinematics: {}", solver.family());
    let _ = writeln!(s, "chain (workpiece → tool tip, mm and degrees):");
    for d in machine.element_descriptions() {
        let _ = writeln!(s, "  {d}");
    }
    let _ = writeln!(s, "axes (output order):");
    for a in &machine.axes {
        let limits = match (a.min, a.max) {
            (Some(lo), Some(hi)) => format!("{lo} … {hi} {}", a.unit()),
            (Some(lo), None) => format!("≥ {lo} {}", a.unit()),
            (None, Some(hi)) => format!("≤ {hi} {}", a.unit()),
            (None, None) => "no limits".to_string(),
        };
        let mode = if a.kind == JointKind::Revolute {
            format!(", {}", a.rotary)
        } else {
            String::new()
        };
        let _ = writeln!(s, "  {}: {limits}{mode}, {} decimals", a.name, a.decimals);
    }
    s.trim_end().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries_name_the_family_and_the_axes() {
        let m = Machine::embedded("wang2023-xyzab").unwrap();
        let text = summary_text(&m, &IkSolver::new(&m));
        assert!(text.starts_with("machine wang2023-xyzab"));
        assert!(text.contains("five-axis 2R3T"));
        assert!(text.contains("translate [0, 0, 265]"));
        assert!(text.contains("A: no limits, continuous, 3 decimals"));
        let r = Machine::from_json_str(
            r#"{"chain": [{"rotate": {"axis": [0, 0, 1], "angle": 90}}, {"prismatic": {"name": "X", "axis": [1, 0, 0]}}]}"#,
            "dir/plain.json",
        )
        .unwrap();
        assert_eq!(r.name, "plain");
        assert!(summary_text(&r, &IkSolver::new(&r)).contains("rotate axis [0, 0, 1] angle 90"));
    }
}
