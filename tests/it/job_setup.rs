//! The job set-up (`--tool-length`, `--tool-table`, `--work-offset`):
//! every command that takes it must give what the same command gives on a
//! machine file edited by hand — the tool as `translate [0, 0, −L]` at the
//! end of the chain, the work offset as `translate −o` at its start — and
//! the axes `post` writes must put the tool tip on the programmed point,
//! checked with the untouched machine's forward kinematics and the tool
//! and offset added by hand.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::BIN;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).args(args).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn ok(args: &[&str]) -> String {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "kinpost {args:?}: {err}");
    out
}

/// The machine file of `name` with the tool and work offset written into
/// its chain by hand.
fn edited_machine(dir: &Path, name: &str, tool_mm: f64, offset: [f64; 3]) -> PathBuf {
    let json = ok(&["machine", "--json", "-m", name]);
    let mut v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let o = v.as_object_mut().unwrap();
    o.remove("_ik_family");
    let chain = o.get_mut("chain").unwrap().as_array_mut().unwrap();
    chain.insert(
        0,
        serde_json::json!({"translate": [-offset[0], -offset[1], -offset[2]]}),
    );
    chain.push(serde_json::json!({"translate": [0.0, 0.0, -tool_mm]}));
    let path = dir.join(format!("{name}-edited.json"));
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    path
}

fn program(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("job.ngc");
    std::fs::write(&p, text).unwrap();
    p
}

const FIVE_AXIS: &str = "G21 G90 G94\nT1 M6\nG43.4 H1\nG1 X10 Y20 Z30 I0 J0 K1 F500\n\
X15 Y22 Z28 I0 J0.6 K0.8\nX18 Y25 Z26 I0.28 J0.48 K0.83066239\nX5 Y-10 Z20 I-0.3 J0 K0.9539392\nG49\nM30\n";

fn axis_words(block: &str, names: &[&str]) -> Option<Vec<f64>> {
    names
        .iter()
        .map(|n| {
            block
                .split_whitespace()
                .find(|w| w.starts_with(n) && w[1..].parse::<f64>().is_ok())
                .map(|w| w[1..].parse().unwrap())
        })
        .collect()
}

