//! Criterion benchmarks: analytic IK, compensated poses per second on both
//! seed machines, and post-processing throughput (parse alone, post, and
//! compensate through the chunked driver on all cores).
//! Run: `cargo bench --bench kinematics`; figures in docs/performance.md.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kinpost::compensate::{
    BlockRecord, CompensatingSolver, OnFail, Options, compensate_gcode, refine,
};
use kinpost::demo::{OffAxisLens, impeller_poses, lens_path, lens_program};
use kinpost::gcode::LineReader;
use kinpost::geometric::model::ErrorModel;
use kinpost::machine::{IkSolver, Machine, Pose};
use kinpost::post::{PostOptions, post_gcode};
use std::hint::black_box;
use std::path::Path;

fn case(name: &str, errors: &str, poses: Vec<Pose>) -> (Machine, ErrorModel, Vec<Pose>, String) {
    let machine = Machine::embedded(name).unwrap();
    let path = format!("{}/fixtures/errors/{errors}", env!("CARGO_MANIFEST_DIR"));
    let model = ErrorModel::load(Path::new(&path)).unwrap();
    (machine, model, poses, name.to_string())
}

fn bench(c: &mut Criterion) {
    let cases = [
        case(
            "zhao2022-xzbc",
            "zhao2022-xzbc.csv",
            lens_path(&OffAxisLens::default()),
        ),
        case("wang2023-xyzab", "wang2023-xyzab.csv", impeller_poses(600)),
    ];
    for (machine, model, poses, name) in &cases {
        let ik = IkSolver::new(machine);
        let bound = model.bind(&machine.chain).unwrap();
        let actual = model.apply_fixed(&machine.chain).unwrap();
        let mut g = c.benchmark_group(name.as_str());
        g.throughput(Throughput::Elements(poses.len() as u64));
        g.bench_function("ik", |b| {
            b.iter(|| {
                let mut prev: Option<kinpost::machine::JointValues> = None;
                for p in poses {
                    prev = Some(ik.solve(black_box(p), prev.as_deref()).unwrap().q);
                }
                prev
            })
        });
        g.bench_function("ik+compensate", |b| {
            let opts = Options::default();
            b.iter(|| {
                let mut prev: Option<kinpost::machine::JointValues> = None;
                for p in poses {
                    let q = ik.solve(black_box(p), prev.as_deref()).unwrap().q;
                    let r = refine(&actual, &bound, p, &q, &opts);
                    prev = Some(r.q);
                }
                prev
            })
        });
        g.finish();
    }
    let program = lens_program(&OffAxisLens::default());
    let machine = Machine::embedded_default();
    let mut g = c.benchmark_group("post");
    g.throughput(Throughput::Bytes(program.len() as u64));
    g.bench_function("zhao2022-lens parse only", |b| {
        b.iter(|| {
            let mut reader = LineReader::new(program.as_bytes());
            let mut words = 0;
            while let Some(line) = reader.next_line() {
                words += line.unwrap().words().count();
            }
            words
        })
    });
    g.bench_function("zhao2022-lens", |b| {
        let opts = PostOptions::default();
        b.iter(|| {
            let mut ik = IkSolver::new(&machine);
            let mut out = Vec::with_capacity(program.len());
            post_gcode(
                &machine,
                &mut ik,
                program.as_bytes(),
                &mut out,
                &opts,
                |_| {},
            )
            .unwrap();
            out
        })
    });
    g.bench_function("zhao2022-lens compensate (chunked driver)", |b| {
        let opts = PostOptions::default();
        let path = format!(
            "{}/fixtures/errors/zhao2022-xzbc.csv",
            env!("CARGO_MANIFEST_DIR")
        );
        let model = ErrorModel::load(Path::new(&path)).unwrap();
        let bound = model.bind(&machine.chain).unwrap();
        b.iter(|| {
            let mut solver = CompensatingSolver {
                machine: &machine,
                actual_chain: model.apply_fixed(&machine.chain).unwrap(),
                errors: &bound,
                ik: IkSolver::new(&machine),
                options: Options::default(),
                on_fail: OnFail::Error,
                accept_tip_mm: 1e-9,
                axis_tolerance_rad: 1e-4,
                records: Vec::new(),
                warnings: Vec::new(),
                singular_blocks: 0,
                decimals: Vec::new(),
                backlash: Vec::new(),
                directions: Vec::new(),
                written_per_block: true,
                written_largest: (0.0, 0.0),
            };
            let mut out = Vec::with_capacity(program.len());
            compensate_gcode(
                &machine,
                &mut solver,
                program.as_bytes(),
                &mut out,
                &opts,
                |_| {},
                |r: &mut Vec<BlockRecord>| {
                    r.clear();
                    Ok(())
                },
            )
            .unwrap();
            out
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
