//! The INI file of a LinuxCNC configuration, read as LinuxCNC reads it:
//! sections, `KEY = VALUE` entries, `#INCLUDE` files, a value continued
//! on the next line by a trailing `\\`, and `[SECTION]KEY` references.

use crate::error::{Error, Location, Result};
use std::path::{Path, PathBuf};

/// One `KEY = VALUE` line of an INI file.
pub(super) struct IniEntry {
    pub(super) section: String,
    pub(super) key: String,
    pub(super) value: String,
    /// Index of the file it is in ([`Ini::sources`]).
    pub(super) source: usize,
    pub(super) line: usize,
    /// Byte column of the value (1-based).
    pub(super) col: usize,
}

impl IniEntry {
    /// The value read as LinuxCNC reads a number, a boolean or a unit
    /// (`IniFile::Find` with `sscanf`): what stands before a comment that
    /// follows it (`MAX_LIMIT = 110 ; soft limit`, `WRAPPED_ROTARY = 1 #
    /// indexing`), blanks trimmed. Real configurations write such
    /// comments; LinuxCNC's `sscanf` reads the number and ignores them.
    pub(super) fn before_comment(&self) -> &str {
        self.value.split([';', '#']).next().unwrap_or("").trim()
    }

    /// The value as a finite number ([`IniEntry::before_comment`]), or
    /// `None`.
    pub(super) fn number(&self) -> Option<f64> {
        self.before_comment()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
    }
}

/// One file of an INI: the INI itself or a file it includes.
pub(super) struct IniSource {
    pub(super) file: String,
    pub(super) text: String,
}

/// An INI file with the files it includes (`#INCLUDE`): its entries in
/// order.
pub(super) struct Ini {
    pub(super) sources: Vec<IniSource>,
    pub(super) entries: Vec<IniEntry>,
}

/// How deep `#INCLUDE` may nest, as in LinuxCNC.
pub(super) const MAX_INCLUDE_DEPTH: usize = 16;

impl Ini {
    /// Reads the INI at `path` and, where a line starts with `#INCLUDE `,
    /// the file it names, in its place (LinuxCNC's rule: a relative name is
    /// relative to the directory of the file that includes it, `~/` is the
    /// home directory; up to 16 levels; a file that includes itself is an
    /// error).
    pub(super) fn load(path: &Path) -> Result<Ini> {
        let mut ini = Ini {
            sources: Vec::new(),
            entries: Vec::new(),
        };
        let mut section = String::new();
        let mut stack = Vec::new();
        ini.read(path, &mut section, &mut stack)?;
        Ok(ini)
    }

