//! APT CL cutter compensation (`CUTCOM/LEFT|RIGHT`, written `G41`/`G42`).
//! The controller offsets the path by the tool radius in the machine's X Y
//! plane (`G17`), at right angles to its Z axis: that is the compensation
//! the CL asks for only while the tool is along the machine's Z axis and no
//! rotary axis turns. Before, every compensated move was converted and the
//! program written with `G41`/`G42`, exit 0, on any machine and tool axis
//! (a head tilted 30°, a table turning under compensation). Now such a
//! move is refused at its `GOTO`, by `post` and by `compensate`, and the
//! ordinary 2.5D case (tool along Z, rotaries still) is converted as
//! before. `docs/robustness.md` has the row.

use crate::util;

/// `kinpost args… --input-kind cl -` with `input` on standard input: exit
/// code, stdout, stderr.
fn run(args: &[&str], input: &str) -> (i32, String, String) {
    crate::cl_support::cl_stdin(args, input)
}

/// A pocket side under compensation: the approach at tool axis `before`,
/// `CUTCOM/LEFT` (line 5), three moves at tool axis `during` (lines 6–8),
/// `CUTCOM/OFF`, a retract at `after`.
fn contour(before: &str, during: &str, after: &str) -> String {
    format!(
        "UNITS/MM\nLOAD/TOOL,1\nMULTAX/ON\nGOTO/0,-10,10,{before}\nCUTCOM/LEFT\n\
         GOTO/0,0,0,{during}\nGOTO/20,0,0,{during}\nGOTO/20,20,0,{during}\n\
         CUTCOM/OFF\nGOTO/20,20,30,{after}\nFINI\n"
    )
}

const Z: &str = "0,0,1";
/// 30° from Z towards +X.
const TILTED: &str = "0.5,0,0.8660254038";

/// An error table for the machine `name`: the zhao2022 table for X Z B C
/// (xyzbc-trt), the linear axes of wang2023's for a machine with other
/// rotaries. Written to `dir`.
fn table(dir: &std::path::Path, name: &str) -> String {
    if name == "xyzbc-trt" {
        return util::repo_file("fixtures/errors/zhao2022-xzbc.csv");
    }
    let xyz = crate::cl_support::wang_linear_table();
    let p = dir.join("xyz.csv");
    std::fs::write(&p, xyz).unwrap();
    p.to_string_lossy().into_owned()
}

/// `post` and `compensate` of `input` on machine `m`: both results.
fn both(m: &str, input: &str) -> [(i32, String, String); 2] {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path(), m);
    [
        run(&["post", "-q", "-m", m], input),
        run(&["compensate", "-q", "-m", m, "--errors", &t], input),
    ]
}

#[test]
fn cutter_compensation_is_converted_only_with_the_tool_along_z_and_rotaries_still() {
    // 2.5D: converted, G41 D1 … G40, on every machine with X, Y and Z.
    for m in ["xyzbc-trt", "xyzac-head", "xyz-3axis", "xyza-4axis"] {
        for (k, (code, nc, err)) in both(m, &contour(Z, Z, Z)).into_iter().enumerate() {
            assert_eq!(code, 0, "{m} (command {k}): {err}");
            assert!(
                nc.contains("\nG41 D1\n") && nc.contains("\nG40\n"),
                "{m}: {nc}"
            );
        }
    }
    // A table tilted 30°: the tool stays along the machine's Z, and the
    // contour at right angles to the tool lies in the machine's X Y plane.
    for (code, nc, err) in both("xyzbc-trt", &contour(TILTED, TILTED, TILTED)) {
        assert_eq!(code, 0, "{err}");
        assert!(
            nc.contains("B-30.0000") && nc.contains("\nG41 D1\n"),
            "{nc}"
        );
    }
    // A head tilted 30°: the controller would offset in the machine's X Y
    // plane, not at right angles to the tool. Refused at the first
    // compensated GOTO (line 6).
    for (code, nc, err) in both("xyzac-head", &contour(TILTED, TILTED, TILTED)) {
        assert_eq!(code, 1, "{err}");
        assert!(nc.is_empty(), "{nc}");
        assert!(
            err.contains("<stdin>:6:1:")
                && err.contains("CUTCOM/LEFT")
                && err.contains("not along the machine's Z axis")
                && err.contains("tool-centre path"),
            "{err}"
        );
    }
    // A rotary that turns while compensation is on: in the lead-in (from
    // the approach's pose) or later (line 7 turns B back).
    let cases = [
        (contour(Z, TILTED, TILTED), "<stdin>:6:1:"),
        (
            contour(Z, Z, Z).replace("GOTO/20,0,0,0,0,1", &format!("GOTO/20,0,0,{TILTED}")),
            "<stdin>:7:1:",
        ),
    ];
    for (input, at) in &cases {
        for (code, _, err) in both("xyzbc-trt", input) {
            assert_eq!(code, 1, "{err}");
            assert!(
                err.contains(at) && err.contains("B turns") && err.contains("CUTCOM/LEFT"),
                "{err}"
            );
        }
    }
    // After CUTCOM/OFF the rotaries may turn again.
    for (code, _, err) in both("xyzbc-trt", &contour(Z, Z, TILTED)) {
        assert_eq!(code, 0, "{err}");
    }
    // A machine without a Y axis has no X Y plane to offset in.
    let (code, _, err) = run(&["post", "-q", "-m", "zhao2022-xzbc"], &contour(Z, Z, Z));
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:6:1:") && err.contains("no linear X, Y and Z axes"),
        "{err}"
    );
}

