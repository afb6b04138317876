//! Error tables: the CSV format of `formats.md` §1.
//!
//! ```text
//! # comment lines start with '#' (also '//')
//! X,EXX,EYX,EZX,EAX,EBX,ECX
//! -100.0,0.00031,-0.00012,0.00002,1.2e-6,-0.8e-6,2.0e-6
//! ```
//!
//! A header line (first field an axis letter) starts a table; the data lines
//! that follow belong to it until the next header. Error columns are named
//! `E` + direction of the error (`X`, `Y`, `Z` for δx, δy, δz; `A`, `B`, `C`
//! for εx, εy, εz) + the block's axis letter, optionally followed by a unit in
//! brackets. Values are converted to the internal units (mm, rad) here;
//! positions stay in the file's units (mm for linear axes, degrees for
//! rotary axes A, B, C).
//!
//! Accepted beyond the strict format (harmless liberties): a `dir` /
//! `direction` / `run` column giving the approach direction of each row
//! (`+1`/`-1`, `+`/`-`, `fwd`/`bwd`, `up`/`down`), a unit on the position
//! column (`X[mm]`, `B[deg]`, `B[rad]`, …), `;` or tab as the separator when
//! the header has no comma, trailing empty fields, trailing `#` or `//`
//! comments, a byte-order mark, CRLF line ends, and the Unicode minus sign.
//! Everything else that is malformed is an [`Error`] naming
//! `file:line:col` and showing the offending line.

use std::fmt;
use std::path::Path;

use crate::error::{Error, Location, Result};

/// One of the six error motions of a joint, in the order of
/// [`crate::machine::ErrorMotion`]: `[δx, δy, δz, εx, εy, εz]`.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// δx, translation along x (mm).
    Dx,
    /// δy, translation along y (mm).
    Dy,
    /// δz, translation along z (mm).
    Dz,
    /// εx, rotation about x (rad).
    Ex,
    /// εy, rotation about y (rad).
    Ey,
    /// εz, rotation about z (rad).
    Ez,
}

impl Component {
    /// All six components in `ErrorMotion` order.
    pub const ALL: [Component; 6] = [
        Component::Dx,
        Component::Dy,
        Component::Dz,
        Component::Ex,
        Component::Ey,
        Component::Ez,
    ];

    /// Index in the error motion vector `[δx, δy, δz, εx, εy, εz]`.
    pub fn index(self) -> usize {
        match self {
            Component::Dx => 0,
            Component::Dy => 1,
            Component::Dz => 2,
            Component::Ex => 3,
            Component::Ey => 4,
            Component::Ez => 5,
        }
    }

    /// True for δx, δy, δz (mm); false for εx, εy, εz (rad).
    pub fn is_translation(self) -> bool {
        self.index() < 3
    }

    /// The direction letter used in column names (`X`, `Y`, `Z`, `A`, `B`, `C`).
    pub fn letter(self) -> char {
        ['X', 'Y', 'Z', 'A', 'B', 'C'][self.index()]
    }

    /// The component named by a direction letter (case-insensitive).
    pub fn from_letter(c: char) -> Option<Component> {
        match c.to_ascii_uppercase() {
            'X' => Some(Component::Dx),
            'Y' => Some(Component::Dy),
            'Z' => Some(Component::Dz),
            'A' => Some(Component::Ex),
            'B' => Some(Component::Ey),
            'C' => Some(Component::Ez),
            _ => None,
        }
    }

    /// Internal unit: `"mm"` or `"rad"`.
    pub fn internal_unit(self) -> &'static str {
        if self.is_translation() { "mm" } else { "rad" }
    }

    /// Unit used in reports: `"µm"` for translations, `"µrad"` for rotations.
    pub fn display_unit(self) -> &'static str {
        if self.is_translation() {
            "µm"
        } else {
            "µrad"
        }
    }

    /// Factor from the internal unit to [`Component::display_unit`] (1000 or 1e6).
    pub fn display_factor(self) -> f64 {
        if self.is_translation() { 1e3 } else { 1e6 }
    }

    /// Conventional symbol, e.g. `δx` or `εz`.
    pub fn symbol(self) -> &'static str {
        ["δx", "δy", "δz", "εx", "εy", "εz"][self.index()]
    }
}

