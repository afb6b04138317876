//! The binary's panic hook removes the temporary outputs (the release
//! build aborts on a panic, so their own clean-up never runs). The test
//! runs itself again as a child process, so that the hook is installed
//! there and nowhere near the other tests' temporaries.

use std::path::Path;
use std::process::Command;

/// Set in the child: the output path it writes.
const CHILD: &str = "KINPOST_PANIC_CLEANUP_CHILD";

/// `*.part` files in `dir`.
fn temporaries(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .filter(|e| e.file_name().to_string_lossy().ends_with(".part"))
                .count()
        })
        .unwrap_or(0)
}

/// The child (does nothing unless run by the test below): with the hook
/// installed, a write to the output is begun; while its temporary exists
/// another thread panics (its unwinding does not reach the writer, as an
/// abort would not); the temporaries are counted before and after.
#[test]
fn child_for_panic_cleanup() {
    let Some(out) = std::env::var_os(CHILD) else {
        return;
    };
    let out = Path::new(&out).to_path_buf();
    let dir = out.parent().unwrap().to_path_buf();
    kinpost::output::remove_temporaries_on_panic();
    let result = kinpost::output::write_atomically(Some(&out), |w| {
        w.write_all(b"half a program")
            .map_err(|e| kinpost::error::Error::io("<output>", e))?;
        let before = temporaries(&dir);
        let _ = std::thread::spawn(|| panic!("a forced panic")).join();
        let after = temporaries(&dir);
        println!("before {before} after {after}");
        Ok(())
    });
    // The temporary is gone, so committing it fails.
    if let Err(e) = result {
        println!("commit refused: {e}");
    }
}

#[test]
fn a_panic_leaves_no_temporary_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.nc");
    std::fs::write(&out, b"the previous output\n").unwrap();
    let r = Command::new(std::env::current_exe().unwrap())
        .args([
            "panic_cleanup::child_for_panic_cleanup",
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, &out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&r.stdout);
    let stderr = String::from_utf8_lossy(&r.stderr);
    // The temporary existed while the program was half written; the hook
    // removed it when the other thread panicked, before the message.
    assert!(stdout.contains("before 1 after 0"), "{stdout}\n{stderr}");
    assert!(stderr.contains("a forced panic"), "{stderr}");
    assert!(stdout.contains("commit refused"), "{stdout}");
    // The output keeps its previous contents; nothing else is left.
    assert_eq!(std::fs::read(&out).unwrap(), b"the previous output\n");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
}
