//! `kinpost post` end to end: the output axes, put back through the chain,
//! land on every programmed pose; snapshots of every machine family; the
//! filter's behaviour (stdin → stdout, -o atomic, progress, errors).

use kinpost::cl::{ClReader, ClStatement};
use kinpost::gcode::{ItemKind, LineReader};
use kinpost::machine::{Machine, NoErrors, Pose};
use kinpost::program::{ModalState, PoseStart, WordRef};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::util::BIN;

use crate::util::repo_file;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).args(args).output().expect("run kinpost");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The poses a G-code pose program commands (independently of the emitter).
fn gcode_poses(path: &str) -> Vec<Pose> {
    let f = std::fs::File::open(path).unwrap();
    let mut modal = ModalState::new(PoseStart::On);
    let mut poses = Vec::new();
    for line in LineReader::new(std::io::BufReader::new(f)) {
        let line = line.unwrap();
        let words: Vec<WordRef> = line
            .items
            .iter()
            .enumerate()
            .filter_map(|(i, it)| match &it.kind {
                ItemKind::Word(w) => Some(WordRef {
                    address: w.address.as_str(),
                    value: w.value,
                    item: i,
                }),
                _ => None,
            })
            .collect();
        let kws: Vec<(usize, &str)> = line
            .items
            .iter()
            .enumerate()
            .filter_map(|(i, it)| match &it.kind {
                ItemKind::Keyword(k) => Some((i, k.as_str())),
                _ => None,
            })
            .collect();
        if let Some((tip, axis)) = modal.apply(&words, &kws).unwrap().pose {
            poses.push(Pose::new(tip, axis));
        }
    }
    poses
}

fn cl_poses(path: &str) -> Vec<Pose> {
    let f = std::fs::File::open(path).unwrap();
    let mut axis = Vector3::z();
    let mut poses = Vec::new();
    for r in ClReader::new(std::io::BufReader::new(f), path) {
        match r.unwrap().statement {
            ClStatement::Goto { tip, axis: a } => {
                if let Some(a) = a {
                    axis = Vector3::from(a);
                }
                poses.push(Pose::new(Vector3::from(tip), axis));
            }
            ClStatement::TlAxis(a) => axis = Vector3::from(a),
            _ => {}
        }
    }
    poses
}

/// Machine axis values (output order, file units) of every block of an
/// output program that carries axis words, with modal carry-over.
fn output_axes(machine: &Machine, text: &str) -> Vec<Vec<f64>> {
    let mut current = vec![f64::NAN; machine.axes.len()];
    let mut rows = Vec::new();
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
            rows.push(current.clone());
        }
    }
    rows
}

fn check_lands(machine_file: &str, program: &str, cl: bool) {
    let machine = Machine::load(Path::new(&repo_file(machine_file))).unwrap();
    let prog = repo_file(program);
    let (code, out, err) = run(&[
        "post",
        "--machine",
        &repo_file(machine_file),
        "--decimals",
        "9",
        &prog,
    ]);
    assert_eq!(code, 0, "{err}");
    let poses = if cl {
        cl_poses(&prog)
    } else {
        gcode_poses(&prog)
    };
    let rows = output_axes(&machine, &out);
    assert_eq!(rows.len(), poses.len(), "one output block per pose");
    let mut worst = (0.0f64, 0.0f64);
    for (k, (row, pose)) in rows.iter().zip(&poses).enumerate() {
        let q = machine.to_internal(row);
        let got = machine.chain.pose(&q, &NoErrors);
        let dt = got.tip_distance(pose);
        let da = got.axis_angle(pose);
        worst = (worst.0.max(dt), worst.1.max(da));
        assert!(dt <= 1e-6, "{program} block {k}: tip off by {dt} mm");
        assert!(da <= 1e-6, "{program} block {k}: axis off by {da} rad");
        if k > 0 {
            for (a, spec) in machine.axes.iter().enumerate() {
                if spec.kind == kinpost::machine::JointKind::Revolute {
                    let mut jump = (row[a] - rows[k - 1][a]).abs();
                    if spec.rotary == kinpost::machine::RotaryMode::Modulo {
                        // The controller takes the short way round.
                        jump = jump.min(360.0 - jump);
                    }
                    assert!(
                        jump < 20.0,
                        "{program} block {k}: rotary {} jumps {jump}°",
                        spec.name
                    );
                }
            }
        }
    }
    eprintln!(
        "{program}: {} poses, worst tip {:.3e} mm, axis {:.3e} rad",
        poses.len(),
        worst.0,
        worst.1
    );
}

