//! Shared helpers of the APT CL tests: an evaluation of the CL path of its
//! own (lines, arcs about their axes, helices, drilled holes, `CSYS`
//! set-ups), an evaluation of the written G-code of its own (`G0`/`G1`,
//! `G2`/`G3` in `G17`/`G18`/`G19` sampled on the arc, canned cycles `G73`,
//! `G81`…`G89` with `G98`/`G99`) through hand-written forward kinematics,
//! and the check that the two paths agree both ways. Nothing here calls
//! the converter's geometry.
#![allow(dead_code)]

use std::process::Command;

/// Agreement asked of the two paths, mm.
pub const TOL: f64 = 5e-3;

pub type V = [f64; 3];

pub fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub fn mul(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub fn len(a: V) -> f64 {
    dot(a, a).sqrt()
}
pub fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn kinpost(args: &[&str]) -> std::process::Output {
    Command::new(crate::util::BIN)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .unwrap()
}

/// `kinpost post -m machine --input-kind cl args` on `input`: exit code,
/// stdout, stderr.
pub fn post_stdin(machine: &str, args: &[&str], input: &str) -> (i32, String, String) {
    let mut all = vec!["post", "-m", machine];
    all.extend_from_slice(args);
    cl_stdin(&all, input)
}

/// `kinpost args --input-kind cl -` with `input` on standard input: exit
/// code, stdout, stderr.
pub fn cl_stdin(args: &[&str], input: &str) -> (i32, String, String) {
    use std::io::Write;
    let mut child = Command::new(crate::util::BIN)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .args(["--input-kind", "cl", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // A command that stops before it reads its input (a usage error)
    // closes the pipe: its exit code says why.
    let written = child.stdin.take().unwrap().write_all(input.as_bytes());
    if let Err(e) = written {
        assert_eq!(e.kind(), std::io::ErrorKind::BrokenPipe, "{e}");
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A piece of tool-tip path in the workpiece (set-up) frame.
#[derive(Debug, Clone)]
pub enum Piece {
    Line(V, V),
    /// Centre, unit axis, unit start direction, radius, sweep (rad), rise
    /// along the axis over the sweep.
    Arc(V, V, V, f64, f64, f64),
}

impl Piece {
    fn at(c: V, n: V, u: V, r: f64, t: f64, h: f64) -> V {
        let v = cross(n, u);
        add(
            c,
            add(add(mul(u, r * t.cos()), mul(v, r * t.sin())), mul(n, h)),
        )
    }

    pub fn distance(&self, q: V) -> f64 {
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
            Piece::Arc(c, n, u, r, sweep, rise) if rise.abs() < 1e-9 => {
                let v = cross(n, u);
                let w = sub(q, c);
                let (h, x, y) = (dot(w, n), dot(w, u), dot(w, v));
                let th = y.atan2(x).rem_euclid(std::f64::consts::TAU);
                if th <= sweep {
                    ((x.hypot(y) - r).powi(2) + h * h).sqrt()
                } else {
                    let end = Piece::at(c, n, u, r, sweep, 0.0);
                    len(sub(q, Piece::at(c, n, u, r, 0.0, 0.0))).min(len(sub(q, end)))
                }
            }
            Piece::Arc(c, n, u, r, sweep, rise) => {
                // A helix: the nearest of a fine sampling, refined on the
                // chords to its two neighbours.
                let k = ((r * sweep / 0.01).ceil() as usize).clamp(8, 200_000);
                let pt = |i: f64| Piece::at(c, n, u, r, sweep * i / k as f64, rise * i / k as f64);
                let mut best = (f64::INFINITY, 0usize);
                for i in 0..=k {
                    let d = len(sub(q, pt(i as f64)));
                    if d < best.0 {
                        best = (d, i);
                    }
                }
                let i = best.1 as f64;
                let lo = (i - 1.0).max(0.0);
                let hi = (i + 1.0).min(k as f64);
                let seg = |a: f64, b: f64| Piece::Line(pt(a), pt(b)).distance(q);
                best.0.min(seg(lo, i)).min(seg(i, hi))
            }
        }
    }

    pub fn samples(&self, step: f64) -> Vec<V> {
        match *self {
            Piece::Line(a, b) => {
                let n = (len(sub(b, a)) / step).ceil().max(1.0) as usize;
                (0..=n)
                    .map(|k| add(a, mul(sub(b, a), k as f64 / n as f64)))
                    .collect()
            }
            Piece::Arc(c, n, u, r, sweep, rise) => {
                let k = (r * sweep / step).ceil().max(1.0) as usize;
                (0..=k)
                    .map(|i| {
                        let f = i as f64 / k as f64;
                        Piece::at(c, n, u, r, sweep * f, rise * f)
                    })
                    .collect()
            }
        }
    }
}

/// What a test reads from a CL file itself.
#[derive(Default, Debug)]
pub struct ClPath {
    pub pieces: Vec<Piece>,
    pub holes: Vec<V>,
    /// The `CYCLE` arguments of each hole.
    pub hole_cycles: Vec<String>,
    pub tools: Vec<u32>,
    pub spindles: Vec<String>,
    pub cutcom_left: usize,
    pub cutcom_off: usize,
}

fn nums(s: &str) -> Vec<f64> {
    s.split(',').filter_map(|x| x.trim().parse().ok()).collect()
}

/// The logical statements of a CL file: `$` continuations joined, `$$`
/// comments dropped, the major word trimmed and uppercased.
pub fn statements(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut acc = String::new();
    for line in text.lines() {
        let line = match line.find("$$") {
            Some(i) => &line[..i],
            None => line,
        };
        let line = line.trim();
        if let Some(head) = line.strip_suffix('$') {
            acc.push_str(head);
            continue;
        }
        acc.push_str(line);
        let s = std::mem::take(&mut acc);
        if s.is_empty() {
            continue;
        }
        let (major, args) = s.split_once('/').unwrap_or((&s, ""));
        out.push((major.trim().to_ascii_uppercase(), args.trim().to_string()));
    }
    out
}

/// The CL path: `CSYS` columns are the set-up axes in the CL frame, so a
/// point `p` is `Rᵀ (p − t)` in the set-up frame, and the tool axis is the
/// set-up's Z until a `GOTO` or `TLAXIS` gives another. Arcs run counter-clockwise
/// about the `CIRCLE` axis (clockwise after a Siemens NX statement, `TOOL
/// PATH`, `TLDATA` or `MSYS`, as NX's CLSF manual says), a difference along the axis a helix; a hole
/// under `CYCLE` runs from `RTRCTO` above the point down to `FEDTO` below
/// it and back. `UNITS/INCHES` scales by 25.4.
pub fn cl_path(text: &str) -> ClPath {
    let mut out = ClPath::default();
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut t = [0.0; 3];
    let mut axis = [0.0, 0.0, 1.0];
    let mut unit = 1.0;
    let mut pos: Option<V> = None; // set-up frame, mm
    let mut circle: Option<(V, V)> = None;
    // Depth, RAPTO, RTRCTO (None: AUTO, back to the level the tool came
    // from).
    let mut cycle: Option<(f64, f64, Option<f64>)> = None;
    let mut indirv: Option<V> = None;
    let mut nx = false;
    let mut cycle_text = String::new();
    let to_setup = |p: V, r: &[[f64; 3]; 3], t: V| {
        let d = sub(p, t);
        [
            r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2],
            r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2],
            r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2],
        ]
    };
    for (major, args) in statements(text) {
        let upper = args.to_ascii_uppercase();
        match major.as_str() {
            "UNITS" | "UNIT" if upper.starts_with("INCH") => unit = 25.4,
            "CSYS" => {
                let v = nums(&args);
                r = [[v[0], v[1], v[2]], [v[4], v[5], v[6]], [v[8], v[9], v[10]]];
                t = mul([v[3], v[7], v[11]], unit);
                // The set-up's tool axis: its Z (the third column).
                axis = [v[2], v[6], v[10]];
            }
            "LOAD" | "LOADTL" => out.tools.push(*nums(&args).first().unwrap_or(&0.0) as u32),
            "SPINDL" => {
                let v = nums(&args);
                if let Some(s) = v.first() {
                    out.spindles.push(format!("S{s} M3"));
                }
            }
            "CUTCOM" if upper.starts_with("LEFT") => out.cutcom_left += 1,
            "CUTCOM" if upper.starts_with("OFF") => out.cutcom_off += 1,
            "TLAXIS" => {
                let v = nums(&args);
                axis = [v[0], v[1], v[2]];
            }
            // Siemens NX's CLSF gives the axis of a clockwise arc.
            "TOOL PATH" | "TLDATA" | "MSYS" => nx = true,
            "CIRCLE" => {
                let v = nums(&args);
                let s = if nx { -1.0 } else { 1.0 };
                circle = Some((
                    mul([v[0], v[1], v[2]], unit),
                    [s * v[3], s * v[4], s * v[5]],
                ));
            }
            "CYCLE" => {
                let w: Vec<String> = upper.split(',').map(|x| x.trim().to_string()).collect();
                let val = |k: &str| {
                    w.iter()
                        .position(|x| x == k)
                        .map(|i| w[i + 1].parse::<f64>().map(|v| v * unit).ok())
                };
                if w[0] == "OFF" {
                    cycle = None;
                } else if w[0] == "INIT" || w == ["ON"] {
                } else {
                    // A new cycle, or CYCLE/ON changing the one in force.
                    let (mut depth, mut rapto, mut rtrcto) = match (w[0].as_str(), cycle) {
                        ("ON", Some(c)) => c,
                        _ => (f64::NAN, 0.0, Some(f64::NAN)),
                    };
                    if let Some(d) = val("FEDTO") {
                        depth = d.unwrap().abs();
                    }
                    if let Some(r) = val("RAPTO").or(val("CLEAR")) {
                        rapto = r.unwrap();
                    }
                    if let Some(r) = val("RTRCTO") {
                        rtrcto = r;
                    }
                    let rtrcto = rtrcto.map(|r| if r.is_nan() { rapto } else { r });
                    cycle = Some((depth, rapto, rtrcto));
                    cycle_text = upper.clone();
                }
            }
            "INDIRV" => {
                let v = nums(&args);
                indirv = Some([v[0], v[1], v[2]]);
            }
            "TLON,GOFWD" => {
                // (CIRCLE/xc,yc,zc,r),ON[,2,INTOF],(LINE/xc,yc,zc,xe,ye,ze):
                // about the tool axis, starting in the INDIRV direction, to
                // the first (or second) crossing of the line.
                let tk: Vec<String> = upper
                    .split([',', '(', ')', '/'])
                    .map(|x| x.trim().to_string())
                    .filter(|x| !x.is_empty())
                    .collect();
                let f = |i: usize| tk[i].parse::<f64>().unwrap() * unit;
                let centre = to_setup([f(1), f(2), f(3)], &r, t);
                let radius = f(4);
                let nth = if tk[6] == "2" { 2 } else { 1 };
                let l = tk.len() - 6;
                let e = to_setup([f(l + 3), f(l + 4), f(l + 5)], &r, t);
                let a = to_setup(axis, &r, [0.0; 3]);
                let a = mul(a, 1.0 / len(a));
                let start = pos.expect("arc start");
                let sp = sub(start, centre);
                let dir = to_setup(indirv.take().expect("INDIRV"), &r, [0.0; 3]);
                let n = mul(a, dot(cross(sp, dir), a).signum());
                let u = mul(sp, 1.0 / len(sp));
                let v = cross(n, u);
                let d = sub(e, centre);
                let d = mul(d, 1.0 / len(d));
                let mut sweeps: Vec<f64> = [1.0, -1.0]
                    .iter()
                    .map(|k| {
                        let p = mul(d, *k);
                        let th = dot(p, v).atan2(dot(p, u)).rem_euclid(std::f64::consts::TAU);
                        if th < 1e-9 { std::f64::consts::TAU } else { th }
                    })
                    .collect();
                sweeps.sort_by(f64::total_cmp);
                let sweep = sweeps[nth - 1];
                out.pieces
                    .push(Piece::Arc(centre, n, u, radius, sweep, 0.0));
                pos = Some(add(
                    centre,
                    add(mul(u, radius * sweep.cos()), mul(v, radius * sweep.sin())),
                ));
            }
            "GOTO" | "FROM" => {
                let v = nums(&args);
                let p = mul([v[0], v[1], v[2]], unit);
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
                    let hs = dot(s, n);
                    let s = sub(s, mul(n, hs));
                    let e = sub(q, c);
                    let he = dot(e, n);
                    let e = sub(e, mul(n, he));
                    let u = mul(s, 1.0 / len(s));
                    let v = cross(n, u);
                    let mut sweep = dot(e, v).atan2(dot(e, u));
                    if sweep <= 1e-9 {
                        sweep += std::f64::consts::TAU;
                    }
                    let c = add(c, mul(n, hs));
                    out.pieces.push(Piece::Arc(c, n, u, len(s), sweep, he - hs));
                } else if let Some((depth, rapto, rtrcto)) = cycle {
                    let rtrcto = rtrcto
                        .unwrap_or_else(|| pos.map_or(rapto, |p| dot(sub(p, q), a).max(rapto)));
                    let clear = add(q, mul(a, rtrcto));
                    let bottom = add(q, mul(a, -depth));
                    if let Some(from) = pos {
                        out.pieces.push(Piece::Line(from, clear));
                    }
                    out.pieces.push(Piece::Line(clear, add(q, mul(a, rapto))));
                    out.pieces.push(Piece::Line(add(q, mul(a, rapto)), bottom));
                    out.pieces.push(Piece::Line(bottom, clear));
                    out.holes.push(bottom);
                    out.hole_cycles.push(cycle_text.clone());
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
pub fn forward_trt(q: [f64; 5]) -> V {
    let [x, y, z, a_deg, c_deg] = q;
    let (sa, ca) = (-a_deg.to_radians()).sin_cos();
    let (sc, cc) = (-c_deg.to_radians()).sin_cos();
    let p = [x, y, z + 60.0];
    let p = [p[0], ca * p[1] - sa * p[2], sa * p[1] + ca * p[2]];
    let p = [p[0], p[1], p[2] - 60.0];
    [cc * p[0] - sc * p[1], sc * p[0] + cc * p[1], p[2]]
}

/// Tool tip of fixtures/machines/xyzac-head.json, by hand:
/// `(X, Y, Z + 150) + Rz(C) · Rx(A) · (0, 0, −150)`.
pub fn forward_head(q: [f64; 5]) -> V {
    let [x, y, z, a_deg, c_deg] = q;
    let (sa, ca) = a_deg.to_radians().sin_cos();
    let (sc, cc) = c_deg.to_radians().sin_cos();
    let p = [0.0, sa * 150.0, -ca * 150.0];
    let p = [cc * p[0] - sc * p[1], sc * p[0] + cc * p[1], p[2]];
    [x + p[0], y + p[1], z + 150.0 + p[2]]
}

/// Tool-tip points of the program's motion, through `forward` (axes X Y Z
/// A C): straight moves by their end points, arcs sampled by chords within 0.5 µm
/// (the plane's two axes on the circle, the third linear in the angle),
/// canned cycles as the moves a controller makes (to the hole at the
/// current level, down to `R`, to the bottom `Z`, back to `R` (`G99`) or to
/// the level before the cycle (`G98`)), each bottom also listed in `holes`.
pub fn output_points(nc: &str, forward: fn([f64; 5]) -> V) -> (Vec<V>, Vec<V>) {
    use std::f64::consts::TAU;
    let mut pts = Vec::new();
    let mut holes = Vec::new();
    let mut q = [0.0f64; 5];
    let mut motion = 0u32;
    let mut plane = 17u32;
    let mut g99 = false;
    for line in nc.lines() {
        if line.starts_with('(') || line.trim().is_empty() {
            continue;
        }
        let mut target = q;
        let mut moved = false;
        let mut centre = [0.0f64; 3];
        let mut r_level = None;
        for w in line.split_whitespace() {
            let (l, v) = w.split_at(1);
            let Ok(v) = v.parse::<f64>() else { continue };
            match l {
                "G" => {
                    let g = (v * 10.0).round() as u32;
                    match g {
                        0 | 10 | 20 | 30 | 730 | 800..=890 => motion = g / 10,
                        170 | 180 | 190 => plane = g / 10,
                        980 => g99 = false,
                        990 => g99 = true,
                        _ => {}
                    }
                }
                "X" | "Y" | "Z" | "A" | "C" => {
                    let k = "XYZAC".find(l).unwrap();
                    target[k] = v;
                    moved = true;
                }
                "I" => centre[0] = v,
                "J" => centre[1] = v,
                "K" => centre[2] = v,
                "R" => r_level = Some(v),
                _ => {}
            }
        }
        if !moved {
            continue;
        }
        match motion {
            0 | 1 => {
                pts.push(forward(target));
                q = target;
            }
            2 | 3 => {
                assert_eq!(q[3..], target[3..], "rotaries move in an arc: {line}");
                let (a, b, n) = match plane {
                    17 => (0, 1, 2),
                    18 => (2, 0, 1),
                    _ => (1, 2, 0),
                };
                let c = [q[0] + centre[0], q[1] + centre[1], q[2] + centre[2]];
                let (sa, sb) = (q[a] - c[a], q[b] - c[b]);
                let (ea, eb) = (target[a] - c[a], target[b] - c[b]);
                let r = sa.hypot(sb);
                assert!((ea.hypot(eb) - r).abs() < 1e-3, "radii differ: {line}");
                let t0 = sb.atan2(sa);
                let dir = if motion == 3 { 1.0 } else { -1.0 };
                let mut sweep = (dir * (eb.atan2(ea) - t0)).rem_euclid(TAU);
                if sweep < 1e-9 {
                    sweep = TAU;
                }
                // Chords within 0.5 µm of the arc.
                let step = if r > 5e-4 {
                    2.0 * (1.0 - 5e-4 / r).acos()
                } else {
                    TAU
                };
                let k = ((sweep / step.min(0.5)).ceil() as usize).max(1);
                for i in 1..=k {
                    let f = i as f64 / k as f64;
                    let t = t0 + dir * sweep * f;
                    let mut p = q;
                    p[a] = c[a] + r * t.cos();
                    p[b] = c[b] + r * t.sin();
                    p[n] = q[n] + (target[n] - q[n]) * f;
                    pts.push(forward(p));
                }
                q = target;
            }
            73 | 81..=89 => {
                let r = r_level.expect("R in a canned cycle");
                let start_z = q[2];
                let mut p = q;
                p[0] = target[0];
                p[1] = target[1];
                pts.push(forward(p));
                p[2] = r;
                pts.push(forward(p));
                p[2] = target[2];
                pts.push(forward(p));
                holes.push(forward(p));
                p[2] = if g99 { r } else { start_z.max(r) };
                pts.push(forward(p));
                q = p;
            }
            _ => panic!("axis words with no motion mode: {line}"),
        }
    }
    (pts, holes)
}

/// Fold step: the first candidate within the tolerance (the path may pass
/// the same place again later), else the nearest.
fn first_within(a: (usize, f64), b: (usize, f64)) -> (usize, f64) {
    if a.1 <= TOL || b.1 >= a.1 { a } else { b }
}

/// Checks that the output polyline `pts` and the CL path agree within
/// [`TOL`] both ways (searched in windows that move forward) and that every
/// CL hole bottom is drilled; returns the worst distances (output → CL,
/// CL → output), mm.
pub fn agree(name: &str, cl: &ClPath, pts: &[V], holes: &[V]) -> (f64, f64) {
    for h in &cl.holes {
        assert!(
            holes.iter().chain(pts).any(|p| len(sub(*p, *h)) < 1e-3),
            "{name}: hole bottom {h:?} missing"
        );
    }
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
            let ds: Vec<(usize, f64)> = (lo..hi).map(|k| (k, cl.pieces[k].distance(q))).collect();
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
    let mut k: usize = 1;
    let mut worst_cl = 0.0f64;
    for (pi, piece) in cl.pieces.iter().enumerate() {
        for q in piece.samples(0.2) {
            let lo = k.saturating_sub(3).max(1);
            let hi = (k + 20000).min(pts.len());
            let ds: Vec<(usize, f64)> = (lo..hi)
                .map(|m| (m, Piece::Line(pts[m - 1], pts[m]).distance(q)))
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
    (worst_out, worst_cl)
}

/// An X, Y, Z error table: the linear axes' rows of wang2023-xyzab's
/// (everything before its `A` rows), for machines with other rotaries.
pub fn wang_linear_table() -> String {
    std::fs::read_to_string(crate::util::repo_file("fixtures/errors/wang2023-xyzab.csv"))
        .unwrap()
        .lines()
        .take_while(|l| !l.starts_with("A,"))
        .map(|l| format!("{l}\n"))
        .collect()
}
