//! `kinpost machine`: `--json` prints a machine file that loads back as the
//! same machine; `--list` names the embedded machines; `--template FAMILY`
//! prints a starting file that loads.

use kinpost::machine::{IkSolver, Machine, NoErrors};
use std::process::{Command, Stdio};

use crate::util::BIN;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run kinpost");
    (
        out.status.code().expect("exit code"),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn machine_json_round_trips_for_every_embedded_machine() {
    let dir = tempfile::tempdir().unwrap();
    for name in Machine::embedded_names() {
        let (code, json, err) = run(&["machine", "--json", "-m", name]);
        assert_eq!(code, 0, "{err}");
        let path = dir.path().join(format!("{name}.json"));
        std::fs::write(&path, &json).unwrap();
        let back = Machine::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let orig = Machine::embedded(name).unwrap();
        assert_eq!(back.name, orig.name);
        assert_eq!(back.description, orig.description);
        assert_eq!(back.source, orig.source);
        assert_eq!(back.axes, orig.axes, "{name}");
        assert_eq!(back.chain.elements().len(), orig.chain.elements().len());
        assert_eq!(IkSolver::new(&back).family(), IkSolver::new(&orig).family());
        let family: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            family["_ik_family"],
            IkSolver::new(&orig).family().short_name()
        );
        // Same forward kinematics at a few joint values.
        for k in 0..5 {
            let values: Vec<f64> = (0..orig.axes.len())
                .map(|i| 37.0 * ((k * 7 + i * 3) as f64).sin())
                .collect();
            let (a, b) = (orig.to_internal(&values), back.to_internal(&values));
            let (pa, pb) = (
                orig.chain.pose(&a, &NoErrors),
                back.chain.pose(&b, &NoErrors),
            );
            assert!(pa.tip_distance(&pb) < 1e-12, "{name}");
            assert!(pa.axis_angle(&pb) < 1e-14, "{name}");
        }
        // The file read back prints the same file.
        let (code, again, _) = run(&["machine", "--json", "-m", path.to_str().unwrap()]);
        assert_eq!(code, 0);
        assert_eq!(again, json, "{name}");
    }
}

#[test]
fn machine_list_has_one_line_per_embedded_machine() {
    let (code, out, _) = run(&["machine", "--list"]);
    assert_eq!(code, 0);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), Machine::embedded_names().len());
    for (line, name) in lines.iter().zip(Machine::embedded_names()) {
        let m = Machine::embedded(name).unwrap();
        let words: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(words[0], name);
        assert_eq!(words[1], IkSolver::new(&m).family().short_name());
        let axes: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(&words[2..], axes.as_slice());
    }
}

#[test]
fn machine_templates_load_and_unknown_families_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    for family in ["2R3T", "1R3T", "RTTR", "3T", "rttr"] {
        let (code, text, err) = run(&["machine", "--template", family]);
        assert_eq!(code, 0, "{err}");
        let path = dir.path().join(format!("{family}.json"));
        std::fs::write(&path, &text).unwrap();
        let m = Machine::load(&path).unwrap_or_else(|e| panic!("{family}: {e}"));
        assert!(
            IkSolver::new(&m)
                .family()
                .short_name()
                .eq_ignore_ascii_case(family)
        );
        let (code, _, err) = run(&["machine", "-m", path.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
    }
    let (code, out, err) = run(&["machine", "--template", "6R"]);
    assert_eq!(code, 2);
    assert!(out.is_empty());
    assert!(err.contains("2R3T, 1R3T, RTTR, 3T"), "{err}");
}
