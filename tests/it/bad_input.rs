//! Bad input, through the binary: every way a program, machine file, error
//! table or recording can be wrong gets a message with file:line:col, the
//! offending text and what was expected, and the documented exit code
//! (1 input, 2 usage, 3 I/O). An error never leaves a half-written output.
//!
//! The cases are listed in `docs/robustness.md`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::util::BIN;

fn fixture(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(rel)
        .display()
        .to_string()
}

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run_in(dir: &Path, args: &[&str]) -> Run {
    let out: Output = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .env_remove("AXIS_PROGRESS_BAR")
        .output()
        .expect("run kinpost");
    Run {
        code: out
            .status
            .code()
            .expect("kinpost exited by a signal (a crash?)"),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// A scratch directory with `files` written into it.
fn dir_with(files: &[(&str, &[u8])]) -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        std::fs::write(d.path().join(name), bytes).unwrap();
    }
    d
}

/// Asserts exit code `code` and that stderr contains every one of `parts`.
#[track_caller]
fn expect(r: &Run, code: i32, parts: &[&str]) {
    assert_eq!(
        r.code, code,
        "exit code: expected {code}, got {}\nstderr: {}",
        r.code, r.stderr
    );
    for p in parts {
        assert!(
            r.stderr.contains(p),
            "stderr lacks {p:?}\nstderr: {}",
            r.stderr
        );
    }
    assert!(!r.stderr.contains("panicked"), "a panic: {}", r.stderr);
}

/// `kinpost post` on a one-file program `text` (named `p.nc` unless it is CL).
fn post(name: &str, text: &[u8], extra: &[&str]) -> Run {
    let d = dir_with(&[(name, text)]);
    let mut args = vec!["post"];
    args.extend_from_slice(extra);
    args.push(name);
    run_in(d.path(), &args)
}

// ---------------------------------------------------------------- programs

#[test]
fn malformed_number_in_a_pose_block() {
    let r = post("p.nc", b"G1 X1.2.3 Y0 Z0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: malformed number `X1.2.3`: more than one decimal point",
            "expected a number such as X12.5",
            "\n  | G1 X1.2.3 Y0 Z0 I0 J0 K1",
        ],
    );
    assert!(r.stdout.is_empty(), "nothing written on error");
}

#[test]
fn malformed_number_later_in_the_block_is_named_not_the_missing_coordinate() {
    let r = post("p.nc", b"G1 Y0 Z0 X1.2.3 I0 J0 K1\n", &[]);
    expect(&r, 1, &["p.nc:1:10: malformed number `X1.2.3`"]);
}

#[test]
fn comma_as_decimal_point() {
    // No tool vector and no TCP code: the program asks for pose mode by option.
    let r = post(
        "p.nc",
        b"G1 X1 Y0 Z0\nG1 X1,5 Y0 Z0\n",
        &["--pose-start", "on"],
    );
    expect(
        &r,
        1,
        &["p.nc:2:4: malformed number `X1,5`: a comma is not a decimal point"],
    );
}

#[test]
fn nan_in_a_pose_block() {
    let r = post("p.nc", b"G1 XNAN Y0 Z0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &["p.nc:1:4: `XNAN` is not a finite number; expected a number"],
    );
}

#[test]
fn infinity_in_a_pose_block() {
    let r = post("p.nc", b"G1 X0 Y0 Z0 I0 J0 K1\nG1 Y-inf\n", &[]);
    expect(&r, 1, &["p.nc:2:4: `Y-inf` is not a finite number"]);
}

