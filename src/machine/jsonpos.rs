//! Finding where a value sits in JSON text, so that semantic errors in a
//! machine file can name a line and a column.
//!
//! `serde_json::Value` keeps no positions. The machine file is first parsed
//! by `serde_json` (which reports syntax errors with their position); for a
//! problem found later, this module walks the (then known to be valid) text
//! along a path of object keys and array indices and returns the byte offset
//! of the value, or of the key naming it.

/// One step of a path into a JSON document.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Seg {
    /// A member of an object.
    Key(String),
    /// An element of an array.
    Index(usize),
}

/// What to point at when the path is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Target {
    /// The value at the end of the path.
    Value,
    /// The key that names the value at the end of the path (falls back to the
    /// value for array elements).
    Key,
}

struct Scan<'t> {
    b: &'t [u8],
    i: usize,
}

impl Scan<'_> {
    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    fn ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\r' | b'\n')) {
            self.i += 1;
        }
    }

    /// Reads a string starting at the opening quote; returns its content
    /// with the common escapes resolved.
    fn string(&mut self) -> Option<String> {
        if self.peek() != Some(b'"') {
            return None;
        }
        self.i += 1;
        let mut out = Vec::new();
        loop {
            let c = self.peek()?;
            self.i += 1;
            match c {
                b'"' => return String::from_utf8(out).ok(),
                b'\\' => {
                    let e = self.peek()?;
                    self.i += 1;
                    match e {
                        b'n' => out.push(b'\n'),
                        b't' => out.push(b'\t'),
                        b'r' => out.push(b'\r'),
                        b'b' => out.push(8),
                        b'f' => out.push(12),
                        b'u' => {
                            let hex = self.b.get(self.i..self.i + 4)?;
                            self.i += 4;
                            let mut code =
                                u32::from_str_radix(std::str::from_utf8(hex).ok()?, 16).ok()?;
                            // A surrogate pair (`\ud83d\ude00`) is one character.
                            if (0xD800..0xDC00).contains(&code)
                                && self.b.get(self.i..self.i + 2) == Some(b"\\u")
                                && let Some(low) = self
                                    .b
                                    .get(self.i + 2..self.i + 6)
                                    .and_then(|h| std::str::from_utf8(h).ok())
                                    .and_then(|h| u32::from_str_radix(h, 16).ok())
                                    .filter(|l| (0xDC00..0xE000).contains(l))
                            {
                                self.i += 6;
                                code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
                            }
                            let ch = char::from_u32(code).unwrap_or('\u{fffd}');
                            let mut buf = [0u8; 4];
                            out.extend_from_slice(ch.encode_utf8(&mut buf).as_bytes());
                        }
                        other => out.push(other),
                    }
                }
                other => out.push(other),
            }
        }
    }

    fn skip_value(&mut self) -> Option<()> {
        self.ws();
        match self.peek()? {
            b'"' => self.string().map(|_| ()),
            open @ (b'{' | b'[') => {
                let close = if open == b'{' { b'}' } else { b']' };
                self.i += 1;
                loop {
                    self.ws();
                    match self.peek()? {
                        c if c == close => {
                            self.i += 1;
                            return Some(());
                        }
                        b',' => self.i += 1,
                        b':' => self.i += 1,
                        _ => self.skip_value()?,
                    }
                }
            }
            _ => {
                while let Some(c) = self.peek() {
                    if matches!(c, b',' | b']' | b'}' | b' ' | b'\t' | b'\r' | b'\n') {
                        break;
                    }
                    self.i += 1;
                }
                Some(())
            }
        }
    }

    /// Positions the scanner at the value of member `key` of the object
    /// starting here; returns the key's offset.
    fn member(&mut self, key: &str) -> Option<usize> {
        self.ws();
        if self.peek()? != b'{' {
            return None;
        }
        self.i += 1;
        loop {
            self.ws();
            match self.peek()? {
                b'}' => return None,
                b',' => {
                    self.i += 1;
                    continue;
                }
                _ => {}
            }
            let key_at = self.i;
            let name = self.string()?;
            self.ws();
            if self.peek()? != b':' {
                return None;
            }
            self.i += 1;
            self.ws();
            if name == key {
                return Some(key_at);
            }
            self.skip_value()?;
        }
    }

    /// Positions the scanner at element `n` of the array starting here.
    fn element(&mut self, n: usize) -> Option<()> {
        self.ws();
        if self.peek()? != b'[' {
            return None;
        }
        self.i += 1;
        let mut k = 0;
        loop {
            self.ws();
            match self.peek()? {
                b']' => return None,
                b',' => {
                    self.i += 1;
                    continue;
                }
                _ => {}
            }
            if k == n {
                return Some(());
            }
            self.skip_value()?;
            k += 1;
        }
    }
}

/// The first key that appears twice in one object of `text` (valid JSON):
/// the byte offset of its second occurrence and the key. `serde_json`
/// keeps the last of duplicate keys silently; machine and model files
/// refuse them instead. One pass over the text (linear in its length).
pub(crate) fn first_duplicate_key(text: &str) -> Option<(usize, String)> {
    let mut s = Scan {
        b: text.as_bytes(),
        i: 0,
    };
    match s.dup_in_value() {
        Dup::Found(at, k) => Some((at, k)),
        Dup::None | Dup::Malformed => None,
    }
}

