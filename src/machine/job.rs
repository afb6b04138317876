//! The job set-up: the tool and the work offset of one job, applied to the
//! machine's chain without editing the machine file.
//!
//! A machine file's chain runs from the workpiece frame W to the tool tip
//! of the tool the file declares with `tool_length` (mm, default 0: the
//! chain ends at the gauge line, the spindle nose or tool flange point the
//! tool length is measured from). The job set-up makes the chain the job
//! needs, once, before any command converts or evaluates a pose:
//!
//! - the tool: the job's tool of length L replaces the file's tool of
//!   length T: `translate [0, 0, T − L]` appended, so the tool tip lies L mm
//!   along the tool axis (away from the spindle) beyond the gauge line; it
//!   turns with a head like the rest of the chain's end;
//! - the work offset `o` (the program's origin in W, mm): `translate −o`
//!   put in front, so the chain gives the pose in the program's frame, whose
//!   axes are W's: a program point `p` is the point `p + o` of W.
//!
//! Every command that takes a machine gets the same chain, so `post`,
//! `compensate`, `analyze`, `linkage` and `simulate` agree (the inverse
//! kinematics, the error-aware chain, the nonlinear error all see the tool
//! tip). The tool table (LinuxCNC's format) gives the length of the tool
//! the program selects: the `H` word of `G43`/`G43.4`/`G43.5`, or, without
//! one, the `T` word of the last tool change (`M6`).

use crate::error::{Error, Location, Result};
use crate::gcode::{ItemKind, LineReader};
use crate::machine::Machine;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::io::BufRead;

/// One tool of a tool table.
#[derive(Debug, Clone, PartialEq)]
pub struct Tool {
    /// Tool number (`T`).
    pub number: u32,
    /// Length offset (`Z`), mm.
    pub length_mm: f64,
    /// 1-based line of the table it was read from.
    pub line: usize,
}

/// A LinuxCNC tool table: lines `T1 P1 Z+0.500000 D0.125 ;comment`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ToolTable {
    /// The table's file name, for messages.
    pub file: String,
    /// The tools by number.
    pub tools: BTreeMap<u32, Tool>,
}

impl ToolTable {
    /// Parses a tool table. `mm_per_unit` scales its lengths to mm (1 for a
    /// table in mm, 25.4 for one in inch). Each non-empty line (after a
    /// `;` comment is cut off) must have a `T` word with a whole tool number
    /// ≥ 0; `Z` is its length (0 when absent); `P` (pocket), `D`
    /// (diameter), `X Y U V W A B C` (other offsets), `I J Q` (lathe) are
    /// read and ignored. Any other word, a number that does not parse, a
    /// tool given twice are errors naming file:line:col.
    pub fn parse(text: &str, file: &str, mm_per_unit: f64) -> Result<ToolTable> {
        let mut table = ToolTable {
            file: file.to_string(),
            tools: BTreeMap::new(),
        };
        // A Windows editor's byte-order mark, as machine files and error
        // tables accept it.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let content = raw.split(';').next().unwrap_or("");
            if content.trim().is_empty() {
                continue;
            }
            let err = |col: usize, msg: String| {
                Error::input_with(Location::new(file, line, col), msg, raw)
            };
            let mut number = None;
            let mut length = 0.0;
            let mut seen = String::new();
            let bytes = content.as_bytes();
            let mut k = 0;
            while k < bytes.len() {
                if bytes[k].is_ascii_whitespace() {
                    k += 1;
                    continue;
                }
                let start = k;
                let letter = (bytes[k] as char).to_ascii_uppercase();
                k += 1;
                while k < bytes.len() && !bytes[k].is_ascii_whitespace() {
                    k += 1;
                }
                // A word starts with an ASCII letter (checked before its
                // value is cut after that letter: `Ø6mm` starts with a
                // two-byte character).
                if !bytes[start].is_ascii_alphabetic() || !"TPZDXYUVWABCIJQ".contains(letter) {
                    return Err(err(
                        start + 1,
                        format!(
                            "`{}` is not a tool-table word; expected T, P, X, Y, Z, A, B, C, U, V, W, D, I, J, Q (LinuxCNC's format: `T1 P1 Z+0.5 D0.125 ;comment`)",
                            &content[start..k]
                        ),
                    ));
                }
                if seen.contains(letter) {
                    return Err(err(
                        start + 1,
                        format!("word {letter} is given twice on this line"),
                    ));
                }
                seen.push(letter);
                let value_text = &content[start + 1..k];
                let value: f64 = value_text
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| {
                        err(
                            start + 1,
                            format!(
                                "malformed number `{}`; expected a number such as {letter}0.5",
                                &content[start..k]
                            ),
                        )
                    })?;
                match letter {
                    'T' => {
                        if value < 0.0 || value.fract() != 0.0 || value > u32::MAX as f64 {
                            return Err(err(
                                start + 1,
                                format!("tool number {value_text} is not a whole number ≥ 0"),
                            ));
                        }
                        number = Some((value as u32, start + 1));
                    }
                    'Z' => length = value * mm_per_unit,
                    _ => {}
                }
            }
            let Some((n, col)) = number else {
                return Err(err(
                    1,
                    "a tool-table line without a T word; expected `T<number> P<pocket> Z<length> …`"
                        .into(),
                ));
            };
            if let Some(first) = table.tools.get(&n) {
                return Err(err(
                    col,
                    format!("tool T{n} is given twice (first on line {})", first.line),
                ));
            }
            table.tools.insert(
                n,
                Tool {
                    number: n,
                    length_mm: length,
                    line,
                },
            );
        }
        Ok(table)
    }
}

