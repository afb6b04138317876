//! The run summary and the streamed JSON report of `compensate`.

use super::solver::BlockRecord;
use super::step::Method;

/// Writes the JSON report of a compensation run block by block, in the
/// layout of `serde_json::to_string_pretty` of
/// `{"blocks": [...], "summary": {...}, "warnings": [...]}` (keys in
/// alphabetical order): the blocks stream out as they are computed, the
/// summary and the warnings follow at the end, so memory stays flat.
pub struct ReportWriter<W: std::io::Write> {
    out: W,
    blocks: usize,
    buf: Vec<u8>,
    /// Keys of the per-axis values: the axis and its unit (`X_mm`, `C_deg`).
    axis_keys: Vec<String>,
    /// The axes in the alphabetical order of their keys.
    key_order: Vec<usize>,
}

/// A block as the report writes it: the record's fields in alphabetical
/// order, the compensation as an object keyed by axis and unit in
/// alphabetical order (the layout `serde_json::to_value` of the record
/// gives, without building the value).
struct BlockJson<'a> {
    record: &'a BlockRecord,
    keys: &'a [String],
    order: &'a [usize],
}

/// The pretty JSON of one block (not yet indented into the report).
fn block_text(r: &BlockRecord, keys: &[String], order: &[usize]) -> std::io::Result<Vec<u8>> {
    let mut text = Vec::with_capacity(640);
    let json = BlockJson {
        record: r,
        keys,
        order,
    };
    serde_json::to_writer_pretty(&mut text, &json).map_err(std::io::Error::other)?;
    Ok(text)
}

/// The per-axis values of a block, keyed (see [`BlockJson`]).
struct AxisValues<'a>(&'a BlockJson<'a>);

impl serde::Serialize for AxisValues<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let values = &self.0.record.compensation;
        let mut map = s.serialize_map(Some(values.len().min(self.0.keys.len())))?;
        for &k in self.0.order {
            if let Some(v) = values.get(k) {
                map.serialize_entry(&self.0.keys[k], v)?;
            }
        }
        map.end()
    }
}

impl serde::Serialize for BlockJson<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let r = self.record;
        let mut st = s.serialize_struct("BlockRecord", 9)?;
        st.serialize_field("compensation", &AxisValues(self))?;
        st.serialize_field("iterations", &r.iterations)?;
        st.serialize_field("line", &r.line)?;
        st.serialize_field(
            "orientation_error_before_urad",
            &r.orientation_error_before_urad,
        )?;
        st.serialize_field("orientation_residual_urad", &r.orientation_residual_urad)?;
        st.serialize_field(
            "orientation_residual_written_urad",
            &r.orientation_residual_written_urad,
        )?;
        st.serialize_field("tip_error_before_mm", &r.tip_error_before_mm)?;
        st.serialize_field("tip_residual_mm", &r.tip_residual_mm)?;
        st.serialize_field("tip_residual_written_mm", &r.tip_residual_written_mm)?;
        st.end()
    }
}

/// `values` (output order) as an object keyed by `keys`.
pub(super) fn by_axis(keys: &[String], values: serde_json::Value) -> serde_json::Value {
    match values {
        serde_json::Value::Array(a) => keys.iter().cloned().zip(a).collect(),
        other => other,
    }
}

impl<W: std::io::Write> ReportWriter<W> {
    /// Starts the report for `machine` (writes the opening of the blocks
    /// array). Per-axis values are objects keyed by axis and unit
    /// (`{"X_mm": …, "C_deg": …}`).
    pub fn new(mut out: W, machine: &crate::machine::Machine) -> std::io::Result<Self> {
        out.write_all(b"{\n  \"blocks\": [")?;
        let axis_keys: Vec<String> = machine
            .axes
            .iter()
            .map(|a| {
                let revolute = machine
                    .chain
                    .joints()
                    .get(a.joint)
                    .is_some_and(|j| j.kind == crate::machine::chain::JointKind::Revolute);
                format!("{}_{}", a.name, if revolute { "deg" } else { "mm" })
            })
            .collect();
        let mut key_order: Vec<usize> = (0..axis_keys.len()).collect();
        key_order.sort_by(|&a, &b| axis_keys[a].cmp(&axis_keys[b]));
        Ok(ReportWriter {
            out,
            blocks: 0,
            buf: Vec::with_capacity(512),
            axis_keys,
            key_order,
        })
    }

