//! `kinpost simulate` → `kinpost diagnose` → `kinpost compensate`, through
//! the binary: the formats.md §3 report, silence on clean data, and the loop
//! closed (the improved model cuts the error of a re-run).

use crate::diagnose_support::FORMATS_FIELDS;
use kinpost::diagnose::parse_effect_spec;
use kinpost::gcode::LineReader;
use kinpost::geometric::model::ErrorModel;
use kinpost::machine::Machine;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::BIN;

use crate::util::repo_file;

fn kinpost(args: &[&str]) -> String {
    let out = Command::new(BIN).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "kinpost {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn simulate(dir: &Path, name: &str, inject: &[&str], seed: &str) -> PathBuf {
    let rec = dir.join(name);
    let mut args = vec![
        "simulate",
        "--machine",
        "zhao2022-xzbc",
        "--errors",
        "fixtures/errors/zhao2022-xzbc.csv",
        "--program",
        "fixtures/programs/zhao2022-xzbc-exercise.nc",
        "--noise",
        "0.001",
        "--seed",
        seed,
        "-o",
        rec.to_str().unwrap(),
    ];
    for i in inject {
        args.push("--inject");
        args.push(i);
    }
    let args: Vec<String> = args
        .iter()
        .map(|a| {
            if a.starts_with("fixtures/") {
                repo_file(a)
            } else {
                a.to_string()
            }
        })
        .collect();
    let refs: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    kinpost(&refs);
    rec
}

fn diagnose_json(rec: &Path, extra: &[&str]) -> serde_json::Value {
    let errors = repo_file("fixtures/errors/zhao2022-xzbc.csv");
    let mut args = vec![
        "diagnose",
        "--machine",
        "zhao2022-xzbc",
        "--errors",
        &errors,
        "--recording",
        rec.to_str().unwrap(),
        "--json",
    ];
    args.extend_from_slice(extra);
    serde_json::from_str(&kinpost(&args)).unwrap()
}

#[test]
fn backlash_found_and_reported_as_formats_md_says() {
    let dir = tempfile::tempdir().unwrap();
    let rec = simulate(dir.path(), "rec.csv", &["backlash:X=0.0024@block=40"], "7");
    let svg = dir.path().join("d.svg");
    let v = diagnose_json(&rec, &["--svg", svg.to_str().unwrap()]);
    for key in FORMATS_FIELDS {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    let f = &v["findings"][0];
    assert_eq!(f["effect"], "backlash");
    assert_eq!(f["axis"], "X");
    let value = f["parameters"]["value_mm"].as_f64().unwrap();
    assert!((value - 0.0024).abs() <= 0.2 * 0.0024, "{value}");
    assert!(f["uncertainty"]["value_mm"].as_f64().unwrap() > 0.0);
    let blocks = f["where"]["blocks"].as_array().unwrap();
    let first = blocks[0].as_i64().unwrap();
    // The program's block k sits on line k + 1.
    assert!((first - 41).abs() <= 10, "start {first}");
    assert!(f["where"]["t_s"].as_array().unwrap().len() == 2);
    assert!(f["where"]["condition"].as_str().unwrap().contains("X"));
    assert!(f["rms_explained_mm"].as_f64().unwrap() > 0.0);
    assert!(
        v["holdout_rms_after_mm"].as_f64().unwrap() < v["holdout_rms_before_mm"].as_f64().unwrap()
    );
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
}

#[test]
fn clean_recording_stays_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let rec = simulate(dir.path(), "clean.csv", &[], "3");
    let v = diagnose_json(&rec, &[]);
    assert_eq!(v["findings"].as_array().unwrap().len(), 0, "{v}");
    assert!(
        v["verdict"].as_str().unwrap().contains("noise"),
        "{}",
        v["verdict"]
    );
}

