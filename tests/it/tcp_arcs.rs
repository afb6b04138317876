//! Circular moves (`G2`/`G3`) under tool centre point control: the tip on
//! the arc in the program's coordinates, the tool axis held. `post`,
//! `compensate`, `analyze` and `simulate` convert them as straight moves
//! through the arc's points; before session 35 every such block was
//! refused. Each written point is checked by the forward chain against
//! the arc as this test computes it from the program's words.

use crate::util::{letter_words as words, run_on};
use kinpost::geometric::model::ErrorModel;
use kinpost::machine::{Machine, NoErrors};
use nalgebra::Vector3;
use std::path::Path;

/// The machine positions (X Y Z A C, mm and degrees) of the moves of
/// `out` between the comments `(arc N)` and `(end N)`, for each N in
/// order, following G90/G91 and G20/G21.
fn sections(out: &str, letters: &str) -> Vec<Vec<Vec<f64>>> {
    let mut position = vec![0.0; letters.len()];
    let mut incremental = false;
    let mut mm_per_unit = 1.0;
    let mut all = Vec::new();
    let mut current: Option<Vec<Vec<f64>>> = None;
    for line in out.lines() {
        if line.contains("(arc") {
            current = Some(vec![position.clone()]);
        }
        let ws = words(line);
        for &(a, v) in &ws {
            if a == 'G' && v == 91.0 {
                incremental = true;
            }
            if a == 'G' && v == 90.0 {
                incremental = false;
            }
            if a == 'G' && (v == 20.0 || v == 21.0) {
                mm_per_unit = if v == 20.0 { 25.4 } else { 1.0 };
            }
        }
        let mut moved = false;
        for (a, v) in ws {
            if let Some(k) = letters.find(a) {
                let v = if "XYZ".contains(a) {
                    v * mm_per_unit
                } else {
                    v
                };
                position[k] = if incremental { position[k] + v } else { v };
                moved = true;
            }
        }
        if moved && let Some(c) = current.as_mut() {
            c.push(position.clone());
        }
        if line.contains("(end") {
            all.push(current.take().expect("an (arc) before each (end)"));
        }
    }
    all
}

/// An arc as the program gives it: centre, normal (the plane's), radius,
/// sense (+1 counter-clockwise about the normal), start and end (mm).
struct Arc {
    centre: Vector3<f64>,
    normal: Vector3<f64>,
    ccw: bool,
    start: Vector3<f64>,
    end: Vector3<f64>,
    /// Angle swept, rad.
    sweep: f64,
}

/// Checks the tips `tips` (the arc's start, then each written point) of
/// `arc`: each on the helix within 1e-6 mm, each chord's middle within
/// `tol` of it, the angle growing in the arc's sense up to the sweep, the
/// last at the end; returns the number of moves.
fn check_arc(name: &str, tips: &[Vector3<f64>], arc: &Arc, tol: f64) -> usize {
    let n = arc.normal;
    let along = |p: Vector3<f64>| (p - arc.centre).dot(&n);
    let radial = |p: Vector3<f64>| {
        let d = p - arc.centre;
        d - n * d.dot(&n)
    };
    let r = radial(arc.start).norm();
    let u = radial(arc.start) / r;
    let v = n.cross(&u);
    let sign = if arc.ccw { 1.0 } else { -1.0 };
    let mut last_angle = 0.0;
    let mut turns = 0.0;
    let mut previous_raw = 0.0;
    assert!(
        (tips[0] - arc.start).norm() < 1e-6,
        "{name}: start {:?}",
        tips[0]
    );
    for (k, p) in tips.iter().enumerate().skip(1) {
        let d = radial(*p);
        assert!(
            (d.norm() - r).abs() < 1e-6,
            "{name} point {k}: radius {} against {r}",
            d.norm()
        );
        let raw = (sign * d.dot(&v).atan2(d.dot(&u))).rem_euclid(std::f64::consts::TAU);
        if raw < previous_raw - 1e-9 {
            turns += std::f64::consts::TAU;
        }
        previous_raw = raw;
        let angle = raw + turns;
        let angle = if k + 1 == tips.len() && angle < 1e-9 {
            arc.sweep
        } else {
            angle
        };
        assert!(
            angle > last_angle,
            "{name} point {k}: angle {angle} after {last_angle}"
        );
        assert!(
            angle <= arc.sweep + 1e-7,
            "{name} point {k}: beyond the sweep"
        );
        // The height along the normal in proportion to the angle (a helix).
        let h = along(arc.start) + (along(arc.end) - along(arc.start)) * angle / arc.sweep;
        assert!((along(*p) - h).abs() < 1e-6, "{name} point {k}: height");
        // The chord's middle: the machine moves its linear axes straight,
        // the rotaries still, so the part sees the chord.
        let middle = (tips[k - 1] + p) / 2.0;
        let sag = r - radial(middle).norm();
        assert!(sag <= tol + 1e-9, "{name} chord {k}: {sag} mm from the arc");
        last_angle = angle;
    }
    assert!(
        (tips[tips.len() - 1] - arc.end).norm() < 1e-6,
        "{name}: end"
    );
    assert!(
        (last_angle - arc.sweep).abs() < 1e-7,
        "{name}: swept {last_angle}"
    );
    tips.len() - 1
}

