//! Twenty-third hunt (session 39, `docs/robustness.md`): recordings as
//! loggers write them, read by `diagnose`. Each test failed before its fix.

use crate::util::{BIN, repo_file};

/// Runs kinpost with `args`; (stdout, stderr), asserting success.
fn kinpost(args: &[&str]) -> String {
    let out = std::process::Command::new(BIN).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A recording of zhao2022-xzbc's exercise program by `simulate` with
/// `extra` options, every line passed through `edit` (header included, as
/// line 0), diagnosed: the text report.
fn diagnose_edited(extra: &[&str], edit: &dyn Fn(usize, &str) -> String) -> String {
    let program = repo_file("fixtures/programs/zhao2022-xzbc-exercise.nc");
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("raw.csv");
    let rec = dir.path().join("r.csv");
    let mut args = vec!["simulate", "-m", "zhao2022-xzbc", "-p", &program];
    args.extend_from_slice(extra);
    args.extend(["-o", raw.to_str().unwrap()]);
    kinpost(&args);
    let text = std::fs::read_to_string(&raw).unwrap();
    let edited: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| edit(i, l) + "\n")
        .collect();
    std::fs::write(&rec, edited).unwrap();
    kinpost(&[
        "diagnose",
        "-m",
        "zhao2022-xzbc",
        "-r",
        rec.to_str().unwrap(),
    ])
}

/// The fields of a CSV line from `from` on rounded to 3 decimals.
fn round_from(line: &str, from: usize) -> String {
    line.split(',')
        .enumerate()
        .map(|(j, f)| {
            if j >= from {
                format!("{:.3}", f.parse::<f64>().unwrap())
            } else {
                f.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// A drive trace in whole encoder counts (0.001 mm and deg) beside
/// full-precision commands, with no physics and no other noise: the
/// rounding error is frozen while an axis rests, so B, resting for seconds
/// at a handful of positions, showed χ² 1.12 and was an "unexplained
/// mismatch on B". The χ² test now counts the rounding's draws, not the
/// samples; a backlash under the same rounding is still found.
#[test]
fn feedback_in_whole_counts_is_noise() {
    let round = |i: usize, l: &str| if i == 0 { l.into() } else { round_from(l, 6) };
    let opts = ["--feedback", "--noise", "0", "--sample-interval", "0.01"];
    let text = diagnose_edited(&opts, &round);
    assert!(
        text.contains("verdict: consistent with measurement noise"),
        "{text}"
    );
    let mut with_backlash = opts.to_vec();
    with_backlash.extend(["--inject", "backlash:X=0.004"]);
    let text = diagnose_edited(&with_backlash, &round);
    assert!(text.contains("1. backlash X: value = "), "{text}");
    assert!(
        text.contains("verdict: missing physics found: backlash of X; what remains is consistent"),
        "{text}"
    );
}
