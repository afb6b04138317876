//! APT CL reader: every statement, continuations, comments and errors.

use kinpost::Error;
use kinpost::cl::{ClReader, ClRecord, ClStatement, ClUnits, FeedUnit, SpindleDir, looks_like_cl};

fn read(src: &str) -> Vec<ClRecord> {
    ClReader::new(src.as_bytes(), "t.cls")
        .collect::<Result<_, _>>()
        .unwrap_or_else(|e| panic!("{e}"))
}

fn one(src: &str) -> ClStatement {
    let mut r = read(src);
    assert_eq!(r.len(), 1, "{src:?}: {r:?}");
    r.remove(0).statement
}

fn err(src: &str) -> String {
    let results: Vec<_> = ClReader::new(src.as_bytes(), "t.cls").collect();
    let e = results
        .into_iter()
        .find_map(Result::err)
        .unwrap_or_else(|| panic!("{src:?} should fail"));
    assert_eq!(e.exit_code(), kinpost::error::exit::INPUT);
    e.to_string()
}

fn other(major: &str, text: &str) -> ClStatement {
    ClStatement::Other {
        major: major.into(),
        text: text.into(),
    }
}

/// A CLSF as NX writes it (values invented for the test).
const NX_SAMPLE: &str = "\
TOOL PATH/CONTOUR_5AX,TOOL,BALL_6
TLDATA/MILL,6.0000,3.0000,75.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
$$ centerline data
PAINT/PATH
PAINT/SPEED,10
LOADTL/3,ADJUST,3,MILL
SPINDL/RPM,12000,CLW
COOLNT/FLOOD
MULTAX/ON
PAINT/COLOR,186
RAPID
GOTO/10.0000,-5.2500,50.0000,0.0000000,0.0000000,1.0000000
PAINT/COLOR,31
FEDRAT/MMPM,800.0000
GOTO/10.5000,-5.0000,2.0000,0.0871557,0.0000000,0.9961947
GOTO/11.0000,-4.7500,1.9000,$
0.1736482,0.0000000,0.9848078
COOLNT/OFF
SPINDL/OFF
END-OF-PATH
FINI
";

#[test]
fn nx_sample() {
    let r = read(NX_SAMPLE);
    let st: Vec<&ClStatement> = r.iter().map(|r| &r.statement).collect();
    assert_eq!(st.len(), 21);
    assert_eq!(*st[0], other("TOOL PATH", "CONTOUR_5AX,TOOL,BALL_6"));
    assert_eq!(
        *st[1],
        other("TLDATA", "MILL,6.0000,3.0000,75.0000,0.0000,0.0000")
    );
    assert!(matches!(st[2], ClStatement::Other { major, .. } if major == "MSYS"));
    assert_eq!(*st[3], ClStatement::Comment("centerline data".into()));
    assert_eq!(
        *st[6],
        ClStatement::LoadTl {
            tool: 3,
            adjust: Some(3)
        }
    );
    assert_eq!(
        *st[7],
        ClStatement::Spindle {
            rpm: Some(12000.0),
            dir: Some(SpindleDir::Clockwise),
            off: false
        }
    );
    assert_eq!(*st[8], ClStatement::Coolant(true));
    assert_eq!(*st[9], ClStatement::Multax(true));
    assert_eq!(*st[11], ClStatement::Rapid);
    assert_eq!(
        *st[12],
        ClStatement::Goto {
            tip: [10.0, -5.25, 50.0],
            axis: Some([0.0, 0.0, 1.0])
        }
    );
    assert_eq!(
        *st[14],
        ClStatement::Fedrat {
            value: 800.0,
            unit: FeedUnit::Mmpm
        }
    );
    assert_eq!(
        *st[16],
        ClStatement::Goto {
            tip: [11.0, -4.75, 1.9],
            axis: Some([0.1736482, 0.0, 0.9848078])
        }
    );
    assert_eq!(*st[17], ClStatement::Coolant(false));
    assert_eq!(
        *st[18],
        ClStatement::Spindle {
            rpm: None,
            dir: None,
            off: true
        }
    );
    assert_eq!(*st[19], other("END-OF-PATH", ""));
    assert_eq!(*st[20], ClStatement::End);
    // Lines, continuation text, and the whole file from the records' text.
    assert_eq!(r[16].line, 17);
    assert_eq!(
        r[16].text,
        b"GOTO/11.0000,-4.7500,1.9000,$\n0.1736482,0.0000000,0.9848078\n"
    );
    assert_eq!(r[17].line, 19);
    let joined: Vec<u8> = r.iter().flat_map(|r| r.text.clone()).collect();
    assert_eq!(joined, NX_SAMPLE.as_bytes());
}

