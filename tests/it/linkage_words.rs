//! `kinpost linkage` divides a five-axis block into inserted blocks followed
//! by the block's own line. The block's other words must still act where
//! the controller would act on them. Found on real programs (an NX lathe
//! post's `G1 X3.6806 C-1.0625 Z.1 F100. M8`): before, everything but the
//! axis words and F stayed on the block's own line, now the last segment,
//! so `G91` came after increments the controller read as absolute
//! positions, `G93` after inverse-time feeds read as mm/min, `M3` after the
//! cut, and a block-delete `/` skipped only the last segment. Each written
//! program is followed here like a controller reads it.

use std::process::Command;

use crate::util::BIN;

/// Runs `kinpost linkage` on xyzbc-trt: (exit code, stdout, stderr).
fn linkage(name: &str, program: &str) -> (i32, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, program).unwrap();
    let out = Command::new(BIN)
        .args(["linkage", "--machine", "xyzbc-trt"])
        .arg(&p)
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// What a controller has in force when it runs a block.
#[derive(Debug, Clone, Default)]
struct State {
    /// X Y Z B C, absolute.
    pos: [f64; 5],
    incremental: bool,
    inverse_time: bool,
    spindle_on: bool,
    speed: f64,
    /// Minutes of the G93 blocks run so far.
    g93_minutes: f64,
}

/// Runs `text` like a controller, calling `each` with the line and the
/// state after it (the motion words of a line run after its modal codes,
/// spindle and feed words, as LinuxCNC and Fanuc order them). Lines that
/// begin with `/` are skipped when `skip` is set.
fn run(text: &str, skip: bool, mut each: impl FnMut(&str, &State)) -> State {
    let mut s = State::default();
    for line in text.lines() {
        if skip && line.starts_with('/') {
            continue;
        }
        let l = kinpost::gcode::parse_line(line.as_bytes(), 1);
        let mut moved = false;
        let mut feed = None;
        for w in l.words() {
            match (w.address.as_str(), w.value) {
                ("G", 90.0) => s.incremental = false,
                ("G", 91.0) => s.incremental = true,
                ("G", 93.0) => s.inverse_time = true,
                ("G", 94.0) => s.inverse_time = false,
                ("M", 3.0) => s.spindle_on = true,
                ("M", 5.0) => s.spindle_on = false,
                ("S", v) => s.speed = v,
                ("F", v) => feed = Some(v),
                _ => {}
            }
        }
        for w in l.words() {
            if let Some(k) = ["X", "Y", "Z", "B", "C"]
                .iter()
                .position(|a| *a == w.address.as_str())
            {
                s.pos[k] = if s.incremental {
                    s.pos[k] + w.value
                } else {
                    w.value
                };
                moved = true;
            }
        }
        if moved && s.inverse_time {
            s.g93_minutes += 1.0 / feed.expect("every G93 move has its F");
        }
        each(line, &s);
    }
    s
}

fn close(a: [f64; 5], b: [f64; 5]) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6)
}

#[test]
fn words_of_a_divided_block_act_where_it_starts() {
    // G91: the inserted increments must be read as increments.
    let (code, out, err) = linkage(
        "inc.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X51 F300\nG91 G1 X9 Y10 Z-10 B10 C20\nG90 G1 X70 F500\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(kinpost linkage 1/"), "{out}");
    let mut at_block_end = None;
    run(&out, false, |line, s| {
        if line.starts_with("G1 X") && !line.contains("kinpost") && at_block_end.is_none() {
            // The divided block's own line, after the inserted ones.
            if s.pos[1] != 0.0 {
                at_block_end = Some(s.pos);
            }
        }
        if line.contains("(kinpost linkage") {
            assert!(s.incremental, "an inserted block read as absolute: {line}");
            // Every inserted point lies between the two ends.
            assert!(s.pos[0] > 50.9 && s.pos[0] < 60.1, "{line}: {:?}", s.pos);
        }
    });
    let end = at_block_end.expect("the divided block's line");
    assert!(close(end, [60.0, 10.0, 10.0, 40.0, 60.0]), "{end:?}\n{out}");

    // G93: every segment in inverse time, the block's time kept (1/F₀).
    let (code, out, err) = linkage(
        "g93.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X51 F300\nG93 G1 X60 Y10 Z10 B40 C60 F2.0\nG94 G1 X70 F500\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    let end = run(&out, false, |line, s| {
        if line.contains("(kinpost linkage") {
            assert!(s.inverse_time, "a G93 segment read in G94: {line}");
        }
    });
    assert!(
        (end.g93_minutes - 0.5).abs() < 1e-9,
        "{}\n{out}",
        end.g93_minutes
    );

    // M3 S2000: the spindle turns from the first segment on.
    let (code, out, err) = linkage(
        "m3.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X60 Y10 Z10 B40 C60 F500 M3 S2000\nG1 X70 M5\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    run(&out, false, |line, s| {
        if line.contains("(kinpost linkage") {
            assert!(
                s.spindle_on && s.speed == 2000.0,
                "cut without the spindle: {line}"
            );
        }
    });
    let m3 = out
        .lines()
        .filter(|l| l.split(' ').any(|w| w == "M3"))
        .count();
    assert_eq!(m3, 1, "{out}");
    // A program stop acts when its block ends: it stays on the block's line.
    let (code, out, err) = linkage(
        "m0.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X60 Y10 Z10 B40 C60 F500 M0\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    let stop = out.lines().find(|l| l.contains("M0")).unwrap();
    assert!(!stop.contains("kinpost linkage"), "{out}");
}