#[test]
fn post_puts_the_tool_tip_on_the_programmed_point() {
    let dir = tempfile::tempdir().unwrap();
    let p = program(dir.path(), FIVE_AXIS);
    let (l, o) = (87.5, [120.0, -40.0, 15.5]);
    for name in ["xyzac-head", "xyzac-trt", "xyzbc-trt", "xyzbc-nutating"] {
        let out = ok(&[
            "post",
            "-m",
            name,
            "--tool-length",
            "87.5",
            "--work-offset",
            "120,-40,15.5",
            "--decimals",
            "9",
            "-q",
            p.to_str().unwrap(),
        ]);
        let machine = kinpost::machine::Machine::embedded(name).unwrap();
        let order: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
        let tips: [([f64; 3], [f64; 3]); 4] = [
            ([10.0, 20.0, 30.0], [0.0, 0.0, 1.0]),
            ([15.0, 22.0, 28.0], [0.0, 0.6, 0.8]),
            ([18.0, 25.0, 26.0], [0.28, 0.48, 0.83066239]),
            ([5.0, -10.0, 20.0], [-0.3, 0.0, 0.9539392]),
        ];
        let blocks: Vec<Vec<f64>> = out.lines().filter_map(|b| axis_words(b, &order)).collect();
        assert_eq!(blocks.len(), tips.len(), "{name}:\n{out}");
        for (values, (tip, axis)) in blocks.iter().zip(tips) {
            // The untouched machine's chain end, then the tool and the
            // offset by hand: tip = end − L·axis − o.
            let q = machine.to_internal(values);
            let end = machine.chain.pose(&q, &kinpost::machine::NoErrors);
            for k in 0..3 {
                let got = end.tip[k] - l * end.axis[k] - o[k];
                assert!(
                    (got - tip[k]).abs() < 1e-6,
                    "{name}: tip {k} {got} != {}\n{out}",
                    tip[k]
                );
                let a =
                    axis[k] / (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
                assert!((end.axis[k] - a).abs() < 1e-6, "{name}: axis\n{out}");
            }
        }
    }
}

#[test]
fn every_command_agrees_with_a_machine_file_edited_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let lens = root().join("fixtures/programs/zhao2022-lens.nc");
    let lens = lens.to_str().unwrap();
    let errors = root().join("fixtures/errors/zhao2022-xzbc.csv");
    let errors = errors.to_str().unwrap();
    // The lens machine (RTTR) reaches the tool axis only with the tip on
    // the plane through its C axis: the offset runs along C.
    let edited = edited_machine(dir.path(), "zhao2022-xzbc", 35.0, [0.0, 0.0, -3.0]);
    let edited = edited.to_str().unwrap();
    let job = ["--tool-length", "35", "--work-offset", "0,0,-3"];
    let with = |cmd: &[&str]| {
        let mut v: Vec<&str> = cmd.to_vec();
        v.extend(["-m", "zhao2022-xzbc"]);
        v.extend(job);
        ok(&v)
    };
    let by_hand = |cmd: &[&str]| {
        let mut v: Vec<&str> = cmd.to_vec();
        v.extend(["-m", edited]);
        ok(&v)
    };
    let cls = root().join("fixtures/programs/zhao2022-xzbc.cls");
    for cmd in [
        vec!["post", "-q", lens],
        vec!["post", "-q", cls.to_str().unwrap()],
        vec!["compensate", "-q", "-e", errors, lens],
        vec!["analyze", "--json", "-e", errors, lens],
        vec!["analyze", "--nonlinear", "--json", lens],
    ] {
        let a = with(&cmd);
        let b = by_hand(&cmd);
        // The machine name differs in analyze's report: the edited file is
        // named after its path.
        let b = b.replace(
            &format!(
                "\"{}\"",
                Path::new(edited).file_stem().unwrap().to_str().unwrap()
            ),
            "\"zhao2022-xzbc\"",
        );
        assert_eq!(a, b, "kinpost {cmd:?}");
        assert!(!a.is_empty());
    }
    // Without the set-up the program converts differently: the options act.
    assert_ne!(ok(&["post", "-q", lens]), with(&["post", "-q", lens]));

    // linkage and simulate, on the five-axis machines.
    let p = program(dir.path(), FIVE_AXIS);
    let p = p.to_str().unwrap();
    let edited = edited_machine(dir.path(), "xyzac-trt", 35.0, [2.0, 0.0, -3.0]);
    let edited = edited.to_str().unwrap();
    let job = ["--tool-length", "35", "--work-offset", "2,0,-3"];
    let job_trt = |cmd: &[&str]| {
        let mut v: Vec<&str> = cmd.to_vec();
        v.extend(["-m", "xyzac-trt"]);
        v.extend(job);
        ok(&v)
    };
    let hand_trt = |cmd: &[&str]| {
        let mut v: Vec<&str> = cmd.to_vec();
        v.extend(["-m", edited]);
        ok(&v)
    };
    let cmd = ["linkage", "-q", "--tolerance", "0.0005", p];
    assert_eq!(job_trt(&cmd), hand_trt(&cmd));
    let rec_a = dir.path().join("a.csv");
    let rec_b = dir.path().join("b.csv");
    job_trt(&[
        "simulate",
        "-p",
        p,
        "--seed",
        "3",
        "-o",
        rec_a.to_str().unwrap(),
    ]);
    hand_trt(&[
        "simulate",
        "-p",
        p,
        "--seed",
        "3",
        "-o",
        rec_b.to_str().unwrap(),
    ]);
    let a = std::fs::read_to_string(&rec_a).unwrap();
    assert!(a.lines().count() > 10);
    assert_eq!(a, std::fs::read_to_string(&rec_b).unwrap());
}

