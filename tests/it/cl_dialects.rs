//! APT CL in the shapes other CAM systems write (test programs written for
//! kinpost in tests/it/cl_dialects/, modelled on the statements of Siemens NX
//! CLSF, CATIA V5 APT, neutral Mastercam/PowerMill CL, CAMplete/Autodesk APT
//! and Creo/NCL CL):
//! `parse --echo` gives each file back byte for byte; `post` on a
//! table-table and a head-head machine exits 0, and the programmed path,
//! evaluated on its own (G2/G3 sampled, canned cycles drilled, forward
//! kinematics by hand), agrees with the CL path, evaluated on its own, within
//! 5 µm both ways. Arcs in a plane of the machine come out as G2/G3, holes
//! with the tool along the machine's Z as canned cycles. Statements that move
//! the tool and are not understood are refused with file:line:col.

use crate::cl_support::{
    agree, cl_path, forward_head, forward_trt, kinpost, output_points, post_stdin,
};

const TRT: &str = "fixtures/machines/xyzac-trt.json";
const HEAD: &str = "fixtures/machines/xyzac-head.json";

/// What each file must give on each machine: G2/G3 blocks and canned
/// cycle blocks (trt, head), and the summary of statements kept as
/// comments.
/// Tool tip from the axis words X Y Z A C, by hand.
type Forward = fn([f64; 5]) -> [f64; 3];

/// (G2/G3 blocks, canned-cycle blocks).
type Counts = (usize, usize);

const FILES: &[(&str, Counts, Counts, &str)] = &[
    (
        "nx-clsf.cls",
        // Six arcs, of which the one about the tilted tool axis is in no
        // plane of the head machine; five holes, one a DRILL,DEEP with
        // CYCLE/ON changing its depth.
        (6, 5),
        (5, 5),
        "18 CL statements that do not move the tool kept as comments (END-OF-PATH 3, MSYS 2, PAINT 7, TLDATA 3, TOOL PATH 3)",
    ),
    (
        "catia-v5.aptsource",
        (3, 0),
        (3, 0),
        "7 CL statements that do not move the tool kept as comments (AUTOPS 1, CUTTER 1, MULTAX 2, PARTNO 1, TOOLNO 1, TPRINT 1)",
    ),
    (
        "neutral.cl",
        (1, 3),
        (1, 3),
        "7 CL statements that do not move the tool kept as comments (CUTTER 1, MULTAX 1, PARTNO 1, PPRINT 4)",
    ),
    (
        "camplete.apt",
        // CAMplete's and Autodesk's APT: MCS/ matrices (the identity here),
        // FEDRAT/f, MMPM, an 11-value CIRCLE, CYCLE/DRILL with CLEAR.
        (1, 2),
        (1, 2),
        "32 CL statements that do not move the tool kept as comments (CSI_PATH_TOLERANCE 1, CSI_SET_FLUTE_LENGTH 1, CSI_TOOL_PATH 3, CUTTER 2, MACHIN 1, MCS 3, MODE 1, MULTAX 3, PARTNO 1, PPRINT 16)",
    ),
    (
        "creo.ncl",
        (1, 0),
        (1, 0),
        "2 CL statements that do not move the tool kept as comments (MACHIN 1, PARTNO 1)",
    ),
];

fn path(name: &str) -> String {
    format!("tests/it/cl_dialects/{name}")
}

#[test]
fn dialects_parse_echo_is_byte_identical() {
    for (name, ..) in FILES {
        let out = kinpost(&["parse", "--echo", &path(name)]);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let file = std::fs::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path(name)))
            .unwrap();
        assert!(out.stdout == file, "{name}");
    }
}

