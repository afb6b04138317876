//! APT CL constructs met in a fourth hunt for real input (session 18):
//! APT and NCL part programs (statement labels, jumps, loops, macros, NCL's
//! abbreviations), `LOADTL` with `ADJUST`, `SPINDL` settings, `DELAY` in
//! revolutions, a rapid arc, cutter compensation under a mirroring `CSYS`,
//! DOS's end-of-file mark and CR-only line endings. Each case exited 0
//! with the tool moved otherwise than the data says (or an unclear
//! message) before.

/// Runs `kinpost post -m xyz-3axis -` on `cl`: (exit code, stdout, stderr).
fn post(cl: &str) -> (i32, String, String) {
    crate::cl_support::post_stdin("xyz-3axis", &[], cl)
}

/// The axis words of the moves `post` wrote, as (X, Y, Z).
fn moves(out: &str) -> Vec<[f64; 3]> {
    out.lines()
        .filter(|l| l.contains('X') && l.contains('Z') && !l.starts_with('('))
        .map(|l| {
            let word = |a: char| {
                l.split_whitespace()
                    .find_map(|w| w.strip_prefix(a).and_then(|v| v.parse().ok()))
                    .unwrap()
            };
            [word('X'), word('Y'), word('Z')]
        })
        .collect()
}

/// `A1) GOTO/10,0,0`: the label was read as the statement's major word and
/// the statement kept as a comment; the tool went straight past the point.
#[test]
fn a_labelled_statement_is_read_after_its_label() {
    let cl = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/0,0,10\nID1) GODLTA/0,0,-5\nA1) GOTO/10,0,0\nA2)\nGT/20,0,0\nFINI\n";
    let (code, out, err) = post(cl);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        moves(&out),
        [
            [0.0, 0.0, 10.0],
            [0.0, 0.0, 5.0],
            [10.0, 0.0, 0.0],
            [20.0, 0.0, 0.0]
        ],
        "{out}"
    );
    // An error in a labelled statement points into it.
    let (code, _, err) = post("UNITS/MM\nA1) GOTO/1,2\nFINI\n");
    assert_eq!(code, 1);
    assert!(err.contains("<stdin>:2:5: GOTO expects"), "{err}");
}

/// Jumps, loops and macros were comments: the file ran from top to bottom.
/// NCL's abbreviations of the motion words were comments too.
#[test]
fn control_flow_and_abbreviated_motion_words_are_refused() {
    for (statement, said) in [
        ("JUMPTO/A3", "JUMPTO changes which statements run"),
        ("IF(1)A2,A2,A3", "IF changes which statements run"),
        ("LOOPST", "LOOPST changes which statements run"),
        ("M1=MACRO/", "M1=MACRO changes which statements run"),
        ("TERMAC", "TERMAC changes which statements run"),
        ("GO/TO,L1,TO,PL1,TO,L2", "GO moves the tool"),
        ("GF/(LN/FWD)", "GF moves the tool"),
        ("TN,GF/(LN/FWD)", "TN moves the tool"),
        ("IV/1,0,0", "IV moves the tool"),
    ] {
        let cl = format!("UNITS/MM\nGOTO/0,0,10\n{statement}\nGOTO/10,0,10\nFINI\n");
        let (code, _, err) = post(&cl);
        assert_eq!(code, 1, "{statement}: {err}");
        assert!(
            err.contains("<stdin>:3:1: ") && err.contains(said),
            "{statement}: {err}"
        );
    }
}

/// `LOADTL/3,ADJUST,3` wrote `T3 M6` alone (and `LOADTL/3` too): with the
/// chain ending at the gauge line nothing asked the controller for the
/// tool's length, and the tip went a tool length off. Now as `LOAD/TOOL`.
#[test]
fn loadtl_asks_for_the_tool_length_as_load_tool_does() {
    for (statement, want) in [
        ("LOADTL/3,ADJUST,13", "T3 M6\nG43 H13\n"),
        ("LOADTL/3", "T3 M6\nG43 H3\n"),
        ("LOADTL/1, 0, 60.000000, 1", "T1 M6\nG43 H1\n"),
    ] {
        let (code, out, err) = post(&format!("UNITS/MM\n{statement}\nGOTO/0,0,10\nFINI\n"));
        assert_eq!(code, 0, "{err}");
        assert!(out.contains(want), "{statement}: {out}");
    }
    let (code, _, err) = post("UNITS/MM\nLOADTL/3,ADJUST\nFINI\n");
    assert_eq!(code, 1);
    assert!(
        err.contains("<stdin>:2:10: expected a whole register number after ADJUST"),
        "{err}"
    );
}

