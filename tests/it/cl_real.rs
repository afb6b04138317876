//! Real APT CL from SolidWorks CAM (`../shared/real/solidworks-cam/`):
//! `parse --echo` gives the file back byte for byte, and `post` for a
//! table-table A/C machine writes a program whose tool path agrees with the
//! CL path within 5 µm both ways. The CL path is evaluated here, on its own
//! (lines, arcs about their axes, drilled holes, `CSYS` set-ups), and the
//! output through a hand-written forward kinematics of the machine, so the
//! check does not rest on the converter's geometry. Skipped with a message
//! when `../shared` is absent; under CI (`CI=true`) that fails instead.

use crate::util;

use std::path::PathBuf;

const DIR: &str = "real/solidworks-cam";
const MACHINE: &str = "fixtures/machines/xyzac-trt.json";

use crate::cl_support::{Piece, agree, cl_path, forward_trt, kinpost, output_points};

fn files() -> Option<Vec<PathBuf>> {
    let dir = util::shared_dir(DIR)?;
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("apt")))
        .collect();
    v.sort();
    assert!(!v.is_empty());
    Some(v)
}

#[test]
fn solidworks_cam_parse_echo_is_byte_identical() {
    let Some(files) = files() else { return };
    for f in files {
        let out = kinpost(&["parse", "--echo", f.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.stdout == std::fs::read(&f).unwrap(), "{}", f.display());
    }
}

#[test]
fn solidworks_cam_post_follows_the_cl_path() {
    let Some(files) = files() else { return };
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(&f).unwrap();
        let out = kinpost(&["post", "-m", MACHINE, f.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        assert!(stderr.contains("kept as comments"), "{name}: {stderr}");
        let nc = String::from_utf8(out.stdout).unwrap();
        let cl = cl_path(&text);
        let (pts, holes) = output_points(&nc, forward_trt);

        // Tool changes, spindle, cutter compensation.
        for t in &cl.tools {
            assert!(nc.contains(&format!("T{t} M6\nG43 H{t}\n")), "{name}: T{t}");
        }
        for s in &cl.spindles {
            assert!(nc.contains(&format!("{s}\n")), "{name}: {s}");
        }
        let g41 = nc.lines().filter(|l| l.starts_with("G41")).count();
        let g40 = nc.lines().filter(|l| *l == "G40").count();
        assert_eq!((g41, g40), (cl.cutcom_left, cl.cutcom_off), "{name}");

        // Arcs and holes are written as such: every CIRCLE of these
        // files lies in the XY plane with the tool along Z. Arcs with a
        // chord under 0.01 mm (not full circles) stay straight moves.
        let arcs = nc
            .lines()
            .filter(|l| l.contains("G2 ") || l.contains("G3 "))
            .count();
        let circles = cl
            .pieces
            .iter()
            .filter(|p| match p {
                Piece::Arc(_, _, _, r, sweep, _) => {
                    *sweep > std::f64::consts::TAU - 1e-6 || 2.0 * r * (sweep / 2.0).sin() >= 0.01
                }
                Piece::Line(..) => false,
            })
            .count();
        assert!(circles > 0, "{name}");
        assert_eq!(arcs, circles, "{name}: G2/G3 blocks");
        // DRILL holes are G81; DEEP2 with a second peck depth (SUBPECK)
        // has no canned form and stays moves.
        let canned = nc.lines().filter(|l| l.contains(" G8")).count();
        let drill = cl
            .hole_cycles
            .iter()
            .filter(|c| c.starts_with("DRILL"))
            .count();
        let g81 = nc.lines().filter(|l| l.contains(" G81 ")).count();
        assert!(
            (canned, g81) == (drill, drill),
            "{name}: {canned} canned blocks for {drill} DRILL holes"
        );
        assert_eq!(holes.len(), drill, "{name}");

        let (worst_out, worst_cl) = agree(&name, &cl, &pts, &holes);
        println!(
            "{name}: {} CL pieces, {} holes, {} arcs, {} output points; worst output→CL {:.4} µm, CL→output {:.4} µm",
            cl.pieces.len(),
            cl.holes.len(),
            arcs,
            pts.len(),
            worst_out * 1e3,
            worst_cl * 1e3
        );
    }
}

fn post_stdin(args: &[&str], input: &str) -> (i32, String, String) {
    crate::cl_support::post_stdin(MACHINE, args, input)
}

/// The SolidWorks CAM spindle form is accepted; motion statements kinpost
/// does not convert and absurd feeds are refused with file:line:col.
#[test]
fn real_forms_and_refusals() {
    let (code, nc, _) = post_stdin(&[], "UNIT/MM\nSPINDL/12000,RPM,CLW\nGOTO/1,2,3\n");
    assert_eq!(code, 0);
    assert!(nc.contains("S12000 M3\n"), "{nc}");
    let (code, _, err) = post_stdin(&[], "UNITS/MM\nGOTO/0,0,0\nGOFWD/S1,TANTO,S2\n");
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("<stdin>:3:1"), "{err}");
    let (code, nc, err) = post_stdin(&[], "UNITS/MM\nFEDRAT/MMPM,1e300\nGOTO/1,0,0\n");
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("<stdin>:2:1") && !nc.contains("F1000"),
        "{err}"
    );
}

