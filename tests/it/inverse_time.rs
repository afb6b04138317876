//! `post --feed inverse-time`, checked as a controller would run the output:
//! the test follows the feed mode (G93/G94) and F of the written program
//! block by block and, for every block, compares the time the controller
//! takes (G93: 1/F min; G94: path/F) with the tool tip's path length over
//! the programmed feed, the path computed here from the programmed poses.

use std::collections::HashMap;
use std::process::Command;

use crate::simulate_arcs::simulate_with;
use crate::util::BIN;

fn words(block: &str) -> HashMap<String, f64> {
    let code = block.split('(').next().unwrap();
    let mut m = HashMap::new();
    for w in code.split_whitespace() {
        let (a, v) = w.split_at(1);
        if let Ok(v) = v.parse::<f64>() {
            if a == "G" {
                m.insert(format!("G{v}"), v);
            } else {
                m.insert(a.to_string(), v);
            }
        }
    }
    m
}

/// A pose program on the xyzac-trt machine: N numbers on every pose block,
/// full X Y Z I J K, a feed that changes, straight moves with and without
/// a change of tool axis, a block that only turns the tool, rapids.
/// A programmed pose block: N, tool tip (mm), rapid, feed in force (mm/min).
type Block = (u32, [f64; 3], bool, f64);

fn program() -> (String, Vec<Block>) {
    let mut text = String::from("G21 G90 G94\nG43.4 H1\n");
    let mut poses = Vec::new();
    let mut feed = 800.0;
    let mut axis = [0.0f64, 0.0, 1.0];
    for k in 0..40u32 {
        let t = k as f64 * 0.37;
        // As written in the program (6 decimals).
        let r6 = |v: f64| format!("{v:.6}").parse::<f64>().unwrap();
        let tip = [
            r6(30.0 * t.cos()),
            r6(20.0 * (1.3 * t).sin()),
            r6(5.0 + 2.0 * t.sin()),
        ];
        // Every fifth block keeps the axis (no rotary move), every seventh
        // keeps the tip (a pure reorientation), block 12 is a rapid.
        if k % 5 != 0 {
            let a = 0.4 * (0.7 * t).sin();
            let c = 1.1 * t;
            axis = [a.sin() * c.cos(), a.sin() * c.sin(), a.cos()];
        }
        let tip = if k % 7 == 6 {
            poses
                .last()
                .map(|p: &(u32, [f64; 3], bool, f64)| p.1)
                .unwrap()
        } else {
            tip
        };
        if k == 20 {
            feed = 350.0;
        }
        let rapid = k == 12;
        let n = 10 * (k + 1);
        text.push_str(&format!(
            "N{n} {} X{:.6} Y{:.6} Z{:.6} I{:.9} J{:.9} K{:.9}{}\n",
            if rapid { "G0" } else { "G1" },
            tip[0],
            tip[1],
            tip[2],
            axis[0],
            axis[1],
            axis[2],
            if k == 0 || k == 13 || k == 20 {
                format!(" F{feed}")
            } else {
                String::new()
            }
        ));
        if k == 26 {
            text.push_str("M8\n");
        }
        poses.push((n, tip, rapid, feed));
    }
    text.push_str("G49\nG1 X0 Y0 Z50\nM30\n");
    (text, poses)
}

