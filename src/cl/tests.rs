//! Unit tests of the APT CL reader and statement parser.

use super::*;

#[test]
fn pieces() {
    assert_eq!(
        statement_piece(b"GOTO/1,2,$\r\n"),
        (&b"GOTO/1,2,"[..], true)
    );
    assert_eq!(
        statement_piece(b"GOTO/1,2,3 $$ x $\n"),
        (&b"GOTO/1,2,3"[..], false)
    );
    assert_eq!(
        statement_piece(b"GOTO/1,2,$  $$ more\n"),
        (&b"GOTO/1,2,"[..], true)
    );
    assert_eq!(statement_piece(b""), (&b""[..], false));
}

#[test]
fn args_offsets() {
    let a = split_args(b" 1, 22 ,3", 5);
    let got: Vec<_> = a.iter().map(|a| (a.text, a.offset)).collect();
    assert_eq!(got, [(&b"1"[..], 6), (&b"22"[..], 9), (&b"3"[..], 13)]);
    assert!(split_args(b"  ", 0).is_empty());
}

#[test]
fn numbers() {
    let n = |s: &str| {
        Arg {
            text: s.as_bytes(),
            offset: 0,
        }
        .number()
    };
    assert_eq!(n("1"), Some(1.0));
    assert_eq!(n("-1.5"), Some(-1.5));
    assert_eq!(n(".5"), Some(0.5));
    assert_eq!(n("5."), Some(5.0));
    assert_eq!(n("1.0E+02"), Some(100.0));
    assert_eq!(n("1e999"), None);
    assert_eq!(n("nan"), None);
    assert_eq!(n("inf"), None);
    assert_eq!(n("1.2.3"), None);
    assert_eq!(n(""), None);
}

/// `Arg::number` (the standard parser) accepts exactly the finite
/// numbers of the grammar's `number_text`.
#[test]
fn number_agrees_with_grammar() {
    use nom::combinator::all_consuming;
    let pieces = [
        "", "+", "-", "0", "7", "12", ".", ".5", "5.", "1.25", "e", "E", "e5", "e+5", "E-05",
        "inf", "Infinity", "nan", "NaN", "_", "1_0", " ", "x", "0x1", "1e999", "d",
    ];
    let grammar = |s: &str| -> Option<f64> {
        let (_, t) = all_consuming(number_text)
            .parse_complete(s.as_bytes())
            .ok()?;
        let v: f64 = std::str::from_utf8(t).ok()?.parse().ok()?;
        v.is_finite().then_some(v)
    };
    let mut checked = 0;
    for a in pieces {
        for b in pieces {
            for c in ["", "5", "e3", ".", "+1"] {
                let s = format!("{a}{b}{c}");
                let arg = Arg {
                    text: s.as_bytes(),
                    offset: 0,
                };
                assert_eq!(arg.number(), grammar(&s), "`{s}`");
                checked += 1;
            }
        }
    }
    assert!(checked > 3000);
}
