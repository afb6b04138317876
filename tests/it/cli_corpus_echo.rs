//! `kinpost parse --echo FILE` is byte-identical for every file of the
//! shared corpus (through the binary, as a user runs it). Skipped with a
//! message when `../shared` is absent; under CI (`CI=true`) that fails.

use crate::util;

use std::path::{Path, PathBuf};
use std::process::Command;

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("corpus directory")
        .flatten()
        .collect();
    entries.sort_by_key(|e| e.path());
    for e in entries {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if p.file_name().is_some_and(|n| n != "README.md") {
            out.push(p);
        }
    }
}

#[test]
fn parse_echo_is_byte_identical_on_the_corpus() {
    let Some(root) = util::shared_dir("corpus") else {
        return;
    };
    let mut all = Vec::new();
    files(&root, &mut all);
    assert!(all.len() > 50, "only {} corpus files", all.len());
    for f in &all {
        let out = Command::new(crate::util::BIN)
            .args(["parse", "--echo"])
            .arg(f)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: {}",
            f.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.stdout == std::fs::read(f).unwrap(),
            "{} differs after parse --echo",
            f.display()
        );
    }
    eprintln!("{} corpus files echoed byte for byte", all.len());
}
