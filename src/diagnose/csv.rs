//! The CSV dialect of a recording as controllers and trace tools export it:
//! the separator, quoted fields, a decimal comma, and a unit in a column's
//! name (`formats.md` §2, §2c; `docs/diagnose.md`, Reading a recording).
//!
//! - The separator is the one of `,`, `;` and tab that the header line
//!   holds most often (a comma where as many).
//! - A field in double quotes (`"meas_x"`, `"0.125"`) is read without them.
//! - With a semicolon or tab as the separator, a number may have a decimal
//!   comma (`-20,00516`: a German-locale export); with commas it cannot.
//! - A column name may carry its unit in brackets or parentheses, `t [ms]`,
//!   `t (s)`, `X[um]` (and `time` names the time column `t`),
//!   `B [rad]`, `temp_spindle [°C]`: the values are converted to the units of
//!   `formats.md` (s, mm, deg, °C). A unit of the wrong kind, or one not
//!   known, is refused at the column. A units row under the header
//!   (`s,,mm,deg,…`) gives the units of the columns whose names carry none
//!   ([`units_row`]).

use crate::geometric::table::{angle_unit, length_unit};

/// The separator and number form of one recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Dialect {
    /// The field separator.
    sep: u8,
    /// Whether a number may have a decimal comma.
    decimal_comma: bool,
}

impl Dialect {
    /// The dialect of a recording whose header line is `header`: the
    /// separator is the one of `,`, `;` and tab that the header holds most
    /// often (a comma before a semicolon before a tab where as many), so
    /// that a comma inside a column name of a `;`-separated file (`meas,x`)
    /// does not make every line one field.
    pub(crate) fn of_header(header: &str) -> Dialect {
        let count = |c: u8| unquoted(header).filter(|&(_, b)| b == c).count();
        let sep = [b',', b';', b'\t']
            .into_iter()
            .fold((b',', 0), |best, c| {
                let n = count(c);
                if n > best.1 { (c, n) } else { best }
            })
            .0;
        Dialect {
            sep,
            decimal_comma: sep != b',',
        }
    }

    /// The fields of `line`, trimmed and without their double quotes, with
    /// their 1-based byte columns. A separator between double quotes is
    /// part of the field (`"X, cmd"`, `"-20,25"`: RFC 4180, as spreadsheets
    /// write a field that holds one); such a number is then refused where
    /// it is read, as a comma in a comma-separated file is no decimal
    /// point.
    pub(crate) fn fields<'a>(&self, line: &'a str) -> Vec<(usize, &'a str)> {
        let mut out = Vec::with_capacity(12);
        let mut start = 0;
        let mut ends = unquoted(line)
            .filter(|&(_, b)| b == self.sep)
            .map(|(i, _)| i)
            .chain([line.len()]);
        let mut from = 0;
        let pieces = std::iter::from_fn(|| {
            let end = ends.next()?;
            let piece = &line[from..end];
            from = end + 1;
            Some(piece)
        });
        for piece in pieces {
            let lead = piece.len() - piece.trim_start().len();
            let mut text = piece.trim();
            let mut col = start + lead + 1;
            if text.len() >= 2 && text.starts_with('"') && text.ends_with('"') {
                text = text[1..text.len() - 1].trim();
                col += 1;
            }
            out.push((col, text));
            start += piece.len() + 1;
        }
        out
    }

    /// `text` as a number: a plain decimal or exponent form, with a decimal
    /// comma where the dialect allows one. `None` when it is not one.
    pub(crate) fn number(&self, text: &str) -> Option<f64> {
        if let Ok(v) = text.parse::<f64>() {
            return Some(v);
        }
        if self.decimal_comma && text.bytes().filter(|b| *b == b',').count() == 1 {
            return text.replacen(',', ".", 1).parse().ok();
        }
        None
    }
}

/// The bytes of `line` outside double quotes, with their indices (a
/// doubled quote inside quotes, `""`, is one quote of the field).
fn unquoted(line: &str) -> impl Iterator<Item = (usize, u8)> + '_ {
    let mut quoted = false;
    line.bytes().enumerate().filter(move |&(_, b)| {
        if b == b'"' {
            quoted = !quoted;
        }
        !quoted && b != b'"'
    })
}

/// What a column holds, for the check of its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Quantity {
    /// Time, s.
    Time,
    /// A length, mm.
    Length,
    /// An angle, deg.
    Angle,
    /// A temperature, °C.
    Temperature,
    /// A number without a unit (block number, direction cosine).
    Plain,
}

