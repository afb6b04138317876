//! The chunked, multi-threaded compensation driver gives what the block by
//! block solver gives; the report streams out with the same layout; errors
//! name the same line; the result does not depend on the number of threads.

use kinpost::compensate::{BlockRecord, CompensatingSolver, OnFail, Options, compensate_gcode};
use kinpost::geometric::model::{BoundErrors, ErrorModel};
use kinpost::machine::{IkSolver, Machine};
use kinpost::post::{PostOptions, post_gcode};
use std::path::Path;
use std::process::Command;

use crate::util::repo_file;

fn solver<'a>(
    machine: &'a Machine,
    model: &ErrorModel,
    bound: &'a BoundErrors<'a>,
) -> CompensatingSolver<'a> {
    CompensatingSolver {
        machine,
        actual_chain: model.apply_fixed(&machine.chain).unwrap(),
        errors: bound,
        ik: IkSolver::new(machine),
        options: Options::default(),
        on_fail: OnFail::Error,
        accept_tip_mm: 1e-9,
        axis_tolerance_rad: 1e-4,
        records: Vec::new(),
        warnings: Vec::new(),
        singular_blocks: 0,
        decimals: Vec::new(),
        backlash: Vec::new(),
        directions: Vec::new(),
        written_per_block: true,
        written_largest: (0.0, 0.0),
    }
}

/// A lens spiral program long enough for several chunks, with comments and
/// a modal line in between.
fn program(poses: usize) -> String {
    let mut v = Vec::new();
    kinpost::demo::write_lens_spiral_program(&kinpost::demo::OffAxisLens::default(), poses, &mut v)
        .unwrap();
    let text = String::from_utf8(v).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        out.push_str(line);
        out.push('\n');
        if i % 1000 == 999 {
            out.push_str("(ring)\nF150.\n");
        }
    }
    out
}

/// Output (or error text) of one driver.
type Run = Result<Vec<u8>, String>;

fn run_both(text: &str) -> (Run, Run, Vec<BlockRecord>) {
    let machine = Machine::embedded_default();
    let model =
        ErrorModel::load(Path::new(&repo_file("fixtures/errors/zhao2022-xzbc.csv"))).unwrap();
    let bound = model.bind(&machine.chain).unwrap();
    let opts = PostOptions {
        decimals: Some(9),
        file_name: "p.nc".into(),
        ..PostOptions::default()
    };
    let mut seq = solver(&machine, &model, &bound);
    let mut a = Vec::new();
    let ra = post_gcode(&machine, &mut seq, text.as_bytes(), &mut a, &opts, |_| {})
        .map(|_| a)
        .map_err(|e| e.to_string());
    let mut par = solver(&machine, &model, &bound);
    let mut b = Vec::new();
    let mut records = Vec::new();
    let rb = compensate_gcode(
        &machine,
        &mut par,
        text.as_bytes(),
        &mut b,
        &opts,
        |_| {},
        |r: &mut Vec<BlockRecord>| {
            records.append(r);
            Ok(())
        },
    )
    .map(|_| b)
    .map_err(|e| e.to_string());
    assert_eq!(
        seq.records.len(),
        records.len(),
        "one record per compensated block"
    );
    for (x, y) in seq.records.iter().zip(&records) {
        assert_eq!(x.line, y.line);
        assert_eq!(x.iterations, y.iterations);
        assert_eq!(x.compensation, y.compensation);
    }
    (ra, rb, records)
}

#[test]
fn chunked_driver_matches_block_by_block_solver() {
    let text = program(9000);
    let (a, b, records) = run_both(&text);
    assert_eq!(records.len(), 9000);
    assert_eq!(a.unwrap(), b.unwrap());
}

#[test]
fn chunked_driver_reports_the_same_error_line() {
    // An expression in a pose block beyond the first chunk.
    let mut text = program(6000);
    let at = text.match_indices('\n').nth(5000).unwrap().0 + 1;
    text.insert_str(at, "X[1+2] Y0 Z0 I0 J0 K1\n");
    let (a, b, _) = run_both(&text);
    let (ea, eb) = (a.unwrap_err(), b.unwrap_err());
    assert_eq!(ea, eb);
    assert!(ea.contains("p.nc:5002:"), "{ea}");
}

