//! Property tests: any bytes round-trip byte for byte and never panic;
//! well-formed blocks parse into exactly their words.

use kinpost::gcode::{ItemKind, Line, LineReader, echo, parse_line};
use proptest::prelude::*;

fn emit(line: &Line) -> Vec<u8> {
    let mut out = Vec::new();
    line.write_to(&mut out).unwrap();
    out
}

/// Invariants every parsed line keeps.
fn check_line(line: &Line) -> Result<(), TestCaseError> {
    prop_assert!(line.is_tiled(), "not tiled: {:?}", line);
    for (k, item) in line.items.iter().enumerate() {
        match &item.kind {
            ItemKind::Word(w) => {
                prop_assert!(w.value.is_finite());
                prop_assert!(!w.address.is_empty());
                prop_assert!(w.address.bytes().all(|b| !b.is_ascii_lowercase()));
            }
            ItemKind::EndOfLine => prop_assert_eq!(k, line.items.len() - 1),
            ItemKind::Opaque => {
                // Opaque runs to the line ending.
                let last = line.items.len() - 1;
                prop_assert!(
                    k == last || (k + 1 == last && line.items[last].kind == ItemKind::EndOfLine)
                );
            }
            _ => {}
        }
    }
    Ok(())
}

fn round_trip_file(src: &[u8]) -> Result<(), TestCaseError> {
    let mut out = Vec::new();
    for (k, line) in LineReader::new(src).enumerate() {
        let line = line.unwrap();
        check_line(&line)?;
        prop_assert_eq!(line.number, k + 1);
        line.write_to(&mut out).unwrap();
    }
    prop_assert_eq!(&out, &src);
    let mut echoed = Vec::new();
    echo(src, &mut echoed).unwrap();
    prop_assert_eq!(&echoed, &src);
    Ok(())
}

/// Pieces of G-code of every dialect, good and bad.
const TOKENS: &[&str] = &[
    "G1",
    "G0",
    "g01",
    "X",
    "Y",
    "Z",
    "A3",
    "R1",
    "N10",
    "O100",
    "o",
    "M6",
    "F",
    "T1",
    "E",
    "-",
    "+",
    ".",
    "5",
    "5.",
    ".5",
    "10",
    "007",
    "1e5",
    "nan",
    "inf",
    " ",
    "  ",
    "\t",
    "(",
    ")",
    "(c)",
    ";",
    "; x",
    "*",
    "*71",
    "%",
    "/",
    "/1",
    "=",
    "A3=0.5",
    "X=10",
    "R1=2",
    "TRAORI",
    "trafoof",
    "#",
    "#1=2",
    "#<a>",
    "[",
    "]",
    "[#1+2]",
    "<",
    ">",
    "o100 sub",
    "sub",
    "call",
    "if",
    "\r",
    "\n",
    "\r\n",
    "\u{ef}\u{bb}\u{bf}",
    "\u{b0}",
    "@",
    "^",
    ",",
    ":",
    "$",
    "\"",
    "\u{0}",
];

fn token_soup() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(prop::sample::select(TOKENS), 0..40)
        .prop_map(|ts| ts.concat().into_bytes())
}

/// A finite number written the ways G-code writes numbers.
fn number_text() -> impl Strategy<Value = (String, f64)> {
    (
        prop::sample::select(&["", "-", "+", "- "][..]),
        0u32..100_000,
        prop::option::of(0u32..10_000),
        any::<bool>(),
    )
        .prop_map(|(sign, int, frac, drop_int)| {
            let mut t = sign.to_string();
            match frac {
                Some(f) if drop_int => t.push_str(&format!(".{f}")),
                Some(f) => t.push_str(&format!("{int}.{f}")),
                None => t.push_str(&int.to_string()),
            }
            let v: f64 = t.replace(' ', "").parse().unwrap();
            (t, v)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_bytes_round_trip(src in prop::collection::vec(any::<u8>(), 0..300)) {
        round_trip_file(&src)?;
        // parse_line on the whole buffer (interior newlines and all).
        let line = parse_line(&src, 1);
        check_line(&line)?;
        prop_assert_eq!(emit(&line), src);
    }

    #[test]
    fn random_ascii_round_trips(src in "[ -~\t\r\n]{0,200}") {
        round_trip_file(src.as_bytes())?;
    }

    #[test]
    fn token_soup_round_trips(src in token_soup()) {
        round_trip_file(&src)?;
        let line = parse_line(&src, 1);
        check_line(&line)?;
        prop_assert_eq!(emit(&line), src);
    }

    #[test]
    fn well_formed_blocks_parse_into_their_words(
        words in prop::collection::vec(
            (prop::sample::select(&["G", "X", "y", "Z", "a", "B", "C", "F", "S", "M", "N", "I", "J", "K"][..]), number_text(), any::<bool>()),
            1..12,
        ),
        sep in prop::sample::select(&["", " ", "\t", "  "][..]),
        ending in prop::sample::select(&["", "\n", "\r\n"][..]),
        comment in prop::option::of("[ -'*-~]{0,20}"),
    ) {
        let mut src = String::new();
        for (letter, (num, _), space_after_letter) in &words {
            src.push_str(letter);
            if *space_after_letter { src.push(' '); }
            src.push_str(num);
            src.push_str(if sep.is_empty() { "" } else { sep });
        }
        if let Some(c) = &comment { src.push('('); src.push_str(c); src.push(')'); }
        src.push_str(ending);
        // Without separators, a number may run into the next word only if
        // the next word starts with a letter, which it always does.
        let line = parse_line(src.as_bytes(), 1);
        check_line(&line)?;
        prop_assert!(!line.has_opaque(), "opaque in {:?}: {:?}", src, line.items);
        let got: Vec<(String, f64)> = line.words().map(|w| (w.address.to_string(), w.value)).collect();
        let want: Vec<(String, f64)> = words.iter().map(|(l, (_, v), _)| (l.to_ascii_uppercase(), *v)).collect();
        prop_assert_eq!(got, want);
        for (w, (_, (num, _), _)) in line.words().zip(&words) {
            prop_assert_eq!(line.value_text(w), num.as_bytes());
        }
        prop_assert_eq!(line.comments().count(), usize::from(comment.is_some()));
    }
}
