//! Error tables, least-squares B-spline fits, ISO 230-2 figures and the
//! error model bound to a chain.

use std::f64::consts::PI;

use kinpost::geometric::bspline::{self, Extrapolation, KnotChoice, SplineOptions};
use kinpost::geometric::synth::{SplitMix64, ZHAO2022_SEED, zhao2022_tables};
use kinpost::geometric::table::RAD_PER_ARCSEC;
use kinpost::geometric::{
    AxisErrors, Component, ErrorModel, FitOptions, FixedError, iso230_2, parse_tables,
};
use kinpost::machine::chain::{JointErrors, NoErrors};

// ---------------------------------------------------------------- parsing

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn parses_every_feature_of_the_format() {
    let text = "\u{feff}# a comment\r\n\
                // another comment\r\n\
                \r\n\
                 X , EXX[um] , EYX [nm], EZX[mm], EAX[urad], EBX[mrad], ECX[arcsec]\r\n\
                 10 , 1.5, 200, 0.001, 2, 0.003, 1   # trailing comment\r\n\
                -10, -1.5, -200, -0.001, -2, -0.003, -1\r\n\
                \r\n\
                10, 2.5, 0, 0, 0, 0, 0\r\n\
                B,EBB[rad],EAB[µrad],ECB[deg],EXB[µm]\r\n\
                0,1e-6,1,0.001,2\r\n\
                90,2e-6,2,0.002,3\r\n\
                C[rad],ECC\n\
                3.141592653589793,5e-6\n\
                0,4e-6\n\
                Z;EZZ[um]\n\
                0; 1\n\
                100;\u{2212}2\n\
                Y,EYY,\n\
                5,0.002,\n";
    let tables = parse_tables(text, "t.csv").unwrap();
    assert_eq!(tables.len(), 5);

    let x = &tables[0];
    assert_eq!(x.axis, "X");
    assert!(!x.rotary);
    assert_eq!(x.positions, vec![10.0, -10.0, 10.0]);
    assert_eq!(x.source_line, vec![5, 6, 8]);
    assert_eq!(x.header_line, 4);
    assert_eq!(x.columns.len(), 6);
    let names: Vec<&str> = x.columns.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]);
    let v = |c: Component| x.column(c).unwrap().values[0];
    assert!(close(v(Component::Dx), 1.5e-3, 1e-12));
    assert!(close(v(Component::Dy), 200e-6, 1e-12));
    assert!(close(v(Component::Dz), 0.001, 1e-12));
    assert!(close(v(Component::Ex), 2e-6, 1e-12));
    assert!(close(v(Component::Ey), 3e-6, 1e-12));
    assert!(close(v(Component::Ez), RAD_PER_ARCSEC, 1e-12));
    assert!(close(
        x.column(Component::Dx).unwrap().values[2],
        2.5e-3,
        1e-12
    ));

    let b = &tables[1];
    assert_eq!(b.axis, "B");
    assert!(b.rotary);
    assert_eq!(b.positions, vec![0.0, 90.0]);
    assert!(close(
        b.column(Component::Ey).unwrap().values[1],
        2e-6,
        1e-12
    ));
    assert!(close(
        b.column(Component::Ex).unwrap().values[0],
        1e-6,
        1e-12
    ));
    assert!(close(
        b.column(Component::Ez).unwrap().values[0],
        0.001_f64.to_radians(),
        1e-12
    ));
    assert!(close(
        b.column(Component::Dx).unwrap().values[1],
        3e-3,
        1e-12
    ));
    assert!(b.column(Component::Dy).is_none());

    let c = &tables[2];
    assert!(
        close(c.positions[0], 180.0, 1e-12),
        "C[rad] positions become degrees"
    );
    assert_eq!(c.column(Component::Ez).unwrap().values, vec![5e-6, 4e-6]);

    let z = &tables[3];
    assert_eq!(z.positions, vec![0.0, 100.0]);
    assert!(
        close(z.columns[0].values[1], -2e-3, 1e-12),
        "Unicode minus, ';' separator"
    );

    let y = &tables[4];
    assert_eq!(
        y.columns[0].values,
        vec![0.002],
        "trailing empty fields are ignored"
    );
}

