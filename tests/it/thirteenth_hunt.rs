//! Thirteenth hunt for real-world input (session 29, `docs/robustness.md`).
//! Each test failed on the session's first build.

use crate::util::{post_file, run_on};

const ZHAO: &str = "zhao2022-xzbc";

/// The commands that follow motion in machine axes, each with the file
/// last: `analyze --nonlinear`, `simulate`, `linkage`.
fn followers(out: &str) -> [Vec<String>; 3] {
    let s = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    [
        s(&["analyze", "--machine", ZHAO, "--nonlinear"]),
        s(&["simulate", "--machine", ZHAO, "-o", out, "--program"]),
        s(&["linkage", "--machine", ZHAO]),
    ]
}

/// A lathe's cutting cycles cut a contour with moves their words do not
/// give: Fanuc's `G71 P10 Q20 …` (stock removal between the sequence
/// numbers 10 and 20), `G70 P10 Q20` (finishing), `G73` pattern repeating,
/// `G74 … Q` peck drilling, and LinuxCNC's `G71 Q100 …` (the contour in
/// subroutine 100). Before, `analyze`, `simulate` and `linkage` skipped
/// them (Fanuc's G70/G71 without U or W taken for Sinumerik's inch / mm),
/// exit 0: a recording and a rewritten program without the roughing
/// passes. Now refused at the cycle's G word; `post` passes the program
/// through byte for byte, as it passes any program without poses.
#[test]
fn a_lathes_cutting_cycle_is_refused_where_motion_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.csv");
    let out = out.to_str().unwrap();
    let programs = [
        "G18 G21 G99\nG0 X52. Z2.\nG71 P10 Q20 F0.25\nN10 G0 X20.\nG1 Z-20. F0.1\nN20 X40.\nG0 X100. Z100.\nM30\n",
        "G18 G21\nG0 X52. Z2.\nG70 P10 Q20\nG0 X100. Z100.\nM30\n",
        "G18 G21\nG0 X52. Z2.\nG71 Q100 X52 Z2 D1 I0.2 R0.5\nG0 X100. Z100.\nM30\n",
        "G18 G21\nG0 X52. Z2.\nG73 P10 Q20 F0.25\nG0 X100. Z100.\nM30\n",
        "G18 G21\nG0 X0 Z2.\nG74 Z-20. Q5. F0.1\nG0 X100. Z100.\nM30\n",
    ];
    for program in programs {
        for args in followers(out) {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let (code, _, err) = run_on(&args, "lathe.nc", program);
            assert_eq!(code, 1, "{args:?} on {program}: {err}");
            assert!(
                err.contains("lathe.nc:3:1:") && err.contains("a lathe's cutting cycle"),
                "{args:?} on {program}: {err}"
            );
        }
        let (code, nc, err) = post_file(ZHAO, "lathe.nc", program.as_bytes());
        assert_eq!(code, 0, "{err}");
        assert_eq!(nc, program.as_bytes());
    }
    // Sinumerik's G71 (mm) and a mill's peck drilling G73 are followed.
    for program in [
        "G71\nG0 X52. Z2.\nG1 X40 F100\nM30\n",
        "G17 G21\nG0 X10 Z5\nG73 X10 Z-5 R1 Q1 F100\nG80\nG0 X20 Z5\nM30\n",
    ] {
        let args = ["simulate", "--machine", ZHAO, "-o", out, "--program"];
        let (code, _, err) = run_on(&args, "mill.nc", program);
        assert_eq!(code, 0, "{program}: {err}");
    }
}

/// A lathe program's `U` and `W` (increments of X and Z on a Fanuc lathe)
/// are named as such: before, only "the program is for another machine".
#[test]
fn a_lathes_incremental_words_are_named() {
    let (code, _, err) = run_on(
        &["linkage", "--machine", ZHAO],
        "lathe.nc",
        "G18 G21\nG0 X52. Z2.\nG1 U-2. W-10. F0.1\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("lathe.nc:3:4:") && err.contains("U is an increment of X"),
        "{err}"
    );
}