/// Outcome of the duplicate-key scan of one value.
enum Dup {
    None,
    Found(usize, String),
    Malformed,
}

impl Scan<'_> {
    fn dup_in_value(&mut self) -> Dup {
        self.ws();
        match self.peek() {
            None => Dup::Malformed,
            Some(b'{') => {
                self.i += 1;
                let mut seen = std::collections::HashSet::new();
                loop {
                    self.ws();
                    match self.peek() {
                        None => return Dup::Malformed,
                        Some(b'}') => {
                            self.i += 1;
                            return Dup::None;
                        }
                        Some(b',') => {
                            self.i += 1;
                            continue;
                        }
                        _ => {}
                    }
                    let key_at = self.i;
                    let Some(name) = self.string() else {
                        return Dup::Malformed;
                    };
                    if !seen.insert(name.clone()) {
                        return Dup::Found(key_at, name);
                    }
                    self.ws();
                    if self.peek() != Some(b':') {
                        return Dup::Malformed;
                    }
                    self.i += 1;
                    match self.dup_in_value() {
                        Dup::None => {}
                        other => return other,
                    }
                }
            }
            Some(b'[') => {
                self.i += 1;
                loop {
                    self.ws();
                    match self.peek() {
                        None => return Dup::Malformed,
                        Some(b']') => {
                            self.i += 1;
                            return Dup::None;
                        }
                        Some(b',') => {
                            self.i += 1;
                            continue;
                        }
                        _ => {}
                    }
                    match self.dup_in_value() {
                        Dup::None => {}
                        other => return other,
                    }
                }
            }
            Some(_) => match self.skip_value() {
                Some(()) => Dup::None,
                None => Dup::Malformed,
            },
        }
    }
}

/// Byte offset of the value (or key) at `path` in `text`. When the path
/// cannot be followed to its end, the offset of the deepest value reached
/// (for example the object that lacks a required key) is returned.
pub(crate) fn locate(text: &str, path: &[Seg], target: Target) -> usize {
    let mut s = Scan {
        b: text.as_bytes(),
        i: 0,
    };
    s.ws();
    let mut best = s.i;
    for (depth, seg) in path.iter().enumerate() {
        let last = depth + 1 == path.len();
        match seg {
            Seg::Key(k) => match s.member(k) {
                Some(key_at) => {
                    best = if last && target == Target::Key {
                        key_at
                    } else {
                        s.i
                    };
                }
                None => return best,
            },
            Seg::Index(n) => match s.element(*n) {
                Some(()) => best = s.i,
                None => return best,
            },
        }
    }
    best
}

/// 1-based line and column (byte offset within the line + 1) of `offset`.
pub(crate) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&c| c == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|&c| c == b'\n')
        .map_or(0, |p| p + 1);
    (line, offset - line_start + 1)
}

/// The text of line `line` (1-based), without its line break.
pub(crate) fn line_text(text: &str, line: usize) -> &str {
    text.lines().nth(line.saturating_sub(1)).unwrap_or("")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(k: &str) -> Seg {
        Seg::Key(k.to_string())
    }

    #[test]
    fn finds_nested_values_and_keys() {
        let text = "{\n  \"a\": [1, {\"b\": \"x\\\"y\"}, {\"c\": [true, null]}],\n  \"d\": {\"e\": 5}\n}\n";
        let at = locate(
            text,
            &[key("a"), Seg::Index(2), key("c"), Seg::Index(1)],
            Target::Value,
        );
        assert_eq!(&text[at..at + 4], "null");
        let at = locate(text, &[key("d"), key("e")], Target::Key);
        assert_eq!(line_col(text, at), (3, 9));
        // Missing key: the containing object.
        let at = locate(text, &[key("d"), key("zz")], Target::Value);
        assert_eq!(&text[at..at + 1], "{");
        assert_eq!(line_col(text, at), (3, 8));
        assert_eq!(line_text(text, 3), "  \"d\": {\"e\": 5}");
    }

    #[test]
    fn finds_the_second_of_duplicate_keys() {
        let text = "{\"a\": {\"min\": 1, \"max\": 2},\n \"b\": [{\"x\": 1}, {\"x\": 2, \"y\": {\"max\": 3, \"max\": 300}}]}";
        let (at, k) = first_duplicate_key(text).unwrap();
        assert_eq!(k, "max");
        assert_eq!(line_col(text, at), (2, 43));
        assert_eq!(first_duplicate_key("{\"a\": 1, \"b\": {\"a\": 2}}"), None);
        // Escaped spellings of the same key are the same key.
        assert!(first_duplicate_key("{\"a\": 1, \"\\u0061\": 2}").is_some());
        // Different characters outside the BMP are different keys.
        assert_eq!(
            first_duplicate_key("{\"\\ud83d\\ude00\": 1, \"\\ud83d\\ude01\": 2}"),
            None
        );
        assert!(first_duplicate_key("{\"\\ud83d\\ude00\": 1, \"\u{1F600}\": 2}").is_some());
    }
}
