//! The fitted-model cache: error tables given to `--errors` are fitted once
//! per table content, and later runs read the fitted model back from a
//! small JSON entry instead of fitting again.
//!
//! An entry is found by a 64-bit key over the table's exact bytes, the fit
//! options and the identity of this build of kinpost (its version, and the
//! size and modification time of the running executable), and is used only
//! if it also records the table's length and a second, independent hash of
//! its bytes. Anything wrong with an entry (unreadable, not a regular file,
//! not JSON, another table or build) makes it a miss: the table is fitted
//! as without the cache. Writing is best effort and atomic (a temporary in
//! the cache directory, then a rename); at most [`MAX_ENTRIES`] entries are
//! kept. The cache never changes a result; see `docs/error-tables.md`.
//!
//! This module stores and finds entries; what goes in them (the model JSON
//! and the axes' origins) is decided by [`super::model::ErrorModel::load`].

use std::ffi::OsString;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use super::axis_errors::Origin;
use crate::error::Location;

/// The environment variable that names the cache directory; `off`, `0`,
/// `none` or the empty string disable the cache.
pub const CACHE_DIR_VAR: &str = "KINPOST_CACHE_DIR";

/// Most entries kept: after a write, the oldest beyond this are removed.
pub const MAX_ENTRIES: usize = 64;

/// Value of the `format` field of an entry.
const ENTRY_FORMAT: &str = "kinpost-fit-cache";
/// Version of the entry layout.
const ENTRY_VERSION: u32 = 1;
/// An entry larger than this is not read (a miss).
const MAX_ENTRY_BYTES: u64 = 256 << 20;
/// Temporaries left by a killed run are removed once this old.
const STALE_TEMPORARY: Duration = Duration::from_secs(3600);

/// A cache directory and the build whose fits it may hold.
#[derive(Debug, Clone)]
pub struct FitCache {
    dir: PathBuf,
    build: String,
}

/// What an entry is looked up by, and what it must record to be used.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheKey {
    /// The key proper (the entry's file name).
    name: u64,
    /// The table's length in bytes.
    len: u64,
    /// FNV-1a of the table's bytes, independent of `name`.
    fnv: u64,
    /// The fit options, as text.
    options: String,
}

/// A found entry: the model JSON and the origin of each of its axes, in
/// the order of the model's axes.
#[derive(Debug, Clone)]
pub struct Hit {
    /// The fitted model (`ErrorModel::to_json`), as JSON text.
    pub model: String,
    /// Where each axis was given in the table, in the current file's name.
    pub origins: Vec<Origin>,
}

/// An axis's origin in an entry: line, column and text of the table; the
/// file name is the current run's.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct OriginJson {
    line: usize,
    col: usize,
    text: String,
}

/// An entry file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct EntryJson<M> {
    format: String,
    version: u32,
    key: String,
    build: String,
    fit_options: String,
    table_bytes: u64,
    table_fnv1a: String,
    origins: Vec<Option<OriginJson>>,
    model: M,
}

impl FitCache {
    /// The cache of this process: at [`location`], for this build; `None`
    /// when disabled, when no location is known, or when the build cannot
    /// be identified.
    pub fn from_env() -> Option<FitCache> {
        Some(FitCache::new(location()?, build_identity()?))
    }

    /// A cache in `dir` for the build identified by `build`.
    pub fn new(dir: impl Into<PathBuf>, build: impl Into<String>) -> FitCache {
        FitCache {
            dir: dir.into(),
            build: build.into(),
        }
    }

    /// The directory of the entries.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The key of a table's bytes fitted with `options` (their text, e.g.
    /// their `Debug` form) by this build.
    pub fn key(&self, table: &[u8], options: &str) -> CacheKey {
        let mut h = DefaultHasher::new();
        ENTRY_FORMAT.hash(&mut h);
        ENTRY_VERSION.hash(&mut h);
        table.hash(&mut h);
        options.hash(&mut h);
        self.build.hash(&mut h);
        CacheKey {
            name: h.finish(),
            len: table.len() as u64,
            fnv: fnv1a(table),
            options: options.to_string(),
        }
    }