/// Arcs in each plane, by centre and by radius, a helix, a full circle, an
/// incremental arc and one in inch, with the tool tilted 30° on a
/// table-table machine: every written point lies on the arc, every chord
/// within the arc tolerance of it, the rotaries still, and no more moves
/// than a chord tolerance needs.
#[test]
fn arcs_under_tcp_are_written_as_chords_of_the_arc() {
    let program = "G21 G90 G17 G94\nG43.4 H1\nG1 X10 Y0 Z5 I0 J-0.5 K0.8660254038 F500\n\
                   (arc 1)\nG3 X0 Y10 I-10 J0\n(end 1)\n\
                   (arc 2)\nG2 X10 Y0 R10\n(end 2)\n\
                   (arc 3)\nG3 X10 Y0 Z2 I-10 J0\n(end 3)\n\
                   (arc 4)\nG18 G2 X20 Z2 I5 K0\n(end 4)\n\
                   (arc 5)\nG19 G3 Y4 Z6 J2 K2\n(end 5)\n\
                   (arc 6)\nG17 G91 G2 X-4 Y-4 I-4 J0\nG90\n(end 6)\n\
                   (arc 7)\nG20 G3 X0.2362204724 Y0 I-0.1968503937 J0\nG21\n(end 7)\n\
                   G49\nM30\n";
    let y = Vector3::y();
    let (x, z) = (Vector3::x(), Vector3::z());
    let tau = std::f64::consts::TAU;
    let pi = std::f64::consts::PI;
    let v = |a: f64, b: f64, c: f64| Vector3::new(a, b, c);
    let arcs = [
        Arc {
            centre: v(0.0, 0.0, 5.0),
            normal: z,
            ccw: true,
            start: v(10.0, 0.0, 5.0),
            end: v(0.0, 10.0, 5.0),
            sweep: pi / 2.0,
        },
        Arc {
            centre: v(0.0, 0.0, 5.0),
            normal: z,
            ccw: false,
            start: v(0.0, 10.0, 5.0),
            end: v(10.0, 0.0, 5.0),
            sweep: pi / 2.0,
        },
        Arc {
            centre: v(0.0, 0.0, 5.0),
            normal: z,
            ccw: true,
            start: v(10.0, 0.0, 5.0),
            end: v(10.0, 0.0, 2.0),
            sweep: tau,
        },
        // G18: the plane Z X, normal +Y; G2 clockwise seen from +Y.
        Arc {
            centre: v(15.0, 0.0, 2.0),
            normal: y,
            ccw: false,
            start: v(10.0, 0.0, 2.0),
            end: v(20.0, 0.0, 2.0),
            sweep: pi,
        },
        // G19: the plane Y Z, normal +X; centre (y, z) = (2, 4).
        Arc {
            centre: v(20.0, 2.0, 4.0),
            normal: x,
            ccw: true,
            start: v(20.0, 0.0, 2.0),
            end: v(20.0, 4.0, 6.0),
            sweep: pi,
        },
        Arc {
            centre: v(16.0, 4.0, 6.0),
            normal: z,
            ccw: false,
            start: v(20.0, 4.0, 6.0),
            end: v(16.0, 0.0, 6.0),
            sweep: pi / 2.0,
        },
        // Inch: from (16, 0) to (6, 0) mm about (11, 0): 6 mm is 0.23622 in,
        // the centre 5 mm (0.19685 in) to the left of the start.
        Arc {
            centre: v(11.0, 0.0, 6.0),
            normal: z,
            ccw: true,
            start: v(16.0, 0.0, 6.0),
            end: v(6.0, 0.0, 6.0),
            sweep: pi,
        },
    ];
    let machine = Machine::embedded("xyzac-trt").unwrap();
    for tol in [0.001, 0.05] {
        let t = tol.to_string();
        let args = [
            "post",
            "--machine",
            "xyzac-trt",
            "--decimals",
            "9",
            "--arc-tolerance",
            &t,
        ];
        let (code, out, err) = run_on(&args, "arcs.ngc", program);
        assert_eq!(code, 0, "{err}");
        // No arc is left: every move is straight.
        let codes = out.lines().flat_map(words).filter(|&(a, _)| a == 'G');
        assert!(codes.clone().all(|(_, v)| v != 2.0 && v != 3.0), "{out}");
        assert!(!out.contains(" R10") && !out.contains("I-"), "{out}");
        let found = sections(&out, "XYZAC");
        assert_eq!(found.len(), arcs.len());
        for (i, (positions, arc)) in found.iter().zip(&arcs).enumerate() {
            let name = format!("arc {} at {tol} mm", i + 1);
            let tips: Vec<Vector3<f64>> = positions
                .iter()
                .map(|p| {
                    assert!(
                        (p[3] + 30.0).abs() < 1e-9 && p[4].abs() < 1e-9,
                        "{name}: {p:?}"
                    );
                    machine.chain.pose(&machine.to_internal(p), &NoErrors).tip
                })
                .collect();
            let moves = check_arc(&name, &tips, arc, tol);
            let r =
                (arc.start - arc.centre - arc.normal * (arc.start - arc.centre).dot(&arc.normal))
                    .norm();
            let step = 2.0 * (1.0 - tol / r).acos();
            assert!(
                moves <= (arc.sweep / step).ceil() as usize,
                "{name}: {moves} moves"
            );
        }
    }
}