/// Tool-tip error of a compensated lens program on the true machine.
fn rerun_error(machine: &Machine, truth: &ErrorModel, program: &str) -> f64 {
    let bound = truth.bind(&machine.chain).unwrap();
    let chain = truth.apply_fixed(&machine.chain).unwrap();
    let poses = kinpost::demo::lens_path(&kinpost::demo::OffAxisLens::default());
    let mut current = vec![0.0; machine.axes.len()];
    let mut k = 0;
    let mut sum = 0.0;
    for line in LineReader::new(program.as_bytes()) {
        let line = line.unwrap();
        let mut any = false;
        for w in line.words() {
            if let Some(i) = machine.axes.iter().position(|a| a.name == w.address) {
                current[i] = w.value;
                any = true;
            }
        }
        if any {
            let p = chain.pose(&machine.to_internal(&current), &bound);
            sum += p.tip_distance(&poses[k]).powi(2);
            k += 1;
        }
    }
    assert_eq!(k, poses.len());
    (sum / k as f64).sqrt()
}

#[test]
fn improved_model_closes_the_loop() {
    // The machine really has a scale error of X (40 ppm) that the tables miss.
    let dir = tempfile::tempdir().unwrap();
    let rec = simulate(dir.path(), "scale.csv", &["scale:X=40"], "5");
    let improved = dir.path().join("improved.json");
    let v = diagnose_json(&rec, &["--write-model", improved.to_str().unwrap()]);
    assert_eq!(v["findings"][0]["effect"], "scale", "{v}");
    let base = repo_file("fixtures/errors/zhao2022-xzbc.csv");
    let lens = repo_file("fixtures/programs/zhao2022-lens.nc");
    let with_base = kinpost(&[
        "compensate",
        "-q",
        "--errors",
        &base,
        "--decimals",
        "9",
        &lens,
    ]);
    let with_improved = kinpost(&[
        "compensate",
        "-q",
        "--errors",
        improved.to_str().unwrap(),
        "--decimals",
        "9",
        &lens,
    ]);
    // analyze accepts the improved model too.
    let a = kinpost(&[
        "analyze",
        "--errors",
        improved.to_str().unwrap(),
        "--json",
        &lens,
    ]);
    assert!(a.contains("tip_error_max_mm"));

    let machine = Machine::embedded_default();
    let mut truth = ErrorModel::load(Path::new(&base)).unwrap();
    truth.effects.push(parse_effect_spec("scale:X=40").unwrap());
    let before = rerun_error(&machine, &truth, &with_base);
    let after = rerun_error(&machine, &truth, &with_improved);
    eprintln!(
        "re-run tool-tip RMS: base model {:.4} µm, improved model {:.4} µm",
        before * 1e3,
        after * 1e3
    );
    assert!(after < 0.3 * before, "{before} → {after}");
}

#[test]
fn an_untidy_recording_names_its_faults_and_claims_no_machine_effect() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("untidy.csv");
    kinpost(&[
        "simulate",
        "--machine",
        "zhao2022-xzbc",
        "--errors",
        &repo_file("fixtures/errors/zhao2022-xzbc.csv"),
        "--program",
        &repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc"),
        "--seed",
        "11",
        "--time-offset",
        "0.015",
        "--outliers",
        "0.005",
        "--round",
        "0.001",
        "-o",
        rec.to_str().unwrap(),
    ]);
    let v = diagnose_json(&rec, &[]);
    let findings = v["findings"].as_array().unwrap();
    let names: Vec<&str> = findings
        .iter()
        .map(|f| f["effect"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["time_offset", "outliers"], "{v}");
    let offset = findings[0]["parameters"]["offset_s"].as_f64().unwrap();
    assert!((offset - 0.015).abs() < 0.0015, "{offset}");
    assert!(findings.iter().all(|f| f["machine_physics"] == false));
    assert!(findings.iter().all(|f| f["axis"].is_null()));
    assert!(findings[1]["parameters"]["count"].as_f64().unwrap() >= 1.0);
    assert_eq!(v["resolution"]["meas_mm"].as_f64(), Some(0.001));
    assert!(
        v["verdict"]
            .as_str()
            .unwrap()
            .starts_with("consistent with measurement noise"),
        "{}",
        v["verdict"]
    );
}

