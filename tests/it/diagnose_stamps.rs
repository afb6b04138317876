//! Clock offsets in recordings as loggers write them (fourteenth hunt,
//! `docs/robustness.md`): the lens program sampled at 10 Hz, time stamps
//! rounded to whole milliseconds, samples taken at uneven times. Each
//! recording is clean but for its clock (no effect injected, σ = 1 µm):
//! `diagnose` must name the clock offset and claim no machine physics.
//!
//! Before: on zhao2022-lens.nc only C determines its own lag (X, Z and B
//! move together along the profile), so no offset was seen, and a 15 ms
//! offset came out as a wander of 82 µm, a 5 ms one as servo lags of B and
//! C with two cyclic errors; stamps rounded to 1 ms at a 7.5 ms rate on
//! wang2023-xyzab came out as servo lags of B, A and X and a wander; taken
//! at uneven times, most samples were left out as not alignable.

use std::path::Path;
use std::process::Command;

use crate::util::{BIN, repo_file};

/// `simulate` of `program` on `machine` (no effect, σ = 1 µm) with
/// `args`, written to `out`.
fn simulate(machine: &str, program: &str, args: &[&str], out: &Path) {
    let program = repo_file(&format!("fixtures/programs/{program}"));
    let mut all = vec!["simulate", "-m", machine, "-p", &program];
    all.extend_from_slice(args);
    all.extend(["-o", out.to_str().unwrap()]);
    succeed(&all);
}

/// `diagnose --json` of `rec` on `machine`.
fn diagnose(machine: &str, rec: &Path) -> serde_json::Value {
    let rec = rec.to_str().unwrap();
    serde_json::from_slice(&succeed(&["diagnose", "-m", machine, "-r", rec, "--json"])).unwrap()
}

/// The standard output of kinpost run with `args`, which must succeed.
fn succeed(args: &[&str]) -> Vec<u8> {
    let out = Command::new(BIN).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {err}");
    out.stdout
}

/// The machine findings of a report, and its clock offset (s).
fn read(r: &serde_json::Value) -> (Vec<String>, Option<f64>) {
    let mut physics = Vec::new();
    let mut offset = None;
    for f in r["findings"].as_array().unwrap() {
        if f["effect"] == "time_offset" {
            offset = f["parameters"]["offset_s"].as_f64();
        } else if f["machine_physics"] != false {
            physics.push(format!("{} {}", f["effect"], f["axis"]));
        }
    }
    (physics, offset)
}

/// `from` written to `to` with the data rows `keep` keeps (given each
/// row's index and its fields, which it may change).
fn rewrite(from: &Path, to: &Path, mut keep: impl FnMut(usize, &mut Vec<String>) -> bool) {
    let text = std::fs::read_to_string(from).unwrap();
    let mut lines = text.lines();
    let mut out = String::from(lines.next().unwrap());
    out.push('\n');
    for (i, line) in lines.enumerate() {
        let mut f: Vec<String> = line.split(',').map(str::to_string).collect();
        if keep(i, &mut f) {
            out.push_str(&f.join(","));
            out.push('\n');
        }
    }
    std::fs::write(to, out).unwrap();
}

#[test]
fn a_clock_offset_on_the_lens_program_is_named_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    for (offset, seed) in [(0.005, "3"), (0.015, "3"), (0.015, "4"), (0.05, "3")] {
        let rec = dir.path().join("rec.csv");
        let off = offset.to_string();
        simulate(
            "zhao2022-xzbc",
            "zhao2022-lens.nc",
            &["--time-offset", &off, "--seed", seed],
            &rec,
        );
        let (physics, found) = read(&diagnose("zhao2022-xzbc", &rec));
        println!("offset {offset} s, seed {seed}: found {found:?}, {physics:?}");
        let found = found.unwrap_or_else(|| panic!("{offset} s: no clock offset named"));
        assert!(
            (found - offset).abs() < 0.05 * offset,
            "{found} s against {offset} s"
        );
        assert!(physics.is_empty(), "{offset} s: {physics:?}");
    }
}

#[test]
fn time_stamps_rounded_to_milliseconds_are_put_back_on_the_sampling_clock() {
    let dir = tempfile::tempdir().unwrap();
    let exact = dir.path().join("exact.csv");
    let rounded = dir.path().join("rounded.csv");
    for (offset, seed) in [("0.015", "5"), ("0", "6")] {
        simulate(
            "wang2023-xyzab",
            "wang2023-xyzab.ngc",
            &[
                "--sample-interval",
                "0.0075",
                "--time-offset",
                offset,
                "--seed",
                seed,
            ],
            &exact,
        );
        rewrite(&exact, &rounded, |_, f| {
            f[0] = format!("{:.3}", f[0].parse::<f64>().unwrap());
            true
        });
        let want = read(&diagnose("wang2023-xyzab", &exact));
        let r = diagnose("wang2023-xyzab", &rounded);
        let got = read(&r);
        println!("offset {offset}: exact stamps {want:?}, rounded {got:?}");
        assert!(want.0.is_empty() && got.0.is_empty(), "{want:?} {got:?}");
        match (want.1, got.1) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-4, "{a} against {b}"),
            (None, None) => {}
            other => panic!("offset {offset}: {other:?}"),
        }
        let note = &r["time_stamps"];
        assert_eq!(note["effect"], "time_stamps");
        assert_eq!(note["machine_physics"], false);
        let period = note["parameters"]["period_s"].as_f64().unwrap();
        assert!((period - 0.0075).abs() < 1e-7, "{period}");
        let stray = note["parameters"]["largest_stray_s"].as_f64().unwrap();
        assert!((stray - 0.0005).abs() < 1e-6, "{stray}");
        // Exact stamps need no such note.
        assert!(
            diagnose("wang2023-xyzab", &exact)
                .get("time_stamps")
                .is_none()
        );
    }
}

#[test]
fn samples_taken_at_uneven_times_are_aligned_where_they_fall() {
    // A 5 ms recording thinned to every 19th, 20th or 21st sample: the
    // stamps are right, the intervals 95 … 105 ms.
    let dir = tempfile::tempdir().unwrap();
    let fine = dir.path().join("fine.csv");
    let uneven = dir.path().join("uneven.csv");
    simulate(
        "zhao2022-xzbc",
        "zhao2022-lens.nc",
        &[
            "--sample-interval",
            "0.005",
            "--time-offset",
            "0.015",
            "--seed",
            "3",
        ],
        &fine,
    );
    let steps = [20, 19, 21, 20, 21, 19, 19, 20, 21];
    let mut next = 0;
    let mut k = 0;
    rewrite(&fine, &uneven, |i, _| {
        if i < next {
            return false;
        }
        next = i + steps[k % steps.len()];
        k += 1;
        true
    });
    let r = diagnose("zhao2022-xzbc", &uneven);
    let (physics, found) = read(&r);
    println!("uneven sampling: {found:?}, {physics:?}");
    let found = found.expect("the clock offset named");
    assert!((found - 0.015).abs() < 0.05 * 0.015, "{found}");
    assert!(physics.is_empty(), "{physics:?}");
    // The stamps are where the samples were taken: kept as they are.
    assert!(r.get("time_stamps").is_none());
}