#[test]
fn the_tool_table_gives_the_length_the_program_selects() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("tool.tbl");
    std::fs::write(
        &table,
        "T1 P1 Z+50.000000 D6 ;flat end mill\nT2 P2 Z87.5 D10\nT7 P7 Z50 ;same length as T1\n",
    )
    .unwrap();
    let t = table.to_str().unwrap();
    let p = program(dir.path(), FIVE_AXIS);
    let by_length = |l: &str| {
        ok(&[
            "post",
            "-m",
            "xyzac-head",
            "--tool-length",
            l,
            "-q",
            p.to_str().unwrap(),
        ])
    };
    let by_table = |text: &str| {
        let p = program(dir.path(), text);
        run(&[
            "post",
            "-m",
            "xyzac-head",
            "--tool-table",
            t,
            "-q",
            p.to_str().unwrap(),
        ])
    };
    // H of G43.4 selects.
    let (code, out, err) = by_table(
        &FIVE_AXIS
            .replace("T1 M6", "T2 M6")
            .replace("G43.4 H1", "G43.4 H2"),
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, by_length("87.5").replace("T1 M6", "T2 M6"));
    let (code, out, err) = by_table(FIVE_AXIS);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, by_length("50"));
    // Without H: the tool of the last tool change (T2 M6).
    let (code, out, err) = by_table(
        &FIVE_AXIS
            .replace("T1 M6", "T2 M6")
            .replace("G43.4 H1", "G43.4"),
    );
    assert_eq!(code, 0, "{err}");
    let expected = by_length("87.5").replace("T1 M6", "T2 M6");
    assert_eq!(out, expected);
    // A tool change to a tool of the same length is fine.
    let (code, _, err) =
        by_table(&FIVE_AXIS.replace("G49\n", "T7 M6\nG43.4 H7\nG1 X1 Y1 Z40 I0 J0 K1\nG49\n"));
    assert_eq!(code, 0, "{err}");
    // Refusals name file:line:col.
    let (code, _, err) = by_table(&FIVE_AXIS.replace("G43.4 H1", "G43.4 H9"));
    assert_eq!(code, 1);
    assert!(
        err.contains("job.ngc:3:7: length offset H9 is not in the tool table"),
        "{err}"
    );
    let (code, _, err) = by_table(&FIVE_AXIS.replace("T1 M6", "T4 M6"));
    assert_eq!(code, 1);
    assert!(
        err.contains("job.ngc:2:1: tool T4 is not in the tool table"),
        "{err}"
    );
    // A command other than post takes one tool length per run: a change to
    // a tool of another length is refused there.
    let two = program(
        dir.path(),
        &FIVE_AXIS.replace("G49\n", "T2 M6\nG43.4 H2\nG1 X1 Y1 Z40 I0 J0 K1\nG49\n"),
    );
    let (code, _, err) = run(&[
        "analyze",
        "--nonlinear",
        "-m",
        "xyzac-head",
        "--tool-table",
        t,
        two.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("job.ngc:8:4: this selects tool 2 of length 87.5 mm"),
        "{err}"
    );
    let (code, _, err) = by_table("G1 X1 Y1 Z1 I0 J0 K1\n");
    assert_eq!(code, 1);
    assert!(err.contains("selects no tool"), "{err}");
    // --tool-length and --tool-table exclude each other (usage, exit 2).
    let (code, _, _) = run(&[
        "post",
        "--tool-length",
        "5",
        "--tool-table",
        t,
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 2);
    // A bad work offset is a usage error.
    let (code, _, err) = run(&["post", "--work-offset", "1,2", p.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn the_job_tool_replaces_the_tool_of_the_machine_file() {
    let dir = tempfile::tempdir().unwrap();
    let ini = root().join("fixtures/linuxcnc/xyzac-trt.ini");
    let file = |t: &str| {
        let path = dir.path().join(format!("trt-{t}.json"));
        ok(&[
            "machine",
            "--from-linuxcnc",
            ini.to_str().unwrap(),
            "--tool-length",
            t,
            "-o",
            path.to_str().unwrap(),
        ]);
        path
    };
    let (m20, m50) = (file("20"), file("50"));
    assert!(
        std::fs::read_to_string(&m20)
            .unwrap()
            .contains("\"tool_length\": 20")
    );
    let p = program(dir.path(), FIVE_AXIS);
    let post = |m: &Path, extra: &[&str]| {
        let mut v = vec!["post", "-q", "--decimals", "9", "-m", m.to_str().unwrap()];
        v.extend(extra);
        v.push(p.to_str().unwrap());
        ok(&v)
    };
    // The file made for a 20 mm tool, posted for a 50 mm one, is the file
    // made for the 50 mm tool: the job's tool replaces the file's.
    let replaced = post(&m20, &["--tool-length", "50"]);
    assert_eq!(replaced, post(&m50, &[]));
    assert_ne!(replaced, post(&m20, &[]));
    assert_eq!(post(&m50, &["--tool-length", "20"]), post(&m20, &[]));
    // `machine --json` keeps the file's tool: it loads back the same.
    let json = ok(&["machine", "--json", "-m", m20.to_str().unwrap()]);
    assert!(json.contains("\"tool_length\": 20"), "{json}");
    let back = dir.path().join("back.json");
    std::fs::write(&back, json).unwrap();
    assert_eq!(post(&back, &["--tool-length", "50"]), replaced);
}

#[test]
fn a_work_offset_with_a_base_fixed_error_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.json");
    ok(&[
        "fit",
        root()
            .join("fixtures/errors/zhao2022-xzbc.csv")
            .to_str()
            .unwrap(),
        "-o",
        model.to_str().unwrap(),
    ]);
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    v["fixed"] = serde_json::json!([{"name": "base tilt", "after_joint": null,
        "motion": [0.0, 0.0, 0.0, 1e-5, 0.0, 0.0]}]);
    std::fs::write(&model, v.to_string()).unwrap();
    let lens = root().join("fixtures/programs/zhao2022-lens.nc");
    for cmd in ["analyze", "compensate"] {
        let (code, _, err) = run(&[
            cmd,
            "-e",
            model.to_str().unwrap(),
            "--work-offset",
            "0,0,3",
            lens.to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(
            err.contains("fixed error `base tilt` at the start of the chain"),
            "{err}"
        );
        // Without the offset the same model is used.
        let (code, _, err) = run(&[cmd, "-e", model.to_str().unwrap(), lens.to_str().unwrap()]);
        assert_eq!(code, 0, "{cmd}: {err}");
    }
}

#[test]
fn diagnose_takes_the_set_up_of_the_recorded_job() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    let errors = root().join("fixtures/errors/zhao2022-xzbc.csv");
    let errors = errors.to_str().unwrap();
    let program = root().join("fixtures/programs/zhao2022-xzbc-exercise.nc");
    let job = ["--tool-length", "30", "--work-offset", "0,0,-3"];
    let mut sim = vec!["simulate", "-e", errors, "-p", program.to_str().unwrap()];
    sim.extend([
        "--noise",
        "0.0005",
        "--seed",
        "5",
        "-o",
        rec.to_str().unwrap(),
    ]);
    sim.extend(job);
    ok(&sim);
    let diag = |extra: &[&str]| {
        let mut v = vec![
            "diagnose",
            "-e",
            errors,
            "-r",
            rec.to_str().unwrap(),
            "--json",
        ];
        v.extend(extra);
        run(&v)
    };
    // With the job's set-up the recording fits the model machine...
    let (code, out, err) = diag(&job);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(v.is_object());
    // ...without it the tip is 30 mm away along the tool axis: refused.
    let (code, _, err) = diag(&[]);
    assert_eq!(code, 1, "{err}");
    // A tool table needs the program that selects the tool.
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, "T1 Z30\n").unwrap();
    let (code, _, err) = diag(&["--tool-table", table.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn post_switches_to_the_length_of_each_tool_change() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("tool.tbl");
    std::fs::write(&table, "T1 P1 Z50 ;ball\nT2 P2 Z87.5 ;flat\nT3 P3 Z120\n").unwrap();
    // Three parts: T1 (H1), T2 by M6 and G43.4 without H, T3 by H3 after
    // T3 M6; machine-coordinate moves between them.
    let text = "G21 G90 G94\nT1 M6\nG43.4 H1\nG1 X10 Y20 Z30 I0 J0 K1 F500\n\
X15 Y22 Z28 I0 J0.6 K0.8\nG49\nG0 Z300\nT2 M6\nG43.4\nG1 X18 Y25 Z26 I0.28 J0.48 K0.83066239\n\
X5 Y-10 Z20 I-0.3 J0 K0.9539392\nG49\nT3 M6\nG43.4 H3 X-4 Y6 Z12 I0 J0 K1\nX-8 Y6 Z10 I0.6 J0 K0.8\nG49\nM30\n";
    let p = program(dir.path(), text);
    let out = ok(&[
        "post",
        "-m",
        "xyzac-head",
        "--tool-table",
        table.to_str().unwrap(),
        "--work-offset",
        "3,4,5",
        "--decimals",
        "9",
        "-q",
        p.to_str().unwrap(),
    ]);
    let machine = kinpost::machine::Machine::embedded("xyzac-head").unwrap();
    let order: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
    // (tip, axis, tool length) of every pose, as programmed.
    let poses: [([f64; 3], [f64; 3], f64); 6] = [
        ([10.0, 20.0, 30.0], [0.0, 0.0, 1.0], 50.0),
        ([15.0, 22.0, 28.0], [0.0, 0.6, 0.8], 50.0),
        ([18.0, 25.0, 26.0], [0.28, 0.48, 0.83066239], 87.5),
        ([5.0, -10.0, 20.0], [-0.3, 0.0, 0.9539392], 87.5),
        ([-4.0, 6.0, 12.0], [0.0, 0.0, 1.0], 120.0),
        ([-8.0, 6.0, 10.0], [0.6, 0.0, 0.8], 120.0),
    ];
    let blocks: Vec<Vec<f64>> = out
        .lines()
        .filter(|l| !l.starts_with("G0"))
        .filter_map(|b| axis_words(b, &order))
        .collect();
    assert_eq!(blocks.len(), poses.len(), "{out}");
    let o = [3.0, 4.0, 5.0];
    for (values, (tip, axis, l)) in blocks.iter().zip(poses) {
        let q = machine.to_internal(values);
        let end = machine.chain.pose(&q, &kinpost::machine::NoErrors);
        let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        for k in 0..3 {
            let got = end.tip[k] - l * end.axis[k] - o[k];
            assert!(
                (got - tip[k]).abs() < 1e-6,
                "tool {l}: {got} != {}\n{out}",
                tip[k]
            );
            assert!((end.axis[k] - axis[k] / n).abs() < 1e-6, "{out}");
        }
    }
}

/// A program's own plain tool length compensation (`G43 H1`, no TCP code)
/// before poses started by their tool vectors: with the tool's length in
/// the chain (`--tool-length`, `--tool-table`) the axis words include it,
/// and the controller would add it again. Before: converted, `G43 H1`
/// passed on, exit 0 (the tip 50 mm off on the machine). Now refused at the
/// `G43`; after `G49`, with `G43.4`, or without a tool length in the chain,
/// converted as before.
#[test]
fn plain_tool_length_compensation_under_a_tool_in_the_chain_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("tool.tbl");
    std::fs::write(&table, "T1 P1 Z+50.0 D6 ;end mill\n").unwrap();
    let program = "G21 G90\nT1 M6\nG43 H1\nG0 X0 Y0 Z100\nG1 X10 Y0 Z5 I0 J0 K1 F100\nX20 I0.6 J0 K0.8\nM30\n";
    let run = |args: &[&str], text: &str| {
        let p = dir.path().join("p.ngc");
        std::fs::write(&p, text).unwrap();
        let out = std::process::Command::new(crate::util::BIN)
            .args(["post", "--machine", "xyzbc-trt"])
            .args(args)
            .arg(&p)
            .output()
            .unwrap();
        (
            out.status.code().unwrap(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let table = table.display().to_string();
    for args in [
        vec!["--tool-length", "50"],
        vec!["--tool-table", table.as_str()],
        vec!["--tool-length", "50", "--pose-start", "on"],
    ] {
        let (code, err) = run(&args, program);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(
            err.contains("p.ngc:3:1:") && err.contains("G49"),
            "{args:?}: {err}"
        );
    }
    // Switched off before the poses, TCP instead, or the tool not in the chain.
    for (args, text) in [
        (
            vec!["--tool-length", "50"],
            program.replace("G43 H1\n", "G43 H1\nG49\n"),
        ),
        (
            vec!["--tool-length", "50"],
            program.replace("G43 H1\n", "G43.4 H1\n"),
        ),
        (vec![], program.to_string()),
    ] {
        let (code, err) = run(&args, &text);
        assert_eq!(code, 0, "{args:?} {text}: {err}");
    }
}
