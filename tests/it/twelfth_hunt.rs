//! Twelfth hunt for real-world input (session 28, `docs/robustness.md`):
//! Siemens NX CLSF from two sites, Creo and CATIA V5 CL data, GRBL, Haas,
//! Fanuc and Sinumerik programs. Each test failed on the session's first
//! build.

use crate::cl_support::post_stdin;
use crate::util::run_on;

const XYZ: &str = "fixtures/machines/xyz-3axis.json";

/// An NX floor-facing operation as NX writes it: a plunge, a quarter-circle
/// lead-in from the west of the circle to its south, then a cut in +X. NX's
/// CLSF manual: "i,j,k is the circle or helix axis vector in the MCS
/// (assuming a clockwise direction)", so the axis (0, 0, −1) is the axis of
/// a counter-clockwise arc seen from above: `G3`, the 90° lead-in. Before,
/// kinpost read the axis by the right-hand rule, as APT's, and wrote `G2`:
/// the other 270° of the circle, through the part up to Y 180.
const NX_LEAD_IN: &str = "TOOL PATH/FLOOR_FACING,TOOL,MILL
TLDATA/MILL,30.0000,0.0000,75.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
LOAD/TOOL,1,ADJUST,1
RAPID
GOTO/-72.5000,72.5000,13.0000,0.0000000,0.0000000,1.0000000
FEDRAT/MMPM,250.0000
GOTO/-72.5000,72.5000,10.0000
CIRCLE/-65.0000,72.5000,10.0000,0.0000000,0.0000000,-1.0000000,7.5000,0.0600,0.5000,30.0000,0.0000
GOTO/-65.0000,65.0000,10.0000
GOTO/65.0000,65.0000,10.0000
END-OF-PATH
";

#[test]
fn an_nx_circle_runs_clockwise_about_its_axis() {
    let (code, nc, err) = post_stdin(XYZ, &["--units", "mm"], NX_LEAD_IN);
    assert_eq!(code, 0, "{err}");
    let arc: Vec<&str> = nc
        .lines()
        .filter(|l| l.contains(" G2 ") || l.contains(" G3 "))
        .collect();
    assert_eq!(arc.len(), 1, "{nc}");
    assert!(arc[0].contains("G3 X-65.0000 Y65.0000"), "{nc}");
    // The same statements without NX's: APT's right-hand rule, `G2`.
    let plain: String = NX_LEAD_IN
        .lines()
        .filter(|l| {
            !l.starts_with("TOOL PATH") && !l.starts_with("TLDATA") && !l.starts_with("MSYS")
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let (code, nc, err) = post_stdin(XYZ, &["--units", "mm"], &plain);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("G2 X-65.0000 Y65.0000"), "{nc}");
}

/// NX's helix of n turns (`CIRCLE/…,TIMES,n`) is refused by name; before,
/// "expected a finite number, found `TIMES`", as if the file were damaged.
#[test]
fn an_nx_helix_with_turns_is_refused_by_name() {
    let cl = NX_LEAD_IN.replace(",30.0000,0.0000\n", ",30.0000,0.0000,TIMES,2\n");
    assert!(cl.contains("TIMES,2"));
    let (code, _, err) = post_stdin(XYZ, &["--units", "mm"], &cl);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains(":9:") && err.contains("helix of n turns"),
        "{err}"
    );
}

/// NX's deep drilling without a step (`CYCLE/DRILL,DEEP,RAPTO,3,FEDTO,0`,
/// a countersink at the point) is one peck from R to the bottom: `Q3`.
/// Before, the depth (0) was the peck, clamped to 0.001 mm: 3,000 pecks.
#[test]
fn a_deep_drill_without_a_step_is_one_peck() {
    let cl = "UNITS/MM
GOTO/66.0000,0.0000,250.0000,0.0000000,0.0000000,1.0000000
CYCLE/DRILL,DEEP,RAPTO,3.0000,FEDTO,0.0000,MMPM,250.0000
GOTO/66.0000,0.0000,240.0000,0.0000000,0.0000000,1.0000000
CYCLE/OFF
";
    let (code, nc, err) = post_stdin(XYZ, &[], cl);
    assert_eq!(code, 0, "{err}");
    let g83 = nc
        .lines()
        .find(|l| l.contains("G83"))
        .unwrap_or_else(|| panic!("{nc}"));
    assert!(
        g83.contains("R243.0000") && g83.contains("Q3.0000"),
        "{g83}"
    );
}

