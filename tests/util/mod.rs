//! Helpers shared by the integration tests.

use std::path::PathBuf;

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