/// `--units` sets the units of a program without `UNITS` (no warning
/// then); without either, millimetres and a warning. `--arc-tolerance`
/// sets the chord error of linearised arcs: 0.1 mm needs fewer moves than
/// the default. (The circle is about (1,1,0) with the tool along Z: in no
/// plane of the machine, so it is linearised; one in a plane is a G2/G3.)
#[test]
fn units_and_arc_tolerance_options() {
    let (code, nc, err) = post_stdin(&[], "GOTO/1,0,0\n");
    assert_eq!(code, 0);
    assert!(
        nc.contains("X1.0000 ") && err.contains("millimetres assumed"),
        "{err}"
    );
    let (code, nc, err) = post_stdin(&["--units", "inch"], "GOTO/1,0,0\n");
    assert_eq!(code, 0);
    assert!(
        nc.contains("X25.4000 ") && !err.contains("assumed"),
        "{nc}{err}"
    );
    let arc = "UNITS/MM\nGOTO/0,0,10\nCIRCLE/0,0,0,1,1,0\nGOTO/0,0,10\n";
    let moves = |nc: &str| {
        nc.lines()
            .filter(|l| l.starts_with("G1 ") || l.starts_with('X'))
            .count()
    };
    let (_, fine, _) = post_stdin(&[], arc);
    let (_, coarse, _) = post_stdin(&["--arc-tolerance", "0.1"], arc);
    // Full circle, radius 10: 2π / (2 acos(1 − tol/r)) chords.
    let chords = |tol: f64| (std::f64::consts::TAU / (2.0 * (1.0 - tol / 10.0f64).acos())).ceil();
    assert!(!fine.contains("G2 ") && !fine.contains("G3 "), "{fine}");
    assert_eq!(moves(&fine) as f64, 1.0 + chords(1e-3));
    assert_eq!(moves(&coarse) as f64, 1.0 + chords(0.1));
    let (code, _, _) = post_stdin(&["--arc-tolerance", "0"], arc);
    assert_eq!(code, 2);
}

/// `compensate` converts every SolidWorks program that `post` converts, on
/// the five-axis fixture machines with an error table. Before, APT CL
/// compensation continued each IK from the previous *compensated* axes: at
/// the vertical tool a free C kept its compensated value, and
/// Sacrifice-Board.apt on xyzbc-trt and xyzbc-nutating (and on xyzac-trt)
/// was refused at line 405 with Y beyond its travel, while `post` converted
/// it.
#[test]
fn solidworks_cam_compensate_wherever_post_succeeds() {
    let Some(files) = files() else { return };
    // An X, Y, Z table for the A/C machine: the linear axes of wang2023's.
    let xyz = crate::cl_support::wang_linear_table();
    let dir = std::env::temp_dir().join(format!("kinpost-cl-real-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let xyz_path = dir.join("xyz.csv");
    std::fs::write(&xyz_path, xyz).unwrap();
    let zhao = util::repo_file("fixtures/errors/zhao2022-xzbc.csv");
    let cases = [
        ("fixtures/machines/xyzbc-trt.json", zhao.clone()),
        ("fixtures/machines/xyzbc-nutating.json", zhao.clone()),
        (MACHINE, xyz_path.to_string_lossy().into_owned()),
    ];
    let mut compared = 0;
    for f in &files {
        let f = f.to_str().unwrap();
        for (machine, table) in &cases {
            let machine = util::repo_file(machine);
            let post = kinpost(&["post", "-q", "-m", &machine, f]);
            if !post.status.success() {
                continue;
            }
            let comp = kinpost(&["compensate", "-q", "-m", &machine, "--errors", table, f]);
            assert!(
                comp.status.success(),
                "{f} on {machine}: post converts it, compensate refuses: {}",
                String::from_utf8_lossy(&comp.stderr)
            );
            compared += 1;
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(compared >= 6, "{compared} runs compared");
}