#[test]
fn direction_column_and_inferred_directions() {
    let t = parse_tables("X,dir,EXX\n0,+,1\n10,fwd,2\n10,-1,3\n0,bwd,4\n", "t.csv").unwrap();
    assert_eq!(t[0].direction, Some(vec![1, 1, -1, -1]));
    assert_eq!(t[0].columns.len(), 1);
    // Forward then backward passes, three runs: inferred from the order.
    let mut s = String::from("Z,EZZ\n");
    for _ in 0..3 {
        for p in [0, 10, 20, 20, 10, 0] {
            s.push_str(&format!("{p},0.001\n"));
        }
    }
    let t = parse_tables(&s, "t.csv").unwrap();
    let d = t[0].direction.as_ref().unwrap();
    assert_eq!(&d[..6], &[1, 1, 1, -1, -1, -1]);
    assert_eq!(d.len(), 18);
    // A single sorted pass: direction unknown.
    let t = parse_tables("X,EXX\n0,1\n10,2\n20,3\n30,4\n", "t.csv").unwrap();
    assert_eq!(t[0].direction, None);
}

fn parse_err(text: &str) -> String {
    match parse_tables(text, "t.csv") {
        Ok(t) => panic!("expected an error for {text:?}, got {t:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn every_malformed_input_is_located() {
    let cases: &[(&str, &str, &str)] = &[
        ("X,EXX,EQX\n0,1,2\n", "t.csv:1:7", "unknown column `EQX`"),
        (
            "X,EXX,EXZ\n0,1,2\n",
            "t.csv:1:7",
            "this table is for axis X",
        ),
        ("X,EXX,temp\n0,1,2\n", "t.csv:1:7", "unknown column"),
        (
            "X,EXX[furlong]\n0,1\n",
            "t.csv:1:3",
            "unknown unit `[furlong]`",
        ),
        ("X,EAX[um]\n0,1\n", "t.csv:1:3", "unknown unit `[um]`"),
        ("X,EXX[urad]\n0,1\n", "t.csv:1:3", "unknown unit"),
        ("X,EXX[um\n0,1\n", "t.csv:1:3", "missing ']'"),
        ("X[deg],EXX\n0,1\n", "t.csv:1:1", "unknown unit `[deg]`"),
        ("X,EXX\n0,abc\n", "t.csv:2:3", "not a number"),
        ("X,EXX\n0,NaN\n", "t.csv:2:3", "finite"),
        ("X,EXX\n0,inf\n", "t.csv:2:3", "finite"),
        ("X,EXX\n0,1\r\n0,-infinity\r\n", "t.csv:3:3", "finite"),
        ("X,EXX\nnan,1\n", "t.csv:2:1", "axis position"),
        ("X,EXX\n0,1\nfoo,3\n", "t.csv:3:1", "axis position"),
        ("X,EXX\n0,1,2\n", "t.csv:2:5", "wrong number of fields"),
        ("X,EXX,EYX\n0,1\n", "t.csv:2:4", "wrong number of fields"),
        ("X,EXX\n0,,1\n", "t.csv:2:4", "wrong number of fields"),
        ("X,EXX,EYX\n0,,1\n", "t.csv:2:3", "empty field"),
        (
            "0,1,2\nX,EXX\n",
            "t.csv:1:1",
            "data before the first header",
        ),
        ("pos,EXX\n0,1\n", "t.csv:1:1", "expected a header"),
        ("X,EXX\nZ,EZZ\n0,1\n", "t.csv:1:1", "empty table"),
        ("Z,EZZ\n0,1\nX,EXX\n# nothing\n", "t.csv:3:1", "empty table"),
        ("X,EXX,EXX\n0,1,2\n", "t.csv:1:7", "duplicate column"),
        ("X,EXX[um], exx\n0,1,2\n", "t.csv:1:12", "duplicate column"),
        (
            "X,dir,run,EXX\n0,1,1,2\n",
            "t.csv:1:7",
            "duplicate direction column",
        ),
        ("X,EXX,,EYX\n0,1,2,3\n", "t.csv:1:7", "empty column name"),
        ("X\n0\n", "t.csv:1:1", "no error column"),
        ("X,dir,EXX\n0,sideways,1\n", "t.csv:2:3", "direction"),
        ("", "t.csv:1:1", "no error table"),
        ("# only a comment\n\n", "t.csv:1:1", "no error table"),
    ];
    for (text, loc, what) in cases {
        let e = parse_err(text);
        assert!(
            e.starts_with(&format!("{loc}: ")),
            "{text:?}: expected location {loc}, got {e}"
        );
        assert!(e.contains(what), "{text:?}: expected {what:?} in {e}");
    }
    // The offending line is shown.
    let e = parse_err("X,EXX\n0,1\n5,oops\n");
    assert!(e.ends_with("\n  | 5,oops"), "{e}");
}

// ---------------------------------------------------------------- fitting

/// Samples `f` at `positions`, `runs` times, with normal noise `sigma`.
fn sample(
    f: impl Fn(f64) -> f64,
    positions: &[f64],
    runs: usize,
    sigma: f64,
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let mut x = Vec::new();
    let mut y = Vec::new();
    for _ in 0..runs {
        for &p in positions {
            x.push(p);
            y.push(f(p) + sigma * rng.normal());
        }
    }
    (x, y)
}

fn travel(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let n = ((hi - lo) / step).round() as usize;
    (0..=n).map(|i| lo + step * i as f64).collect()
}

fn smooth(x: f64) -> f64 {
    // mm: a few µm of smooth error.
    2e-3 * (x / 40.0).sin() + 1e-5 * x - 3e-8 * x * x
}

#[test]
fn fit_recovers_a_smooth_function() {
    let pos = travel(-100.0, 100.0, 5.0);
    let (x, y) = sample(smooth, &pos, 2, 0.0, 1);
    let f = bspline::fit(&x, &y, &SplineOptions::default()).unwrap();
    let worst = (0..=400)
        .map(|i| -100.0 + 0.5 * i as f64)
        .map(|t| (f.spline.value(t) - smooth(t)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-8, "noise-free: worst error {worst} mm");
    assert!(f.rms < 1e-8);

    // With 0.1 µm noise and 6 runs the fit is well inside the noise.
    let sigma = 1e-4;
    let (x, y) = sample(smooth, &pos, 6, sigma, 2);
    let f = bspline::fit(&x, &y, &SplineOptions::default()).unwrap();
    let worst = (0..=400)
        .map(|i| -100.0 + 0.5 * i as f64)
        .map(|t| (f.spline.value(t) - smooth(t)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.6 * sigma, "noisy: worst error {worst} mm");
    assert!(
        close(f.rms, sigma, 0.25),
        "residual RMS {} ≈ noise {sigma}",
        f.rms
    );
    assert_eq!(f.points, x.len());
    assert_eq!(f.positions, pos.len());
}

#[test]
fn cross_validation_picks_a_sensible_knot_count() {
    let pos = travel(-100.0, 100.0, 10.0);
    // Noisy measurement of a smooth error: few knots, well below the maximum.
    let (x, y) = sample(smooth, &pos, 6, 1e-4, 3);
    let f = bspline::fit(&x, &y, &SplineOptions::default()).unwrap();
    let cv = f.cv.clone().unwrap();
    let max_tried = cv.scores.last().unwrap().0;
    assert!(max_tried >= 10, "candidates up to {max_tried}");
    assert!(f.interior_knots <= 4, "chose {} knots", f.interior_knots);
    assert!(f.interior_knots < max_tried);
    // The chosen score is (within tolerance) the best one.
    let best = cv.scores.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
    assert!(cv.score <= best * 1.01 + 1e-18);

    // A wiggly, noise-free error needs more knots, and CV finds them.
    let wiggly = |x: f64| 1e-3 * (x / 8.0).sin();
    let (x, y) = sample(wiggly, &travel(-100.0, 100.0, 4.0), 1, 0.0, 0);
    let g = bspline::fit(&x, &y, &SplineOptions::default()).unwrap();
    assert!(
        g.interior_knots > f.interior_knots + 4,
        "wiggly chose {}",
        g.interior_knots
    );
}

#[test]
fn derivative_matches_finite_differences() {
    let pos = travel(-100.0, 100.0, 10.0);
    let (x, y) = sample(smooth, &pos, 3, 5e-5, 4);
    for knots in [0, 3, 7] {
        let opts = SplineOptions {
            knots: KnotChoice::Fixed(knots),
            ..Default::default()
        };
        let s = bspline::fit(&x, &y, &opts).unwrap().spline;
        for t in [
            -99.9, -75.0, -50.0, -12.5, 0.0, 3.3, 25.0, 49.99, 88.0, 99.9,
        ] {
            let h = 1e-4;
            let fd = (s.value(t + h) - s.value(t - h)) / (2.0 * h);
            let d = s.derivative(t);
            assert!(
                (d - fd).abs() < 1e-9 * (1.0 + d.abs()) + 1e-12,
                "knots {knots} at {t}: {d} vs {fd}"
            );
        }
    }
}

#[test]
fn extrapolation_is_held_or_linear() {
    let pos = travel(-100.0, 100.0, 10.0);
    let (x, y) = sample(smooth, &pos, 1, 0.0, 0);
    let held = bspline::fit(&x, &y, &SplineOptions::default())
        .unwrap()
        .spline;
    assert_eq!(held.extrapolation(), Extrapolation::Hold);
    assert_eq!(held.range(), (-100.0, 100.0));
    assert_eq!(held.value(150.0), held.value(100.0));
    assert_eq!(held.value(1e12), held.value(100.0));
    assert_eq!(held.value(-1e12), held.value(-100.0));
    assert_eq!(held.derivative(150.0), 0.0);
    assert_eq!(held.derivative(-150.0), 0.0);

    let opts = SplineOptions {
        extrapolation: Extrapolation::Linear,
        ..Default::default()
    };
    let lin = bspline::fit(&x, &y, &opts).unwrap().spline;
    let (v, d) = lin.value_and_derivative(100.0);
    assert!(close(lin.value(150.0), v + 50.0 * d, 1e-12));
    assert_eq!(lin.derivative(150.0), d);
    let (v, d) = lin.value_and_derivative(-100.0);
    assert!(close(lin.value(-130.0), v - 30.0 * d, 1e-12));
    // Never a wild polynomial: far outside, the linear continuation stays linear.
    assert!(lin.value(1000.0).abs() < 1.0);
    // No panics on non-finite positions.
    let _ = held.value_and_derivative(f64::NAN);
    let _ = lin.value_and_derivative(f64::INFINITY);
}

#[test]
fn fixed_knot_count_and_limits() {
    let text = "X,EXX\n-100,0\n-50,1e-3\n0,2e-3\n50,1e-3\n100,0\n-100,0\n0,2e-3\n";
    let tables = parse_tables(text, "t.csv").unwrap();
    let (model, report) = ErrorModel::fit(&tables, &FitOptions::fixed_knots(1)).unwrap();
    assert_eq!(report.columns[0].knots, 1);
    assert_eq!(report.columns[0].knots_chosen_by, "fixed");
    assert_eq!(report.columns[0].points, 7);
    assert_eq!(report.columns[0].positions, 5);
    let s = &model.axis("x").unwrap().columns[0].spline;
    assert_eq!(s.interior_knots(), &[0.0]);
    // 5 positions cannot carry 2 interior knots of a cubic (6 coefficients).
    let e = ErrorModel::fit(&tables, &FitOptions::fixed_knots(2)).unwrap_err();
    let msg = e.to_string();
    assert!(msg.starts_with("t.csv:1:1: axis X, column EXX:"), "{msg}");
    assert!(msg.contains("at most 1"), "{msg}");
}

// ---------------------------------------------------------------- ISO 230-2

#[test]
fn iso230_2_figures_on_a_hand_computable_dataset() {
    // Target 0: ↑ 1, 3 µm (mean 2, s √2); ↓ 0, 0 (mean 0, s 0).
    // Target 10: ↑ 4, 4 (mean 4, s 0); ↓ 5, 7 (mean 6, s √2).
    let with_dir = "X,dir,EXX[um]\n0,+,1\n10,+,4\n10,-,5\n0,-,0\n0,+,3\n10,+,4\n10,-,7\n0,-,0\n";
    let inferred = "X,EXX[um]\n0,1\n10,4\n10,5\n0,0\n0,3\n10,4\n10,7\n0,0\n";
    let mut figures = Vec::new();
    for text in [with_dir, inferred] {
        let t = parse_tables(text, "t.csv").unwrap();
        let iso = iso230_2::from_table(&t[0]).unwrap();
        let s2 = 2f64.sqrt();
        let eq = |a: f64, b: f64| assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        assert_eq!(iso.unit, "µm");
        assert_eq!(iso.position_unit, "mm");
        assert_eq!(iso.column, "EXX");
        assert_eq!(iso.targets.len(), 2);
        assert_eq!(iso.min_runs, 2);
        eq(iso.targets[0].mean_up, 2.0);
        eq(iso.targets[0].reversal, 2.0);
        eq(iso.targets[1].reversal, -2.0);
        eq(iso.targets[1].s_down.unwrap(), s2);
        eq(iso.reversal_b, 2.0);
        eq(iso.mean_reversal, 0.0);
        eq(iso.repeatability_up.unwrap(), 4.0 * s2);
        eq(iso.repeatability_down.unwrap(), 4.0 * s2);
        // R_0 = max(2√2 + 0 + 2, 4√2, 0) = 4√2; same at 10.
        eq(iso.repeatability_r.unwrap(), 4.0 * s2);
        eq(iso.systematic_up, 2.0);
        eq(iso.systematic_down, 6.0);
        eq(iso.systematic_e, 6.0);
        eq(iso.mean_range_m, 4.0);
        eq(iso.accuracy_up.unwrap(), 2.0 + 2.0 * s2 + 2.0 * s2 - 2.0);
        eq(iso.accuracy_a.unwrap(), 4.0 + 4.0 * s2);
        figures.push(iso);
    }
    assert_eq!(figures[0], figures[1]);

    // Rotary axes report µrad (and arc seconds in the text).
    let t = parse_tables("B,EBB[arcsec]\n0,1\n90,2\n90,3\n0,0\n", "t.csv").unwrap();
    let iso = iso230_2::from_table(&t[0]).unwrap();
    assert_eq!(iso.unit, "µrad");
    assert!((iso.reversal_b - RAD_PER_ARCSEC * 1e6).abs() < 1e-9);
    assert!(iso.repeatability_r.is_none(), "one run per direction: no R");
    assert!(iso.to_text().contains("arcsec"));
    // No positioning column, or unknown directions: no figures.
    let t = parse_tables("X,EYX\n0,1\n10,2\n10,3\n0,0\n", "t.csv").unwrap();
    assert!(iso230_2::from_table(&t[0]).is_none());
}

// ---------------------------------------------------------------- model

fn zhao_model() -> ErrorModel {
    let tables = parse_tables(&zhao2022_tables(ZHAO2022_SEED), "zhao.csv").unwrap();
    ErrorModel::fit(&tables, &FitOptions::default()).unwrap().0
}

#[test]
fn bound_errors_have_analytic_derivatives() {
    let model = zhao_model();
    let chain = crate::util::zhao();
    let bound = model.bind(&chain).unwrap();
    assert!(!bound.is_empty());
    assert!(bound.error(0, 0.3).is_none(), "C carries no error");
    // Per joint: derivative vs finite differences (B: rad, spline in degrees).
    for (j, q) in [(1, 12.3), (2, -47.0), (3, 0.61), (3, -1.2)] {
        let (e, d) = bound.error_and_derivative(j, q).unwrap();
        assert_eq!(e, bound.error(j, q).unwrap());
        let h = 1e-5;
        let fd = (bound.error(j, q + h).unwrap() - bound.error(j, q - h).unwrap()) / (2.0 * h);
        assert!(
            (d - fd).norm() < 1e-6 * d.norm() + 1e-14,
            "joint {j}: {d} vs {fd}"
        );
    }
    // B's table is in degrees, the chain's q in radians.
    let b = model.axis("B").unwrap();
    let (e, _) = bound.error_and_derivative(3, 30f64.to_radians()).unwrap();
    assert_eq!(e[4], b.column(Component::Ey).unwrap().spline.value(30.0));

    // The chain's analytic Jacobian with these errors matches finite
    // differences of the pose; the error part is checked separately so the
    // (µm-sized) error derivatives are not hidden by the nominal ones.
    for q in [[0.4, 12.0, -7.0, 0.5], [-2.0, -60.0, 35.0, -1.1]] {
        let (p_err, j_err) = chain.pose_and_jacobian(&q, &bound);
        let (p_nom, j_nom) = chain.pose_and_jacobian(&q, &NoErrors);
        assert!((p_err.tip - chain.pose(&q, &bound).tip).norm() < 1e-12);
        assert!((p_err.tip - p_nom.tip).norm() > 1e-4 * 1e-2, "errors act");
        for k in 0..4 {
            let h = 1e-4;
            let mut qp = q;
            let mut qm = q;
            qp[k] += h;
            qm[k] -= h;
            let diff = |qq: &[f64; 4]| {
                let a = chain.pose(qq, &bound);
                let b = chain.pose(qq, &NoErrors);
                (a.tip - b.tip, a.axis - b.axis)
            };
            let (tp, ap) = diff(&qp);
            let (tm, am) = diff(&qm);
            let fd_tip = (tp - tm) / (2.0 * h);
            let fd_ax = (ap - am) / (2.0 * h);
            for r in 0..3 {
                let an_tip = j_err[(r, k)] - j_nom[(r, k)];
                let an_ax = j_err[(r + 3, k)] - j_nom[(r + 3, k)];
                assert!((an_tip - fd_tip[r]).abs() < 1e-9, "tip row {r} joint {k}");
                assert!((an_ax - fd_ax[r]).abs() < 1e-11, "axis row {r} joint {k}");
            }
            // And the full Jacobian against the full pose.
            let pp = chain.pose(&qp, &bound);
            let pm = chain.pose(&qm, &bound);
            let fd = (pp.tip - pm.tip) / (2.0 * h);
            for r in 0..3 {
                assert!((j_err[(r, k)] - fd[r]).abs() < 1e-6);
            }
        }
    }
}

#[test]
fn tool_tip_error_on_a_lens_path_is_about_4_um() {
    // A spiral over a concave lens (radius 30 mm, R = 150 mm): X = r, Z = sag,
    // B tilts the tool with the surface normal, C turns the part.
    let model = zhao_model();
    let chain = crate::util::zhao();
    let bound = model.bind(&chain).unwrap();
    let mut max: f64 = 0.0;
    let mut sum = 0.0;
    let n = 241;
    for i in 0..n {
        let t = i as f64 / (n - 1) as f64;
        let r = 30.0 * t;
        let q = [2.0 * PI * 8.0 * t, r, r * r / 300.0, -(r / 150.0).atan()];
        let d = (chain.pose(&q, &bound).tip - chain.pose(&q, &NoErrors).tip).norm() * 1e3;
        max = max.max(d);
        sum += d;
    }
    let mean = sum / n as f64;
    eprintln!("lens path: tool-tip error max {max:.3} µm, mean {mean:.3} µm");
    assert!((3.0..5.5).contains(&max), "max tool-tip error {max} µm");
    assert!((3.0..5.5).contains(&mean), "mean tool-tip error {mean} µm");
}

#[test]
fn bind_rejects_unknown_axes_and_kind_mismatch() {
    let tables = parse_tables("Y,EYY\n0,1e-3\n10,2e-3\n", "y.csv").unwrap();
    let (model, _) = ErrorModel::fit(&tables, &FitOptions::default()).unwrap();
    let e = model.bind(&crate::util::zhao()).unwrap_err().to_string();
    assert!(e.contains("axis Y") && e.contains("not a joint"), "{e}");
    assert!(e.starts_with("y.csv"), "{e}");

    let model = ErrorModel {
        axes: vec![AxisErrors {
            axis: "X".into(),
            rotary: true,
            columns: vec![],
            origin: Default::default(),
        }],
        ..Default::default()
    };
    let e = model.bind(&crate::util::zhao()).unwrap_err().to_string();
    assert!(e.contains("rotary") && e.contains("prismatic"), "{e}");
}

#[test]
fn model_json_round_trips() {
    let model = zhao_model();
    let json = serde_json::to_string_pretty(&model.to_json()).unwrap();
    assert!(json.contains("\"format\": \"kinpost-error-model\""));
    let back = ErrorModel::from_json_str(&json, "m.json").unwrap();
    assert_eq!(back, model);
    // A model with fixed errors and linear extrapolation.
    let mut m2 = model.clone();
    m2.fixed.push(FixedError {
        name: "squareness XZ".into(),
        after_joint: Some("X".into()),
        motion: [0.0, 0.0, 0.0, 0.0, 12e-6, 0.0],
    });
    m2.axes[0].columns[0]
        .spline
        .set_extrapolation(Extrapolation::Linear);
    let back = ErrorModel::from_json_str(&m2.to_json().to_string(), "m.json").unwrap();
    assert_eq!(back, m2);
}

#[test]
fn model_json_errors_are_located() {
    let e = ErrorModel::from_json_str("{\n  \"format\": \"kinpost-error-model\",\n  \"version\": 1,\n  \"axes\": [\n    {\"axis\": 3}\n  ]\n}", "m.json")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("m.json:5:"), "{e}");
    let e = ErrorModel::from_json_str("{\"format\": \"something\", \"version\": 1}", "m.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.json: ") && e.contains("kinpost-error-model"),
        "{e}"
    );
    let bad_knots = r#"{"format": "kinpost-error-model", "version": 1, "axes": [
        {"axis": "X", "rotary": false, "position_unit": "mm", "columns": [
          {"name": "EXX", "component": "dx", "unit": "mm", "degree": 3,
           "knots": [0, 0, 0, 0, 10, 10, 10, 5], "coefficients": [0, 0, 0, 0]}]}]}"#;
    let e = ErrorModel::from_json_str(bad_knots, "m.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.json:3:") && e.contains("EXX") && e.contains("knots"),
        "{e}"
    );
    // Units in the model JSON are honoured.
    let um = r#"{"format": "kinpost-error-model", "version": 1, "axes": [
        {"axis": "B", "rotary": true, "position_unit": "rad", "columns": [
          {"name": "EBB", "component": "ey", "unit": "urad", "degree": 1,
           "knots": [0, 0, 1, 1], "coefficients": [0, 10]}]}]}"#;
    let m = ErrorModel::from_json_str(um, "m.json").unwrap();
    let s = &m.axis("B").unwrap().columns[0].spline;
    assert!(close(s.range().1, 180.0 / PI, 1e-12));
    assert!(close(s.value(180.0 / PI), 10e-6, 1e-12));
}

