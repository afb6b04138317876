//! Output paths never destroy anything: an output that is one of the inputs
//! is refused (also through a link), devices and FIFOs are written rather
//! than replaced, modes and links of an existing file are kept, a signal
//! leaves no temporary file, and a reader that stops early is not an error.
//!
//! Each case failed before `output.rs` learnt it; the list is in
//! `docs/robustness.md`.

#![cfg(unix)]

use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::util::BIN;

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(rel)
}

/// Runs kinpost in `dir`; returns (exit code, stderr).
fn run(dir: &Path, args: &[&str]) -> (i32, String) {
    let out = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .output()
        .expect("run kinpost");
    (
        out.status.code().expect("exited by a signal"),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A scratch directory holding the lens program as `p.nc` and the error table as `t.csv`.
fn scratch() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    std::fs::copy(fixture("programs/zhao2022-lens.nc"), d.path().join("p.nc")).unwrap();
    std::fs::copy(fixture("errors/zhao2022-xzbc.csv"), d.path().join("t.csv")).unwrap();
    d
}

fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".part"))
        .collect()
}

#[test]
fn an_output_equal_to_an_input_is_refused() {
    let d = scratch();
    let p = d.path().join("p.nc");
    let before = std::fs::read(&p).unwrap();
    std::os::unix::fs::symlink("p.nc", d.path().join("alias.nc")).unwrap();
    std::fs::hard_link(&p, d.path().join("hard.nc")).unwrap();
    let cases: &[&[&str]] = &[
        &[
            "compensate",
            "-e",
            "t.csv",
            "p.nc",
            "-o",
            "o.nc",
            "--report",
            "p.nc",
        ],
        &["compensate", "-e", "t.csv", "p.nc", "-o", "p.nc"],
        &["compensate", "-e", "t.csv", "p.nc", "-o", "t.csv"],
        &["post", "p.nc", "-o", "p.nc"],
        &["post", "p.nc", "-o", "alias.nc"],
        &["post", "p.nc", "-o", "hard.nc"],
        &["post", "p.nc", "-o", "./p.nc"],
        &["fit", "t.csv", "-o", "t.csv"],
        &["analyze", "-e", "t.csv", "p.nc", "--svg", "p.nc"],
        &["linkage", "p.nc", "-o", "o.nc", "--report", "p.nc"],
    ];
    for args in cases {
        let (code, err) = run(d.path(), args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains("refusing to write an output over it"),
            "{args:?}: {err}"
        );
        assert_eq!(
            std::fs::read(&p).unwrap(),
            before,
            "{args:?} changed the input"
        );
        assert!(
            !d.path().join("o.nc").exists(),
            "{args:?} wrote the other output"
        );
    }
    assert_eq!(
        std::fs::read(d.path().join("t.csv")).unwrap(),
        std::fs::read(fixture("errors/zhao2022-xzbc.csv")).unwrap()
    );
    let (code, err) = run(
        d.path(),
        &[
            "compensate",
            "-e",
            "t.csv",
            "p.nc",
            "-o",
            "o.nc",
            "--report",
            "o.nc",
        ],
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("name the same file"), "{err}");
    assert!(leftovers(d.path()).is_empty());
}