/// A site's post-processor words that call a subprogram, move the
/// controlled point or run the spindle (CATIA V5 with a PP word table:
/// `SUBPROG/1010` is `M98 P1010` there, `STANDOFF/6` moves every point 6 mm
/// along the tool axis, `SPINDLE/CLW20` starts the spindle) are refused at
/// their line; before, they were kept as comments, exit 0.
#[test]
fn a_site_word_that_moves_or_calls_is_refused() {
    for (word, line) in [("SUBPROG/1010", 3), ("STANDOFF/6", 3), ("SPINDLE/CLW20", 3)] {
        let cl = format!("UNITS/MM\nGOTO/0,0,50\n{word}\nGOTO/10,0,50\n");
        let (code, _, err) = post_stdin(XYZ, &[], &cl);
        assert_eq!(code, 1, "{word}: {err}");
        assert!(err.contains(&format!(":{line}:1")), "{word}: {err}");
    }
}

/// A CL file without `UNITS` whose feeds are in inches (an NX listing with
/// `FEDRAT/IPM,10`) is refused: before, its lengths were taken as
/// millimetres and its feed as inches (F254), with a warning only.
#[test]
fn inch_feeds_without_units_are_refused() {
    let cl = "GOTO/0,0,2\nFEDRAT/IPM,10.0000\nGOTO/1,0,2\n";
    let (code, _, err) = post_stdin(XYZ, &[], cl);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(":2:") && err.contains("--units inch"), "{err}");
    let (code, nc, err) = post_stdin(XYZ, &["--units", "inch"], cl);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("X25.4000") && nc.contains("F254.0"), "{nc}");
}

const TRT: &str = "fixtures/machines/xyzac-trt.json";

/// A GRBL program that starts with its system commands (`$$`, `$I`, as
/// real GRBL files do) is G-code: `post` gives it back byte for byte.
/// Before, `$$` was taken for an APT comment: the file was read as CL and
/// every move kept as a comment (exit 0), or refused as "expected an APT
/// statement". An APT comment with text (`$$ centerline data`) still makes
/// a file CL.
#[test]
fn grbl_system_commands_do_not_make_a_program_cl() {
    for head in [
        "$$\n",
        "$I  ; View build info\n$G\n$$  ; View current settings\n",
        "$10=255\n",
    ] {
        let text = format!("{head}G21 G90\nG0 X10 Y10\nG1 X20 Y0 Z5 F100\nM2\n");
        let (code, out, err) = crate::util::post_file(XYZ, "grbl.gcode", text.as_bytes());
        assert_eq!(code, 0, "{head:?}: {err}");
        assert_eq!(String::from_utf8(out).unwrap(), text, "{head:?}");
    }
    let (code, _, err) =
        crate::util::post_file(XYZ, "nx.cls", b"$$ centerline data\nUNITS/MM\nGOTO/1,2,3\n");
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("APT CL") || err.contains("1 poses"), "{err}");
}

/// LinuxCNC's `G43.1 Z20` (and `G43.2`) changes the tool length offset and
/// "does not cause any motion": `linkage` divides the next block from where
/// the tool is (Z50), not from Z20; in pose mode the block is refused.
/// Before, it was followed as a move: `linkage` planned a 30 mm plunge
/// below the programmed line, and `post` converted `G43.1 Z50` as a pose,
/// putting every later pose 45 mm off.
#[test]
fn a_dynamic_tool_offset_is_not_a_move() {
    for code in ["G43.1", "G43.2"] {
        let text =
            format!("G90 G21 G17\nG0 X0 Y0 Z50 A0 C0\n{code} Z20\nG1 X10 Y0 Z30 A10 F500\nM2\n");
        let (rc, out, err) = run_on(&["linkage", "--machine", TRT], "t.ngc", &text);
        assert_eq!(rc, 0, "{code}: {err}");
        let first = out
            .lines()
            .find(|l| l.contains("linkage 1/"))
            .unwrap_or_else(|| panic!("{out}"));
        let z: f64 = first
            .split_whitespace()
            .find_map(|w| w.strip_prefix('Z'))
            .unwrap()
            .parse()
            .unwrap();
        assert!(z > 45.0, "{code}: the first inserted block {first}");
    }
    let pose = "G0 X0 Y0 Z50 A0 C0\nG1 X10 Y0 Z5 I0 J0.5 K0.8660254 F500\nG43.1 Z50\nG1 X20\n";
    let (rc, _, err) = run_on(&["post", "--machine", TRT], "p.ngc", pose);
    assert_eq!(rc, 1, "{err}");
    assert!(err.contains(":3:1:") && err.contains("G43.1"), "{err}");
}