#[test]
fn seed_machines_land_every_pose_gcode_and_cl() {
    check_lands(
        "fixtures/machines/zhao2022-xzbc.json",
        "fixtures/programs/zhao2022-xzbc.ngc",
        false,
    );
    check_lands(
        "fixtures/machines/zhao2022-xzbc.json",
        "fixtures/programs/zhao2022-lens.nc",
        false,
    );
    check_lands(
        "fixtures/machines/zhao2022-xzbc.json",
        "fixtures/programs/zhao2022-xzbc.cls",
        true,
    );
    check_lands(
        "fixtures/machines/wang2023-xyzab.json",
        "fixtures/programs/wang2023-xyzab.ngc",
        false,
    );
    check_lands(
        "fixtures/machines/wang2023-xyzab.json",
        "fixtures/programs/wang2023-xyzab.cls",
        true,
    );
}

#[test]
fn every_family_lands_every_pose() {
    for name in [
        "xyzac-trt",
        "xyzbc-trt",
        "xyzac-head",
        "xyzbc-nutating",
        "xyza-4axis",
    ] {
        check_lands(
            &format!("fixtures/machines/{name}.json"),
            &format!("fixtures/programs/{name}.ngc"),
            false,
        );
    }
}

#[test]
fn snapshots_of_every_family() {
    let cases = [
        ("zhao2022-xzbc", "zhao2022-lens.nc"),
        ("zhao2022-xzbc", "zhao2022-xzbc.cls"),
        ("wang2023-xyzab", "wang2023-xyzab.ngc"),
        ("wang2023-xyzab", "wang2023-xyzab.cls"),
        ("xyzac-trt", "xyzac-trt.ngc"),
        ("xyzbc-trt", "xyzbc-trt.ngc"),
        ("xyzac-head", "xyzac-head.ngc"),
        ("xyzbc-nutating", "xyzbc-nutating.ngc"),
        ("xyza-4axis", "xyza-4axis.ngc"),
    ];
    for (machine, program) in cases {
        let (code, out, err) = run(&[
            "post",
            "--machine",
            &repo_file(&format!("fixtures/machines/{machine}.json")),
            "--quiet",
            &repo_file(&format!("fixtures/programs/{program}")),
        ]);
        assert_eq!(code, 0, "{err}");
        // The file name in CL headers depends on the checkout path.
        let out = out.replace(env!("CARGO_MANIFEST_DIR"), "<repo>");
        insta::assert_snapshot!(format!("post_{}", program.replace('.', "_")), out);
    }
}

#[test]
fn default_machine_is_embedded_zhao2022() {
    let (code, out, _) = run(&[
        "post",
        "--quiet",
        &repo_file("fixtures/programs/zhao2022-lens.nc"),
    ]);
    assert_eq!(code, 0);
    let (_, with_file, _) = run(&[
        "post",
        "--quiet",
        "--machine",
        &repo_file("fixtures/machines/zhao2022-xzbc.json"),
        &repo_file("fixtures/programs/zhao2022-lens.nc"),
    ]);
    assert_eq!(out, with_file);
    assert!(out.contains("G49") && !out.contains("G43.5") && !out.contains(" I"));
}