#[test]
fn a_recording_of_another_machine_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("trt.csv");
    kinpost(&[
        "simulate",
        "--machine",
        "xyzbc-trt",
        "--program",
        &repo_file("fixtures/programs/xyzbc-trt.ngc"),
        "-o",
        rec.to_str().unwrap(),
    ]);
    let out = Command::new(BIN)
        .args([
            "diagnose",
            "--machine",
            "xyzbc-nutating",
            "--recording",
            rec.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("does not fit this machine"), "{err}");
    assert!(err.contains("trt.csv"), "{err}");
}

/// A joint-feedback trace of zhao2022-xzbc's exercise program at 100 Hz
/// with a servo lag of X of 4 ms, written in `dir`.
fn lagging_trace(dir: &Path) -> PathBuf {
    let trace = dir.join("fb.csv");
    kinpost(&[
        "simulate",
        "--machine",
        "zhao2022-xzbc",
        "--program",
        &repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc"),
        "--feedback",
        "--sample-interval",
        "0.01",
        "--noise",
        "0.0005",
        "--inject",
        "servo_lag:X=0.004",
        "-o",
        trace.to_str().unwrap(),
    ]);
    trace
}

#[test]
fn a_joint_feedback_trace_without_time_is_diagnosed_at_its_sample_rate() {
    let dir = tempfile::tempdir().unwrap();
    let trace = lagging_trace(dir.path());
    // As halsampler writes it: no time column (the rate is known).
    let text = std::fs::read_to_string(&trace).unwrap();
    let no_t: String = text
        .lines()
        .map(|l| l.split_once(',').map_or(l, |(_, rest)| rest).to_string() + "\n")
        .collect();
    let bare = dir.path().join("bare.csv");
    std::fs::write(&bare, no_t).unwrap();
    let out = Command::new(BIN)
        .args(["diagnose", "--machine", "zhao2022-xzbc", "--recording"])
        .arg(&bare)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bare.csv:1:1") && err.contains("--sample-rate"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_str(&kinpost(&[
        "diagnose",
        "--machine",
        "zhao2022-xzbc",
        "--recording",
        bare.to_str().unwrap(),
        "--sample-rate",
        "100",
        "--json",
    ]))
    .unwrap();
    assert_eq!(v["recording"], "joint_feedback");
    for key in FORMATS_FIELDS {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    let f = &v["findings"][0];
    assert_eq!(f["effect"], "servo_lag");
    assert_eq!(f["axis"], "X");
    let tau = f["parameters"]["tau_s"].as_f64().unwrap();
    assert!((tau - 0.004).abs() < 0.001, "{tau}");
    assert_eq!(v["findings"].as_array().unwrap().len(), 1, "{v}");
}

/// A joint-feedback trace whose header is written as a comment
/// (`# t,block,…`, as NumPy's savetxt writes it), or with a units row
/// under it (feedback of the linear axes in µm): before, the first was
/// taken for a tool-tip recording ("the header has no `meas_x` column")
/// and the second refused ("`s` is not a finite number"). Both give the
/// plain trace's findings.
#[test]
fn a_joint_feedback_trace_with_a_comment_header_or_a_units_row_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let trace = lagging_trace(dir.path());
    let findings = |path: &Path| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_str(&kinpost(&[
            "diagnose",
            "--machine",
            "zhao2022-xzbc",
            "--recording",
            path.to_str().unwrap(),
            "--json",
        ]))
        .unwrap();
        assert_eq!(v["recording"], "joint_feedback", "{}", path.display());
        v["findings"].clone()
    };
    let plain = findings(&trace);
    assert_eq!(plain[0]["effect"], "servo_lag");
    // The text report gives the values with their units (before:
    // `tau_s = 0.004001 ± 0.000000`, a fault's parameters as a map).
    let text = kinpost(&[
        "diagnose",
        "--machine",
        "zhao2022-xzbc",
        "--recording",
        trace.to_str().unwrap(),
    ]);
    let line = text
        .lines()
        .find(|l| l.contains("servo_lag X:"))
        .unwrap_or("");
    assert!(
        line.contains("tau = 0.00") && line.ends_with(" s") && !text.contains('{'),
        "{text}"
    );
    let text = std::fs::read_to_string(&trace).unwrap();
    let (header, body) = text.split_once('\n').unwrap();
    let commented = dir.path().join("commented.csv");
    std::fs::write(&commented, format!("# simulated\n# {header}\n{body}")).unwrap();
    assert_eq!(findings(&commented), plain);
    // The units row: s, no unit for the block, mm and deg for the
    // commands, µm for the linear axes' feedback (its values × 1000).
    let names: Vec<&str> = header.split(',').collect();
    let unit = |n: &str| match n {
        "t" => "s",
        "block" => "",
        "fb_X" | "fb_Z" => "um",
        "X" | "Z" => "mm",
        _ => "deg",
    };
    let mut units = format!(
        "{header}\n{}\n",
        names.iter().map(|n| unit(n)).collect::<Vec<_>>().join(",")
    );
    for line in body.lines() {
        let fields: Vec<String> = line
            .split(',')
            .zip(&names)
            .map(|(f, n)| {
                if unit(n) == "um" {
                    format!("{:.4}", f.parse::<f64>().unwrap() * 1e3)
                } else {
                    f.to_string()
                }
            })
            .collect();
        units.push_str(&fields.join(","));
        units.push('\n');
    }
    let with_units = dir.path().join("units.csv");
    std::fs::write(&with_units, units).unwrap();
    let found = findings(&with_units);
    assert_eq!(found.as_array().unwrap().len(), 1, "{found}");
    assert_eq!(found[0]["effect"], "servo_lag");
    let tau = |f: &serde_json::Value| f[0]["parameters"]["tau_s"].as_f64().unwrap();
    assert!(
        (tau(&found) - tau(&plain)).abs() < 1e-6,
        "{found} against {plain}"
    );
}

