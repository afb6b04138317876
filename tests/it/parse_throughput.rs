//! Parse throughput on a large synthetic five-axis program. Ignored by
//! default (it measures, it does not assert a speed):
//!
//! ```text
//! cargo test --release --test it parse_throughput:: -- --ignored --nocapture
//! ```

use std::io::Write;
use std::time::Instant;

use kinpost::cl::ClReader;
use kinpost::gcode::{LineReader, summarize};

/// About `mb` megabytes of G-code in the style of a CAM post's output.
fn synthetic_gcode(mb: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(mb << 20);
    out.extend_from_slice(
        b"%\r\nO1000 (SYNTHETIC 5-AXIS)\r\nG90 G94 G17 G21\r\nT1 M6\r\nG43.4 H1\r\n",
    );
    let mut n = 10u64;
    while out.len() < mb << 20 {
        let t = n as f64 * 1e-3;
        writeln!(
            out,
            "N{n} G1 X{:.4} Y{:.4} Z{:.4} A{:.3} C{:.3} F{}\r",
            100.0 * t.sin(),
            80.0 * t.cos(),
            -5.0 + t % 3.0,
            30.0 * (t * 0.7).sin(),
            (t * 57.3) % 360.0,
            if n.is_multiple_of(50) { 1200 } else { 800 }
        )
        .unwrap();
        if n.is_multiple_of(100) {
            out.extend_from_slice(b"(CHECKPOINT) ; a comment\r\n");
        }
        n += 10;
    }
    out.extend_from_slice(b"M30\r\n%\r\n");
    out
}

fn synthetic_cl(mb: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(mb << 20);
    out.extend_from_slice(b"TOOL PATH/OP1,TOOL,BALL6\nMULTAX/ON\nFEDRAT/MMPM,800.0000\n");
    let mut k = 0u64;
    while out.len() < mb << 20 {
        let t = k as f64 * 1e-3;
        writeln!(
            out,
            "GOTO/{:.4},{:.4},{:.4},{:.7},{:.7},{:.7}",
            100.0 * t.sin(),
            80.0 * t.cos(),
            -5.0 + t % 3.0,
            0.0,
            (t * 0.5).sin() * 0.5,
            (1.0 - 0.25 * (t * 0.5).sin().powi(2)).sqrt()
        )
        .unwrap();
        k += 1;
    }
    out.extend_from_slice(b"END-OF-PATH\n");
    out
}

fn rate(bytes: usize, secs: f64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64 / secs
}

#[test]
#[ignore = "measures throughput; run with --release --ignored --nocapture"]
fn parse_throughput() {
    let src = synthetic_gcode(64);

    // The streaming path: the reader's own line, buffers reused.
    let t0 = Instant::now();
    let mut words = 0usize;
    let mut reader = LineReader::new(src.as_slice());
    while let Some(line) = reader.next_line() {
        words += line.unwrap().words().count();
    }
    let parse = t0.elapsed().as_secs_f64();

    // Owned lines (the reader as an iterator): two allocations per line.
    let t0 = Instant::now();
    let mut owned_words = 0usize;
    for line in LineReader::new(src.as_slice()) {
        owned_words += line.unwrap().words().count();
    }
    let owned = t0.elapsed().as_secs_f64();
    assert_eq!(owned_words, words);

    let t0 = Instant::now();
    let mut out = Vec::with_capacity(src.len());
    kinpost::gcode::echo(src.as_slice(), &mut out).unwrap();
    let echo = t0.elapsed().as_secs_f64();
    assert_eq!(out, src);

    let t0 = Instant::now();
    let s = summarize(src.as_slice()).unwrap();
    let summary = t0.elapsed().as_secs_f64();

    let cl = synthetic_cl(64);
    let t0 = Instant::now();
    let mut records = 0usize;
    for r in ClReader::new(cl.as_slice(), "synthetic.cls") {
        r.unwrap();
        records += 1;
    }
    let cl_secs = t0.elapsed().as_secs_f64();

    println!(
        "G-code: {:.1} MiB, {} lines, {words} words\n  parse {:.0} MiB/s (owned lines {:.0} MiB/s), echo {:.0} MiB/s, summarize {:.0} MiB/s",
        src.len() as f64 / (1u64 << 20) as f64,
        s.lines,
        rate(src.len(), parse),
        rate(src.len(), owned),
        rate(src.len(), echo),
        rate(src.len(), summary),
    );
    println!(
        "CL: {:.1} MiB, {records} statements\n  read {:.0} MiB/s",
        cl.len() as f64 / (1u64 << 20) as f64,
        rate(cl.len(), cl_secs)
    );
}
