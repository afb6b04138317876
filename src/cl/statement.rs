//! The grammar of one APT CL statement (`grammar/apt-cl.ebnf`): its
//! major word, and the arguments of the statements the converter
//! interprets (`GOTO`, `FEDRAT`, `LOADTL`, `SPINDL`, ...); every other
//! statement is kept as [`ClStatement::Other`].

use super::{
    Arg, ClStatement, ClUnits, FeedUnit, In, PResult, SpindleDir, StatementError, is_blank,
    major_word, major_words, non_zero, split_args, trim, vector,
};
use nom::{Parser, bytes::complete::tag, bytes::complete::take_while};

/// Majors whose text after the major word is free text, not `/args`.
const TEXT_MAJORS: &[&str] = &["PARTNO", "PPRINT", "INSERT", "REMARK"];

/// Majors that are interpreted only with `/args`.
const NEEDS_ARGS: &[&str] = &[
    "GOTO", "TLAXIS", "FEDRAT", "LOADTL", "UNITS", "SPINDL", "COOLNT",
];

/// Interpret one logical statement (starts at its first non-blank byte).
pub(super) fn parse_statement(text: &[u8]) -> Result<ClStatement, StatementError> {
    // A statement label (`A1) GOTO/10,0,0`, APT and NCL part programs): a
    // target of the jumps kinpost refuses (`JUMPTO`, `IF`), so the
    // statement after it is read as if the label were not there.
    if let Ok((rest, label)) = major_word(text)
        && let after = trim(rest)
        && after.first() == Some(&b')')
    {
        let statement = trim(&after[1..]);
        if statement.is_empty() {
            return Ok(ClStatement::Comment(format!(
                "label {}",
                String::from_utf8_lossy(label)
            )));
        }
        let skip = statement.as_ptr() as usize - text.as_ptr() as usize;
        return parse_statement(statement).map_err(|mut e| {
            e.offset += skip;
            e
        });
    }
    let Ok((rest, major_raw)) = major_words(text) else {
        return Err(StatementError {
            offset: 0,
            message: "expected an APT statement (`MAJOR/args` or `MAJOR`)".into(),
        });
    };
    // The first word alone, for statements without `/`.
    let first_raw = major_word(text).map(|(_, w)| w).unwrap_or_default();
    let first_known = known_major(first_raw);
    let after_first = trim(&text[first_raw.len()..]);
    if first_known == Some("INSERT") {
        let slash = usize::from(after_first.first() == Some(&b'/'));
        let body = String::from_utf8_lossy(&after_first[slash..]);
        let at = after_first.as_ptr() as usize - text.as_ptr() as usize + slash;
        match super::insert::inserted(&body) {
            Ok(super::insert::Inserted::Code(block)) => return Ok(ClStatement::Block(block)),
            Ok(super::insert::Inserted::Text) => {}
            Err((offset, message)) => {
                return Err(StatementError {
                    offset: at + offset,
                    message,
                });
            }
        }
    }
    if let Some(word) = first_known.filter(|w| TEXT_MAJORS.contains(w)) {
        return Ok(ClStatement::Other {
            major: word.to_string(),
            text: String::from_utf8_lossy(after_first).into_owned(),
        });
    }
    let slash: PResult<In> = (take_while(is_blank), tag(&b"/"[..]))
        .parse_complete(rest)
        .map(|(r, _)| (r, r));
    let Ok((args_text, _)) = slash else {
        // No slash: a bare major word, possibly followed by free text.
        if let Some(word) = first_known.filter(|w| NEEDS_ARGS.contains(w)) {
            return Err(StatementError {
                offset: first_raw.len(),
                message: format!("expected `/` and arguments after {word}"),
            });
        }
        return Ok(bare(collapse_upper(first_raw), after_first));
    };
    // The major word(s), uppercased, blanks collapsed (no allocation for
    // the majors interpreted here).
    let major: std::borrow::Cow<'static, str> = match first_known {
        Some(word) if major_raw.len() == first_raw.len() => word.into(),
        // NCL's abbreviations of GOTO and RAPID.
        _ if major_raw.eq_ignore_ascii_case(b"GT") => "GOTO".into(),
        _ if major_raw.eq_ignore_ascii_case(b"RP") => "RAPID".into(),
        _ => collapse_upper(major_raw).into(),
    };
    let args_offset = text.len() - args_text.len();
    let args = split_args(args_text, args_offset);
    let at_major = Arg {
        text: &text[..major_raw.len()],
        offset: 0,
    };
    let other = || ClStatement::Other {
        major: major.to_string(),
        text: String::from_utf8_lossy(trim(args_text)).into_owned(),
    };
    let count_err = |want: &str| {
        at_major.err(format!(
            "{major} expects {want}, found {} argument{}",
            args.len(),
            if args.len() == 1 { "" } else { "s" }
        ))
    };
    match &*major {
        "GOTO" => {
            if args.len() != 3 && args.len() != 6 {
                return Err(count_err("3 numbers (x,y,z) or 6 (x,y,z,i,j,k)"));
            }
            let tip = vector(&args[..3], "a coordinate")?;
            let axis = if args.len() == 6 {
                let v = vector(&args[3..], "a tool axis component")?;
                Some(non_zero(v, &args[3], "the tool axis")?)
            } else {
                None
            };
            Ok(ClStatement::Goto { tip, axis })
        }
        "TLAXIS" => {
            if args.len() != 3 {
                return Err(count_err("3 numbers (i,j,k)"));
            }
            let v = vector(&args, "a tool axis component")?;
            Ok(ClStatement::TlAxis(non_zero(v, &args[0], "the tool axis")?))
        }
        "FEDRAT" => fedrat(&args).ok_or_else(|| {
            count_err("a feed rate, optionally with a unit: `FEDRAT/[MMPM|IPM|MMPR|IPR|PERMIN,]f`")
        })?,
        "LOADTL" => {
            let Some(first) = args.first() else {
                return Err(count_err("a tool number"));
            };
            match first.number() {
                Some(n) if n >= 0.0 && n.fract() == 0.0 && n <= f64::from(u32::MAX) => {
                    let register = |a: &Arg| super::lower::LENGTH_REGISTER.iter().any(|w| a.is(w));
                    let adjust = match args.iter().position(register) {
                        None => None,
                        Some(k) => match args.get(k + 1).and_then(|h| h.number()) {
                            Some(h) if h >= 0.0 && h.fract() == 0.0 && h < 1e9 => Some(h as u32),
                            _ => {
                                return Err(args[k].err(
                                    "expected a whole register number after ADJUST, OFFSET or OSETNO (LOADTL/n,ADJUST,h)",
                                ));
                            }
                        },
                    };
                    Ok(ClStatement::LoadTl {
                        tool: n as u32,
                        adjust,
                    })
                }
                _ => Err(first.err(format!(
                    "expected a tool number (a whole number), found `{}`",
                    String::from_utf8_lossy(first.text)
                ))),
            }
        }
        "MULTAX" => match args.as_slice() {
            [] => Ok(ClStatement::Multax(true)),
            [a] if a.is("ON") => Ok(ClStatement::Multax(true)),
            [a] if a.is("OFF") => Ok(ClStatement::Multax(false)),
            [a, ..] => Err(a.err(format!(
                "expected MULTAX/ON or MULTAX/OFF, found `{}`",
                a.upper()
            ))),
        },
        "UNITS" => match args.as_slice() {
            [a] if a.is("MM") => Ok(ClStatement::Units(ClUnits::Mm)),
            [a] if a.is("INCHES") || a.is("INCH") => Ok(ClStatement::Units(ClUnits::Inches)),
            [a, ..] => Err(a.err(format!(
                "expected UNITS/MM or UNITS/INCHES, found `{}`",
                a.upper()
            ))),
            [] => Err(count_err("MM or INCHES")),
        },
        "COOLNT" => match args.as_slice() {
            [a, ..] if a.is("OFF") => Ok(ClStatement::Coolant(false)),
            [a, ..]
                if ["ON", "FLOOD", "MIST", "THRU", "AIR", "TAPKUL"]
                    .iter()
                    .any(|w| a.is(w)) =>
            {
                Ok(ClStatement::Coolant(true))
            }
            _ => Ok(other()),
        },
        "SPINDL" => spindle(&args).map(|s| s.unwrap_or_else(other)),
        "RAPID" => Ok(ClStatement::Rapid),
        "FINI" | "END" => Ok(ClStatement::End),
        _ => Ok(other()),
    }
}