#[test]
fn overflow_long_digit_string() {
    let text = format!("G1 X1 Y0 Z0 I0 J0 K1\nG1 X{} Y0 Z0\n", "9".repeat(400));
    let r = post("p.nc", text.as_bytes(), &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:2:4: number out of range `X9999",
            "(400 digits): it does not fit a 64-bit float",
            "expected a coordinate in mm or inch",
            "\n  | G1 X9999",
        ],
    );
}

#[test]
fn exponent_notation_is_not_taken_for_a_number() {
    // `X1e999` is X1 and E999 in G-code; taking it as X1 would be silent data loss.
    let r = post("p.nc", b"G1 X1e999 Y0 Z0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: `X1` is followed directly by `E999`: G-code numbers have no exponent",
            "expected a plain decimal number",
        ],
    );
}

#[test]
fn incremental_moves_that_overflow() {
    let nines = "9".repeat(308);
    let text = format!("G90 G1 X0 Y0 Z0 I0 J0 K1\nG91\nG1 X{nines}\nG1 X{nines}\n");
    let r = post("p.nc", text.as_bytes(), &[]);
    // Once a panic in the solver (NaN in an SVD); now a clean error with a
    // short number (scientific notation), not a 300-digit one.
    expect(
        &r,
        1,
        &[
            "p.nc:3:4: pose unreachable: the tool tip coordinate 1.000e308 mm is beyond any machine's travel",
        ],
    );
    let line = r.stderr.lines().next().unwrap();
    assert!(line.len() < 200, "{line}");
    // The same on the other IK family and for APT CL.
    let r = post("p.nc", text.as_bytes(), &["-m", "wang2023-xyzab"]);
    expect(
        &r,
        1,
        &["p.nc:3:4: pose unreachable: the tool tip coordinate 1.000e308 mm"],
    );
    let cl = format!("GOTO/0,0,0,0,0,1\nGOTO/{nines},0,0\n");
    let r = post("p.cls", cl.as_bytes(), &["-m", "xyzac-trt"]);
    expect(
        &r,
        1,
        &["p.cls:2:1: pose unreachable: the tool tip coordinate 1.000e308 mm"],
    );
}

#[test]
fn nan_and_overflow_in_apt_cl() {
    let r = post("p.cls", b"GOTO/1,2,nan,0,0,1\n", &[]);
    expect(
        &r,
        1,
        &["p.cls:1:10: expected a coordinate (a finite number), found `nan`"],
    );
    let r = post("p.cls", b"GOTO/1,2,1e999\n", &[]);
    expect(
        &r,
        1,
        &["p.cls:1:10: expected a coordinate (a finite number), found `1e999`"],
    );
}

#[test]
fn zero_tool_vector() {
    let r = post("p.nc", b"G1 X1 Y0 Z0 I0 J0 K0\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:13: the tool vector (I, J, K) is zero: expected a unit vector",
            "\n  | G1 X1 Y0 Z0 I0 J0 K0",
        ],
    );
    let r = post("p.cls", b"GOTO/1,2,3,0,0,0\n", &[]);
    expect(
        &r,
        1,
        &["p.cls:1:12: the tool axis has zero length; expected a direction"],
    );
}

#[test]
fn nearly_unit_tool_vector_is_normalised_with_a_warning() {
    let r = post("p.nc", b"G1 X1 Y0 Z0 I0 J0 K1.0005\n", &[]);
    expect(
        &r,
        0,
        &["warning: p.nc:1:4: tool vector of length 1.000500000 normalised to unit length"],
    );
    assert_eq!(r.stdout, "G1 X1.0000 Z20.0000 B0.0000 C0.0000\n");
    let r = post("p.cls", b"GOTO/1,2,3,0,0,1.0004\n", &[]);
    expect(
        &r,
        0,
        &["warning: p.cls:1:1: tool axis of length 1.000400000 normalised to unit length"],
    );
    assert!(r.stdout.contains("G1 X2.2361 Z23.0000"), "{}", r.stdout);
}

#[test]
fn non_unit_tool_vector_is_an_error() {
    let r = post("p.nc", b"G1 X1 Y0 Z0 I0 J0 K1.1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:13: the tool vector (0, 0, 1.1) has length 1.100000, not 1 (tolerance 0.001): expected a unit vector",
        ],
    );
    let r = post("p.cls", b"GOTO/1,2,3,0,0,1.1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.cls:1:1: tool axis of length 1.100000, not 1 (tolerance 0.001): expected a unit vector",
        ],
    );
}

#[test]
fn pose_beyond_linear_axis_limits() {
    let r = post("p.nc", b"G1 X500 Y0 Z0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: axis X would have to move to 500.000000 mm, outside its limits -100 … 100 mm",
            "\n  | G1 X500 Y0 Z0 I0 J0 K1",
        ],
    );
}

#[test]
fn pose_beyond_rotary_axis_limits() {
    let r = post("p.nc", b"G1 X10 Y0 Z0 I0 J0 K-1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: axis B would have to move to -180.000000 deg, outside its limits -90 … 90 deg",
        ],
    );
}

#[test]
fn unreachable_tool_axis_off_the_cone_of_a_four_axis_machine() {
    let r = post("p.nc", b"G1 X10 Y0 Z0 I1 J0 K0\n", &["-m", "xyza-4axis"]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: machine xyza-4axis cannot reach this tool axis",
            "misses it by 1570796.327 µrad (90.000000°), more than the tolerance 100.000 µrad",
        ],
    );
    // Within a wider tolerance the closest reachable axis is accepted.
    let r = post(
        "p.nc",
        b"G1 X10 Y0 Z0 I0.001 J0 K1\n",
        &["-m", "xyza-4axis", "--axis-tolerance-urad", "1001"],
    );
    expect(&r, 0, &["largest tool-axis miss 1000.000 µrad"]);
}

#[test]
fn singular_pose_converts_and_keeps_the_previous_rotary() {
    // Table-table A/C: at K=1 (A = 0) C is free; it keeps the previous 90°.
    let r = post(
        "p.nc",
        b"G1 X10 Y0 Z0 I0.6 J0 K0.8\nG1 X10 Y0 Z0 I0 J0 K1\n",
        &["-m", "xyzac-trt"],
    );
    expect(&r, 0, &["2 poses converted"]);
    let lines: Vec<&str> = r.stdout.lines().collect();
    assert!(lines[0].ends_with("A36.8699 C90.0000"), "{}", r.stdout);
    assert_eq!(lines[1], "G1 X0.0000 Y10.0000 Z0.0000 A0.0000 C90.0000");
}

#[test]
fn program_with_non_utf8_comment_passes_through_byte_for_byte() {
    let r = Command::new(BIN)
        .args(["post", "-q", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .and_then(|mut c| {
            use std::io::Write;
            c.stdin
                .take()
                .unwrap()
                .write_all(b"(caf\xe9 \xff)\nG1 X1 Y0 Z0 I0 J0 K1 (\xfe)\r\n")?;
            c.wait_with_output()
        })
        .unwrap();
    assert_eq!(r.status.code(), Some(0));
    assert_eq!(
        r.stdout,
        b"(caf\xe9 \xff)\nG1 X1.0000 Z20.0000 B0.0000 C0.0000 (\xfe)\r\n".to_vec()
    );
}

#[test]
fn empty_program() {
    let r = post("p.nc", b"", &[]);
    expect(
        &r,
        1,
        &["p.nc:1: the program is empty: expected G-code blocks or APT CL statements"],
    );
}

#[test]
fn arc_in_pose_mode() {
    // The lens machine's C follows the tip: an arc in X Y would turn it.
    let r = post("p.nc", b"G1 X0 Y0 Z0 I0 J0 K1\nG2 X1 Y1 R1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:2:1: the machine reaches a point of this circular move only with its rotary axes turned by 2.500000°",
        ],
    );
    let r = post("p.nc", b"G1 X0 Y0 Z0 I0 J0 K1\nG81 X1 Y1 Z-1 R1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:2:5: a canned cycle, a thread or a spline (G81–G89, G33, G5, Sinumerik ASPLINE, BSPLINE, CSPLINE, POLY) cannot be converted in pose mode",
        ],
    );
}

#[test]
fn first_pose_without_a_full_tip() {
    let r = post("p.nc", b"G1 X1 Y0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &["p.nc:1:4: the tool tip Z is not known yet: the first pose block must give X, Y and Z"],
    );
}

#[test]
fn expression_in_a_pose_block() {
    let r = post("p.nc", b"G1 X[#1+2] Y0 Z0 I0 J0 K1\n", &[]);
    expect(
        &r,
        1,
        &[
            "p.nc:1:4: this block must be converted but holds syntax kinpost does not evaluate (`X[#1+2]`",
        ],
    );
}

