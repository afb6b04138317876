//! The fitted-model cache of `--errors TABLE.csv`: a second run with the
//! same table reads the fitted model from the cache and gives the same
//! bytes; another table, a damaged or tampered entry, a link and the
//! entry limit; the cache never changes an output or a message.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, SystemTime};

use crate::util::{BIN, repo_file};

/// A scratch directory with the zhao table and program in it, and a cache
/// directory below it.
struct Scratch {
    dir: tempfile::TempDir,
}

impl Scratch {
    fn new() -> Scratch {
        let dir = tempfile::tempdir().unwrap();
        for (from, to) in [
            ("fixtures/errors/zhao2022-xzbc.csv", "t.csv"),
            ("fixtures/errors/wang2023-xyzab.csv", "w.csv"),
            ("fixtures/programs/zhao2022-xzbc.ngc", "p.ngc"),
        ] {
            std::fs::copy(repo_file(from), dir.path().join(to)).unwrap();
        }
        Scratch { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn cache(&self) -> PathBuf {
        self.path("cache")
    }

    /// Runs kinpost in the scratch directory with `KINPOST_CACHE_DIR` set
    /// to `cache` (and the other places a cache could go pointed into the
    /// scratch directory, so that nothing is written elsewhere).
    fn run(&self, cache: &str, args: &[&str]) -> Output {
        Command::new(BIN)
            .current_dir(self.dir.path())
            .env("KINPOST_CACHE_DIR", cache)
            .env("HOME", self.path("home"))
            .env("XDG_CACHE_HOME", self.path("xdg"))
            .args(args)
            .output()
            .unwrap()
    }

    /// `compensate` of p.ngc on zhao2022-xzbc with `table`: the output and
    /// the report.
    fn compensate(&self, cache: &str, table: &str) -> (Vec<u8>, Vec<u8>) {
        let _ = std::fs::remove_file(self.path("out.nc"));
        let _ = std::fs::remove_file(self.path("report.json"));
        let mut args = compensate_args(table);
        args.extend(["--report", "report.json", "--quiet"]);
        let o = self.run(cache, &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            std::fs::read(self.path("out.nc")).unwrap(),
            std::fs::read(self.path("report.json")).unwrap(),
        )
    }

    /// The same, with the cache at [`Scratch::cache`].
    fn cached(&self, table: &str) -> (Vec<u8>, Vec<u8>) {
        let cache = self.cache();
        self.compensate(cache.to_str().unwrap(), table)
    }

    /// The entries in the cache directory.
    fn entries(&self) -> Vec<PathBuf> {
        entries_in(&self.cache())
    }
}

/// The command line of `compensate` of p.ngc on zhao2022-xzbc with
/// `table`, written to out.nc.
fn compensate_args(table: &str) -> Vec<&str> {
    vec![
        "compensate",
        "--machine",
        "zhao2022-xzbc",
        "--errors",
        table,
        "p.ngc",
        "-o",
        "out.nc",
    ]
}

fn entries_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = rd
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.starts_with("fit-") && n.ends_with(".json")
        })
        .collect();
    v.sort();
    v
}

/// Everything under `dir`, recursively (empty if absent).
fn all_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.extend(all_files(&p));
            }
            out.push(p);
        }
    }
    out
}

/// Identity of a file: content, modification time and (on Unix) inode.
fn identity(p: &Path) -> (Vec<u8>, SystemTime, u64) {
    let m = std::fs::metadata(p).unwrap();
    #[cfg(unix)]
    let ino = std::os::unix::fs::MetadataExt::ino(&m);
    #[cfg(not(unix))]
    let ino = 0;
    (std::fs::read(p).unwrap(), m.modified().unwrap(), ino)
}

/// The entry with the coefficients of the first column of the first axis
/// moved by `delta` (mm or rad): that error moves by `delta` everywhere.
fn tampered(entry: &[u8], delta: f64) -> Vec<u8> {
    let mut v: serde_json::Value = serde_json::from_slice(entry).unwrap();
    let coefficients = v["model"]["axes"][0]["columns"][0]["coefficients"]
        .as_array_mut()
        .unwrap();
    for c in coefficients {
        *c = serde_json::json!(c.as_f64().unwrap() + delta);
    }
    serde_json::to_vec(&v).unwrap()
}

