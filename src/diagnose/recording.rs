//! Recordings (`formats.md` §2): commanded axes and measured tool tip, sample
//! by sample.
//!
//! ```text
//! t,block,X,Z,B,C,meas_x,meas_y,meas_z
//! 0.000,1,10.0,5.0,0.0,0.0,10.0011,0.0002,-14.9993
//! ```
//!
//! * `t` (s, strictly increasing) and `meas_x, meas_y, meas_z` (mm) are
//!   required, and one column per machine joint, named by its letter
//!   (mm or deg, case-insensitive).
//! * `block` (NC block / line number; an `N` prefix is accepted), the
//!   measured tool axis `meas_i, meas_j, meas_k` (all three or none) and
//!   temperatures `temp*` (°C) are optional. Other columns are ignored.
//! * Lines starting with `#` or `//` and blank lines are skipped; a byte-order
//!   mark and CRLF line ends are accepted.
//!
//! [`RecordingReader`] streams samples one line at a time;
//! [`Recording::parse`] collects them. Every problem is an [`Error`] naming
//! `file:line:col` and showing the offending text.

use std::io::{BufRead, Write};
use std::path::Path;

use super::csv::{Dialect, column_name};
use super::csv_lines::{Lines, read_header, read_units_row};
use crate::error::{Error, Location, Result};

/// One recorded sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Time since the start, s.
    pub t: f64,
    /// NC block (line number) the sample belongs to, if recorded.
    pub block: Option<u64>,
    /// Commanded positions in the machine's joint order (mm, deg).
    pub q: Vec<f64>,
    /// Measured tool tip in the workpiece frame, mm.
    pub meas: [f64; 3],
    /// Measured tool axis (unit vector), if recorded.
    pub meas_axis: Option<[f64; 3]>,
    /// Temperatures, °C, in the order of [`Recording::temp_names`].
    pub temps: Vec<f64>,
}

/// A whole recording.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Joint names in machine (chain) order; `Sample::q` follows it.
    pub axes: Vec<String>,
    /// Names of the temperature columns.
    pub temp_names: Vec<String>,
    /// Samples in time order.
    pub samples: Vec<Sample>,
}

/// Column layout found in a header.
#[derive(Debug, Clone)]
struct Layout {
    /// Separator and number form (`super::csv`).
    dialect: Dialect,
    /// Per field, the factor to the units of `formats.md` (a unit in the
    /// column's name; 1 without).
    factor: Vec<f64>,
    n_fields: usize,
    t: usize,
    block: Option<usize>,
    q: Vec<usize>,
    meas: [usize; 3],
    meas_axis: Option<[usize; 3]>,
    temps: Vec<usize>,
}

/// Streaming reader: yields one [`Sample`] per data line.
pub struct RecordingReader<R: BufRead> {
    lines: Lines<R>,
    layout: Layout,
    axes: Vec<String>,
    temp_names: Vec<String>,
    last_t: Option<f64>,
    done: bool,
    /// The current line is the first sample's, read with the header.
    pending: bool,
}

