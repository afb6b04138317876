//! Helpers shared by the integration tests: the kinpost binary, paths in
//! the repository, the two seed machines, the shared material.

use std::path::{Path, PathBuf};

use kinpost::machine::{Chain, Machine};

/// The kinpost binary cargo built for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_kinpost");

/// The repository root.
pub fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The path of `p` (relative to the repository root) as a string.
pub fn repo_file(p: &str) -> String {
    format!("{}/{p}", env!("CARGO_MANIFEST_DIR"))
}

/// zhao2022-xzbc, the embedded seed 000 machine (C X Z B + translate
/// [0, 0, −20]).
pub fn zhao_machine() -> Machine {
    Machine::embedded("zhao2022-xzbc").expect("embedded fixture")
}

/// wang2023-xyzab, the embedded seed 003 machine (A X Y Z, translate
/// [0, 0, 265], B, translate [0, 0, −265]).
pub fn wang_machine() -> Machine {
    Machine::embedded("wang2023-xyzab").expect("embedded fixture")
}

/// The chain of zhao2022-xzbc.
pub fn zhao() -> Chain {
    zhao_machine().chain
}

/// The chain of wang2023-xyzab.
pub fn wang() -> Chain {
    wang_machine().chain
}

/// The environment variable that moves the shared material elsewhere than
/// `../shared` beside the repository (also used to check the skip: point it
/// at a path that does not exist).
pub const SHARED_VAR: &str = "KINPOST_SHARED";

/// The root of the shared material: `$KINPOST_SHARED` when set, otherwise
/// `../shared` beside the repository.
pub fn shared_root() -> PathBuf {
    match std::env::var_os(SHARED_VAR) {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"),
    }
}

/// Whether the tests run under CI (`CI` set to anything but empty, `0` or
/// `false`): there the shared material is required.
pub fn in_ci() -> bool {
    std::env::var("CI")
        .map(|v| !matches!(v.trim().to_ascii_lowercase().as_str(), "" | "0" | "false"))
        .unwrap_or(false)
}

/// The directory `sub` of the shared material (`corpus`, `real/…`, `spec`,
/// `seeds`), or `None` when it is absent: the caller skips, and a message
/// says so. Under CI an absent directory fails the test instead.
pub fn shared_dir(sub: &str) -> Option<PathBuf> {
    let dir = shared_root().join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        !in_ci(),
        "CI needs the shared material: {} is absent (set {SHARED_VAR} or put it at ../shared)",
        dir.display()
    );
    println!(
        "skipped: {} is absent (the shared material is not beside the repository)",
        dir.display()
    );
    None
}

/// Runs `kinpost post --machine machine` on `bytes` written to a file
/// `name` in a temporary folder: (exit code, stdout, stderr).
pub fn post_file(machine: &str, name: &str, bytes: &[u8]) -> (i32, Vec<u8>, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    let out = std::process::Command::new(BIN)
        .args(["post", "--machine", machine])
        .arg(&p)
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        out.stdout,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `kinpost args… FILE` (in the repository) on `text` written to a
/// file `name` in a temporary folder: (exit code, stdout, stderr).
pub fn run_on(args: &[&str], name: &str, text: &str) -> (i32, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    let out = std::process::Command::new(BIN)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .arg(&p)
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A straight pose block `G1 X Y Z I J K` for `pose` (tip to 9 decimals,
/// tool axis to 12), without a line end.
pub fn pose_block(pose: &kinpost::machine::Pose) -> String {
    format!(
        "G1 X{:.9} Y{:.9} Z{:.9} I{:.12} J{:.12} K{:.12}",
        pose.tip.x, pose.tip.y, pose.tip.z, pose.axis.x, pose.axis.y, pose.axis.z
    )
}

/// The numbers of the words of an output `line` with one-letter
/// addresses, by letter, in order (comments left out).
pub fn letter_words(line: &str) -> Vec<(char, f64)> {
    let line = line.split('(').next().unwrap_or("");
    line.split_whitespace()
        .filter_map(|w| {
            let mut c = w.chars();
            let a = c.next()?;
            let v: f64 = c.as_str().parse().ok()?;
            a.is_ascii_alphabetic().then_some((a, v))
        })
        .collect()
}