/// `diagnose --svg` on a joint-feedback trace draws one panel per axis of
/// `fb − command` before and after the fit (before: "--svg ignored").
#[test]
fn a_joint_feedback_trace_is_plotted_per_axis() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("fb.csv");
    let svg = dir.path().join("fb.svg");
    kinpost(&[
        "simulate",
        "--machine",
        "zhao2022-xzbc",
        "--program",
        &repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc"),
        "--feedback",
        "--noise",
        "0.0005",
        "--inject",
        "servo_lag:X=0.004",
        "-o",
        trace.to_str().unwrap(),
    ]);
    kinpost(&[
        "diagnose",
        "--machine",
        "zhao2022-xzbc",
        "--recording",
        trace.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg"), "{}", &text[..text.len().min(80)]);
    for label in [
        "X fb − command [µm]",
        "Z fb − command [µm]",
        "B fb − command [arcsec]",
        "C fb − command [arcsec]",
        "before the fit",
        "after the fit",
    ] {
        assert!(text.contains(label), "no {label}");
    }
}

#[test]
fn a_registration_is_simulated_and_named_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("registered.csv");
    let base = [
        "simulate",
        "--machine",
        "zhao2022-xzbc",
        "--errors",
        &repo_file("fixtures/errors/zhao2022-xzbc.csv"),
        "--program",
        &repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc"),
        "--seed",
        "12",
    ];
    let mut args = base.to_vec();
    args.extend([
        "--registration",
        "-0.002,0.0015,0",
        "-o",
        rec.to_str().unwrap(),
    ]);
    kinpost(&args);
    let v = diagnose_json(&rec, &[]);
    let f = &v["findings"].as_array().unwrap()[..];
    assert_eq!(f.len(), 1, "{v}");
    assert_eq!(f[0]["effect"], "registration");
    assert_eq!(f[0]["machine_physics"], false);
    let p = &f[0]["parameters"];
    assert!((p["dx_mm"].as_f64().unwrap() + 0.002).abs() < 2e-4, "{p}");
    assert!((p["dy_mm"].as_f64().unwrap() - 0.0015).abs() < 2e-4, "{p}");
    // A bad registration is a usage error (exit 2), and writes nothing.
    for bad in ["0.002,0.001", "0.002,0.001,nan", "0,0,11"] {
        let out_path = dir.path().join("bad.csv");
        let mut args = base.to_vec();
        args.extend(["--registration", bad, "-o", out_path.to_str().unwrap()]);
        let out = Command::new(BIN).args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--registration"));
        assert!(!out_path.exists());
    }
}
