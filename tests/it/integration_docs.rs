//! What `docs/integration.md` promises: the LinuxCNC snippet (the same as in
//! `docs/programs.md`) and its progress protocol, and the FreeCAD wrapper
//! producing a pose program that kinpost converts.

use std::process::{Command, Stdio};

use crate::util::BIN;

use crate::util::repo;

fn ini_snippet(doc: &str) -> String {
    let text = std::fs::read_to_string(repo().join(doc)).unwrap();
    let start = text
        .find("```ini\n[FILTER]")
        .unwrap_or_else(|| panic!("{doc}: no [FILTER] snippet"));
    let rest = &text[start..];
    rest[..rest[6..].find("```").unwrap() + 6].to_string()
}

#[test]
fn linuxcnc_snippet_is_the_same_in_both_documents() {
    assert_eq!(
        ini_snippet("docs/integration.md"),
        ini_snippet("docs/programs.md")
    );
}

#[test]
fn linuxcnc_filter_reports_progress_on_stderr_only() {
    let program = repo().join("fixtures/programs/zhao2022-lens.nc");
    // As the snippet runs it: post --machine … --quiet PROGRAM.
    let out = Command::new(BIN)
        .args(["post", "--machine", "zhao2022-xzbc", "--quiet"])
        .arg(&program)
        .env("AXIS_PROGRESS_BAR", "1")
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    let pct: Vec<u32> = err
        .lines()
        .map(|l| {
            l.strip_prefix("FILTER_PROGRESS=")
                .unwrap_or_else(|| panic!("not a progress line: {l}"))
                .parse()
                .unwrap()
        })
        .collect();
    assert!(pct.windows(2).all(|w| w[0] < w[1]), "increasing: {pct:?}");
    assert_eq!(pct.last(), Some(&100));
    assert!(String::from_utf8(out.stdout).unwrap().contains("G49"));
    // Without the variable: silent.
    let out = Command::new(BIN)
        .args(["post", "--quiet"])
        .arg(&program)
        .env_remove("AXIS_PROGRESS_BAR")
        .output()
        .unwrap();
    assert!(out.status.success() && out.stderr.is_empty());
}

fn python() -> Option<&'static str> {
    ["python3", "python"].into_iter().find(|p| {
        Command::new(p)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

#[test]
fn freecad_wrapper_self_test() {
    let Some(py) = python() else {
        eprintln!("no python: FreeCAD wrapper not checked");
        return;
    };
    let out = Command::new(py)
        .arg(repo().join("docs/integration/kinpost_post.py"))
        .arg("--self-test")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn freecad_wrapper_posts_through_kinpost() {
    let Some(py) = python() else {
        eprintln!("no python: FreeCAD wrapper not checked");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let script = format!(
        r#"
import sys
sys.path.insert(0, {docs:?})
import kinpost_post as k

class Path:
    def __init__(self, cmds): self.Commands = cmds

class Op:
    def __init__(self, label, cmds): self.Label = label; self.Path = Path(cmds)

C = k._Cmd
ops = [Op("Profile", [C("G0", X=0.0, Y=0.0, Z=5.0), C("G1", Z=0.0, F=10.0),
                      C("G1", X=10.0, I=0.0, J=0.6, K=0.8),
                      C("G2", X=20.0, Y=0.0, I=5.0, J=0.0)])]
args = "--machine xyzac-trt --kinpost '" + {bin:?} + "' --decimals 3"
text = k.export(ops, {out:?}, args)
assert text.startswith("%"), text[:80]
try:
    k.export([Op("Bad", [C("G0", X=0.0, Y=0.0, Z=5.0), C("G1", X=900.0)])], {out:?}, args)
except RuntimeError as e:
    print("ERROR:", e)
"#,
        docs = repo().join("docs/integration").display().to_string(),
        bin = BIN,
        out = dir.path().join("part.ngc").display().to_string(),
    );
    let out = Command::new(py).arg("-c").arg(&script).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    let posted = std::fs::read_to_string(dir.path().join("part.ngc")).unwrap();
    // Machine axes of the xyzac-trt table-table machine, 3 decimals.
    assert!(posted.contains("A36.870 C"), "{posted}");
    assert!(posted.contains("(Profile)"), "{posted}");
    assert!(!posted.contains(" I0"), "tool vectors replaced: {posted}");
    // A rejected job: kinpost's message reaches FreeCAD; the file is kept.
    assert!(
        stdout.contains("ERROR: kinpost failed (exit 1)") && stdout.contains("<stdin>:"),
        "{stdout}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("part.ngc")).unwrap(),
        posted
    );
}