/// `analyze --errors` on a program whose TCP code comes after its first
/// 4 KB (a long approach in machine axes first): the program was taken for
/// one in machine axes and refused with exit 2 ("needs a program of tool
/// poses"), though `post` converts it. Now its poses are analysed, the
/// same as those of the program without the approach; a program with no
/// pose at all is still refused so.
#[test]
fn analyze_errors_reads_a_program_whose_tcp_comes_late() {
    let args = [
        "analyze",
        "--machine",
        "wang2023-xyzab",
        "--errors",
        "fixtures/errors/wang2023-xyzab.csv",
    ];
    let poses = "G43.4 H1\nG1 X10 Y0 Z20 I0 J0 K1 F500\nG1 X12 Y0 Z20 I0.1 J0 K0.995\nG49\nM30\n";
    let approach: String = (0..300)
        .map(|i| format!("G1 X{:.3} Y0 Z40 F500\n", i as f64 * 0.1))
        .collect();
    assert!(approach.len() > 4096);
    let late = format!("G21 G90\n{approach}{poses}");
    let (code, late_out, err) = run_on(&args, "late.nc", &late);
    assert_eq!(code, 0, "{err}");
    assert!(late_out.contains("2 poses"), "{late_out}");
    let (code, early_out, err) = run_on(&args, "early.nc", &format!("G21 G90\n{poses}"));
    assert_eq!(code, 0, "{err}");
    // The same figures (the lines differ by the approach's 300).
    let figures = |s: &str| {
        s.lines()
            .skip(1)
            .map(|l| l.split("(line").next().unwrap().to_string())
            .collect::<Vec<_>>()
    };
    assert_eq!(figures(&late_out), figures(&early_out));
    let (code, _, err) = run_on(&args, "axes.nc", &format!("G21 G90\n{approach}M30\n"));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("needs a program of tool poses"), "{err}");
}

const TRT: &str = "xyzac-trt";

/// `post` on `program` (G-code or APT CL) for xyzac-trt: (exit code,
/// output, messages).
fn post_trt(program: &str) -> (i32, String, String) {
    let (code, out, err) = post_file(TRT, "p.nc", program.as_bytes());
    (code, String::from_utf8_lossy(&out).into_owned(), err)
}

/// A tilted pose under TRAORI and the block after it.
const TILTED: &str = "G1 X10 Y0 Z5 A3=0 B3=-0.7071068 C3=0.7071068 F100\n";

/// Sinumerik reads its keywords in any case (`Traori`, `Trafoof`, `Trans`):
/// before, a keyword in mixed case was text kinpost did not read, so
/// `Traori` was left in the output under converted poses (TCP twice),
/// `Trafoof` did not end pose mode (`G0 Z100` written as a tilted pose),
/// and `Trans X10` before TRAORI let pose mode start under the frame.
#[test]
fn sinumerik_keywords_are_read_in_any_case() {
    let upper = post_trt(&format!("TRAORI\n{TILTED}TRAFOOF\nG0 Z100\nM30\n"));
    let mixed = post_trt(&format!("Traori\n{TILTED}Trafoof\nG0 Z100\nM30\n"));
    assert_eq!(upper.0, 0, "{}", upper.2);
    assert_eq!(mixed.0, 0, "{}", mixed.2);
    assert_eq!(
        mixed.1.replace("Trafoof", "TRAFOOF"),
        upper.1,
        "{}",
        mixed.1
    );
    assert!(mixed.1.contains("\nG0 Z100\n"), "{}", mixed.1);
    assert!(!mixed.1.contains("Traori"), "{}", mixed.1);
    let (code, _, err) = post_trt(&format!("Trans X10\nTRAORI\n{TILTED}TRAFOOF\nM30\n"));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("p.nc:2:1:") && err.contains("frame"), "{err}");
}

