//! `simulate` streams (docs/robustness.md, "simulate streams"): the
//! recording is written as the program is read, each sample handed on as
//! soon as the blocks it depends on are known, so memory holds a few blocks
//! and not the program (it held the whole program, its timeline and every
//! sample: 1.05 GB for 2,000,000 blocks; now 6 MB, bench/memory.sh).
//! The references here are the positions worked out in the test from the
//! blocks' lengths and feeds.

use kinpost::diagnose::simulate::{SimOptions, TipSimulator, Waypoint, WaypointPath};
use kinpost::diagnose::{EffectSpec, Sample};
use kinpost::machine::Machine;

use crate::cl_support::kinpost;

/// Waypoints along X on a three-axis machine: 0, 10, 20, … mm, `blocks`
/// moves of 10 mm at F600 (10 mm/s: 1 s each).
fn along_x(blocks: usize) -> Vec<Waypoint> {
    (0..=blocks)
        .map(|k| Waypoint {
            q: vec![10.0 * k as f64, 0.0, 0.0],
            feed: 600.0,
            block: k as u64 + 1,
            path: WaypointPath::Straight,
        })
        .collect()
}

/// Runs a [`TipSimulator`] over `waypoints`; returns every sample and how
/// many had been handed on after each waypoint was pushed.
fn streamed(waypoints: &[Waypoint], opts: &SimOptions) -> (Vec<Sample>, Vec<usize>) {
    let m = Machine::embedded("xyz-3axis").unwrap();
    let effects: Vec<EffectSpec> = Vec::new();
    let mut sim = TipSimulator::new(&m.chain, None, &effects, opts).unwrap();
    let mut samples = Vec::new();
    let mut after = Vec::new();
    for w in waypoints {
        sim.push(w, &mut |s| {
            samples.push(s);
            Ok(())
        })
        .unwrap();
        after.push(samples.len());
    }
    let n = sim
        .finish(&mut |s| {
            samples.push(s);
            Ok(())
        })
        .unwrap();
    assert_eq!(n, samples.len());
    (samples, after)
}

fn options(time_offset_s: f64) -> SimOptions {
    SimOptions {
        noise_mm: 0.0,
        sample_interval_s: 0.25,
        accel_mm_s2: None,
        time_offset_s,
        ..SimOptions::default()
    }
}

#[test]
fn samples_are_handed_on_while_the_program_is_read() {
    let blocks = 200;
    let (samples, after) = streamed(&along_x(blocks), &options(0.0));
    // 200 s every 0.25 s, both ends included.
    assert_eq!(samples.len(), 4 * blocks + 1);
    // Once the block ending at waypoint k (k s) is pushed, every sample
    // before the block before it is known (the sampler waits until no
    // later block can start before a sample's time).
    for (k, &n) in after.iter().enumerate().skip(2) {
        assert!(n >= 4 * (k - 1), "after waypoint {k}: {n} samples");
    }
    for (i, s) in samples.iter().enumerate() {
        let t = 0.25 * i as f64;
        assert!((s.t - t).abs() < 1e-12, "sample {i}: t {}", s.t);
        // 10 mm/s from X0.
        assert!((s.q[0] - 10.0 * t).abs() < 1e-9, "sample {i}: X {}", s.q[0]);
        assert!(
            (s.meas[0] - 10.0 * t).abs() < 1e-9,
            "sample {i}: tip {}",
            s.meas[0]
        );
        // The block of waypoint k + 1 (numbered k + 2) runs from k s to
        // k + 1 s; the last one goes on to the end.
        let k = (t.floor() as u64).min(blocks as u64 - 1);
        assert_eq!(s.block, Some(k + 2), "sample {i}");
    }
}

#[test]
fn a_clock_offset_either_way_streams_the_machine_behind_or_ahead() {
    let blocks = 50;
    for offset in [0.3, -0.3, 2.6, -2.6] {
        let (samples, after) = streamed(&along_x(blocks), &options(offset));
        assert_eq!(samples.len(), 4 * blocks + 1, "offset {offset}");
        // Samples still go out before the end: all but those within the
        // offset (and a block) of the end.
        let before_end = after[after.len() - 1];
        assert!(
            before_end as f64 >= samples.len() as f64 - 4.0 * (offset.abs() + 2.0),
            "offset {offset}: {before_end} of {} before the end",
            samples.len()
        );
        for s in &samples {
            // The command is the command at the stamp; the tip is where
            // the machine was `offset` earlier (held at the ends).
            assert!((s.q[0] - 10.0 * s.t).abs() < 1e-9);
            let machine_t = (s.t - offset).clamp(0.0, blocks as f64);
            assert!(
                (s.meas[0] - 10.0 * machine_t).abs() < 1e-9,
                "offset {offset}, t {}: tip X {} expected {}",
                s.t,
                s.meas[0],
                10.0 * machine_t
            );
        }
    }
}

/// Found making `simulate` stream: a joint-feedback trace with a clock
/// offset read the axes on a fine sampling of the whole program every
/// 0.1 ms, kept in memory, and refused programs longer than 5,000 s
/// ("9.000e8 samples … are too many") whatever the sample interval asked
/// for. The reference: at constant speed the axes at t − offset.
#[test]
fn a_feedback_trace_with_a_clock_offset_runs_a_long_program() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("slow.ngc");
    // 1000 mm at F1 (60,000 s), then back at F2 (30,000 s).
    std::fs::write(&prog, "G90 G21\nG1 X0 Y0 Z0 F100\nG1 X1000 F1\nG1 X0 F2\n").unwrap();
    let rec = dir.path().join("fb.csv");
    let out = kinpost(&[
        "simulate",
        "-m",
        "xyz-3axis",
        "--feedback",
        "--noise",
        "0",
        "--accel",
        "0",
        "--time-offset",
        "0.1",
        "--sample-interval",
        "100",
        "--program",
        prog.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let text = std::fs::read_to_string(&rec).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 901, "90,000 s every 100 s");
    for r in &rows {
        let (t, x, fb_x) = (r[0], r[2], r[5]);
        let at = |t: f64| {
            if t <= 60_000.0 {
                t / 60.0
            } else {
                1000.0 - (t - 60_000.0) / 30.0
            }
        };
        assert!((x - at(t)).abs() < 2e-7, "t {t}: X {x}");
        // Away from the turn and the start, the axes are where the
        // command was 0.1 s earlier.
        if t > 1.0 && (t - 60_000.0).abs() > 1.0 {
            assert!((fb_x - at(t - 0.1)).abs() < 2e-7, "t {t}: fb_X {fb_x}");
        }
    }
}

/// A program with one position or none cannot be recorded; the refusal
/// names a line and column (it named only the file).
#[test]
fn a_program_with_fewer_than_two_positions_is_refused_at_a_line() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text, said) in [
        (
            "one.ngc",
            "G21 G90\nG0 X1 Y2 Z3\nM30\n",
            "one.ngc:2:1: this is the program's only position",
        ),
        (
            "none.ngc",
            "G21 G90\nM30\n",
            "none.ngc:1:1: the program has no position",
        ),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let o = dir.path().join("r.csv");
        let out = kinpost(&[
            "simulate",
            "-m",
            "xyz-3axis",
            "-p",
            p.to_str().unwrap(),
            "-o",
            o.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(said), "{err}");
        assert!(!o.exists());
    }
}
