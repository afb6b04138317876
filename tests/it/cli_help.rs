//! `--help` explains every option, numeric ones with their unit, and the
//! shell completions are generated for every supported shell. The
//! commands and options are read from the help texts themselves (the
//! command-line layer is the binary's, not the library's).

use std::process::Command;

use crate::util::BIN;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).args(args).output().expect("run kinpost");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Words that state a unit (or that a number has none).
const UNIT_WORDS: &[&str] = &[
    "in mm",
    "mm/s²",
    "mm/min",
    "in s",
    "µrad",
    "a count",
    "no unit",
    "dimensionless",
];

/// An option as its help text shows it.
struct Opt {
    /// The long name, without `--`.
    long: String,
    /// The value name (`<MM>` → `MM`), when it takes a value.
    value_name: Option<String>,
}

/// The subcommands `kinpost --help` lists (`help` left out).
fn subcommands(top: &str) -> Vec<String> {
    top.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|n| n != "help")
        .collect()
}

/// The options a help text documents: the lines that start with a flag.
fn options(help: &str) -> Vec<Opt> {
    help.lines()
        .filter(|l| {
            let indent = l.len() - l.trim_start().len();
            indent < 8 && l.trim_start().starts_with('-')
        })
        .filter_map(|l| {
            let at = l.find("--")?;
            let rest = &l[at + 2..];
            let end = rest.find([' ', '=', '<', ',']).unwrap_or(rest.len());
            let value_name = rest[end..]
                .trim_start_matches([' ', '='])
                .strip_prefix('<')
                .and_then(|v| v.split('>').next())
                .map(str::to_string);
            Some(Opt {
                long: rest[..end].to_string(),
                value_name,
            })
        })
        .collect()
}

/// Is this option's value a number? (Its default or value name says so.)
fn is_numeric(opt: &Opt, doc: &str) -> bool {
    let numeric_default = doc
        .split("[default: ")
        .nth(1)
        .and_then(|d| d.split(']').next())
        .is_some_and(|v| v.split(',').all(|p| p.trim().parse::<f64>().is_ok()));
    let numeric_name = opt
        .value_name
        .as_deref()
        .is_some_and(|n| ["N", "MM", "URAD", "S", "MM/S2", "MM/MIN", "WX,WY,WZ"].contains(&n));
    opt.value_name.is_some() && (numeric_default || numeric_name)
}

/// The part of `help` that documents `--long` (up to the next option).
fn section<'a>(help: &'a str, long: &str) -> &'a str {
    let flag = format!("--{long}");
    let start = help
        .lines()
        .scan(0usize, |off, l| {
            let here = *off;
            *off += l.len() + 1;
            Some((here, l))
        })
        .find(|(_, l)| {
            let t = l.trim_start();
            (t.starts_with(&flag) || t.starts_with('-') && t.contains(&format!(", {flag}")))
                && t[t.find(&flag).unwrap() + flag.len()..]
                    .chars()
                    .next()
                    .is_none_or(|c| c == ' ' || c == '=' || c == '<')
        })
        .map(|(off, _)| off)
        .unwrap_or_else(|| panic!("{flag} not in help:\n{help}"));
    let rest = &help[start..];
    let end = rest[1..]
        .lines()
        .scan(1usize, |off, l| {
            let here = *off;
            *off += l.len() + 1;
            Some((here, l))
        })
        .skip(1)
        .find(|(_, l)| {
            let t = l.trim_start();
            t.starts_with("--") || (t.starts_with('-') && t.len() > 1 && t.as_bytes()[1] != b' ')
        })
        .map_or(rest.len(), |(off, _)| off);
    &rest[..end]
}

#[test]
fn every_subcommand_has_help_and_every_numeric_option_a_unit() {
    let (code, top, _) = run(&["--help"]);
    assert_eq!(code, 0);
    let commands = subcommands(&top);
    // post, parse, machine, fit, analyze, compensate, linkage, simulate,
    // diagnose, completions.
    assert!(commands.len() >= 10, "{commands:?}");
    let mut checked = 0;
    for name in &commands {
        let name = name.as_str();
        let (code, help, err) = run(&[name, "--help"]);
        assert_eq!(code, 0, "kinpost {name} --help: {err}");
        assert!(help.contains("Usage: kinpost"), "{name}: {help}");
        for opt in options(&help) {
            let long = opt.long.as_str();
            if long == "help" || long == "version" {
                continue;
            }
            let doc = section(&help, long);
            assert!(
                doc.split_whitespace().count() > 3,
                "{name} --{long} is not explained:\n{doc}"
            );
            if is_numeric(&opt, doc) {
                assert!(
                    UNIT_WORDS.iter().any(|u| doc.contains(u)),
                    "{name} --{long}: numeric option without a unit:\n{doc}"
                );
                checked += 1;
            }
        }
    }
    // post, compensate, linkage, simulate, diagnose, fit: at least these.
    assert!(checked >= 18, "only {checked} numeric options found");
}

#[test]
fn units_of_some_options_as_documented() {
    for (cmd, long, unit) in [
        ("post", "axis-tolerance-urad", "in µrad"),
        ("compensate", "tip-tolerance-mm", "in mm"),
        ("linkage", "tolerance", "in mm"),
        ("simulate", "noise", "in mm"),
        ("simulate", "sample-interval", "in s"),
        ("simulate", "accel", "in mm/s²"),
        ("simulate", "rapid-feed", "in mm/min"),
        ("diagnose", "noise-floor", "in mm"),
    ] {
        let (_, help, _) = run(&[cmd, "--help"]);
        let doc = section(&help, long);
        assert!(doc.contains(unit), "{cmd} --{long} lacks {unit:?}:\n{doc}");
    }
}

#[test]
fn completions_for_every_shell() {
    for (shell, marker) in [
        ("bash", "_kinpost()"),
        ("zsh", "#compdef kinpost"),
        ("fish", "complete -c kinpost"),
        ("powershell", "Register-ArgumentCompleter"),
        ("elvish", "edit:completion:arg-completer[kinpost]"),
    ] {
        let (code, out, err) = run(&["completions", shell]);
        assert_eq!(code, 0, "{shell}: {err}");
        assert!(out.contains(marker), "{shell}: no {marker:?} in\n{out}");
        for sub in ["post", "compensate", "diagnose", "completions"] {
            assert!(out.contains(sub), "{shell} completion lacks {sub}");
        }
        assert!(
            out.contains("axis-tolerance-urad"),
            "{shell}: options completed"
        );
    }
}