/// Arcs and holes under compensation: on the tilted table an arc about the
/// tool axis is a `G17` arc and is written as `G2`/`G3`; on the tilted head
/// its moves are refused; a hole is moves under compensation (no canned
/// cycle with G41), checked as moves. `CUTCOM/…,YZPLAN` and `ZXPLAN` ask for
/// another plane than the `G17` kinpost writes: refused at the statement.
#[test]
fn cutter_compensation_of_arcs_holes_and_planes() {
    let arc = format!(
        "UNITS/MM\nMULTAX/ON\nGOTO/10,0,0,{TILTED}\nCUTCOM/RIGHT\n\
         CIRCLE/0,0,0,{TILTED}\nGOTO/-10,0,0,{TILTED}\nCUTCOM/OFF\nFINI\n"
    );
    let (code, nc, err) = run(&["post", "-q", "-m", "xyzbc-trt"], &arc);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("\nG42\n") && nc.contains("G3 "), "{nc}");
    let (code, _, err) = run(&["post", "-q", "-m", "xyzac-head"], &arc);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:6:1:") && err.contains("not along the machine's Z axis"),
        "{err}"
    );
    let hole = format!(
        "UNITS/MM\nMULTAX/ON\nGOTO/10,0,20,{TILTED}\nCUTCOM/LEFT\n\
         CYCLE/DRILL,FEDTO,5,RAPTO,2,MMPM,100\nGOTO/10,0,0,{TILTED}\nCYCLE/OFF\nFINI\n"
    );
    let (code, nc, err) = run(&["post", "-q", "-m", "xyzbc-trt"], &hole);
    assert_eq!(code, 0, "{err}");
    assert!(!nc.contains("G81"), "{nc}");
    let (code, _, err) = run(&["post", "-q", "-m", "xyzac-head"], &hole);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("<stdin>:6:1:"), "{err}");
    for plane in ["YZPLAN", "ZXPLAN"] {
        let input = contour(Z, Z, Z).replace("CUTCOM/LEFT", &format!("CUTCOM/LEFT,{plane}"));
        let (code, _, err) = run(&["post", "-q", "-m", "xyz-3axis"], &input);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("<stdin>:5:1:") && err.contains(plane), "{err}");
    }
    let input = contour(Z, Z, Z).replace("CUTCOM/LEFT", "CUTCOM/LEFT,XYPLAN");
    let (code, _, err) = run(&["post", "-q", "-m", "xyz-3axis"], &input);
    assert_eq!(code, 0, "{err}");
}

/// The SolidWorks CAM programs of `../shared/real` compensate their
/// contours in 2.5D set-ups (`CSYS` turns each set-up's tool axis to its
/// Z): converted with their `G41`/`G40` on the table-table and head
/// machines and on the three-axis one, as before.
#[test]
fn real_cl_with_cutter_compensation_in_2_5d_converts() {
    let Some(dir) = util::shared_dir("real/solidworks-cam") else {
        return;
    };
    let mut seen = 0;
    for f in std::fs::read_dir(&dir).unwrap() {
        let f = f.unwrap().path();
        let text = std::fs::read_to_string(&f).unwrap_or_default();
        if !text.contains("CUTCOM/LEFT") {
            continue;
        }
        let left = text
            .lines()
            .filter(|l| l.starts_with("CUTCOM/LEFT"))
            .count();
        for m in ["xyzbc-trt", "xyzac-head", "xyz-3axis"] {
            let out = crate::cl_support::kinpost(&["post", "-q", "-m", m, f.to_str().unwrap()]);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{} on {m}: {err}", f.display());
            let nc = String::from_utf8_lossy(&out.stdout);
            assert_eq!(
                nc.lines().filter(|l| l.starts_with("G41")).count(),
                left,
                "{} on {m}",
                f.display()
            );
            seen += 1;
        }
    }
    assert!(seen >= 6, "{seen}");
}

/// `compensate` writes rotary values that differ from pose to pose by the
/// compensation, and that is not a rotary turning under the offset: the
/// test compares the theoretical values. Here an X axis whose pitch
/// (EBX) grows by 0.4 µrad per mm turns the compensated B by 20 µrad
/// (0.0011°) along a 50 mm side of a 2.5D contour, twice the tolerance,
/// and the contour is converted with its `G41`.
#[test]
fn compensate_compares_the_theoretical_rotary_values() {
    let dir = tempfile::tempdir().unwrap();
    let mut table = String::from("X,EBX\n");
    for x in (-300..=300).step_by(10) {
        table.push_str(&format!("{x},{:e}\n", f64::from(x + 300) * 4e-7));
    }
    let t = dir.path().join("pitch.csv");
    std::fs::write(&t, table).unwrap();
    let input = "UNITS/MM\nLOAD/TOOL,1\nGOTO/0,-10,10\nCUTCOM/LEFT\nGOTO/0,0,0\n\
                 GOTO/50,0,0\nGOTO/50,20,0\nCUTCOM/OFF\nGOTO/50,20,30\nFINI\n";
    let (code, nc, err) = run(
        &[
            "compensate",
            "-q",
            "-m",
            "xyzbc-trt",
            "--decimals",
            "6",
            "--errors",
            t.to_str().unwrap(),
        ],
        input,
    );
    assert_eq!(code, 0, "{err}");
    let b: Vec<f64> = nc
        .lines()
        .filter_map(|l| l.split(' ').find_map(|w| w.strip_prefix('B')))
        .map(|v| v.parse().unwrap())
        .collect();
    let turn = (b[3] - b[1]).to_radians().abs();
    assert!(turn > 1.5e-5, "B {b:?}");
    assert!(nc.contains("\nG41 D1\n"), "{nc}");
}
