//! APT CL words met on CL data from outside the project: Autodesk's
//! "Common ISO 4343 APT" post (`MODE/MILL` first, `CUTCOM/LEFT, n` with
//! the tool's offset register), NX's NURBS output (`NURBS/`, `KNOT/`,
//! `CNTRL/` between two `GOTO`s, on a real NX CLSF), and words of other
//! dialects and of ISO 4343 that move the tool. Before: `MODE/MILL`
//! refused every such file at line 1; `CUTCOM/LEFT, 3` wrote `G41 D1` (the
//! tool number); the spline and the other words were kept as comments with
//! exit 0, the tool going straight from one `GOTO` to the next.

/// Runs `kinpost post -m xyzbc-trt -` on `cl`: (exit code, stdout, stderr).
fn post(cl: &str) -> (i32, String, String) {
    crate::cl_support::post_stdin("xyzbc-trt", &[], cl)
}

#[test]
fn autodesk_common_apt_mode_and_cutter_compensation_register() {
    let cl = "MODE/MILL\nPARTNO/'1001'\nUNITS/MM\nMULTAX/ON\nLOADTL/1, 0, 60.000000, 1\nSPINDL/5000.000000, RPM, CLW\nRAPID\nGOTO/10.000000, 0.000000, 50.000000, 0.000000000, 0.000000000, 1.000000000\nFEDRAT/500.000000, MMPM\nCUTCOM/LEFT, 3\nGOTO/10.000000, 0.000000, 5.000000, 0.000000000, 0.000000000, 1.000000000\nCUTCOM/OFF\nCUTCOM/RIGHT,XYPLAN\nGOTO/10.000000, 5.000000, 5.000000, 0.000000000, 0.000000000, 1.000000000\nCUTCOM/OFF\nEND\nFINI\n";
    let (code, out, err) = post(cl);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(MODE/MILL)"), "{out}");
    assert!(
        out.contains("\nG41 D3\n"),
        "the register the CL names: {out}"
    );
    assert!(
        out.contains("\nG42 D1\n"),
        "the loaded tool's register: {out}"
    );
    assert!(err.contains("MODE 1"), "counted as a comment: {err}");
    // A lathe mode, or compensation in another plane, is refused.
    let (code, _, err) = post("MODE/TURN\nUNITS/MM\nGOTO/0,0,0\n");
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:1:1:") && err.contains("MODE"),
        "{err}"
    );
    let (code, _, err) = post("UNITS/MM\nCUTCOM/LEFT,YZPLAN\nGOTO/0,0,0\n");
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:2:1:") && err.contains("YZPLAN"),
        "{err}"
    );
}

#[test]
fn nx_nurbs_output_is_refused() {
    // The shape of an NX CLSF with NURBS output: the spline lies between
    // the GOTO before it and the GOTO after it.
    let cl = "TOOL PATH/FIXED_CONTOUR,TOOL,BALL_MILL\nUNITS/MM\nRAPID\nGOTO/0.0000,166.5681,6.8891,0.0000000,0.0000000,1.0000000\nFEDRAT/MMPM,250.0000\nNURBS/\nKNOT/0.0416667,0.3750000,0.6250000,0.9583333,1.0000000\nCNTRL/0.0000,166.2698,6.9401\nCNTRL/0.0000,163.5692,7.2380\nCNTRL/0.0000,159.2589,9.0136\nCNTRL/0.0000,154.6135,13.9021\nGOTO/0.0000,152.7940,23.3200\nEND-OF-PATH\n";
    let (code, out, err) = post(cl);
    assert_eq!(code, 1, "{out}");
    assert!(
        err.contains("<stdin>:6:1:") && err.contains("NURBS"),
        "{err}"
    );
    assert!(out.is_empty());
}

#[test]
fn dialect_words_that_move_the_tool_are_refused() {
    for (word, statement) in [
        ("CYCLE81", "CYCLE81 / 10, 0, 2, -25, 0"),
        ("TLCOMP", "TLCOMP / ON, LEFT"),
        ("CALLSUB", "CALLSUB / 1001"),
        ("RETRCT", "RETRCT"),
        ("PREFUN", "PREFUN/91"),
        ("OPSKIP", "OPSKIP/ON"),
        ("ZSURF", "ZSURF/10"),
    ] {
        let cl = format!("UNITS/MM\nGOTO/0,0,10\n{statement}\nGOTO/10,0,10\nFINI\n");
        let (code, _, err) = post(&cl);
        assert_eq!(code, 1, "{statement}: {err}");
        assert!(
            err.contains("<stdin>:3:1:") && err.contains(word),
            "{statement}: {err}"
        );
    }
}

