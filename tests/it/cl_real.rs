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
use std::process::Command;

const DIR: &str = "real/solidworks-cam";
const MACHINE: &str = "fixtures/machines/xyzac-trt.json";
const TOL: f64 = 5e-3;

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn mul(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn len(a: V) -> f64 {
    dot(a, a).sqrt()
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

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

fn kinpost(args: &[&str]) -> std::process::Output {
    Command::new(crate::util::BIN)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .unwrap()
}

/// A piece of tool-tip path in the workpiece (set-up) frame.
#[derive(Debug, Clone)]
enum Piece {
    Line(V, V),
    /// Centre, unit axis, unit start direction, radius, sweep (rad), both
    /// in the set-up frame.
    Arc(V, V, V, f64, f64),
}

impl Piece {
    fn distance(&self, q: V) -> f64 {
        match *self {
            Piece::Line(a, b) => {
                let d = sub(b, a);
                let l2 = dot(d, d);
                let t = if l2 == 0.0 {
                    0.0
                } else {
                    (dot(sub(q, a), d) / l2).clamp(0.0, 1.0)
                };
                len(sub(q, add(a, mul(d, t))))
            }
            Piece::Arc(c, n, u, r, sweep) => {
                let v = cross(n, u);
                let w = sub(q, c);
                let h = dot(w, n);
                let x = dot(w, u);
                let y = dot(w, v);
                let mut th = y.atan2(x);
                if th < 0.0 {
                    th += std::f64::consts::TAU;
                }
                let at = |t: f64| add(c, add(mul(u, r * t.cos()), mul(v, r * t.sin())));
                if th <= sweep {
                    ((x.hypot(y) - r).powi(2) + h * h).sqrt()
                } else {
                    len(sub(q, at(0.0))).min(len(sub(q, at(sweep))))
                }
            }
        }
    }

    fn samples(&self, step: f64) -> Vec<V> {
        match *self {
            Piece::Line(a, b) => {
                let n = (len(sub(b, a)) / step).ceil().max(1.0) as usize;
                (0..=n)
                    .map(|k| add(a, mul(sub(b, a), k as f64 / n as f64)))
                    .collect()
            }
            Piece::Arc(c, n, u, r, sweep) => {
                let v = cross(n, u);
                let k = (r * sweep / step).ceil().max(1.0) as usize;
                (0..=k)
                    .map(|i| {
                        let t = sweep * i as f64 / k as f64;
                        add(c, add(mul(u, r * t.cos()), mul(v, r * t.sin())))
                    })
                    .collect()
            }
        }
    }
}

/// What the test reads from the CL file itself.
#[derive(Default)]
struct ClPath {
    pieces: Vec<Piece>,
    holes: Vec<V>,
    tools: Vec<u32>,
    spindles: Vec<String>,
    cutcom_left: usize,
    cutcom_off: usize,
}

fn nums(s: &str) -> Vec<f64> {
    s.split(',').filter_map(|x| x.trim().parse().ok()).collect()
}

/// The CL path: `CSYS` columns are the set-up axes in the CL frame, so a
/// point `p` is `Rᵀ (p − t)` in the set-up frame. Arcs run counter-clockwise
/// about the `CIRCLE` axis; a hole under `CYCLE` runs from `RTRCTO` above
/// the point down to `FEDTO` below it and back.
fn cl_path(text: &str) -> ClPath {
    let mut out = ClPath::default();
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut t = [0.0; 3];
    let mut axis = [0.0, 0.0, 1.0];
    let mut pos: Option<V> = None; // set-up frame
    let mut circle: Option<(V, V)> = None;
    let mut cycle: Option<(f64, f64, f64)> = None;
    for line in text.lines() {
        let line = line.trim();
        let (major, args) = line.split_once('/').unwrap_or((line, ""));
        let to_setup = |p: V, r: &[[f64; 3]; 3], t: V| {
            let d = sub(p, t);
            [
                r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2],
                r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2],
                r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2],
            ]
        };
        match major {
            "CSYS" => {
                let v = nums(args);
                r = [[v[0], v[1], v[2]], [v[4], v[5], v[6]], [v[8], v[9], v[10]]];
                t = [v[3], v[7], v[11]];
            }
            "LOAD" => out.tools.push(nums(args)[0] as u32),
            "SPINDL" => {
                let v = nums(args);
                out.spindles.push(format!("S{} M3", v[0]));
            }
            "CUTCOM" if args.starts_with("LEFT") => out.cutcom_left += 1,
            "CUTCOM" if args.starts_with("OFF") => out.cutcom_off += 1,
            "CIRCLE" => {
                let v = nums(args);
                circle = Some(([v[0], v[1], v[2]], [v[3], v[4], v[5]]));
            }
            "CYCLE" => {
                let w: Vec<&str> = args.split(',').collect();
                if w[0] == "OFF" {
                    cycle = None;
                } else if w[0] != "INIT" {
                    let val = |k: &str| {
                        w.iter()
                            .position(|x| *x == k)
                            .map(|i| w[i + 1].parse::<f64>().unwrap())
                            .unwrap_or(0.0)
                    };
                    cycle = Some((val("FEDTO"), val("RAPTO"), val("RTRCTO")));
                }
            }
            "GOTO" => {
                let v = nums(args);
                let p = [v[0], v[1], v[2]];
                if v.len() == 6 {
                    axis = [v[3], v[4], v[5]];
                }
                let a = to_setup(axis, &r, [0.0; 3]);
                let a = mul(a, 1.0 / len(a));
                let q = to_setup(p, &r, t);
                if let Some((c, n)) = circle.take() {
                    let start = pos.expect("arc start");
                    let c = to_setup(c, &r, t);
                    let n = to_setup(n, &r, [0.0; 3]);
                    let n = mul(n, 1.0 / len(n));
                    let s = sub(start, c);
                    let s = sub(s, mul(n, dot(s, n)));
                    let e = sub(q, c);
                    let e = sub(e, mul(n, dot(e, n)));
                    let u = mul(s, 1.0 / len(s));
                    let v = cross(n, u);
                    let mut sweep = dot(e, v).atan2(dot(e, u));
                    if sweep <= 1e-9 {
                        sweep += std::f64::consts::TAU;
                    }
                    out.pieces.push(Piece::Arc(c, n, u, len(s), sweep));
                } else if let Some((depth, rapto, rtrcto)) = cycle {
                    let clear = add(q, mul(a, rtrcto));
                    let bottom = add(q, mul(a, -depth));
                    if let Some(from) = pos {
                        out.pieces.push(Piece::Line(from, clear));
                    }
                    out.pieces.push(Piece::Line(clear, add(q, mul(a, rapto))));
                    out.pieces.push(Piece::Line(add(q, mul(a, rapto)), bottom));
                    out.pieces.push(Piece::Line(bottom, clear));
                    out.holes.push(bottom);
                    pos = Some(clear);
                    continue;
                } else if let Some(from) = pos {
                    out.pieces.push(Piece::Line(from, q));
                }
                pos = Some(q);
            }
            _ => {}
        }
    }
    out
}