/// A shift of the coordinates (`G52 X10`, `G92 X…`) set before TCP is
/// switched on moves every linear axis word kinpost writes by it, which on
/// a table-tilting machine is not the tip's move it stands for: before,
/// converted with exit 0 (a tilted pose 20 mm off), where Sinumerik's
/// `TRANS` was refused. `G52 X0` and `G92.1` cancel.
#[test]
fn a_shift_of_the_coordinates_before_tcp_is_refused() {
    let pose = "G1 X10 Y0 Z5 I0 J-0.7071068 K0.7071068 F100\nG49\nM30\n";
    for (set, cancel) in [("G52 X10", "G52 X0"), ("G92 X10 Y0 Z50", "G92.1")] {
        let (code, _, err) = post_trt(&format!("G90 G54\n{set}\nG43.4 H1\n{pose}"));
        assert_eq!(code, 1, "{set}: {err}");
        assert!(
            err.contains("p.nc:3:1:") && err.contains("shift of the program's coordinates"),
            "{set}: {err}"
        );
        let (code, out, err) = post_trt(&format!("G90 G54\n{set}\n{cancel}\nG43.4 H1\n{pose}"));
        assert_eq!(code, 0, "{set} {cancel}: {err}");
        assert!(out.contains("A45.0000"), "{out}");
    }
}

/// After a move that goes where its words do not say — under a frame
/// (`G68 R90`, `TRANS`), Fanuc's `G53.1` (the rotaries turn to a tilted
/// plane), Sinumerik's reference or fixed point approach (`G74 Z1=0`,
/// `G75 FP=2 Z1=0`) — the position is not known, and a first pose that
/// gives only some of X Y Z is refused, as after `G28`. Before, it took the
/// rest from where kinpost had followed the words (X10 Y0 where the
/// controller stands at X0 Y10 after `G68 R90`).
#[test]
fn a_pose_after_a_move_to_an_unknown_place_must_give_x_y_z() {
    let cases = [
        "G0 X0 Y0 Z50 A0 C0\nG68 X0 Y0 R90\nG0 X10 Y0 Z50\nG69\nG43.4 H1\nG1 Z5 F100\nG49\nM30\n",
        "G0 X0 Y0 Z50 A0 C0\nTRANS X10\nG0 X10 Y0 Z50\nTRANS\nTRAORI\nG1 Z5 F100\nTRAFOOF\nM30\n",
        "G0 X0 Y0 Z50 A0 C0\nG68.2 X0 Y0 Z0 I0 J45 K0\nG53.1\nG69\nG43.4 H1\nG1 X10 F100\nG49\nM30\n",
        "G0 X0 Y0 Z100 A0 C0\nG74 Z1=0\nTRAORI\nG1 X20 F100\nTRAFOOF\nM30\n",
        "G0 X0 Y0 Z100 A0 C0\nG75 FP=2 Z1=0\nTRAORI\nG1 X20 F100\nTRAFOOF\nM30\n",
    ];
    for program in cases {
        let (code, out, err) = post_trt(program);
        assert_eq!(code, 1, "{program}: {out}");
        assert!(err.contains("is not known yet"), "{program}: {err}");
    }
}

/// Sinumerik `DIAMON` (X a diameter) and LinuxCNC `G7` set before TCP:
/// before, `X10` was converted as a radius; now pose mode may not start
/// under them (`DIAMOF`, `G8` end them).
#[test]
fn diameter_programming_before_tcp_is_refused() {
    for (on, off, tcp, end) in [
        ("DIAMON", "DIAMOF", "TRAORI", "TRAFOOF"),
        ("G7", "G8", "G43.4 H1", "G49"),
    ] {
        let pose = if tcp == "TRAORI" {
            TILTED.to_string()
        } else {
            "G1 X10 Y0 Z5 I0 J-0.7071068 K0.7071068 F100\n".to_string()
        };
        let (code, _, err) = post_trt(&format!("{on}\n{tcp}\n{pose}{end}\nM30\n"));
        assert_eq!(code, 1, "{on}: {err}");
        assert!(
            err.contains("p.nc:2:1:") && err.contains("diameter"),
            "{on}: {err}"
        );
        let (code, _, err) = post_trt(&format!("{on}\n{off}\n{tcp}\n{pose}{end}\nM30\n"));
        assert_eq!(code, 0, "{on} {off}: {err}");
    }
}

