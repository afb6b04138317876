//! The committed demo programs equal their deterministic generators' output.
//! Regenerate with `KINPOST_UPDATE_FIXTURES=1 cargo test --test demo_fixtures`.

use kinpost::demo::{OffAxisLens, impeller_program, lens_program};

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