impl fmt::Display for Component {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

/// Radians per arc second.
pub const RAD_PER_ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

/// Whether an axis letter names a rotary axis (A, B or C).
pub fn is_rotary_axis(axis: &str) -> bool {
    matches!(axis.to_ascii_uppercase().as_str(), "A" | "B" | "C")
}

/// The component that lies along (linear axis) or about (rotary axis) the
/// axis itself: the positioning error (`EXX`, `EZZ`, `EBB`, …). `None` for
/// axis letters other than X, Y, Z, A, B, C.
pub fn positioning_component(axis: &str) -> Option<Component> {
    let mut chars = axis.chars();
    let c = chars.next()?;
    if chars.next().is_some() {
        return None;
    }
    Component::from_letter(c)
}

/// One error column of a table, values in internal units.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorColumn {
    /// Which of the six error motions.
    pub component: Component,
    /// Column name as written, without the unit, upper-case (e.g. `EXX`).
    pub name: String,
    /// One value per table row: mm for δ, rad for ε.
    pub values: Vec<f64>,
}

/// The errors of one axis measured (or tabulated) against its position.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorTable {
    /// Axis letter, upper-case (`X`, `Z`, `B`, …).
    pub axis: String,
    /// True for rotary axes (A, B, C): positions are in degrees.
    pub rotary: bool,
    /// Error columns in file order (a subset of the six).
    pub columns: Vec<ErrorColumn>,
    /// Axis positions, one per row, in file units: mm, or degrees for rotary axes.
    pub positions: Vec<f64>,
    /// Approach direction of each row (+1 or −1), from a `dir` column or
    /// inferred from the order of the rows; `None` when unknown.
    pub direction: Option<Vec<i8>>,
    /// 1-based line of each row in the file.
    pub source_line: Vec<usize>,
    /// File name the table was read from (for messages).
    pub file: String,
    /// 1-based line of the table's header.
    pub header_line: usize,
    /// The header line as written (for messages).
    pub header_text: String,
}

impl ErrorTable {
    /// The column of component `c`, if present.
    pub fn column(&self, c: Component) -> Option<&ErrorColumn> {
        self.columns.iter().find(|col| col.component == c)
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when the table has no rows (never the case for parsed tables).
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Location of the header line (for messages).
    pub fn location(&self) -> Location {
        Location::new(self.file.clone(), self.header_line, 1)
    }
}

/// Reads and parses an error-table file.
pub fn read_tables(path: &Path) -> Result<Vec<ErrorTable>> {
    let name = path.display().to_string();
    let text = crate::text::read_text_file(path)?;
    parse_tables(&text, &name)
}

/// A field of a line: trimmed text and its 1-based column.
#[derive(Debug, Clone, Copy)]
struct Field<'a> {
    text: &'a str,
    col: usize,
}

/// Splits `line` at `sep`, trimming whitespace around each field; trailing
/// empty fields are dropped.
fn split_fields(line: &str, sep: char) -> Vec<Field<'_>> {
    let mut out = Vec::with_capacity(8);
    let mut start = 0;
    let bytes_len = line.len();
    // An ASCII separator (all but exotic ones) is found byte by byte.
    let ascii = u8::try_from(sep).ok().filter(u8::is_ascii);
    loop {
        let found = match ascii {
            Some(b) => line.as_bytes()[start..].iter().position(|&c| c == b),
            None => line[start..].find(sep),
        };
        let end = found.map_or(bytes_len, |i| start + i);
        let raw = &line[start..end];
        let lead = raw.len() - raw.trim_start().len();
        let mut text = raw.trim();
        let mut col = start + lead + 1;
        // A spreadsheet's export that quotes its cells (`"X","EXX"`).
        if text.len() >= 2 && text.starts_with('"') && text.ends_with('"') {
            text = text[1..text.len() - 1].trim();
            col += 1;
        }
        out.push(Field { text, col });
        if end >= bytes_len {
            break;
        }
        start = end + sep.len_utf8();
    }
    while out.len() > 1 && out.last().is_some_and(|f| f.text.is_empty()) {
        out.pop();
    }
    out
}