/// The arc's block keeps its other words (number, feed, coolant, comment)
/// and its line end on the first move; the later moves are blocks of their
/// own with the same line end. Orientation by rotary positions (`G43.4`
/// type 1, `TRAORI`) holds them through the arc, and Sinumerik's `CR=` and
/// `TURN=` are read.
#[test]
fn arcs_keep_their_words_and_rotary_positions() {
    let program = "G21 G90 G17\r\nG43.4 H1\r\nG0 X10 Y0 Z5 A20 C30\r\n\
                   N10 G2 X0 Y-10 I-10 J0 F300 M8 (quarter)\r\nG1 X5\r\nG49\r\nM30\r\n";
    let args = ["post", "--machine", "xyzac-trt", "--arc-tolerance", "0.01"];
    let (code, out, err) = run_on(&args, "words.ngc", program);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.split_inclusive('\n').collect();
    assert!(lines.iter().all(|l| l.ends_with("\r\n")), "{out:?}");
    assert!(
        lines[3].starts_with("N10 G1 X") && lines[3].ends_with(" F300 M8 (quarter)\r\n"),
        "{out}"
    );
    let arc: Vec<&&str> = lines[3..]
        .iter()
        .take_while(|l| !l.starts_with("G1 X5") && l.contains(" A"))
        .collect();
    assert!(arc.len() > 5, "{out}");
    for l in &arc {
        assert!(l.contains(" A20.0000 C30.0000"), "{l}");
        assert!(!l.contains(" I") && !l.contains(" J"), "{l}");
    }
    for l in &arc[1..] {
        assert!(l.starts_with("G1 X"), "{l}");
    }
    // Sinumerik: the radius by CR=, a full turn added by TURN=.
    let traori = "G71 G90 G17\nTRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F300\n\
                  (arc 1)\nG3 X-10 Y0 CR=10\n(end 1)\n(arc 2)\nG2 X10 Y0 I10 J0 TURN=1\n(end 2)\n\
                  TRAFOOF\nM30\n";
    let machine = Machine::embedded("xyzac-trt").unwrap();
    let args = ["post", "--machine", "xyzac-trt", "--decimals", "9"];
    let (code, out, err) = run_on(&args, "traori.mpf", traori);
    assert_eq!(code, 0, "{err}");
    let found: Vec<Vec<Vector3<f64>>> = sections(&out, "XYZAC")
        .iter()
        .map(|s| {
            s.iter()
                .map(|p| machine.chain.pose(&machine.to_internal(p), &NoErrors).tip)
                .collect()
        })
        .collect();
    let pi = std::f64::consts::PI;
    let z = Vector3::z();
    let v = |a: f64, b: f64| Vector3::new(a, b, 5.0);
    let half = Arc {
        centre: v(0.0, 0.0),
        normal: z,
        ccw: true,
        start: v(10.0, 0.0),
        end: v(-10.0, 0.0),
        sweep: pi,
    };
    check_arc("CR=", &found[0], &half, 0.001);
    // One turn and a half, clockwise: the second arc's points follow.
    let turn_and_half = Arc {
        centre: v(0.0, 0.0),
        normal: z,
        ccw: false,
        start: v(-10.0, 0.0),
        end: v(10.0, 0.0),
        sweep: 3.0 * pi,
    };
    check_arc("TURN=", &found[1], &turn_and_half, 0.001);
}