/// `SPINDL/MAXRPM,3000` and `SPINDL/RANGE,2` each started the spindle
/// (`M3`), and a clamp with a surface speed was dropped; `DELAY/3,REV` was
/// a dwell of 3 s; a `RAPID` before a `CIRCLE` made its first chord `G0`
/// and the rest `G1`.
#[test]
fn spindle_settings_dwell_forms_and_rapid_arcs() {
    let (code, out, err) = post(
        "UNITS/MM\nSPINDL/RANGE,2\nSPINDL/RPM,1000,CLW,MAXRPM,3000\nFEDRAT/100\nGOTO/0,0,5\nFINI\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(SPINDL/RANGE,2)\nS1000 M3\n"), "{out}");
    assert_eq!(out.matches("M3\n").count(), 1, "{out}");
    for (statement, said) in [
        ("SPINDL/MAXRPM,3000", "SPINDL with MAXRPM"),
        ("SPINDL/SFM,300,CLW,MAXRPM,3000", "SPINDL with MAXRPM"),
        ("DELAY/3,REV", "DELAY expects a time in seconds"),
        ("RAPID\nCIRCLE/0,0,0,0,0,1,10", "CIRCLE after RAPID"),
    ] {
        let cl = format!("UNITS/MM\nFEDRAT/100\nGOTO/10,0,0\n{statement}\nGOTO/0,10,0\nFINI\n");
        let (code, _, err) = post(&cl);
        assert_eq!(code, 1, "{statement}: {err}");
        assert!(err.contains(said), "{statement}: {err}");
    }
}

/// A left-handed `CSYS` mirrors the path (its arcs turn the other way, as
/// they did), so the tool's left of the CL is the path's right on the
/// machine: `CUTCOM/LEFT` is `G42`. Before it was `G41`, the tool offset to
/// the wrong side by its radius twice.
#[test]
fn cutter_compensation_sides_swap_under_a_mirroring_setup() {
    let cl = |csys: &str| {
        format!(
            "UNITS/MM\nFEDRAT/MMPM,100\nLOAD/TOOL,1\n{csys}GOTO/10,0,0\nCUTCOM/LEFT\nGOTO/0,20,0\nCUTCOM/OFF\nFINI\n"
        )
    };
    let (code, out, err) = post(&cl("CSYS/-1,0,0,0,0,1,0,0,0,0,1,0\n"));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G42 D1\n") && !out.contains("G41"), "{out}");
    let (code, out, err) = post(&cl(""));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G41 D1\n") && !out.contains("G42"), "{out}");
    // The handedness changing under compensation is refused.
    let (code, _, err) = post(
        "UNITS/MM\nFEDRAT/100\nGOTO/10,0,0\nCUTCOM/LEFT\nGOTO/0,20,0\nCSYS/-1,0,0,0,0,1,0,0,0,0,1,0\nGOTO/0,30,0\nFINI\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:6:1: CSYS changes between a right- and a left-handed frame"),
        "{err}"
    );
}

/// DOS's end-of-file mark after `FINI` was refused as "expected an APT
/// statement"; text after the mark is refused. CR-only line endings were
/// refused with a message about `MMFEDRAT/MMPM`.
#[test]
fn dos_end_of_file_mark_and_cr_only_line_endings() {
    let (code, out, err) = post("UNITS/MM\nFEDRAT/100\nGOTO/0,0,5\nFINI\n\x1a");
    assert_eq!(code, 0, "{err}");
    assert!(out.ends_with("M30\n"), "{out}");
    let (code, _, err) = post("UNITS/MM\nGOTO/0,0,5\n\x1a\nGOTO/0,0,9\n");
    assert_eq!(code, 1);
    assert!(
        err.contains("<stdin>:4:1: text after DOS's end-of-file mark"),
        "{err}"
    );
    let (code, _, err) = post("UNITS/MM\rFEDRAT/MMPM,100\rGOTO/0,0,10\rFINI\r");
    assert_eq!(code, 1);
    assert!(
        err.contains("<stdin>:1:9: a carriage return (CR) inside the line"),
        "{err}"
    );
}