/// A canned cycle's `K` is its repeat count (Fanuc), not a tool vector: a
/// program in machine axes with `G81 … K2` is read as one, and its corner
/// rounding refused as without the K. Before, the K made the program a
/// pose program: `simulate`, `analyze` and `linkage` dropped most of it and
/// their checks, exit 0.
#[test]
fn a_cycle_repeat_count_is_not_a_tool_vector() {
    let text = "G90 G21\nG0 X0 Y0 Z50 A0 C0\nG1 X10 Y0 Z30 A30 F500\nG1 X20 Y5 ,R2\nG1 X30 Y0\nG81 X20 Y0 R5 Z-5 F800 K2\nG80\nM30\n";
    for args in [
        &["simulate", "--machine", TRT, "--program"][..],
        &["analyze", "--nonlinear", "--machine", TRT],
        &["linkage", "--machine", TRT],
    ] {
        let (rc, _, err) = run_on(args, "k.nc", text);
        assert_eq!(rc, 1, "{args:?}: {err}");
        assert!(
            err.contains(":4:11:") && err.contains(",R2"),
            "{args:?}: {err}"
        );
    }
}

/// `G43`, `G44` or `G43.1` after `G43.4`/`G43.5` end tool centre point
/// control (one modal group on Fanuc; Mitsubishi's G44 is its cancel):
/// the block after is in machine axes and passes as it is. Before, it was
/// converted as a pose: `G0 X0 Y0 Z100` written as `Y-80 Z78.56`.
#[test]
fn tool_length_codes_end_tcp() {
    for code in ["G43 H1", "G44 H1", "G43.1 H1"] {
        let text = format!(
            "G0 X0 Y0 Z50 A0 C0\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0.5 K0.8660254 F500\n{code}\nG0 X0 Y0 Z100\nM30\n"
        );
        let (rc, out, err) = crate::util::post_file(TRT, "tcp.nc", text.as_bytes());
        assert_eq!(rc, 0, "{code}: {err}");
        let out = String::from_utf8(out).unwrap();
        assert!(
            out.contains(&format!("\n{code}\nG0 X0 Y0 Z100\n")),
            "{code}:\n{out}"
        );
    }
    // The code in the block of a move in machine coordinates (before: an
    // internal error, the move waited for before the pose was solved).
    for code in ["G43 H2", "G44 H2", "G43.1 H2", "G49"] {
        let text = format!("G43.4 H1\nG1 X1 Y0 Z5 I0 J0 K1\n{code} G1 X0 Y0 Z50\n");
        let (rc, out, err) = crate::util::post_file(TRT, "same.nc", text.as_bytes());
        assert_eq!(rc, 0, "{code}: {err}");
        assert!(
            String::from_utf8(out)
                .unwrap()
                .ends_with(&format!("\n{code} G1 X0 Y0 Z50\n")),
            "{code}"
        );
    }
    // A program that starts pose mode without a TCP code keeps it on
    // through a tool change's G43.
    let text = "G1 X10 Y0 Z5 I0 J0.5 K0.8660254 F500\nG43 H1\nG1 X12 Y0 Z5 I0 J0.5 K0.8660254\n";
    let (rc, out, err) = crate::util::post_file(TRT, "implicit.nc", text.as_bytes());
    assert_eq!(rc, 0, "{err}");
    assert!(
        String::from_utf8(out).unwrap().contains("A30.0000"),
        "{err}"
    );
}

/// `linkage` does not divide a block that turns a rotary right after a
/// canned cycle, whose end (R level or start level, by G98/G99 and the
/// controller) the program does not say: refused as after G28. Before, it
/// started the block at the hole's bottom: a 54 mm plunge beside the hole.
#[test]
fn linkage_after_a_cycle_does_not_start_at_the_bottom() {
    let text = "G90 G21 G17 G98\nG0 X0 Y0 Z50 A0 C0\nG81 Z-5 R1 F100\nG1 X10 Y0 Z30 A10 F500\n";
    let (rc, _, err) = run_on(&["linkage", "--machine", TRT], "c.ngc", text);
    assert_eq!(rc, 1, "{err}");
    assert!(
        err.contains(":4:1:") && err.contains("canned cycle"),
        "{err}"
    );
    // A G0 to a known position after the cycle makes it measurable again.
    let text = "G90 G21 G17 G98\nG0 X0 Y0 Z50 A0 C0\nG81 Z-5 R1 F100\nG80\nG0 Z50\nG1 X10 Y0 Z30 A10 F500\n";
    let (rc, _, err) = run_on(&["linkage", "--machine", TRT], "c.ngc", text);
    assert_eq!(rc, 0, "{err}");
}

