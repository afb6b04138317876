//! Differential tests: the parser reads every line exactly as the earlier,
//! plainly written nom parser did (`tests/it/gcode_reference.rs`): the same items,
//! the same byte ranges, the same addresses, and word values equal to the
//! bit.

use crate::util;

use crate::gcode_reference::{RefItem, RefKind};
use kinpost::gcode::{ItemKind, Line, LineReader, parse_line};
use proptest::prelude::*;

/// The items of `line` in the reference's notation.
fn as_reference(line: &Line) -> Vec<RefItem> {
    line.items
        .iter()
        .map(|it| RefItem {
            start: it.start,
            end: it.end,
            kind: match &it.kind {
                ItemKind::Bom => RefKind::Bom,
                ItemKind::Space => RefKind::Space,
                ItemKind::EndOfLine => RefKind::EndOfLine,
                ItemKind::Percent => RefKind::Percent,
                ItemKind::BlockDelete => RefKind::BlockDelete,
                ItemKind::Comment => RefKind::Comment,
                ItemKind::Checksum(v) => RefKind::Checksum(*v),
                ItemKind::Word(w) => RefKind::Word {
                    address: w.address.to_string(),
                    value_bits: w.value.to_bits(),
                    value_start: w.value_start,
                    value_end: w.value_end,
                    assign: w.assign,
                },
                ItemKind::Keyword(k) => RefKind::Keyword(k.clone()),
                ItemKind::Opaque => RefKind::Opaque,
            },
        })
        .collect()
}

/// Parses `bytes` as line `number` with both parsers and compares.
fn same(bytes: &[u8], number: usize) -> Result<(), TestCaseError> {
    let line = parse_line(bytes, number);
    prop_assert!(line.is_tiled());
    prop_assert_eq!(&line.bytes[..], bytes);
    let want = crate::gcode_reference::parse_line(bytes, number);
    prop_assert_eq!(
        as_reference(&line),
        want,
        "line {:?}",
        String::from_utf8_lossy(bytes)
    );
    Ok(())
}

/// Every line of `src` read through the reader's reused line, against the
/// reference; the owned iterator gives the same lines.
fn same_program(src: &[u8]) -> Result<(), TestCaseError> {
    let mut reader = LineReader::new(src);
    let mut owned = LineReader::new(src);
    let mut pos = 0;
    while let Some(line) = reader.next_line() {
        let line = line.unwrap();
        let end = pos + line.bytes.len();
        prop_assert_eq!(&line.bytes[..], &src[pos..end]);
        let want = crate::gcode_reference::parse_line(&src[pos..end], line.number);
        prop_assert_eq!(as_reference(line), want);
        let o = owned.next().unwrap().unwrap();
        prop_assert_eq!(&o, line);
        pos = end;
    }
    prop_assert!(owned.next().is_none());
    prop_assert_eq!(pos, src.len());
    Ok(())
}

/// Pieces of G-code, good and bad, with the edges of the number scanner
/// and of the address length.
const TOKENS: &[&str] = &[
    "G1",
    "g01",
    "X",
    "x",
    "Y",
    "A3",
    "a3",
    "R12",
    "AP",
    "ap",
    "Ab",
    "N10",
    "O100",
    "o",
    "E",
    "XNAN",
    "Xinf",
    "xinfinity",
    "TRAORI",
    "trafoof",
    "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAA",
    "BBBBBBBBBBBBBBBBBBBBBBBBBBBBBBB",
    "CCCCCCCCCCCCCCCCCCCCCCCCCCCCCCCC",
    "1234567890",
    "9007199254740993",
    "9007199254740992",
    "12345678901234567890",
    "00000000000000000000000",
    "0.0000000000000000000000001",
    "99999999999999999999",
    "-",
    "+",
    ".",
    "5",
    "5.",
    ".5",
    "0",
    "007",
    "1e5",
    " ",
    "  ",
    "\t",
    "(",
    ")",
    "(c)",
    ";",
    "*",
    "*71",
    "*4294967296",
    "%",
    "/",
    "/1",
    "/0",
    "=",
    " = ",
    "#",
    "[",
    "]",
    "sub",
    "if",
    "\r",
    "\n",
    "\r\n",
    "\u{ef}\u{bb}\u{bf}",
    "\u{b0}",
    "@",
    ",",
    ":",
    "\u{0}",
];