#[test]
fn dialects_post_follows_the_cl_path() {
    for (name, trt, head, summary) in FILES {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path(name)),
        )
        .unwrap();
        let cl = cl_path(&text);
        for (machine, forward, (arcs, canned)) in [
            (TRT, forward_trt as Forward, trt),
            (HEAD, forward_head, head),
        ] {
            let out = kinpost(&["post", "-m", machine, "--units", "mm", &path(name)]);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{name} on {machine}: {stderr}");
            assert!(stderr.contains(summary), "{name} on {machine}: {stderr}");
            let nc = String::from_utf8(out.stdout).unwrap();
            let count = |f: &dyn Fn(&str) -> bool| nc.lines().filter(|l| f(l)).count();
            let g23 = count(&|l| l.contains("G2 ") || l.contains("G3 "));
            let g8x = count(&|l| l.contains(" G8") || l.contains(" G73 "));
            assert_eq!((g23, g8x), (*arcs, *canned), "{name} on {machine}:\n{nc}");
            let (pts, holes) = output_points(&nc, forward);
            let (worst_out, worst_cl) = agree(name, &cl, &pts, &holes);
            println!(
                "{name} on {machine}: {} CL pieces, {} holes, {g23} G2/G3, {g8x} canned; worst output→CL {:.4} µm, CL→output {:.4} µm",
                cl.pieces.len(),
                cl.holes.len(),
                worst_out * 1e3,
                worst_cl * 1e3
            );
        }
    }
}

/// Statements that move the tool in forms kinpost does not convert are
/// refused with the file, line and column, and nothing is written.
#[test]
fn motion_not_understood_is_refused() {
    let start = "UNITS/MM\nGOTO/10,0,0\n";
    let cases = [
        ("GOFWD/(LINE/0,0,0,1,0,0),TO,(PLANE/1,0,0,5)\n", "GOFWD"),
        ("INDIRP/0,1,0\n", "INDIRP"),
        (
            "INDIRV/0,1,0\nTLON,GOFWD/(CIRCLE/CANON,0,0,0,10)\n",
            "TLON,GOFWD",
        ),
        (
            "TLON,GOFWD/(CIRCLE/0,0,0,10),ON,(LINE/0,0,0,0,10,0)\n",
            "no INDIRV",
        ),
        (
            "INDIRV/1,0,0\nTLON,GOFWD/(CIRCLE/0,0,0,10),ON,(LINE/0,0,0,0,10,0)\n",
            "along the radius",
        ),
        (
            "INDIRV/0,1,0\nTLON,GOFWD/(CIRCLE/0,0,0,12),ON,(LINE/0,0,0,0,10,0)\n",
            "not on the circle",
        ),
        ("CYCLE/ON,FEDTO,-5\n", "no cycle is in force"),
        ("CYCLE/MILL,FEDTO,-5\n", "CYCLE/MILL"),
        ("CYCLE/DRILL,FEDTO,-5,RTRCTO,HIGH\n", "RTRCTO"),
        ("GOHOME\n", "GOHOME"),
    ];
    for (tail, what) in cases {
        let program = format!("{start}{tail}");
        let (code, nc, err) = post_stdin(TRT, &[], &program);
        let line = program.lines().count();
        assert_eq!(code, 1, "{tail}: {err}");
        assert!(err.contains(&format!("<stdin>:{line}:1")), "{tail}: {err}");
        assert!(err.contains(what), "{tail}: {err}");
        assert!(!nc.contains('X'), "{tail}: {nc}");
    }
    // Tapping with the tool not along the machine's Z axis (a head tilted
    // by 30°) cannot be moves: refused at the hole.
    let tap = "UNITS/MM\nGOTO/0,0,30,0,-0.5,0.8660254\nCYCLE/TAP,FEDTO,10,MMPR,1.5,RAPTO,3\nGOTO/0,0,0\nCYCLE/OFF\n";
    let (code, _, err) = post_stdin(HEAD, &[], tap);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:4:1") && err.contains("tapping"),
        "{err}"
    );
    // On the table-table machine the tool is always along Z: G84.
    let (code, nc, err) = post_stdin(TRT, &[], tap);
    assert_eq!(code, 0, "{err}");
    assert!(
        nc.contains("G99 G84 ") && nc.contains(" F1.5\n") && nc.contains("G95"),
        "{nc}"
    );
}

/// Feeds keep their decimals: `FEDRAT/0.05,MMPR` was written `F0.1`
/// (twice the feed) and 123.45 mm/min `F123.5` before.
#[test]
fn feeds_keep_their_decimals() {
    let cl = "UNITS/MM\nFEDRAT/0.05,MMPR\nGOTO/1,0,0\nFEDRAT/MMPM,123.45\nGOTO/2,0,0\nFEDRAT/MMPM,800\nGOTO/3,0,0\n";
    let (code, nc, err) = post_stdin(TRT, &[], cl);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains(" F0.05\n") && nc.contains(" F123.45\n"), "{nc}");
    assert!(nc.contains(" F800.0\n"), "{nc}");
}