/// Tool tip in the workpiece frame of fixtures/machines/xyzac-trt.json, by
/// hand: `Rz(−C) · ((0,0,−60) + Rx(−A) · ((X,Y,Z) + (0,0,60)))`.
fn forward(x: f64, y: f64, z: f64, a_deg: f64, c_deg: f64) -> V {
    let (sa, ca) = (-a_deg.to_radians()).sin_cos();
    let (sc, cc) = (-c_deg.to_radians()).sin_cos();
    let p = [x, y, z + 60.0];
    let p = [p[0], ca * p[1] - sa * p[2], sa * p[1] + ca * p[2]];
    let p = [p[0], p[1], p[2] - 60.0];
    [cc * p[0] - sc * p[1], sc * p[0] + cc * p[1], p[2]]
}

/// Tool-tip points of the output's motion blocks.
fn output_points(nc: &str) -> Vec<V> {
    let mut pts = Vec::new();
    let mut q = [0.0f64; 5];
    for line in nc.lines() {
        if line.starts_with('(') {
            continue;
        }
        let mut moved = false;
        for w in line.split_whitespace() {
            let (l, v) = w.split_at(1);
            let k = match l {
                "X" => 0,
                "Y" => 1,
                "Z" => 2,
                "A" => 3,
                "C" => 4,
                _ => continue,
            };
            q[k] = v.parse().unwrap();
            moved = true;
        }
        if moved {
            pts.push(forward(q[0], q[1], q[2], q[3], q[4]));
        }
    }
    pts
}