#[test]
fn report_streams_and_threads_do_not_change_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("p.nc");
    std::fs::write(&prog, program(5000)).unwrap();
    let run = |threads: &str, tag: &str| {
        let out = dir.path().join(format!("{tag}.nc"));
        let rep = dir.path().join(format!("{tag}.json"));
        let st = Command::new(crate::util::BIN)
            .env("RAYON_NUM_THREADS", threads)
            .args(["compensate", "-q", "--errors"])
            .arg(repo_file("fixtures/errors/zhao2022-xzbc.csv"))
            .arg("--report")
            .arg(&rep)
            .arg(&prog)
            .arg("-o")
            .arg(&out)
            .status()
            .unwrap();
        assert!(st.success());
        (std::fs::read(out).unwrap(), std::fs::read(rep).unwrap())
    };
    // One thread (the main thread alone), two, and more than the cores.
    let (o1, r1) = run("1", "one");
    let (o2, r2) = run("2", "two");
    let (o4, r4) = run("4", "four");
    assert_eq!(o1, o2);
    assert_eq!(r1, r2);
    assert_eq!(o1, o4);
    assert_eq!(r1, r4);
    let v: serde_json::Value = serde_json::from_slice(&r1).unwrap();
    let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
    assert_eq!(keys, ["blocks", "summary", "warnings"]);
    assert_eq!(v["blocks"].as_array().unwrap().len(), 5000);
    assert_eq!(v["summary"]["poses"], 5000);
    assert!(v["summary"]["tip_residual_max_mm"].as_f64().unwrap() < 1e-12);
    // The layout of serde_json's pretty printer.
    let text = String::from_utf8(r1).unwrap();
    assert_eq!(serde_json::to_string_pretty(&v).unwrap(), text);
}

/// Without a report only the largest errors as written are exact: a block
/// whose first-order upper bounds lie below the largest so far is not
/// evaluated at its written values. The summary is the same as that of a
/// run with a report, where every block is evaluated, on both seed
/// machines, for coarse and fine decimals and either number of threads;
/// the report's largest values are those of its blocks.
#[test]
fn the_largest_errors_as_written_do_not_depend_on_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let spiral = dir.path().join("spiral.nc");
    std::fs::write(&spiral, program(3000)).unwrap();
    let spiral = spiral.display().to_string();
    let cases = [
        (
            "zhao2022-xzbc",
            "fixtures/errors/zhao2022-xzbc.csv",
            spiral.clone(),
        ),
        (
            "zhao2022-xzbc",
            "fixtures/errors/zhao2022-xzbc.csv",
            repo_file("fixtures/programs/zhao2022-lens.nc"),
        ),
        (
            "wang2023-xyzab",
            "fixtures/errors/wang2023-xyzab.csv",
            repo_file("fixtures/programs/wang2023-xyzab.ngc"),
        ),
        (
            "wang2023-xyzab",
            "fixtures/errors/wang2023-xyzab.csv",
            repo_file("fixtures/programs/wang2023-impeller.nc"),
        ),
    ];
    for (machine, table, prog) in &cases {
        for decimals in ["2", "4", "7"] {
            let run = |threads: &str, report: bool| {
                let rep = dir.path().join("r.json");
                let mut cmd = Command::new(crate::util::BIN);
                cmd.env("RAYON_NUM_THREADS", threads)
                    .args([
                        "compensate",
                        "--machine",
                        machine,
                        "--decimals",
                        decimals,
                        "--errors",
                    ])
                    .arg(repo_file(table))
                    .arg(prog)
                    .arg("-o")
                    .arg(dir.path().join("o.nc"));
                if report {
                    cmd.arg("--report").arg(&rep);
                }
                let out = cmd.output().unwrap();
                assert!(
                    out.status.success(),
                    "{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                let report = report.then(|| {
                    serde_json::from_slice::<serde_json::Value>(&std::fs::read(&rep).unwrap())
                        .unwrap()
                });
                (String::from_utf8(out.stderr).unwrap(), report)
            };
            let (with, report) = run("2", true);
            let (without, _) = run("2", false);
            let (one, _) = run("1", false);
            let case = format!("{machine} {prog} --decimals {decimals}");
            assert_eq!(with, without, "{case}");
            assert_eq!(with, one, "{case}");
            let report = report.unwrap();
            for (block_key, summary_key) in [
                ("tip_residual_written_mm", "tip_residual_written_max_mm"),
                (
                    "orientation_residual_written_urad",
                    "orientation_residual_written_max_urad",
                ),
            ] {
                let largest = report["blocks"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|b| b[block_key].as_f64().unwrap())
                    .fold(0.0, f64::max);
                assert_eq!(
                    report["summary"][summary_key].as_f64(),
                    Some(largest),
                    "{case}"
                );
            }
        }
    }
}