/// The forms of the arc and cycle blocks on the table-table machine: a
/// whole circle ends where it starts (I J to the centre, not a zero-length
/// move), a helix carries its axis word, `--modal-axes` still writes every
/// axis of an arc, inches are converted (also the peck depth), and
/// `CYCLE/OFF` is `G80` after which the motion code is written again.
#[test]
fn arc_and_cycle_blocks() {
    let cl = "UNITS/MM\nFEDRAT/MMPM,500\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1\nGOTO/0,-10,-2\nGOTO/5,5,0\n";
    let (code, nc, err) = post_stdin(TRT, &["--modal-axes"], cl);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = nc.lines().collect();
    assert!(
        lines.contains(&"G17 G3 X10.0000 Y0.0000 Z0.0000 A0.0000 C0.0000 I-10.0000 J0.0000"),
        "{nc}"
    );
    assert!(
        lines.contains(&"G2 X0.0000 Y-10.0000 Z-2.0000 A0.0000 C0.0000 I-10.0000 J0.0000"),
        "{nc}"
    );
    assert!(lines.contains(&"G1 X5.0000 Y5.0000 Z0.0000"), "{nc}");
    let inch = "UNITS/INCHES\nGOTO/1,0,2\nCYCLE/DEEP,FEDTO,0.5,STEP,0.1,RAPTO,0.1,RTRCTO,1,IPM,10\nGOTO/1,0,0\nCYCLE/OFF\nGOTO/0,1,0\nCIRCLE/0,0,0,0,0,1\nGOTO/-1,0,0\n";
    let (code, nc, err) = post_stdin(TRT, &[], inch);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = nc.lines().collect();
    assert!(
        lines.contains(&"G17 G98 G83 X25.4000 Y0.0000 Z-12.7000 R2.5400 Q2.5400 F254.0"),
        "{nc}"
    );
    let g80 = lines.iter().position(|l| *l == "G80").unwrap();
    assert!(lines[g80 + 1].starts_with("G1 X0.0000 Y25.4000"), "{nc}");
    assert!(
        lines.contains(&"G3 X-25.4000 Y0.0000 Z0.0000 A0.0000 C0.0000 I0.0000 J-25.4000"),
        "{nc}"
    );
}

/// CAMWorks (SolidWorks CAM) drilling: `CYCLE/CLEAR` before a cycle (a
/// reset, no motion) and the peck increment `INCR` of `CYCLE/DEEP`. Both
/// were refused ("CYCLE/CLEAR is not supported", "CYCLE: unknown word
/// INCR"), so hardly any CAMWorks drilling converted; now the same G83 as
/// with NX's `STEP`.
#[test]
fn camworks_cycle_clear_and_incr() {
    let cl = "UNITS/MM\nGOTO/10,0,20\nCYCLE/CLEAR\nCYCLE/DEEP,FEDTO,5.,INCR,2.,MMPM,300.,RAPTO,2.,RTRCTO,20.\nGOTO/10,0,0\nCYCLE/OFF\nGOTO/0,10,20\n";
    let (code, nc, err) = post_stdin(TRT, &[], cl);
    assert_eq!(code, 0, "{err}");
    let step = cl.replace("INCR", "STEP").replace("CYCLE/CLEAR\n", "");
    let (code, reference, err) = post_stdin(TRT, &[], &step);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("(CYCLE/CLEAR)"), "{nc}");
    let holes = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| l.contains("G83"))
            .map(String::from)
            .collect()
    };
    assert_eq!(holes(&nc), holes(&reference));
    assert!(holes(&nc)[0].contains("Z-5.0000 R2.0000 Q2.0000"), "{nc}");
    // CLEAR with words is not a reset: still refused.
    let (code, _, err) = post_stdin(TRT, &[], "UNITS/MM\nCYCLE/CLEAR,5\nGOTO/0,0,0\n");
    assert_eq!(code, 1, "{err}");
}