/// Where the tool length comes from.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum ToolChoice {
    /// The machine file's chain as it is (its end is the tool tip).
    #[default]
    MachineFile,
    /// A given length, mm.
    Length(f64),
    /// A tool table: the program selects the tool.
    Table(ToolTable),
}

/// The set-up of one job: tool and work offset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JobSetup {
    /// The tool.
    pub tool: ToolChoice,
    /// The program's origin in the machine file's workpiece frame W, mm.
    pub work_offset_mm: Vector3<f64>,
}

/// The tool a program selects, found by [`JobSetup::selected_tool`].
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The tool's number in the table.
    pub tool: u32,
    /// Its length, mm.
    pub length_mm: f64,
    /// Where the program selects it.
    pub at: Location,
    /// The line that selects it, as written (for messages).
    pub text: String,
}

impl JobSetup {
    /// Whether the set-up changes nothing.
    pub fn is_identity(&self) -> bool {
        self.tool == ToolChoice::MachineFile && self.work_offset_mm == Vector3::zeros()
    }

    /// The machine of the job: `base` with the work offset in front of its
    /// chain and a tool of `tool_length_mm` at its end (None: the chain's
    /// end is the tool tip, nothing appended). Its name and description
    /// say what was added.
    pub fn machine(&self, base: &Machine, tool_length_mm: Option<f64>) -> Machine {
        let mut m = base.clone();
        let mut notes = Vec::new();
        if self.work_offset_mm != Vector3::zeros() {
            let o = self.work_offset_mm;
            m.chain = m
                .chain
                .with_fixed_inserted(0, crate::machine::chain::translation(&(-o)));
            notes.push(format!(
                "work offset ({}, {}, {}) mm: the program's origin in the workpiece frame",
                o.x, o.y, o.z
            ));
        }
        if let Some(l) = tool_length_mm {
            // The machine file's own tool (its chain ends `tool_length_mm`
            // beyond the gauge line) is replaced by this one.
            m.chain
                .translate(Vector3::new(0.0, 0.0, base.tool_length_mm - l));
            m.tool_length_mm = l;
            notes.push(format!(
                "tool length {l} mm from the gauge line, replacing the machine file's {} mm",
                base.tool_length_mm
            ));
        }
        if !notes.is_empty() {
            m.description = format!("{} Job set-up: {}.", m.description, notes.join("; "));
        }
        m
    }

