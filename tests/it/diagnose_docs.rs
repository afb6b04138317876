//! The worked examples of `docs/diagnose.md`.
//!
//! - The first is run from the commands written in the document, on the
//!   shipped fixtures, through the binary; its text, JSON and plot must
//!   equal the committed files, and every line the document quotes must be
//!   in the text. `KINPOST_BLESS=1 cargo test --test it diagnose_docs::`
//!   rewrites the files after a deliberate change (review the diff).
//! - The others come from the library's scenarios:
//!   `cargo test --test it diagnose_docs:: -- --ignored` regenerates them.

use crate::diagnose_support::*;

fn example(m: Machine, blocks: usize, seed: u64, specs: &[&str], name: &str) {
    let sc = m.scenario(blocks, seed);
    let effects = effects(specs);
    let (rec, r) = sc.run(&effects);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/diagnose");
    std::fs::create_dir_all(&dir).unwrap();
    r.write_svg(&dir.join(format!("{name}.svg"))).unwrap();
    std::fs::write(dir.join(format!("{name}.txt")), r.to_text()).unwrap();
    std::fs::write(dir.join(format!("{name}.json")), r.to_json_string() + "\n").unwrap();
    println!(
        "{name}: effect RMS {:.3} µm, geometric {:.3} µm, {} samples\n{}",
        effect_rms(&sc.chain, Some(&sc.errors), &sc.program, &effects, &sc.opts) * 1e3,
        geometric_rms(&sc.chain, &sc.errors, &sc.program, &sc.opts) * 1e3,
        rec.len(),
        r.to_text()
    );
}

#[test]
#[ignore]
fn regenerate_worked_examples() {
    example(
        Machine::Wang,
        100,
        7,
        &["pivot_length:0.0015"],
        "wang-pivot",
    );
    example(Machine::Wang, 100, 8, &[], "wang-clean");
}

/// The commands of the first ```text block after "## Worked example" in
/// docs/diagnose.md, continuation lines joined, split into words.
fn documented_commands(doc: &str) -> Vec<Vec<String>> {
    let at = doc.find("## Worked example").expect("a worked example");
    let rest = &doc[at..];
    let start = rest.find("```text\n").expect("a text block") + 8;
    let end = start + rest[start..].find("```").unwrap();
    let joined = rest[start..end].replace("\\\n", " ");
    joined
        .lines()
        .filter(|l| l.trim_start().starts_with("kinpost "))
        .map(|l| {
            let mut words = Vec::new();
            let mut cur = String::new();
            let mut quoted = false;
            for ch in l.trim().chars() {
                match ch {
                    '"' => quoted = !quoted,
                    c if c.is_whitespace() && !quoted => {
                        if !cur.is_empty() {
                            words.push(std::mem::take(&mut cur));
                        }
                    }
                    c => cur.push(c),
                }
            }
            if !cur.is_empty() {
                words.push(cur);
            }
            words
        })
        .collect()
}

#[test]
fn the_worked_example_is_what_the_shipped_fixtures_give() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("docs/diagnose.md")).unwrap();
    let cmds = documented_commands(&doc);
    assert_eq!(cmds.len(), 2, "{cmds:?}");
    let dir = tempfile::tempdir().unwrap();
    // The fixtures are named from the repository root.
    let located = |w: &String| {
        if w.starts_with("fixtures/") {
            root.join(w).display().to_string()
        } else {
            w.clone()
        }
    };
    let mut stdout = String::new();
    for words in &cmds {
        assert_eq!(words[0], "kinpost");
        let args: Vec<String> = words[1..].iter().map(located).collect();
        let out = std::process::Command::new(crate::util::BIN)
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{words:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        stdout = String::from_utf8(out.stdout).unwrap();
    }
    // The same diagnosis as JSON (formats.md §3).
    let mut json_args: Vec<String> = cmds[1][1..]
        .iter()
        .map(located)
        .filter(|w| {
            !w.ends_with(".svg") && !w.ends_with(".json") && w != "--svg" && w != "--write-model"
        })
        .collect();
    json_args.push("--json".into());
    let json = std::process::Command::new(crate::util::BIN)
        .args(&json_args)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(json.status.success());
    let files = [
        ("zhao-backlash.txt", stdout.clone()),
        (
            "zhao-backlash.json",
            String::from_utf8(json.stdout).unwrap(),
        ),
        (
            "zhao-backlash.svg",
            std::fs::read_to_string(dir.path().join("zhao-backlash.svg")).unwrap(),
        ),
    ];
    let bless = std::env::var_os("KINPOST_BLESS").is_some();
    for (name, text) in &files {
        let path = root.join("docs/diagnose").join(name);
        if bless {
            std::fs::write(&path, text).unwrap();
        } else {
            let committed = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                committed == *text,
                "docs/diagnose/{name} differs from what the documented commands give; rerun with KINPOST_BLESS=1 and review"
            );
        }
    }
    // Every line the document quotes from the report is in it.
    let at = doc.find("## Worked example").unwrap();
    let rest = &doc[at..];
    let second = rest.match_indices("```text\n").nth(1).unwrap().0 + 8;
    let end = second + rest[second..].find("```").unwrap();
    for line in rest[second..end].lines() {
        if line.trim() == "..." || line.trim().is_empty() {
            continue;
        }
        assert!(
            stdout.lines().any(|l| l == line),
            "docs/diagnose.md quotes a line the report does not have:\n{line}\n---\n{stdout}"
        );
    }
    // The figures of the prose match the run.
    let samples = stdout
        .lines()
        .nth(1)
        .and_then(|l| l.split_whitespace().next())
        .unwrap()
        .to_string();
    assert!(
        rest[..second].contains(&format!("{samples} samples")),
        "the prose must give the {samples} samples of the run"
    );
}