/// Removes a trailing `#` or `//` comment and a trailing `\r`.
fn strip_comment(line: &str) -> &str {
    let line = line.strip_suffix('\r').unwrap_or(line);
    let cut = match (line.find('#'), line.find("//")) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) => a,
        (None, Some(b)) => b,
        (None, None) => line.len(),
    };
    &line[..cut]
}

/// Parses a number, accepting the Unicode minus sign; rejects NaN and infinities.
/// Largest geometric error a table may give, in internal units: a
/// rotation of 0.05 rad (2.9°; the small-angle form of `kinematics.md`
/// is off by 0.1 % there, and `compensate` corrects at most 5 mrad), a
/// translation of 10 mm (`compensate` corrects at most 0.5 mm). Beyond
/// them a value is no geometric error of a machine tool but a unit
/// mistake: µrad or µm read as rad or mm.
const MAX_ROTATION_RAD: f64 = 0.05;
/// See [`MAX_ROTATION_RAD`].
const MAX_TRANSLATION_MM: f64 = 10.0;

/// Why `value` (internal units, as `text` was written) in column `name`
/// is no geometric error of `component`, or `None`.
fn implausible(component: Component, name: &str, value: f64, text: &str) -> Option<String> {
    let (limit, unit, small) = if component.is_translation() {
        (MAX_TRANSLATION_MM, "mm", "[um]")
    } else {
        (MAX_ROTATION_RAD, "rad", "[urad]")
    };
    (value.abs() > limit).then(|| {
        format!(
            "`{text}` is {} {unit}, beyond any geometric error of a machine tool (at most {limit} {unit} here): values in µm or µrad read in the default units mm and rad? give the unit in the header, e.g. {}{small}",
            crate::numeric::readable(value),
            name
        )
    })
}

fn parse_number(text: &str) -> std::result::Result<f64, &'static str> {
    if text.is_empty() {
        return Err("empty field: expected a number");
    }
    // A plain decimal (`-0.0017216`) exactly by the digit scan, as the
    // program readers do; anything else by the standard parser.
    if let Some(v) = crate::numeric::plain_decimal(text.as_bytes()) {
        return Ok(v);
    }
    let owned;
    let t = if text.contains('\u{2212}') {
        owned = text.replace('\u{2212}', "-");
        owned.as_str()
    } else {
        text
    };
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err("not a finite number (NaN and infinities are not allowed)"),
        Err(_) => Err("not a number"),
    }
}

/// True if `text` looks like an axis name for a header: one ASCII letter,
/// optionally followed by a bracketed unit.
fn header_axis(text: &str) -> Option<(char, Option<&str>)> {
    let (name, unit) = split_unit(text).ok()?;
    let mut chars = name.chars();
    let c = chars.next()?;
    if chars.next().is_none() && c.is_ascii_alphabetic() {
        Some((c.to_ascii_uppercase(), unit))
    } else {
        None
    }
}

/// Splits `NAME[unit]` into name and optional unit (both trimmed).
fn split_unit(text: &str) -> std::result::Result<(&str, Option<&str>), &'static str> {
    match text.find('[') {
        None => {
            if text.contains(']') {
                Err("unbalanced ']' in column name")
            } else {
                Ok((text.trim(), None))
            }
        }
        Some(open) => {
            let rest = &text[open + 1..];
            let close = rest.find(']').ok_or("missing ']' after the unit")?;
            if !rest[close + 1..].trim().is_empty() {
                return Err("unexpected text after the unit");
            }
            Ok((text[..open].trim(), Some(rest[..close].trim())))
        }
    }
}

/// Factor from a translation unit to mm.
pub(crate) fn length_unit(unit: &str) -> Option<f64> {
    match unit.to_lowercase().as_str() {
        "mm" => Some(1.0),
        "um" | "µm" | "μm" | "micron" | "microns" => Some(1e-3),
        "nm" => Some(1e-6),
        "m" => Some(1e3),
        _ => None,
    }
}