#[test]
fn goto_three_and_six() {
    assert_eq!(
        one("GOTO/1,2,3"),
        ClStatement::Goto {
            tip: [1.0, 2.0, 3.0],
            axis: None
        }
    );
    assert_eq!(
        one("goto / 1.5 , -.5 , 3. , 0,0,1 $$ tail\r\n"),
        ClStatement::Goto {
            tip: [1.5, -0.5, 3.0],
            axis: Some([0.0, 0.0, 1.0])
        }
    );
    assert_eq!(
        one("GOTO/1.0E+01,2e-1,3"),
        ClStatement::Goto {
            tip: [10.0, 0.2, 3.0],
            axis: None
        }
    );
}

#[test]
fn fedrat_forms() {
    let f = |value, unit| ClStatement::Fedrat { value, unit };
    assert_eq!(one("FEDRAT/MMPM,250.0"), f(250.0, FeedUnit::Mmpm));
    assert_eq!(one("FEDRAT/IPM,10"), f(10.0, FeedUnit::Ipm));
    assert_eq!(one("FEDRAT/MMPR,0.1"), f(0.1, FeedUnit::Mmpr));
    assert_eq!(one("FEDRAT/ipr,.004"), f(0.004, FeedUnit::Ipr));
    assert_eq!(one("FEDRAT/120"), f(120.0, FeedUnit::Unspecified));
    assert_eq!(one("FEDRAT/120,IPM"), f(120.0, FeedUnit::Ipm));
}

#[test]
fn rapid_tlaxis_multax_loadtl() {
    assert_eq!(one("RAPID"), ClStatement::Rapid);
    assert_eq!(one("  rapid  \n"), ClStatement::Rapid);
    assert_eq!(
        one("TLAXIS/0,0.6,0.8"),
        ClStatement::TlAxis([0.0, 0.6, 0.8])
    );
    assert_eq!(one("MULTAX"), ClStatement::Multax(true));
    assert_eq!(one("MULTAX/ON"), ClStatement::Multax(true));
    assert_eq!(one("MULTAX/OFF"), ClStatement::Multax(false));
    assert_eq!(
        one("LOADTL/12"),
        ClStatement::LoadTl {
            tool: 12,
            adjust: None
        }
    );
    assert_eq!(
        one("LOADTL/7,IN,7,LENGTH,75.0"),
        ClStatement::LoadTl {
            tool: 7,
            adjust: None
        }
    );
    assert_eq!(
        one("LOADTL/5.0"),
        ClStatement::LoadTl {
            tool: 5,
            adjust: None
        }
    );
}

#[test]
fn spindle_forms() {
    let s = |rpm, dir, off| ClStatement::Spindle { rpm, dir, off };
    assert_eq!(
        one("SPINDL/RPM,1000,CLW"),
        s(Some(1000.0), Some(SpindleDir::Clockwise), false)
    );
    assert_eq!(
        one("SPINDL/RPM,800,CCLW"),
        s(Some(800.0), Some(SpindleDir::CounterClockwise), false)
    );
    assert_eq!(one("SPINDL/1500"), s(Some(1500.0), None, false));
    assert_eq!(
        one("SPINDL/1500,CLW,RANGE,2"),
        s(Some(1500.0), Some(SpindleDir::Clockwise), false)
    );
    assert_eq!(one("SPINDL/ON"), s(None, None, false));
    assert_eq!(one("SPINDL/OFF"), s(None, None, true));
    // Surface speed is not interpreted.
    assert_eq!(one("SPINDL/SFM,300,CLW"), other("SPINDL", "SFM,300,CLW"));
}

#[test]
fn coolant_units_end() {
    for on in ["ON", "FLOOD", "MIST", "THRU", "mist"] {
        assert_eq!(one(&format!("COOLNT/{on}")), ClStatement::Coolant(true));
    }
    assert_eq!(one("COOLNT/OFF"), ClStatement::Coolant(false));
    assert_eq!(one("COOLNT/SPECIAL"), other("COOLNT", "SPECIAL"));
    assert_eq!(one("UNITS/MM"), ClStatement::Units(ClUnits::Mm));
    assert_eq!(one("UNITS/INCHES"), ClStatement::Units(ClUnits::Inches));
    assert_eq!(one("UNITS/INCH"), ClStatement::Units(ClUnits::Inches));
    assert_eq!(one("FINI"), ClStatement::End);
    assert_eq!(one("END"), ClStatement::End);
}