    /// The path of the entry of `key`.
    pub fn entry_path(&self, key: &CacheKey) -> PathBuf {
        self.dir.join(format!("fit-{:016x}.json", key.name))
    }

    /// The entry of `key`, if there is a usable one; origins are given the
    /// file name `file`. Any problem is a miss.
    pub fn get(&self, key: &CacheKey, file: &str) -> Option<Hit> {
        let text = read_regular_file(&self.entry_path(key))?;
        let e: EntryJson<serde_json::Value> = serde_json::from_str(&text).ok()?;
        let matches = e.format == ENTRY_FORMAT
            && e.version == ENTRY_VERSION
            && e.key == format!("{:016x}", key.name)
            && e.build == self.build
            && e.fit_options == key.options
            && e.table_bytes == key.len
            && e.table_fnv1a == format!("{:016x}", key.fnv);
        if !matches || !e.model.is_object() {
            return None;
        }
        let origins = e
            .origins
            .into_iter()
            .map(|o| Origin(o.map(|o| (Location::new(file, o.line, o.col), o.text))))
            .collect();
        Some(Hit {
            model: e.model.to_string(),
            origins,
        })
    }

    /// Stores `model` (JSON) with the origins of its axes as the entry of
    /// `key`, then removes the oldest entries beyond [`MAX_ENTRIES`].
    /// Returns the entry's path; on an error nothing is left behind (the
    /// caller ignores it: the cache is best effort).
    pub fn put(
        &self,
        key: &CacheKey,
        model: &serde_json::Value,
        origins: &[Origin],
    ) -> std::io::Result<PathBuf> {
        let entry = EntryJson {
            format: ENTRY_FORMAT.to_string(),
            version: ENTRY_VERSION,
            key: format!("{:016x}", key.name),
            build: self.build.clone(),
            fit_options: key.options.clone(),
            table_bytes: key.len,
            table_fnv1a: format!("{:016x}", key.fnv),
            origins: origins
                .iter()
                .map(|o| {
                    o.0.as_ref().map(|(loc, text)| OriginJson {
                        line: loc.line,
                        col: loc.col,
                        text: text.clone(),
                    })
                })
                .collect(),
            model,
        };
        let bytes = serde_json::to_vec(&entry)?;
        create_dir(&self.dir)?;
        let path = self.entry_path(key);
        crate::output::replace_file(&path, &bytes)?;
        self.prune(&path);
        Ok(path)
    }