impl Quantity {
    /// The unit values of this quantity are converted to.
    pub(crate) fn unit(self) -> &'static str {
        match self {
            Quantity::Time => "s",
            Quantity::Length => "mm",
            Quantity::Angle => "deg",
            Quantity::Temperature => "°C",
            Quantity::Plain => "no unit",
        }
    }

    /// The factor from `unit` to this quantity's unit, or `None` when
    /// `unit` is not one of it.
    pub(crate) fn factor(self, unit: &str) -> Option<f64> {
        let u = unit.trim();
        match self {
            Quantity::Time => match u {
                "s" | "sec" => Some(1.0),
                "ms" => Some(1e-3),
                "us" | "µs" | "μs" => Some(1e-6),
                _ => None,
            },
            Quantity::Length => match u.to_ascii_lowercase().as_str() {
                "in" | "inch" => Some(25.4),
                _ => length_unit(u),
            },
            Quantity::Angle => angle_unit(u).map(|f| f.to_degrees()),
            Quantity::Temperature => {
                matches!(u, "°C" | "C" | "degC" | "℃" | "°c" | "c" | "degc").then_some(1.0)
            }
            Quantity::Plain => matches!(u, "" | "1" | "-").then_some(1.0),
        }
    }
}

/// A column name split into its lower-case name and its unit, if it has
/// one in brackets or parentheses (`X [um]` → `("x", Some("um"))`, `t (s)`
/// → `("t", Some("s"))`). `time` is the time column `t`.
pub(crate) fn column_name(field: &str) -> (String, Option<&str>) {
    let end = field.trim_end();
    let split = [('[', ']'), ('(', ')')].iter().find_map(|&(open, close)| {
        let at = field.find(open)?;
        end.ends_with(close)
            .then(|| (at, &field[at + 1..end.len() - 1]))
    });
    let (name, unit) = match split {
        Some((at, unit)) => (field[..at].trim().to_ascii_lowercase(), Some(unit.trim())),
        None => (field.trim().to_ascii_lowercase(), None),
    };
    (if name == "time" { "t".into() } else { name }, unit)
}

/// The quantity of a spatial-recording or feedback column by its name:
/// `t`, an axis (A, B, C angles; other letters lengths), `fb_<axis>`,
/// `meas_x`…`meas_z` (lengths), `meas_i`…`meas_k` (plain), `temp…`.
pub(crate) fn quantity(name: &str) -> Quantity {
    let axis = |a: &str| match a {
        "a" | "b" | "c" => Quantity::Angle,
        _ => Quantity::Length,
    };
    match name {
        "t" => Quantity::Time,
        "block" | "meas_i" | "meas_j" | "meas_k" => Quantity::Plain,
        "meas_x" | "meas_y" | "meas_z" => Quantity::Length,
        n if n.starts_with("temp") => Quantity::Temperature,
        n => axis(n.strip_prefix("fb_").unwrap_or(n)),
    }
}

/// The factor of each header field to the units of `formats.md`, or the
/// index of the first field whose unit is unknown or of the wrong kind and
/// the message for it.
pub(crate) fn factors(fields: &[(usize, &str)]) -> Result<Vec<f64>, (usize, String)> {
    fields
        .iter()
        .enumerate()
        .map(|(i, (_, f))| {
            let (name, unit) = column_name(f);
            let Some(unit) = unit else {
                return Ok(1.0);
            };
            let q = quantity(&name);
            q.factor(unit).ok_or_else(|| {
                (
                    i,
                    format!(
                        "column `{f}`: `{unit}` is not a unit of {} (expected {}{})",
                        match q {
                            Quantity::Time => "time",
                            Quantity::Length => "length",
                            Quantity::Angle => "angle",
                            Quantity::Temperature => "temperature",
                            Quantity::Plain => "this column, which has none",
                        },
                        q.unit(),
                        match q {
                            Quantity::Time => ", ms or µs",
                            Quantity::Length => ", µm, nm, m or inch",
                            Quantity::Angle => ", rad, mrad, µrad, arcmin or arcsec",
                            _ => "",
                        }
                    ),
                )
            })
        })
        .collect()
}

