mod diagnose_support;
use diagnose_support::*;
use kinpost::diagnose::*;

#[test]
#[ignore]
fn explore() {
    let spec = std::env::var("SPEC").unwrap_or("backlash:X=0.003".into());
    let m = if std::env::var("M").as_deref() == Ok("wang") { Machine::Wang } else { Machine::Zhao };
    let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let blocks: usize = std::env::var("BLOCKS").ok().and_then(|s| s.parse().ok()).unwrap_or(150);
    let chain = m.chain();
    let errors = m.errors();
    let prog = m.program(blocks, seed);
    let opts = sim_options(seed);
    let effects: Vec<EffectSpec> = if spec.is_empty() { vec![] } else { spec.split(';').map(|s| parse_effect_spec(s).unwrap()).collect() };
    let t0 = std::time::Instant::now();
    let rec = simulate(&chain, Some(&errors), &prog, &effects, &opts).unwrap();
    let t1 = t0.elapsed();
    println!("samples {} sim {:?}", rec.len(), t1);
    println!("effect rms {:.5} geom rms {:.5}", effect_rms(&chain, Some(&errors), &prog, &effects, &opts), geometric_rms(&chain, &errors, &prog, &opts));
    let t0 = std::time::Instant::now();
    let r = diagnose(&chain, Some(&errors), &rec, &DiagOptions::default()).unwrap();
    println!("diagnose {:?}", t0.elapsed());
    println!("{}", r.to_text());
    println!("{}", serde_json::to_string_pretty(&r.candidates).unwrap());
}

#[test]
#[ignore]
fn profile() {
    use kinpost::diagnose::{fit, prepare};
    let m = Machine::Zhao;
    let chain = m.chain();
    let errors = m.errors();
    let prog = m.program(150, 1);
    let rec = simulate(&chain, Some(&errors), &prog, &[], &sim_options(1)).unwrap();
    let t0 = std::time::Instant::now();
    let mm = prepare::ModelMachine::new(&chain, Some(&errors)).unwrap();
    let prep = prepare::prepare(&mm, &rec).unwrap();
    println!("prepare {:?}", t0.elapsed());
    let (_, sigma) = prepare::noise_floor(&prep.r);
    let ctx = fit::SearchCtx { sigma, ln_n: (prep.rows() as f64).ln(), min_after: 80 };
    let sel = fit::Selected::new(&prep, fit::design(&prep, &[]));
    for f in fit::Family::all(&prep) {
        let t0 = std::time::Instant::now();
        let c = fit::search_family(&prep, &sel, f, &ctx);
        println!("{:?} {:?} {:?}", f, t0.elapsed(), c.map(|c| c.score));
    }
    let t0 = std::time::Instant::now();
    let h = fit::holdout_rss(&prep, &fit::design(&prep, &[fit::Term{family: fit::Family::Backlash(1), nl: 0.0, onset: 0}]));
    println!("holdout {:?} {h}", t0.elapsed());
}

#[test]
#[ignore]
fn thermal_profile() {
    use kinpost::diagnose::{fit, prepare};
    let m = Machine::Zhao;
    let chain = m.chain();
    let errors = m.errors();
    let seed = 14;
    let prog = m.program(120, seed);
    let opts = sim_options(seed);
    let truth = calibrated(&chain, &errors, &prog, "thermal_drift:Z=0.002,tau=120@block=30", 0.0012, &opts);
    let rec = simulate(&chain, Some(&errors), &prog, &[truth.clone()], &opts).unwrap();
    let mm = prepare::ModelMachine::new(&chain, Some(&errors)).unwrap();
    let prep = prepare::prepare(&mm, &rec).unwrap();
    let (_, sigma) = prepare::noise_floor(&prep.r);
    let sel = fit::Selected::new(&prep, fit::design(&prep, &[]));
    let on30 = (0..prep.n).find(|&i| rec.samples[i].block == Some(30)).unwrap();
    let on27 = (0..prep.n).find(|&i| rec.samples[i].block == Some(27)).unwrap();
    for (tau, on) in [(120.0, on30), (247.3, on27), (120.0, on27), (247.3, on30), (160.0, on30), (90.0, on30)] {
        let t = fit::Term { family: fit::Family::ThermalDrift(2), nl: tau, onset: on };
        let cols = fit::design(&prep, &[t]);
        let s = fit::Selected::new(&prep, cols);
        let d = (s.h.transpose() * &s.ginv * &s.h)[(0,0)];
        println!("tau {tau} onset {on} t {:.1} dchi2 {:.1}", prep.t[on], d / sigma / sigma);
    }
    let _ = sel;
}