    /// The machine of the job for a program whose first bytes are G-code:
    /// for a tool table, the tool the program selects ([`Self::selected_tool`]
    /// on `program`, which is read to its end); otherwise the set-up's
    /// tool. `program` is not needed without a tool table.
    pub fn machine_for_program(
        &self,
        base: &Machine,
        program: Option<(&mut dyn BufRead, &str)>,
    ) -> Result<Machine> {
        let length = match &self.tool {
            ToolChoice::MachineFile => None,
            ToolChoice::Length(l) => Some(*l),
            ToolChoice::Table(_) => {
                let Some((reader, file)) = program else {
                    return Err(Error::Usage(
                        "--tool-table needs a G-code program that selects its tool (G43 H…, or T… M6)"
                            .into(),
                    ));
                };
                Some(self.selected_tool(reader, file)?.length_mm)
            }
        };
        Ok(self.machine(base, length))
    }

    /// The tool a G-code program selects from the tool table, for a command
    /// that takes one tool length per run: the first of
    /// [`Self::tool_changes`]; a program that changes to a tool of another
    /// length is refused at that change (convert it per tool).
    pub fn selected_tool(&self, program: &mut dyn BufRead, file: &str) -> Result<Selection> {
        let changes = self.tool_changes(program, file)?;
        if let Some(second) = changes.get(1) {
            let first = &changes[0];
            return Err(Error::input_with(
                second.at.clone(),
                format!(
                    "this selects tool {} of length {} mm, but the program selected tool {} of length {} mm at {}: this command converts a job with one tool length (`post` switches tools); split the program at the tool change and convert each part with its tool",
                    second.tool, second.length_mm, first.tool, first.length_mm, first.at
                ),
                &second.text,
            ));
        }
        Ok(changes
            .into_iter()
            .next()
            .expect("tool_changes is never empty"))
    }