#[test]
fn load_detects_json_or_csv_by_content() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("errors.dat");
    std::fs::write(&csv, zhao2022_tables(ZHAO2022_SEED)).unwrap();
    let from_csv = ErrorModel::load(&csv).unwrap();
    assert_eq!(from_csv.axes.len(), 3);
    let json = dir.path().join("model.txt");
    std::fs::write(&json, format!("\n  {}", from_csv.to_json())).unwrap();
    let from_json = ErrorModel::load(&json).unwrap();
    assert_eq!(from_json.axes, from_csv.axes);
    let e = ErrorModel::load(&dir.path().join("missing.csv")).unwrap_err();
    assert_eq!(e.exit_code(), kinpost::error::exit::IO);
    std::fs::write(&csv, "X,EXX\n0,zz\n").unwrap();
    let e = ErrorModel::load(&csv).unwrap_err().to_string();
    assert!(e.contains("errors.dat:2:3"), "{e}");
}

#[test]
fn fixed_errors_enter_the_chain_after_their_joint() {
    let chain = crate::util::zhao();
    let eps = 10e-6;
    let sq = FixedError {
        name: "squareness XZ".into(),
        after_joint: Some("x".into()),
        motion: [0.0, 0.0, 0.0, 0.0, eps, 0.0],
    };
    let c2 = sq.apply(&chain).unwrap();
    assert_eq!(c2.elements().len(), chain.elements().len() + 1);
    let q = [0.0, 10.0, 30.0, 0.0];
    let d = c2.pose(&q, &NoErrors).tip - chain.pose(&q, &NoErrors).tip;
    // Rotation εy after X tilts Z's travel and the tool: Δx = εy (z − 20).
    assert!((d.x - eps * (30.0 - 20.0)).abs() < 1e-12, "{d}");
    assert!(d.y.abs() < 1e-15);
    // Joint lookups still work after insertion.
    assert_eq!(c2.joint_index("B"), Some(3));
    // At the start of the chain, and order preserved by apply_fixed.
    let model = ErrorModel {
        fixed: vec![
            FixedError {
                name: "offset".into(),
                after_joint: None,
                motion: [1e-3, 0.0, 0.0, 0.0, 0.0, 0.0],
            },
            sq.clone(),
        ],
        ..Default::default()
    };
    let c3 = model.apply_fixed(&chain).unwrap();
    assert_eq!(c3.elements().len(), chain.elements().len() + 2);
    let d = c3.pose(&q, &NoErrors).tip - chain.pose(&q, &NoErrors).tip;
    assert!((d.x - 1e-3 - eps * 10.0).abs() < 1e-12);
    let bad = FixedError {
        after_joint: Some("W".into()),
        ..sq
    };
    let e = bad.apply(&chain).unwrap_err().to_string();
    assert!(e.contains("joint W"), "{e}");
}