    /// Appends blocks, in order; their text is made on every core.
    pub fn blocks(&mut self, records: &[BlockRecord]) -> std::io::Result<()> {
        use rayon::prelude::*;
        let (keys, order) = (&self.axis_keys, &self.key_order);
        let texts: Vec<std::io::Result<Vec<u8>>> = records
            .par_iter()
            .map(|r| block_text(r, keys, order))
            .collect();
        for text in texts {
            let text = text?;
            self.buf.clear();
            self.buf
                .extend_from_slice(if self.blocks == 0 { b"\n" } else { b",\n" });
            // serde_json writes UTF-8.
            indent(
                &mut self.buf,
                std::str::from_utf8(&text).unwrap_or_default(),
                "    ",
                true,
            );
            self.out.write_all(&self.buf)?;
            self.blocks += 1;
        }
        Ok(())
    }

    /// Closes the blocks array and writes the summary and the warnings;
    /// returns the writer.
    pub fn finish(mut self, summary: &RunSummary, warnings: &[String]) -> std::io::Result<W> {
        let mut tail = Vec::new();
        tail.extend_from_slice(if self.blocks == 0 {
            b"]".as_slice()
        } else {
            b"\n  ]".as_slice()
        });
        let mut summary = serde_json::to_value(summary).map_err(std::io::Error::other)?;
        if let Some(obj) = summary.as_object_mut() {
            obj.remove("axes");
            if let Some(c) = obj.get_mut("compensation_range") {
                *c = by_axis(&self.axis_keys, c.take());
            }
        }
        for (key, v) in [
            ("summary", Ok(summary)),
            ("warnings", serde_json::to_value(warnings)),
        ] {
            let v = v.map_err(std::io::Error::other)?;
            let text = serde_json::to_string_pretty(&v).map_err(std::io::Error::other)?;
            tail.extend_from_slice(format!(",\n  \"{key}\": ").as_bytes());
            indent(&mut tail, &text, "  ", false);
        }
        tail.extend_from_slice(b"\n}");
        self.out.write_all(&tail)?;
        Ok(self.out)
    }
}

/// Appends `text` with every line indented by `pad` (the first line too when
/// `first`).
pub(super) fn indent(out: &mut Vec<u8>, text: &str, pad: &str, first: bool) {
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push(b'\n');
        }
        if i > 0 || first {
            out.extend_from_slice(pad.as_bytes());
        }
        out.extend_from_slice(line.as_bytes());
    }
}

/// Summary of a compensation run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunSummary {
    /// Machine name.
    pub machine: String,
    /// Step method.
    pub method: Method,
    /// Poses compensated.
    pub poses: usize,
    /// Largest tool-tip error before compensation, mm.
    pub tip_error_before_max_mm: f64,
    /// Largest tool-tip residual after compensation, mm.
    pub tip_residual_max_mm: f64,
    /// Largest orientation error before, µrad.
    pub orientation_error_before_max_urad: f64,
    /// Largest orientation residual after, µrad.
    pub orientation_residual_max_urad: f64,
    /// Largest tool-tip error of the words as written, mm.
    pub tip_residual_written_max_mm: f64,
    /// Largest orientation error of the words as written, µrad.
    pub orientation_residual_written_max_urad: f64,
    /// Blocks whose orientation error got worse (by more than 1e-9 µrad).
    pub orientation_worse_blocks: usize,
    /// Largest iteration count.
    pub iterations_max: usize,
    /// Mean iteration count.
    pub iterations_mean: f64,
    /// Per-axis compensation range [min, max], output order, mm / deg.
    pub compensation_range: Vec<[f64; 2]>,
    /// Axis names in output order.
    pub axes: Vec<String>,
}

impl RunSummary {
    /// Summarises per-block records.
    pub fn new(machine: &crate::machine::Machine, method: Method, records: &[BlockRecord]) -> Self {
        let mut s = RunSummary::start(machine, method);
        for r in records {
            s.add(r);
        }
        s.finish()
    }

    /// An empty summary, to be fed block by block with [`RunSummary::add`]
    /// and closed with [`RunSummary::finish`] (memory does not grow with the
    /// length of the program).
    pub fn start(machine: &crate::machine::Machine, method: Method) -> Self {
        RunSummary {
            machine: machine.name.clone(),
            method,
            poses: 0,
            tip_error_before_max_mm: 0.0,
            tip_residual_max_mm: 0.0,
            orientation_error_before_max_urad: 0.0,
            orientation_residual_max_urad: 0.0,
            tip_residual_written_max_mm: 0.0,
            orientation_residual_written_max_urad: 0.0,
            orientation_worse_blocks: 0,
            iterations_max: 0,
            iterations_mean: 0.0,
            compensation_range: vec![[f64::INFINITY, f64::NEG_INFINITY]; machine.axes.len()],
            axes: machine.axes.iter().map(|a| a.name.clone()).collect(),
        }
    }

