//! Twentieth hunt (session 36, `docs/robustness.md`): NX output for a
//! Haas UMC-750 (`G234`, inch) and NX CL data in inch, from a public
//! repository of student projects, with variants. Each test failed on
//! the session's first build (cb8d8fe).

use crate::util::run_on;

/// The time of the last sample of a `simulate` recording (its first
/// column, s).
fn last_time(recording: &str) -> f64 {
    let last = recording.lines().last().unwrap();
    last.split(',').next().unwrap().parse().unwrap()
}

/// A move of rotaries alone runs at F degrees a minute, in G20 as in
/// G21: 40° at F100 take 24 s. `simulate` took F as inches a minute and
/// ran the inch program's turn 25.4 times too fast (0.9 s), exit 0.
#[test]
fn a_turn_alone_in_inch_runs_at_degrees_a_minute() {
    let args = [
        "simulate",
        "-m",
        "xyzbc-trt",
        "--accel",
        "0",
        "--noise",
        "0",
        "-p",
    ];
    for (units, x) in [("G20", "2."), ("G21", "50.8")] {
        let program = format!("{units} G90 G94\nG0 X{x} Y0 Z{x} B0 C0\nG1 C40. F100.\nM30\n");
        let (code, out, err) = run_on(&args, "turn.nc", &program);
        assert_eq!(code, 0, "{err}");
        assert!((last_time(&out) - 24.0).abs() < 1e-9, "{units}: {err}");
    }
    // A linear move in inch still runs at F inches a minute: 10 in at
    // F10 take 60 s.
    let program = "G20 G90 G94\nG0 X0 Y0 Z1. B0 C0\nG1 X10. F10.\nM30\n";
    let (code, out, err) = run_on(&args, "line.nc", program);
    assert_eq!(code, 0, "{err}");
    assert!((last_time(&out) - 60.0).abs() < 1e-9, "{err}");
}

/// `linkage`'s cycle time divided a path in mm by a feed in inches a
/// minute: 10 in at F10 reported 1,524 s instead of 60 s (the feeds it
/// wrote were right).
#[test]
fn the_linkage_cycle_time_of_an_inch_program() {
    let program = "G20 G90 G94\nG0 X0 Y0 Z1 B0 C0\nG1 X10. F10.\nG1 C40. F100.\nM30\n";
    let (code, _, err) = run_on(&["linkage", "-m", "xyzbc-trt"], "inch.nc", program);
    assert_eq!(code, 0, "{err}");
    // 60 s for the line, 24 s for the turn.
    assert!(
        err.contains("cycle time at the programmed feed: 84.000 s before"),
        "{err}"
    );
}

/// NX writes inch CL to 4 decimals (2.54 µm): its arcs have radii up to a
/// few µm apart, and a fixed 1 µm refused 36 of the 144 arcs of one file.
/// The slack follows the data's decimals now (unit test in `cl/arc.rs`).
#[test]
fn an_inch_cl_arc_to_four_decimals_converts() {
    let cl = "UNITS/INCHES\nMULTAX/ON\nRAPID\nGOTO/2.3600,2.2749,3.1000,0.0000000,0.0000000,1.0000000\nFEDRAT/IPM,10.0000\nCIRCLE/2.1643,2.0000,2.9020,0.0000000,0.0000000,-1.0000000,0.3375,0.0060,0.5000,0.7500,0.1200\nGOTO/1.8268,2.0000,2.9020\nFINI\n";
    let (code, out, err) = run_on(&["post", "-m", "xyz-3axis"], "arc.cls", cl);
    assert_eq!(code, 0, "{err}");
    // Clockwise about -Z seen from above: a G2 (or G3 about +Z) to the
    // end point, in mm.
    assert!(out.contains("X46.4007 Y50.8000 Z73.7108"), "{out}");
}

/// `--units` was `post`'s alone, while `compensate`, `analyze` and
/// `simulate` told the user to give it for a CL program without `UNITS`
/// and then refused it.
#[test]
fn every_command_that_reads_cl_takes_units() {
    let cl = "MULTAX/ON\nRAPID\nGOTO/1.0000,0.5000,2.0000,0.0000000,0.3000000,0.9539392\nFEDRAT/IPM,10.0000\nGOTO/1.5000,0.5000,1.5000\nFINI\n";
    let table = "fixtures/errors/wang2023-xyzab.csv";
    let machine = ["-m", "wang2023-xyzab"];
    for command in [
        vec!["compensate", "-e", table],
        vec!["analyze", "-e", table],
        vec!["analyze", "--nonlinear"],
        vec!["simulate", "--noise", "0", "--accel", "0", "-p"],
    ] {
        let mut args = vec![command[0]];
        args.extend(machine);
        args.extend(&command[1..]);
        let (code, _, err) = run_on(&args, "p.cls", cl);
        assert_eq!(code, 1, "{command:?}: {err}");
        assert!(err.contains("--units inch"), "{command:?}: {err}");
        let mut args = vec![command[0], "--units", "inch"];
        args.extend(machine);
        args.extend(&command[1..]);
        let (code, out, err) = run_on(&args, "p.cls", cl);
        assert_eq!(code, 0, "{command:?}: {err}");
        if command[0] == "simulate" {
            // 0.5 in along X and Z at 10 in/min: 0.5·√2 in / 10 in/min.
            // The samples are 0.1 s apart: the last within 0.1 s before.
            let want = 0.5 * 2f64.sqrt() / 10.0 * 60.0;
            let last = last_time(&out);
            assert!(last <= want && want - last < 0.1, "{last} {want}");
        }
    }
}