/// A subprogram after the main program's `M30` (Fanuc `O1000` … `M99`
/// called by `M98 P1000`, Haas `M97 P100`) runs under the modes of its
/// call: before, kinpost converted its poses under those the main program
/// ended with (a `G20` after the call made them inches: 40 mm off; a `G91`
/// made them increments). Now refused at the pose, naming the `M30`.
#[test]
fn a_pose_after_the_main_programs_end_is_refused() {
    let sub = "O1000\nG43.4 H1\nG1 X10 Y0 Z5 I0 J-.7071068 K.7071068 F100\nG49\nM99\n%\n";
    for (after_call, what) in [("G20\n", "units"), ("G91\n", "G90/G91"), ("", "subprogram")] {
        let program = format!("O0001\nG21 G90\nM98 P1000\n{after_call}G0 Z4.\nM30\n{sub}");
        let (code, out, err) = post_trt(&program);
        assert_eq!(code, 1, "{program}: {out}");
        assert!(
            err.contains("after the end of the main program") && err.contains(what),
            "{program}: {err}"
        );
    }
    // A program whose poses come before its M30 converts as before.
    let (code, _, err) = post_trt(&format!(
        "G21 G90\nG43.4 H1\n{}G49\nM30\n",
        "G1 X10 Y0 Z5 I0 J-.7071068 K.7071068 F100\n"
    ));
    assert_eq!(code, 0, "{err}");
}

/// A file saved as UTF-16 (a Windows editor's "Unicode") is named as
/// such; before, "a NUL byte: the file is damaged".
#[test]
fn a_utf16_file_is_named() {
    let text = "G1 X10 Y0 Z10\r\nM30\r\n";
    let mut bytes = vec![0xFF, 0xFE];
    for u in text.encode_utf16() {
        bytes.extend_from_slice(&u.to_le_bytes());
    }
    let (code, _, err) = post_file(TRT, "u.nc", &bytes);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("UTF-16"), "{err}");
}

const CL_HEAD: &str = "UNITS/MM\nFEDRAT/100\nGOTO/0,0,50\n";