impl<R: BufRead> RecordingReader<R> {
    /// Reads the header of a recording for a machine with joints `axes`
    /// (chain order). Fails if a required column is missing.
    pub fn new(input: R, file: &str, axes: &[String]) -> Result<Self> {
        let mut lines = Lines::new(input, file);
        let head = read_header(&mut lines, "t,block,<axes>,meas_x,meas_y,meas_z")?;
        let (header_line, header) = (head.line, head.text.clone());
        let dialect = Dialect::of_header(&header);
        let fs = head.fields(dialect);
        let loc = |col: usize| Location::new(file, header_line, col);
        let mut factor = super::csv::factors(&fs)
            .map_err(|(i, msg)| Error::input_with(loc(fs[i].0), msg, header.clone()))?;
        let mut names: Vec<String> = Vec::new();
        for (col, f) in &fs {
            let (lower, _) = column_name(f);
            if !lower.is_empty() && names.contains(&lower) {
                return Err(Error::input_with(
                    loc(*col),
                    format!("column `{f}` appears twice in the header"),
                    header.clone(),
                ));
            }
            names.push(lower);
        }
        let find = |n: &str| names.iter().position(|c| c == n);
        let need = |n: &str, what: &str| {
            find(n).ok_or_else(|| {
                Error::input_with(
                    loc(1),
                    format!("the header has no `{n}` column ({what})"),
                    header.clone(),
                )
            })
        };
        let t = need("t", "time in seconds")?;
        let block = find("block");
        let mut q = Vec::with_capacity(axes.len());
        for a in axes {
            let idx = find(&a.to_ascii_lowercase()).ok_or_else(|| {
                Error::input_with(
                    loc(1),
                    format!(
                        "the header has no column for machine axis {a} (the machine's axes: {})",
                        axes.join(", ")
                    ),
                    header.clone(),
                )
            })?;
            q.push(idx);
        }
        let meas = [
            need("meas_x", "measured tool tip x, mm")?,
            need("meas_y", "measured tool tip y, mm")?,
            need("meas_z", "measured tool tip z, mm")?,
        ];
        let ijk = [find("meas_i"), find("meas_j"), find("meas_k")];
        let meas_axis = match ijk {
            [Some(i), Some(j), Some(k)] => Some([i, j, k]),
            [None, None, None] => None,
            _ => {
                return Err(Error::input_with(
                    loc(1),
                    "the measured tool axis needs all three columns meas_i, meas_j, meas_k",
                    header.clone(),
                ));
            }
        };
        // A units row under the header (`s,,mm,deg,…`): read and skipped.
        let pending = read_units_row(&mut lines, &head, dialect, &mut factor, Some(t))?;
        let mut temps = Vec::new();
        let mut temp_names = Vec::new();
        for (i, (_, f)) in fs.iter().enumerate() {
            if names[i].starts_with("temp") {
                temps.push(i);
                temp_names.push(f.split('[').next().unwrap_or(f).trim().to_string());
            }
        }
        Ok(RecordingReader {
            lines,
            layout: Layout {
                dialect,
                factor,
                n_fields: fs.len(),
                t,
                block,
                q,
                meas,
                meas_axis,
                temps,
            },
            axes: axes.to_vec(),
            temp_names,
            last_t: None,
            done: false,
            pending,
        })
    }

    /// Names of the temperature columns.
    pub fn temp_names(&self) -> &[String] {
        &self.temp_names
    }

    /// Whether the recording has a `block` column.
    pub fn has_blocks(&self) -> bool {
        self.layout.block.is_some()
    }

    fn parse_line(&mut self) -> Result<Sample> {
        let line = self.lines.buf.as_str();
        let fs = self.layout.dialect.fields(line);
        let loc = |col: usize| Location::new(self.lines.file.clone(), self.lines.line_no, col);
        if fs.len() < self.layout.n_fields {
            let col = line.len() + 1;
            return Err(Error::input_with(
                loc(col),
                format!(
                    "expected {} fields as in the header, found {}",
                    self.layout.n_fields,
                    fs.len()
                ),
                line.to_string(),
            ));
        }
        if let Some(&(col, f)) = fs[self.layout.n_fields..]
            .iter()
            .find(|(_, f)| !f.trim().is_empty())
        {
            return Err(Error::input_with(
                loc(col),
                super::csv_lines::beyond_header(self.layout.n_fields, f),
                line.to_string(),
            ));
        }
        let num = |idx: usize, what: &str| -> Result<f64> {
            let (col, f) = fs[idx];
            let v = self.layout.dialect.number(f).ok_or_else(|| {
                Error::input_with(
                    loc(col),
                    format!("{what}: `{f}` is not a number"),
                    line.to_string(),
                )
            })? * self.layout.factor[idx];
            if !v.is_finite() {
                return Err(Error::input_with(
                    loc(col),
                    format!("{what}: `{f}` is not a finite number"),
                    line.to_string(),
                ));
            }
            Ok(v)
        };
        let t = num(self.layout.t, "time t (s)")?;
        if let Some(prev) = self.last_t
            && t <= prev
        {
            return Err(Error::input_with(
                loc(fs[self.layout.t].0),
                format!("time must increase: t = {t} s after t = {prev} s"),
                line.to_string(),
            ));
        }
        let block = match self.layout.block {
            None => None,
            Some(idx) => {
                let (col, f) = fs[idx];
                if f.is_empty() {
                    None
                } else {
                    let digits = f.strip_prefix(['N', 'n']).unwrap_or(f);
                    let b = digits.parse::<u64>().ok().or_else(|| {
                        digits
                            .parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite() && *v >= 0.0 && v.fract() == 0.0)
                            .map(|v| v as u64)
                    });
                    match b {
                        Some(b) => Some(b),
                        None => {
                            return Err(Error::input_with(
                                loc(col),
                                format!(
                                    "block: `{f}` is not a block number (a non-negative integer)"
                                ),
                                line.to_string(),
                            ));
                        }
                    }
                }
            }
        };
        let mut q = Vec::with_capacity(self.layout.q.len());
        for (k, &idx) in self.layout.q.iter().enumerate() {
            q.push(num(idx, &format!("axis {}", self.axes[k]))?);
        }
        let m = self.layout.meas;
        let meas = [
            num(m[0], "meas_x (mm)")?,
            num(m[1], "meas_y (mm)")?,
            num(m[2], "meas_z (mm)")?,
        ];
        let meas_axis = match self.layout.meas_axis {
            None => None,
            Some([i, j, k]) => Some([num(i, "meas_i")?, num(j, "meas_j")?, num(k, "meas_k")?]),
        };
        let mut temps = Vec::with_capacity(self.layout.temps.len());
        for (k, &idx) in self.layout.temps.iter().enumerate() {
            temps.push(num(idx, &format!("temperature {}", self.temp_names[k]))?);
        }
        self.last_t = Some(t);
        Ok(Sample {
            t,
            block,
            q,
            meas,
            meas_axis,
            temps,
        })
    }
}