#[test]
#[ignore]
fn fa_case() {
    use kinpost::diagnose::{fit, prepare};
    let m = Machine::Zhao;
    let chain = m.chain();
    let errors = m.errors();
    let prog = m.program(80, 1003);
    let rec = simulate(&chain, Some(&errors), &prog, &[], &sim_options(1003)).unwrap();
    let mm = prepare::ModelMachine::new(&chain, Some(&errors)).unwrap();
    let prep = prepare::prepare(&mm, &rec).unwrap();
    let (_, sigma) = prepare::noise_floor(&prep.r);
    let ctx = fit::SearchCtx { sigma, ln_n: (prep.rows() as f64).ln(), min_after: (prep.n / 50).max(20) };
    let sel = fit::Selected::new(&prep, fit::design(&prep, &[]));
    let c = fit::search_family(&prep, &sel, fit::Family::Squareness(1, 2), &ctx).unwrap();
    println!("{c:?} n {} onsets {}", prep.n, prep.onsets.len());
    let base = fit::base_columns(&prep, fit::Family::Squareness(1, 2), 0.0);
    let prof = fit::scan(&prep, &sel, &base, &prep.onsets, None, ctx.min_after);
    for (k, d) in prof.iter().enumerate() { print!("{}:{:.1} ", prep.onsets[k], d / sigma / sigma); }
    println!();
}

#[test]
#[ignore]
fn refine_check() {
    use kinpost::compensate::{Options, refine};
    use kinpost::machine::NoErrors;
    let m = Machine::Zhao;
    let chain = m.chain();
    let errors = m.errors();
    let mchain = errors.apply_fixed(&chain).unwrap();
    let bound = errors.bind(&mchain).unwrap();
    let other = m.program(10, 77);
    let traj = sample_waypoints(&chain, &other, 1.0, Some(300.0)).unwrap();
    for p in traj.iter().take(15) {
        let qn: Vec<f64> = p.q.iter().zip(&chain.joints).map(|(v, j)| if j.kind == kinpost::machine::JointKind::Revolute { v.to_radians() } else { *v }).collect();
        let target = chain.pose(&qn, &NoErrors);
        let r = refine(&mchain, &bound, &target, &qn, &Options::default());
        let got = mchain.pose(&r.q, &bound);
        println!("q {:?} -> {:?} it {} conv {} tip err {:.3e} dq {:?}", p.q, r.q, r.iterations, r.converged, (got.tip - target.tip).norm(), r.q.iter().zip(&qn).map(|(a,b)| a-b).collect::<Vec<_>>());
    }
}

#[test]
#[ignore]
fn svg() {
    let m = Machine::Zhao;
    let chain = m.chain();
    let errors = m.errors();
    let prog = m.program(120, 3);
    let e = parse_effect_spec("backlash:X=0.0025").unwrap();
    let rec = simulate(&chain, Some(&errors), &prog, &[e], &sim_options(3)).unwrap();
    let r = diagnose(&chain, Some(&errors), &rec, &DiagOptions::default()).unwrap();
    r.write_svg(std::path::Path::new("/tmp/diag.svg")).unwrap();
}