    /// Adds one block (while open, `iterations_mean` holds the sum).
    pub fn add(&mut self, r: &BlockRecord) {
        let s = self;
        s.poses += 1;
        s.tip_error_before_max_mm = s.tip_error_before_max_mm.max(r.tip_error_before_mm);
        s.tip_residual_max_mm = s.tip_residual_max_mm.max(r.tip_residual_mm);
        s.tip_residual_written_max_mm =
            s.tip_residual_written_max_mm.max(r.tip_residual_written_mm);
        s.orientation_residual_written_max_urad = s
            .orientation_residual_written_max_urad
            .max(r.orientation_residual_written_urad);
        s.orientation_error_before_max_urad = s
            .orientation_error_before_max_urad
            .max(r.orientation_error_before_urad);
        s.orientation_residual_max_urad = s
            .orientation_residual_max_urad
            .max(r.orientation_residual_urad);
        if r.orientation_residual_urad > r.orientation_error_before_urad + 1e-9 {
            s.orientation_worse_blocks += 1;
        }
        s.iterations_max = s.iterations_max.max(r.iterations);
        s.iterations_mean += r.iterations as f64;
        for (k, c) in r.compensation.iter().enumerate() {
            s.compensation_range[k][0] = s.compensation_range[k][0].min(*c);
            s.compensation_range[k][1] = s.compensation_range[k][1].max(*c);
        }
    }

    /// Closes the summary (the mean iteration count, empty ranges).
    pub fn finish(mut self) -> Self {
        if self.poses > 0 {
            self.iterations_mean /= self.poses as f64;
        } else {
            self.compensation_range = vec![[0.0, 0.0]; self.axes.len()];
        }
        self
    }

    /// A report a person can read.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "kinpost compensate — machine {}, {} poses, method {:?}",
            self.machine, self.poses, self.method
        );
        let _ = writeln!(
            t,
            "  tool-tip error:    before max {:.4} µm  →  after max {:.3e} mm as written (solution {:.3e} mm)",
            self.tip_error_before_max_mm * 1e3,
            self.tip_residual_written_max_mm,
            self.tip_residual_max_mm
        );
        let _ = writeln!(
            t,
            "  orientation error: before max {:.4} µrad ({:.4} arcsec)  →  after max {:.4} µrad ({:.4} arcsec); {} blocks worse",
            self.orientation_error_before_max_urad,
            self.orientation_error_before_max_urad * 1e-6 * crate::analyze::ARCSEC_PER_RAD,
            self.orientation_residual_max_urad,
            self.orientation_residual_max_urad * 1e-6 * crate::analyze::ARCSEC_PER_RAD,
            self.orientation_worse_blocks
        );
        let _ = writeln!(
            t,
            "  Newton iterations: max {}, mean {:.2}",
            self.iterations_max, self.iterations_mean
        );
        for (name, r) in self.axes.iter().zip(&self.compensation_range) {
            let (unit, f) = if ["A", "B", "C"].contains(&name.as_str()) {
                ("µrad", 1e6 * std::f64::consts::PI / 180.0)
            } else {
                ("µm", 1e3)
            };
            let _ = writeln!(
                t,
                "  compensation {name}: {:.4} … {:.4} {unit}",
                r[0] * f,
                r[1] * f
            );
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block's text is what `serde_json::to_string_pretty` makes of the
    /// record as a value with the compensation keyed by axis (the layout
    /// the report promises), for axes out of alphabetical order, extreme
    /// and non-finite numbers.
    #[test]
    fn block_text_is_the_pretty_value() {
        let keys: Vec<String> = ["Z_mm", "X_mm", "C_deg", "B_deg"]
            .iter()
            .map(|k| k.to_string())
            .collect();
        let mut order: Vec<usize> = (0..keys.len()).collect();
        order.sort_by(|&a, &b| keys[a].cmp(&keys[b]));
        for (k, values) in [
            [1e-300, -0.0, 123456.789, f64::MIN_POSITIVE],
            [f64::NAN, 1.0, -2.5e-14, 3.0],
            [0.1, 0.2, 0.30000000000000004, -1e21],
        ]
        .into_iter()
        .enumerate()
        {
            let r = BlockRecord {
                line: 7 + k,
                iterations: k,
                tip_error_before_mm: values[0],
                tip_residual_mm: values[1],
                orientation_error_before_urad: values[2],
                orientation_residual_urad: values[3],
                tip_residual_written_mm: values[3] * 3.0,
                orientation_residual_written_urad: f64::INFINITY,
                written_is_bound: false,
                compensation: values.iter().copied().collect(),
            };
            let mut v = serde_json::to_value(&r).unwrap();
            let c = v.get_mut("compensation").unwrap();
            *c = by_axis(&keys, c.take());
            let want = serde_json::to_string_pretty(&v).unwrap();
            let got = block_text(&r, &keys, &order).unwrap();
            assert_eq!(String::from_utf8(got).unwrap(), want);
        }
    }
}