/// Constructs that set the tool or the frame another way under TCP are
/// refused at their place: Fanuc's tool inclination `G43.5 … Q15.` (before:
/// left on a `G49` line, the tool converted untilted), Sinumerik
/// `POS[C]=90` under TRAORI (before: kept, a bare turn of the table in
/// kinpost's output), Fanuc's rotary table dynamic fixture offset
/// `G54.2 P1` before `G43.4` (before: pose mode started under it; Haas's
/// G254 was refused). A polar move in the block of `G16` is refused by
/// `simulate` (before: left out of the recording).
#[test]
fn other_ways_to_set_tool_or_frame_are_refused() {
    let cases: [(&str, &str, &str, &str); 3] = [
        (
            TRT,
            "q.nc",
            "G0 X0 Y0 Z50 A0 C0\nG43.5 H1 Q15.\nG1 X10 Y0 Z5 I0 J0 K1 F500\n",
            ":2:10:",
        ),
        (
            "fixtures/machines/xyzbc-trt.json",
            "pos.mpf",
            "N10 G90 G71\nN20 TRAORI\nN30 G1 X10 Y0 Z5 A3=0 B3=0 C3=1 F1000\nN40 POS[C]=90\nN50 G1 X12 Y0 Z5 A3=0 B3=0 C3=1\n",
            ":4:5:",
        ),
        (
            TRT,
            "g542.nc",
            "G0 X0 Y0 Z50 A0 C0\nG54.2 P1\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0.5 K0.8660254 F500\n",
            ":3:1:",
        ),
    ];
    for (machine, name, text, place) in cases {
        let (rc, _, err) = crate::util::post_file(machine, name, text.as_bytes());
        assert_eq!(rc, 1, "{name}: {err}");
        assert!(err.contains(place), "{name}: {err}");
    }
    // G54.2 P0 cancels it.
    let text =
        "G0 X0 Y0 Z50 A0 C0\nG54.2 P1\nG54.2 P0\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0.5 K0.8660254 F500\n";
    let (rc, _, err) = crate::util::post_file(TRT, "g542.nc", text.as_bytes());
    assert_eq!(rc, 0, "{err}");
    let text = "G90 G21 G17\nG0 X0 Y0 Z0\nG1 X10 Y0 F300\nG16 G1 X20 Y0\nG15\n";
    let (rc, _, err) = run_on(&["simulate", "--machine", XYZ, "--program"], "g16.nc", text);
    assert_eq!(rc, 1, "{err}");
    assert!(err.contains(":4:8:") && err.contains("polar move"), "{err}");
}

/// Sinumerik calls that move nothing pass in pose mode as outside it: NX
/// and Autodesk 840D posts call `CYCLE832(…)` per operation, with TRAORI
/// still on. Before, refused as "a cycle or subprogram call". A call that
/// moves (`CYCLE81(…)`) is still refused.
#[test]
fn a_call_that_moves_nothing_passes_under_traori() {
    let head = "N10 G90 G71\nN20 TRAORI\nN30 G1 X10 Y0 Z5 A3=0 B3=0 C3=1 F1000\n";
    let tail = "N50 G1 X12 Y0 Z5 A3=0 B3=0 C3=1\nN60 TRAFOOF\n";
    let machine = "fixtures/machines/xyzbc-trt.json";
    let ok = format!("{head}N40 CYCLE832(0.01,_ORI_FINISH,1) ; tolerance\n{tail}");
    let (rc, out, err) = crate::util::post_file(machine, "c832.mpf", ok.as_bytes());
    assert_eq!(rc, 0, "{err}");
    assert!(
        String::from_utf8(out)
            .unwrap()
            .contains("\nN40 CYCLE832(0.01,_ORI_FINISH,1) ; tolerance\n")
    );
    for harmless in ["SETAL(61000)", "WAITM(1,1,2)", "G450", "G451"] {
        let text = format!("{head}N40 {harmless}\n{tail}");
        let (rc, _, err) = crate::util::post_file(machine, "h.mpf", text.as_bytes());
        assert_eq!(rc, 0, "{harmless}: {err}");
    }
    let moves = format!("{head}N40 CYCLE81(10,0,2,-5)\n{tail}");
    let (rc, _, err) = crate::util::post_file(machine, "c81.mpf", moves.as_bytes());
    assert_eq!(rc, 1, "{err}");
}
