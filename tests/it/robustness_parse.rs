//! Broken programs get a clear refusal at file:line:col (issue 13): a word
//! given twice in a pose block, CR-only line endings, NUL bytes, an
//! unclosed comment, a file cut inside a pose block. Each passed with exit
//! 0 or gave a misleading message before; `docs/robustness.md` lists them.

use std::process::Command;

use crate::util::BIN;

/// Runs `kinpost post` on `bytes` written to `name`: (exit code, stdout, stderr).
fn post(name: &str, bytes: &[u8]) -> (i32, Vec<u8>, String) {
    crate::util::post_file("zhao2022-xzbc", name, bytes)
}

#[test]
fn a_word_given_twice_in_a_pose_block_is_refused_at_the_second() {
    let (code, _, err) = post("dup.ngc", b"G43.4 H1\nG1 X1 Y2 X5 Z0 I0 J0 K1 F100\nM30\n");
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("dup.ngc:2:10:") && err.contains("word X is given twice"),
        "{err}"
    );
    let (code, _, err) = post(
        "ijk.ngc",
        b"G43.4 H1\nG1 X1 Y2 Z0 I0 J0 K1 A3=0.5 F100\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("same tool-axis component (I and A3)"), "{err}");
    // Outside pose mode kinpost converts nothing: the block passes through.
    let prog = b"G1 X1 X5 Y2\nM30\n";
    let (code, out, err) = post("plain.ngc", prog);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, prog);
}

#[test]
fn cr_only_line_endings_are_named() {
    let (code, _, err) = post(
        "mac.ngc",
        b"O1000\rG43.4 H1\rG1 X1 Y2 Z0 I0 J0 K1 F100\rM30\r",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("mac.ngc:1:") && err.contains("CR-only"),
        "{err}"
    );
    assert!(err.contains("O1000\\rG43.4"), "the CR is shown: {err}");
}

#[test]
fn a_nul_byte_is_refused_and_shown() {
    let (code, _, err) = post("nul.ngc", b"G43.4 H1\nG1 X1 Y2\0 Z0 I0 J0 K1 F100\nM30\n");
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("nul.ngc:2:9:") && err.contains("NUL"), "{err}");
    assert!(err.contains("Y2\\0 Z0"), "{err}");
    let (code, _, err) = post("zeros.ngc", &[0u8; 300]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("zeros.ngc:1:1:") && err.chars().count() < 400,
        "{err}"
    );
}

#[test]
fn an_unclosed_comment_in_a_pose_block_is_quoted() {
    let (code, _, err) = post("unc.ngc", b"G43.4 H1\nG1 X1 Y2 Z3 (abc I0 J0 K1\nM30\n");
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("unc.ngc:2:13: unclosed comment `(abc I0 J0 K1`"),
        "{err}"
    );
}

