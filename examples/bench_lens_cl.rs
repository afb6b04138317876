//! Writes the second benchmark workload's program: seed 000's lens ring
//! (`kinpost::demo::lens_path`, 241 poses) run back and forth until `POSES`
//! poses, as APT CL (`cl`, the default) or as a G-code pose program
//! (`gcode`, for the peer, which reads only G-code). Streams.
//! Usage: `cargo run --release --example bench_lens_cl -- 200000 cl > lens.cls`

use kinpost::demo::{OffAxisLens, lens_path};
use std::io::Write;

fn main() -> std::io::Result<()> {
    let mut args = std::env::args().skip(1);
    let n: usize = args
        .next()
        .map(|s| s.parse().expect("usage: bench_lens_cl POSES [cl|gcode]"))
        .unwrap_or(200_000);
    let cl = args.next().is_none_or(|f| f == "cl");
    let ring = lens_path(&OffAxisLens::default());
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    if cl {
        writeln!(
            out,
            "PARTNO/LENS BACK AND FORTH\nUNITS/MM\nMULTAX\nFEDRAT/MMPM,200.0"
        )?;
    } else {
        writeln!(
            out,
            "%\nO1002 (LENS RING BACK AND FORTH, {n} TOOL POSES)\nG21 G90 G94 G17\nG43.5 H1"
        )?;
    }
    for i in 0..n {
        // Forward on even laps, backward on odd ones; the turning points repeat a pose.
        let lap = i / ring.len();
        let j = i % ring.len();
        let p = &ring[if lap.is_multiple_of(2) {
            j
        } else {
            ring.len() - 1 - j
        }];
        let (t, a) = (p.tip, p.axis);
        if cl {
            writeln!(
                out,
                "GOTO/{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}",
                t.x, t.y, t.z, a.x, a.y, a.z
            )?;
        } else {
            let feed = if i == 0 { "G1 " } else { "" };
            let f = if i == 0 { " F200." } else { "" };
            writeln!(
                out,
                "{feed}X{:.9} Y{:.9} Z{:.9} I{:.9} J{:.9} K{:.9}{f}",
                t.x, t.y, t.z, a.x, a.y, a.z
            )?;
        }
    }
    if cl {
        writeln!(out, "FINI")?;
    } else {
        writeln!(out, "G49\nM30\n%")?;
    }
    out.flush()
}