impl<R: BufRead> Iterator for RecordingReader<R> {
    type Item = Result<Sample>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        // The first sample's line may have been read with the header.
        if !std::mem::take(&mut self.pending) {
            match self.lines.next_data() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    return None;
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
        let r = self.parse_line();
        if r.is_err() {
            self.done = true;
        }
        Some(r)
    }
}

impl Recording {
    /// Parses a whole recording for a machine with joints `axes` (chain order).
    pub fn parse(text: &str, file: &str, axes: &[String]) -> Result<Recording> {
        Self::read(text.as_bytes(), file, axes)
    }

    /// Reads a recording from any buffered reader.
    pub fn read<R: BufRead>(input: R, file: &str, axes: &[String]) -> Result<Recording> {
        let reader = RecordingReader::new(input, file, axes)?;
        let temp_names = reader.temp_names().to_vec();
        let mut samples = Vec::new();
        for s in reader {
            samples.push(s?);
        }
        Ok(Recording {
            axes: axes.to_vec(),
            temp_names,
            samples,
        })
    }

    /// Loads a recording from a file.
    pub fn load(path: &Path, axes: &[String]) -> Result<Recording> {
        let name = path.display().to_string();
        crate::text::check_not_dir(path)?;
        let f = crate::output::open_input(path).map_err(|e| Error::io(name.clone(), e))?;
        Self::read(std::io::BufReader::new(f), &name, axes)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Writes the recording as CSV (`formats.md` §2). Times with 6 decimals,
    /// axes with 7, measured positions with 8 (0.01 nm), so a written and
    /// re-read recording diagnoses the same.
    pub fn write_csv<W: Write>(&self, mut w: W) -> std::io::Result<()> {
        let csv = RecordingCsv {
            axes: &self.axes,
            has_block: self.samples.iter().any(|s| s.block.is_some()),
            has_axis: self.samples.iter().any(|s| s.meas_axis.is_some()),
            temp_names: &self.temp_names,
        };
        csv.write_header(&mut w)?;
        for s in &self.samples {
            csv.write_sample(&mut w, s)?;
        }
        Ok(())
    }

    /// The recording as CSV text.
    pub fn to_csv_string(&self) -> String {
        let mut v = Vec::new();
        // Writing to a Vec cannot fail.
        let _ = self.write_csv(&mut v);
        String::from_utf8(v).unwrap_or_default()
    }
}

/// The columns of a recording's CSV (`formats.md` §2), for writing it a
/// sample at a time.
pub struct RecordingCsv<'a> {
    /// Axis names, machine order.
    pub axes: &'a [String],
    /// Whether there is a `block` column.
    pub has_block: bool,
    /// Whether there are measured tool-axis columns.
    pub has_axis: bool,
    /// Temperature columns.
    pub temp_names: &'a [String],
}