/// `kinpost post` of `path` on xyzac-trt with 9 decimals and `--feed
/// feed`: its standard output (the run must succeed).
fn post_with_feed(path: &std::path::Path, feed: &str) -> String {
    let out = Command::new(BIN)
        .args([
            "post",
            "-m",
            "xyzac-trt",
            "--decimals",
            "9",
            "-q",
            "--feed",
            feed,
        ])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Follows the written program `out` as a controller would (feed mode G93 /
/// G94 and the modal F) and checks every pose block: one that turns a
/// rotary axis and moves the tip is in G93 with F · (1/F min) equal to
/// the tip path at the programmed feed; any other is in G94 with the
/// programmed feed. `block` gives the programmed block of a line's words
/// (None for a line that is not a pose block). Returns the blocks
/// converted and kept; the program must not end in G93.
fn follow(
    out: &str,
    mut block: impl FnMut(&HashMap<String, f64>) -> Option<Block>,
) -> (usize, usize) {
    let mut inverse = false;
    let mut f_modal: Option<f64> = None;
    let mut last_axes: Option<(f64, f64)> = None;
    let mut last_tip: Option<[f64; 3]> = None;
    let (mut converted, mut kept) = (0, 0);
    for line in out.lines() {
        let w = words(line);
        if w.contains_key("G93") {
            inverse = true;
        }
        if w.contains_key("G94") {
            inverse = false;
        }
        if let Some(f) = w.get("F") {
            f_modal = Some(*f);
        }
        let Some((_, tip, rapid, feed)) = block(&w) else {
            continue;
        };
        let axes = (w["A"], w["C"]);
        let rotary =
            last_axes.is_some_and(|a| (a.0 - axes.0).abs() > 1e-7 || (a.1 - axes.1).abs() > 1e-7);
        let length = last_tip.map(|s| {
            ((tip[0] - s[0]).powi(2) + (tip[1] - s[1]).powi(2) + (tip[2] - s[2]).powi(2)).sqrt()
        });
        if !rapid && rotary && length.is_some_and(|l| l > 1e-6) {
            // G93: the block lasts 1/F min; at the programmed feed the tip
            // needs length/feed.
            assert!(inverse, "not in G93: {line}");
            let time = 1.0 / f_modal.unwrap();
            let l = length.unwrap();
            assert!(
                (feed * time - l).abs() < 1e-7 * l.max(1.0),
                "F·t = {} mm, tip path {l} mm: {line}",
                feed * time
            );
            assert!(w.contains_key("F"), "G93 needs F on every block: {line}");
            converted += 1;
        } else {
            // Not converted: G94 with the programmed feed.
            assert!(!inverse, "left in G93: {line}");
            if !rapid {
                assert_eq!(f_modal, Some(feed), "{line}");
            }
            kept += 1;
        }
        last_axes = Some(axes);
        last_tip = Some(tip);
    }
    assert!(!inverse, "the program ends in G93:\n{out}");
    (converted, kept)
}

#[test]
fn the_tool_tip_keeps_the_programmed_feed() {
    let dir = tempfile::tempdir().unwrap();
    let (text, poses) = program();
    let path = dir.path().join("p.ngc");
    std::fs::write(&path, &text).unwrap();
    let run = |feed: &str| post_with_feed(&path, feed);
    let out = run("inverse-time");
    let by_n: HashMap<u32, &Block> = poses.iter().map(|p| (p.0, p)).collect();
    // The pose blocks carry their N numbers.
    let (converted, kept) = follow(&out, |w| w.get("N").map(|n| *by_n[&(*n as u32)]));
    assert!(
        converted >= 25 && kept >= 8,
        "converted {converted}, kept {kept}"
    );
    // M8 between converted blocks: the controller is back in G94 before it.
    let m8 = out.lines().position(|l| l.trim() == "M8").unwrap();
    assert!(
        out.lines().nth(m8 - 1).unwrap().starts_with("G94 F"),
        "{out}"
    );
    // The default leaves the feeds as programmed: no G93 anywhere.
    let keep = run("keep");
    assert!(!keep.contains("G93"));
    assert_eq!(
        keep.lines().filter(|l| l.contains('F')).count(),
        text.lines().filter(|l| l.contains('F')).count()
    );
}

/// The same poses as APT CL (`GOTO/x,y,z,i,j,k`, `FEDRAT/MMPM`, `RAPID`),
/// posted with `--feed inverse-time` and followed as a controller runs it:
/// the pose blocks come in the order of the `GOTO`s.
#[test]
fn apt_cl_keeps_the_programmed_tip_feed_too() {
    let dir = tempfile::tempdir().unwrap();
    let (_, poses) = program();
    let mut cl = String::from("UNITS/MM\nMULTAX/ON\n");
    let mut feed = None;
    let mut axis = [0.0f64, 0.0, 1.0];
    let (text, _) = program();
    for (line, p) in text.lines().filter(|l| l.starts_with('N')).zip(&poses) {
        let w = words(line);
        axis = [
            w.get("I").copied().unwrap_or(axis[0]),
            w.get("J").copied().unwrap_or(axis[1]),
            w.get("K").copied().unwrap_or(axis[2]),
        ];
        if p.2 {
            cl.push_str("RAPID\n");
        } else if feed != Some(p.3) {
            cl.push_str(&format!("FEDRAT/MMPM,{}\n", p.3));
            feed = Some(p.3);
        }
        cl.push_str(&format!(
            "GOTO/{:.6},{:.6},{:.6},{:.9},{:.9},{:.9}\n",
            p.1[0], p.1[1], p.1[2], axis[0], axis[1], axis[2]
        ));
    }
    cl.push_str("FINI\n");
    let path = dir.path().join("p.cls");
    std::fs::write(&path, &cl).unwrap();
    let out = post_with_feed(&path, "inverse-time");
    // The pose blocks come in the order of the GOTOs.
    let mut blocks = poses.iter();
    let (converted, kept) = follow(&out, |w| {
        w.contains_key("X")
            .then(|| *blocks.next().expect("one block per GOTO"))
    });
    assert!(blocks.next().is_none(), "{out}");
    assert!(
        converted >= 25 && kept >= 8,
        "converted {converted}, kept {kept}"
    );
}

#[test]
fn a_block_that_sets_its_own_feed_mode_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.ngc");
    std::fs::write(
        &path,
        "G21 G90 G94\nG43.4 H1\nG1 X0 Y0 Z10 I0 J0 K1 F500\nX10 Y0 Z10 I0 J0.6 K0.8\n\
G93 X20 Y0 Z10 I0 J0 K1 F12\nG94 X30 Y0 Z10 I0 J0.6 K0.8 F400\nG49\nM30\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["post", "-m", "xyzac-trt", "-q", "--feed", "inverse-time"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success());
    let out = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    // Converted: 10 mm at 500 mm/min.
    assert!(lines[3].ends_with(" G93 F50"), "{out}");
    // The program's own G93 block keeps its words (G93 F12).
    assert!(
        lines[4].starts_with("G93 X") && lines[4].ends_with(" F12"),
        "{out}"
    );
    assert_eq!(lines[4].matches("G9").count(), 1, "{out}");
    // Back in the program's G94: converted again (10 mm at 400 mm/min).
    assert!(lines[5].ends_with(" G93 F40"), "{out}");
    assert!(!lines[5].contains("G94"), "{out}");
}

/// `simulate` runs a block under inverse time (`G93`) in 1/F minutes,
/// whatever its length, in a program in machine axes and in a pose
/// program alike. Before, G93 blocks had no feed for it and ran at the
/// rapid feed (a 10 s block in 0.3 s), exit 0.
#[test]
fn simulate_runs_inverse_time_blocks_in_their_time() {
    for (name, machine, program, blocks) in [
        (
            "axes.ngc",
            "xyzac-trt",
            "G21 G90 G94\nG1 X0 Y0 Z0 A0 C0 F600\nG93 G1 X10 A10 F6\nG1 X20 A20 F12\nG94 G1 X30 F600\nM2\n",
            [3u64, 4],
        ),
        (
            "poses.ngc",
            "xyzac-trt",
            "G21 G90 G94\nG43.4 H1\nG1 X10 Y0 Z20 I0 J0 K1 F600\nG93 G1 X12 Y3 Z20 I0 J0.1 K0.99498744 F6\nG1 X14 Y5 Z20 I0 J0.2 K0.9797959 F12\nG94 G1 X20 F600\nM2\n",
            [4, 5],
        ),
    ] {
        let (text, _) = simulate_with(machine, program, &["--accel", "0"]);
        // Samples every 0.01 s: a block of 1/F minutes holds 60/F s of them.
        for (block, seconds) in blocks.iter().zip([10.0, 5.0]) {
            let count = text
                .lines()
                .skip(1)
                .filter(|l| l.split(',').nth(1) == Some(&block.to_string()))
                .count();
            let expected = seconds / 0.01;
            assert!(
                (count as f64 - expected).abs() <= 1.0,
                "{name}: block {block} has {count} samples, {expected} expected"
            );
        }
    }
}

/// A feed per revolution with the spindle turning at a known speed runs at
/// F × S: `G95 F0.1` with `S600 M3` is 60 mm/min, 10 mm in 10 s. Before,
/// every `G95` block ran at `--rapid-feed` (10 mm in 0.2 s). The speed
/// must be known: after `M5`, and under a constant surface speed (`G96`),
/// the block runs at the rapid feed with the warning; an `S` with `G50` is
/// a speed clamp, not a speed.
#[test]
fn a_feed_per_revolution_runs_at_the_spindle_speed() {
    let time_of = |program: &str| -> (f64, String) {
        let (rec, stderr) = simulate_with("xyz-3axis", program, &[]);
        let end: f64 = rec
            .lines()
            .last()
            .and_then(|l| l.split(',').next())
            .unwrap()
            .parse()
            .unwrap();
        (end, stderr)
    };
    let (t, err) =
        time_of("G21 G90 G94\nG0 X0 Y0 Z0\nS600 M3\nG50 S3000\nG95 G1 X10 F0.1\nM5\nM2\n");
    // 10 s at 60 mm/min.
    assert!(t > 9.99 && t < 10.5, "{t} s\n{err}");
    assert!(!err.contains("without a feed per minute"), "{err}");
    for stopped in [
        "G21 G90 G94\nG0 X0 Y0 Z0\nS600 M3\nM5\nG95 G1 X10 F0.1\nM2\n",
        "G21 G90 G94\nG0 X0 Y0 Z0\nG96 S200 M3\n(surface speed)\nG95 G1 X10 F0.1\nM2\n",
    ] {
        let (t, err) = time_of(stopped);
        assert!(t < 1.0, "{t} s: {stopped}");
        assert!(
            err.contains("1 block(s) move without a feed per minute") && err.contains("line 5)"),
            "{err}"
        );
    }
}

/// A cutting block without a feed per minute (F per revolution under
/// `G95`, or no F at all) runs at `--rapid-feed`, and `simulate` says so,
/// naming the line; before, it ran so without a word.
#[test]
fn simulate_names_the_blocks_without_a_feed_per_minute() {
    let (_, stderr) = simulate_with(
        "xyz-3axis",
        "G21 G90 G95\nG1 X0 Y0 Z0 F0.1\nG1 X10 F0.1\nG94 G1 X20 F600\nG1 X30\nM2\n",
        &[],
    );
    assert!(
        stderr.contains("1 block(s) move without a feed per minute") && stderr.contains("line 3)"),
        "{stderr}"
    );
}