#[test]
fn fit_report_has_units_on_every_number() {
    let tables = parse_tables(&zhao2022_tables(ZHAO2022_SEED), "zhao.csv").unwrap();
    let (_, report) = ErrorModel::fit(&tables, &FitOptions::default()).unwrap();
    assert_eq!(report.columns.len(), 11);
    let exx = &report.columns[0];
    assert_eq!((exx.axis.as_str(), exx.name.as_str()), ("X", "EXX"));
    assert_eq!(exx.display_unit, "µm");
    assert_eq!(exx.points, 126);
    assert_eq!(exx.knots_chosen_by, "cross-validation");
    assert!(exx.cv_score.is_some());
    let ebb = report.columns.iter().find(|c| c.name == "EBB").unwrap();
    assert_eq!(ebb.display_unit, "µrad");
    assert!(ebb.rms_residual_arcsec.is_some());
    let text = report.to_text();
    assert!(text.contains("µm") && text.contains("µrad") && text.contains("arcsec"));
    assert!(text.contains("ISO 230-2, axis X"));
    let json = serde_json::to_value(&report).unwrap();
    // Units in the keys: µm for a translation, µrad for a rotation.
    assert!(json["columns"][0]["rms_residual_um"].is_number());
    assert!(json["columns"][0].get("rms_residual").is_none());
    assert_eq!(json["columns"][0]["value_unit"], "mm");
    let ebb_json = json["columns"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "EBB")
        .unwrap();
    assert!(ebb_json["rms_residual_urad"].is_number());
    assert!(ebb_json["cv_scores_urad"].is_array());
    assert_eq!(json["iso230_2"][0]["unit"], "µm");
}

