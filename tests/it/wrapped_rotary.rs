//! LinuxCNC's wrapped rotary axis (`WRAPPED_ROTARY = 1`, kinpost's
//! `"rotary": "wrapped"`): an absolute word is the position in [0, 360)
//! and its sign the direction the controller turns to it. Before, such a
//! configuration was refused. Each output is read back here by LinuxCNC's
//! rule (`unwrap_rotary` in its interpreter, written out again below, not
//! kinpost's code) and compared with the same job on the axis declared
//! `continuous`, whose words are the unwound positions themselves.

use crate::util::{BIN, pose_block};
use kinpost::machine::{Machine, NoErrors};
use std::path::Path;
use std::process::Command;

/// LinuxCNC's reading of the absolute word `word` of a wrapped rotary
/// standing at `current` (deg): `|word|` plus whole turns, reached in the
/// direction of the word's sign (`-0` is negative), less than a turn away.
pub(crate) fn linuxcnc_unwrap(word: f64, current: f64) -> f64 {
    assert!(word.abs() < 360.0, "LinuxCNC refuses the word {word}");
    let neg = word.is_sign_negative();
    let mut r = word.abs() + 360.0 * (current / 360.0).floor();
    if !neg && r < current {
        r += 360.0;
    }
    if neg && r > current {
        r -= 360.0;
    }
    r
}

