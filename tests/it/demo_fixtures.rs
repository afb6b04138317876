//! The committed demo programs equal their deterministic generators' output.
//! Regenerate with `KINPOST_UPDATE_FIXTURES=1 cargo test --test it demo_fixtures::`.

use kinpost::demo::{OffAxisLens, exercise_program, impeller_program, lens_program};
use kinpost::machine::Machine;

fn check(path: &str, text: &str) {
    let full = format!("{}/{path}", env!("CARGO_MANIFEST_DIR"));
    if std::env::var_os("KINPOST_UPDATE_FIXTURES").is_some() {
        std::fs::write(&full, text).unwrap();
    }
    let committed = std::fs::read_to_string(&full).unwrap_or_default();
    assert!(
        committed == text,
        "{path} differs from its generator; regenerate with KINPOST_UPDATE_FIXTURES=1"
    );
}

#[test]
fn lens_program_fixture_is_generated() {
    let text = lens_program(&OffAxisLens::default());
    assert_eq!(text.lines().filter(|l| l.contains(" I")).count(), 241);
    check("fixtures/programs/zhao2022-lens.nc", &text);
}

#[test]
fn impeller_program_fixture_is_generated() {
    let text = impeller_program(600);
    assert_eq!(text.lines().filter(|l| l.contains(" I")).count(), 601);
    check("fixtures/programs/wang2023-impeller.nc", &text);
}

#[test]
fn exercise_program_fixtures_are_generated() {
    for (name, seed) in [("zhao2022-xzbc", 11), ("wang2023-xyzab", 12)] {
        let m = Machine::embedded(name).unwrap();
        let text = exercise_program(&m, 120, seed);
        check(&format!("fixtures/programs/{name}-exercise.nc"), &text);
    }
}