#[test]
fn untouched_bytes_stay_identical() {
    // Comments, N numbers, CRLF, odd spacing and words the post does not
    // convert survive; only the pose words are replaced.
    let input = b"%\r\nN10 G21 G90 (HEADER \xe9)\r\nN20 G43.5 H1 ; tcp on\r\nN30 G1 X10 Y0 Z5 I0 J0 K1 F100 M8 (cut)\r\nN40 g1x10y1z5\r\n#1=2\r\nN50 G49\r\nM30\r\n%";
    let mut child = Command::new(BIN)
        .args(["post", "--quiet", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected: &[u8] = b"%\r\nN10 G21 G90 (HEADER \xe9)\r\nN20 G49 ; tcp on\r\nN30 G1 X10.0000 Z25.0000 B0.0000 C0.0000 F100 M8 (cut)\r\nN40 g1X10.0499Z25.0000B0.0000C-5.7106\r\n#1=2\r\nN50 G49\r\nM30\r\n%";
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(expected)
    );
}

#[test]
fn output_file_is_atomic_and_errors_leave_it_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.nc");
    std::fs::write(&out, "previous").unwrap();
    let bad = dir.path().join("bad.nc");
    std::fs::write(&bad, "G1 X10 Y0 Z5 I0 J0 K1\nG1 X10 Y0 Z5 I0 J0 K0\n").unwrap();
    let (code, stdout, err) = run(&["post", "-o", out.to_str().unwrap(), bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(stdout.is_empty());
    assert!(err.contains("bad.nc:2:"), "{err}");
    assert!(err.contains("zero"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        2,
        "no temporary file left"
    );
    let (code, _, _) = run(&[
        "post",
        "-q",
        "-o",
        out.to_str().unwrap(),
        &repo_file("fixtures/programs/zhao2022-lens.nc"),
    ]);
    assert_eq!(code, 0);
    assert!(std::fs::read_to_string(&out).unwrap().contains("G49"));
}

#[test]
fn stdout_gets_nothing_when_a_late_block_fails() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("late.nc");
    std::fs::write(&bad, "G1 X10 Y0 Z5 I0 J0 K1\nG1 X11\nG2 X12 Y1 R1\n").unwrap();
    let (code, stdout, err) = run(&["post", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(stdout.is_empty(), "half a program was written: {stdout}");
    // On the lens machine C follows the tip: an arc in X Y turns it.
    assert!(err.contains("late.nc:3:1"), "{err}");
    assert!(
        err.contains("circular move only with its rotary axes turned"),
        "{err}"
    );
}

#[test]
fn linuxcnc_filter_progress_on_stderr() {
    let out = Command::new(BIN)
        .args([
            "post",
            "--quiet",
            &repo_file("fixtures/programs/zhao2022-lens.nc"),
        ])
        .env("AXIS_PROGRESS_BAR", "1")
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("FILTER_PROGRESS=100"), "{err}");
    let without = Command::new(BIN)
        .args([
            "post",
            "--quiet",
            &repo_file("fixtures/programs/zhao2022-lens.nc"),
        ])
        .env_remove("AXIS_PROGRESS_BAR")
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&without.stderr).contains("FILTER_PROGRESS"));
}

#[test]
fn inch_program_is_converted() {
    let dir = tempfile::tempdir().unwrap();
    let mm = dir.path().join("mm.nc");
    let inch = dir.path().join("inch.nc");
    std::fs::write(&mm, "G21\nG1 X25.4 Y0 Z12.7 I0 J0 K1\n").unwrap();
    std::fs::write(&inch, "G20\nG1 X1 Y0 Z0.5 I0 J0 K1\n").unwrap();
    let (_, a, _) = run(&["post", "-q", mm.to_str().unwrap()]);
    let (_, b, _) = run(&["post", "-q", inch.to_str().unwrap()]);
    // The same pose; linear axes written in the program's units, in inch
    // with one decimal more (32.7 mm = 1.287402 in).
    assert!(a.contains("X25.4000 Z32.7000"), "{a}");
    assert!(b.contains("X1.00000 Z1.28740"), "{b}");
}

#[test]
fn unreachable_axis_on_four_axis_machine_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("off.nc");
    // Tool axis tilted sideways (off the XZBC machine's cone at this tip).
    std::fs::write(&p, "G1 X30 Y0 Z0 I0 J0.2 K0.9797958971\n").unwrap();
    let (code, _, err) = run(&["post", p.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("off.nc:1:4") && err.contains("µrad"), "{err}");
}

#[test]
fn tcp_switched_on_after_machine_moves_continues_from_the_machine_position() {
    // A Fanuc header cancels TCP (G49), moves in machine coordinates, then
    // switches TCP on with only Z: X and Y come from the machine's position.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("fanuc.nc");
    std::fs::write(
        &p,
        "G90 G94 G17 G49 G40 G80\nG0 X100. Y0. A0. C0.\nG43.4 H1 Z60.\nG1 X90. Y5. Z40. I0. J0. K1. F500.\nG49\nM30\n",
    )
    .unwrap();
    let (code, out, err) = run(&["post", "-q", "--machine", "xyzac-trt", p.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[1], "G0 X100. Y0. A0. C0.",
        "machine-coordinate block untouched"
    );
    assert_eq!(lines[2], "G49 X100.0000 Y0.0000 Z60.0000 A0.0000 C0.0000");
    assert_eq!(
        lines[3],
        "G1 X90.0000 Y5.0000 Z40.0000 A0.0000 C0.0000 F500."
    );
}