/// The fixture xyzac-trt with its C axis in `mode`, written to `dir`.
fn machine_with_c(dir: &Path, mode: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(crate::util::repo_file("fixtures/machines/xyzac-trt.json"))
        .unwrap()
        .replace(
            r#""C": {"rotary": "continuous"}"#,
            &format!(r#""C": {{"rotary": "{mode}"}}"#),
        );
    assert!(text.contains(mode));
    let p = dir.join(format!("trt-{mode}.json"));
    std::fs::write(&p, text).unwrap();
    p
}

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).args(args).output().unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `kinpost CMD --machine MACHINE PROGRAM`, which must succeed: its output.
fn run_ok(cmd: &str, machine: &Path, program: &Path) -> String {
    let (code, out, err) = run(&[
        cmd,
        "--machine",
        machine.to_str().unwrap(),
        program.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{cmd}: {err}");
    out
}

/// The value of word `address` on a line, as written (a `-0` kept).
fn word(line: &str, address: char) -> Option<f64> {
    line.split_whitespace()
        .find(|w| {
            w.starts_with(address) && w[1..].starts_with(|c: char| c == '-' || c.is_ascii_digit())
        })
        .map(|w| w[1..].parse().unwrap())
}

/// The C positions of the blocks of `program` that carry a C word (LinuxCNC
/// reading them as wrapped from 0° when `wrapped`, else as they are), with
/// whether the line was inserted by `linkage`.
fn c_positions(program: &str, wrapped: bool) -> Vec<(f64, bool)> {
    let mut c = 0.0;
    let mut out = Vec::new();
    for line in program
        .lines()
        .filter(|l| l.starts_with("G1") || l.starts_with("G0"))
    {
        if let Some(w) = word(line, 'C') {
            if wrapped {
                assert!(w.abs() < 360.0, "{line}");
            }
            c = if wrapped { linuxcnc_unwrap(w, c) } else { w };
            out.push((c, line.contains("(kinpost linkage")));
        }
    }
    out
}

/// A pose program on xyzac-trt whose C turns two turns one way, then three
/// back, through 0° and 360° several times, in steps of 7° (A at 30°).
fn pose_program(m: &Machine) -> String {
    let mut text = String::from("G21 G90 G94\nG43.4 H1\n");
    let mut cs: Vec<f64> = (0..=110).map(|k| 7.0 * k as f64).collect();
    cs.extend((1..=170).map(|k| 770.0 - 7.0 * k as f64));
    for (k, c) in cs.iter().enumerate() {
        let ext = [10.0 + 0.1 * k as f64, -20.0, 5.0, 30.0, *c];
        let p = m.chain.pose(&m.to_internal(&ext), &NoErrors);
        text.push_str(&pose_block(&p));
        text.push_str(if k == 0 { " F500\n" } else { "\n" });
    }
    text.push_str("G49\nM30\n");
    text
}

#[test]
fn post_and_compensate_write_wrapped_words_linuxcnc_turns_as_the_unwound_ones() {
    let dir = tempfile::tempdir().unwrap();
    let wrapped = machine_with_c(dir.path(), "wrapped");
    let continuous = machine_with_c(dir.path(), "continuous");
    let m = Machine::load(&continuous).unwrap();
    let program = dir.path().join("turns.ngc");
    std::fs::write(&program, pose_program(&m)).unwrap();
    // A measured X axis (for `compensate`): a scale and a straightness error.
    let table = dir.path().join("x.csv");
    let mut rows = String::from("X,EXX[um],EYX[um]\n");
    for k in -10..=10 {
        let x = 50.0 * k as f64;
        rows.push_str(&format!("{x},{},{}\n", 0.01 * x, 2.0 * (x / 300.0).sin()));
    }
    std::fs::write(&table, rows).unwrap();
    for cmd in ["post", "compensate"] {
        let out = |machine: &Path| {
            let mut args = vec![cmd, "--machine", machine.to_str().unwrap()];
            if cmd == "compensate" {
                args.extend(["--errors", table.to_str().unwrap()]);
            }
            args.push(program.to_str().unwrap());
            let (code, out, err) = run(&args);
            assert_eq!(code, 0, "{cmd}: {err}");
            out
        };
        let (w, c) = (out(&wrapped), out(&continuous));
        let (pw, pc) = (c_positions(&w, true), c_positions(&c, false));
        assert_eq!(pw.len(), 281, "{cmd}");
        assert_eq!(pw.len(), pc.len(), "{cmd}");
        // The unwound C went to 770° and back to −420°; LinuxCNC follows
        // the wrapped words to exactly the same places.
        assert!(pc.iter().any(|p| p.0 > 769.0) && pc.iter().any(|p| p.0 < -419.0));
        for (k, (a, b)) in pw.iter().zip(&pc).enumerate() {
            assert!(
                (a.0 - b.0).abs() < 1e-9,
                "{cmd} block {k}: {} vs {}",
                a.0,
                b.0
            );
        }
        // Negative turns are written with a minus sign; the words stay
        // below 360° in size; the other words are the same.
        assert!(w.contains(" C-"), "{cmd}");
        let strip = |s: &str| -> Vec<String> {
            s.lines()
                .map(|l| {
                    l.split_whitespace()
                        .filter(|w| !w.starts_with('C'))
                        .collect::<Vec<_>>()
                        .join(" ")
                })
                .collect()
        };
        assert_eq!(strip(&w), strip(&c), "{cmd}");
    }
}

/// A turn from 10° negative to 0° is written `C-0.0000` (`C0.0000` would
/// turn LinuxCNC +350°), and a turn on to −5° `C-355.0000`.
#[test]
fn a_negative_turn_to_zero_is_written_minus_zero() {
    let dir = tempfile::tempdir().unwrap();
    let wrapped = machine_with_c(dir.path(), "wrapped");
    let m = Machine::load(&wrapped).unwrap();
    let mut text = String::from("G21 G90 G94\nG43.4 H1\n");
    for c in [10.0, 5.0, 0.0, -5.0, 0.0] {
        let p = m
            .chain
            .pose(&m.to_internal(&[10.0, -20.0, 5.0, 30.0, c]), &NoErrors);
        text.push_str(&pose_block(&p));
        text.push_str(" F500\n");
    }
    text.push_str("G49\nM30\n");
    let program = dir.path().join("p.ngc");
    std::fs::write(&program, text).unwrap();
    let out = run_ok("post", &wrapped, &program);
    let words: Vec<&str> = out
        .split_whitespace()
        .filter(|w| w.starts_with('C'))
        .collect();
    assert_eq!(
        words,
        ["C10.0000", "C-5.0000", "C-0.0000", "C-355.0000", "C0.0000"],
        "{out}"
    );
    let cs: Vec<f64> = c_positions(&out, true).iter().map(|p| p.0).collect();
    assert_eq!(cs, [10.0, 5.0, 0.0, -5.0, 0.0], "{out}");
}

/// `linkage` divides five-axis blocks of a machine-axis program whose
/// wrapped C words turn it both ways through 0°: the inserted blocks and
/// the rewritten ones, read by LinuxCNC's rule, follow the unwound path
/// that the same program gives on the continuous axis.
#[test]
fn linkage_divides_wrapped_blocks_along_the_turn_linuxcnc_makes() {
    let dir = tempfile::tempdir().unwrap();
    let wrapped = machine_with_c(dir.path(), "wrapped");
    let continuous = machine_with_c(dir.path(), "continuous");
    // Unwound C, each turn less than a turn: +30, −40, −330, −40, +230.
    let unwound = [350.0, 380.0, 340.0, 10.0, -30.0, 200.0];
    let mut w_text = String::from("G21 G90 G94\n");
    let mut c_text = w_text.clone();
    let mut c = 0.0f64;
    for (k, &u) in unwound.iter().enumerate() {
        let sign = if u < c { "-" } else { "" };
        let mag = u.rem_euclid(360.0);
        let line = |cword: String| {
            format!(
                "G1 X{:.3} Y{:.3} Z{:.3} A{:.3} C{cword}{}\n",
                10.0 + 3.0 * k as f64,
                -5.0 + 2.0 * k as f64,
                1.0 + k as f64,
                20.0 + 4.0 * k as f64,
                if k == 0 { " F200" } else { "" }
            )
        };
        w_text.push_str(&line(format!("{sign}{mag:.3}")));
        c_text.push_str(&line(format!("{u:.3}")));
        c = u;
    }
    w_text.push_str("M30\n");
    c_text.push_str("M30\n");
    let (pw, pc) = (dir.path().join("w.ngc"), dir.path().join("c.ngc"));
    std::fs::write(&pw, &w_text).unwrap();
    std::fs::write(&pc, &c_text).unwrap();
    let (ow, oc) = (
        run_ok("linkage", &wrapped, &pw),
        run_ok("linkage", &continuous, &pc),
    );
    let (qw, qc) = (c_positions(&ow, true), c_positions(&oc, false));
    assert!(qw.iter().filter(|q| q.1).count() > 10, "{ow}");
    assert_eq!(qw.len(), qc.len(), "{ow}\n{oc}");
    for (a, b) in qw.iter().zip(&qc) {
        assert!(
            (a.0 - b.0).abs() < 1e-9 && a.1 == b.1,
            "{} vs {}\n{ow}",
            a.0,
            b.0
        );
    }
    // The original blocks end where the program put them.
    let ends: Vec<f64> = qw.iter().filter(|q| !q.1).map(|q| q.0).collect();
    assert_eq!(ends, unwound, "{ow}");
}

/// A word of 360° or more on a wrapped axis, which LinuxCNC refuses, is
/// refused at its column by `post` (in a block it passes through) and by
/// the commands that read machine axes.
#[test]
fn a_wrapped_word_of_a_full_turn_is_refused_at_its_column() {
    let dir = tempfile::tempdir().unwrap();
    let wrapped = machine_with_c(dir.path(), "wrapped");
    let m = wrapped.to_str().unwrap();
    let p = dir.path().join("p.ngc");
    std::fs::write(&p, "G21 G90\nG0 X0 Y0 Z50 A0 C-400\nM30\n").unwrap();
    let p = p.to_str().unwrap();
    for args in [
        vec!["post", "--machine", m, p],
        vec!["analyze", "--nonlinear", "--machine", m, p],
        vec!["simulate", "--machine", m, "-p", p],
        vec!["linkage", "--machine", m, p],
    ] {
        let (code, out, err) = run(&args);
        assert_eq!(code, 1, "{args:?}: {out}");
        assert!(
            err.contains("p.ngc:2:17: C-400: a wrapped rotary axis (LinuxCNC WRAPPED_ROTARY) takes an absolute position below 360°"),
            "{args:?}: {err}"
        );
    }
}