/// The factors a units row under the header gives (`s,,mm,deg,…`, as
/// many exports write one): `None` when `fields` is not such a row (its
/// time field, `t_index`, is empty, or any field is a number; without a
/// time column, every field is empty); else each
/// column's factor from `header` (names with their bracket units, and
/// their factors `from_names`), or the index of the first field whose
/// unit is not one of its column's quantity, or disagrees with the unit
/// in its name, and the message for it.
#[allow(clippy::type_complexity)]
pub(crate) fn units_row(
    dialect: Dialect,
    header: &[(usize, &str)],
    from_names: &[f64],
    fields: &[(usize, &str)],
    t_index: Option<usize>,
) -> Option<Result<Vec<f64>, (usize, String)>> {
    let numeric = |f: &str| dialect.number(f).is_some();
    let unit_of_time = match t_index {
        Some(t) => !fields.get(t)?.1.is_empty(),
        None => fields.iter().any(|(_, f)| !f.is_empty()),
    };
    if !unit_of_time || fields.iter().any(|(_, f)| numeric(f)) {
        return None;
    }
    Some(
        header
            .iter()
            .enumerate()
            .map(|(i, (_, h))| {
                let unit = fields.get(i).map_or("", |f| f.1);
                let unit = unit
                    .trim_start_matches(['[', '('])
                    .trim_end_matches([']', ')'])
                    .trim();
                let (name, in_name) = column_name(h);
                let q = quantity(&name);
                if unit.is_empty() || (q == Quantity::Plain && unit == "-") {
                    return Ok(from_names[i]);
                }
                let Some(f) = q.factor(unit) else {
                    return Err((
                        i,
                        format!(
                            "the line under the header reads as a units row, and `{unit}` is not a unit of column `{h}` (expected {})",
                            q.unit()
                        ),
                    ));
                };
                if in_name.is_some() && (f - from_names[i]).abs() > 1e-12 * f.abs() {
                    return Err((
                        i,
                        format!(
                            "the units row gives `{unit}` for column `{h}`, whose name gives another unit"
                        ),
                    ));
                }
                Ok(f)
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separators_quotes_and_decimal_commas() {
        let d = Dialect::of_header("t;X;meas_x");
        assert_eq!(
            d.fields("0,5; \"-20,25\" ;3"),
            vec![(1, "0,5"), (7, "-20,25"), (16, "3")]
        );
        assert_eq!(d.number("-20,25"), Some(-20.25));
        assert_eq!(d.number("1.5e-3"), Some(1.5e-3));
        assert_eq!(d.number("1,2,3"), None);
        let c = Dialect::of_header("\"t\",\"X\"");
        assert_eq!(c.fields("\"t\",\"X\""), vec![(2, "t"), (6, "X")]);
        assert_eq!(c.number("0,5"), None);
        let tab = Dialect::of_header("t\tX");
        assert_eq!(tab.fields("1\t2,5"), vec![(1, "1"), (3, "2,5")]);
        assert_eq!(tab.number("2,5"), Some(2.5));
    }

    #[test]
    fn a_separator_in_quotes_is_part_of_the_field() {
        // A spreadsheet's comma-separated export of a German locale quotes
        // the numbers with a decimal comma: one field each, refused as a
        // number (a comma is no decimal point there), never split in two.
        let c = Dialect::of_header("t,\"X, cmd\",meas_x");
        assert_eq!(c, Dialect::of_header("t,X,meas_x"));
        assert_eq!(
            c.fields("0.5,\"-20,25\",3"),
            vec![(1, "0.5"), (6, "-20,25"), (14, "3")]
        );
        assert_eq!(c.number("-20,25"), None);
        assert_eq!(
            c.fields("t,\"X, cmd\",meas_x"),
            vec![(1, "t"), (4, "X, cmd"), (12, "meas_x")]
        );
        // A `;` file whose header names hold commas keeps `;`.
        let d = Dialect::of_header("\"t, s\";\"X, mm\"");
        assert_eq!(d.fields("1,5;2"), vec![(1, "1,5"), (5, "2")]);
    }

    #[test]
    fn units_in_column_names() {
        assert_eq!(column_name("meas_x [um]"), ("meas_x".into(), Some("um")));
        assert_eq!(column_name("T"), ("t".into(), None));
        let h = [
            (1, "t [ms]"),
            (2, "X[um]"),
            (3, "B [rad]"),
            (4, "temp_s [°C]"),
            (5, "meas_z"),
        ];
        let f = factors(&h).unwrap();
        assert_eq!(f[0], 1e-3);
        assert_eq!(f[1], 1e-3);
        assert!((f[2] - 180.0 / std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(&f[3..], [1.0, 1.0]);
        let e = factors(&[(1, "t"), (3, "X [deg]")]).unwrap_err();
        assert_eq!(e.0, 1);
        assert!(e.1.contains("`deg` is not a unit of length"), "{}", e.1);
        assert!(factors(&[(1, "meas_i [mm]")]).is_err());
        assert!(factors(&[(1, "t [furlong]")]).is_err());
    }
}
