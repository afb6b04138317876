//! Regenerates the worked examples of `docs/diagnose.md` (plots, text and
//! JSON reports): `cargo test --test diagnose_docs -- --ignored`.

mod diagnose_support;

use diagnose_support::*;

fn example(m: Machine, blocks: usize, seed: u64, specs: &[&str], name: &str) {
    let sc = m.scenario(blocks, seed);
    let effects = effects(specs);
    let (rec, r) = sc.run(&effects);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/diagnose");
    std::fs::create_dir_all(&dir).unwrap();
    r.write_svg(&dir.join(format!("{name}.svg"))).unwrap();
    std::fs::write(dir.join(format!("{name}.txt")), r.to_text()).unwrap();
    std::fs::write(dir.join(format!("{name}.json")), r.to_json_string() + "\n").unwrap();
    println!(
        "{name}: effect RMS {:.3} µm, geometric {:.3} µm, {} samples\n{}",
        effect_rms(&sc.chain, Some(&sc.errors), &sc.program, &effects, &sc.opts) * 1e3,
        geometric_rms(&sc.chain, &sc.errors, &sc.program, &sc.opts) * 1e3,
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