/// CL statements that moved the tool, or set how, kept as comments with
/// exit 0 before; now each refused at its line (or read).
#[test]
fn cl_statements_kept_as_comments_before_are_refused() {
    let cases = [
        // DMG MORI's work plane (Autodesk's "Mori APT (MfgSuite)" post).
        (
            "MCSYS/ NUM, 1, POINT, 50, 0, 10, VECTOR, 1, 0, 0, VECTOR, 0, 0.70710678, 0.70710678\nGOTO/10,20,5\nFINI\n",
            4,
            "MCSYS",
        ),
        // Tool length registers other than the tool's number.
        ("LOADTL/3\nOFSTNO/5\nGOTO/10,20,5\nFINI\n", 5, "register 5"),
        (
            "TOOLNO/ 3, MILL, OSETNO, 5, 7\nLOADTL/3\nGOTO/10,20,5\nFINI\n",
            4,
            "register 5",
        ),
        // Blanks in a statement word (APT ignores them).
        ("GO TO/10,20,30\nFINI\n", 4, "blanks"),
        ("RAPID GOTO/10,20,30\nFINI\n", 4, "blanks"),
        ("CUTCOM LEFT/1\nGOTO/10,20,30\nFINI\n", 4, "blanks"),
        // A `$` that would take the next GOTO into a kept statement.
        ("PAINT/COLOR,31 $\nGOTO/10,20,30\nFINI\n", 5, "continuation"),
        // A lone CR: the statements after it hidden in a comment.
        (
            "GOTO/10,20,30 $$ first\rGOTO/40,20,30\nFINI\n",
            4,
            "carriage return",
        ),
        // A file cut mid-number.
        ("GOTO/40,20,3", 4, "truncated"),
    ];
    for (rest, line, what) in cases {
        let program = format!("{CL_HEAD}{rest}");
        let (code, out, err) = post_file("xyz-3axis", "p.cl", program.as_bytes());
        let out = String::from_utf8_lossy(&out);
        assert_eq!(code, 1, "{program}: {out}");
        assert!(
            err.contains(&format!("p.cl:{line}:")) && err.contains(what),
            "{program}: {err}"
        );
    }
    // The set-up frame, the tool's own register and a PPRINT ending in `$`
    // (its text is literal) are read as before.
    for rest in [
        "MCSYS/ NUM, 1, POINT, 0, 0, 0, VECTOR, 1, 0, 0, VECTOR, 0, 1, 0\nGOTO/10,20,5\nFINI\n",
        "LOADTL/3\nOFSTNO/3\nGOTO/10,20,5\nFINI\n",
        "PPRINT/PRICE IN $\nGOTO/10,20,5\nFINI\n",
    ] {
        let program = format!("{CL_HEAD}{rest}");
        let (code, out, err) = post_file("xyz-3axis", "p.cl", program.as_bytes());
        let out = String::from_utf8_lossy(&out);
        assert_eq!(code, 0, "{program}: {err}");
        assert!(
            out.contains("X10.0000 Y20.0000 Z5.0000"),
            "{program}: {out}"
        );
    }
}

/// Statements Autodesk's "Mori APT (MfgSuite)" and HSMWorks APT posts
/// write in every section, refused before with the wrong cause: MORI's
/// `CUTCOM/ ON, LENGTH, h` (tool length compensation, not the cutter's
/// radius), `FEDRAT/ PERMIN, f` ("wrong count"), HSMWorks'
/// `CUTCOM/ON, LEFT, d` ("CUTCOM/ON is not supported (LEFT, …)").
#[test]
fn mori_and_hsmworks_apt_words_are_read() {
    let mori = "UNITS/ MM\nLOAD/ TOOL, 1, 'D10', NEXTTL, 1\nCUTCOM/ ON, LENGTH, 1\nRAPID\nGOTO/ 10, 20, 30\nFEDRAT/ PERMIN, 500\nGOTO/ 10, 20, 5\nCUTCOM/ OFF, LENGTH\nEND/\n";
    let (code, out, err) = post_file("xyz-3axis", "m.apt", mori.as_bytes());
    let out = String::from_utf8_lossy(&out);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G43 H1\n"), "{out}");
    assert!(
        out.contains("G1 X10.0000 Y20.0000 Z5.0000 F500.0\n"),
        "{out}"
    );
    assert!(!out.contains("G40"), "{out}");
    // Another register than the tool's: another tool length.
    let other = mori.replace("LENGTH, 1", "LENGTH, 5");
    let (code, _, err) = post_file("xyz-3axis", "m.apt", other.as_bytes());
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("m.apt:3:1:") && err.contains("register 5"),
        "{err}"
    );
    let hsm = "UNITS/MM\nFEDRAT/MMPM,500\nGOTO/10,0,5\nCUTCOM/ON, LEFT, 1\nGOTO/20,0,5\nCUTCOM/OFF\nFINI\n";
    let (code, out, err) = post_file("xyz-3axis", "h.apt", hsm.as_bytes());
    let out = String::from_utf8_lossy(&out);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("G41 D1\nX20.0000 Y0.0000 Z5.0000\nG40\n"),
        "{out}"
    );
}
