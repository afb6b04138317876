//! `kinpost linkage` with its default options (four-axis linkage, 1 µm
//! tolerance) on every shipped fixture program, checked independently:
//! no output block moves more than four axes, and the tool tip, sampled on
//! the chain along every written segment, stays within the tolerance of the
//! straight line between the original blocks' tips.
//!
//! Before the fix, four of these failed: blocks that turn both rotaries but
//! move only four axes were divided evenly (every segment then moved five),
//! and a machine with two linear axes (X Z B C) could not place the
//! inserted tips with its linear axes alone.

use kinpost::gcode::LineReader;
use kinpost::linkage::point_segment_distance;
use kinpost::machine::{Machine, NoErrors};
use std::path::Path;
use std::process::{Command, Stdio};

use crate::util::BIN;

/// Machine axes (output order) of every motion block, with modal carry-over,
/// and whether the block was inserted by kinpost.
fn rows(machine: &Machine, text: &str) -> Vec<(Vec<f64>, bool)> {
    let mut current = vec![0.0; machine.axes.len()];
    let mut out = Vec::new();
    for line in LineReader::new(text.as_bytes()) {
        let line = line.unwrap();
        let mut any = false;
        for w in line.words() {
            if let Some(k) = machine.axes.iter().position(|a| a.name == w.address) {
                current[k] = w.value;
                any = true;
            }
        }
        if any {
            out.push((
                current.clone(),
                line.text_lossy().contains("(kinpost linkage"),
            ));
        }
    }
    out
}

fn load(machine: &str) -> Machine {
    Machine::embedded(machine).unwrap_or_else(|| {
        Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(machine)).unwrap()
    })
}

#[test]
fn default_linkage_on_every_fixture() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cases = [
        ("wang2023-xyzab.ngc", "wang2023-xyzab"),
        ("wang2023-impeller.nc", "wang2023-xyzab"),
        ("xyzac-head.ngc", "fixtures/machines/xyzac-head.json"),
        (
            "xyzbc-nutating.ngc",
            "fixtures/machines/xyzbc-nutating.json",
        ),
        ("xyzac-trt.ngc", "fixtures/machines/xyzac-trt.json"),
        ("xyzbc-trt.ngc", "fixtures/machines/xyzbc-trt.json"),
        ("xyza-4axis.ngc", "fixtures/machines/xyza-4axis.json"),
        ("zhao2022-lens.nc", "zhao2022-xzbc"),
        ("zhao2022-xzbc.ngc", "zhao2022-xzbc"),
    ];
    let tolerance = 1e-3;
    for (program, machine) in cases {
        let path = root.join("fixtures/programs").join(program);
        let m = load(machine);
        let out = Command::new(BIN)
            .args(["linkage", "--machine", machine])
            .arg(&path)
            .current_dir(root)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{program}: {err}");
        let got = rows(&m, &String::from_utf8_lossy(&out.stdout));
        for w in got.windows(2) {
            let moved = w[0].0.iter().zip(&w[1].0).filter(|(a, b)| a != b).count();
            assert!(moved <= 4, "{program}: a block moves {moved} axes");
        }
        let originals: Vec<usize> = (0..got.len()).filter(|&i| !got[i].1).collect();
        let tip = |row: &[f64]| m.chain.pose(&m.to_internal(row), &NoErrors).tip;
        let mut worst = 0.0f64;
        for pair in originals.windows(2) {
            let (a, b) = (tip(&got[pair[0]].0), tip(&got[pair[1]].0));
            for s in pair[0]..pair[1] {
                let qa = m.to_internal(&got[s].0);
                let qb = m.to_internal(&got[s + 1].0);
                for i in 0..=64 {
                    let t = i as f64 / 64.0;
                    let q: Vec<f64> = qa.iter().zip(&qb).map(|(x, y)| x + t * (y - x)).collect();
                    let d = point_segment_distance(&m.chain.pose(&q, &NoErrors).tip, &a, &b);
                    worst = worst.max(d);
                }
            }
        }
        eprintln!(
            "{program}: {} blocks out, worst deviation {:.4} µm",
            got.len(),
            worst * 1e3
        );
        assert!(worst <= tolerance, "{program}: {:.4} µm", worst * 1e3);
    }
}