/// What the arc conversion cannot do right is refused at the word: an arc
/// that turns the tool, one the block delete switch may skip, or after a
/// skippable block changed its plane, under inverse time, from where the
/// program does not say, with a centre word outside its plane, Sinumerik
/// `CIP`; `linkage` (which divides one block into segments) refuses arcs
/// in pose mode as before.
#[test]
fn arcs_that_cannot_be_converted_are_refused_at_the_word() {
    let start = "G21 G90 G17\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F300\n";
    let rotary = "G21 G90 G17\nG43.4 H1\nG0 X10 Y0 Z5 A20 C30\n";
    for (args, name, program, at, says) in [
        (
            &["post"][..],
            "rotary.ngc",
            format!("{rotary}G2 X0 Y-10 R10 C40\nM30\n"),
            "rotary.ngc:4:16:",
            "`C40` gives the tool orientation in a circular move",
        ),
        (
            &["post"][..],
            "vector.mpf",
            "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1\nG2 X0 Y-10 CR=10 A3=0.1 B3=0 C3=1\nM30\n"
                .to_string(),
            "vector.mpf:3:18:",
            "`A3=0.1` gives the tool orientation in a circular move",
        ),
        (
            &["post"][..],
            "slash.ngc",
            format!("{start}/G2 X0 Y-10 R10\nM30\n"),
            "slash.ngc:4:1:",
            "may skip",
        ),
        (
            &["post"][..],
            "plane.ngc",
            format!("{start}/G18\nG2 X0 Y-10 R10\nM30\n"),
            "plane.ngc:5:1:",
            "block delete switch on the arc runs otherwise",
        ),
        (
            &["post"][..],
            "g93.ngc",
            format!("{start}G93 G2 X0 Y-10 R10 F2\nM30\n"),
            "g93.ngc:4:5:",
            "inverse-time feed",
        ),
        (
            &["post", "--feed", "inverse-time"][..],
            "inverse.ngc",
            format!("{start}G2 X0 Y-10 R10\nM30\n"),
            "inverse.ngc:4:1:",
            "inverse-time feed",
        ),
        (
            &["post"][..],
            "home.ngc",
            format!("{start}G91 G28 Z0\nG90\nG2 X0 Y-10 Z5 R10\nM30\n"),
            "home.ngc:6:1:",
            "where the tool tip is not known",
        ),
        (
            &["post"][..],
            "plane_k.ngc",
            format!("{start}G2 X0 Y-10 I-10 J0 K1\nM30\n"),
            "plane_k.ngc:4:20:",
            "outside the plane of the arc (G17: I J)",
        ),
        (
            &["post"][..],
            "cip.mpf",
            "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1\nCIP X0 Y-10 I1=5 J1=-5\nM30\n".to_string(),
            "cip.mpf:3:1:",
            "`CIP` is not followed",
        ),
        (
            &["post"][..],
            "radius.ngc",
            format!("{start}G2 X0 Y-10 I-12 J0\nM30\n"),
            "radius.ngc:4:",
            "its centre is not where I J put it",
        ),
        (
            &["linkage"][..],
            "linkage.ngc",
            format!("{start}G2 X0 Y-10 R10\nM30\n"),
            "linkage.ngc:4:4:",
            "cannot be converted in pose mode here",
        ),
        (
            &["post"][..],
            "inherit.ngc",
            format!("{start}G2 X0 Y-10 R10\nG49\nX-10 Y0\nM30\n"),
            "inherit.ngc:6:1:",
            "which kinpost wrote as straight moves (G1)",
        ),
        (
            &["post"][..],
            "both.ngc",
            format!("{start}G2 X0 Y-10 I-10 J0 R10\nM30\n"),
            "both.ngc:4:20:",
            "both its centre (I J) and its radius",
        ),
    ] {
        let mut all = args.to_vec();
        all.extend(["--machine", "xyzac-trt"]);
        let (code, out, err) = run_on(&all, name, &program);
        assert_eq!(code, 1, "{name}: {out}{err}");
        assert!(err.contains(at) && err.contains(says), "{name}: {err}");
    }
}

