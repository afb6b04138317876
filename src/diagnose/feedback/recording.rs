//! The joint-feedback CSV of `formats.md` §2b: reader and writer.

// Numerical code: several parallel arrays are indexed by one counter.
#![allow(clippy::needless_range_loop)]

use std::io::{BufRead, Write};

use super::super::csv::{Dialect, column_name, factors};
use super::super::csv_lines::{Lines, read_header, read_units_row};
use crate::error::{Error, Location, Result};

/// A joint-feedback recording: per traced axis, command and feedback.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeedbackRecording {
    /// Traced axes (those with an `fb_` column), machine order.
    pub axes: Vec<String>,
    /// Whether each traced axis is rotary (values in degrees).
    pub rotary: Vec<bool>,
    /// Time of each sample, s.
    pub t: Vec<f64>,
    /// Block of each sample, when recorded.
    pub block: Vec<Option<u64>>,
    /// Commanded position per axis, per sample (mm or deg).
    pub cmd: Vec<Vec<f64>>,
    /// Fed-back position per axis, per sample (mm or deg).
    pub fb: Vec<Vec<f64>>,
    /// Time was made from `--sample-rate` (no `t` column).
    pub time_from_rate: bool,
}

/// Whether a header line is that of a joint-feedback recording: it has an
/// `fb_` column and no `meas_x`.
pub fn is_feedback_header(header: &str) -> bool {
    let names: Vec<String> = Dialect::of_header(header)
        .fields(header)
        .iter()
        .map(|(_, f)| column_name(f).0)
        .collect();
    names.iter().any(|n| n.starts_with("fb_")) && !names.iter().any(|n| n == "meas_x")
}

/// The header of the recording read from `input` (a header written as a
/// comment included); `None` where none is found (the recording's reader
/// then says why).
pub fn header_line<R: BufRead>(input: R, file: &str) -> Option<String> {
    read_header(&mut Lines::new(input, file), "")
        .ok()
        .map(|h| h.text)
}