/// Factor from an angle unit to rad.
pub(crate) fn angle_unit(unit: &str) -> Option<f64> {
    match unit.to_lowercase().as_str() {
        "rad" => Some(1.0),
        "mrad" => Some(1e-3),
        "urad" | "µrad" | "μrad" => Some(1e-6),
        "nrad" => Some(1e-9),
        "deg" | "°" => Some(std::f64::consts::PI / 180.0),
        "arcmin" => Some(std::f64::consts::PI / (180.0 * 60.0)),
        "arcsec" | "as" | "\"" => Some(RAD_PER_ARCSEC),
        _ => None,
    }
}

/// What a header column holds.
#[derive(Debug, Clone)]
enum ColumnKind {
    /// An error column: component, upper-case name, factor to internal units.
    Error(Component, String, f64),
    /// The approach direction of each row.
    Direction,
}

/// A table being read.
struct Block {
    axis: String,
    rotary: bool,
    header_line: usize,
    header_text: String,
    sep: char,
    position_factor: f64,
    kinds: Vec<ColumnKind>,
    positions: Vec<f64>,
    values: Vec<Vec<f64>>,
    directions: Vec<i8>,
    has_direction: bool,
    source_line: Vec<usize>,
}

/// Parses one or more error tables from CSV text. `file` is used in messages.
pub fn parse_tables(text: &str, file: &str) -> Result<Vec<ErrorTable>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let loc = |line: usize, col: usize| Location::new(file, line, col);
    let mut tables = Vec::new();
    let mut block: Option<Block> = None;

    for (idx, raw_line) in text.split('\n').enumerate() {
        let line_no = idx + 1;
        let raw_line = raw_line.strip_suffix('\r').unwrap_or(raw_line);
        let content = strip_comment(raw_line);
        if content.trim().is_empty() {
            continue;
        }
        // The separator: the current block's, or guessed from this line.
        let guess_sep = guess_separator(content);
        let first = split_fields(content, guess_sep)[0];
        let first_is_number = parse_number(first.text).is_ok();
        if !first_is_number && header_axis(first.text).is_some() {
            if let Some(b) = block.take() {
                tables.push(finish_block(b, file)?);
            }
            block = Some(parse_header(content, raw_line, line_no, guess_sep, file)?);
            continue;
        }
        let Some(b) = block.as_mut() else {
            let what = if first_is_number {
                "data before the first header: expected a header line such as `X,EXX,EYX` first"
            } else {
                "expected a header line whose first field is an axis letter (X, Y, Z, A, B, C, …)"
            };
            return Err(Error::input_with(loc(line_no, first.col), what, raw_line));
        };
        let fields = split_fields(content, b.sep);
        let first = fields[0];
        let pos = match parse_number(first.text) {
            Ok(p) => p * b.position_factor,
            Err(m) => {
                let msg = format!("axis position: {m}: `{}`", first.text);
                return Err(Error::input_with(loc(line_no, first.col), msg, raw_line));
            }
        };
        if fields.len() != b.kinds.len() + 1 {
            let col = fields
                .get(b.kinds.len() + 1)
                .map_or(content.trim_end().len() + 1, |f| f.col);
            return Err(Error::input_with(
                loc(line_no, col),
                format!(
                    "wrong number of fields: {} found, the header (line {}) has {}",
                    fields.len(),
                    b.header_line,
                    b.kinds.len() + 1
                ),
                raw_line,
            ));
        }
        let mut dir = 0i8;
        let mut row = Vec::with_capacity(b.kinds.len());
        for (kind, f) in b.kinds.iter().zip(&fields[1..]) {
            match kind {
                ColumnKind::Error(component, name, factor) => {
                    let v = parse_number(f.text).map_err(|m| {
                        Error::input_with(
                            loc(line_no, f.col),
                            format!("column {name}: {m}: `{}`", f.text),
                            raw_line,
                        )
                    })?;
                    if let Some(m) = implausible(*component, name, v * factor, f.text) {
                        return Err(Error::input_with(
                            loc(line_no, f.col),
                            format!("column {name}: {m}"),
                            raw_line,
                        ));
                    }
                    row.push(v * factor);
                }
                ColumnKind::Direction => {
                    dir = parse_direction(f.text).ok_or_else(|| {
                        Error::input_with(
                            loc(line_no, f.col),
                            format!(
                                "direction: expected +1/-1, +/-, fwd/bwd or up/down, found `{}`",
                                f.text
                            ),
                            raw_line,
                        )
                    })?;
                }
            }
        }
        b.positions.push(pos);
        b.values.push(row);
        b.directions.push(dir);
        b.source_line.push(line_no);
    }
    if let Some(b) = block.take() {
        tables.push(finish_block(b, file)?);
    }
    if tables.is_empty() {
        return Err(Error::input(
            Location::new(file, 1, 1),
            "no error table found: expected a header line such as `X,EXX,EYX` followed by data",
        ));
    }
    Ok(tables)
}

