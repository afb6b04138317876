//! Fourteenth hunt (session 30, `docs/robustness.md`): items left from the
//! thirteenth. Each test failed on the session's first build.

use crate::util::post_file;

const TRT: &str = "xyzac-trt";

fn post(name: &str, program: &str) -> (i32, String, String) {
    let (code, out, err) = post_file(TRT, name, program.as_bytes());
    (code, String::from_utf8(out).unwrap(), err)
}

/// `G43.4 P1 H1`: the `P` (the TCP type on some controls) went on to the
/// `G49` written for the code (`G49 P1`, which a control may read as
/// a dwell's or take as an error). Now it goes with the code, as the `H`
/// does, unless another code of the block takes a `P` (`G4 P1`).
#[test]
fn a_p_word_beside_the_tcp_code_goes_with_it() {
    let poses = "G1 X10 Y0 Z5 I0 J0 K1 F100\nG49\nM30\n";
    let (code, nc, err) = post("p.ngc", &format!("G21 G90\nG43.4 P1 H1\n{poses}"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.starts_with("G21 G90\nG49\nG1 X10.0000"), "{nc}");
    let (code, nc, err) = post("p.ngc", &format!("G21 G90\nG43.4 H1 G4 P1\n{poses}"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.starts_with("G21 G90\nG49 G4 P1\n"), "{nc}");
}

/// Sinumerik allows a blank between a call and its arguments; the parser
/// reads `(…)` after a blank as a comment. `TRAORI (1)` became
/// `TRAFOOF (1)`, and `TRAORI (1,0,1,0)` (a basic tool orientation along
/// Y) was converted as a plain `TRAORI`, with the tool along Z. Now the
/// arguments go with the call, and with more than the transformation's
/// number the call is refused, as `TRAORI(1,0,1,0)` is.
#[test]
fn traori_with_a_blank_before_its_arguments() {
    let poses = "G1 X10 Y0 Z5 A3=0 B3=0 C3=1 F100\nTRAFOOF\nM30\n";
    let (code, nc, err) = post("t.mpf", &format!("TRAORI (1)\n{poses}"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.starts_with("TRAFOOF\nG1 X10.0000"), "{nc}");
    let (code, nc, err) = post("t.mpf", &format!("TRAORI ( 2 ) ; on\n{poses}"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.starts_with("TRAFOOF ; on\n"), "{nc}");
    let (code, _, err) = post("t.mpf", &format!("TRAORI (1,0,1,0)\n{poses}"));
    assert_eq!(code, 1);
    assert!(
        err.contains("t.mpf:1:1:") && err.contains("basic tool orientation"),
        "{err}"
    );
    // A comment in words is a comment, kept.
    let (code, nc, err) = post("t.mpf", &format!("TRAORI (tcp on)\n{poses}"));
    assert_eq!(code, 0, "{err}");
    assert!(nc.starts_with("TRAFOOF (tcp on)\n"), "{nc}");
}

/// A form feed (a page break of an old listing) at the start of the TCP
/// block made the line text kinpost does not parse: TCP was not seen, the
/// poses were converted anyway (their I J K start pose mode), and
/// `G43.4 H1` stayed in the output, where the control would apply TCP to
/// kinpost's machine axes. A form feed or vertical tab now separates like
/// a blank; the byte is kept.
#[test]
fn a_form_feed_separates_like_a_blank() {
    for ff in ["\x0c", "\x0b"] {
        let program = format!("G21 G90\n{ff}G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F100\nG49\nM30\n");
        let (code, nc, err) = post("ff.ngc", &program);
        assert_eq!(code, 0, "{err}");
        assert!(
            nc.starts_with(&format!("G21 G90\n{ff}G49\nG1 X10.0000")),
            "{nc:?}"
        );
    }
}
