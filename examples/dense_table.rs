//! Writes the dense error table of the second benchmark workload
//! (`kinpost::geometric::synth::zhao2022_dense_tables`: X, Z every 0.1 mm,
//! B every 0.09°, six error motions each) to standard output; with an
//! argument N, the spacing divided by N (the speed as tables grow).
//! Usage: `cargo run --release --example dense_table [N] > dense.csv`

fn main() {
    let finer = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1);
    print!(
        "{}",
        kinpost::geometric::synth::zhao2022_dense_tables_finer(
            kinpost::geometric::synth::ZHAO2022_SEED,
            finer
        )
    );
}
