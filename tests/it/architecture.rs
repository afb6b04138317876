//! The shape of the code, checked: the module graph drawn from the `crate::`
//! and `super::` paths of every file under `src/` (comments and test
//! modules left out).
//!
//! - Imports point down the data flow gcode → program → machine → geometric
//!   → compensate / linkage / diagnose → report → cli: no module of gcode,
//!   program, machine or geometric names diagnose, compensate, linkage or
//!   cli.
//! - No import circle between files.
//!
//! What is still left is listed here, and the lists may only shrink: an
//! entry that no longer holds fails the test, so that it is struck off.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Upward imports not yet removed: (file, the higher module it names).
const KNOWN_UPWARD: &[(&str, &str)] = &[];

/// Import circles not yet broken, each as its sorted list of files.
const KNOWN_CYCLES: &[&[&str]] = &[];

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a file: `src/machine/ik.rs` → [machine, ik];
/// `src/compensate/mod.rs` → [compensate]; `src/lib.rs` → [].
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without its test module.
fn code(text: &str) -> String {
    let body = text.split("#[cfg(test)]").next().unwrap_or("");
    body.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Module paths named in `code`, absolute (from the crate root), for a
/// file whose module is `me`. `crate::a::b::{c, d::e}` gives a::b::c and
/// a::b::d::e; `super::x` is resolved against `me`.
fn named_paths(code: &str, me: &[String], is_mod_file: bool) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let bytes: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < bytes.len() {
        let rest: String = bytes[i..bytes.len().min(i + 7)].iter().collect();
        let starts = (rest.starts_with("crate::") || rest.starts_with("super::"))
            && (i == 0
                || !(bytes[i - 1].is_alphanumeric() || bytes[i - 1] == '_' || bytes[i - 1] == ':'));
        if !starts {
            i += 1;
            continue;
        }
        // Read the path up to a brace or a non-path character.
        let mut j = i;
        while j < bytes.len() && (bytes[j].is_alphanumeric() || bytes[j] == '_' || bytes[j] == ':')
        {
            j += 1;
        }
        let head: String = bytes[i..j].iter().collect();
        let head = head.trim_end_matches(':').to_string();
        let mut tails = vec![String::new()];
        if j < bytes.len() && bytes[j] == '{' {
            // One level of braces, items split at top-level commas.
            let mut depth = 0;
            let mut k = j;
            let mut item = String::new();
            tails.clear();
            while k < bytes.len() {
                let c = bytes[k];
                match c {
                    '{' => {
                        depth += 1;
                        if depth > 1 {
                            item.push(c);
                        }
                    }
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            tails.push(item.trim().to_string());
                            break;
                        }
                        item.push(c);
                    }
                    ',' if depth == 1 => {
                        tails.push(item.trim().to_string());
                        item.clear();
                    }
                    _ => item.push(c),
                }
                k += 1;
            }
            j = k;
        }
        for tail in tails {
            let tail_path: String = tail.split(['{', ' ', '}']).next().unwrap_or("").to_string();
            let full = if tail_path.is_empty() {
                head.clone()
            } else {
                format!("{head}::{tail_path}")
            };
            let mut segs: Vec<&str> = full.split("::").filter(|s| !s.is_empty()).collect();
            let mut path: Vec<String> = Vec::new();
            match segs.first() {
                Some(&"crate") => {
                    segs.remove(0);
                }
                Some(&"super") => {
                    // The parent of this module (a mod.rs file is its directory's module).
                    path = me.to_vec();
                    let _ = is_mod_file;
                    while segs.first() == Some(&"super") {
                        segs.remove(0);
                        path.pop();
                    }
                }
                _ => {}
            }
            path.extend(segs.iter().map(|s| s.to_string()));
            out.push(path);
        }
        i = j.max(i + 1);
    }
    out
}

/// The file (module path) a named path lands in: its longest prefix that
/// is a module of the crate.
fn resolve(path: &[String], modules: &BTreeSet<Vec<String>>) -> Option<Vec<String>> {
    (1..=path.len())
        .rev()
        .map(|n| path[..n].to_vec())
        .find(|p| modules.contains(p))
}