/// NX's Haas post writes no `G49` before `M30`, and after the closing
/// `%` a line of its own ("Tool Path Listing has 3 lines.", no line end).
/// `post` refused it as a truncated pose block. A controller reads
/// nothing after that `%`: every command passes it through unread.
#[test]
fn text_after_the_closing_percent_passes_unread() {
    let program =
        "%\nO1000\nG234 H1\nG1 X1 Y2 Z3 B10 C20 F100\nM30\n%\nTool Path Listing has 3 lines.";
    let (code, out, err) = run_on(&["post", "-m", "xyzbc-trt"], "nx.nc", program);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.ends_with("M30\n%\nTool Path Listing has 3 lines."),
        "{out}"
    );
    assert!(
        err.contains("nx.nc:7:1: text after the program's closing `%` (line 6) passed on unread"),
        "{err}"
    );
    // A `%` with a name starts a Sinumerik program and ends none: the
    // second program of an archive is read, not passed on unread (its
    // poses come after the first's M30: refused as a subprogram's).
    let pose = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\nTRAFOOF\n";
    let archive = format!("%_N_ONE_MPF\n{pose}M30\n%_N_TWO_MPF\n{pose}M30\n");
    let (code, _, err) = run_on(&["post", "-m", "xyzbc-trt"], "a.arc", &archive);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("a.arc:8:4: a pose after the end of the main program"),
        "{err}"
    );
    // Past the `%` after the main program's end even a pose is not read.
    let after = "G1 X0 Y0 Z100 B0 C0\nM30\n%\nG43.4 H1\nG1 X1 Y2 Z3 I0 J0 K1\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzbc-trt"], "after.nc", after);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, after);
    for args in [
        vec!["linkage", "-m", "xyzbc-trt"],
        vec!["analyze", "--nonlinear", "-m", "xyzbc-trt"],
        vec!["simulate", "-m", "xyzbc-trt", "-p"],
    ] {
        let program = "G0 X0 Y0 Z100 B0 C0\nG1 X10 F100\nM30\n%\nTool Path: C:\\nx\\part.prt";
        let (code, _, err) = run_on(&args, "nx.nc", program);
        assert_eq!(code, 0, "{args:?}: {err}");
    }
}

/// Haas `G187 P1 E0.01` sets the smoothing and its corner tolerance `E`.
/// In pose mode `E` was refused as an extruder or seventh axis.
#[test]
fn haas_smoothing_tolerance_in_pose_mode() {
    let program =
        "G0 X0 Y0 Z50 B0 C0\nG234 H1\nG187 P1 E0.01\nG1 X1 Y0.5 Z1 B10 C20 F100\nG49\nM30\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzbc-trt"], "g187.nc", program);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("\nG187 P1 E0.01\n"), "{out}");
    // An E of its own still is refused.
    let program = program.replace("G187 P1 E0.01", "G1 X2 E0.01");
    let (code, _, err) = run_on(&["post", "-m", "xyzbc-trt"], "e.nc", &program);
    assert_eq!(code, 1);
    assert!(err.contains("e.nc:3:7: `E` in pose mode"), "{err}");
}

/// Inch/mm twins (a helper's metamorphic hunt): `linkage` timed a rapid at
/// the F in force, also where that F is deg/min or inverse time, so its
/// cycle time differed between a program and its inch twin (66 s and
/// 8.4 s; under G93 600 s and 23.6 s). A rapid's speed is the machine's:
/// it is left out now. Its JSON report gave the mm decimals for an inch
/// program, which is written with 6 (`decimals_inch`).
#[test]
fn linkage_times_no_rapid_and_reports_the_inch_decimals() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["linkage", "-m", "xyzac-trt"];
    for (units, x) in [("G21", "100"), ("G20", "3.937007874")] {
        // A turn of 10° at F100 deg/min: 6 s; the rapid after it none.
        let text = format!("{units} G90 G94\nG1 X0 Y0 Z0 A0 C0 F100\nG1 A10\nG0 X{x}\nM30\n");
        let (code, _, err) = run_on(&args, "r.nc", &text);
        assert_eq!(code, 0, "{err}");
        assert!(
            err.contains("programmed feed: 6.000 s before"),
            "{units}: {err}"
        );
        let text = format!("{units} G90 G93\nG1 X0 Y0 Z0 A0 C0 F10\nG94 G0 X{x}\nM30\n");
        let (code, _, err) = run_on(&args, "r.nc", &text);
        assert_eq!(code, 0, "{err}");
        assert!(
            err.contains("programmed feed: 0.000 s before"),
            "{units}: {err}"
        );
    }
    let report = dir.path().join("r.json");
    let mut args = args.to_vec();
    args.extend(["-o", "/dev/null", "--report", report.to_str().unwrap()]);
    let (code, _, err) = run_on(
        &args,
        "p.nc",
        "G20 G90\nG1 X0 Y0 Z0 A0 C0 F10\nG1 X1\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["decimals"][0], serde_json::json!(["X", 4]));
    assert_eq!(json["decimals_inch"][0], serde_json::json!(["X", 6]));
    // A program in mm has no inch decimals to report.
    let (code, _, err) = run_on(
        &args,
        "p.nc",
        "G21 G90\nG1 X0 Y0 Z0 A0 C0 F10\nG1 X1\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(json.get("decimals_inch").is_none(), "{json}");
}