#[test]
fn a_file_cut_inside_a_pose_block_is_refused() {
    let full = "G43.4 H1\nG1 X1 Y2 Z3 I0 J0 K1 F100\nG1 X1 Y2 Z3.125 I0 J0 K1\nM30\n";
    // Every cut inside the last pose block's digits or words.
    let start = full.find("G1 X1 Y2 Z3.125").unwrap();
    let end = full.find("\nM30").unwrap();
    for cut in start + 1..end {
        let (code, _, err) = post("cut.ngc", &full.as_bytes()[..cut]);
        assert_eq!(code, 1, "cut at {cut}: {err}");
        assert!(
            err.contains("cut.ngc:3:") && err.contains("truncated"),
            "{err}"
        );
    }
    // Cut after the pose blocks but still in pose mode (`M3` of `M30`):
    // refused too.
    let (code, _, err) = post("cut.ngc", &full.as_bytes()[..full.len() - 2]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("cut.ngc:4:") && err.contains("truncated"),
        "{err}"
    );
    // A plain program cut short is passed on unchanged, with a warning.
    let plain = b"G0 X1 Y2\nG1 X5 F100\nM3";
    let (code, out, err) = post("plain.ngc", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
    assert!(
        err.contains("plain.ngc:3:1") && err.contains("truncated"),
        "{err}"
    );
    // A program whose last line `M30` has no line end is whole.
    let (code, _, err) = post("end.ngc", &full.as_bytes()[..full.len() - 1]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("truncated"), "{err}");
    // The whole program: quiet.
    let (code, _, err) = post("cut.ngc", full.as_bytes());
    assert_eq!(code, 0);
    assert!(!err.contains("truncated"), "{err}");
}

/// Sinumerik circles (`CIP` through an intermediate point, `CT`
/// tangential) and splines under TRAORI: before, the block's end point was
/// converted and `CIP` kept, so the controller drew a circle in machine
/// axes through an intermediate point given in the workpiece frame (exit
/// 0). They are modal like G2: the next block without a motion word is
/// refused too. Outside pose mode they pass through unchanged.
#[test]
fn sinumerik_circles_and_splines_in_pose_mode_are_refused() {
    let start = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, rest, col_line) in [
        (
            "cip.mpf",
            "CIP X20 Y10 Z5 I1=15 J1=5 K1=5\nTRAFOOF\nM30\n",
            "cip.mpf:3:1:",
        ),
        ("ct.mpf", "CT X30 Y0 Z5\nTRAFOOF\nM30\n", "ct.mpf:3:1:"),
        (
            "spline.mpf",
            "BSPLINE\nX20 Y10 Z5\nTRAFOOF\nM30\n",
            "spline.mpf:4:1:",
        ),
    ] {
        let (code, out, err) = post(name, format!("{start}{rest}").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(col_line), "{name}: {err}");
        assert!(out.is_empty() || !String::from_utf8_lossy(&out).contains("CIP X20.0000"));
    }
    // Modal: a circle mode set before TRAORI still holds for a pose block
    // without a motion word.
    let (code, _, err) = post(
        "modal.mpf",
        b"G1 X0 Y0 Z5 F500\nCIP X20 Y10 Z5 I1=15 J1=5 K1=5\nTRAORI\nX30 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("modal.mpf:4:") && err.contains("circular move (G2/G3, CIP, CT)"),
        "{err}"
    );
    let plain = b"G1 X10 Y0 Z5 F500\nCIP X20 Y10 Z5 I1=15 J1=5 K1=5\nCT X30 Y0 Z5\nM30\n";
    let (code, out, err) = post("plain.mpf", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
}

/// Orientation given another way than by a tool vector in pose mode:
/// Euler angles, lead and tilt, surface normals, and rotary axis
/// positions the machine cannot take. Before: the previous tool vector was
/// kept and a second set of rotary words appended (`A0.0000 C0.0000 A30
/// C10`), exit 0; a block turning A alone passed through, so the
/// controller turned A without holding the tip. (Since session 34 rotary
/// positions under G43.4 / G234 / TRAORI are converted:
/// `rotary_orientation.rs`; this machine, zhao2022-xzbc, has no A, and its
/// tip decides C.)
#[test]
fn an_orientation_not_given_as_a_tool_vector_is_refused() {
    let start = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, block, at, word) in [
        (
            "axes.mpf",
            "G1 X20 Y0 Z5 A30 C10",
            "axes.mpf:3:14:",
            "no rotary axis A",
        ),
        ("alone.mpf", "G1 A30", "alone.mpf:3:4:", "no rotary axis A"),
        (
            "euler.mpf",
            "G1 X30 Y0 Z5 A2=10 B2=20 C2=0",
            "euler.mpf:3:14:",
            "`A2`",
        ),
        (
            "lead.mpf",
            "G1 X20 Y0 Z5 LEAD=10 TILT=5",
            "lead.mpf:3:14:",
            "`LEAD`",
        ),
        (
            "normal.mpf",
            "G1 X40 Y0 Z5 A3=0 B3=0 C3=1 A5=0 B5=0 C5=1",
            "normal.mpf:3:29:",
            "`A5`",
        ),
    ] {
        let (code, out, err) = post(name, format!("{start}{block}\nTRAFOOF\nM30\n").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(at) && err.contains(word), "{name}: {err}");
        assert!(!String::from_utf8_lossy(&out).contains("A30"), "{name}");
    }
    // Fanuc G43.4 with rotary positions that do not fit the tip: C10
    // turns the tip (20, 0, 5) off the plane of X and Z.
    let (code, _, err) = post(
        "fanuc.ngc",
        b"G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG1 X20 B30 C10\nG49\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("fanuc.ngc:3:4:") && err.contains("do not reach this pose"),
        "{err}"
    );
}