impl<'a> RecordingCsv<'a> {
    /// The columns of a simulated tool-tip recording of `axes`: time,
    /// block, the axes and the measured tip.
    pub fn tool_tip(axes: &'a [String]) -> Self {
        RecordingCsv {
            axes,
            has_block: true,
            has_axis: false,
            temp_names: &[],
        }
    }

    /// The header line.
    pub fn write_header<W: Write + ?Sized>(&self, w: &mut W) -> std::io::Result<()> {
        let mut header = String::from("t");
        if self.has_block {
            header.push_str(",block");
        }
        for a in self.axes {
            header.push(',');
            header.push_str(a);
        }
        header.push_str(",meas_x,meas_y,meas_z");
        if self.has_axis {
            header.push_str(",meas_i,meas_j,meas_k");
        }
        for t in self.temp_names {
            header.push(',');
            header.push_str(t);
        }
        writeln!(w, "{header}")
    }

    /// The line of sample `s`.
    pub fn write_sample<W: Write + ?Sized>(&self, w: &mut W, s: &Sample) -> std::io::Result<()> {
        let fx = crate::program::format::fixed;
        let mut line = String::new();
        line.push_str(&fx(s.t, 6));
        if self.has_block {
            line.push(',');
            if let Some(b) = s.block {
                line.push_str(&b.to_string());
            }
        }
        for v in &s.q {
            line.push(',');
            line.push_str(&fx(*v, 7));
        }
        for v in s.meas {
            line.push(',');
            line.push_str(&fx(v, 8));
        }
        if self.has_axis {
            let a = s.meas_axis.unwrap_or([0.0; 3]);
            for v in a {
                line.push(',');
                line.push_str(&fx(v, 10));
            }
        }
        for v in &s.temps {
            line.push(',');
            line.push_str(&fx(*v, 4));
        }
        writeln!(w, "{line}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes() -> Vec<String> {
        ["C", "X", "Z", "B"].iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn parses_the_spec_example() {
        let text = "# comment\nt,block,X,Z,B,C,meas_x,meas_y,meas_z\n0.000,1,10.0,5.0,0.0,0.0,10.0011,0.0002,-14.9993\n0.1,N2,10.5,5.0,0.0,1.0,10.5,0.0,-15\n";
        let r = Recording::parse(text, "r.csv", &axes()).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r.samples[0].q, vec![0.0, 10.0, 5.0, 0.0]);
        assert_eq!(r.samples[1].block, Some(2));
        assert_eq!(r.samples[0].meas, [10.0011, 0.0002, -14.9993]);
        let again = Recording::parse(&r.to_csv_string(), "w.csv", &axes()).unwrap();
        assert_eq!(again, r);
    }

    #[test]
    fn errors_are_located() {
        let h = "t,X,Z,B,C,meas_x,meas_y,meas_z\n";
        let e = Recording::parse(
            &format!("{h}0,1,2,3,4,5,6,7\n0,1,2,3,4,5,6,7\n"),
            "r.csv",
            &axes(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("r.csv:3:1:"), "{e}");
        assert!(e.contains("time must increase"), "{e}");
        let e = Recording::parse(&format!("{h}0,1,2,x3,4,5,6,7\n"), "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("r.csv:2:7:"), "{e}");
        assert!(e.contains("`x3`"), "{e}");
        let e = Recording::parse(&format!("{h}0,1,2,NaN,4,5,6,7\n"), "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a finite number"), "{e}");
        let e = Recording::parse("t,X,Z,C,meas_x,meas_y,meas_z\n", "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("machine axis B"), "{e}");
        let e = Recording::parse("t,X,Z,B,C,meas_x,meas_y\n", "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("meas_z"), "{e}");
        let e = Recording::parse(&format!("{h}0,1,2,3\n"), "r.csv", &axes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected 8 fields"), "{e}");
    }
}
