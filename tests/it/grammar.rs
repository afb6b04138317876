//! Keeps `grammar/*.ebnf` true: the examples written in the grammar files
//! are checked against the parsers, and the grammars are checked to be
//! closed (every name used is defined, every production is used).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;

use kinpost::cl::{ClReader, ClStatement};
use kinpost::gcode::{ItemKind, parse_line};

const GCODE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/grammar/gcode.ebnf");
const APT_CL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/grammar/apt-cl.ebnf");

/// One `(* example: INPUT -> KINDS *)` or `(* counterexample: ... *)`.
#[derive(Debug)]
struct Example {
    line: usize,
    counter: bool,
    input: Vec<u8>,
    kinds: Vec<String>,
}

/// Undo the escapes `\t \r \n \\ \xHH`.
fn unescape(s: &str, line: usize) -> Vec<u8> {
    let mut out = Vec::new();
    let b = s.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'\\' && i + 1 < b.len() {
            match b[i + 1] {
                b't' => out.push(b'\t'),
                b'r' => out.push(b'\r'),
                b'n' => out.push(b'\n'),
                b'\\' => out.push(b'\\'),
                b'x' => {
                    let hex = s
                        .get(i + 2..i + 4)
                        .unwrap_or_else(|| panic!("line {line}: bad \\x escape"));
                    out.push(
                        u8::from_str_radix(hex, 16)
                            .unwrap_or_else(|_| panic!("line {line}: bad \\x{hex}")),
                    );
                    i += 2;
                }
                other => panic!("line {line}: unknown escape \\{}", other as char),
            }
            i += 2;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    out
}

fn examples(text: &str) -> Vec<Example> {
    let mut out = Vec::new();
    for (k, l) in text.lines().enumerate() {
        let l = l.trim();
        let (counter, rest) = if let Some(r) = l.strip_prefix("(* example: ") {
            (false, r)
        } else if let Some(r) = l.strip_prefix("(* counterexample: ") {
            (true, r)
        } else {
            continue;
        };
        let rest = rest
            .strip_suffix("*)")
            .unwrap_or_else(|| panic!("line {}: example must end with *)", k + 1));
        let (input, kinds) = rest
            .rsplit_once(" -> ")
            .unwrap_or_else(|| panic!("line {}: example needs ' -> '", k + 1));
        out.push(Example {
            line: k + 1,
            counter,
            input: unescape(input, k + 1),
            kinds: kinds.split_whitespace().map(str::to_string).collect(),
        });
    }
    out
}

/// The kinds of a parsed G-code line, Space left out, in the notation of
/// the examples. `detail` adds values: `Word(X,-1.5)`.
fn gcode_kinds(input: &[u8]) -> Vec<(String, String)> {
    let line = parse_line(input, 1);
    assert!(line.is_tiled());
    let mut out = Vec::new();
    line.write_to(&mut out).unwrap();
    assert_eq!(out, input, "echo differs");
    line.items
        .iter()
        .filter(|it| it.kind != ItemKind::Space)
        .map(|it| match &it.kind {
            ItemKind::Word(w) => (
                "Word".to_string(),
                format!(
                    "Word({},{}{})",
                    w.address,
                    w.value,
                    if w.assign { ",=" } else { "" }
                ),
            ),
            ItemKind::Keyword(k) => ("Keyword".into(), format!("Keyword({k})")),
            ItemKind::Checksum(v) => ("Checksum".into(), format!("Checksum({v})")),
            other => {
                let name = format!("{other:?}");
                (name.clone(), name)
            }
        })
        .collect()
}

/// Does the expected `want` (`Word` or `Word(X,1)`) match `got`?
fn matches(want: &str, got: &(String, String)) -> bool {
    if want.contains('(') {
        // Compare values numerically so that `Word(X,5.0)` and `Word(X,5)` agree.
        if let (Some((wa, wv)), Some((ga, gv))) = (split_word(want), split_word(&got.1)) {
            return wa == ga && wv == gv;
        }
        want == got.1
    } else {
        want == got.0
    }
}

/// `Word(A,v[,=])` into (`"A,="`, v).
fn split_word(s: &str) -> Option<(String, f64)> {
    let inner = s.strip_prefix("Word(")?.strip_suffix(')')?;
    let mut parts = inner.split(',');
    let addr = parts.next()?;
    let value: f64 = parts.next()?.parse().ok()?;
    let rest: Vec<&str> = parts.collect();
    Some((format!("{addr},{}", rest.join(",")), value))
}

#[test]
fn gcode_grammar_examples_hold() {
    let text = fs::read_to_string(GCODE).expect("grammar/gcode.ebnf");
    let examples = examples(&text);
    assert!(examples.len() >= 60, "only {} examples", examples.len());
    let mut failures = Vec::new();
    let mut seen = BTreeSet::new();
    for ex in &examples {
        let has_opaque = ex.kinds.iter().any(|k| k == "Opaque");
        if has_opaque != ex.counter {
            failures.push(format!(
                "gcode.ebnf:{}: an example must not expect Opaque, a counterexample must",
                ex.line
            ));
        }
        let got = gcode_kinds(&ex.input);
        let ok =
            got.len() == ex.kinds.len() && ex.kinds.iter().zip(&got).all(|(w, g)| matches(w, g));
        if !ok {
            failures.push(format!(
                "gcode.ebnf:{}: {:?}: grammar says [{}], parser gives [{}]",
                ex.line,
                String::from_utf8_lossy(&ex.input),
                ex.kinds.join(" "),
                got.iter()
                    .map(|g| g.1.as_str())
                    .collect::<Vec<_>>()
                    .join(" ")
            ));
        }
        for g in got {
            seen.insert(g.0);
        }
    }
    for kind in [
        "Bom",
        "EndOfLine",
        "Percent",
        "BlockDelete",
        "Comment",
        "Checksum",
        "Word",
        "Keyword",
        "Opaque",
    ] {
        if !seen.contains(kind) {
            failures.push(format!("gcode.ebnf: no example shows a {kind}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    println!("gcode.ebnf: {} examples hold", examples.len());
}

fn cl_kind(s: &ClStatement) -> &'static str {
    match s {
        ClStatement::Goto { .. } => "Goto",
        ClStatement::Fedrat { .. } => "Fedrat",
        ClStatement::Rapid => "Rapid",
        ClStatement::TlAxis(_) => "TlAxis",
        ClStatement::Multax(_) => "Multax",
        ClStatement::LoadTl { .. } => "LoadTl",
        ClStatement::Spindle { .. } => "Spindle",
        ClStatement::Coolant(_) => "Coolant",
        ClStatement::Units(_) => "Units",
        ClStatement::Comment(_) => "Comment",
        ClStatement::End => "End",
        ClStatement::Other { .. } => "Other",
        ClStatement::Block(_) => "Block",
        ClStatement::CutterCompensation { .. } => "CutterCompensation",
        ClStatement::Warning(_) => "Warning",
        ClStatement::Arc(_) => "Arc",
        ClStatement::Hole(_) => "Hole",
    }
}

#[test]
fn apt_cl_grammar_examples_hold() {
    let text = fs::read_to_string(APT_CL).expect("grammar/apt-cl.ebnf");
    let examples = examples(&text);
    assert!(examples.len() >= 40, "only {} examples", examples.len());
    let mut failures = Vec::new();
    let mut seen = BTreeSet::new();
    for ex in &examples {
        let got: Vec<String> = ClReader::new(ex.input.as_slice(), "ex")
            .map(|r| match r {
                Ok(rec) => cl_kind(&rec.statement).to_string(),
                Err(_) => "Error".to_string(),
            })
            .collect();
        if (ex.kinds == ["Error"]) != ex.counter {
            failures.push(format!(
                "apt-cl.ebnf:{}: a counterexample expects Error, an example a statement",
                ex.line
            ));
        }
        if got != ex.kinds {
            failures.push(format!(
                "apt-cl.ebnf:{}: {:?}: grammar says [{}], reader gives [{}]",
                ex.line,
                String::from_utf8_lossy(&ex.input),
                ex.kinds.join(" "),
                got.join(" ")
            ));
        }
        seen.extend(got);
    }
    for kind in [
        "Goto", "Fedrat", "Rapid", "TlAxis", "Multax", "LoadTl", "Spindle", "Coolant", "Units",
        "Comment", "End", "Other", "Error",
    ] {
        if !seen.contains(kind) {
            failures.push(format!("apt-cl.ebnf: no example shows {kind}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    println!("apt-cl.ebnf: {} examples hold", examples.len());
}

/// The productions of an EBNF text: name -> names used on its right side.
/// Comments, terminal strings and special sequences are skipped.
fn productions(text: &str) -> Result<BTreeMap<String, BTreeSet<String>>, String> {
    // Strip comments, strings and special sequences, keeping the rest.
    let b = text.as_bytes();
    let mut clean = String::new();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"(*") {
            let end = text[i + 2..].find("*)").ok_or("unterminated comment")?;
            i += 2 + end + 2;
            clean.push(' ');
        } else if matches!(b[i], b'"' | b'\'' | b'?') {
            let close = b[i] as char;
            let end = text[i + 1..]
                .find(close)
                .ok_or_else(|| format!("unterminated {close} at byte {i}"))?;
            i += 1 + end + 1;
            clean.push_str(" \u{1} ");
        } else {
            clean.push(b[i] as char);
            i += 1;
        }
    }
    let mut out = BTreeMap::new();
    for rule in clean.split(';') {
        if rule.trim().is_empty() {
            continue;
        }
        let (lhs, rhs) = rule
            .split_once('=')
            .ok_or_else(|| format!("no '=' in {:?}", rule.trim()))?;
        let lhs = lhs.trim().to_string();
        if !is_identifier(&lhs) {
            return Err(format!("bad production name {lhs:?}"));
        }
        let used: BTreeSet<String> = rhs
            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .filter(|w| !w.is_empty())
            .map(str::to_string)
            .collect();
        if let Some(bad) = used.iter().find(|w| !is_identifier(w)) {
            return Err(format!("{lhs}: stray {bad:?} outside quotes"));
        }
        if out.insert(lhs.clone(), used).is_some() {
            return Err(format!("{lhs} is defined twice"));
        }
    }
    Ok(out)
}

fn is_identifier(s: &str) -> bool {
    s.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

fn roots(text: &str) -> BTreeSet<String> {
    text.lines()
        .find_map(|l| l.trim().strip_prefix("(* roots:"))
        .and_then(|r| r.strip_suffix("*)"))
        .expect("a (* roots: ... *) comment")
        .split_whitespace()
        .map(str::to_string)
        .collect()
}

fn check_closed(path: &str) {
    let text = fs::read_to_string(path).unwrap();
    let prods = productions(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    let roots = roots(&text);
    let used: BTreeSet<&String> = prods.values().flatten().collect();
    let mut problems = Vec::new();
    for (name, refs) in &prods {
        for r in refs {
            if !prods.contains_key(r) {
                problems.push(format!("{name} uses {r}, which is not defined"));
            }
        }
        if !roots.contains(name) && !used.contains(name) {
            problems.push(format!("{name} is defined but never used"));
        }
    }
    for r in &roots {
        if !prods.contains_key(r) {
            problems.push(format!("root {r} is not defined"));
        }
    }
    assert!(problems.is_empty(), "{path}:\n{}", problems.join("\n"));
    assert!(
        prods.len() >= 10,
        "{path}: only {} productions",
        prods.len()
    );
}

#[test]
fn gcode_grammar_is_closed() {
    check_closed(GCODE);
}

#[test]
fn apt_cl_grammar_is_closed() {
    check_closed(APT_CL);
}

#[test]
fn checker_catches_disagreement() {
    // The checks above would notice a wrong grammar.
    let wrong = gcode_kinds(b"X1.2.3");
    assert!(!(wrong.len() == 1 && matches("Word", &wrong[0])));
    assert!(productions("a = b ;").is_ok());
    assert!(productions("a = b ; a = c ;").is_err());
    assert!(productions("a = 'x ;").is_err());
    let p = productions("a = b , \"c\" , ? d e ? ; (* x = y ; *) b = 'q' ;").unwrap();
    assert_eq!(p.len(), 2);
    assert_eq!(p["a"].iter().collect::<Vec<_>>(), ["b"]);
    let ex =
        examples("(* example: G1\\tX\\x41 -> Word Word *)\n(* counterexample: #1 -> Opaque *)");
    assert_eq!(ex.len(), 2);
    assert_eq!(ex[0].input, b"G1\tXA");
    assert!(ex[1].counter);
}
