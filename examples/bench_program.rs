//! Writes the benchmark pose program (a long lens-like spiral for
//! zhao2022-xzbc, `kinpost::demo::write_lens_spiral_program`) to standard
//! output. Usage: `cargo run --release --example bench_program -- 200000 > poses.nc`

use kinpost::demo::{OffAxisLens, write_lens_spiral_program};
use std::io::Write;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("usage: bench_program POSES"))
        .unwrap_or(200_000);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    write_lens_spiral_program(&OffAxisLens::default(), n, &mut out).expect("write");
    out.flush().expect("flush");
}
