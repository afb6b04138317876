//! Twenty-second hunt (session 38, `docs/robustness.md`): CAMWorks and
//! CATIA APT from public repositories not used before, and recordings as
//! loggers write them. Each test failed on the session's first build
//! (78ea2b4).

use crate::util::run_on;

const HOLE: &str = "UNITS/MM\nLOAD/TOOL,1\nRAPID\nGOTO/10,0,50\nCYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,3,RTRCTO,50\nGOTO/10,0,0\n";

/// A cycle left in force (CAMWorks writes no `CYCLE/OFF` before the next
/// operation) made every later `GOTO` a hole: the end mill's contour was
/// drilled 7.65 mm below the pocket's floor, and an arc started from the
/// hole's retract level became a helix, exit 0. An arc and a tool change
/// under a cycle are refused now, naming the cycle's line.
#[test]
fn motions_of_another_kind_under_a_cycle_are_refused() {
    let cases = [
        (
            "CIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n",
            "p.apt:7:1: CIRCLE while the cycle of line 5 is in force",
        ),
        (
            "LOAD/TOOL,2\nGOTO/30,0,20\n",
            "p.apt:7:1: LOAD/TOOL while the cycle of line 5 is in force",
        ),
        (
            "LOADTL/2\nGOTO/30,0,20\n",
            "p.apt:7:1: LOADTL while the cycle of line 5 is in force",
        ),
    ];
    for (rest, want) in cases {
        let program = format!("{HOLE}{rest}CYCLE/OFF\nFINI\n");
        for command in ["post", "compensate"] {
            let mut args = vec![command, "-m", "xyzac-trt"];
            if command == "compensate" {
                args.extend(["-e", "fixtures/errors/wang2023-xyzab.csv"]);
                args[2] = "wang2023-xyzab";
            }
            let (code, out, err) = run_on(&args, "p.apt", &program);
            assert_eq!(code, 1, "{command} {rest:?}: {out}");
            assert!(err.contains(want), "{command} {rest:?}: {err}");
        }
        // With the cycle ended first, the same motions are converted.
        let ended = format!("{HOLE}CYCLE/OFF\n{rest}FINI\n");
        let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", &ended);
        assert_eq!(code, 0, "{rest:?}: {err}");
        assert_eq!(out.matches("G81").count(), 1, "{out}");
    }
}

/// CAMWorks writes a pattern's copies as the same `SETUP/START,n` again
/// under another `CSYS`, with the points already placed in the CL frame:
/// read in the `CSYS` frame, all three copies of a nested plate were
/// drilled where the first is, exit 0. Refused now; a set-up number seen
/// again under the same `CSYS`, and `CSYS` without `SETUP`, read as before.
#[test]
fn a_setup_copied_under_another_csys_is_refused() {
    let copy = |csys: &str, x: f64| {
        format!(
            "TRNTYP/WORLD,0,0,0\nCSYS/{csys}\nSETUP/START,2\nRAPID\nGOTO/{x},90,25\nGOTO/{x},90,0\nSETUP/END,2\n"
        )
    };
    let identity = "1.,0,0,0,0,1.,0,0,0,0,1.,0";
    let turned = "-1.,0,0,456.34944,0,-1.,0,197.0266,0,0,1.,0";
    let program = format!(
        "UNIT/MM\nLOAD/TOOL,18\n{}{}FINI\n",
        copy(identity, 160.9),
        copy(turned, 295.4)
    );
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", &program);
    assert_eq!(code, 1, "{out}");
    assert!(
        err.contains("p.apt:12:1: SETUP/START,2 again under another CSYS than at line 5"),
        "{err}"
    );
    // The same set-up twice in the same frame: both passes converted.
    let program = format!(
        "UNIT/MM\nLOAD/TOOL,18\n{}{}FINI\n",
        copy(turned, 295.4),
        copy(turned, 295.4)
    );
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", &program);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.matches("X160.9494 Y107.0266").count(), 4, "{out}");
}