#[test]
fn a_block_delete_divided_block_is_skipped_whole() {
    let program = "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X51 F300\n/G1 X60 Y10 Z10 B40 C60\nG1 X70 F500\nM30\n";
    let (code, out, err) = linkage("bd.nc", program);
    assert_eq!(code, 0, "{err}");
    // With the switch on, the tool stays where it was until the next block
    // (which moves X only).
    run(&out, true, |line, s| {
        if line == "G1 X70 F500" {
            assert!(
                close(s.pos, [70.0, 0.0, 20.0, 30.0, 40.0]),
                "part of the skipped block ran: {:?}\n{out}",
                s.pos
            );
        }
    });
    // A block after a / block starts where the switch says: not divided.
    let (code, _, err) = linkage(
        "after.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\n/G1 X51 F300\nG1 X60 Y10 Z10 B40 C60\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("after.nc:4:") && err.contains("block delete"),
        "{err}"
    );
}

#[test]
fn an_axis_the_machine_lacks_in_a_divided_block_is_refused() {
    // A five-axis printing program: its E is the extrusion of the whole
    // segment, which kinpost cannot share out between inserted blocks.
    let (code, _, err) = linkage(
        "e.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X60 Y10 Z10 B40 C60 E0.25 F500\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("e.nc:3:24:") && err.contains("`E`"), "{err}");
}

/// Runs `kinpost analyze --nonlinear` on xyzbc-trt: (exit code, stdout, stderr).
fn nonlinear(name: &str, program: &str) -> (i32, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, program).unwrap();
    let out = Command::new(BIN)
        .args(["analyze", "--nonlinear", "--machine", "xyzbc-trt"])
        .arg(&p)
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn blocks_that_are_not_moves_are_not_followed() {
    // G52 (a local offset), G10 (offset data), Fanuc's G4 X1.5 (a dwell of
    // 1.5 s): their axis words are not a position. Before, linkage took
    // each for a five-axis G1 move and inserted up to 55 blocks that drove
    // the machine there (and rewrote the G52's words), exit 0.
    for (name, data) in [
        ("g52.nc", "G52 X10 B10"),
        ("g10.nc", "G10 L2 P1 X60 Y10 Z10 B40 C60"),
        ("g4.nc", "G4 X1.5"),
        ("trans.mpf", "TRANS X10 Y5"),
    ] {
        let program =
            format!("G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG1 X51 F300\n{data}\nG1 X52 F500\nM30\n");
        let (code, out, err) = linkage(name, &program);
        assert_eq!(code, 0, "{name}: {err}");
        assert_eq!(out, program, "{name}: not a move, nothing to divide");
        let (code, out, err) = nonlinear(name, &program);
        assert_eq!(code, 0, "{name}: {err}");
        // The G1 after it moves X by 1 mm from X51: no nonlinear error.
        assert!(out.contains("max 0.0000 µm"), "{name}: {out}");
    }
    // After G53 the Z in program coordinates is not known: a G1 from there
    // cannot be divided (before: measured and divided from program Z0).
    let (code, _, err) = linkage(
        "g53.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG53 G0 Z0\nG1 X60 Y10 Z10 B40 C60 F300\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("g53.nc:4:") && err.contains("G53"), "{err}");
    // A move of linear axes alone is a straight line whatever the start.
    let (code, _, err) = linkage(
        "g53lin.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG53 G0 Z0\nG1 Z5 F300\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    // NX's tool change: G28 homes B to 0°, the linear axes are programmed
    // again before the cut (an NX post's Mori Seiki NMV sample).
    let (code, out, err) = linkage(
        "g28.nc",
        "G91 G28 Z0.0\nG28 X0.0 Y0.0 B0.0\nG90 G0 X50 Y0 Z20\nG1 X60 Y10 Z10 B40 C60 F300\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(kinpost linkage 1/"), "{out}");
    // Programmed again, Z is known: the next G1 is divided as usual.
    let (code, out, err) = linkage(
        "g53z.nc",
        "G90 G21 G94\nG0 X50 Y0 Z20 B30 C40\nG53 G0 Z0\nG0 Z20\nG1 X60 Y10 Z10 B40 C60 F300\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("(kinpost linkage 1/"), "{out}");
}

#[test]
fn tool_centre_point_control_past_the_start_is_refused() {
    // A program taken for one in machine axes (nothing in its first 64 KiB
    // asks for TCP; before session 35, 4 KiB) that switches G43.4 on
    // later, as an NX post's Mori Seiki NMV sample does at line 350: from
    // there X Y Z are tool-tip positions. Before, linkage divided those
    // blocks as machine axes and analyze --nonlinear measured them, exit 0.
    let tcp = "G43.4 H1\nG1 X10 Y0 Z5 B30 C10\nG1 X20 Y10 Z5 B40 C60\nG49\nM30\n";
    let approach = |lines: usize| {
        let mut program = String::from("G90 G21 G94\n");
        for i in 0..lines {
            program.push_str(&format!("G1 X{} Y0 Z5 B0 C0 F500\n", i % 7));
        }
        program.push_str(tcp);
        program
    };
    // Within 64 KiB the TCP code is seen: the program is read as poses,
    // its moves in machine axes before TCP followed.
    let near = approach(300);
    assert!(near.len() > 4096);
    assert_eq!(linkage("near.nc", &near).0, 0);
    assert_eq!(nonlinear("near.nc", &near).0, 0);
    let program = approach(3000);
    assert!(program.len() > 65536);
    let line = program.lines().position(|l| l == "G43.4 H1").unwrap() + 1;
    for (code, err) in [
        {
            let (c, _, e) = linkage("tcp.nc", &program);
            (c, e)
        },
        {
            let (c, _, e) = nonlinear("tcp.nc", &program);
            (c, e)
        },
    ] {
        assert_eq!(code, 1, "{err}");
        assert!(
            err.contains(&format!("tcp.nc:{line}:1:")) && err.contains("tool centre point"),
            "{err}"
        );
    }
}

/// Minutes of the `G1` moves of `text` in G94 as LinuxCNC and Fanuc time
/// them on X Y Z B C: F is mm/min along the linear axes' path, or, where
/// only rotaries move, degrees a minute of the largest turn.
fn g94_minutes(text: &str) -> f64 {
    let (mut pos, mut feed, mut rapid, mut minutes) = ([0.0f64; 5], 0.0, true, 0.0);
    for line in text.lines() {
        let l = kinpost::gcode::parse_line(line.as_bytes(), 1);
        let mut next = pos;
        for w in l.words() {
            match (w.address.as_str(), w.value) {
                ("G", 0.0) => rapid = true,
                ("G", 1.0) => rapid = false,
                ("F", v) => feed = v,
                (a, v) => {
                    if let Some(k) = ["X", "Y", "Z", "B", "C"].iter().position(|x| *x == a) {
                        next[k] = v;
                    }
                }
            }
        }
        let lin = (0..3)
            .map(|k| (next[k] - pos[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        let rot = (3..5).map(|k| (next[k] - pos[k]).abs()).fold(0.0, f64::max);
        if !rapid && (lin > 0.0 || rot > 0.0) {
            minutes += if lin > 1e-12 { lin } else { rot } / feed;
        }
        pos = next;
    }
    minutes
}

/// Found in session 17 (a real five-axis program, `G1 A30 F100`): a block
/// that turns a rotary alone runs at F degrees a minute. Divided to keep
/// the tool on the programmed line, its segments also move linear axes,
/// where the same F is mm/min: the turn ran 11 % faster, and the report
/// said so in its cycle time only. Now each segment carries the feed that
/// keeps its share of the block's time, and the programmed feed is set
/// again after the block: the program runs as long as before, timed here
/// as a controller times it.
#[test]
fn a_divided_rotary_turn_keeps_its_time_and_the_feed_after_it() {
    let program = "G21 G90 G94\nG0 X0 Y15 Z50 B0 C0\nG1 C40 F100\nG1 C50\nG1 X5 F300\nM30\n";
    let (code, out, err) = linkage("turn.ngc", program);
    assert_eq!(code, 0, "{err}");
    assert!(out.lines().count() > 10, "the turn is divided: {out}");
    let (before, after) = (g94_minutes(program), g94_minutes(&out));
    assert!(
        (before - (0.4 + 0.1 + 5.0 / 300.0)).abs() < 1e-12,
        "{before}"
    );
    // The feeds are worked out from the words as written; the feed's own
    // four decimals remain. Before, the turns took 11 % less.
    assert!(
        (after - before).abs() < 1e-3 * before,
        "{after} min against {before} min:\n{out}"
    );
    // After each of the two divided turns.
    assert_eq!(
        out.matches("\nF100.0000 (kinpost linkage: the programmed feed again)\n")
            .count(),
        2,
        "{out}"
    );
    assert!(err.contains("(+0.0 %)"), "{err}");
}