/// A bare statement (no `/`).
fn bare(major: String, after: &[u8]) -> ClStatement {
    match (major.as_str(), after.is_empty()) {
        ("RAPID" | "RP", true) => ClStatement::Rapid,
        ("FINI" | "END", true) => ClStatement::End,
        ("MULTAX", true) => ClStatement::Multax(true),
        _ => ClStatement::Other {
            major,
            text: String::from_utf8_lossy(after).into_owned(),
        },
    }
}

/// The major words interpreted here (`NEEDS_ARGS`, `TEXT_MAJORS`, the
/// bare ones), as written in this list: `word` compared without case.
const KNOWN_MAJORS: &[&str] = &[
    "GOTO", "TLAXIS", "FEDRAT", "LOADTL", "UNITS", "SPINDL", "COOLNT", "MULTAX", "RAPID", "FINI",
    "END", "PARTNO", "PPRINT", "INSERT", "REMARK",
];

/// `word` uppercased, when it is one of [`KNOWN_MAJORS`].
fn known_major(word: &[u8]) -> Option<&'static str> {
    KNOWN_MAJORS
        .iter()
        .copied()
        .find(|k| word.eq_ignore_ascii_case(k.as_bytes()))
}

/// Uppercase, blanks collapsed to one space.
fn collapse_upper(s: &[u8]) -> String {
    let mut out = String::with_capacity(s.len());
    for word in String::from_utf8_lossy(s)
        .split([' ', '\t'])
        .filter(|w| !w.is_empty())
    {
        if !out.is_empty() {
            out.push(' ');
        }
        out.push_str(word);
    }
    out.make_ascii_uppercase();
    out
}