/// The positional `CYCLE/DRILL,d,MMPM,f,c` is written by CAM posts with
/// the point at the hole's top or at its bottom (Autodesk's common ISO 4343
/// APT post: the bottom, `c` the clearance height, `RAPTO` its distance to
/// the retract plane): refused at the cycle, where before it was drilled
/// `d` below the point with `R` at `c` above it, exit 0.
#[test]
fn a_positional_cycle_is_refused() {
    for cycle in [
        "CYCLE/DRILL, 8, MMPM, 150, 15, RAPTO, 10",
        "CYCLE/DRILL,8,MMPM,150,5",
        "CYCLE/DEEP, 12, INCR, 3, MMPM, 100, 15",
        "CYCLE/TAP, 10, MMPM, 1.5, 5, RAPTO, 2",
    ] {
        let cl = format!(
            "UNITS/MM\nRAPID\nGOTO/10,0,15\nFEDRAT/150, MMPM\n{cycle}\nGOTO/10,0,-8\nCYCLE/OFF\nGOTO/0,10,20\n"
        );
        let (code, nc, err) = post_stdin(TRT, &[], &cl);
        assert_eq!(code, 1, "{cycle}: {err}");
        assert!(
            err.contains("<stdin>:5:1") && err.contains("positional form"),
            "{cycle}: {err}"
        );
        assert!(!nc.contains("G81") && !nc.contains("G83"), "{cycle}: {nc}");
    }
    // The same hole with its words named is converted.
    let named = "UNITS/MM\nRAPID\nGOTO/10,0,15\nCYCLE/DRILL, FEDTO, 8, MMPM, 150, RAPTO, 5, RTRCTO, 15\nGOTO/10,0,0\nCYCLE/OFF\nGOTO/0,10,20\n";
    let (code, nc, err) = post_stdin(TRT, &[], named);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("G81") && nc.contains("R5.0000"), "{nc}");
}

