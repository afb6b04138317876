//! The committed synthetic error tables equal the generator's output.
//!
//! Regenerate with `KINPOST_UPDATE_FIXTURES=1 cargo test --test it fit_fixtures::`.

use std::path::PathBuf;

use kinpost::geometric::synth::{WANG2023_SEED, ZHAO2022_SEED, wang2023_tables, zhao2022_tables};
use kinpost::geometric::{ErrorModel, FitOptions, read_tables};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/errors")
        .join(name)
}

fn check(name: &str, generated: String) {
    let path = fixture(name);
    if std::env::var_os("KINPOST_UPDATE_FIXTURES").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap();
    assert!(
        committed == generated,
        "{} differs from the generator's output; regenerate with KINPOST_UPDATE_FIXTURES=1",
        path.display()
    );
}

#[test]
fn zhao2022_fixture_matches_generator() {
    check("zhao2022-xzbc.csv", zhao2022_tables(ZHAO2022_SEED));
}

#[test]
fn wang2023_fixture_matches_generator() {
    check("wang2023-xyzab.csv", wang2023_tables(WANG2023_SEED));
}

#[test]
fn fixtures_parse_and_fit() {
    for (name, axes) in [
        ("zhao2022-xzbc.csv", vec!["X", "Z", "B"]),
        ("wang2023-xyzab.csv", vec!["X", "Y", "Z", "A", "B"]),
    ] {
        let tables = read_tables(&fixture(name)).unwrap();
        let got: Vec<&str> = tables.iter().map(|t| t.axis.as_str()).collect();
        assert_eq!(got, axes);
        for t in &tables {
            assert!(
                t.direction.is_some(),
                "{name} {}: directions inferred",
                t.axis
            );
        }
        let (model, report) = ErrorModel::fit(&tables, &FitOptions::default()).unwrap();
        assert_eq!(model.axes.len(), axes.len());
        assert_eq!(report.iso230_2.len(), axes.len());
        if std::env::var_os("KINPOST_PRINT_REPORT").is_some() {
            println!("== {name}\n{}", report.to_text());
        }
    }
}