pub(super) fn feed_unit(a: &Arg) -> Option<FeedUnit> {
    [
        ("MMPM", FeedUnit::Mmpm),
        ("IPM", FeedUnit::Ipm),
        ("MMPR", FeedUnit::Mmpr),
        ("IPR", FeedUnit::Ipr),
    ]
    .into_iter()
    .find(|(w, _)| a.is(w))
    .map(|(_, u)| u)
}

/// `FEDRAT/f`, `FEDRAT/unit,f` or `FEDRAT/f,unit`; `None` if malformed.
fn fedrat(args: &[Arg]) -> Option<Result<ClStatement, StatementError>> {
    let (value_arg, unit) = match args {
        [f] if feed_unit(f).is_none() => (f, FeedUnit::Unspecified),
        [u, f] if feed_unit(u).is_some() => (f, feed_unit(u)?),
        // DMG MORI's `FEDRAT/ PERMIN, f`: per minute, in the program's units.
        [u, f] if u.is("PERMIN") => (f, FeedUnit::Unspecified),
        [f, u] if feed_unit(u).is_some() => (f, feed_unit(u)?),
        _ => return None,
    };
    Some(match value_arg.expect_number("a feed rate") {
        Ok(v) if v >= 0.0 => Ok(ClStatement::Fedrat { value: v, unit }),
        Ok(_) => Err(value_arg.err("expected a feed rate that is not negative")),
        Err(e) => Err(e),
    })
}

/// `SPINDL/OFF`, `SPINDL/ON`, `SPINDL/[RPM,]s[,CLW|CCLW][,RANGE,n|MAXRPM,n]`.
/// `Ok(None)`: a form not interpreted (surface speed, unknown words).
fn spindle(args: &[Arg]) -> Result<Option<ClStatement>, StatementError> {
    let mut rpm = None;
    let mut dir = None;
    let mut on = false;
    let mut k = 0;
    while let Some(a) = args.get(k) {
        if a.is("OFF") && args.len() == 1 {
            return Ok(Some(ClStatement::Spindle {
                rpm: None,
                dir: None,
                off: true,
            }));
        } else if a.is("RPM") && rpm.is_some() && k == 1 {
            // `SPINDL/n,RPM,...`: the unit after the speed.
        } else if a.is("RPM") {
            let Some(v) = args.get(k + 1) else {
                return Err(a.err("expected a speed after RPM"));
            };
            rpm = Some(v.expect_number("a spindle speed")?);
            k += 1;
        } else if a.is("RANGE") || a.is("MAXRPM") {
            let Some(v) = args.get(k + 1) else {
                return Err(a.err(format!("expected a number after {}", a.upper())));
            };
            v.expect_number("a number")?;
            k += 1;
        } else if a.is("CLW") {
            dir = Some(SpindleDir::Clockwise);
        } else if a.is("CCLW") {
            dir = Some(SpindleDir::CounterClockwise);
        } else if a.is("ON") {
            on = true;
        } else if k == 0 && a.number().is_some() {
            rpm = a.number();
        } else {
            return Ok(None);
        }
        k += 1;
    }
    // No speed, direction or `ON`: a setting (`RANGE,n`, `MAXRPM,n`), not a
    // start of the spindle (`lower` reads it).
    if args.is_empty() || (rpm.is_none() && dir.is_none() && !on) {
        return Ok(None);
    }
    if rpm.is_some_and(|v| v < 0.0) {
        return Err(args[0].err("expected a spindle speed that is not negative"));
    }
    Ok(Some(ClStatement::Spindle {
        rpm,
        dir,
        off: false,
    }))
}