// ---------------------------------------------------------------- robustness

mod never_panics {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Arbitrary CSV-like text: an error or tables, never a panic.
        #[test]
        fn parser(text in "[XZBCxEAYdir0-9.,;+\\-\\[\\]umradsecµ#/ \r\n\t]{0,200}") {
            if let Ok(tables) = parse_tables(&text, "p.csv") {
                for t in &tables {
                    prop_assert!(!t.is_empty());
                    prop_assert!(t.columns.iter().all(|c| c.values.len() == t.len()));
                }
                let _ = ErrorModel::fit(&tables, &FitOptions::default());
            }
        }

        /// Arbitrary samples (including huge and non-finite values): the fit
        /// returns an error or a spline, never panics.
        #[test]
        fn fit(
            pts in proptest::collection::vec(
                (prop_oneof![-1e3..1e3f64, Just(f64::NAN), Just(1e300), Just(0.0)],
                 prop_oneof![-1.0..1.0f64, Just(f64::INFINITY)]),
                0..30),
            knots in proptest::option::of(0usize..12),
            linear in any::<bool>(),
        ) {
            let (x, y): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
            let opts = SplineOptions {
                knots: knots.map_or(KnotChoice::default(), KnotChoice::Fixed),
                extrapolation: if linear { Extrapolation::Linear } else { Extrapolation::Hold },
            };
            if let Ok(f) = bspline::fit(&x, &y, &opts) {
                for t in [-1e9, -1.0, 0.0, 1.0, 1e9, f64::NAN] {
                    let _ = f.spline.value_and_derivative(t);
                }
            }
        }