/// Creo's couplet form `CYCLE/DRILL, DEPTH, a, IPM, b, CLEAR, c, RAPTO, d`
/// (PTC, "CL Output for Holemaking Cycles"): `c` is the clearance above the
/// point, where the tool also returns to, and `d` a further rapid from
/// there towards the point, so the R level is `c − d` above it. kinpost
/// read RAPTO and CLEAR alike as the R level and the later won: `R3`, 1 mm
/// above Creo's, and a return to it (`G99`) instead of to the clearance.
#[test]
fn creo_rapto_counts_from_the_clearance() {
    let hole = |cycle: &str| {
        format!(
            "UNITS/MM\nRAPID\nGOTO/10,0,15\nFEDRAT/150, MMPM\n{cycle}\nGOTO/10,0,0\nCYCLE/OFF\nGOTO/0,10,20\n"
        )
    };
    let (code, nc, err) = post_stdin(
        TRT,
        &[],
        &hole("CYCLE / DRILL, DEPTH, 8, MMPM, 150, CLEAR, 5, RAPTO, 3"),
    );
    assert_eq!(code, 0, "{err}");
    let g81 = nc.lines().find(|l| l.contains("G81")).expect("a G81 block");
    // R 5 − 3 = 2 above the top at Z0, the bottom 8 below, back to Z5.
    assert!(
        g81.contains("G98") && g81.contains("Z-8.0000") && g81.contains("R2.0000"),
        "{nc}"
    );
    // The rapid (G0 modal since the first move) to the clearance above it.
    let before: Vec<&str> = nc.lines().take_while(|l| !l.contains("G81")).collect();
    assert!(
        before
            .last()
            .is_some_and(|l| l.starts_with("X10.0000 Y0.0000 Z5.0000")),
        "the tool goes to the clearance above the hole: {nc}"
    );
    // CLEAR alone is the R level and the return, as before.
    let (code, nc, err) = post_stdin(
        TRT,
        &[],
        &hole("CYCLE/DRILL, DEPTH, 8, MMPM, 150, CLEAR, 5"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("G99") && nc.contains("R5.0000"), "{nc}");
    // A rapid beyond the point is refused at the cycle.
    let (code, nc, err) = post_stdin(
        TRT,
        &[],
        &hole("CYCLE/DRILL, DEPTH, 8, MMPM, 150, CLEAR, 2, RAPTO, 3"),
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:5:1") && err.contains("RAPTO"),
        "{err}"
    );
    assert!(!nc.contains("G81"), "{nc}");
    // The Autodesk posts' FEDTO form keeps RAPTO as the R level.
    let (code, nc, err) = post_stdin(
        TRT,
        &[],
        &hole("CYCLE/DRILL, FEDTO, 8, MMPM, 150, CLEAR, 10, RTRCTO, 10, RAPTO, 2"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("R2.0000"), "{nc}");
}

/// docs/programs.md names every major word that moves the tool in its
/// table of CL major words, and the dialect files' comment words.
#[test]
fn every_motion_major_is_documented() {
    let doc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/programs.md"),
    )
    .unwrap();
    let table = doc
        .split("### Every CL major word")
        .nth(1)
        .and_then(|t| t.split("\n### ").next())
        .expect("the table of CL major words");
    let rows: Vec<&str> = table.lines().filter(|l| l.starts_with("| ")).collect();
    for major in kinpost::cl::MOTION_MAJORS
        .iter()
        .chain(kinpost::cl::FLOW_MAJORS)
        .chain(&[
            "TOOL PATH",
            "TLDATA",
            "MSYS",
            "PAINT",
            "END-OF-PATH",
            "TOOLNO",
            "TPRINT",
            "AUTOPS",
            "MACHIN",
            "PPRINT",
        ])
    {
        assert!(
            rows.iter().any(|r| r.contains(&format!("`{major}"))),
            "{major} is not in the table of CL major words"
        );
    }
}

/// A three-axis machine file whose axis `flip` runs the other way.
fn flipped_machine(flip: &str) -> std::path::PathBuf {
    let axis = |n: &str, v: [i32; 3]| {
        let s = if n == flip { -1 } else { 1 };
        format!(
            r#"{{"prismatic": {{"name": "{n}", "axis": [{}, {}, {}]}}}}"#,
            v[0] * s,
            v[1] * s,
            v[2] * s
        )
    };
    let json = format!(
        r#"{{"name": "xyz-flip-{flip}", "description": "test", "source": "test",
  "chain": [{}, {}, {}],
  "axes": {{"X": {{}}, "Y": {{}}, "Z": {{}}}}}}"#,
        axis("X", [1, 0, 0]),
        axis("Y", [0, 1, 0]),
        axis("Z", [0, 0, 1])
    );
    let dir = std::env::temp_dir().join(format!("kinpost-cl-dialects-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("flip-{flip}.json"));
    std::fs::write(&path, json).unwrap();
    path
}

/// The direction and the tool axis come from the kinematics: on a machine
/// whose X runs the other way a counter-clockwise CL arc is a `G2`, and on
/// one whose Z runs the other way (joint Z up moves the tool down) a hole
/// is not a canned cycle but moves; both paths still agree with the CL.
#[test]
fn direction_and_tool_axis_come_from_the_kinematics() {
    let cl = "UNITS/MM\nFEDRAT/MMPM,300\nGOTO/10,0,5\nCIRCLE/0,0,5,0,0,1\nGOTO/0,10,5\nCYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10\nGOTO/0,10,0\nCYCLE/OFF\nGOTO/0,10,20\n";
    let path = cl_path(cl);
    let cases: [(&str, Forward, &str, bool); 3] = [
        ("none", |q| [q[0], q[1], q[2]], "G17 G3 ", true),
        ("X", |q| [-q[0], q[1], q[2]], "G17 G2 ", true),
        ("Z", |q| [q[0], q[1], -q[2]], "G17 G3 ", false),
    ];
    for (flip, forward, arc, canned) in cases {
        let machine = flipped_machine(flip);
        let (code, nc, err) = post_stdin(machine.to_str().unwrap(), &[], cl);
        assert_eq!(code, 0, "{flip}: {err}");
        assert!(nc.lines().any(|l| l.starts_with(arc)), "{flip}:\n{nc}");
        assert_eq!(nc.contains(" G81 "), canned, "{flip}:\n{nc}");
        let (pts, holes) = output_points(&nc, forward);
        agree(flip, &path, &pts, &holes);
    }
}

/// A `RAPID` before a hole written as a canned cycle is used up by the
/// hole: the move after `CYCLE/OFF` is a feed move (it was a `G0`).
#[test]
fn rapid_before_a_canned_hole_is_used_up() {
    let cl = "UNITS/MM\nFEDRAT/MMPM,300\nGOTO/0,0,10\nCYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10\nRAPID\nGOTO/0,0,0\nCYCLE/OFF\nGOTO/5,0,10\n";
    let (code, nc, err) = post_stdin(TRT, &[], cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        nc.contains("G98 G81 X0.0000 Y0.0000 Z-4.0000 R2.0000 F300.0\nG80\nG1 X5.0000 "),
        "{nc}"
    );
}

/// `compensate` converts every pose it solves and reports each: arcs and
/// holes stay moves there (`post` writes G3 and G81 for the same file), and
/// the report counts exactly the moves written.
#[test]
fn compensate_keeps_arcs_and_holes_as_moves() {
    let dir = std::env::temp_dir().join(format!("kinpost-cl-comp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("c.cls");
    std::fs::write(
        &file,
        "UNITS/MM\nFEDRAT/MMPM,300\nGOTO/10,0,5\nCIRCLE/0,0,5,0,0,1\nGOTO/0,10,5\nCYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10\nGOTO/0,10,0\nCYCLE/OFF\n",
    )
    .unwrap();
    let file = file.to_str().unwrap();
    let post = kinpost(&["post", "-m", "wang2023-xyzab", file]);
    let nc = String::from_utf8_lossy(&post.stdout);
    assert!(nc.contains("G17 G3 ") && nc.contains(" G81 "), "{nc}");
    let comp = kinpost(&[
        "compensate",
        "-m",
        "wang2023-xyzab",
        "--errors",
        "fixtures/errors/wang2023-xyzab.csv",
        file,
    ]);
    let err = String::from_utf8_lossy(&comp.stderr);
    assert!(comp.status.success(), "{err}");
    let nc = String::from_utf8_lossy(&comp.stdout);
    assert!(
        !nc.contains("G3 ") && !nc.contains("G2 ") && !nc.contains(" G8"),
        "{nc}"
    );
    let moves = nc
        .lines()
        .filter(|l| l.starts_with("G0 ") || l.starts_with("G1 ") || l.starts_with('X'))
        .count();
    assert!(moves > 20, "{nc}");
    assert!(
        err.contains(&format!("{moves} poses")),
        "{moves} moves: {err}"
    );
}

/// One statement kept as a comment is counted in the singular ("1 CL
/// statement that does not move the tool", not "… that do not").
#[test]
fn one_statement_kept_as_a_comment_is_said_in_the_singular() {
    let (code, _, stderr) = post_stdin(TRT, &[], "UNITS/MM\nMULTAX/ON\nGOTO/10,5,20,0,0,1\n");
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("1 CL statement that does not move the tool kept as comments (MULTAX 1)"),
        "{stderr}"
    );
}

/// A frame statement that would put the points after it in another frame
/// than the set-up frame is refused at its place: `MCS/` with a rotation
/// or an origin (CAMplete's and Autodesk's APT: the work plane of a 3+2
/// operation), `MSYS/` other than the first (Siemens NX: another MCS),
/// `ZERO/` other than the first (CAMplete: another work offset); the
/// identity `MCS/` and a repeated `MSYS/` or `ZERO/` are comments.
#[test]
fn a_frame_the_points_are_in_is_refused_where_it_changes() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path("camplete.apt")),
    )
    .unwrap();
    let tilted = text.replacen(
        "MCS/1.000000000, 0.000000000, 0.000000000, $\n0.000000000, 1.000000000, 0.000000000, $\n0.000000000, 0.000000000, 1.000000000, $\n0.000000, 0.000000, 0.000000",
        "MCS/1.000000000, 0.000000000, 0.000000000, $\n0.000000000, 0.707106781, 0.707106781, $\n0.000000000, -0.707106781, 0.707106781, $\n0.000000, 0.000000, 0.000000",
        2,
    );
    let shifted = text.replacen(
        "0.000000, 0.000000, 0.000000\n",
        "0.000000, 0.000000, 12.500000\n",
        1,
    );
    for (what, program, line) in [("tilted", &tilted, 20), ("shifted", &shifted, 20)] {
        assert_ne!(program, &text, "{what}");
        let (code, stdout, stderr) = post_stdin(TRT, &[], program);
        assert_eq!(code, 1, "{what}: {stderr}");
        assert!(stdout.is_empty() || !stdout.contains("G1 "), "{what}");
        assert!(
            stderr.contains(&format!(
                "<stdin>:{line}:1: MCS/ with a rotation or an origin"
            )),
            "{what}: {stderr}"
        );
    }
    let nx = |second: &str| {
        format!(
            "UNITS/MM\nMSYS/0.0000,0.0000,20.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000\nFEDRAT/MMPM,500\nGOTO/1,2,3\n{second}\nGOTO/4,5,6\nFINI\n"
        )
    };
    let (code, _, stderr) = post_stdin(
        TRT,
        &[],
        &nx(
            "MSYS/0.0000,0.0000,20.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000",
        ),
    );
    assert_eq!(code, 0, "{stderr}");
    let (code, _, stderr) = post_stdin(
        TRT,
        &[],
        &nx(
            "MSYS/0.0000,0.0000,20.0000,1.0000000,0.0000000,0.0000000,0.0000000,0.0000000,1.0000000",
        ),
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains(
            "<stdin>:5:1: MSYS/ changes the machine coordinate system from that of line 2"
        ),
        "{stderr}"
    );
    // CAMplete's work offset: the first one is the program's, the same
    // again passes, another is refused.
    let zero = |second: &str| {
        format!("UNITS/MM\nZERO/2\nFEDRAT/500, MMPM\nGOTO/1,2,3\n{second}\nGOTO/4,5,6\nFINI\n")
    };
    let (code, _, stderr) = post_stdin(TRT, &[], &zero("ZERO/2"));
    assert_eq!(code, 0, "{stderr}");
    let (code, _, stderr) = post_stdin(TRT, &[], &zero("ZERO/3"));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("<stdin>:5:1: ZERO/ changes the work offset from that of line 2"),
        "{stderr}"
    );
}