#[test]
fn comments_partno_and_other_statements() {
    assert_eq!(
        one("$$ hello $ world"),
        ClStatement::Comment("hello $ world".into())
    );
    assert_eq!(one("  $$"), ClStatement::Comment(String::new()));
    assert_eq!(
        one("PARTNO BRACKET A/B REV 2"),
        other("PARTNO", "BRACKET A/B REV 2")
    );
    assert_eq!(one("PPRINT CHECK TOOL"), other("PPRINT", "CHECK TOOL"));
    assert_eq!(
        one("TOOL  PATH/OP1,TOOL,T1"),
        other("TOOL PATH", "OP1,TOOL,T1")
    );
    assert_eq!(one("PAINT/COLOR,186"), other("PAINT", "COLOR,186"));
    assert_eq!(one("CUTTER/10.0,0.0"), other("CUTTER", "10.0,0.0"));
    assert_eq!(one("END-OF-PATH"), other("END-OF-PATH", ""));
    assert_eq!(one("SELECT/TOOL,3"), other("SELECT", "TOOL,3"));
    assert_eq!(one("OPSTOP"), other("OPSTOP", ""));
}

#[test]
fn records_locate_statements() {
    let r = read("\n\n   GOTO/1,2,3\r\n\t$$ c\n");
    assert_eq!((r[0].line, r[0].col), (3, 4));
    assert_eq!(r[0].text, b"   GOTO/1,2,3\r\n");
    assert_eq!((r[1].line, r[1].col), (4, 2));
}

#[test]
fn continuation_over_several_lines() {
    let src = "GOTO/1,$\n   2,$ $$ second\n  3,0,$\n0,1\nRAPID\n";
    let r = read(src);
    assert_eq!(r.len(), 2);
    assert_eq!(
        r[0].statement,
        ClStatement::Goto {
            tip: [1.0, 2.0, 3.0],
            axis: Some([0.0, 0.0, 1.0])
        }
    );
    assert_eq!(r[1].line, 5);
}

#[test]
fn goto_errors_name_line_col_and_text() {
    let e = err("RAPID\nGOTO/1,2\n");
    assert!(e.starts_with("t.cls:2:1: GOTO expects 3 numbers"), "{e}");
    assert!(e.contains("found 2 arguments"), "{e}");
    assert!(e.contains("| GOTO/1,2"), "{e}");

    let e = err("GOTO/1,2,3,4\n");
    assert!(e.contains("found 4 arguments"), "{e}");

    let e = err("GOTO/1, abc ,3\n");
    assert!(e.starts_with("t.cls:1:9: expected a coordinate"), "{e}");
    assert!(e.contains("`abc`"), "{e}");

    let e = err("GOTO/1,2,NaN\n");
    assert!(e.starts_with("t.cls:1:10:"), "{e}");
    let e = err("GOTO/1,2,inf\n");
    assert!(e.contains("finite"), "{e}");
    let e = err("GOTO/1,2,1e999\n");
    assert!(e.contains("`1e999`"), "{e}");
    let e = err("GOTO/1,2,1.2.3\n");
    assert!(e.contains("`1.2.3`"), "{e}");
    let e = err("GOTO/1,2,3,0,0,0\n");
    assert!(e.contains("zero length"), "{e}");
    let e = err("GOTO 1,2,3\n");
    assert!(e.contains("expected `/`"), "{e}");
}

#[test]
fn errors_in_continuation_lines_point_there() {
    let e = err("GOTO/1,2,3,$\n  0,x,1\n");
    assert!(
        e.starts_with("t.cls:2:5: expected a tool axis component"),
        "{e}"
    );
    // The snippet is the physical line with the error.
    assert!(e.ends_with("\n  |   0,x,1"), "{e}");
    let e = err("GOTO/1,2,$\n");
    assert!(e.contains("file ends"), "{e}");
}

