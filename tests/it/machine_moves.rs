//! Moves in machine coordinates between poses: a program leaves pose mode
//! (`G49`), moves the machine (`G91 G1 Z5`) and comes back (`G43.5`) with
//! a pose that gives only X. `post` follows the move; `compensate` must do
//! the same wherever its chunks end, `linkage` must divide the next
//! segment from where the move left the machine, and `analyze` and
//! `simulate` must read it as `post` does (`docs/robustness.md`).

use crate::cl_support::kinpost;
use crate::util::repo_file;

/// The standard output of `kinpost args`, which must succeed.
fn kinpost_ok(args: &[&str]) -> String {
    let out = kinpost(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// `pad` comment lines, `count` poses of the zhao2022-xzbc fixture, then a
/// move in machine coordinates (`G49`, `G91 G1 Z5`) and back to pose mode,
/// where the first pose gives X alone (and `first_yz`, say ` Y0 Z-5`).
fn machine_move_program(pad: usize, count: usize, first_yz: &str) -> String {
    let fixture =
        std::fs::read_to_string(repo_file("fixtures/programs/zhao2022-xzbc.ngc")).unwrap();
    let poses: Vec<&str> = fixture
        .lines()
        .filter(|l| l.starts_with("G1 X"))
        .map(|l| l.trim_end_matches(" F200.0"))
        .take(150)
        .collect();
    let first = format!("G1 X30{first_yz} I0 J0 K1 F200");
    let mut lines = vec!["(pad)"; pad];
    lines.extend(["G21 G90 G94", "G43.5 H1"]);
    lines.extend(poses.iter().cycle().take(count));
    lines.extend([
        "G49",
        "G91 G1 Z5. F100",
        "G90",
        "G43.5 H1",
        &first,
        "G1 X31 I0 J0 K1",
        "G49",
        "M30",
    ]);
    lines.join("\n") + "\n"
}

/// `analyze` and `simulate` read the poses without converting them and did
/// not follow a move in machine coordinates: a pose after one that gives
/// only X took Y and Z from the pose before the move (5 mm below where
/// `post` puts it), exit 0. They now read G-code with `post`'s own reader:
/// the pose is where `post` puts it, the move is a block of its own
/// (`--nonlinear` measures it, and the segment after it from where it left
/// the machine), and `simulate` runs through it.
#[test]
fn analyze_and_simulate_follow_a_machine_move_as_post_does() {
    let dir = tempfile::tempdir().unwrap();
    let partial = dir.path().join("partial.nc");
    std::fs::write(&partial, machine_move_program(0, 300, "")).unwrap();
    let p = partial.to_str().unwrap();
    let table = repo_file("fixtures/errors/zhao2022-xzbc.csv");
    // post's axes of the pose after the move (line 307): X Z B C.
    let posted = kinpost_ok(&["post", "-q", "-m", "zhao2022-xzbc", "--decimals", "6", p]);
    let line307 = posted.lines().nth(306).unwrap();
    let want: Vec<f64> = ["X", "Z", "B", "C"]
        .iter()
        .map(|a| {
            line307
                .split(' ')
                .find_map(|w| w.strip_prefix(a))
                .unwrap()
                .parse()
                .unwrap()
        })
        .collect();
    assert!(want[1] > 15.0, "{line307}");
    let analysed: serde_json::Value = serde_json::from_str(&kinpost_ok(&[
        "analyze",
        "-m",
        "zhao2022-xzbc",
        "-e",
        &table,
        "--json",
        p,
    ]))
    .unwrap();
    let block = analysed["blocks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|b| b["line"] == 307)
        .expect("the pose after the move is analysed");
    for (k, w) in want.iter().enumerate() {
        let got = block["axes"][k].as_f64().unwrap();
        assert!((got - w).abs() < 1e-5, "axis {k}: {got} vs post's {w}");
    }
    let nonlinear: serde_json::Value = serde_json::from_str(&kinpost_ok(&[
        "analyze",
        "-m",
        "zhao2022-xzbc",
        "--nonlinear",
        "--json",
        p,
    ]))
    .unwrap();
    let lines: Vec<u64> = nonlinear["nonlinear"]["blocks"]
        .as_array()
        .expect("nonlinear blocks")
        .iter()
        .map(|b| b["line"].as_u64().unwrap())
        .collect();
    // The retract (line 304) and the pose after it are measured.
    assert!(lines.contains(&304) && lines.contains(&307), "{lines:?}");
    let sim = dir.path().join("sim.csv");
    kinpost_ok(&[
        "simulate",
        "-m",
        "zhao2022-xzbc",
        "--program",
        p,
        "-o",
        sim.to_str().unwrap(),
    ]);
}

/// A block in machine coordinates after the poses (`G49`, then `G91 G1
/// Z5`) moves on from the machine's position at the last pose, and a pose
/// after it that gives only X continues from the tip there. Under
/// `compensate` the first pass of a chunk runs before the chunk before it
/// is written: the position followed was that of the last pose *written*
/// (none in the first chunk, the chunk before's otherwise), so the pose
/// went to Z5 instead of Z17.5 (exit 0). Now it is that of the last pose
/// begun, wherever the chunks end; `post` (no errors) is the independent
/// reference, within the compensation (micrometres).
#[test]
fn a_machine_move_after_the_poses_continues_from_the_last_pose() {
    // The last pose before the machine move in the first chunk, at the end
    // of the first chunk (512 lines) and in the middle of the second.
    let dir = tempfile::tempdir().unwrap();
    let mut results = Vec::new();
    for (pad, count) in [(0, 300), (0, 508), (100, 508)] {
        let prog = dir.path().join(format!("p{pad}-{count}.nc"));
        std::fs::write(&prog, machine_move_program(pad, count, "")).unwrap();
        let prog = prog.to_str().unwrap();
        let run = |args: &[&str]| {
            let text = kinpost_ok(&[args, &[prog]].concat());
            // The two poses after the machine move: X Z B C.
            text.lines()
                .rev()
                .skip(2)
                .take(2)
                .map(|l| {
                    ["X", "Z", "B", "C"].map(|a| {
                        l.split(' ')
                            .find_map(|w| w.strip_prefix(a))
                            .unwrap_or_else(|| panic!("{a} in {l}"))
                            .parse::<f64>()
                            .unwrap()
                    })
                })
                .collect::<Vec<_>>()
        };
        let table = repo_file("fixtures/errors/zhao2022-xzbc.csv");
        let compensated = run(&[
            "compensate",
            "-q",
            "--machine",
            "zhao2022-xzbc",
            "--errors",
            &table,
        ]);
        let nominal = run(&["post", "-q", "--machine", "zhao2022-xzbc"]);
        for (c, n) in compensated.iter().zip(&nominal) {
            for k in 0..4 {
                assert!(
                    (c[k] - n[k]).abs() < 0.01,
                    "pad {pad}, {count} poses: compensate {c:?}, post {n:?}"
                );
            }
        }
        // The retract from the last pose: Z 5 mm above it, not at 5.
        assert!(nominal[1][1] > 15.0, "{nominal:?}");
        results.push(compensated);
    }
    assert_eq!(
        results[1], results[2],
        "the chunk boundaries change nothing"
    );
}

/// `linkage` divided the first pose block after the move from the last
/// pose *before* the move (Z 11.57, where the machine was before the 5 mm
/// retract): its first inserted point took the machine back down, a path
/// the program never asked for, exit 0. Now the segment starts where the
/// move left the machine; after `G28`, where it starts is not known and a
/// block that must be divided is refused.
#[test]
fn linkage_divides_from_where_a_machine_move_left_the_machine() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("p.nc");
    let text = machine_move_program(0, 40, " Y0 Z-5");
    std::fs::write(&prog, &text).unwrap();
    let linked = kinpost_ok(&["linkage", "-m", "zhao2022-xzbc", prog.to_str().unwrap()]);
    let z = |l: &str| -> f64 {
        l.split(' ')
            .find_map(|w| w.strip_prefix('Z'))
            .unwrap()
            .parse()
            .unwrap()
    };
    let lines: Vec<&str> = linked.lines().collect();
    let retract = lines
        .iter()
        .position(|l| l.starts_with("G91 G1 Z5"))
        .unwrap();
    // The last pose before the retract, and the first block after it.
    let before = lines[..retract]
        .iter()
        .rev()
        .find(|l| l.starts_with("G1 X"))
        .unwrap();
    let first = lines[retract..]
        .iter()
        .find(|l| l.starts_with("G1 X"))
        .unwrap();
    assert!(first.contains("(kinpost linkage 1/"), "{first}");
    let (z_before, z_first) = (z(before), z(first));
    // The target is below the pose before: the first inserted point lies
    // between the retracted Z (5 mm up) and the target, above the pose
    // before.
    assert!(
        z_first > z_before + 2.0 && z_first < z_before + 5.0,
        "{before} → retract → {first}"
    );
    let homed = dir.path().join("homed.nc");
    std::fs::write(&homed, text.replace("G91 G1 Z5. F100", "G28 Z0")).unwrap();
    let out = kinpost(&["linkage", "-m", "zhao2022-xzbc", homed.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("homed.nc:47:") && err.contains("not known"),
        "{err}"
    );
}

/// `linkage`, `simulate` and `analyze --nonlinear` on xyzac-trt each
/// refuse `prog` (exit 1, no output), their message holding every one of
/// `said`.
fn refused_where_its_motion_is_read(prog: &std::path::Path, said: &[&str]) {
    let p = prog.to_str().unwrap();
    let out = prog.with_extension("out");
    let o = out.to_str().unwrap();
    for args in [
        vec!["linkage", "-m", "xyzac-trt", p, "-o", o],
        vec!["simulate", "-m", "xyzac-trt", "-p", p, "-o", o],
        vec!["analyze", "-m", "xyzac-trt", "--nonlinear", p],
    ] {
        let r = kinpost(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{args:?}: {err}");
        assert!(said.iter().all(|s| err.contains(s)), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote an output");
    }
}

/// Found in session 16: a block in machine axes with an axis word twice
/// (`G1 X1 X2 A5`) was read with its last word by `linkage`, `simulate` and
/// `analyze --nonlinear`; `linkage` even rewrote it as a valid block
/// (`X2.0000`), exit 0. LinuxCNC and Fanuc refuse such a block, and which
/// word a controller would take is not for kinpost to guess: the commands
/// that read the block's motion refuse it at the second word. `post`, which
/// converts nothing there, passes the line through as it came.
#[test]
fn a_machine_axis_block_with_an_axis_twice_is_refused_where_its_motion_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("dup.ngc");
    let text = "G90 G21\nG0 X0 Y0 Z0 A0 C0\nG1 X1 X2 A5 F100\n";
    std::fs::write(&prog, text).unwrap();
    refused_where_its_motion_is_read(&prog, &["dup.ngc:3:7:", "X is given twice", "X1 and X2"]);
    let p = prog.to_str().unwrap();
    let r = kinpost(&["post", "-m", "xyzac-trt", p]);
    assert!(r.status.success());
    assert_eq!(String::from_utf8_lossy(&r.stdout), text);
}

/// Found in session 17 (third hunt for real input): `simulate` and
/// `analyze --nonlinear` read a block in machine axes whose motion words
/// hold a parameter or an expression (`G0 X10 Y#1 Z50`, LinuxCNC and Fanuc
/// macro programs) as if those words were not there: the text from `Y#1`
/// on is one unreadable item, so Y and Z (and a feed `F#3`) were dropped,
/// exit 0; the recording put Y at 0 where the program says 5. A block with
/// an axis word the machine does not have (`B45` on an A/C machine: a
/// program for another machine) lost that axis the same way. `post`
/// refused the first in pose mode already, and `linkage` the second where
/// it had to divide the block. Now the three commands that read a block's
/// motion refuse both at the word.
#[test]
fn a_move_with_an_expression_or_an_axis_the_machine_lacks_is_refused_where_its_motion_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "param.ngc",
            "#1=5.\nG21 G90 G94\nG0 X0 Y0 Z50 A0 C0\nG0 X10 Y#1 Z50\nG1 X20 Y20 F600\nM30\n",
            "param.ngc:4:8:",
            "`Y#1 Z50`: a parameter, an expression or a malformed number",
        ),
        (
            "feed.ngc",
            "G21 G90 G94\nG0 X0 Y0 Z50 A0 C0\nG1 X10 F#3\nM30\n",
            "feed.ngc:3:8:",
            "`F#3`",
        ),
        (
            "b.ngc",
            "G21 G90 G94\nG1 X0 Y0 Z10 A0 C0 F1000\nG1 X10 Y0 Z10 B45 C90\nM30\n",
            "b.ngc:3:15:",
            "axis word B in a move, and machine xyzac-trt has no B axis (its axes: X Y Z A C)",
        ),
    ];
    for (name, text, at, what) in cases {
        let prog = dir.path().join(name);
        std::fs::write(&prog, text).unwrap();
        refused_where_its_motion_is_read(&prog, &[at, what]);
    }
    // A parameter set, or a G10 data block with one, moves nothing.
    let prog = dir.path().join("data.ngc");
    std::fs::write(
        &prog,
        "#1=5.\nG21 G90 G94\nG10 L2 P1 X#1\nG0 X0 Y0 Z50 A0 C0\nG1 X10 F600\nM30\n",
    )
    .unwrap();
    analyze_succeeds("xyzac-trt", &prog);
}

/// Found in session 18 (fourth hunt for real input): a program in machine
/// axes that turns a rotary beyond the machine's limits (`A150` on
/// xyzac-trt, whose A tilts −30…110°; a Fanuc four-axis program wrapping
/// A through ±180°) was followed there by `linkage` (1,422 inserted
/// blocks running A to 150°), `simulate` and `analyze --nonlinear`, exit 0
/// and nothing said. A rotary's program coordinates are its machine
/// coordinates, so the commands that follow the motion refuse the word; an
/// incremental turn and `G53` count too. A modulo axis (xyzbc-trt's C)
/// has no limits, and a linear axis's program coordinates are shifted by
/// a work offset kinpost does not know: neither is checked.
#[test]
fn a_rotary_moved_beyond_its_limits_is_refused_where_its_motion_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "abs.ngc",
            "G90 G21\nG1 X0 Y0 Z50 A0 C0 F500\nG1 X10 Y5 Z40 A150 C30\n",
            "abs.ngc:3:15:",
            "A would move to 150.0000°",
        ),
        (
            "inc.ngc",
            "G90 G21\nG1 X0 Y0 Z50 A100 C0 F500\nG91 G1 A-20\nG1 A30\n",
            "inc.ngc:4:4:",
            "A would move to 110.0000°",
        ),
        (
            "g53.ngc",
            "G90 G21\nG1 X0 Y0 Z50 A0 C0 F500\nG53 A-45\nG1 X5\n",
            "g53.ngc:3:5:",
            "A would move to -45.0000°",
        ),
    ];
    for (name, text, at, what) in cases {
        let prog = dir.path().join(name);
        std::fs::write(&prog, text).unwrap();
        if name == "inc.ngc" {
            // 110° is the limit itself: within.
            analyze_succeeds("xyzac-trt", &prog);
            std::fs::write(&prog, format!("{text}G1 A0.001\n")).unwrap();
            refused_where_its_motion_is_read(&prog, &["inc.ngc:5:4:", "A would move to 110.0010°"]);
            continue;
        }
        refused_where_its_motion_is_read(&prog, &[at, what, "outside its limits -30 … 110°"]);
    }
    // C of xyzbc-trt turns without limits; X beyond its travel in program
    // coordinates is left to the controller (a work offset shifts it).
    let prog = dir.path().join("ok.ngc");
    std::fs::write(&prog, "G90 G21\nG1 X0 Y0 Z50 B0 C0 F500\nG1 X900 C720\n").unwrap();
    analyze_succeeds("xyzbc-trt", &prog);
}