/// CATIA wraps long `PPRINT` lines at 72 columns with the continuation
/// `$`; kinpost read a final `$` of literal text as text, so the wrapped
/// part was refused as a statement ("expected an APT statement"), and a
/// wrapped `END` or `STOP` became `M2` or `M0` in the middle of the
/// program, exit 0. Text after the `$` continues the statement now; a
/// statement after it (`GOTO/…`) is read as one; a bare word, which could
/// be either, is refused.
#[test]
fn literal_text_continued_over_lines() {
    let catia = "UNITS/MM\nPPRINT/(=====$\n=======) \nPPRINT/(USING .250\" DIAM. O$\nRIFICE ) \nLOADTL/1\nGOTO/1,2,3\nFINI\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", catia);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(PPRINT/[=====$ =======])"), "{out}");
    assert!(out.contains("O$ RIFICE ])"), "{out}");
    assert!(out.contains("X1.0000 Y2.0000 Z3.0000"), "{out}");
    for word in ["END", "STOP", "FINI"] {
        let program = format!(
            "UNITS/MM\nLOADTL/1\nGOTO/0,0,10\nPPRINT/CHECK THE CLAMPS, THEN $\n{word}\nGOTO/10,0,10\nFINI\n"
        );
        let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", &program);
        assert_eq!(code, 1, "{word}: {out}");
        assert!(
            err.contains(&format!("p.apt:5:1: the statement at line 4 holds text and ends with `$`, and this line is the bare word {word}")),
            "{err}"
        );
    }
    // A statement after the `$`: the `$` is text, as before.
    let program = "UNITS/MM\nLOADTL/1\nPPRINT/PRICE IN $\nGOTO/1,2,3\nFINI\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", program);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(PPRINT/PRICE IN $)"), "{out}");
    assert!(out.contains("X1.0000 Y2.0000 Z3.0000"), "{out}");
}

