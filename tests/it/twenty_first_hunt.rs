//! Twenty-first hunt (session 37, `docs/robustness.md`): NX output for a
//! Haas UMC-750 from another public repository, Sinumerik 840C and 840D
//! programs, with variants. Each test failed on the session's first
//! build (d28aeeb).

use crate::util::{repo_file, run_on};

/// A line before the opening `%` (a DNC header, a comment, NX's
/// "Information listing") made that `%` the closing one: every command
/// passed the whole program on unread, `post` and `compensate` with exit 0
/// and the poses unconverted, `linkage` and `analyze` with "0 blocks".
/// The first `%` opens the program whatever stands before it: the result
/// is the one without the header, with the header line in front.
#[test]
fn a_header_before_the_opening_percent_leaves_the_program_read() {
    let wang = std::fs::read_to_string(repo_file("fixtures/programs/wang2023-xyzab.ngc")).unwrap();
    let errors = repo_file("fixtures/errors/wang2023-xyzab.csv");
    let haas = "O1000\nG234 H1\nG1 X1 Y2 Z3 B10 C20 F100\nG1 X2 B12 C25\nG49\nM30\n";
    let cases: [(&[&str], &str); 5] = [
        (&["post", "-m", "xyzbc-trt"], haas),
        (&["post", "-m", "wang2023-xyzab"], &wang),
        (
            &["compensate", "-m", "wang2023-xyzab", "-e", &errors],
            &wang,
        ),
        (&["linkage", "-m", "wang2023-xyzab"], &wang),
        (&["analyze", "--nonlinear", "-m", "wang2023-xyzab"], &wang),
    ];
    for (args, program) in cases {
        let bare = format!("%\n{program}%\n");
        let (code, want, err) = run_on(args, "p.nc", &bare);
        assert_eq!(code, 0, "{args:?}: {err}");
        assert_ne!(want, bare, "{args:?}: nothing converted");
        for header in ["(JOB 42)\n", ";listing\n", "O1000 (PROG)\n"] {
            let (code, out, err) = run_on(args, "p.nc", &format!("{header}{bare}"));
            assert_eq!(code, 0, "{args:?} {header:?}: {err}");
            assert!(!err.contains("closing `%`"), "{args:?} {header:?}: {err}");
            if args[0] == "analyze" {
                // The report names lines: one further down.
                assert_eq!(out.lines().count(), want.lines().count(), "{args:?}: {out}");
            } else {
                assert_eq!(out, format!("{header}{want}"), "{args:?} {header:?}");
            }
        }
    }
    // `simulate`: the same recording, its blocks one line further down.
    let args = ["simulate", "-m", "wang2023-xyzab", "--noise", "0", "-p"];
    let (code, want, err) = run_on(&args, "p.nc", &format!("%\n{wang}%\n"));
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = run_on(&args, "p.nc", &format!("(JOB 42)\n%\n{wang}%\n"));
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.lines().count(), want.lines().count());
}

/// `compensate` dropped every warning of reading the program (the text
/// after the closing `%`, the modal state's), from its messages and from
/// its report: only the refinement's own were printed. `post` prints them.
#[test]
fn compensate_gives_the_warnings_of_reading_the_program() {
    let wang = std::fs::read_to_string(repo_file("fixtures/programs/wang2023-xyzab.ngc")).unwrap();
    let errors = repo_file("fixtures/errors/wang2023-xyzab.csv");
    let program = format!("%\n{wang}%\nTool Path Listing has 3 lines.");
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let report_arg = report.to_str().unwrap();
    let args = [
        "compensate",
        "-m",
        "wang2023-xyzab",
        "-e",
        &errors,
        "--report",
        report_arg,
    ];
    let (code, out, err) = run_on(&args, "w.ngc", &program);
    assert_eq!(code, 0, "{err}");
    assert!(out.ends_with("%\nTool Path Listing has 3 lines."), "{out}");
    let want = "text after the program's closing `%` (line 160) passed on unread";
    assert!(err.contains(want), "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let warnings = json["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w.as_str().unwrap().contains(want)),
        "{warnings:?}"
    );
}

/// A pose program of `n` poses for zhao2022-xzbc (about 40 bytes a line).
fn many_poses(n: usize) -> String {
    let mut p = String::from("G21 G90\nG43.4 H1\n");
    for i in 0..n {
        let x = 10.0 + (i % 1000) as f64 * 0.01;
        p.push_str(&format!("G1 X{x:.3} Y5 Z5 I0 J0 K1 F100\n"));
    }
    p.push_str("G49\nM30\n");
    p
}

