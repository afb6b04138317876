//! Regenerates the worked examples of `docs/diagnose.md` (plots, text and
//! JSON reports): `cargo test --test diagnose_docs -- --ignored`.

mod diagnose_support;

use diagnose_support::*;
use kinpost::diagnose::{DiagOptions, diagnose, parse_effect_spec, simulate};

fn example(m: Machine, blocks: usize, seed: u64, specs: &[&str], name: &str) {
    let chain = m.chain();
    let errors = m.errors();
    let program = m.program(blocks, seed);
    let opts = sim_options(seed);
    let effects: Vec<_> = specs
        .iter()
        .map(|s| parse_effect_spec(s).unwrap())
        .collect();
    let rec = simulate(&chain, Some(&errors), &program, &effects, &opts).unwrap();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/diagnose");
    std::fs::create_dir_all(&dir).unwrap();
    let r = diagnose(&chain, Some(&errors), &rec, &DiagOptions::default()).unwrap();
    r.write_svg(&dir.join(format!("{name}.svg"))).unwrap();
    std::fs::write(dir.join(format!("{name}.txt")), r.to_text()).unwrap();
    std::fs::write(dir.join(format!("{name}.json")), r.to_json_string() + "\n").unwrap();
    println!(
        "{name}: effect RMS {:.3} µm, geometric {:.3} µm, {} samples\n{}",
        effect_rms(&chain, Some(&errors), &program, &effects, &opts) * 1e3,
        geometric_rms(&chain, &errors, &program, &opts) * 1e3,
        rec.len(),
        r.to_text()
    );
}

#[test]
#[ignore]
fn regenerate_worked_examples() {
    example(
        Machine::Zhao,
        120,
        7,
        &["backlash:X=0.0024@block=40"],
        "zhao-backlash",
    );
    example(
        Machine::Wang,
        100,
        7,
        &["pivot_length:0.0015"],
        "wang-pivot",
    );
    example(Machine::Wang, 100, 8, &[], "wang-clean");
}