#[test]
fn miss_then_hit_gives_the_same_bytes_and_the_hit_is_used() {
    let s = Scratch::new();
    let uncached = s.compensate("off", "t.csv");
    let first = s.cached("t.csv");
    assert!(
        first == uncached,
        "a miss gives the uncached output and report"
    );
    let entries = s.entries();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let before = identity(&entries[0]);
    let second = s.cached("t.csv");
    assert!(
        second == uncached,
        "a hit gives the uncached output and report"
    );
    assert_eq!(s.entries(), entries);
    assert!(
        identity(&entries[0]) == before,
        "a hit does not rewrite the entry"
    );

    // The hit is what is used: a tampered coefficient (10 µm) changes the
    // output, and the original entry gives it back.
    std::fs::write(&entries[0], tampered(&before.0, 0.01)).unwrap();
    let changed = s.cached("t.csv");
    assert!(changed.0 != uncached.0, "the tampered entry was not used");
    assert!(changed.1 != uncached.1, "the tampered entry was not used");
    std::fs::write(&entries[0], &before.0).unwrap();
    assert!(s.cached("t.csv") == uncached);
}

#[test]
fn another_table_is_another_entry_and_off_writes_nothing() {
    let s = Scratch::new();
    let uncached = s.compensate("off", "t.csv");
    assert!(
        all_files(s.dir.path())
            .iter()
            .all(|p| !p.starts_with(s.cache())
                && !p.starts_with(s.path("home"))
                && !p.starts_with(s.path("xdg"))),
        "a disabled cache writes nothing"
    );
    for off in ["", "0", "none"] {
        assert!(s.compensate(off, "t.csv") == uncached);
    }
    assert!(!s.path("home").exists() && !s.path("xdg").exists());

    s.cached("t.csv");
    // One byte more (a blank line): the same fit, another entry.
    let mut bytes = std::fs::read(s.path("t.csv")).unwrap();
    bytes.push(b'\n');
    std::fs::write(s.path("t2.csv"), &bytes).unwrap();
    assert!(s.cached("t2.csv") == uncached);
    assert_eq!(s.entries().len(), 2);
    // One byte changed in a value: another entry, and another result.
    let text = String::from_utf8(std::fs::read(s.path("t.csv")).unwrap()).unwrap();
    let line = text.lines().nth(6).unwrap().to_string();
    // The last digit of the second field (not an exponent's, which would
    // make the value implausible: a table error then).
    let at = line.match_indices(',').nth(1).unwrap().0 - 1;
    let other = if &line[at..=at] == "1" { "2" } else { "1" };
    let changed_line = format!("{}{other}{}", &line[..at], &line[at + 1..]);
    std::fs::write(s.path("t3.csv"), text.replacen(&line, &changed_line, 1)).unwrap();
    let uncached3 = s.compensate("off", "t3.csv");
    assert!(s.cached("t3.csv") == uncached3);
    assert_eq!(s.entries().len(), 3);

    // Without KINPOST_CACHE_DIR, $XDG_CACHE_HOME/kinpost.
    let o = Command::new(BIN)
        .current_dir(s.dir.path())
        .env_remove("KINPOST_CACHE_DIR")
        .env("XDG_CACHE_HOME", s.path("xdg"))
        .args(["compensate", "--machine", "zhao2022-xzbc", "--errors"])
        .args(["t.csv", "p.ngc", "-o", "out.nc", "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(entries_in(&s.path("xdg/kinpost")).len(), 1);
}

#[test]
fn a_damaged_entry_is_a_miss_and_is_rewritten() {
    let s = Scratch::new();
    let uncached = s.compensate("off", "t.csv");
    s.cached("t.csv");
    let entry = s.entries().remove(0);
    let good = std::fs::read(&entry).unwrap();
    let text = String::from_utf8(good.clone()).unwrap();
    let len_field = text.split("\"table_bytes\":").nth(1).unwrap();
    let len: String = len_field.chars().take_while(char::is_ascii_digit).collect();
    let damaged: Vec<(&str, Vec<u8>)> = vec![
        ("truncated", good[..good.len() / 2].to_vec()),
        ("empty", Vec::new()),
        (
            "wrong length",
            text.replacen(
                &format!("\"table_bytes\":{len}"),
                &format!("\"table_bytes\":{}", len.parse::<u64>().unwrap() + 1),
                1,
            )
            .into_bytes(),
        ),
        (
            "other build",
            text.replacen("\"build\":\"kinpost", "\"build\":\"kinpost?", 1)
                .into_bytes(),
        ),
        ("not UTF-8", [&good[..20], b"\xFF", &good[20..]].concat()),
        (
            "a model that does not read",
            text.replacen("\"format\":\"kinpost-error-model\"", "\"format\":\"x\"", 1)
                .into_bytes(),
        ),
    ];
    for (what, bytes) in damaged {
        assert_ne!(bytes, good, "{what}: the damage changes the entry");
        std::fs::write(&entry, &bytes).unwrap();
        assert!(s.cached("t.csv") == uncached, "{what}: the uncached result");
        assert_eq!(s.entries(), vec![entry.clone()], "{what}");
        assert_eq!(
            std::fs::read(&entry).unwrap(),
            good,
            "{what}: the entry is rewritten"
        );
    }
    // A directory in the entry's place: a miss, and nothing is written.
    std::fs::remove_file(&entry).unwrap();
    std::fs::create_dir(&entry).unwrap();
    assert!(s.cached("t.csv") == uncached);
    assert!(entry.is_dir());
    let left: Vec<_> = std::fs::read_dir(s.cache()).unwrap().collect();
    assert_eq!(left.len(), 1, "no temporary left behind: {left:?}");
}

#[cfg(unix)]
#[test]
fn a_link_in_place_of_an_entry_is_not_followed() {
    let s = Scratch::new();
    let uncached = s.compensate("off", "t.csv");
    s.cached("t.csv");
    let entry = s.entries().remove(0);
    let good = std::fs::read(&entry).unwrap();
    let elsewhere = s.path("elsewhere.json");
    std::fs::write(&elsewhere, tampered(&good, 0.01)).unwrap();
    std::fs::remove_file(&entry).unwrap();
    std::os::unix::fs::symlink(&elsewhere, &entry).unwrap();
    assert!(s.cached("t.csv") == uncached, "the link was followed");
    let m = std::fs::symlink_metadata(&entry).unwrap();
    assert!(m.file_type().is_file(), "the link is replaced by an entry");
    assert_eq!(std::fs::read(&entry).unwrap(), good);
    assert_eq!(
        std::fs::read(&elsewhere).unwrap(),
        tampered(&good, 0.01),
        "the link's target is untouched"
    );
}

#[test]
fn messages_name_the_table_as_without_the_cache() {
    let s = Scratch::new();
    let args = compensate_args;
    let cache = s.cache();
    let cache = cache.to_str().unwrap();
    let uncached = s.run("off", &args("w.csv"));
    let miss = s.run(cache, &args("w.csv"));
    assert_eq!(s.entries().len(), 1, "the fit is stored though bind fails");
    let hit = s.run(cache, &args("w.csv"));
    let msg = String::from_utf8_lossy(&uncached.stderr).into_owned();
    assert!(
        msg.contains("w.csv:134:1: the error model has errors for axis Y"),
        "{msg}"
    );
    assert!(msg.contains("| Y,EXY[um]"), "{msg}");
    for o in [&miss, &hit] {
        assert_eq!(o.status.code(), uncached.status.code());
        assert_eq!(String::from_utf8_lossy(&o.stderr), msg);
    }
    // The same bytes under another name: a hit, named as given.
    std::fs::copy(s.path("w.csv"), s.path("v.csv")).unwrap();
    let uncached = s.run("off", &args("v.csv"));
    let hit = s.run(cache, &args("v.csv"));
    assert_eq!(s.entries().len(), 1, "same bytes, same entry");
    let msg = String::from_utf8_lossy(&uncached.stderr).into_owned();
    assert!(msg.contains("v.csv:134:1:"), "{msg}");
    assert_eq!(String::from_utf8_lossy(&hit.stderr), msg);
    assert_eq!(hit.status.code(), uncached.status.code());
}

#[test]
fn at_most_64_entries_the_oldest_go() {
    let s = Scratch::new();
    let cache = s.cache();
    std::fs::create_dir_all(&cache).unwrap();
    let now = SystemTime::now();
    // 70 old entries, entry i older than entry i + 1, and other files.
    let old: Vec<PathBuf> = (0..70u64)
        .map(|i| {
            let p = cache.join(format!("fit-{:016x}.json", 0xabc0_0000 + i));
            std::fs::write(&p, b"{}").unwrap();
            let f = std::fs::File::options().write(true).open(&p).unwrap();
            f.set_modified(now - Duration::from_secs(10_000 - i * 10))
                .unwrap();
            p
        })
        .collect();
    std::fs::write(cache.join("notes.txt"), b"mine").unwrap();
    std::fs::write(cache.join("fit-short.json"), b"{}").unwrap();
    let uncached = s.compensate("off", "t.csv");
    assert!(s.cached("t.csv") == uncached);
    let left = s.entries();
    assert_eq!(left.len(), 65, "64 entries and fit-short.json: {left:?}");
    for (i, p) in old.iter().enumerate() {
        assert_eq!(p.exists(), i >= 7, "{}", p.display());
    }
    assert!(cache.join("notes.txt").exists() && cache.join("fit-short.json").exists());
    // The new entry is kept and used.
    let new: Vec<&PathBuf> = left.iter().filter(|p| !old.contains(p)).collect();
    assert_eq!(new.len(), 2);
    assert!(s.cached("t.csv") == uncached);
    assert_eq!(s.entries(), left);
}