/// Careless command lines (a helper's output-path hunt): standard input
/// that is the output file was not caught (`-o p.nc < p.nc` replaced the
/// program, exit 0); `-o /dev/stdout` with standard output redirected to a
/// file replaced that file (what a shell's `>>` appended to was lost);
/// `-o -` wrote a file named `-`.
#[test]
fn standard_input_and_output_given_as_paths() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let program = many_poses(20);
    let p = dir.path().join("p.nc");
    std::fs::write(&p, &program).unwrap();
    let out = Command::new(crate::util::BIN)
        .current_dir(dir.path())
        .args(["post", "-q", "-o", "p.nc"])
        .stdin(std::fs::File::open(&p).unwrap())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("p.nc is the input <stdin> (the same file)"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&p).unwrap(), program);
    // The converted program, as `post` writes it to a pipe.
    let want = Command::new(crate::util::BIN)
        .args(["post", "-q"])
        .arg(&p)
        .output()
        .unwrap();
    assert_eq!(want.status.code(), Some(0));
    for target in ["/dev/stdout", "-"] {
        let g = dir.path().join("g.txt");
        std::fs::write(&g, "HEADER\n").unwrap();
        let append = std::fs::OpenOptions::new().append(true).open(&g).unwrap();
        let status = Command::new(crate::util::BIN)
            .current_dir(dir.path())
            .args(["post", "-q", "p.nc", "-o", target])
            .stdout(Stdio::from(append))
            .status()
            .unwrap();
        assert_eq!(status.code(), Some(0));
        let mut expected = b"HEADER\n".to_vec();
        expected.extend_from_slice(&want.stdout);
        assert_eq!(std::fs::read(&g).unwrap(), expected, "{target}");
        assert!(!dir.path().join("-").exists());
    }
}

/// `compensate … --report r.json | head -1`: the reader of standard output
/// stopped early, and the report was silently not written (exit 0). The
/// report is written; the program's rest goes nowhere, as with any filter.
#[test]
fn the_report_is_written_when_the_reader_stops_early() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("p.nc");
    std::fs::write(&p, many_poses(5000)).unwrap();
    let report = dir.path().join("r.json");
    let errors = repo_file("fixtures/errors/zhao2022-xzbc.csv");
    let mut child = Command::new(crate::util::BIN)
        .args(["compensate", "-q", "-e", &errors, "--report"])
        .arg(&report)
        .arg(&p)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert_eq!(first, "G21 G90\n");
    // The pipe is closed here: the rest of the output finds no reader.
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["blocks"].as_array().unwrap().len(), 5000);
}

/// `--work-offset 1e155,1e155,0`: the program's coordinates are bounded,
/// the offset added to them was not, and the IK's arithmetic overflowed
/// into a NaN on which nalgebra's SVD panicked (exit 134).
#[test]
fn a_work_offset_beyond_any_travel_is_refused() {
    let program = "G21 G90\nG43.4 H1\nG1 X10 Y5 Z5 I0 J0 K1 F100\nG49\nM30\n";
    for offset in ["1e155,1e155,0", "1e308,0,0", "-2e6,0,0"] {
        let arg = format!("--work-offset={offset}");
        let (code, _, err) = run_on(&["post", &arg], "s.nc", program);
        assert_eq!(code, 2, "{offset}: {err}");
        assert!(err.contains("beyond any machine's travel"), "{err}");
    }
    let (code, _, err) = run_on(&["post", "--work-offset=1e6,1e6,0"], "s.nc", program);
    assert_eq!(code, 1, "{err}");
}

/// Numbers no machine shows, given to `simulate` and `diagnose` (a
/// helper's hunt): `--round 1e-310` and `cyclic:…,period=1e-320` wrote
/// `inf` and NaN with exit 0, `rotary_center_offset:C=1e308,0,0` wrote
/// `inf`; `--accel 1e-9` ran for minutes before its sample count was
/// refused; `--noise-floor 1e308` hid an injected backlash ("no missing
/// physics found"); `--tool-length 1e308` gave a median of `inf` mm. Each
/// is a bad command line now (exit 2) naming the option and its range.
#[test]
fn numbers_no_machine_shows_are_refused() {
    let program =
        std::fs::read_to_string(repo_file("fixtures/programs/zhao2022-xzbc.ngc")).unwrap();
    let bad: [(&[&str], &str); 9] = [
        (&["--round", "1e-310"], "--round"),
        (
            &["--inject", "cyclic:X=0.002,period=1e-320,phase=0"],
            "cyclic period",
        ),
        (&["--inject", "rotary_center_offset:C=1e308,0,0"], "offset"),
        (&["--inject", "backlash:X=-1"], "backlash"),
        (&["--inject", "servo_lag:X=1e3"], "servo_lag"),
        (&["--inject", "backlash:X=1e308"], "backlash"),
        (&["--accel", "1e-9"], "--accel"),
        (&["--accel", "1e-320"], "--accel"),
        (&["--tool-length", "1e308"], "--tool-length"),
    ];
    for (extra, what) in bad {
        let mut args = vec!["simulate"];
        args.extend_from_slice(extra);
        args.push("-p");
        let (code, out, err) = run_on(&args, "p.nc", &program);
        assert_eq!(code, 2, "{extra:?}: {err}");
        assert!(err.contains(what), "{extra:?}: {err}");
        assert!(out.is_empty());
    }
    // The sizes a machine shows still run.
    let args = [
        "simulate",
        "--round",
        "1e-6",
        "--accel",
        "1",
        "--inject",
        "backlash:X=0.003",
        "-p",
    ];
    let (code, recording, err) = run_on(&args, "p.nc", &program);
    assert_eq!(code, 0, "{err}");
    // diagnose: a noise floor beyond 10 mm is refused.
    let (code, _, err) = run_on(
        &["diagnose", "--noise-floor", "1e308", "-r"],
        "r.csv",
        &recording,
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--noise-floor must be above 0 and at most 10 mm"),
        "{err}"
    );
}