/// Fold step: the first candidate within the tolerance (the path may pass
/// the same place again later), else the nearest.
fn first_within(a: (usize, f64), b: (usize, f64)) -> (usize, f64) {
    if a.1 <= TOL || b.1 >= a.1 { a } else { b }
}

fn seg_distance(q: V, a: V, b: V) -> f64 {
    Piece::Line(a, b).distance(q)
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
        let pts = output_points(&nc);

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

        // Every hole reaches its bottom.
        for h in &cl.holes {
            assert!(
                pts.iter().any(|p| len(sub(*p, *h)) < 1e-3),
                "{name}: hole bottom {h:?} missing"
            );
        }

        // Output → CL: every output vertex and segment midpoint lies on the
        // CL path (pieces searched in a window that moves forward).
        let mut j: usize = 0;
        let mut worst_out = 0.0f64;
        for (i, p) in pts.iter().enumerate() {
            let mut probes = vec![*p];
            if i > 0 {
                probes.push(mul(add(*p, pts[i - 1]), 0.5));
            }
            for q in probes {
                let lo = j.saturating_sub(2);
                let hi = (j + 60).min(cl.pieces.len());
                let ds: Vec<(usize, f64)> =
                    (lo..hi).map(|k| (k, cl.pieces[k].distance(q))).collect();
                let (bj, _) = ds.iter().copied().fold((j, f64::INFINITY), first_within);
                let d = ds.iter().map(|x| x.1).fold(f64::INFINITY, f64::min);
                assert!(
                    d <= TOL,
                    "{name}: output point {i} {q:?} is {d} mm off the CL path (piece {bj})"
                );
                worst_out = worst_out.max(d);
                j = bj;
            }
        }
        // CL → output: points sampled along the CL path lie on the output
        // polyline.
        let mut k: usize = 1;
        let mut worst_cl = 0.0f64;
        for (pi, piece) in cl.pieces.iter().enumerate() {
            for q in piece.samples(0.2) {
                let lo = k.saturating_sub(3).max(1);
                let hi = (k + 3000).min(pts.len());
                let ds: Vec<(usize, f64)> = (lo..hi)
                    .map(|m| (m, seg_distance(q, pts[m - 1], pts[m])))
                    .collect();
                let (bk, _) = ds.iter().copied().fold((k, f64::INFINITY), first_within);
                let d = ds.iter().map(|x| x.1).fold(f64::INFINITY, f64::min);
                assert!(
                    d <= TOL,
                    "{name}: CL piece {pi} point {q:?} is {d} mm off the output path"
                );
                worst_cl = worst_cl.max(d);
                k = bk;
            }
        }
        println!(
            "{name}: {} CL pieces, {} holes, {} output points; worst output→CL {:.4} µm, CL→output {:.4} µm",
            cl.pieces.len(),
            cl.holes.len(),
            pts.len(),
            worst_out * 1e3,
            worst_cl * 1e3
        );
    }
}

fn post_stdin(args: &[&str], input: &str) -> (i32, String, String) {
    use std::io::Write;
    let mut child = Command::new(crate::util::BIN)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["post", "-m", MACHINE, "--input-kind", "cl"])
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
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
/// sets the chord error: 0.1 mm needs fewer moves than the default.
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
    let arc = "UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/10,0,0\n";
    let moves = |nc: &str| nc.lines().filter(|l| l.contains('X')).count();
    let (_, fine, _) = post_stdin(&[], arc);
    let (_, coarse, _) = post_stdin(&["--arc-tolerance", "0.1"], arc);
    // Full circle, radius 10: 2π / (2 acos(1 − tol/r)) chords.
    let chords = |tol: f64| (std::f64::consts::TAU / (2.0 * (1.0 - tol / 10.0f64).acos())).ceil();
    assert_eq!(moves(&fine) as f64, 1.0 + chords(1e-3));
    assert_eq!(moves(&coarse) as f64, 1.0 + chords(0.1));
    let (code, _, _) = post_stdin(&["--arc-tolerance", "0"], arc);
    assert_eq!(code, 2);
}