        /// Arbitrary model JSON numbers: an error or a model, never a panic.
        #[test]
        fn model_json(
            degree in 0usize..5,
            knots in proptest::collection::vec(-10.0..10.0f64, 0..12),
            coef in proptest::collection::vec(-1.0..1.0f64, 0..8),
        ) {
            let doc = serde_json::json!({
                "format": "kinpost-error-model", "version": 1,
                "axes": [{"axis": "B", "rotary": true, "position_unit": "deg",
                          "columns": [{"name": "EBB", "component": "ey", "unit": "rad",
                                       "degree": degree, "knots": knots, "coefficients": coef}]}]
            });
            if let Ok(m) = ErrorModel::from_json_str(&doc.to_string(), "m.json") {
                let chain = crate::util::zhao();
                let bound = m.bind(&chain).unwrap();
                for q in [-10.0, 0.0, 0.5, 10.0] {
                    let _ = bound.error_and_derivative(3, q);
                }
            }
        }
    }
}

#[test]
fn dense_scans_are_cross_validated_quickly() {
    let pos = travel(-500.0, 500.0, 0.5);
    let (x, y) = sample(smooth, &pos, 1, 5e-5, 9);
    let t0 = std::time::Instant::now();
    let f = bspline::fit(&x, &y, &SplineOptions::default()).unwrap();
    let dt = t0.elapsed().as_secs_f64();
    assert!(dt < 10.0, "{dt} s for {} positions", pos.len());
    assert_eq!(f.positions, 2001);
    assert!(f.cv.is_some());
    eprintln!("dense: {dt:.3} s, {} knots", f.interior_knots);
}
