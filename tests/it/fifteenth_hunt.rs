//! Fifteenth hunt (session 31, `docs/robustness.md`): `INSERT/` text in
//! APT CL. Each test failed on the session's first build.

use crate::util::post_file;

const TRT: &str = "xyzac-trt";

fn post(name: &str, program: &str) -> (i32, String, String) {
    let (code, out, err) = post_file(TRT, name, program.as_bytes());
    (code, String::from_utf8(out).unwrap(), err)
}

/// `INSERT/` passes text to the NC program. Every INSERT was a comment:
/// `INSERT/M8` lost the coolant and `INSERT/G0 X10 Y20` dropped a move,
/// exit 0. Now code that only switches the spindle or coolant, stops or
/// ends is written as it is; code with an axis, feed, tool or G word is
/// refused at the word; notes (as SolidWorks CAM writes tool descriptions)
/// stay comments.
#[test]
fn insert_passes_plain_codes_refuses_moves_and_keeps_notes() {
    let head = "UNITS/MM\nMULTAX/ON\nFEDRAT/MMPM,300\nGOTO/0,0,50,0,0,1\n";
    let tail = "GOTO/10,0,50,0,0,1\nFINI\n";
    let (code, nc, err) = post(
        "i.apt",
        &format!(
            "{head}INSERT/M8\nINSERT/ S1200 M3 (on)\nINSERT/Stock Size X85. Y38. Z48.\n{tail}"
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        nc.contains("F300.0\nM8\nS1200 M3 (on)\n(INSERT/Stock Size X85. Y38. Z48.)\nX10.0000"),
        "{nc}"
    );
    for (insert, col, word) in [
        ("INSERT/G0 X10 Y20", 8, "`G0`"),
        ("INSERT/M8 X10", 11, "`X10`"),
        ("insert/T2 M6", 8, "`T2`"),
    ] {
        let (code, _, err) = post("i.apt", &format!("{head}{insert}\n{tail}"));
        assert_eq!(code, 1, "{insert}: {err}");
        assert!(
            err.contains(&format!("i.apt:5:{col}:")) && err.contains(word),
            "{insert}: {err}"
        );
    }
}
