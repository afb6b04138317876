//! Every file of the shared corpus survives `parse -> emit from the tree`
//! byte for byte. Skipped with a message when `../shared` is absent; under
//! CI (`CI=true`) that fails.

use crate::util;

use std::fs;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use kinpost::gcode::{LineReader, echo};

/// All regular files under `dir`, sorted, README.md skipped.
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let entries =
        fs::read_dir(dir).unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()));
    for entry in entries {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            files_under(&path, out);
        } else if path.file_name().is_some_and(|n| n != "README.md") {
            out.push(path);
        }
    }
}

/// The corpus files, or `None` when the corpus is absent (skipped).
fn corpus_files() -> Option<Vec<PathBuf>> {
    let root = util::shared_dir("corpus")?;
    let mut files = Vec::new();
    files_under(&root, &mut files);
    files.sort();
    Some(files)
}

#[test]
fn corpus_round_trips_byte_for_byte() {
    let Some(files) = corpus_files() else {
        return;
    };
    let mut lines = 0usize;
    let mut bytes = 0usize;
    let mut opaque = 0usize;
    for path in &files {
        let original = fs::read(path).unwrap();
        let mut emitted = Vec::with_capacity(original.len());
        for line in LineReader::new(BufReader::new(original.as_slice())) {
            let line = line.unwrap();
            assert!(
                line.is_tiled(),
                "{}:{} items do not tile",
                path.display(),
                line.number
            );
            if line.has_opaque() {
                opaque += 1;
            }
            lines += 1;
            line.write_to(&mut emitted).unwrap();
        }
        if emitted != original {
            let at = emitted
                .iter()
                .zip(&original)
                .take_while(|(a, b)| a == b)
                .count();
            panic!(
                "{}: emitted text differs from the input at byte {at}",
                path.display()
            );
        }
        // The public echo function too, straight from the file.
        let mut echoed = Vec::with_capacity(original.len());
        echo(BufReader::new(fs::File::open(path).unwrap()), &mut echoed).unwrap();
        assert!(echoed == original, "{}: echo differs", path.display());
        bytes += original.len();
    }
    println!(
        "corpus: {} files, {lines} lines, {bytes} bytes round-tripped; {opaque} lines with opaque items",
        files.len()
    );
    assert!(files.len() > 50, "only {} corpus files found", files.len());
}