/// Found by metamorphic tests in session 18: CL data with blanks before
/// `/` (`GOTO / 10 , 20 , 5`) or a byte-order mark was taken for G-code
/// and passed through unconverted, exit 0 ("0 poses converted"), or
/// refused at line 1; a statement continued with `$` and written as a
/// comment (`CSYS`, `TRNTYP`, `CYCLE`) kept its line breaks: an unclosed
/// `(CSYS/1,0,0,0,$` and bare lines of numbers after it.
#[test]
fn cl_with_blanks_before_the_slash_a_bom_and_continued_comments() {
    let cl = "UNITS / MM\nFEDRAT / 500 , MMPM\nGOTO / 10 , 20 , 5\nFINI\n";
    let (code, out, err) = crate::util::post_file("xyz-3axis", "b.apt", cl.as_bytes());
    assert_eq!(code, 0, "{err}");
    let out = String::from_utf8(out).unwrap();
    assert!(
        out.contains("G1 X10.0000 Y20.0000 Z5.0000 F500.0\n"),
        "{out}"
    );
    let bom = format!("\u{feff}{cl}");
    let (code, out, err) = crate::util::post_file("xyz-3axis", "bom.apt", bom.as_bytes());
    assert_eq!(code, 0, "{err}");
    assert!(
        String::from_utf8(out)
            .unwrap()
            .contains("G1 X10.0000 Y20.0000 Z5.0000")
    );
    let (code, out, err) = post(
        "UNITS/MM\nCSYS/1,0,0,0,$\n 0,1,0,0,$\n 0,0,1,0\nCYCLE/DRILL,FEDTO,5.,$\n MMPM,100.,RAPTO,3.\nGOTO/1,2,3\nCYCLE/OFF\nFINI\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("\n(CSYS/1,0,0,0,$ 0,1,0,0,$ 0,0,1,0)\n"),
        "{out}"
    );
    assert!(
        out.contains("\n(CYCLE/DRILL,FEDTO,5.,$ MMPM,100.,RAPTO,3.)\n"),
        "{out}"
    );
    assert!(out.lines().all(|l| !l.starts_with(' ')), "{out}");
}

/// Found by metamorphic tests in session 18: the peck clearance of a
/// deep or chip-breaking hole (0.5 mm) was 0.5 CL units, 0.5 inch in an
/// inch CL; and pecks that add up to the depth but for rounding (0.3 +
/// 3 × 0.2) drilled the bottom twice.
#[test]
fn peck_holes_do_not_depend_on_the_units_or_on_rounding() {
    let moves_of = |cl: &str| -> Vec<String> {
        let (code, out, err) = post(cl);
        assert_eq!(code, 0, "{err}");
        out.lines()
            .filter(|l| !l.starts_with('(') && l.contains(" Z"))
            .map(str::to_string)
            .collect()
    };
    for kind in ["DEEP2", "BRKCHP"] {
        let mm = moves_of(&format!(
            "UNITS/MM\nRAPID\nGOTO/10,20,25.4\nCYCLE/{kind},FEDTO,12.7,1STPECK,5.08,SUBPECK,2.54,MMPM,254,RAPTO,5.08,RTRCTO,25.4\nGOTO/10,20,0\nCYCLE/OFF\nFINI\n"
        ));
        let inch = moves_of(&format!(
            "UNITS/INCHES\nRAPID\nGOTO/0.393700787401575,0.78740157480315,1\nCYCLE/{kind},FEDTO,0.5,1STPECK,0.2,SUBPECK,0.1,IPM,10,RAPTO,0.2,RTRCTO,1\nGOTO/0.393700787401575,0.78740157480315,0\nCYCLE/OFF\nFINI\n"
        ));
        assert!(mm.len() > 6, "{kind}: {mm:?}");
        assert_eq!(mm, inch, "{kind}");
        assert!(mm.iter().any(|l| l.contains("Z-4.5800")), "{kind}: {mm:?}");
    }
    let pecks = moves_of(
        "UNITS/MM\nRAPID\nGOTO/10,20,5\nCYCLE/DEEP2,FEDTO,0.9,1STPECK,0.3,SUBPECK,0.2,MMPM,100,RAPTO,1\nGOTO/10,20,0\nCYCLE/OFF\nFINI\n",
    );
    let bottoms = pecks.iter().filter(|l| l.contains("Z-0.9000")).count();
    assert_eq!(bottoms, 1, "{pecks:?}");
}