/// An axis that stands at exactly 0 all through (a planar job at Z0, an
/// unused axis) has its measured coordinate as noise about 0, which every
/// large step seemed to divide ("0 · q"): `diagnose` read the values as
/// rounded to 12.7 m, took a noise floor of 3.7 m and called a 4 µm
/// backlash measurement noise. A step larger than the smallest gap
/// between the values is no rounding of them; the backlash is found.
#[test]
fn an_axis_at_zero_is_not_read_as_rounded() {
    let dir = tempfile::tempdir().unwrap();
    let mut program = String::from("G21 G90 G17\nG0 X0 Y0 Z0\nF600\n");
    for i in 0..60 {
        let a = i as f64 * 2.39996;
        program.push_str(&format!(
            "G1 X{:.3} Y{:.3}\n",
            20.0 * a.cos() * (1.0 + 0.3 * (3.0 * a).sin()),
            20.0 * a.sin()
        ));
    }
    program.push_str("M2\n");
    let p = dir.path().join("flat.ngc");
    std::fs::write(&p, program).unwrap();
    let rec = dir.path().join("r.csv");
    let run = |args: &[&str]| {
        std::process::Command::new(crate::util::BIN)
            .args(args)
            .output()
            .unwrap()
    };
    let sim = run(&[
        "simulate",
        "-m",
        "xyz-3axis",
        "-p",
        p.to_str().unwrap(),
        "--inject",
        "backlash:X=0.004",
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let out = run(&["diagnose", "-m", "xyz-3axis", "-r", rec.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!text.contains("values rounded"), "{text}");
    assert!(text.contains("1. backlash X: value = "), "{text}");
}

/// A joint-feedback trace whose only fault is its clock: the delay every
/// axis shares was estimated from its linear term, 19.76 ms of 20 (the
/// command's acceleration biases it), and the 0.24 ms left was reported as
/// servo lags of C and X, or at 0.1 s sampling as a zero offset of C or
/// an unexplained mismatch. The delay the axes still share after the
/// alignment is now added to the clock's: no machine physics is claimed.
#[test]
fn a_clock_offset_alone_claims_no_servo_lag() {
    let program = crate::util::repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc");
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("r.csv");
    let rec = rec.to_str().unwrap();
    for (interval, offset, seed) in [("0.01", "0.02", "1"), ("0.1", "0.015", "2")] {
        let sim = std::process::Command::new(crate::util::BIN)
            .args([
                "simulate",
                "-m",
                "zhao2022-xzbc",
                "-p",
                &program,
                "--feedback",
            ])
            .args(["--noise", "0.0005", "--sample-interval", interval])
            .args(["--time-offset", offset, "--seed", seed, "-o", rec])
            .output()
            .unwrap();
        assert!(
            sim.status.success(),
            "{}",
            String::from_utf8_lossy(&sim.stderr)
        );
        let out = std::process::Command::new(crate::util::BIN)
            .args(["diagnose", "-m", "zhao2022-xzbc", "-r", rec])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            text.contains("time_offset: offset = "),
            "{interval}: {text}"
        );
        assert!(
            text.contains("verdict: consistent with measurement noise"),
            "{interval}: {text}"
        );
    }
}

/// `--sample-rate 1e-300` and `0.001` were accepted: a joint-feedback
/// trace's time stretched so far that a 4 ms servo lag was reported as a
/// backlash of 110 µm. Refused below 0.1 Hz, naming the range.
#[test]
fn a_sample_rate_no_drive_trace_has_is_refused() {
    for rate in ["1e-300", "0.001", "0"] {
        let (code, _, err) = run_on(
            &[
                "diagnose",
                "-m",
                "zhao2022-xzbc",
                "--sample-rate",
                rate,
                "-r",
            ],
            "trace.csv",
            "X,fb_X\n0,0\n",
        );
        assert_eq!(code, 2, "{rate}: {err}");
        assert!(
            err.contains("--sample-rate must be 0.1 … 1e7 Hz"),
            "{rate}: {err}"
        );
    }
}

/// CATIA writes `FROM` (where the tool starts) before `LOADTL`: it was
/// written as a rapid before `T1 M6` and `G43 H1`, without tool length
/// compensation, so the tip went a tool length past the point. Before the
/// first tool change it is a comment now; after one, a rapid as before.
#[test]
fn from_before_the_tool_change_is_no_rapid() {
    let program =
        "UNITS/MM\nFROM/0,0,100\nLOADTL/1\nFEDRAT/100,MMPM\nGOTO/1,2,3\nFROM/0,0,50\nFINI\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", program);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let tool = lines.iter().position(|l| *l == "T1 M6").unwrap();
    assert!(lines[..tool].contains(&"(FROM/0,0,100)"), "{out}");
    assert!(!lines[..tool].iter().any(|l| l.starts_with("G0")), "{out}");
    assert!(out.contains("G0 X0.0000 Y0.0000 Z50.0000"), "{out}");
}

/// Heidenhain ISO's `M128` in a program read as machine axes: `linkage`
/// and `analyze` advised converting it with `kinpost post` first, which
/// passes M128 programs on unconverted (the control converts them), so
/// the advice led back to the same refusal. It names what to do now.
#[test]
fn m128_refusal_does_not_send_the_user_round_in_a_circle() {
    let program = "%1001 G71 *\nN30 T1 G17 S5000 *\nN40 G00 G40 G90 Z+100 M03 *\nN50 G01 X+10 Y+10 Z+5 B+0 C+0 F500 M128 *\nN60 G01 X+20 Y+10 Z+5 B+10 C+0 *\nN70 M129 *\nN80 G00 Z+100 M02 *\nN99999 %1001 G71 *\n";
    for args in [
        &["linkage", "-m", "xyzbc-trt"][..],
        &["analyze", "--nonlinear", "-m", "xyzbc-trt"][..],
    ] {
        let (code, _, err) = run_on(args, "p.h", program);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(err.contains("p.h:4:36: tool centre point control"), "{err}");
        assert!(
            err.contains("`kinpost post` passes them on unconverted"),
            "{err}"
        );
        assert!(
            !err.contains("convert the program with `kinpost post` first"),
            "{err}"
        );
    }
    // post passes the program on as it is.
    let (code, out, err) = run_on(&["post", "-m", "xyzbc-trt"], "p.h", program);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, program);
}