/// Strongly connected components of more than one file (Tarjan).
fn cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'g> {
        graph: &'g BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit(s: &mut State, v: &str) {
        s.index.insert(v.to_string(), s.next);
        s.low.insert(v.to_string(), s.next);
        s.next += 1;
        s.stack.push(v.to_string());
        s.on.insert(v.to_string());
        let succ: Vec<String> = s
            .graph
            .get(v)
            .map(|x| x.iter().cloned().collect())
            .unwrap_or_default();
        for w in succ {
            if !s.index.contains_key(&w) {
                visit(s, &w);
                let lw = s.low[&w];
                let lv = s.low[v];
                s.low.insert(v.to_string(), lv.min(lw));
            } else if s.on.contains(&w) {
                let iw = s.index[&w];
                let lv = s.low[v];
                s.low.insert(v.to_string(), lv.min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(&w);
                comp.push(w.clone());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn imports_point_down_the_flow_and_form_no_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    all.sort();
    let rel = |p: &Path| p.strip_prefix(&src).unwrap().to_path_buf();
    let mut module_file: BTreeMap<Vec<String>, String> = BTreeMap::new();
    for p in &all {
        if rel(p) == Path::new("main.rs") {
            continue; // the binary is its own crate
        }
        module_file.insert(module_of(&rel(p)), rel(p).display().to_string());
    }
    let modules: BTreeSet<Vec<String>> = module_file.keys().cloned().collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut upward = BTreeSet::new();
    let low = ["gcode", "program", "machine", "geometric"];
    let high = ["diagnose", "compensate", "linkage", "cli"];
    for (module, file) in &module_file {
        let text = std::fs::read_to_string(src.join(file)).unwrap();
        // A module file: `x/mod.rs`, `lib.rs`, or `x.rs` beside a directory `x/`.
        let is_mod = file.ends_with("mod.rs")
            || file == "lib.rs"
            || src.join(file.trim_end_matches(".rs")).is_dir();
        let edges = graph.entry(file.clone()).or_default();
        for path in named_paths(&code(&text), module, is_mod) {
            let Some(target) = resolve(&path, &modules) else {
                continue;
            };
            let target_file = &module_file[&target];
            // A module file naming its own submodules is not an import.
            let child = target.len() > module.len() && target.starts_with(module) && is_mod;
            if target_file != file && !child && file != "lib.rs" {
                edges.insert(target_file.clone());
            }
            if let (Some(from), Some(to)) = (module.first(), target.first())
                && low.contains(&from.as_str())
                && high.contains(&to.as_str())
            {
                upward.insert((file.clone(), to.clone()));
            }
        }
    }
    let known_up: BTreeSet<(String, String)> = KNOWN_UPWARD
        .iter()
        .map(|(f, m)| (f.to_string(), m.to_string()))
        .collect();
    let new_up: Vec<_> = upward.difference(&known_up).collect();
    assert!(new_up.is_empty(), "imports running up the flow: {new_up:?}");
    let gone_up: Vec<_> = known_up.difference(&upward).collect();
    assert!(
        gone_up.is_empty(),
        "fixed, strike them off KNOWN_UPWARD: {gone_up:?}"
    );

    // The graph sees what it should: a sanity check of the path reading.
    assert!(
        graph["compensate/refine.rs"].contains("compensate/step.rs"),
        "{graph:?}"
    );
    assert!(graph["geometric/merged.rs"].contains("geometric/axis_errors.rs"));
    assert!(graph["machine/ik.rs"].contains("machine/chain.rs"));
    let found = cycles(&graph);
    let known: Vec<Vec<String>> = KNOWN_CYCLES
        .iter()
        .map(|c| c.iter().map(|s| s.to_string()).collect())
        .collect();
    let new_cycles: Vec<_> = found.iter().filter(|c| !known.contains(c)).collect();
    assert!(
        new_cycles.is_empty(),
        "import circles between files: {new_cycles:?}"
    );
    let gone: Vec<_> = known.iter().filter(|c| !found.contains(c)).collect();
    assert!(
        gone.is_empty(),
        "broken, strike them off KNOWN_CYCLES: {gone:?}"
    );
}

#[test]
fn circles_are_found() {
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec!["a"]),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.into_iter().map(String::from).collect()))
    .collect();
    assert_eq!(
        cycles(&g),
        vec![vec!["a".to_string(), "b".into(), "c".into()]]
    );
}

#[test]
fn no_source_file_is_over_1000_lines() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let long: Vec<_> = all
        .iter()
        .map(|p| {
            (
                p.strip_prefix(&src).unwrap().display().to_string(),
                std::fs::read_to_string(p).unwrap().lines().count(),
            )
        })
        .filter(|(_, n)| *n > 1000)
        .collect();
    // Left to split (the list may only shrink).
    let known: [&str; 0] = [];
    let new: Vec<_> = long
        .iter()
        .filter(|(f, _)| !known.contains(&f.as_str()))
        .collect();
    assert!(new.is_empty(), "files over 1,000 lines: {new:?}");
    let gone: Vec<_> = known
        .iter()
        .filter(|k| !long.iter().any(|(f, _)| f == *k))
        .collect();
    assert!(
        gone.is_empty(),
        "now short enough, strike them off: {gone:?}"
    );
}
