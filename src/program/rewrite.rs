//! Rewriting a line: the pose words replaced by the machine's axis words,
//! TCP codes by their machine-coordinate equivalent, a RepRap checksum
//! computed again, everything else kept byte for byte.

use super::TcpCode;
use crate::gcode::{ItemKind, Line};

/// Rewrites `line` into `out`: the items in `replace` (sorted) are removed and
/// `words` is written where the first of them stood; TCP-on codes become
/// their machine-coordinate equivalent (`G49`, `TRAFOOF`) and the tool length
/// offset words that went with them are dropped. A RepRap checksum (`*n`,
/// the XOR of the line's bytes before it) is computed again over the new
/// bytes, off by as much as it was (a right one stays right; a wrong one,
/// which the firmware refuses, stays as wrong). All other bytes are kept.
pub fn rewrite(
    line: &Line,
    replace: &[usize],
    words: &[u8],
    tcp: &[TcpCode],
    drop: &[usize],
    out: &mut Vec<u8>,
) {
    // Kept bytes are copied in runs: items tile the line, so consecutive
    // kept items (and the spaces kept between them) are one range.
    let line_start = out.len();
    let mut run = Run::default();
    let mut pending_space: Option<(usize, usize)> = None;
    let mut swallow_space = false;
    let mut skip_arguments = false;
    let mut inserted = false;
    let mut next_replaced = replace.iter().copied().peekable();
    for (i, item) in line.items.iter().enumerate() {
        let span = (item.start, item.end);
        if matches!(item.kind, ItemKind::Space) {
            if std::mem::take(&mut swallow_space) {
                // The space after a word dropped at the start of the line
                // goes with it; the indentation before it stays pending.
                continue;
            }
            if let Some(p) = pending_space {
                run.keep(line, p, out);
            }
            pending_space = Some(span);
            continue;
        }
        swallow_space = false;
        if std::mem::take(&mut skip_arguments) {
            // The arguments of `TRAORI (1)` and the blank before them.
            pending_space = None;
            continue;
        }
        while next_replaced.next_if(|&r| r < i).is_some() {}
        if next_replaced.next_if_eq(&i).is_some() {
            if !inserted {
                inserted = true;
                if !words.is_empty() {
                    if let Some(p) = pending_space {
                        run.keep(line, p, out);
                    }
                    run.flush(line, out);
                    out.extend_from_slice(words);
                }
            }
            pending_space = None;
            continue;
        }
        if drop.contains(&i) {
            // A space before a dropped word goes with it, except at the
            // start of the line, where the space after it goes instead.
            let at_start = out.len() == line_start && run.is_empty();
            pending_space = pending_space.filter(|_| at_start);
            swallow_space = at_start;
            continue;
        }
        if let Some(p) = pending_space.take() {
            run.keep(line, p, out);
        }
        if let ItemKind::Checksum(given) = item.kind {
            run.flush(line, out);
            let xor = |bytes: &[u8]| bytes.iter().fold(0u32, |x, &b| x ^ u32::from(b));
            let off = xor(&line.bytes[..item.start]) ^ given;
            out.push(b'*');
            out.extend_from_slice(
                (xor(&out[line_start..out.len() - 1]) ^ off)
                    .to_string()
                    .as_bytes(),
            );
            continue;
        }
        match tcp
            .iter()
            .find(|c| matches!(c, TcpCode::FanucOn(k) | TcpCode::SiemensOn(k) if *k == i))
        {
            Some(TcpCode::FanucOn(_)) => {
                run.flush(line, out);
                // Keep the letter's case as written.
                let g = if line.item_bytes(item).first() == Some(&b'g') {
                    b"g49"
                } else {
                    b"G49"
                };
                out.extend_from_slice(g);
            }
            Some(TcpCode::SiemensOn(_)) => {
                run.flush(line, out);
                out.extend_from_slice(b"TRAFOOF");
                // `TRAORI (1)`: the arguments after a blank go with it.
                if matches!(item.kind, ItemKind::Keyword(_))
                    && super::block_words::spaced_arguments(line, i).is_some()
                {
                    skip_arguments = true;
                }
                // `TRAORI(1) ; comment` (an opaque item): the call is
                // replaced, what follows it kept.
                if matches!(item.kind, ItemKind::Opaque) {
                    let text = String::from_utf8_lossy(line.item_bytes(item));
                    if let Some(end) = super::opaque::call_len(&text) {
                        out.extend_from_slice(&line.item_bytes(item)[end..]);
                    }
                }
            }
            None => run.keep(line, span, out),
        }
    }
    if let Some(p) = pending_space {
        run.keep(line, p, out);
    }
    run.flush(line, out);
}

/// A range of a line's bytes waiting to be copied by [`rewrite`].
#[derive(Default)]
struct Run {
    start: usize,
    end: usize,
}

impl Run {
    fn is_empty(&self) -> bool {
        self.start == self.end
    }

    /// Keeps the bytes `span` of `line`: extends the run if they follow it,
    /// else copies the run out and starts a new one.
    fn keep(&mut self, line: &Line, span: (usize, usize), out: &mut Vec<u8>) {
        if span.0 != self.end || self.is_empty() {
            self.flush(line, out);
            self.start = span.0;
        }
        self.end = span.1;
    }

    /// Copies the run out.
    fn flush(&mut self, line: &Line, out: &mut Vec<u8>) {
        if self.start < self.end {
            out.extend_from_slice(&line.bytes[self.start..self.end]);
        }
        self.start = self.end;
    }
}