/// `compensate` puts the real tool on the arc: its axis words, evaluated
/// through the machine with its measured errors, land on the points `post`
/// writes (the nominal chain's), within 1e-6 mm; `analyze` and `simulate`
/// read the same points.
#[test]
fn compensate_analyze_and_simulate_follow_the_arc() {
    let program = "G21 G90 G17\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0.3 K0.9539392014 F500\n\
                   G3 X0 Y10 I-10 J0\nG2 X-10 Y20 Z3 R10\nG49\nM30\n";
    let machine = Machine::embedded("wang2023-xyzab").unwrap();
    let errors = format!(
        "{}/fixtures/errors/wang2023-xyzab.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let model = ErrorModel::load(Path::new(&errors)).unwrap();
    let bound = model.bind(&machine.chain).unwrap();
    let actual = model.apply_fixed(&machine.chain).unwrap();
    let letters: String = machine.axes.iter().map(|a| a.name.clone()).collect();
    let positions = |out: &str| -> Vec<Vec<f64>> {
        out.lines()
            .filter(|l| l.starts_with("G1 "))
            .map(|l| {
                let mut p = vec![0.0; letters.len()];
                for (a, v) in words(l) {
                    if let Some(k) = letters.find(a) {
                        p[k] = v;
                    }
                }
                p
            })
            .collect()
    };
    let post = ["post", "--machine", "wang2023-xyzab", "--decimals", "9"];
    let (code, nominal, err) = run_on(&post, "arc.ngc", program);
    assert_eq!(code, 0, "{err}");
    let compensate = [
        "compensate",
        "--machine",
        "wang2023-xyzab",
        "--decimals",
        "9",
        "-e",
        &errors,
    ];
    let (code, real, err) = run_on(&compensate, "arc.ngc", program);
    assert_eq!(code, 0, "{err}");
    let (want, got) = (positions(&nominal), positions(&real));
    assert_eq!(want.len(), got.len());
    assert!(want.len() > 100, "{nominal}");
    for (w, g) in want.iter().zip(&got) {
        let target = machine.chain.pose(&machine.to_internal(w), &NoErrors);
        let landed = actual.pose(&machine.to_internal(g), &bound);
        assert!(landed.tip_distance(&target) < 1e-6, "{w:?} {g:?}");
        assert!(landed.axis_angle(&target) < 1e-9, "{w:?} {g:?}");
    }
    let (code, out, err) = run_on(
        &["analyze", "--machine", "wang2023-xyzab", "-e", &errors],
        "arc.ngc",
        program,
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains(&format!("{} poses", want.len())), "{out}");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("arc.ngc");
    std::fs::write(&p, program).unwrap();
    let sim = std::process::Command::new(crate::util::BIN)
        .args(["simulate", "--machine", "wang2023-xyzab", "--program"])
        .arg(&p)
        .output()
        .unwrap();
    assert_eq!(sim.status.code(), Some(0));
    let text = String::from_utf8_lossy(&sim.stdout);
    let lines: std::collections::BTreeSet<&str> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(1))
        .collect();
    assert!(lines.contains("4") && lines.contains("5"), "{text}");
}

/// The arc mode is modal as on the controller: a pose block after an arc
/// without a motion code is an arc too, and one with its own `G2` after
/// TCP is off passes through as it came.
#[test]
fn the_arc_mode_is_modal() {
    let program = "G21 G90 G17\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n\
                   G2 X0 Y-10 R10\nX-10 Y0 R10\nG49\nG2 X0 Y10 R10\nM30\n";
    let args = ["post", "--machine", "xyzac-trt", "--arc-tolerance", "0.1"];
    let (code, out, err) = run_on(&args, "modal.ngc", program);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    // Two quarter circles of radius 10 at 0.1 mm: 6 chords each (the
    // chord angle 2·acos(0.99) = 16.2°).
    let moves = lines.iter().filter(|l| l.starts_with("G1 X")).count();
    assert_eq!(moves, 1 + 6 + 6, "{out}");
    assert!(
        out.contains("X-10.0000 Y0.0000 Z5.0000 A0.0000 C0.0000\nG49\nG2 X0 Y10 R10\n"),
        "{out}"
    );
}