// ------------------------------------------------------------ machine files

fn machine(text: &[u8]) -> Run {
    let d = dir_with(&[("m.json", text)]);
    run_in(d.path(), &["machine", "-m", "m.json"])
}

#[test]
fn machine_output_order_names_a_non_joint() {
    let text = std::fs::read_to_string(fixture("machines/zhao2022-xzbc.json"))
        .unwrap()
        .replace(
            r#""output_order": ["X", "Z", "B", "C"]"#,
            r#""output_order": ["X", "Z", "B", "Q"]"#,
        );
    let r = machine(text.as_bytes());
    expect(
        &r,
        1,
        &[
            r#"m.json:18:35: "output_order" names "Q", which is not a joint of the chain; joints are "C", "X", "Z" or "B""#,
            r#"  |   "output_order": ["X", "Z", "B", "Q"]"#,
        ],
    );
}

#[test]
fn machine_file_not_json() {
    let r = machine(b"{\"name\": \"x\",\n  \"chain\": [ }\n");
    expect(
        &r,
        1,
        &[
            "m.json:2:14: machine file is not valid JSON: expected value",
            "\n  |   \"chain\": [ }",
        ],
    );
}

#[test]
fn machine_file_not_utf8() {
    let r = machine(b"{\"name\": \"x\", \xff }");
    expect(
        &r,
        1,
        &[
            "m.json:1:15: byte 0xFF is not UTF-8: expected UTF-8 text",
            "\n  | {\"name\": \"x\", \u{FFFD} }",
        ],
    );
}

#[test]
fn machine_file_empty() {
    let r = machine(b"");
    expect(
        &r,
        1,
        &["m.json:1: the file is empty: expected a machine file (JSON)"],
    );
}

#[test]
fn machine_limit_inverted() {
    let text = std::fs::read_to_string(fixture("machines/zhao2022-xzbc.json"))
        .unwrap()
        .replace(
            r#""min": -100, "max": 100, "decimals": 4}"#,
            r#""min": 100, "max": -100, "decimals": 4}"#,
        );
    let r = machine(text.as_bytes());
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.starts_with("kinpost: error: m.json:"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("\n  | "), "{}", r.stderr);
}

// -------------------------------------------------------------- error tables