    /// The tool selections of a G-code program that change the tool length,
    /// in program order (the first selection always; a later one only when
    /// its length differs from the one in force): the `H` word of `G43`,
    /// `G43.4` or `G43.5` (or, in a block of one of them without `H`, the
    /// tool loaded by the last `M6`), or the tool a tool change (`M6`, with
    /// the `T` word of its block or the last `T` before it) loads. An `H` or
    /// `T` the table does not have, an `M6` before any `T`, and a program
    /// that selects no tool are refused with their place.
    pub fn tool_changes(&self, program: &mut dyn BufRead, file: &str) -> Result<Vec<Selection>> {
        let ToolChoice::Table(table) = &self.tool else {
            return Err(Error::Usage("no tool table given".into()));
        };
        let mut prepared: Option<u32> = None;
        let mut loaded: Option<u32> = None;
        let mut changes: Vec<Selection> = Vec::new();
        let mut lines = LineReader::new(program);
        while let Some(line) = lines.next_line() {
            let line = line.map_err(|e| Error::io(file, e))?;
            let mut t_word = None;
            let mut h_word = None;
            let mut m6 = None;
            let mut g43 = None;
            for item in &line.items {
                let ItemKind::Word(w) = &item.kind else {
                    continue;
                };
                let col = item.start + 1;
                match w.address.as_str() {
                    "T" => t_word = Some((w.value, col)),
                    "H" => h_word = Some((w.value, col)),
                    "M" if (w.value - 6.0).abs() < 1e-9 => m6 = Some(col),
                    "G" if [43.0, 43.4, 43.5]
                        .iter()
                        .any(|g| (w.value - g).abs() < 1e-9) =>
                    {
                        g43 = Some(col)
                    }
                    _ => {}
                }
            }
            let text = line.text_lossy();
            let lookup = |value: f64, col: usize, what: &str| -> Result<(u32, Location)> {
                let at = Location::new(file, line.number, col);
                let n = (value >= 0.0 && value.fract() == 0.0 && value <= u32::MAX as f64)
                    .then_some(value as u32);
                match n.filter(|n| table.tools.contains_key(n)) {
                    Some(n) => Ok((n, at)),
                    None => Err(Error::input_with(
                        at,
                        format!(
                            "{what}{value} is not in the tool table {} (tools: {}); expected a tool the table has",
                            table.file,
                            table
                                .tools
                                .keys()
                                .map(|k| format!("T{k}"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                        &text,
                    )),
                }
            };
            if let Some((v, col)) = t_word {
                prepared = Some(lookup(v, col, "tool T")?.0);
            }
            let mut selection = None;
            if let Some(col) = m6 {
                match prepared {
                    Some(n) => {
                        loaded = Some(n);
                        selection = Some((n, Location::new(file, line.number, col)));
                    }
                    None => {
                        return Err(Error::input_with(
                            Location::new(file, line.number, col),
                            "a tool change (M6) before any T word: which tool is loaded is not known; expected T<number> with or before M6",
                            &text,
                        ));
                    }
                }
            }
            if let Some(gcol) = g43 {
                selection = Some(match (h_word, loaded) {
                    (Some((v, col)), _) => lookup(v, col, "length offset H")?,
                    (None, Some(n)) => (n, Location::new(file, line.number, gcol)),
                    (None, None) => {
                        return Err(Error::input_with(
                            Location::new(file, line.number, gcol),
                            "tool length compensation without an H word and before any tool change (T… M6): which tool's length is not known; expected G43 H<number>",
                            &text,
                        ));
                    }
                });
            }
            let Some((n, at)) = selection else {
                continue;
            };
            let length_mm = table.tools[&n].length_mm;
            if changes.last().is_none_or(|c| c.length_mm != length_mm) {
                changes.push(Selection {
                    tool: n,
                    length_mm,
                    at,
                    text,
                });
            }
        }
        if changes.is_empty() {
            return Err(Error::input(
                Location::new(file, 0, 0),
                format!(
                    "the program selects no tool of the tool table {}: expected G43/G43.4/G43.5 H<number> or T<number> M6",
                    table.file
                ),
            ));
        }
        Ok(changes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_linuxcnc_lines() {
        let t = ToolTable::parse(
            "T1 P1 Z+0.500000 D0.125 ;small\n\n; only a comment\nT2 P2 D6 Z50.25\n",
            "tool.tbl",
            25.4,
        )
        .unwrap();
        assert_eq!(t.tools.len(), 2);
        assert!((t.tools[&1].length_mm - 12.7).abs() < 1e-12);
        assert!((t.tools[&2].length_mm - 50.25 * 25.4).abs() < 1e-9);
        assert_eq!(t.tools[&2].line, 4);
    }

    #[test]
    fn refuses_bad_lines_with_their_place() {
        let e = ToolTable::parse("T1 Z1\nT2 Z1.2.3\n", "t.tbl", 1.0).unwrap_err();
        assert!(e.to_string().contains("t.tbl:2:4"), "{e}");
        let e = ToolTable::parse("T1 Z1\nT1 Z2\n", "t.tbl", 1.0).unwrap_err();
        assert!(e.to_string().contains("t.tbl:2:1") && e.to_string().contains("twice"));
        let e = ToolTable::parse("P1 Z1\n", "t.tbl", 1.0).unwrap_err();
        assert!(e.to_string().contains("without a T word"));
        let e = ToolTable::parse("T1 G1\n", "t.tbl", 1.0).unwrap_err();
        assert!(e.to_string().contains("t.tbl:1:4"), "{e}");
    }

    /// A byte-order mark, and a word that starts with a character of more
    /// than one byte (`Ø6mm`, a non-breaking space), panicked: the value
    /// was cut inside the character (session 39).
    #[test]
    fn a_byte_order_mark_passes_and_other_characters_are_refused() {
        let t = ToolTable::parse("\u{feff}T1 P1 Z+50.000 D6 ;end mill\n", "t.tbl", 1.0).unwrap();
        assert_eq!(t.tools[&1].length_mm, 50.0);
        let t = ToolTable::parse("\u{feff};tools\nT2 Z5\n", "t.tbl", 1.0).unwrap();
        assert_eq!(t.tools[&2].length_mm, 5.0);
        for (text, col) in [
            ("T1 P1 Z+50.000 D6 Ø6mm endmill\n", "t.tbl:1:19"),
            ("T1 \u{a0}Z5\n", "t.tbl:1:4"),
        ] {
            let e = ToolTable::parse(text, "t.tbl", 1.0)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(col) && e.contains("not a tool-table word"),
                "{e}"
            );
        }
    }
}