    /// Removes the oldest entries (by modification time) beyond
    /// [`MAX_ENTRIES`], never `keep`, and temporaries of killed runs.
    fn prune(&self, keep: &Path) {
        let Ok(dir) = std::fs::read_dir(&self.dir) else {
            return;
        };
        let now = SystemTime::now();
        let mut entries: Vec<(SystemTime, PathBuf)> = Vec::new();
        for e in dir.flatten() {
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            // Not followed: a link is neither counted nor removed.
            let Ok(meta) = e.metadata() else { continue };
            if !meta.is_file() {
                continue;
            }
            let Ok(modified) = meta.modified() else {
                continue;
            };
            if is_entry_name(name) {
                entries.push((modified, e.path()));
            } else if name.starts_with(".kinpost-")
                && name.ends_with(".part")
                && now
                    .duration_since(modified)
                    .is_ok_and(|age| age > STALE_TEMPORARY)
            {
                let _ = std::fs::remove_file(e.path());
            }
        }
        if entries.len() <= MAX_ENTRIES {
            return;
        }
        let excess = entries.len() - MAX_ENTRIES;
        entries.sort();
        for (_, p) in entries.into_iter().filter(|(_, p)| p != keep).take(excess) {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Whether `name` is an entry's file name: `fit-` 16 hex digits `.json`.
fn is_entry_name(name: &str) -> bool {
    name.strip_prefix("fit-")
        .and_then(|n| n.strip_suffix(".json"))
        .is_some_and(|h| h.len() == 16 && h.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// The cache directory from the environment: `KINPOST_CACHE_DIR` (unless
/// it disables the cache), else `%LOCALAPPDATA%\kinpost` on Windows, else
/// `$XDG_CACHE_HOME/kinpost`, else `$HOME/.cache/kinpost`; `None` when
/// disabled or unknown.
pub fn location() -> Option<PathBuf> {
    location_from(|k| std::env::var_os(k), cfg!(windows))
}

/// [`location`] with the environment read through `var`.
fn location_from(var: impl Fn(&str) -> Option<OsString>, windows: bool) -> Option<PathBuf> {
    if let Some(v) = var(CACHE_DIR_VAR) {
        let disabled = v.to_str().is_some_and(|s| {
            matches!(
                s.trim().to_ascii_lowercase().as_str(),
                "" | "off" | "0" | "none"
            )
        });
        return (!disabled).then(|| PathBuf::from(v));
    }
    // Only absolute base directories: a relative one would move with the
    // working directory.
    let base = |k: &str| var(k).map(PathBuf::from).filter(|p| p.is_absolute());
    if windows {
        return base("LOCALAPPDATA").map(|p| p.join("kinpost"));
    }
    base("XDG_CACHE_HOME")
        .map(|p| p.join("kinpost"))
        .or_else(|| base("HOME").map(|p| p.join(".cache").join("kinpost")))
}

/// This build of kinpost: its version and the size and modification time
/// of the running executable, so that a rebuilt binary never uses a model
/// fitted by older code. `None` when the executable cannot be examined.
pub fn build_identity() -> Option<String> {
    static ID: OnceLock<Option<String>> = OnceLock::new();
    ID.get_or_init(|| {
        let exe = std::env::current_exe().ok()?;
        let meta = std::fs::metadata(exe).ok()?;
        let t = meta.modified().ok()?.duration_since(UNIX_EPOCH).ok()?;
        Some(format!(
            "kinpost {}; executable of {} bytes modified at {}.{:09} s",
            env!("CARGO_PKG_VERSION"),
            meta.len(),
            t.as_secs(),
            t.subsec_nanos()
        ))
    })
    .clone()
}

/// 64-bit FNV-1a.
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The text of the regular file at `path` (not followed if a link), or
/// `None` for anything else, a file too large, or bytes not UTF-8.
fn read_regular_file(path: &Path) -> Option<String> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    if !meta.file_type().is_file() || meta.len() > MAX_ENTRY_BYTES {
        return None;
    }
    let f = std::fs::File::open(path).ok()?;
    let opened = f.metadata().ok()?;
    if !opened.is_file() || !crate::output::same_file(&meta, &opened) {
        return None;
    }
    let mut text = String::new();
    f.take(MAX_ENTRY_BYTES).read_to_string(&mut text).ok()?;
    Some(text)
}

/// Creates the cache directory (and its parents) if missing, private to the
/// user where the system has modes.
fn create_dir(dir: &Path) -> std::io::Result<()> {
    let mut b = std::fs::DirBuilder::new();
    b.recursive(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::DirBuilderExt;
        b.mode(0o700);
    }
    b.create(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<OsString> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| OsString::from(v))
        }
    }

    #[test]
    fn location_follows_the_environment() {
        let home = [("HOME", "/home/u")];
        assert_eq!(
            location_from(env(&home), false),
            Some(PathBuf::from("/home/u/.cache/kinpost"))
        );
        let xdg = [("HOME", "/home/u"), ("XDG_CACHE_HOME", "/var/c")];
        assert_eq!(
            location_from(env(&xdg), false),
            Some(PathBuf::from("/var/c/kinpost"))
        );
        let relative = [("HOME", "/home/u"), ("XDG_CACHE_HOME", "c")];
        assert_eq!(
            location_from(env(&relative), false),
            Some(PathBuf::from("/home/u/.cache/kinpost"))
        );
        let set = [("HOME", "/home/u"), (CACHE_DIR_VAR, "/tmp/kc")];
        assert_eq!(
            location_from(env(&set), false),
            Some(PathBuf::from("/tmp/kc"))
        );
        for off in ["off", "0", "none", "", "OFF"] {
            let v = [("HOME", "/home/u"), (CACHE_DIR_VAR, off)];
            assert_eq!(location_from(env(&v), false), None, "{off:?}");
        }
        assert_eq!(location_from(env(&[]), false), None);
        if cfg!(windows) {
            let w = [("LOCALAPPDATA", r"C:\Users\u\AppData\Local")];
            assert!(location_from(env(&w), true).is_some());
        }
        assert_eq!(location_from(env(&home), true), None);
    }

    #[test]
    fn entries_round_trip_and_check_their_key() {
        let d = tempfile::tempdir().unwrap();
        let cache = FitCache::new(d.path().join("sub"), "build 1");
        let key = cache.key(b"X,EXX\n0,1\n", "opts");
        assert!(cache.get(&key, "t.csv").is_none(), "empty cache");
        let origin = Origin(Some((Location::new("a.csv", 3, 1), "X,EXX".into())));
        let model = serde_json::json!({"format": "m", "x": [1.5, -0.0]});
        let path = cache.put(&key, &model, &[origin, Origin(None)]).unwrap();
        assert!(is_entry_name(&path.file_name().unwrap().to_string_lossy()));
        let hit = cache.get(&key, "b.csv").expect("hit");
        assert_eq!(
            serde_json::from_str::<serde_json::Value>(&hit.model).unwrap(),
            model
        );
        let (loc, text) = hit.origins[0].0.clone().unwrap();
        assert_eq!(
            (loc.to_string(), text.as_str()),
            ("b.csv:3:1".into(), "X,EXX")
        );
        assert!(hit.origins[1].0.is_none());
        // Another table, other options or another build: another key, a miss.
        assert_ne!(cache.key(b"X,EXX\n0,2\n", "opts"), key);
        assert_ne!(cache.key(b"X,EXX\n0,1\n", "other"), key);
        let other = FitCache::new(d.path().join("sub"), "build 2");
        assert!(
            other
                .get(&other.key(b"X,EXX\n0,1\n", "opts"), "t")
                .is_none()
        );
        // Same file name, different recorded length or hash: a miss.
        let mut forged = key.clone();
        forged.len += 1;
        assert!(cache.get(&forged, "t").is_none());
        let mut forged = key.clone();
        forged.fnv ^= 1;
        assert!(cache.get(&forged, "t").is_none());
        // Truncated: a miss.
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        assert!(cache.get(&key, "t").is_none());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_is_not_an_entry() {
        let d = tempfile::tempdir().unwrap();
        let cache = FitCache::new(d.path(), "b");
        let key = cache.key(b"t", "o");
        let model = serde_json::json!({});
        let path = cache.put(&key, &model, &[]).unwrap();
        let real = d.path().join("real.json");
        std::fs::rename(&path, &real).unwrap();
        std::os::unix::fs::symlink(&real, &path).unwrap();
        assert!(cache.get(&key, "t").is_none(), "a link is a miss");
        // Writing replaces the link, not its target.
        cache.put(&key, &model, &[]).unwrap();
        assert!(std::fs::symlink_metadata(&path).unwrap().is_file());
        assert!(cache.get(&key, "t").is_some());
    }

    #[test]
    fn fnv1a_known_values() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn entry_names() {
        assert!(is_entry_name("fit-0123456789abcdef.json"));
        assert!(!is_entry_name("fit-0123456789abcde.json"));
        assert!(!is_entry_name("fit-0123456789abcdeg.json"));
        assert!(!is_entry_name("other.json"));
    }
}