/// Cycle and subprogram calls in pose mode move the tool in a way kinpost
/// cannot see: refused at the call, naming it (before: `CYCLE800(…)` was
/// refused only because its name holds a `Y`, with "the word CYCLE has no
/// number"; `M98 P1000` and `MYSUB(1,2)` passed with exit 0). Outside pose
/// mode they pass through unchanged.
#[test]
fn calls_in_pose_mode_are_refused_by_name() {
    let pose = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, text, want) in [
        (
            "c800.mpf",
            format!(
                "{pose}CYCLE800(1,\"TABLE\",200000,57,0,0,0,0,0,0,0,0,0,-1,100,1)\nTRAFOOF\nM30\n"
            ),
            "c800.mpf:3:1: a cycle or subprogram call (`CYCLE800`)",
        ),
        (
            "sub.mpf",
            format!("{pose}MYSUB(1,2)\nTRAFOOF\nM30\n"),
            "sub.mpf:3:1: a cycle or subprogram call (`MYSUB`)",
        ),
        (
            "m98.ngc",
            "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nM98 P1000\nG49\nM30\n".to_string(),
            "m98.ngc:3:1: a subprogram or macro call (M98)",
        ),
        (
            "ocall.ngc",
            "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\no100 call [1]\nG49\nM30\n".to_string(),
            "ocall.ngc:3:1: a cycle or subprogram call (`o100 call`)",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    let plain = b"G1 X10 Y0 Z5 F500\nCYCLE800(1,\"TABLE\",200000,57,0,0,0,0,0,0,0,0,0,-1,100,1)\nM98 P1000\nM30\n";
    let (code, out, err) = post("plain.mpf", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
}

/// Offsets and homing in pose mode: the controller would apply them to
/// kinpost's machine axis words (before: `G52 X5`, `G92 X0` and `G55`
/// passed with exit 0, the tool then landing off by the offset; `G28` with
/// an intermediate point passed unconverted). Before pose mode they pass.
#[test]
fn offsets_and_homing_in_pose_mode_are_refused() {
    let pose = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    for (name, block, want) in [
        (
            "g52.ngc",
            "G52 X5",
            "g52.ngc:3:1: this block changes the coordinate system",
        ),
        (
            "g92.ngc",
            "G92 X0",
            "g92.ngc:3:1: this block changes the coordinate system",
        ),
        (
            "g10.ngc",
            "G10 L2 P1 X5",
            "g10.ngc:3:1: this block changes the coordinate system",
        ),
        (
            "g55.ngc",
            "G55",
            "g55.ngc:3:1: this block changes the work offset",
        ),
        (
            "g28.ngc",
            "G28 X0 Y0 Z50",
            "g28.ngc:3:1: this block moves home",
        ),
        // Haas's additional work offsets (found in a fourth hunt: passed
        // through with exit 0 before), and Fanuc's.
        (
            "g154.ngc",
            "G154 P7",
            "g154.ngc:3:1: this block changes the work offset",
        ),
        (
            "g541.ngc",
            "G54.1 P2",
            "g541.ngc:3:1: this block changes the work offset",
        ),
        // Haas G254, the dynamic work offset: a frame (exit 0 before).
        ("g254.ngc", "G254", "g254.ngc:3:1: a frame"),
    ] {
        let (code, _, err) = post(name, format!("{pose}{block}\nG49\nM30\n").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    let (code, _, err) = post(
        "g500.mpf",
        b"TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\nG500\nTRAFOOF\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("g500.mpf:3:1: this block changes the work offset"),
        "{err}"
    );
    // Pose mode does not start under Haas G254 until G255 (exit 0
    // before: the controller would move the converted axis words with
    // the rotaries).
    let (code, _, err) = post(
        "dwo.ngc",
        b"G254\nG234 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG49\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("dwo.ngc:2:1: pose mode starts while a frame"),
        "{err}"
    );
    let (code, _, err) = post(
        "dwo_off.ngc",
        b"G254\nG255\nG234 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG49\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    // Before TCP is on, and G53 / G4 inside it, pass. (A shift, `G92 X0`,
    // before TCP refuses its start since session 29: `thirteenth_hunt.rs`.)
    let ok = b"G54\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG4 P1\nG53 G0 Z0\nG49\nG28\nM30\n";
    let (code, _, err) = post("ok.ngc", ok);
    assert_eq!(code, 0, "{err}");
}

/// `TRAORI(1)` — the call form of TRAORI some Sinumerik posts write —
/// was an unreadable call: pose mode was started by the first tool vector,
/// the poses converted to machine axes, and `TRAORI(1)` left in the output,
/// so the controller applied its own transformation to kinpost's machine
/// axis words (exit 0). Now it is TCP on, written `TRAFOOF` like `TRAORI`;
/// followed by other text on its line it is refused.
#[test]
fn traori_written_as_a_call_is_converted_like_traori() {
    let (code, out, err) = post(
        "t1.mpf",
        b"N10 G90\nN20 TRAORI(1) ; on\nN30 G1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\nN40 TRAFOOF\nN50 M30\n",
    );
    assert_eq!(code, 0, "{err}");
    let out = String::from_utf8(out).unwrap();
    assert!(out.contains("N20 TRAFOOF ; on\n"), "{out}");
    assert!(!out.contains("TRAORI"), "{out}");
    assert!(!out.contains("A3="), "{out}");
    let (code, _, err) = post(
        "t2.mpf",
        b"N10 TRAORI(1) G17\nN20 G1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\nN30 M30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("t2.mpf:1:5: `TRAORI(1) G17` is followed by more text"),
        "{err}"
    );
}

/// Ways of placing the tool that are not X Y Z, found on programs kinpost
/// was not written for: in pose mode they passed with exit 0 — Fanuc `G16`
/// polar coordinates (`G1 X20. Y45.` converted as Cartesian), `G51`
/// scaling (its centre `X0 Y0 Z0` converted as a pose), Sinumerik's pole
/// `G111 X0 Y0` (converted as a pose) and `AP= RP=` moves (passed
/// unconverted), LinuxCNC's `@ ^` polar words (passed unconverted). Now
/// refused at the word; set before pose mode, `G16`, `G51` and a swivelling
/// `CYCLE800(…)` are frames that pose mode may not start under.
#[test]
fn polar_coordinates_scaling_and_swivels_are_refused() {
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    let sin = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, text, want) in [
        (
            "g16.ngc",
            format!("{fanuc}G16\nG1 X20. Y45.\nG15\nG49\nM30\n"),
            "g16.ngc:3:1: a frame (",
        ),
        (
            "g51.ngc",
            format!("{fanuc}G51 X0 Y0 Z0 P2000\nG1 X12\nG50\nG49\nM30\n"),
            "g51.ngc:3:1: a frame (",
        ),
        (
            "g111.mpf",
            format!("{sin}G111 X0 Y0\nG1 AP=45 RP=10\nTRAFOOF\nM30\n"),
            "g111.mpf:3:1: polar coordinates (Sinumerik",
        ),
        (
            "ap.mpf",
            format!("{sin}G1 AP=45 RP=10\nTRAFOOF\nM30\n"),
            "ap.mpf:3:4: polar coordinates (Sinumerik",
        ),
        (
            "at.ngc",
            format!("{fanuc}G1 @10 ^45\nG49\nM2\n"),
            "at.ngc:3:4: polar coordinates (`@10`",
        ),
        (
            "at840c.mpf",
            format!("{fanuc}G1 @136 R102 K5 K900\nG49\nM30\n"),
            "at840c.mpf:3:4: `@136` in pose mode: a Sinumerik 840/840C `@` instruction",
        ),
        (
            "g16before.ngc",
            format!("G16\n{fanuc}G49\nM30\n"),
            "g16before.ngc:2:1: pose mode starts while a frame",
        ),
        (
            "g51before.ngc",
            format!("G51 X0 Y0 Z0 P2000\n{fanuc}G49\nM30\n"),
            "g51before.ngc:2:1: pose mode starts while a frame",
        ),
        (
            "c800.mpf",
            format!("CYCLE800(1,\"TABLE\",0,57,0,0,0,30,0,0,0,0,0,1)\n{sin}TRAFOOF\nM30\n"),
            "c800.mpf:2:1: pose mode starts while a frame",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    // Cancelled before pose mode, they do not stop it.
    for (name, text) in [
        ("g15.ngc", format!("G16\nG15\n{fanuc}G49\nM30\n")),
        (
            "g50.ngc",
            format!("G51 X0 Y0 Z0 P2000\nG50\n{fanuc}G49\nM30\n"),
        ),
        (
            "c800r.mpf",
            format!(
                "CYCLE800(1,\"TABLE\",0,57,0,0,0,30,0,0,0,0,0,1)\nCYCLE800()\n{sin}TRAFOOF\nM30\n"
            ),
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 0, "{name}: {err}");
    }
}

/// Sinumerik orientation words besides the tool vector — `A6 B6 C6`,
/// `A7 B7 C7` (cone and plane interpolation), `XH YH ZH` (ORICURVE) — were
/// kept in a converted block next to the machine's rotary words (exit 0).
/// `MSG("…")` in pose mode, a message that moves nothing, was refused as a
/// subprogram call; it passes now.
#[test]
fn more_orientation_words_are_refused_and_messages_pass() {
    let start = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, block, at) in [
        ("a6.mpf", "G1 X12 A6=0 B6=0 C6=1", "a6.mpf:3:8: `A6`"),
        ("a7.mpf", "G1 X12 A7=0 B7=1 C7=0", "a7.mpf:3:8: `A7`"),
        ("xh.mpf", "G1 X12 XH=1 YH=2 ZH=3", "xh.mpf:3:8: `XH`"),
    ] {
        let (code, _, err) = post(name, format!("{start}{block}\nTRAFOOF\nM30\n").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(at), "{name}: {err}");
    }
    let (code, out, err) = post(
        "msg.mpf",
        format!("{start}MSG(\"FINISH X (Y)\")\nG1 X12\nTRAFOOF\nM30\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        String::from_utf8_lossy(&out).contains("\nMSG(\"FINISH X (Y)\")\n"),
        "{}",
        String::from_utf8_lossy(&out)
    );
}

/// Before pose mode kinpost follows the machine's axis words so that a pose
/// giving only some coordinates continues from where the machine is. It
/// also followed the words of blocks that are not moves: `G10 L2 P1 X100`
/// (offset data) put the next partial pose 100 mm off in X, and after
/// Fusion's retract `G53 G0 Z0` (machine coordinates) a pose without Z was
/// written at program Z0 (exit 0). Data blocks are not followed now; after
/// `G28`, `G30`, `G53` the position is unknown and the next pose must give
/// X, Y and Z. (`G92 X100`, the tool is at X100 now, was followed; since
/// session 29 pose mode may not start under such a shift.)
#[test]
fn non_modal_blocks_are_not_followed_as_moves() {
    let run = |name: &str, setup: &str, pose: &str| {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        let text = format!("G21 G90\nG0 X0 Y0 Z50 B0 C0\n{setup}\nG43.4 H1\n{pose}\nG49\nM30\n");
        std::fs::write(&p, text).unwrap();
        let out = Command::new(BIN)
            .args(["post", "--machine", "xyzbc-trt", "--decimals", "3"])
            .arg(&p)
            .output()
            .unwrap();
        (
            out.status.code().unwrap(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // `G10 L2 P1 X100` changes the active work offset (G54): the machine
    // stays, its program coordinates change, so since session 33 they are
    // not known (before, the pose continued from X0 of the old offset).
    let (code, _, err) = run("g10.ngc", "G10 L2 P1 X100", "G1 Z40 I0 J0 K1 F100");
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("the tool tip X is not known yet"), "{err}");
    let (code, out, err) = run("g10.ngc", "G10 L2 P1 X100", "G1 X0 Y0 Z40 I0 J0 K1 F100");
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G1 X0.000 Y0.000 Z40.000"), "{out}");
    // A shift (G52, G92) before TCP: since session 29 pose mode may not
    // start under it (`thirteenth_hunt.rs`); cancelled, the pose continues
    // from the machine's position as before.
    for shift in ["G52 X100", "G92 X100"] {
        let (code, _, err) = run("shift.ngc", shift, "G1 Z40 I0 J0 K1 F100");
        assert_eq!(code, 1, "{shift}: {err}");
        assert!(err.contains("shift of the program's coordinates"), "{err}");
    }
    let (code, out, err) = run("g52.ngc", "G52 X100\nG52 X0", "G1 Z40 I0 J0 K1 F100");
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("G1 X0.000 Y0.000 Z40.000"), "{out}");
    for setup in ["G53 G0 Z0", "G28 G91 Z0\nG90", "G30"] {
        let (code, _, err) = run("home.ngc", setup, "G1 X1 Y2 I0 J0 K1 F100");
        assert_eq!(code, 1, "{setup}: {err}");
        assert!(
            err.contains("the tool tip Z is not known yet"),
            "{setup}: {err}"
        );
        let (code, _, err) = run("full.ngc", setup, "G1 X1 Y2 Z3 I0 J0 K1 F100");
        assert_eq!(code, 0, "{setup}: {err}");
    }
}

/// A secondary linear axis (`U V W`: a quill along Z, a second slide) or
/// an `E` axis in a pose block: before, `G1 X12. W1.` under G43.4 came out
/// as `… B0.0000 C0.0000 W1.` (exit 0), the quill moving the tool 1 mm off
/// the converted pose. Now refused at the word in pose mode; outside it
/// they pass through unchanged, and `X1.5E-3` keeps its exponent message.
#[test]
fn secondary_linear_axes_in_pose_mode_are_refused() {
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    let sin = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    for (name, text, want) in [
        (
            "w.ngc",
            format!("{fanuc}G1 X12. W1.\nG49\nM30\n"),
            "w.ngc:3:9: `W` in pose mode: U/V/W: a secondary linear axis",
        ),
        (
            "u.ngc",
            format!("{fanuc}G1 U1.\nG49\nM30\n"),
            "u.ngc:3:4: `U` in pose mode: U/V/W: a secondary linear axis",
        ),
        (
            "v.mpf",
            format!("{sin}G1 X12 V2\nTRAFOOF\nM30\n"),
            "v.mpf:3:8: `V` in pose mode: U/V/W: a secondary linear axis",
        ),
        (
            "e.ngc",
            format!("{fanuc}G1 X13 E0.5\nG49\nM30\n"),
            "e.ngc:3:8: `E` in pose mode: E: an extruder or seventh axis",
        ),
        (
            "exp.ngc",
            format!("{fanuc}G1 X1.5E-3\nG49\nM30\n"),
            "exp.ngc:3:4: `X1.5` is followed directly by `E-3`",
        ),
    ] {
        let (code, out, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
        assert!(out.is_empty() || !String::from_utf8_lossy(&out).contains("W1."));
    }
    // Outside pose mode, and D H S T M words in it, pass.
    let plain = b"G1 X12. W1. E3 U2 V1\nM30\n";
    let (code, out, err) = post("plain.ngc", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
    let (code, _, err) = post(
        "ok.ngc",
        format!("{fanuc}T1 M6 S1000 M3 D1\nG1 X12 Y0 Z5 F200\nG4 P1\nG49\nG1 W5\nM30\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
}

/// Cutter radius compensation under TCP: before, `G41 D1`, `G42.2` under
/// G43.4 and `G41` under TRAORI were written through (exit 0) and the
/// controller offset kinpost's machine axis words by the tool radius. Now
/// refused at the word in pose mode; pose mode may not start while it is
/// on; `G40` cancels it.
#[test]
fn cutter_radius_compensation_in_pose_mode_is_refused() {
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    for (name, text, want) in [
        (
            "g41.ngc",
            format!("{fanuc}G41 D1\nG1 X12\nG40\nG49\nM30\n"),
            "g41.ngc:3:1: cutter radius compensation",
        ),
        (
            "g42.ngc",
            format!("{fanuc}G1 G42 X12\nG40\nG49\nM30\n"),
            "g42.ngc:3:4: cutter radius compensation",
        ),
        (
            "g412.ngc",
            format!("{fanuc}G41.2 D1\nG49\nM30\n"),
            "g412.ngc:3:1: cutter radius compensation",
        ),
        (
            "g422.ngc",
            format!("{fanuc}G42.2\nG49\nM30\n"),
            "g422.ngc:3:1: cutter radius compensation",
        ),
        (
            "g41.mpf",
            "TRAORI\nG41\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\nTRAFOOF\nM30\n".to_string(),
            "g41.mpf:2:1: cutter radius compensation",
        ),
        (
            "before.ngc",
            format!("G41 D1\nG1 X0 Y0\n{fanuc}G49\nM30\n"),
            "before.ngc:3:1: pose mode starts while cutter radius compensation",
        ),
        (
            "ijk.ngc",
            "G42 D1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nM30\n".to_string(),
            "ijk.ngc:2:1: pose mode starts while cutter radius compensation",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    // G40 passes in pose mode, and cancels compensation set before it.
    let (code, _, err) = post(
        "g40.ngc",
        format!("G41 D1\nG1 X0 Y0\nG40\n{fanuc}G40\nG1 X12\nG49\nM30\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
    let plain = b"G41 D1\nG1 X0 Y0 F100\nG42.2\nG40\nM30\n";
    let (code, out, err) = post("plain.ngc", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
}

/// Text kinpost does not evaluate in pose mode was named a malformed
/// number: `X=IC(2)` "malformed number `X=IC`", `X=R1` "malformed number
/// `X=R1`", `o100 if [...]` "malformed number `o100`" (and `o100 else`
/// passed: no letter of a pose word in it). Now each message says what it
/// is; every o-word control statement is refused in pose mode.
#[test]
fn unevaluated_values_and_o_words_are_named() {
    let sin = "TRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1 F500\n";
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    for (name, text, want) in [
        (
            "ic.mpf",
            format!("{sin}G1 X=IC(2)\nTRAFOOF\nM30\n"),
            "ic.mpf:3:4: `X=IC(2)`: a Sinumerik dimension function (IC(…): incremental",
        ),
        (
            "ac.mpf",
            format!("{sin}G1 Y0 Z=AC(5.5)\nTRAFOOF\nM30\n"),
            "ac.mpf:3:7: `Z=AC(5.5)`: a Sinumerik dimension function (AC(…): absolute",
        ),
        (
            "r.mpf",
            format!("{sin}G1 X=R1\nTRAFOOF\nM30\n"),
            "r.mpf:3:4: `X=R1`: an R parameter",
        ),
        (
            "if.ngc",
            format!("{fanuc}o100 if [#1 GT 0]\nG1 X12\no100 endif\nG49\nM30\n"),
            "if.ngc:3:1: an o-word control statement (`o100 if`",
        ),
        (
            "else.ngc",
            format!("{fanuc}o100 else\nG49\nM30\n"),
            "else.ngc:3:1: an o-word control statement (`o100 else`",
        ),
        (
            "rep.ngc",
            format!("{fanuc}o<lp> repeat [3]\nG1 X12\no<lp> endrepeat\nG49\nM30\n"),
            "rep.ngc:3:1: an o-word control statement (`o<lp> repeat`",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
        assert!(!err.contains("malformed number"), "{name}: {err}");
    }
    // Outside pose mode they pass through.
    let plain = b"o100 sub\nG1 X1\no100 endsub\no100 call\nG1 X=IC(2)\nM30\n";
    let (code, out, err) = post("plain.ngc", plain);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, plain);
}

/// Block delete (`/`): in absolute mode a `/` pose block is converted and
/// keeps its `/` (the controller may skip it: the next absolute block
/// stands alone). Under G91 the machine-axis increments kinpost writes
/// for later blocks start from that pose: a controller skipping it would
/// put every later block off. Before, it was converted with exit 0; now
/// refused at the `/`.
#[test]
fn block_delete_pose_blocks_are_kept_in_absolute_and_refused_in_incremental() {
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    let (code, out, err) = post(
        "abs.ngc",
        format!("{fanuc}/G1 X12 I0 J0 K1\n/1 G1 X14\nG1 X15\nG49\nM30\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
    let out = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[2].starts_with("/G1 X") && lines[2] != "/G1 X12 I0 J0 K1",
        "{out}"
    );
    assert!(lines[3].starts_with("/1 G1 X"), "{out}");
    assert!(lines[4].starts_with("G1 X"), "{out}");
    for (name, text, want) in [
        (
            "inc.ngc",
            format!("{fanuc}G91\n/G1 X1\nG1 X1\nG90\nG49\nM30\n"),
            "inc.ngc:4:1: a block-delete (`/`) pose block under G91",
        ),
        (
            "inc2.ngc",
            format!("{fanuc}/ G91 G1 X1 I0 J0 K1\nG90\nG49\nM30\n"),
            "inc2.ngc:3:1: a block-delete (`/`) pose block under G91",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    // Under G91 without `/`, and `/` blocks that are not poses, pass.
    let (code, _, err) = post(
        "ok.ngc",
        format!("{fanuc}G91\nG1 X1\n/M1\nG90\nG49\nM30\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
}

/// A pose block that takes over a coordinate or the tool vector from a
/// block-delete (`/`) block is refused where the value differs from the one
/// before it: with the switch on the controller skipped the `/` block.
/// Before, `G1 Y5` after `/G1 X12 I0.6 J0 K0.8` was written at X12 with the
/// tool turned (`G1 X18.4000 Y-5.0000 Z6.2000 B36.8699 C180.0000`), where a
/// controller skipping the block is at X10 with the tool along Z.
#[test]
fn a_pose_taking_over_values_of_a_block_delete_block_is_refused() {
    let fanuc = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F100\n";
    for (name, rest, want) in [
        (
            "carry.ngc",
            "/G1 X12 I0.6 J0 K0.8\nG1 Y5\n",
            "carry.ngc:4:4: X is taken over from a block-delete (`/`) block",
        ),
        (
            "axis.ngc",
            "/G1 X12 I0.6 J0 K0.8\nG1 X11 Y5\n",
            "axis.ngc:4:4: the tool vector (I J K) is taken over from a block-delete (`/`) block",
        ),
        (
            "partial.ngc",
            "/G1 X12 I0.6 J0 K0.8\nG1 X11 Y5 I0\n",
            "partial.ngc:4:4: the tool vector (I J K) is taken over",
        ),
    ] {
        let (code, _, err) = post(name, format!("{fanuc}{rest}G49\nM30\n").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    // Given again, or unchanged by the `/` block: converted.
    for rest in [
        "/G1 X12 I0.6 J0 K0.8\nG1 X11 Y5 I0 J0 K1\nG1 Y6\n",
        "/G1 X10 I0 J0 K1\nG1 Y5\n",
        "/G1 X12 I0.6 J0 K0.8\n/G1 Z6\nG1 X10 Z4 I0 J0 K1\n",
    ] {
        let (code, _, err) = post("ok.ngc", format!("{fanuc}{rest}G49\nM30\n").as_bytes());
        assert_eq!(code, 0, "{rest}: {err}");
    }
}

/// Sinumerik `ORIMKS` puts the tool vectors in machine coordinates: under
/// `TRAORI` the A3 B3 C3 of a block were read as workpiece-frame vectors
/// and converted, exit 0. Now refused at `ORIMKS` in pose mode, or where
/// pose mode starts under it; `ORIWKS` (the default) cancels it.
#[test]
fn orientation_in_machine_coordinates_is_refused() {
    let pose = "G1 X40 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n";
    for (name, head, want) in [
        (
            "a.mpf",
            "TRAORI\nORIMKS\n",
            "a.mpf:2:1: Sinumerik ORIMKS in pose mode",
        ),
        (
            "b.mpf",
            "ORIMKS\nTRAORI\n",
            "b.mpf:2:1: Sinumerik ORIMKS in pose mode",
        ),
    ] {
        let (code, _, err) = post(name, format!("{head}{pose}").as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
    }
    let (code, _, err) = post(
        "c.mpf",
        format!("ORIMKS\nORIWKS\nTRAORI\n{pose}ORIMKS\n").as_bytes(),
    );
    assert_eq!(code, 0, "{err}");
}

/// Haas `G234` (TCPC) is tool centre point control, as Fanuc `G43.4`:
/// before, a Haas TCPC program passed through as machine axes, exit 0 and
/// "0 poses converted", whatever it held. Its rotary positions (`B30 C0`,
/// the usual Haas form) are converted since session 34 (before, refused
/// as orientation given another way than by a tool vector), and so is a
/// program with I J K; `G234` is written as `G49`.
#[test]
fn haas_tcpc_is_tool_centre_point_control() {
    let (code, out, err) = post(
        "haas.nc",
        b"G0 X0 Y0 Z100 B0 C0\nG234 H1\nG1 X10 Y0 Z5 B30 C0 F500\nG49\nM30\n",
    );
    assert_eq!(code, 0, "{err}");
    let out = String::from_utf8(out).unwrap();
    assert!(
        out.contains("\nG49\nG1 X") && out.contains(" B30.0000 C0.0000 F500\n"),
        "{out}"
    );
    let (code, out, err) = post("vec.nc", b"G234 H1\nG1 X40 Y0 Z5 I0 J0 K1 F500\nG49\nM30\n");
    assert_eq!(code, 0, "{err}");
    let out = String::from_utf8(out).unwrap();
    assert!(
        out.starts_with("G49 H1\n") || out.starts_with("G49\n"),
        "{out}"
    );
    assert!(!out.contains("G234"), "{out}");
}

/// A block-delete (`/`) block that only changes modal state: with the
/// switch on the controller skips it, and the blocks after it run in the
/// mode before it. Before, `/G91`, `/G20`, `/G43.4`, `/G49`, `/G69`,
/// `/G40`, `/ORIWKS`, `/G1` (after arcs) were not checked: the poses after
/// them were converted in the mode after the block, exit 0. Now a block
/// without `/` whose conversion depends on such a change is refused at the
/// `/`; a change that nothing converted depends on (a plane, G0/G1, a
/// feed without `--feed inverse-time`; a mode set again without `/`; a
/// program that never enters pose mode) passes byte for byte.
#[test]
fn block_delete_of_a_modal_change_is_refused_where_poses_depend_on_it() {
    let pose = "G1 X10 Y0 Z5 I0 J0 K1 F500\n";
    let refused = [
        (
            "g91.ngc",
            format!("G43.4 H1\n{pose}/G91\nG1 X1\nG90\nG49\nM30\n"),
            "g91.ngc:3:1: this block-delete (`/`) block changes the distance mode (G90/G91)",
        ),
        (
            "g91-first.ngc",
            format!("/G91\nG43.4 H1\n{pose}G49\nM30\n"),
            "g91-first.ngc:1:1: this block-delete (`/`) block changes the distance mode",
        ),
        (
            "g20.ngc",
            format!("  /G20\nG43.4 H1\n{pose}G49\nM30\n"),
            "g20.ngc:1:3: this block-delete (`/`) block changes the units",
        ),
        (
            "tcp-on.ngc",
            "/G43.4 H1\nG1 X10 Y0 Z5 F500\nG49\nM30\n".into(),
            "tcp-on.ngc:1:1: this block-delete (`/`) block changes tool centre point control",
        ),
        (
            "tcp-off.ngc",
            format!("G43.4 H1\n{pose}/G49\nG0 Z100\nM30\n"),
            "tcp-off.ngc:3:1: this block-delete (`/`) block changes tool centre point control",
        ),
        (
            "g69.ngc",
            format!("G68 X0 Y0 R30\n/G69\nG43.4 H1\n{pose}G49\nM30\n"),
            "g69.ngc:2:1: this block-delete (`/`) block changes a frame",
        ),
        (
            "g40.ngc",
            format!("G41 D1\nG1 X5 Y5\n/G40\nG43.4 H1\n{pose}G49\nM30\n"),
            "g40.ngc:3:1: this block-delete (`/`) block changes cutter radius compensation",
        ),
        (
            "oriwks.mpf",
            "ORIMKS\n/ORIWKS\nTRAORI\nG1 X10 Y0 Z5 A3=0 B3=0 C3=1\nTRAFOOF\nM30\n".into(),
            "oriwks.mpf:2:1: this block-delete (`/`) block changes Sinumerik ORIMKS/ORIWKS",
        ),
        (
            "motion.ngc",
            "G2 X10 Y0 I5 J0\n/G1\nG43.4 H1\nX10 Y0 Z5 I0 J0 K1\nG49\nM30\n".into(),
            "motion.ngc:2:1: this block-delete (`/`) block changes the motion mode",
        ),
    ];
    for (name, text, want) in &refused {
        let (code, out, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(out.is_empty(), "{name}");
        assert!(err.contains(want), "{name}: {err}");
    }
    let passed = [
        // Never in pose mode: nothing converted depends on it.
        "G0 X0 Y0\n/G91\nG1 X1\nG90\nM30\n".to_string(),
        // Set again without `/` before the poses.
        format!("G43.4 H1\n{pose}/G91\nG90\nG1 X11\nG49\nM30\n"),
        // A plane, G0/G1 and a feed do not change the conversion.
        format!("G43.4 H1\n{pose}/G18\n/G0\n/F200\nG1 X11\nG49\nM30\n"),
        // A group of `/` blocks that restores the mode: all run or none.
        format!("G43.4 H1\n{pose}/G20\n/G1 X0.5 Y0 Z0.2\n/G21\nG1 X11 Y0 Z5\nG49\nM30\n"),
    ];
    for text in &passed {
        let (code, out, err) = post("ok.ngc", text.as_bytes());
        assert_eq!(code, 0, "{text}: {err}");
        let out = String::from_utf8(out).unwrap();
        for l in text.lines().filter(|l| l.starts_with('/')) {
            assert!(
                out.lines().any(|o| o == l) || l.contains(" X"),
                "{l}: {out}"
            );
        }
    }
    let (code, out, _) = post("plain.ngc", passed[0].as_bytes());
    assert_eq!((code, out), (0, passed[0].as_bytes().to_vec()));
}

/// `post --feed inverse-time` converts feeds, so there a `/` block that
/// changes the feed mode, the feed or G0/G1 is refused where a converted
/// block depends on it; the same program without the option passes.
#[test]
fn block_delete_of_a_feed_change_is_refused_under_inverse_time() {
    let run = |name: &str, text: &str, extra: &[&str]| {
        let args = [&["post", "-q", "--machine", "xyzbc-trt"][..], extra].concat();
        let (code, _, err) = crate::util::run_on(&args, name, text);
        (code, err)
    };
    let head = "G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n";
    let turn = "X20 I0.5 J0 K0.8660254\nG49\nM30\n";
    for (name, change, want) in [
        ("g93.ngc", "/G93\n", "the feed mode (G93/G94/G95)"),
        ("f.ngc", "/F200\n", "the feed (F)"),
        ("g0.ngc", "G0 X12\n/G1\n", "the motion mode"),
    ] {
        let text = format!("{head}{change}{turn}");
        let (code, err) = run(name, &text, &["--feed", "inverse-time"]);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(want) && err.contains("block-delete"),
            "{name}: {err}"
        );
        let (code, err) = run(name, &text, &[]);
        assert_eq!(code, 0, "{name}: {err}");
    }
}

/// Before pose mode kinpost follows machine-axis moves, and a pose that
/// does not give X, Y, Z and its tool vector continues from where they
/// left the machine. A `/` move, or a move in a mode a `/` block changed,
/// leaves the machine elsewhere with the switch on: such a pose is refused
/// at the `/`. Before, `/G0 X20` then `G43.4 H1`, `G1 Z5` was converted at
/// X20, exit 0.
#[test]
fn a_pose_continuing_from_a_block_delete_position_is_refused() {
    for (name, text, want) in [
        (
            "move.ngc",
            "G0 X10 Z50 B0 C0\n/G0 X20\nG43.4 H1\nG1 Z5\nG49\nM30\n",
            "move.ngc:2:1:",
        ),
        (
            "mode.ngc",
            "G0 X10 Z50 B0 C0\n/G91\nG0 X10\nG90\nG43.4 H1\nG1 Z5\nG49\nM30\n",
            "mode.ngc:2:1:",
        ),
    ] {
        let (code, _, err) = post(name, text.as_bytes());
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(want) && err.contains("block-delete"),
            "{name}: {err}"
        );
        // A pose that gives X, Y, Z and the tool vector stands alone.
        let full = text.replace("G1 Z5", "G1 X5 Y0 Z5 I0 J0 K1");
        let (code, _, err) = post(name, full.as_bytes());
        assert_eq!(code, 0, "{name}: {err}");
    }
}