#[test]
fn devices_and_fifos_are_written_not_replaced() {
    let d = scratch();
    let (code, err) = run(d.path(), &["post", "p.nc", "-o", "/dev/null"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device()
    );
    // A FIFO: a reader on the other end gets the program.
    let fifo = d.path().join("pipe");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !matches!(made, Ok(s) if s.success()) {
        eprintln!("skipped the FIFO case: mkfifo is not available");
        return;
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let (code, err) = run(d.path(), &["post", "p.nc", "-o", "pipe"]);
    assert_eq!(code, 0, "{err}");
    let got = reader.join().unwrap();
    assert!(String::from_utf8_lossy(&got).contains("M30"));
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
}

#[test]
fn modes_symlinks_and_hard_links_are_kept() {
    let d = scratch();
    // An existing 0755 file keeps its mode.
    let out = d.path().join("o.nc");
    std::fs::write(&out, b"old").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o755)).unwrap();
    let (code, err) = run(d.path(), &["post", "p.nc", "-o", "o.nc"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::metadata(&out).unwrap().mode() & 0o777, 0o755);
    // A new file gets 0666 less the umask.
    let status = Command::new("sh")
        .arg("-c")
        .arg(format!("umask 027; exec '{BIN}' post p.nc -o new.nc"))
        .current_dir(d.path())
        .stdin(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(
        std::fs::metadata(d.path().join("new.nc")).unwrap().mode() & 0o777,
        0o640
    );
    // A symbolic link is written through.
    std::os::unix::fs::symlink("o.nc", d.path().join("link.nc")).unwrap();
    std::fs::write(&out, b"old").unwrap();
    let (code, err) = run(d.path(), &["post", "p.nc", "-o", "link.nc"]);
    assert_eq!(code, 0, "{err}");
    let link = std::fs::symlink_metadata(d.path().join("link.nc")).unwrap();
    assert!(
        link.file_type().is_symlink(),
        "the link was replaced by a file"
    );
    assert!(std::fs::read_to_string(&out).unwrap().contains("M30"));
    // A hard link keeps seeing the same content.
    std::fs::hard_link(&out, d.path().join("twin.nc")).unwrap();
    std::fs::write(&out, b"old").unwrap();
    let (code, err) = run(d.path(), &["post", "p.nc", "-o", "o.nc"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(d.path().join("twin.nc")).unwrap()
    );
    assert!(
        std::fs::read_to_string(d.path().join("twin.nc"))
            .unwrap()
            .contains("M30")
    );
    assert!(leftovers(d.path()).is_empty());
}

/// A long pose program: the lens ring, `turns` times.
fn long_program(turns: usize) -> String {
    let lens = std::fs::read_to_string(fixture("programs/zhao2022-lens.nc")).unwrap();
    let poses: Vec<&str> = lens
        .lines()
        .filter(|l| l.starts_with('X') || l.starts_with("G1 X"))
        .collect();
    let mut s = String::from("%\nO1000\nG21 G90 G94 G17\nG43.5 H1\n");
    for _ in 0..turns {
        for p in &poses {
            s.push_str(p);
            s.push('\n');
        }
    }
    s.push_str("G49\nM30\n%\n");
    s
}

#[test]
fn a_signal_leaves_no_temporary_file() {
    let d = scratch();
    std::fs::write(d.path().join("big.nc"), long_program(2_000)).unwrap();
    for (signal, name) in [(15, "TERM"), (2, "INT")] {
        let mut child = Command::new(BIN)
            .args([
                "compensate",
                "-e",
                "t.csv",
                "big.nc",
                "-o",
                "o.nc",
                "--report",
                "r.json",
            ])
            .current_dir(d.path())
            .stdin(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait until the run has its temporaries, then signal it.
        let start = Instant::now();
        while leftovers(d.path()).len() < 2 && start.elapsed() < Duration::from_secs(20) {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(
            !leftovers(d.path()).is_empty(),
            "the run made no temporary file"
        );
        let killed = Command::new("kill")
            .args([format!("-{name}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(128 + signal), "SIG{name}");
        assert!(
            leftovers(d.path()).is_empty(),
            "SIG{name} left {:?}",
            leftovers(d.path())
        );
        assert!(!d.path().join("o.nc").exists() && !d.path().join("r.json").exists());
    }
}

#[test]
fn a_reader_that_stops_early_is_not_an_error() {
    let d = scratch();
    std::fs::write(d.path().join("big.nc"), long_program(50)).unwrap();
    let status = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "'{BIN}' post big.nc 2>err.txt | head -n 1 >/dev/null"
        ))
        .current_dir(d.path())
        .stdin(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let err = std::fs::read_to_string(d.path().join("err.txt")).unwrap();
    assert!(err.is_empty(), "a broken pipe printed: {err}");
    // The exit code itself, with the reader closed before any output.
    let mut kin = Command::new(BIN)
        .args(["post", "big.nc"])
        .current_dir(d.path())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(kin.stdout.take());
    let out = kin.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