#[test]
fn error_table_for_an_axis_the_machine_lacks() {
    let d = dir_with(&[
        ("y.csv", b"Y,EYY\n0,0.001\n10,0.002\n20,0.001\n"),
        ("p.nc", b"G1 X1 Y0 Z0 I0 J0 K1\n"),
    ]);
    let r = run_in(d.path(), &["compensate", "-e", "y.csv", "p.nc"]);
    expect(
        &r,
        1,
        &[
            "y.csv:1:1: the error model has errors for axis Y, which is not a joint of the machine (joints: C, X, Z, B)",
            "\n  | Y,EYY",
        ],
    );
}

#[test]
fn error_model_json_for_an_axis_the_machine_lacks() {
    let d = dir_with(&[
        ("y.csv", b"Y,EYY\n0,0.001\n10,0.002\n20,0.001\n"),
        ("p.nc", b"G1 X1 Y0 Z0 I0 J0 K1\n"),
    ]);
    let r = run_in(d.path(), &["fit", "y.csv", "-o", "y.json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = run_in(d.path(), &["analyze", "-e", "y.json", "p.nc"]);
    expect(&r, 1, &["y.json:", "axis Y, which is not a joint", "\"Y\""]);
    let first = r.stderr.lines().next().unwrap();
    assert!(
        first.starts_with("kinpost: error: y.json:") && first.matches(':').count() >= 4,
        "line and column: {first}"
    );
}

#[test]
fn error_table_malformed_and_infinite_numbers() {
    let d = dir_with(&[
        ("a.csv", b"X,EXX\n0,0.001\n10,abc\n"),
        ("b.csv", b"X,EXX\n0,0.001\n10,1e999\n"),
    ]);
    let r = run_in(d.path(), &["fit", "a.csv"]);
    expect(
        &r,
        1,
        &["a.csv:3:4: column EXX: not a number: `abc`", "\n  | 10,abc"],
    );
    let r = run_in(d.path(), &["fit", "b.csv"]);
    expect(
        &r,
        1,
        &[
            "b.csv:3:4: column EXX: not a finite number (NaN and infinities are not allowed): `1e999`",
        ],
    );
}

#[test]
fn error_table_missing_and_unknown_columns() {
    let d = dir_with(&[
        ("few.csv", b"X,EXX,EYX\n0,0.001\n"),
        ("unk.csv", b"X,EQX\n0,0.001\n"),
    ]);
    let r = run_in(d.path(), &["fit", "few.csv"]);
    expect(
        &r,
        1,
        &["few.csv:2:8: wrong number of fields: 2 found, the header (line 1) has 3"],
    );
    let r = run_in(d.path(), &["fit", "unk.csv"]);
    expect(
        &r,
        1,
        &["unk.csv:1:3: unknown column `EQX`: expected E<direction><axis> such as EXX"],
    );
}

#[test]
fn error_table_not_utf8() {
    let d = dir_with(&[("t.csv", b"X,EXX\n0,0.001\n10,0.002\xff\n")]);
    let r = run_in(d.path(), &["fit", "t.csv"]);
    expect(
        &r,
        1,
        &[
            "t.csv:3:9: byte 0xFF is not UTF-8: expected UTF-8 text",
            "\n  | 10,0.002\u{FFFD}",
        ],
    );
}

#[test]
fn error_table_empty() {
    let d = dir_with(&[("t.csv", b""), ("p.nc", b"G1 X1 Y0 Z0\n")]);
    let r = run_in(d.path(), &["fit", "t.csv"]);
    expect(
        &r,
        1,
        &["t.csv:1:1: no error table found: expected a header line such as `X,EXX,EYX`"],
    );
    let r = run_in(d.path(), &["compensate", "-e", "t.csv", "p.nc"]);
    expect(
        &r,
        1,
        &["t.csv:1: the file is empty: expected an error model"],
    );
}

// ---------------------------------------------------------------- recordings

/// A recording of the exercise program on the model machine (no effects).
fn recording() -> String {
    let d = tempfile::tempdir().unwrap();
    let r = run_in(
        d.path(),
        &[
            "simulate",
            "-e",
            &fixture("errors/zhao2022-xzbc.csv"),
            "-p",
            &fixture("programs/zhao2022-xzbc-exercise.nc"),
            "--noise",
            "0.001",
            "-o",
            "rec.csv",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    std::fs::read_to_string(d.path().join("rec.csv")).unwrap()
}

fn diagnose(rec: &[u8]) -> Run {
    let d = dir_with(&[("r.csv", rec)]);
    run_in(d.path(), &["diagnose", "-r", "r.csv"])
}

#[test]
fn recording_missing_an_axis_column() {
    let rec = recording().replacen("t,block,C,", "t,block,Q,", 1);
    let r = diagnose(rec.as_bytes());
    expect(
        &r,
        1,
        &[
            "r.csv:1:1: the header has no column for machine axis C (the machine's axes: C, X, Z, B)",
            "\n  | t,block,Q,X,Z,B,meas_x,meas_y,meas_z",
        ],
    );
}

#[test]
fn recording_without_meas_z() {
    let rec: String = recording()
        .lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.pop();
            f.join(",") + "\n"
        })
        .collect();
    let r = diagnose(rec.as_bytes());
    expect(
        &r,
        1,
        &["r.csv:1:1: the header has no `meas_z` column (measured tool tip z, mm)"],
    );
}

#[test]
fn recording_time_does_not_increase() {
    let mut lines: Vec<String> = recording().lines().map(str::to_string).collect();
    let rest = lines[9].split_once(',').unwrap().1.to_string();
    lines[9] = format!("0.5,{rest}");
    let r = diagnose((lines.join("\n") + "\n").as_bytes());
    expect(
        &r,
        1,
        &[
            "r.csv:10:1: time must increase: t = 0.5 s after t = 0.7 s",
            "\n  | 0.5,",
        ],
    );
}

#[test]
fn recording_with_a_non_number() {
    // Line 5, field 7 (meas_x).
    let mut lines: Vec<String> = recording().lines().map(str::to_string).collect();
    let mut f: Vec<&str> = lines[4].split(',').collect();
    f[6] = "NaN";
    lines[4] = f.join(",");
    let r = diagnose((lines.join("\n") + "\n").as_bytes());
    expect(
        &r,
        1,
        &["r.csv:5:", "meas_x (mm): `NaN` is not a finite number"],
    );
}

#[test]
fn recording_not_utf8() {
    let mut rec = recording().into_bytes();
    rec.truncate(200);
    let cut = rec.iter().rposition(|&b| b == b'\n').unwrap() + 1;
    rec.truncate(cut);
    rec.extend_from_slice(b"9.9,\xff\n");
    let line = rec.iter().filter(|&&b| b == b'\n').count();
    let r = diagnose(&rec);
    expect(
        &r,
        1,
        &[
            &format!("r.csv:{line}:5: byte 0xFF is not UTF-8"),
            "\n  | 9.9,\u{FFFD}",
        ],
    );
}

#[test]
fn recording_empty_or_too_short() {
    let r = diagnose(b"");
    expect(&r, 1, &["r.csv:1: empty recording: expected a header line"]);
    let rec = recording();
    let short: String = rec.lines().take(4).map(|l| format!("{l}\n")).collect();
    let r = diagnose(short.as_bytes());
    expect(
        &r,
        1,
        &["r.csv: the recording has 3 samples; a diagnosis needs at least 20"],
    );
}

// ------------------------------------------------------ files and directories

#[test]
fn a_directory_given_as_a_file() {
    let d = dir_with(&[]);
    std::fs::create_dir(d.path().join("sub")).unwrap();
    for args in [
        &["post", "sub"][..],
        &["machine", "-m", "sub"],
        &["fit", "sub"],
        &["compensate", "-e", "sub", "-"],
        &["diagnose", "-r", "sub"],
    ] {
        let r = run_in(d.path(), args);
        expect(
            &r,
            3,
            &["kinpost: error: sub: is a directory; expected a file"],
        );
    }
}

#[test]
fn a_file_that_does_not_exist() {
    let d = dir_with(&[]);
    for (args, name) in [
        (&["post", "no.nc"][..], "no.nc"),
        (&["fit", "no.csv"], "no.csv"),
        (&["compensate", "-e", "no.csv", "-"], "no.csv"),
        (&["diagnose", "-r", "no.csv"], "no.csv"),
        (&["analyze", "--nonlinear", "no.nc"], "no.nc"),
    ] {
        let r = run_in(d.path(), args);
        expect(
            &r,
            3,
            &[&format!(
                "kinpost: error: {name}: No such file or directory"
            )],
        );
    }
    let r = run_in(d.path(), &["machine", "-m", "dir/no.json"]);
    expect(
        &r,
        3,
        &["kinpost: error: dir/no.json: no such machine file (embedded machines: zhao2022-xzbc"],
    );
}

// ------------------------------------------------------------- option values

#[test]
fn bad_option_values_are_usage_errors() {
    let d = dir_with(&[("p.nc", b"G1 X1 Y0 Z0\n")]);
    let cases: &[(&[&str], &str)] = &[
        (
            &["post", "--decimals", "20", "p.nc"],
            "invalid value '20' for '--decimals <N>'",
        ),
        (
            &["post", "--axis-tolerance-urad", "abc", "p.nc"],
            "invalid value 'abc' for '--axis-tolerance-urad <URAD>'",
        ),
        (
            &["post", "--axis-tolerance-urad=-1", "p.nc"],
            "--axis-tolerance-urad -1: expected a tolerance of 0 … 3.2e6 µrad",
        ),
        (
            &["post", "--axis-tolerance-urad=NaN", "p.nc"],
            "--axis-tolerance-urad NaN: expected a tolerance of 0 … 3.2e6 µrad",
        ),
        (
            &["post", "--axis-tolerance-urad=inf", "p.nc"],
            "--axis-tolerance-urad inf: expected a tolerance of 0 … 3.2e6 µrad",
        ),
        (
            &[
                "simulate",
                "--axis-tolerance-urad=1e300",
                "--program",
                "p.nc",
            ],
            "--axis-tolerance-urad 1e300: expected a tolerance of 0 … 3.2e6 µrad",
        ),
        (
            &["post", "--pose-start", "sometimes", "p.nc"],
            "invalid value 'sometimes' for '--pose-start <POSE_START>'",
        ),
        (
            &["post", "-m", "no-such-machine", "p.nc"],
            "--machine no-such-machine: no such file, and no embedded machine of that name",
        ),
        (
            &["compensate", "-e", "x.csv", "--tip-tolerance-mm=0", "p.nc"],
            "--tip-tolerance-mm must be > 0",
        ),
        (
            &[
                "compensate",
                "-e",
                "x.csv",
                "--axis-weights",
                "1,-1,1",
                "p.nc",
            ],
            "invalid value '1,-1,1' for '--axis-weights <WX,WY,WZ>': weights must be finite and ≥ 0",
        ),
        (
            &["compensate", "-e", "x.csv", "--axis-weights", "1,1", "p.nc"],
            "2 values; expected three numbers WX,WY,WZ",
        ),
        (
            &[
                "compensate",
                "-e",
                "x.csv",
                "--axis-weights",
                "1,x,1",
                "p.nc",
            ],
            "invalid float literal; expected three numbers",
        ),
        (
            &["compensate", "p.nc"],
            "the following required arguments were not provided",
        ),
        (
            &["linkage", "--tolerance=-1", "p.nc"],
            "--tolerance -1: expected a length > 0 mm",
        ),
        (
            &["linkage", "--insert", "3", "p.nc"],
            "the staggered pattern inserts an even number of points",
        ),
        (
            &["linkage", "--max-axes", "9", "p.nc"],
            "invalid value '9' for '--max-axes <N>'",
        ),
        (
            &["linkage", "--split-axis", "X", "p.nc"],
            "--split-axis X: not a rotary axis",
        ),
        (
            &["simulate", "-p", "p.nc", "--noise=-1"],
            "--noise -1: expected a standard deviation of 0 … 10 mm",
        ),
        (
            &["simulate", "-p", "p.nc", "--sample-interval", "0"],
            "--sample-interval 0: expected 1e-6 … 3600 s",
        ),
        (
            &["simulate", "-p", "p.nc", "--accel=-5"],
            "--accel -5: expected 0 (constant feed per block) or an acceleration of 1 … 1e6 mm/s²",
        ),
        (&["simulate", "-p", "p.nc", "--inject", "warp:X=1"], "warp"),
        (
            &["diagnose", "-r", "r.csv", "--noise-floor", "0"],
            "--noise-floor must be above 0 and at most 10 mm",
        ),
        (
            &["analyze", "p.nc"],
            "analyze needs --errors MODEL (or --nonlinear)",
        ),
        (
            &["completions", "tcsh"],
            "invalid value 'tcsh' for '<SHELL>'",
        ),
        (&["frobnicate"], "unrecognized subcommand 'frobnicate'"),
    ];
    for (args, msg) in cases {
        let r = run_in(d.path(), args);
        assert_eq!(r.code, 2, "{args:?}: exit {} — {}", r.code, r.stderr);
        assert!(
            r.stderr.contains(msg),
            "{args:?}: stderr lacks {msg:?}: {}",
            r.stderr
        );
    }
}

// --------------------------------------------- an error leaves outputs alone

const OLD: &[u8] = b"previous contents\n";

/// Runs `args` in `d` where every path in `outputs` holds [`OLD`]; asserts
/// failure with `code`, every output untouched and no temporary left over.
#[track_caller]
fn assert_outputs_untouched(d: &Path, args: &[&str], outputs: &[&str], code: i32) -> Run {
    for o in outputs {
        std::fs::write(d.join(o), OLD).unwrap();
    }
    let before: Vec<PathBuf> = entries(d);
    let r = run_in(d, args);
    assert_eq!(r.code, code, "{args:?}: {}", r.stderr);
    for o in outputs {
        assert_eq!(
            std::fs::read(d.join(o)).unwrap(),
            OLD,
            "{o} was touched by {args:?}"
        );
    }
    assert_eq!(entries(d), before, "{args:?} left files behind");
    r
}

fn entries(d: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

/// A long pose program whose last block is bad.
fn lens_with_bad_tail() -> Vec<u8> {
    let text = std::fs::read_to_string(fixture("programs/zhao2022-lens.nc")).unwrap();
    let at = text
        .rfind("\nM")
        .expect("the lens program ends with an M code")
        + 1;
    let mut p = text.into_bytes();
    p.splice(at..at, b"G1 X1 Y0 Z0 I0 J0 K0\n".iter().copied());
    p
}

#[test]
fn post_error_leaves_output_untouched() {
    let d = dir_with(&[("p.nc", &lens_with_bad_tail())]);
    let r = assert_outputs_untouched(d.path(), &["post", "p.nc", "-o", "out.nc"], &["out.nc"], 1);
    assert!(
        r.stderr.contains("the tool vector (I, J, K) is zero"),
        "{}",
        r.stderr
    );
    // And on standard output nothing at all is written.
    let r = run_in(d.path(), &["post", "p.nc"]);
    assert_eq!(r.code, 1);
    assert!(r.stdout.is_empty(), "half a program on stdout");
}

#[test]
fn compensate_error_leaves_output_and_report_untouched() {
    let d = dir_with(&[("p.nc", &lens_with_bad_tail())]);
    let errors = fixture("errors/zhao2022-xzbc.csv");
    assert_outputs_untouched(
        d.path(),
        &[
            "compensate",
            "-e",
            &errors,
            "p.nc",
            "-o",
            "out.nc",
            "--report",
            "rep.json",
        ],
        &["out.nc", "rep.json"],
        1,
    );
}

#[test]
fn linkage_error_leaves_output_and_report_untouched() {
    let text = std::fs::read_to_string(fixture("programs/wang2023-impeller.nc")).unwrap();
    let p = text
        .replace("G49\nM30\n", "X1.2.3 Y0 Z0\nG49\nM30\n")
        .into_bytes();
    assert_ne!(p, text.as_bytes(), "the fixture ends with G49 M30");
    let d = dir_with(&[("p.nc", &p)]);
    let r = assert_outputs_untouched(
        d.path(),
        &[
            "linkage",
            "-m",
            "wang2023-xyzab",
            "p.nc",
            "-o",
            "out.nc",
            "--report",
            "rep.json",
        ],
        &["out.nc", "rep.json"],
        1,
    );
    assert!(
        r.stderr.contains("malformed number `X1.2.3`"),
        "{}",
        r.stderr
    );
}

#[test]
fn fit_error_leaves_model_untouched() {
    let mut t = std::fs::read(fixture("errors/zhao2022-xzbc.csv")).unwrap();
    t.extend_from_slice(b"12.5,oops\n");
    let d = dir_with(&[("t.csv", &t)]);
    assert_outputs_untouched(
        d.path(),
        &["fit", "t.csv", "-o", "model.json"],
        &["model.json"],
        1,
    );
}

#[test]
fn diagnose_error_leaves_svg_and_model_untouched() {
    let mut rec = recording();
    rec.push_str("0.0,1,0,0,0,0,0,0,0\n"); // time going back, at the very end
    let d = dir_with(&[("r.csv", rec.as_bytes())]);
    assert_outputs_untouched(
        d.path(),
        &[
            "diagnose",
            "-r",
            "r.csv",
            "--svg",
            "d.svg",
            "--write-model",
            "m.json",
        ],
        &["d.svg", "m.json"],
        1,
    );
}

#[test]
fn simulate_and_analyze_errors_leave_outputs_untouched() {
    let d = dir_with(&[("p.nc", &lens_with_bad_tail())]);
    let errors = fixture("errors/zhao2022-xzbc.csv");
    assert_outputs_untouched(
        d.path(),
        &["simulate", "-e", &errors, "-p", "p.nc", "-o", "rec.csv"],
        &["rec.csv"],
        1,
    );
    assert_outputs_untouched(
        d.path(),
        &["analyze", "-e", &errors, "p.nc", "--svg", "a.svg"],
        &["a.svg"],
        1,
    );
}

#[test]
fn output_into_a_missing_directory_is_an_io_error() {
    let d = dir_with(&[("p.nc", b"G1 X1 Y0 Z0 I0 J0 K1\n")]);
    let r = run_in(d.path(), &["post", "p.nc", "-o", "nodir/out.nc"]);
    expect(
        &r,
        3,
        &["kinpost: error: nodir/out.nc: cannot be written: its directory does not exist"],
    );
    // Checked before any work: the first output is not committed when the
    // second cannot be written.
    let errors = fixture("errors/zhao2022-xzbc.csv");
    let r = assert_outputs_untouched(
        d.path(),
        &[
            "compensate",
            "-e",
            &errors,
            "p.nc",
            "-o",
            "out.nc",
            "--report",
            "nodir/r.json",
        ],
        &["out.nc"],
        3,
    );
    expect(&r, 3, &["nodir/r.json: cannot be written"]);
    std::fs::create_dir(d.path().join("sub")).unwrap();
    let r = run_in(d.path(), &["post", "p.nc", "-o", "sub"]);
    expect(
        &r,
        3,
        &["kinpost: error: sub: is a directory; expected a file to write"],
    );
}

#[test]
fn absurd_simulate_numbers_are_a_bad_command_line() {
    // Before: 1e-320 gave 0 samples and 1e308 noise wrote `inf`, both exit 0.
    let program = fixture("programs/zhao2022-xzbc-exercise.nc");
    let d = dir_with(&[]);
    for (option, value, says) in [
        ("--sample-interval", "1e-320", "expected 1e-6 … 3600 s"),
        ("--sample-interval", "0", "expected 1e-6 … 3600 s"),
        (
            "--noise",
            "1e308",
            "expected a standard deviation of 0 … 10 mm",
        ),
        (
            "--noise",
            "20",
            "expected a standard deviation of 0 … 10 mm",
        ),
        ("--accel", "1e300", "or an acceleration of 1 … 1e6 mm/s²"),
        ("--rapid-feed", "1e300", "at most 1e6 mm/min"),
    ] {
        let r = run_in(
            d.path(),
            &["simulate", "-p", &program, option, value, "-o", "rec.csv"],
        );
        expect(&r, 2, &[&format!("{option} {value}"), says]);
        assert!(!d.path().join("rec.csv").exists());
    }
}

#[test]
fn unreachable_tool_axis_is_refused_by_every_command_that_posts() {
    // Before: post refused this pose, but compensate, simulate and analyze
    // wrote or used axes 90° off the programmed tool axis, with exit 0.
    let program = b"G43.5 H1\nG1 X40 Y0 Z5 I0 J0 K1 F100\nG1 X40 Y0 Z5 I0 J1 K0\nM30\n";
    let d = dir_with(&[("p.nc", program)]);
    let errors = fixture("errors/zhao2022-xzbc.csv");
    for args in [
        vec!["post", "p.nc"],
        vec!["compensate", "-e", &errors, "p.nc"],
        vec!["simulate", "-p", "p.nc", "-o", "rec.csv"],
        vec!["analyze", "-e", &errors, "p.nc"],
    ] {
        let r = run_in(d.path(), &args);
        expect(
            &r,
            1,
            &[
                "p.nc:3:",
                "machine zhao2022-xzbc cannot reach this tool axis",
                "more than the tolerance 100.000 µrad (--axis-tolerance-urad)",
            ],
        );
        assert!(r.stdout.is_empty(), "{args:?} wrote {}", r.stdout);
    }
    assert!(!d.path().join("rec.csv").exists());
    // The same tolerance option widens it everywhere.
    for args in [
        vec![
            "compensate",
            "-e",
            &errors,
            "p.nc",
            "--axis-tolerance-urad",
            "2e6",
        ],
        vec!["post", "p.nc", "--axis-tolerance-urad", "2e6"],
    ] {
        let r = run_in(d.path(), &args);
        assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    }
}

#[test]
fn nearly_unit_tool_vectors_are_normalised_quietly_with_one_summary() {
    // CAM output printed to 6 decimals is off by about 1e-6: one summary
    // line, not a warning per block; the embedded machine is named.
    let r = post(
        "p.nc",
        b"G1 X40 Y0 Z5 I0 J0 K1.000001 F100\nG1 X41 Y0 Z5 I0 J0 K0.9999995\n",
        &[],
    );
    expect(
        &r,
        0,
        &[
            "largest deviation of a length from 1: 1.000e-6",
            "note: no --machine given; the poses were converted for the embedded machine zhao2022-xzbc",
        ],
    );
    assert!(!r.stderr.contains("warning"), "{}", r.stderr);
    // With a machine named, no note.
    let r = post(
        "p.nc",
        b"G1 X40 Y0 Z5 I0 J0 K1.000001 F100\n",
        &["--machine", "zhao2022-xzbc"],
    );
    assert!(!r.stderr.contains("note:"), "{}", r.stderr);
}

#[test]
fn analyze_and_simulate_refuse_a_malformed_pose_line() {
    // Before: the line was skipped ("240 poses", exit 0).
    let lens = std::fs::read_to_string(fixture("programs/zhao2022-lens.nc")).unwrap();
    let bad: String = lens
        .lines()
        .enumerate()
        .map(|(i, l)| if i == 19 { l.replacen(".082263857", ".082263857.3", 1) } else { l.to_string() } + "\n")
        .collect();
    assert!(bad.contains("X45.082263857.3"));
    let d = dir_with(&[("p.nc", bad.as_bytes())]);
    let errors = fixture("errors/zhao2022-xzbc.csv");
    for args in [
        vec!["analyze", "-e", &errors, "p.nc"],
        vec!["simulate", "-p", "p.nc", "-o", "rec.csv"],
    ] {
        let r = run_in(d.path(), &args);
        expect(
            &r,
            1,
            &["p.nc:20:1: malformed number `X45.082263857.3`: more than one decimal point"],
        );
    }
    assert!(!d.path().join("rec.csv").exists());
}