/// A recording row with a value more than the header has fields was read
/// silently (its last value dropped), while a row with one fewer is
/// refused; a shifted row then gave a later, misleading error. Refused
/// now at the extra value, in tool-tip and joint-feedback recordings; a
/// trailing separator (an empty field) stays accepted.
#[test]
fn a_row_longer_than_the_header_is_refused() {
    let mut tip = String::from("t,block,C,X,Z,B,meas_x,meas_y,meas_z\n");
    let mut fb = String::from("t,block,C,X,Z,B,fb_C,fb_X,fb_Z,fb_B\n");
    for i in 0..30 {
        let t = i as f64 * 0.1;
        tip.push_str(&format!("{t:.1},3,0,{t},0,0,{t},0,-20\n"));
        fb.push_str(&format!("{t:.1},3,0,{t},0,0,0,{t},0,0,\n"));
    }
    for (text, extra) in [
        (&tip, "0.5,3,0,0.5,0,0,0.5,0,-20,7\n"),
        (&fb, "0.5,3,0,0.5,0,0,0,0.5,0,0,7\n"),
    ] {
        let (code, _, err) = run_on(&["diagnose", "-m", "zhao2022-xzbc", "-r"], "r.csv", text);
        assert_ne!(code, 1, "{err}");
        assert!(!err.contains("beyond the header"), "{err}");
        let mut lines: Vec<&str> = text.lines().collect();
        lines.insert(7, extra.trim_end());
        let bad = lines.join("\n") + "\n";
        let (code, _, err) = run_on(&["diagnose", "-m", "zhao2022-xzbc", "-r"], "r.csv", &bad);
        assert_eq!(code, 1, "{err}");
        let col = extra.len() - 1;
        assert!(
            err.contains(&format!("r.csv:8:{col}: a value beyond the header's")),
            "{err}"
        );
    }
}

/// `CUTCOM/LEFT` on across a tool change: `G41 D1` stayed in force for
/// tool 2, which was then offset by tool 1's radius, exit 0 (LinuxCNC
/// refuses `M6` under G41). The tool change is refused now.
#[test]
fn a_tool_change_under_cutter_compensation_is_refused() {
    let program = "UNITS/MM\nLOAD/TOOL,1\nFEDRAT/100,MMPM\nGOTO/0,0,0\nCUTCOM/LEFT\nGOTO/10,0,0\nLOAD/TOOL,2\nGOTO/20,0,0\nCUTCOM/OFF\nFINI\n";
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", program);
    assert_eq!(code, 1, "{out}");
    assert!(
        err.contains("p.apt:7:1: LOAD/TOOL while cutter compensation is on"),
        "{err}"
    );
    let off_first = program.replace("LOAD/TOOL,2\n", "CUTCOM/OFF\nLOAD/TOOL,2\n");
    let (code, out, err) = run_on(&["post", "-m", "xyzac-trt"], "p.apt", &off_first);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G40\nT2 M6"), "{out}");
}

/// `--units inch` on a program that says `UNIT/MM` was dropped without a
/// word (the program's own statement is followed, rightly): the user
/// learns now that the option did not apply.
#[test]
fn units_given_and_units_said_differ_with_a_warning() {
    let program = "UNIT/MM\nLOADTL/1\nFEDRAT/100,MMPM\nGOTO/1,2,3\nFINI\n";
    let (code, out, err) = run_on(
        &["post", "-m", "xyzac-trt", "--units", "inch"],
        "p.apt",
        program,
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("X1.0000 Y2.0000 Z3.0000"), "{out}");
    assert!(
        err.contains("p.apt:1:1: the program says its units (mm), which it follows; --units inch applies to a program without a UNITS statement"),
        "{err}"
    );
    let (code, _, err) = run_on(
        &["post", "-m", "xyzac-trt", "--units", "mm"],
        "p.apt",
        program,
    );
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("--units"), "{err}");
}