impl FeedbackRecording {
    /// Reads a joint-feedback recording for a machine with joints `axes`
    /// (`rotary` tells which are rotary). Without a `t` column the time is
    /// `i / sample_rate_hz`.
    pub fn read<R: BufRead>(
        input: R,
        file: &str,
        axes: &[String],
        rotary: &[bool],
        sample_rate_hz: Option<f64>,
    ) -> Result<FeedbackRecording> {
        let mut lines = Lines::new(input, file);
        let head = read_header(&mut lines, "t,block,<axes>,fb_<axis>,…")?;
        let (line_no, header) = (head.line, head.text.clone());
        let dialect = Dialect::of_header(&header);
        let hf = head.fields(dialect);
        let names: Vec<String> = hf.iter().map(|(_, f)| column_name(f).0).collect();
        let hloc = |col: usize| Location::new(file, line_no, col);
        let mut factor = factors(&hf)
            .map_err(|(i, msg)| Error::input_with(hloc(hf[i].0), msg, header.clone()))?;
        let find = |n: &str| names.iter().position(|c| c == n);
        let mut traced: Vec<(usize, usize, usize)> = Vec::new(); // (joint, cmd col, fb col)
        for (k, n) in names.iter().enumerate() {
            let Some(a) = n.strip_prefix("fb_") else {
                continue;
            };
            let Some(j) = axes.iter().position(|x| x.eq_ignore_ascii_case(a)) else {
                return Err(Error::input_with(
                    hloc(hf[k].0),
                    format!(
                        "`{}`: {} is not an axis of the machine (its axes: {})",
                        hf[k].1,
                        a.to_ascii_uppercase(),
                        axes.join(", ")
                    ),
                    header.clone(),
                ));
            };
            let c = find(a).ok_or_else(|| {
                Error::input_with(
                    hloc(hf[k].0),
                    format!(
                        "`{}` has no commanded column `{}` beside it",
                        hf[k].1, axes[j]
                    ),
                    header.clone(),
                )
            })?;
            if traced.iter().any(|x| x.0 == j) {
                return Err(Error::input_with(
                    hloc(hf[k].0),
                    format!("`{}` appears twice in the header", hf[k].1),
                    header.clone(),
                ));
            }
            traced.push((j, c, k));
        }
        if traced.is_empty() {
            return Err(Error::input_with(
                hloc(1),
                "a joint-feedback recording needs at least one `fb_<axis>` column",
                header.clone(),
            ));
        }
        traced.sort_by_key(|x| x.0);
        let t_col = find("t");
        let rate = match (t_col, sample_rate_hz) {
            (Some(_), _) => None,
            (None, Some(r)) if r.is_finite() && r > 0.0 => Some(r),
            (None, Some(r)) => {
                return Err(Error::Usage(format!(
                    "--sample-rate {r}: expected a rate above 0 Hz"
                )));
            }
            (None, None) => {
                return Err(Error::input_with(
                    hloc(1),
                    "the trace has no `t` column: give its sample rate with --sample-rate HZ",
                    header.clone(),
                ));
            }
        };
        let block_col = find("block");
        let n_ax = traced.len();
        let mut rec = FeedbackRecording {
            axes: traced.iter().map(|x| axes[x.0].clone()).collect(),
            rotary: traced
                .iter()
                .map(|x| rotary.get(x.0).copied().unwrap_or(false))
                .collect(),
            cmd: vec![Vec::new(); n_ax],
            fb: vec![Vec::new(); n_ax],
            time_from_rate: rate.is_some(),
            ..Default::default()
        };
        // A units row under the header (`s,,mm,deg,…`): read and skipped.
        let mut pending = read_units_row(&mut lines, &head, dialect, &mut factor, t_col)?;
        while std::mem::take(&mut pending) || lines.next_data()? {
            let line = lines.buf.as_str();
            let fs = dialect.fields(line);
            let loc = |col: usize| Location::new(file, lines.line_no, col);
            if fs.len() < hf.len() {
                return Err(Error::input_with(
                    loc(line.len() + 1),
                    format!(
                        "expected {} fields as in the header, found {}",
                        hf.len(),
                        fs.len()
                    ),
                    line,
                ));
            }
            if let Some(&(col, f)) = fs[hf.len()..].iter().find(|(_, f)| !f.trim().is_empty()) {
                return Err(Error::input_with(
                    loc(col),
                    super::super::csv_lines::beyond_header(hf.len(), f),
                    line,
                ));
            }
            let num = |idx: usize, what: &str| -> Result<f64> {
                let (col, f) = fs[idx];
                match dialect.number(f).map(|v| v * factor[idx]) {
                    Some(v) if v.is_finite() => Ok(v),
                    _ => Err(Error::input_with(
                        loc(col),
                        format!("{what}: `{f}` is not a finite number"),
                        line,
                    )),
                }
            };
            let t = match (t_col, rate) {
                (Some(c), _) => num(c, "time t (s)")?,
                (None, Some(r)) => rec.t.len() as f64 / r,
                (None, None) => unreachable!("checked above"),
            };
            if let Some(&prev) = rec.t.last()
                && t <= prev
            {
                return Err(Error::input_with(
                    loc(t_col.map_or(1, |c| fs[c].0)),
                    format!(
                        "time must increase: t = {t} s after t = {prev} s (repeated or out-of-order samples)"
                    ),
                    line,
                ));
            }
            let block = match block_col {
                Some(c) if !fs[c].1.is_empty() => {
                    let f = fs[c].1;
                    let digits = f.strip_prefix(['N', 'n']).unwrap_or(f);
                    Some(digits.parse::<u64>().map_err(|_| {
                        Error::input_with(
                            loc(fs[c].0),
                            format!("block: `{f}` is not a block number"),
                            line,
                        )
                    })?)
                }
                _ => None,
            };
            for (k, &(j, c, f)) in traced.iter().enumerate() {
                rec.cmd[k].push(num(c, &format!("axis {}", axes[j]))?);
                rec.fb[k].push(num(f, &format!("fb_{}", axes[j]))?);
            }
            rec.t.push(t);
            rec.block.push(block);
        }
        Ok(rec)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether it has no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Writes the CSV of `formats.md` §2b: `t,block,<axes>,fb_<axes>`.
    pub fn write_csv<W: Write>(&self, mut w: W) -> std::io::Result<()> {
        write_feedback_header(&mut w, &self.axes)?;
        for i in 0..self.len() {
            let cmd: Vec<f64> = self.cmd.iter().map(|c| c[i]).collect();
            let fb: Vec<f64> = self.fb.iter().map(|f| f[i]).collect();
            write_feedback_row(&mut w, self.t[i], self.block[i], &cmd, &fb)?;
        }
        Ok(())
    }
}

/// The header line of a joint-feedback CSV of the traced `axes`.
pub fn write_feedback_header<W: Write + ?Sized>(w: &mut W, axes: &[String]) -> std::io::Result<()> {
    let mut head = vec!["t".to_string(), "block".to_string()];
    head.extend(axes.iter().cloned());
    head.extend(axes.iter().map(|a| format!("fb_{a}")));
    writeln!(w, "{}", head.join(","))
}

/// One sample's line of a joint-feedback CSV: time (s), block, then the
/// command and the feedback of each axis (mm or deg).
pub fn write_feedback_row<W: Write + ?Sized>(
    w: &mut W,
    t: f64,
    block: Option<u64>,
    cmd: &[f64],
    fb: &[f64],
) -> std::io::Result<()> {
    let mut line = format!("{t:.6},");
    if let Some(b) = block {
        line.push_str(&b.to_string());
    }
    for v in cmd {
        line.push_str(&format!(",{v:.7}"));
    }
    for v in fb {
        line.push_str(&format!(",{v:.7}"));
    }
    writeln!(w, "{line}")
}