/// NX's Haas post: a 3+2 section under `G254` (a work offset that turns
/// with the rotaries) in a program that also holds `G234` poses.
/// `simulate` and `analyze --nonlinear` left its moves out with exit 0
/// (the recording went on from the next pose, the warning blaming G28 or
/// G53); without the poses the same moves are refused. They are refused
/// alike now; `post` passes them on as they are.
#[test]
fn moves_under_a_frame_in_a_pose_program_are_refused() {
    let program = "G20 G90 G17\nG0 X0 Y0 Z2. B0 C0\nG0 B90. C0.\nG254\nG1 X1. Y0. Z2. F10.\nG1 X2. C30.\nG255\nG234 H1\nG1 X1. Y1. Z1. B0 C0 F10.\nG49\nM30\n";
    for args in [
        &["simulate", "-m", "xyzbc-trt", "-p"][..],
        &["analyze", "--nonlinear", "-m", "xyzbc-trt"][..],
    ] {
        let (code, _, err) = run_on(args, "t.nc", program);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(
            err.contains("t.nc:5:4: a move under a frame"),
            "{args:?}: {err}"
        );
        assert!(err.contains("G254"), "{err}");
    }
    let (code, out, err) = run_on(&["post", "-m", "xyzbc-trt"], "t.nc", program);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("G254\nG1 X1. Y0. Z2. F10.\nG1 X2. C30.\nG255\n"),
        "{out}"
    );
    // The linkage names the frame among the causes.
    let (code, _, err) = run_on(&["linkage", "-m", "xyzbc-trt"], "t.nc", program);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("an axis moved under a frame such as G68 or G254"),
        "{err}"
    );
}

/// `linkage` on APT CL refused it without naming the file.
#[test]
fn linkage_names_the_cl_file_it_refuses() {
    let cl = std::fs::read_to_string(repo_file("fixtures/programs/zhao2022-xzbc.cls")).unwrap();
    let (code, _, err) = run_on(&["linkage"], "part.cls", &cl);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("part.cls: APT CL; linkage reads G-code"),
        "{err}"
    );
}

/// `-o nodir/` gave the system's "Not a directory (os error 20)", and `-o
/// p.nc/x` (p.nc a file) said its directory did not exist.
#[test]
fn an_output_path_that_cannot_be_a_file_says_why() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("p.nc"), many_poses(3)).unwrap();
    for (target, says) in [
        (
            "nodir/",
            "nodir/: cannot be written: a path ending in `/` names a directory",
        ),
        (
            "p.nc/x",
            "p.nc/x: cannot be written: p.nc is a file, not a directory",
        ),
        (
            "missing/x",
            "missing/x: cannot be written: its directory does not exist",
        ),
    ] {
        let out = std::process::Command::new(crate::util::BIN)
            .current_dir(dir.path())
            .args(["post", "p.nc", "-o", target])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(3), "{target}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{target}: {err}");
    }
}

/// Messages that misled: `analyze --pose-start on -e E` on a program
/// with an `o`-word said the program "is in machine axes" (no file, wrong
/// advice) where `post` refuses the `o`-word at its place; `linkage
/// --tolerance` printed its planning tolerance (85 % of the one given)
/// with every digit (330 of them for 1e-320); `simulate --noise 1e-320`
/// printed 320 zeros.
#[test]
fn messages_name_the_cause_and_the_numbers_given() {
    let errors = repo_file("fixtures/errors/zhao2022-xzbc.csv");
    let program = "G21 G90\no100 if [1 GT 0]\no100 endif\nG1 X30 Y0 Z5 F100\nG1 X31 Y1 Z5\nM30\n";
    let (code, _, err) = run_on(
        &["analyze", "--pose-start", "on", "-e", &errors],
        "p4.nc",
        program,
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("p4.nc:2:1:"), "{err}");
    assert!(!err.contains("machine axes"), "{err}");
    let wang = std::fs::read_to_string(repo_file("fixtures/programs/wang2023-xyzab.ngc")).unwrap();
    let args = ["linkage", "-m", "wang2023-xyzab", "--tolerance", "1e-9"];
    let (code, _, err) = run_on(&args, "w.ngc", &wang);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("within the tolerance 1e-9 mm (planned to 85 % of it)"),
        "{err}"
    );
    let zhao = std::fs::read_to_string(repo_file("fixtures/programs/zhao2022-xzbc.ngc")).unwrap();
    let (code, _, err) = run_on(&["simulate", "--noise", "1e-320", "-p"], "z.nc", &zhao);
    assert_eq!(code, 0, "{err}");
    let noise = err
        .split("noise σ = ")
        .nth(1)
        .unwrap()
        .split(" µm")
        .next()
        .unwrap();
    assert!(noise.len() < 20 && noise.contains("e-3"), "{err}");
}
