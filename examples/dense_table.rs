//! Writes the dense error table of the second benchmark workload
//! (`kinpost::geometric::synth::zhao2022_dense_tables`: X, Z every 0.1 mm,
//! B every 0.09°, six error motions each) to standard output.
//! Usage: `cargo run --release --example dense_table > dense.csv`

fn main() {
    print!(
        "{}",
        kinpost::geometric::synth::zhao2022_dense_tables(kinpost::geometric::synth::ZHAO2022_SEED)
    );
}
