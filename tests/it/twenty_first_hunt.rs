//! Twenty-first hunt (session 37, `docs/robustness.md`): NX output for a
//! Haas UMC-750 from another public repository, Sinumerik 840C and 840D
//! programs, with variants. Each test failed on the session's first
//! build (d28aeeb).

use crate::util::{repo_file, run_on};

/// A line before the opening `%` (a DNC header, a comment, NX's
/// "Information listing") made that `%` the closing one: every command
/// passed the whole program on unread, `post` and `compensate` with exit 0
/// and the poses unconverted, `linkage` and `analyze` with "0 blocks".
/// The first `%` opens the program whatever stands before it: the result
/// is the one without the header, with the header line in front.
#[test]
fn a_header_before_the_opening_percent_leaves_the_program_read() {
    let wang = std::fs::read_to_string(repo_file("fixtures/programs/wang2023-xyzab.ngc")).unwrap();
    let errors = repo_file("fixtures/errors/wang2023-xyzab.csv");
    let haas = "O1000\nG234 H1\nG1 X1 Y2 Z3 B10 C20 F100\nG1 X2 B12 C25\nG49\nM30\n";
    let cases: [(&[&str], &str); 5] = [
        (&["post", "-m", "xyzbc-trt"], haas),
        (&["post", "-m", "wang2023-xyzab"], &wang),
        (
            &["compensate", "-m", "wang2023-xyzab", "-e", &errors],
            &wang,
        ),
        (&["linkage", "-m", "wang2023-xyzab"], &wang),
        (&["analyze", "--nonlinear", "-m", "wang2023-xyzab"], &wang),
    ];
    for (args, program) in cases {
        let bare = format!("%\n{program}%\n");
        let (code, want, err) = run_on(args, "p.nc", &bare);
        assert_eq!(code, 0, "{args:?}: {err}");
        assert_ne!(want, bare, "{args:?}: nothing converted");
        for header in ["(JOB 42)\n", ";listing\n", "O1000 (PROG)\n"] {
            let (code, out, err) = run_on(args, "p.nc", &format!("{header}{bare}"));
            assert_eq!(code, 0, "{args:?} {header:?}: {err}");
            assert!(!err.contains("closing `%`"), "{args:?} {header:?}: {err}");
            if args[0] == "analyze" {
                // The report names lines: one further down.
                assert_eq!(out.lines().count(), want.lines().count(), "{args:?}: {out}");
            } else {
                assert_eq!(out, format!("{header}{want}"), "{args:?} {header:?}");
            }
        }
    }
    // `simulate`: the same recording, its blocks one line further down.
    let args = ["simulate", "-m", "wang2023-xyzab", "--noise", "0", "-p"];
    let (code, want, err) = run_on(&args, "p.nc", &format!("%\n{wang}%\n"));
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = run_on(&args, "p.nc", &format!("(JOB 42)\n%\n{wang}%\n"));
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.lines().count(), want.lines().count());
}

/// `compensate` dropped every warning of reading the program (the text
/// after the closing `%`, the modal state's), from its messages and from
/// its report: only the refinement's own were printed. `post` prints them.
#[test]
fn compensate_gives_the_warnings_of_reading_the_program() {
    let wang = std::fs::read_to_string(repo_file("fixtures/programs/wang2023-xyzab.ngc")).unwrap();
    let errors = repo_file("fixtures/errors/wang2023-xyzab.csv");
    let program = format!("%\n{wang}%\nTool Path Listing has 3 lines.");
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let report_arg = report.to_str().unwrap();
    let args = [
        "compensate",
        "-m",
        "wang2023-xyzab",
        "-e",
        &errors,
        "--report",
        report_arg,
    ];
    let (code, out, err) = run_on(&args, "w.ngc", &program);
    assert_eq!(code, 0, "{err}");
    assert!(out.ends_with("%\nTool Path Listing has 3 lines."), "{out}");
    let want = "text after the program's closing `%` (line 160) passed on unread";
    assert!(err.contains(want), "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let warnings = json["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w.as_str().unwrap().contains(want)),
        "{warnings:?}"
    );
}
