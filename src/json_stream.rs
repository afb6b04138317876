//! Pretty JSON written as it is made: objects and arrays opened and closed
//! by the caller, their members written one at a time, in exactly the
//! layout of `serde_json::to_string_pretty` of the whole value (two spaces
//! a level; members in the order the caller gives them, which for the
//! same bytes as a `serde_json::Value` must be the alphabetical order of
//! its keys). A report of any length is then written in the memory of one
//! member.

use std::io::Write;

/// What is open at one level, and how many members it has so far.
#[derive(Debug, Clone, Copy)]
struct Level {
    array: bool,
    members: usize,
}

/// Writes one JSON value, member by member (see the module documentation).
pub struct PrettyWriter<W: Write> {
    out: W,
    open: Vec<Level>,
    buf: Vec<u8>,
}

impl<W: Write> PrettyWriter<W> {
    /// A writer to `out`, nothing open.
    pub fn new(out: W) -> Self {
        PrettyWriter {
            out,
            open: Vec::new(),
            buf: Vec::new(),
        }
    }

    /// Starts the next member of what is open: the separator, a new line
    /// and the indentation of its level (nothing at the top).
    fn next_member(&mut self) {
        if let Some(level) = self.open.last_mut() {
            self.buf
                .extend_from_slice(if level.members == 0 { b"\n" } else { b",\n" });
            level.members += 1;
            let pad = 2 * self.open.len();
            self.buf.extend(std::iter::repeat_n(b' ', pad));
        }
    }

    /// Opens an object (as the value of the key just written, an element
    /// of the array open, or the whole value).
    pub fn begin_object(&mut self) -> std::io::Result<()> {
        self.begin(false)
    }

    /// Opens an array (see [`PrettyWriter::begin_object`]).
    pub fn begin_array(&mut self) -> std::io::Result<()> {
        self.begin(true)
    }

    fn begin(&mut self, array: bool) -> std::io::Result<()> {
        self.in_array_member();
        self.buf.push(if array { b'[' } else { b'{' });
        self.open.push(Level { array, members: 0 });
        self.flush_buf()
    }

    /// In an array, a value starts a member of its own; after a key it does
    /// not.
    fn in_array_member(&mut self) {
        if self.open.last().is_some_and(|l| l.array) {
            self.next_member();
        }
    }

    /// Writes the key of the next member of the object open.
    pub fn key(&mut self, key: &str) -> std::io::Result<()> {
        debug_assert!(self.open.last().is_some_and(|l| !l.array));
        self.next_member();
        serde_json::to_writer(&mut self.buf, key).map_err(std::io::Error::other)?;
        self.buf.extend_from_slice(b": ");
        self.flush_buf()
    }

    /// Writes a whole value: after a key, as an element of the array open,
    /// or as the whole value.
    pub fn value<T: serde::Serialize + ?Sized>(&mut self, v: &T) -> std::io::Result<()> {
        self.in_array_member();
        // Through a `Value`, whose objects list their keys alphabetically.
        let v = serde_json::to_value(v).map_err(std::io::Error::other)?;
        let text = serde_json::to_string_pretty(&v).map_err(std::io::Error::other)?;
        let pad = 2 * self.open.len();
        for (i, line) in text.split('\n').enumerate() {
            if i > 0 {
                self.buf.push(b'\n');
                self.buf.extend(std::iter::repeat_n(b' ', pad));
            }
            self.buf.extend_from_slice(line.as_bytes());
        }
        self.flush_buf()
    }

    /// Closes what is open last.
    pub fn end(&mut self) -> std::io::Result<()> {
        if let Some(level) = self.open.pop() {
            if level.members > 0 {
                self.buf.push(b'\n');
                self.buf
                    .extend(std::iter::repeat_n(b' ', 2 * self.open.len()));
            }
            self.buf.push(if level.array { b']' } else { b'}' });
        }
        self.flush_buf()
    }

    /// Closes everything still open; returns the output.
    pub fn finish(mut self) -> std::io::Result<W> {
        while !self.open.is_empty() {
            self.end()?;
        }
        Ok(self.out)
    }

    fn flush_buf(&mut self) -> std::io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// The streamed bytes are those of `to_string_pretty` of the whole
    /// value, for nested objects and arrays, empty ones and scalars.
    #[test]
    fn streamed_is_pretty_printed_whole() {
        let whole = json!({
            "blocks": [{"a": 1.5, "b": [1, 2]}, {"a": -0.0, "b": []}],
            "empty": [],
            "inner": {"list": [{"x": null}], "n": 3, "none": {}},
            "name": "lens \"ring\"",
        });
        let mut w = PrettyWriter::new(Vec::new());
        w.begin_object().unwrap();
        w.key("blocks").unwrap();
        w.begin_array().unwrap();
        w.value(&json!({"b": [1, 2], "a": 1.5})).unwrap();
        w.value(&json!({"a": -0.0, "b": []})).unwrap();
        w.end().unwrap();
        w.key("empty").unwrap();
        w.begin_array().unwrap();
        w.end().unwrap();
        w.key("inner").unwrap();
        w.begin_object().unwrap();
        w.key("list").unwrap();
        w.begin_array().unwrap();
        w.begin_object().unwrap();
        w.key("x").unwrap();
        w.value(&json!(null)).unwrap();
        w.end().unwrap();
        w.end().unwrap();
        w.key("n").unwrap();
        w.value(&3).unwrap();
        w.key("none").unwrap();
        w.begin_object().unwrap();
        w.end().unwrap();
        w.end().unwrap();
        w.key("name").unwrap();
        w.value("lens \"ring\"").unwrap();
        let out = w.finish().unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            serde_json::to_string_pretty(&whole).unwrap()
        );
    }
}