/// Comma if the line has one, else semicolon, else tab.
fn guess_separator(line: &str) -> char {
    if line.contains(',') {
        ','
    } else if line.contains(';') {
        ';'
    } else if line.contains('\t') {
        '\t'
    } else {
        ','
    }
}

fn parse_direction(text: &str) -> Option<i8> {
    let t = text.replace('\u{2212}', "-").to_lowercase();
    match t.as_str() {
        "+" | "+1" | "1" | "1.0" | "+1.0" | "fwd" | "forward" | "up" | "pos" | "↑" => Some(1),
        "-" | "-1" | "-1.0" | "bwd" | "back" | "backward" | "rev" | "down" | "neg" | "↓" => {
            Some(-1)
        }
        _ => None,
    }
}

fn parse_header(
    content: &str,
    raw_line: &str,
    line_no: usize,
    sep: char,
    file: &str,
) -> Result<Block> {
    let loc = |col: usize| Location::new(file, line_no, col);
    let fields = split_fields(content, sep);
    let first = fields[0];
    let (axis, pos_unit) = header_axis(first.text)
        .ok_or_else(|| Error::input_with(loc(first.col), "expected an axis letter", raw_line))?;
    let rotary = matches!(axis, 'A' | 'B' | 'C');
    let position_factor = match pos_unit {
        None => 1.0,
        Some(u) => {
            let f = if rotary {
                angle_unit(u).map(|f| f / angle_unit("deg").unwrap_or(1.0))
            } else {
                length_unit(u)
            };
            f.ok_or_else(|| {
                Error::input_with(
                    loc(first.col),
                    format!(
                        "unknown unit `[{u}]` for the position of {} axis {axis}: expected {}",
                        if rotary { "rotary" } else { "linear" },
                        if rotary {
                            "deg, rad, mrad, urad or arcsec"
                        } else {
                            "mm, um or nm"
                        }
                    ),
                    raw_line,
                )
            })?
        }
    };
    let mut kinds: Vec<ColumnKind> = Vec::new();
    let mut names: Vec<String> = Vec::new();
    for f in &fields[1..] {
        let (name, unit) = split_unit(f.text).map_err(|m| {
            Error::input_with(loc(f.col), format!("column `{}`: {m}", f.text), raw_line)
        })?;
        if name.is_empty() {
            return Err(Error::input_with(
                loc(f.col),
                "empty column name in header",
                raw_line,
            ));
        }
        let upper = name.to_uppercase();
        if names.contains(&upper) {
            return Err(Error::input_with(
                loc(f.col),
                format!("duplicate column `{name}`"),
                raw_line,
            ));
        }
        let kind = if matches!(upper.as_str(), "DIR" | "DIRECTION" | "RUN") {
            if kinds.iter().any(|k| matches!(k, ColumnKind::Direction)) {
                return Err(Error::input_with(
                    loc(f.col),
                    format!("duplicate direction column `{name}`"),
                    raw_line,
                ));
            }
            if let Some(u) = unit {
                return Err(Error::input_with(
                    loc(f.col),
                    format!("the direction column takes no unit, found `[{u}]`"),
                    raw_line,
                ));
            }
            ColumnKind::Direction
        } else {
            let chars: Vec<char> = upper.chars().collect();
            let component = (chars.len() == 3 && chars[0] == 'E')
                .then(|| Component::from_letter(chars[1]))
                .flatten()
                .filter(|_| chars[2].is_ascii_alphabetic());
            let Some(component) = component else {
                return Err(Error::input_with(
                    loc(f.col),
                    format!(
                        "unknown column `{name}`: expected E<direction><axis> such as E{axis}{axis}, \
                         EY{axis}, EA{axis} (direction X, Y, Z, A, B or C), or dir"
                    ),
                    raw_line,
                ));
            };
            if chars[2] != axis {
                return Err(Error::input_with(
                    loc(f.col),
                    format!(
                        "column `{name}` is an error of axis {}, but this table is for axis {axis} \
                         (start a new block with a header `{},…` for axis {})",
                        chars[2], chars[2], chars[2]
                    ),
                    raw_line,
                ));
            }
            if let Some(prev) = kinds.iter().find_map(|k| match k {
                ColumnKind::Error(c, n, _) if *c == component => Some(n.clone()),
                _ => None,
            }) {
                return Err(Error::input_with(
                    loc(f.col),
                    format!("duplicate column `{name}`: {prev} already gives {component}"),
                    raw_line,
                ));
            }
            let factor = match unit {
                None => 1.0,
                Some(u) => {
                    let f_opt = if component.is_translation() {
                        length_unit(u)
                    } else {
                        angle_unit(u)
                    };
                    f_opt.ok_or_else(|| {
                        Error::input_with(
                            loc(f.col),
                            format!(
                                "unknown unit `[{u}]` for {} column {upper}: expected {}",
                                if component.is_translation() {
                                    "translation"
                                } else {
                                    "rotation"
                                },
                                if component.is_translation() {
                                    "um, nm or mm"
                                } else {
                                    "urad, mrad, arcsec, deg or rad"
                                }
                            ),
                            raw_line,
                        )
                    })?
                }
            };
            ColumnKind::Error(component, upper.clone(), factor)
        };
        names.push(upper);
        kinds.push(kind);
    }
    if !kinds.iter().any(|k| matches!(k, ColumnKind::Error(..))) {
        return Err(Error::input_with(
            loc(first.col),
            format!("header for axis {axis} has no error column (expected e.g. E{axis}{axis})"),
            raw_line,
        ));
    }
    let has_direction = kinds.iter().any(|k| matches!(k, ColumnKind::Direction));
    Ok(Block {
        axis: axis.to_string(),
        rotary,
        header_line: line_no,
        header_text: raw_line.to_string(),
        sep,
        position_factor,
        kinds,
        positions: Vec::new(),
        values: Vec::new(),
        directions: Vec::new(),
        has_direction,
        source_line: Vec::new(),
    })
}