#[test]
fn other_statement_errors() {
    assert!(err("FEDRAT/MMPM").contains("FEDRAT expects a feed rate"));
    assert!(err("FEDRAT/-5").contains("not negative"));
    assert!(err("FEDRAT/MMPM,fast").contains("`fast`"));
    assert!(err("TLAXIS/0,0").contains("TLAXIS expects 3 numbers"));
    assert!(err("TLAXIS/0,0,0").contains("zero length"));
    assert!(err("LOADTL/1.5").contains("tool number"));
    assert!(err("LOADTL/").contains("LOADTL expects a tool number"));
    assert!(err("UNITS/FEET").contains("UNITS/MM or UNITS/INCHES"));
    assert!(err("MULTAX/MAYBE").contains("MULTAX/ON"));
    assert!(err("SPINDL/RPM").contains("speed after RPM"));
    assert!(err("SPINDL/RPM,-10").contains("not negative"));
    assert!(err("1,2,3").contains("expected an APT statement"));
}

#[test]
fn reader_goes_on_after_a_statement_error() {
    let results: Vec<Result<ClRecord, Error>> =
        ClReader::new(&b"GOTO/1\nRAPID\n"[..], "t").collect();
    assert_eq!(results.len(), 2);
    assert!(results[0].is_err());
    assert_eq!(results[1].as_ref().unwrap().statement, ClStatement::Rapid);
}

/// A text given back is what a record read later is read into.
#[test]
fn recycled_text_is_read_into() {
    let src = b"GOTO/1,2,3\nGOTO/4,$\n  5,6\nGOTO/7,8,9\n";
    let mut reader = ClReader::new(&src[..], "t");
    let first = reader.next().unwrap().unwrap();
    let second = reader.next().unwrap().unwrap();
    assert_eq!(second.text, b"GOTO/4,$\n  5,6\n");
    let at = first.text.as_ptr();
    reader.recycle(first.text);
    let third = reader.next().unwrap().unwrap();
    assert_eq!(third.text.as_ptr(), at);
    assert_eq!(third.text, b"GOTO/7,8,9\n");
    assert_eq!(
        third.statement,
        ClStatement::Goto {
            tip: [7.0, 8.0, 9.0],
            axis: None
        }
    );
}

#[test]
fn non_utf8_bytes_are_tolerated() {
    let r: Vec<_> = ClReader::new(&b"$$ caf\xe9\nPARTNO \xff\n"[..], "t")
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(r[0].statement, ClStatement::Comment("caf\u{fffd}".into()));
    assert_eq!(r[1].text, b"PARTNO \xff\n");
}

#[test]
fn detection() {
    assert!(looks_like_cl(b"TOOL PATH/OP1,TOOL,T1\nTLDATA/MILL,6\n"));
    assert!(looks_like_cl(b"$$ -> CLSF\n"));
    assert!(looks_like_cl(b"\r\nPARTNO X\r\n"));
    assert!(looks_like_cl(b"(not a comment in CL)\nGOTO/1,2,3\n"));
    assert!(looks_like_cl(b"fedrat/100\n"));
    assert!(!looks_like_cl(b"%\nO1000\nG1 X1\n"));
    assert!(!looks_like_cl(b"G0 X0\nGOTO/1,2,3\n"));
    assert!(!looks_like_cl(b"(header)\n; comment\n"));
    assert!(!looks_like_cl(b""));
    assert!(!looks_like_cl(b"\xff\xfe\x00"));
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    const TOKENS: &[&str] = &[
        "GOTO",
        "/",
        ",",
        "1",
        "-2.5",
        ".5",
        "1e999",
        "nan",
        "$",
        "$$",
        " ",
        "\n",
        "\r\n",
        "FEDRAT",
        "MMPM",
        "SPINDL",
        "RPM",
        "CLW",
        "OFF",
        "TLAXIS",
        "0",
        "UNITS",
        "MM",
        "LOADTL",
        "PARTNO",
        "TOOL PATH",
        "\u{ff}",
        "x",
        "MULTAX",
        "COOLNT",
        "RAPID",
        "END-OF-PATH",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        #[test]
        fn never_panics_on_bytes(src in prop::collection::vec(any::<u8>(), 0..300)) {
            let n = ClReader::new(src.as_slice(), "f").take(1000).count();
            prop_assert!(n <= src.len());
            let _ = looks_like_cl(&src);
        }

        #[test]
        fn never_panics_on_token_soup(ts in prop::collection::vec(prop::sample::select(TOKENS), 0..40)) {
            let src = ts.concat();
            for r in ClReader::new(src.as_bytes(), "f") {
                match r {
                    Ok(rec) => {
                        prop_assert!(rec.line >= 1 && rec.col >= 1);
                        prop_assert!(!rec.text.is_empty());
                    }
                    Err(e) => prop_assert!(e.to_string().starts_with("f:")),
                }
            }
            let _ = looks_like_cl(src.as_bytes());
        }
    }
}