/// Runs `kinpost post -m xyzbc-trt ARGS -` on `cl`: (exit code, stdout, stderr).
fn post_with(args: &[&str], cl: &str) -> (i32, String, String) {
    crate::cl_support::post_stdin("xyzbc-trt", args, cl)
}

#[test]
fn a_tool_length_in_the_axis_words_is_not_compensated_again() {
    let cl = "UNITS/MM\nLOAD/TOOL,1\nGOTO/0,0,50,0,0,1\nFINI\n";
    // With the job's tool in the chain the axis words put its tip on the
    // point (Z100 for a 50 mm tool); before, `G43 H1` followed, and the
    // controller added the length a second time.
    let (code, out, err) = post_with(&["--tool-length", "50"], cl);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("Z100.0000"), "{out}");
    assert!(!out.contains("\nG43 H1\n"), "{out}");
    assert!(out.contains("\nG49 "), "{out}");
    // Without a tool length the chain ends at the gauge line: the
    // controller's compensation adds the tool (as before).
    let (code, out, err) = post_with(&[], cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("T1 M6\nG43 H1\n") && out.contains("Z50.0000"),
        "{out}"
    );
}

/// Creo comments a statement out over several lines, each ended with the
/// continuation `$` inside the comment (`$$-> CSYS / …,  $`, then lines of
/// numbers): the numbers go on with the comment. A `$` at the end of an
/// ordinary comment does not swallow the statement after it. Before, the
/// first line of numbers was refused as "expected an APT statement" (a
/// Creo CL file found on GitHub).
#[test]
fn a_creo_comment_continued_with_a_dollar_takes_its_lines_of_numbers() {
    let cl = "$$* Pro/CLfile  Version 9.0\nUNITS / MM\nMULTAX / ON\n$$-> CSYS / 1.0, 0.0, 0.0, 0.0,  $\n            0.0, 1.0, 0.0, 0.0,  $\n            0.0, 0.0, 1.0, 0.0\nRAPID\nGOTO / 0.0, 0.0, 10.0, 0.0, 0.0, 1.0\n$$ a note that ends with a dollar $\nGOTO / 5.0, 0.0, 10.0, 0.0, 0.0, 1.0\nFINI\n";
    let (code, out, err) = post(cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains(
            "\n(-> CSYS / 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)\nG0 X0.0000 Y0.0000 Z10.0000"
        ),
        "{out}"
    );
    assert!(
        out.contains("\n(a note that ends with a dollar $)\nG1 X5.0000 Y0.0000 Z10.0000"),
        "{out}"
    );
    assert!(err.contains("2 poses converted"), "{err}");
}