fn finish_block(b: Block, file: &str) -> Result<ErrorTable> {
    if b.positions.is_empty() {
        return Err(Error::input_with(
            Location::new(file, b.header_line, 1),
            format!(
                "empty table: the header for axis {} has no data rows",
                b.axis
            ),
            b.header_text,
        ));
    }
    let mut columns = Vec::new();
    for (i, k) in b.kinds.iter().enumerate() {
        if let ColumnKind::Error(component, name, _) = k {
            // Column i of the header; its index among the row values is the
            // number of error columns before it.
            let vi = b.kinds[..i]
                .iter()
                .filter(|k| matches!(k, ColumnKind::Error(..)))
                .count();
            columns.push(ErrorColumn {
                component: *component,
                name: name.clone(),
                values: b.values.iter().map(|r| r[vi]).collect(),
            });
        }
    }
    let direction = if b.has_direction {
        Some(b.directions)
    } else {
        infer_directions(&b.positions)
    };
    Ok(ErrorTable {
        axis: b.axis,
        rotary: b.rotary,
        columns,
        positions: b.positions,
        direction,
        source_line: b.source_line,
        file: file.to_string(),
        header_line: b.header_line,
        header_text: b.header_text,
    })
}

/// Infers approach directions from the order of the rows.
///
/// The rows are split into maximal strictly monotone runs (a step of zero,
/// or a step against the run's direction, starts a new run); each row gets
/// its run's direction. This is how a laser-interferometer test is written
/// (ISO 230-2 linear cycle: targets visited upwards, then downwards, repeated).
/// The inference is only accepted when there are at least two runs, every
/// run has at least two rows, and both directions occur; otherwise `None`.
pub fn infer_directions(positions: &[f64]) -> Option<Vec<i8>> {
    let n = positions.len();
    if n < 4 {
        return None;
    }
    let mut dirs = vec![0i8; n];
    let mut runs: Vec<(usize, usize, i8)> = Vec::new();
    let mut start = 0;
    while start < n {
        if start + 1 >= n {
            return None; // a lone last row
        }
        let step = positions[start + 1] - positions[start];
        if step == 0.0 {
            return None; // a run of one row
        }
        let sign: i8 = if step > 0.0 { 1 } else { -1 };
        let mut end = start + 1;
        while end + 1 < n {
            let s = positions[end + 1] - positions[end];
            if (sign > 0 && s > 0.0) || (sign < 0 && s < 0.0) {
                end += 1;
            } else {
                break;
            }
        }
        runs.push((start, end, sign));
        start = end + 1;
    }
    if runs.len() < 2 || !runs.iter().any(|r| r.2 > 0) || !runs.iter().any(|r| r.2 < 0) {
        return None;
    }
    for (s, e, sign) in runs {
        for d in &mut dirs[s..=e] {
            *d = sign;
        }
    }
    Some(dirs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_fields_with_columns() {
        let f = split_fields(" a , bb,c ,,", ',');
        assert_eq!(f.len(), 3);
        assert_eq!((f[0].text, f[0].col), ("a", 2));
        assert_eq!((f[1].text, f[1].col), ("bb", 6));
        assert_eq!((f[2].text, f[2].col), ("c", 9));
    }

    #[test]
    fn infers_up_down_runs() {
        let p = [0.0, 1.0, 2.0, 2.0, 1.0, 0.0, 0.0, 1.0, 2.0];
        assert_eq!(
            infer_directions(&p).unwrap(),
            vec![1, 1, 1, -1, -1, -1, 1, 1, 1]
        );
        // Without repeated end points.
        let p = [0.0, 1.0, 2.0, 1.0, 0.0];
        assert_eq!(infer_directions(&p).unwrap(), vec![1, 1, 1, -1, -1]);
        // A single sorted run: unknown.
        assert!(infer_directions(&[0.0, 1.0, 2.0, 3.0]).is_none());
        // Pilgrim steps (runs of one): unknown.
        assert!(infer_directions(&[0.0, 1.0, 1.0, 2.0, 2.0, 3.0]).is_none());
    }

    /// µrad and µm read in the default rad and mm gave rotations of
    /// 3.35 rad, far outside the small-angle model, and `compensate` ran
    /// 30 iterations a pose to a 58 mm miss, exit 0 (session 39).
    #[test]
    fn errors_beyond_any_machine_tool_are_refused() {
        let e = parse_tables("X,EXX,EBX\n-100,0.001,-3.35\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.csv:2:12: column EBX") && e.contains("EBX[urad]"),
            "{e}"
        );
        let e = parse_tables("X,EXX\n-100,12.5\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.csv:2:6: column EXX") && e.contains("EXX[um]"),
            "{e}"
        );
        // At the limits, and in their own units, they are read.
        parse_tables("X,EXX,EBX[deg]\n-100,10,2.8\n", "t.csv").unwrap();
        parse_tables("X,EXX[um],EBX[urad]\n-100,12.5,-3.35\n", "t.csv").unwrap();
    }

    #[test]
    fn quoted_cells_are_read_without_their_quotes() {
        let t = parse_tables("\"X\",\"EXX[um]\"\n\"-100\",\"1.5\"\n0,2\n", "t.csv").unwrap();
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].len(), 2);
    }

    #[test]
    fn units_convert() {
        assert_eq!(length_unit("um"), Some(1e-3));
        assert_eq!(length_unit("µm"), Some(1e-3));
        assert!((angle_unit("arcsec").unwrap() - 4.84813681109536e-6).abs() < 1e-18);
        assert!(angle_unit("mm").is_none());
    }

    #[test]
    fn direction_words() {
        assert_eq!(parse_direction("fwd"), Some(1));
        assert_eq!(parse_direction("\u{2212}1"), Some(-1));
        assert_eq!(parse_direction("2"), None);
    }
}