fn token_soup() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(prop::sample::select(TOKENS), 0..30)
        .prop_map(|ts| ts.concat().into_bytes())
}

/// A word with a number of any length and form, as text.
fn number_word() -> impl Strategy<Value = String> {
    (
        "[XYZIJKxAB]",
        prop::sample::select(&["", " ", "="][..]),
        prop::sample::select(&["", "-", "+", "- ", "+\t"][..]),
        "[0-9]{0,24}",
        prop::option::of("[0-9]{0,24}"),
        prop::sample::select(&["", " ", "\r\n", "\n", "Y1", ";c", "(c)", "*5", "x", "."][..]),
    )
        .prop_map(|(letter, eq, sign, int, frac, after)| {
            let mut s = format!("{letter}{eq}{sign}{int}");
            if let Some(f) = frac {
                s.push('.');
                s.push_str(&f);
            }
            s.push_str(after);
            s
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn random_bytes(src in prop::collection::vec(any::<u8>(), 0..200), number in 1usize..3) {
        same(&src, number)?;
        same_program(&src)?;
    }

    #[test]
    fn random_ascii(src in "[ -~\t\r\n]{0,160}") {
        same(src.as_bytes(), 1)?;
        same_program(src.as_bytes())?;
    }

    #[test]
    fn token_soups(src in token_soup(), number in 1usize..3) {
        same(&src, number)?;
        same_program(&src)?;
    }

    #[test]
    fn numbers(words in prop::collection::vec(number_word(), 1..6)) {
        let src = words.concat();
        same(src.as_bytes(), 2)?;
    }

    #[test]
    fn long_numbers(int in "[0-9]{1,40}", frac in "[0-9]{0,40}", neg in any::<bool>()) {
        let src = format!("X{}{int}.{frac}\n", if neg { "-" } else { "" });
        same(src.as_bytes(), 2)?;
    }
}

/// Values in the fast path's corners parse to the same bits as `str::parse`.
#[test]
fn number_corners() {
    for text in [
        "0",
        "-0",
        "-0.0",
        "+.0",
        "9007199254740992",
        "9007199254740993",
        "9007199254740991.5",
        "0.1",
        "0.3",
        "123456789012345678",
        "1234567890123456789",
        "12345678901234567890",
        "18446744073709551615",
        "18446744073709551616",
        "1.0000000000000000000001",
        "0.0000000000000000000001",
        "0.00000000000000000000001",
        "4503599627370497.5",
        "31.000055260",
        "-0.123431940",
        "0.992353040",
        "1.7976931348623157",
        "00000000000000000000000000000000000000012.5",
        "2.50000000000000000000000000000000000000000",
    ] {
        for prefix in ["X", "X ", "A3=", "Y- "] {
            let src = format!("{prefix}{text}\n");
            same(src.as_bytes(), 3).unwrap();
        }
    }
}

/// The real programs of the corpus, line by line (skipped with a message
/// when `../shared` is absent; under CI that fails).
#[test]
fn corpus_lines() {
    let Some(dir) = util::shared_dir("corpus") else {
        return;
    };
    let mut files = 0;
    let mut stack = vec![dir];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if let Ok(src) = std::fs::read(&p) {
                same_program(&src).unwrap();
                files += 1;
            }
        }
    }
    eprintln!("{files} corpus files compared");
}

/// The benchmark program's kind of lines.
#[test]
fn spiral_lines() {
    let mut src = Vec::new();
    kinpost::demo::write_lens_spiral_program(&kinpost::demo::OffAxisLens::default(), 500, &mut src)
        .unwrap();
    same_program(&src).unwrap();
}