    fn read(&mut self, path: &Path, section: &mut String, stack: &mut Vec<PathBuf>) -> Result<()> {
        let text = crate::text::read_text_file(path)?;
        let source = self.sources.len();
        let file = path.display().to_string();
        self.sources.push(IniSource {
            file: file.clone(),
            text,
        });
        stack.push(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()));
        let text = std::mem::take(&mut self.sources[source].text);
        for (n, raw) in logical_lines(&text) {
            let raw = raw.as_str();
            if let Some(rest) = raw.strip_prefix("#INCLUDE") {
                let at = Location::new(&file, n + 1, 1);
                self.include(path, rest, at, raw, section, stack)?;
                continue;
            }
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
                continue;
            }
            if line.starts_with('[') {
                if let Some(end) = line.find(']') {
                    *section = line[1..end].trim().to_ascii_uppercase();
                }
                continue;
            }
            if let Some((k, v)) = raw.split_once('=') {
                let value = v.trim();
                let col = raw.len() - v.trim_start().len() + 1;
                self.entries.push(IniEntry {
                    section: section.clone(),
                    key: k.trim().to_ascii_uppercase(),
                    value: value.to_string(),
                    source,
                    line: n + 1,
                    col,
                });
            }
        }
        self.sources[source].text = text;
        stack.pop();
        Ok(())
    }

    /// Reads the file of an `#INCLUDE` line (`rest` follows the directive)
    /// in the including file `from`.
    fn include(
        &mut self,
        from: &Path,
        rest: &str,
        at: Location,
        raw: &str,
        section: &mut String,
        stack: &mut Vec<PathBuf>,
    ) -> Result<()> {
        let fail = |msg: String| Error::input_with(at.clone(), msg, raw);
        let name = rest.trim();
        if !rest.starts_with([' ', '\t']) || name.is_empty() {
            return Err(fail(
                "`#INCLUDE` without a file name; expected `#INCLUDE file.inc`".into(),
            ));
        }
        let named = match (name.starts_with("~/"), home_path(name)) {
            (_, Some(path)) => path,
            (true, None) => return Err(fail(format!("`{name}`: HOME is not set"))),
            (false, None) => PathBuf::from(name),
        };
        let path = if named.is_absolute() {
            named
        } else {
            from.parent().unwrap_or(Path::new("")).join(named)
        };
        let key = std::fs::canonicalize(&path).unwrap_or_else(|_| path.clone());
        if stack.contains(&key) {
            return Err(fail(format!(
                "`{name}` includes itself (through {} files); expected includes without a loop",
                stack.len()
            )));
        }
        if stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(fail(format!(
                "`{name}`: includes nest deeper than {MAX_INCLUDE_DEPTH} levels, LinuxCNC's limit"
            )));
        }
        if !path.is_file() {
            let why = if path.is_dir() {
                "it is a directory"
            } else {
                "no such file"
            };
            return Err(fail(format!(
                "cannot include `{}`: {why}; expected a file (a relative name is relative to the directory of the file that includes it)",
                path.display()
            )));
        }
        self.read(&path, section, stack)
    }

    pub(super) fn all<'a>(
        &'a self,
        section: &'a str,
        key: &'a str,
    ) -> impl Iterator<Item = &'a IniEntry> {
        self.entries
            .iter()
            .filter(move |e| e.section == section && e.key == key)
    }

    pub(super) fn get(&self, section: &str, key: &str) -> Option<&IniEntry> {
        self.entries
            .iter()
            .find(|e| e.section == section && e.key == key)
    }

    /// The file an entry is in.
    pub(super) fn file_of(&self, e: &IniEntry) -> &str {
        &self.sources[e.source].file
    }

    pub(super) fn err(&self, e: &IniEntry, msg: impl Into<String>) -> Error {
        Error::input_with(
            Location::new(self.file_of(e), e.line, e.col),
            msg,
            self.sources[e.source]
                .text
                .lines()
                .nth(e.line - 1)
                .unwrap_or(""),
        )
    }
}

/// A file name that starts with `~/` under the home directory, as
/// LinuxCNC expands it (`None` for any other name, or without `HOME`).
pub(super) fn home_path(name: &str) -> Option<PathBuf> {
    let under_home = name.strip_prefix("~/")?;
    Some(PathBuf::from(std::env::var_os("HOME")?).join(under_home))
}

/// `[SECTION]KEY` → the INI's value; any other token as it is.
pub(super) fn resolve_ini_ref(ini: &Ini, tok: &str) -> Option<String> {
    let Some(rest) = tok.strip_prefix('[') else {
        return Some(tok.to_string());
    };
    let (section, key) = rest.split_once(']')?;
    // halcmd's other form: `[SECTION](KEY)`.
    let key = match key.strip_prefix('(') {
        Some(inner) => inner.strip_suffix(')')?,
        None => key,
    };
    ini.get(&section.to_ascii_uppercase(), &key.to_ascii_uppercase())
        .map(|e| e.value.clone())
}

/// The lines of an INI file as LinuxCNC reads them, each with the index of
/// its first physical line: a line whose text ends (trailing blanks
/// aside) with `\\` goes on in the next, the backslash and the line end
/// removed. A byte-order mark is not part of the first line's text.
pub(super) fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut lines = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (n, raw) in text.lines().enumerate() {
        let raw = if n == 0 {
            raw.trim_start_matches('\u{feff}')
        } else {
            raw
        };
        let (first, mut joined) = pending.take().unwrap_or((n, String::new()));
        match raw.trim_end().strip_suffix('\\') {
            Some(head) => {
                joined.push_str(head);
                pending = Some((first, joined));
            }
            None => {
                joined.push_str(raw);
                lines.push((first, joined));
            }
        }
    }
    // A continuation on the last line continues nothing.
    lines.extend(pending);
    lines
}