/// `FEDRAT/f,MMPR` (a feed per revolution) was read by `simulate` and
/// `analyze` as f mm/min: the lowering writes it as `G95` and the feed, and
/// the pose reader did not follow the `G95` (0.1 mm/rev: 2,400 s for 4 mm
/// of travel). Then, as `G95` in G-code, those blocks ran at the rapid
/// feed with a warning. Now they run at F × the spindle's speed that
/// `SPINDL/500,RPM` sets (50 mm/min), and without a speed (`SPINDL/OFF`)
/// at the rapid feed, with the warning.
#[test]
fn a_feed_per_revolution_runs_at_the_spindle_speed() {
    let dir = tempfile::tempdir().unwrap();
    let run = |spindle: &str| -> (f64, String) {
        let prog = dir.path().join("rev.apt");
        std::fs::write(
            &prog,
            format!("UNITS/MM\nFEDRAT/0.1000,MMPR\n{spindle}\nGOTO/17.0,0.0,2.0\nGOTO/17.0,0.0,0.0\nGOTO/15.0,0.0,0.0\nFEDRAT/600,MMPM\nGOTO/15.0,10.0,0.0\nFINI\n"),
        )
        .unwrap();
        let rec = dir.path().join("r.csv");
        let out = crate::cl_support::kinpost(&[
            "simulate",
            "-m",
            "xyzac-trt",
            "--sample-interval",
            "0.01",
            "-p",
            prog.to_str().unwrap(),
            "-o",
            rec.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{err}");
        let last_t: f64 = std::fs::read_to_string(&rec)
            .unwrap()
            .lines()
            .last()
            .and_then(|l| l.split(',').next().map(|t| t.parse().unwrap()))
            .unwrap();
        (last_t, err)
    };
    // 4 mm at 50 mm/min (4.8 s), then 10 mm at 600 mm/min (1 s), with
    // acceleration a little more: 5.8 s.
    let (t, err) = run("SPINDL/500.0,RPM,CLW");
    assert!(t > 5.8 && t < 6.3, "{t} s\n{err}");
    assert!(!err.contains("without a feed per minute"), "{err}");
    // 4 mm at the rapid feed (3,000 mm/min: 0.08 s), then the 10 mm: 1.45 s.
    let (t, err) = run("SPINDL/OFF");
    assert!(
        err.contains("2 block(s) move without a feed per minute") && err.contains("line 5, 6"),
        "{err}"
    );
    assert!(t > 1.0 && t < 2.0, "{t} s");
}

/// CATIA's ICAM output comments a statement out with a synonym,
/// `SYN/'TLAXIS','$$*TLAXIS'`: the `TLAXIS` after it is a comment, and the
/// tool stays along Z. Before, the `SYN` was kept as a comment and the
/// `TLAXIS/0,1,0` applied: `A90`, the tool tilted a quarter turn, exit 0.
/// Any other synonym (`SYN/GT,GOTO`), and one that would comment out a
/// statement of the tool's path, is refused.
#[test]
fn a_synonym_that_comments_a_statement_out_is_applied_and_others_are_refused() {
    let cl = "PARTNO SYN TEST\nUNITS/MM\nSYN/'TLAXIS','$$*TLAXIS'\nMULTAX/ON\nFEDRAT/500.0,MMPM\nTLAXIS/ 0.000000, 1.000000, 0.000000\nGOTO/10.0,0.0,5.0\nGOTO/20.0,0.0,5.0\nFINI\n";
    let (code, out, err) = crate::cl_support::post_stdin("xyzac-trt", &[], cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("(TLAXIS/ 0.000000, 1.000000, 0.000000 [SYN: a comment])\nG1 X10.0000 Y0.0000 Z5.0000 A0.0000 C0.0000 F500.0\n"),
        "{out}"
    );
    assert!(err.contains("SYN 1, TLAXIS 1"), "{err}");
    for (syn, word) in [
        ("SYN/GT,GOTO", "`GT` stand for `GOTO`"),
        ("SYN/'GOTO','$$GOTO'", "`GOTO` stand for `$$GOTO`"),
        ("SYN/'TLAXIS'", "pairs of a word"),
    ] {
        let cl = format!("UNITS/MM\n{syn}\nGOTO/1,2,3\n");
        let (code, _, err) = crate::cl_support::post_stdin("xyzac-trt", &[], &cl);
        assert_eq!(code, 1, "{syn}: {err}");
        assert!(err.contains(":2:1:") && err.contains(word), "{syn}: {err}");
    }
}

/// A CL whose first feed moves come before any `FEDRAT` was written as
/// `G1` without `F`, without a word said: LinuxCNC and Fanuc refuse such a
/// block, others move at a feed left from before. Now it is warned of,
/// once, at the first such `GOTO`.
#[test]
fn a_feed_move_before_any_feed_is_warned_of() {
    let cl = "UNITS/MM\nGOTO/1,2,3\nGOTO/2,2,3\nFEDRAT/100,MMPM\nGOTO/3,2,3\nFINI\n";
    let (code, out, err) = post(cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("\nG1 X1.0000 Y2.0000 Z3.0000 B0.0000 C0.0000\n"),
        "{out}"
    );
    let warned: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("before any FEDRAT"))
        .collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(warned[0].contains("<stdin>:2:1:"), "{err}");
    // With a feed first, or rapids only, nothing is said.
    for cl in [
        "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/1,2,3\nFINI\n",
        "UNITS/MM\nRAPID\nGOTO/1,2,3\nFINI\n",
    ] {
        let (code, _, err) = post(cl);
        assert_eq!(code, 0, "{err}");
        assert!(!err.contains("FEDRAT"), "{err}");
    }
}