/// CAMplete's `CUTCOM/ON` before `CUTCOM/LEFT, n`: a comment, the side and
/// the register from the second; a motion between the two is refused at
/// its place (the side is not known).
#[test]
fn cutcom_on_then_its_side() {
    let program = |between: &str| {
        format!(
            "UNITS/MM\nLOADTL/1, 0, 40, 1\nFEDRAT/500, MMPM\nGOTO/0, 0, 0\nCUTCOM/ON\n{between}GOTO/5, 5, 0\nGOTO/10, 5, 0\nCUTCOM/OFF\nGOTO/10, 10, 0\nFINI\n"
        )
    };
    let (code, nc, err) = post_stdin(TRT, &[], &program("CUTCOM/LEFT, 3\n"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("(CUTCOM/ON)\nG41 D3\n"), "{nc}");
    let (code, _, err) = post_stdin(TRT, &[], &program(""));
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:6:1: a motion after CUTCOM/ON (line 5) and before CUTCOM/LEFT"),
        "{err}"
    );
}

/// Autodesk's ISO 4343 APT writes every arc as `MOVARC/xc,yc,zc,i,j,k,r,
/// ANGLE,a` and the `GOTO` that ends it: the same `G2`/`G3` as the
/// `CIRCLE` of the same arc; an angle that the points do not sweep, or
/// more than a turn, is refused at its place.
#[test]
fn movarc_is_an_arc_of_the_angle_it_gives() {
    let program = |arc: &str| {
        format!(
            "UNITS/MM\nLOADTL/3\nFEDRAT/400, MMPM\nGOTO/-50, 0, -2\n{arc}\nGOTO/0, 50, -2\nGOTO/30, 50, -2\nFINI\n"
        )
    };
    let (code, by_circle, err) = post_stdin(TRT, &[], &program("CIRCLE/0, 0, -2, 0, 0, -1, 50"));
    assert_eq!(code, 0, "{err}");
    let (code, by_movarc, err) = post_stdin(
        TRT,
        &[],
        &program(
            "MOVARC/0.000000, 0.000000, -2.000000, 0.000000, 0.000000, -1.000000, 50.000000, ANGLE, 90.000000",
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(by_movarc.contains("G2 X0.0000 Y50.0000"), "{by_movarc}");
    let body = |nc: &str| {
        nc.lines()
            .filter(|l| !l.starts_with('('))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(body(&by_movarc), body(&by_circle));
    for (arc, why) in [
        (
            "MOVARC/0, 0, -2, 0, 0, -1, 50, ANGLE, 270",
            "MOVARC gives an angle of 270° but its start and end points sweep 90°",
        ),
        (
            "MOVARC/0, 0, -2, 0, 0, -1, 50, ANGLE, 450",
            "MOVARC sweeps 450°",
        ),
        (
            "MOVARC/0, 0, -2, 0, 0, -1, 50",
            "MOVARC expects xc,yc,zc,i,j,k,r,ANGLE,a",
        ),
    ] {
        let (code, _, err) = post_stdin(TRT, &[], &program(arc));
        assert_eq!(code, 1, "{arc}: {err}");
        assert!(err.contains(why), "{arc}: {err}");
    }
}