/// Found in session 18: codes and transformations that make the axis
/// words move the machine otherwise than they say were ignored (an unknown
/// G code fell through): Fanuc polar and cylindrical interpolation
/// (`G12.1`, `G7.1 C57.3`, which was even followed as a turn of C to
/// 57.3°), a probing move (`G31 X100`, `G38.2`), Haas's circular pocket
/// (`G12`) and `G150`, LinuxCNC's diameter mode (`G7`), Sinumerik
/// `TRANSMIT` and `TRACYL(40)`, stored stroke limits (`G22 X100 Y100`, its
/// X Y followed as a move), and subprogram calls (`M98`, Haas `M97`,
/// `o100 call`), whose moves stand elsewhere: `analyze`, `simulate` and
/// `linkage` followed the words as moves, exit 0; `post` passed them
/// through in pose mode, where the controller then reads them in machine
/// axes. Now the commands that follow motion refuse them at the code, and
/// `post` refuses them in pose mode; outside pose mode `post` still passes
/// them through, and codes that leave the axes alone (`G61`, `G64 P0.01`,
/// `G187`, `G96`, `G98`) pass everywhere.
#[test]
fn codes_whose_motion_kinpost_does_not_follow_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (code, said) in [
        ("G12.1", "G12.1 is polar coordinate interpolation"),
        ("G7.1 C57.3", "G7.1 is cylindrical interpolation"),
        ("G31 X100", "G31 is a probing or skip move"),
        ("G38.2 Z-50", "G38.2 is a probing or skip move"),
        ("G12 I10 K20 Q5 Z-5", "G12 is circular pocket milling"),
        ("G7", "G7 is diameter mode"),
        ("G22 X100 Y100", "G22 is stored stroke limits"),
        ("G5.4", "G5.4 is a code kinpost does not know"),
        ("TRANSMIT", "TRANSMIT is a Sinumerik transformation"),
        ("TRACYL(40)", "TRACYL is a Sinumerik transformation"),
        ("M97 P100", "a subprogram or macro call (M97)"),
        ("o100 call", "a subprogram or macro call (o100 call)"),
    ] {
        let prog = dir.path().join("m.ngc");
        let text =
            format!("G21 G90 G94\nG0 X50 Y0 Z10 A0 C0\n{code}\nG1 X20 Y5 Z5 C10 F100\nM30\n");
        std::fs::write(&prog, text).unwrap();
        refused_where_its_motion_is_read(&prog, &["m.ngc:3:1:", said]);
        // Outside pose mode `post` passes the line through.
        let p = prog.to_str().unwrap();
        let r = kinpost(&["post", "-m", "xyzac-trt", p]);
        assert!(
            r.status.success(),
            "{code}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        // In pose mode it refuses it.
        let pose = dir.path().join("p.ngc");
        let text = format!(
            "G21 G90 G94\nG43.4 H1\nG1 X50 Y0 Z10 I0 J0 K1 F100\n{code}\nG1 X20 Y5 Z5 I0 J0 K1\nG49\nM30\n"
        );
        std::fs::write(&pose, text).unwrap();
        let r = kinpost(&["post", "-m", "xyzac-trt", pose.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{code}: {err}");
        assert!(err.contains("p.ngc:4:1:"), "{code}: {err}");
    }
    for code in ["G61", "G64 P0.01", "G187 P1", "G96 S200", "G98", "G17"] {
        let prog = dir.path().join("ok.ngc");
        let text =
            format!("G21 G90 G94\nG0 X50 Y0 Z10 A0 C0\n{code}\nG1 X20 Y5 Z5 C10 F100\nM30\n");
        std::fs::write(&prog, text).unwrap();
        analyze_succeeds("xyzac-trt", &prog);
    }
}

/// Found by metamorphic tests in session 18: a `G28` or `G53` between two
/// poses (in pose mode) left the next pose starting from the pose before:
/// `post --feed inverse-time` wrote that block's `G93 F` from the wrong
/// path, `linkage` divided it from there, `analyze --nonlinear` measured
/// it and `simulate` ran it without a word — while on the converted
/// program each of them says the start is not known. Now the pose after
/// starts afresh: no `G93` for it, `linkage` refuses it, `analyze` leaves
/// it out, `simulate` warns.
#[test]
fn a_pose_after_g28_or_g53_in_pose_mode_starts_where_the_program_does_not_say() {
    let dir = tempfile::tempdir().unwrap();
    for home in ["G28", "G53 G0 Z0"] {
        let prog = dir.path().join("h.ngc");
        let text = format!(
            "G21 G90 G94\nG43.4 H1\nG1 X10 Y0 Z20 I0 J0 K1 F300\n{home}\nG1 X30 Y10 Z20 I0 J0.4 K0.9165151\nG1 X40 Y15 Z20 I0 J0.3 K0.9539392\nG49\nM30\n"
        );
        std::fs::write(&prog, text).unwrap();
        let p = prog.to_str().unwrap();
        let r = kinpost(&["post", "-m", "xyzac-trt", "--feed", "inverse-time", p]);
        assert!(r.status.success());
        let out = String::from_utf8_lossy(&r.stdout);
        let line5 = out.lines().nth(4).unwrap();
        assert!(
            line5.starts_with("G1 X") && !line5.contains("G93"),
            "{home}: {out}"
        );
        assert!(out.lines().nth(5).unwrap().contains("G93"), "{home}: {out}");
        let r = kinpost(&["linkage", "-m", "xyzac-trt", p]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{home}: {err}");
        assert!(
            err.contains("h.ngc:5:1: where this G1 block starts is not known"),
            "{home}: {err}"
        );
        let r = kinpost(&["analyze", "-m", "xyzac-trt", "--nonlinear", p]);
        let out = String::from_utf8_lossy(&r.stdout);
        assert!(
            out.contains("at line 6") && out.contains("1 blocks"),
            "{home}: {out}"
        );
        let r = kinpost(&["simulate", "-m", "xyzac-trt", "--noise", "0", "-p", p]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains("1 block(s) start where the program does not say"),
            "{home}: {err}"
        );
    }
}

/// The same codes in the machine-axis part of a pose program (before TCP
/// is switched on), which `analyze`, `simulate` and `linkage` read with
/// `post`'s reader: a Mazak `G68.5 X0 Y0 Z0 I0 J1 K0` macro was read as a
/// pose program with no pose in it ("no blocks", exit 0). Heidenhain's
/// `TOOL CALL` is a tool change, not a subprogram call.
#[test]
fn codes_not_followed_before_pose_mode_are_refused_by_the_commands_that_follow_motion() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("pp.ngc");
    let text = "G21 G90 G94\nG0 X50 Y0 Z10 A0 C0\nG12.1\nG1 X20 C10 F100\nG13.1\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1\nG49\nM30\n";
    std::fs::write(&prog, text).unwrap();
    refused_where_its_motion_is_read(
        &prog,
        &["pp.ngc:3:1:", "G12.1 is polar coordinate interpolation"],
    );
    let r = kinpost(&["post", "-m", "xyzac-trt", prog.to_str().unwrap()]);
    assert!(r.status.success());
    let frame = dir.path().join("g685.ngc");
    std::fs::write(
        &frame,
        "G21 G90\nG0 X0 Y0 Z50 A0 C0\nG68.5 X0. Y0. Z0. I0 J1 K0\nG1 X10 F100\nM30\n",
    )
    .unwrap();
    refused_where_its_motion_is_read(
        &frame,
        &["g685.ngc:3:1:", "G68.5 is an inclined work plane"],
    );
    let tool = dir.path().join("tool.ngc");
    std::fs::write(
        &tool,
        "G21 G90\nG0 X0 Y0 Z50 A0 C0\nTOOL CALL 1 Z S3000\nG1 X10 F100\nM30\n",
    )
    .unwrap();
    analyze_succeeds("xyzac-trt", &tool);
}

/// `analyze --nonlinear` on `machine` reads `prog` and exits 0.
fn analyze_succeeds(machine: &str, prog: &std::path::Path) {
    let p = prog.to_str().unwrap();
    let r = kinpost(&["analyze", "-m", machine, "--nonlinear", p]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}
