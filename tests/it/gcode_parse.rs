//! One test per syntax feature of the G-code parser.

use std::io::BufReader;

use kinpost::gcode::{Item, ItemKind, Line, LineReader, Word, echo, parse_line, summarize};

/// Short names of the items' kinds, in order.
fn kinds(line: &Line) -> Vec<String> {
    line.items
        .iter()
        .map(|it| match &it.kind {
            ItemKind::Bom => "Bom".to_string(),
            ItemKind::Space => "_".to_string(),
            ItemKind::EndOfLine => "EOL".to_string(),
            ItemKind::Percent => "%".to_string(),
            ItemKind::BlockDelete => "/".to_string(),
            ItemKind::Comment => "C".to_string(),
            ItemKind::Checksum(v) => format!("*{v}"),
            ItemKind::Word(w) => format!(
                "{}={}{}",
                w.address,
                w.value,
                if w.assign { "!" } else { "" }
            ),
            ItemKind::Keyword(k) => format!("K:{k}"),
            ItemKind::Opaque => "?".to_string(),
        })
        .collect()
}

/// Parse `src` as line 5 and check tiling and the echo.
fn parse(src: &[u8]) -> Line {
    let line = parse_line(src, 5);
    assert!(
        line.is_tiled(),
        "{:?} does not tile: {:?}",
        String::from_utf8_lossy(src),
        line.items
    );
    let mut out = Vec::new();
    line.write_to(&mut out).unwrap();
    assert_eq!(out, src);
    line
}

fn k(src: &str) -> Vec<String> {
    kinds(&parse(src.as_bytes()))
}

fn words(src: &[u8]) -> Vec<(String, f64)> {
    parse(src)
        .words()
        .map(|w| (w.address.to_string(), w.value))
        .collect()
}

fn item_text<'a>(line: &'a Line, item: &Item) -> &'a str {
    std::str::from_utf8(line.item_bytes(item)).unwrap()
}

#[test]
fn simple_block() {
    assert_eq!(
        k("N10 G1 X10 Y-20.5 F100\n"),
        [
            "N=10", "_", "G=1", "_", "X=10", "_", "Y=-20.5", "_", "F=100", "EOL"
        ]
    );
}

#[test]
fn words_without_spaces() {
    assert_eq!(k("G1X10Y20"), ["G=1", "X=10", "Y=20"]);
    assert_eq!(
        k("G00G21G17G90G40G49G80"),
        ["G=0", "G=21", "G=17", "G=90", "G=40", "G=49", "G=80"]
    );
    assert_eq!(k("T1M06"), ["T=1", "M=6"]);
}

#[test]
fn decimal_forms_keep_source_text() {
    for (src, value, text) in [
        ("x.5", 0.5, ".5"),
        ("X5.", 5.0, "5."),
        ("X+5", 5.0, "+5"),
        ("X-.5", -0.5, "-.5"),
        ("X-1.", -1.0, "-1."),
        ("F.5", 0.5, ".5"),
        ("G43.4", 43.4, "43.4"),
        ("X0007.2500", 7.25, "0007.2500"),
    ] {
        let line = parse(src.as_bytes());
        let w = line
            .words()
            .next()
            .unwrap_or_else(|| panic!("{src}: no word"));
        assert_eq!(w.value, value, "{src}");
        assert_eq!(line.value_text(w), text.as_bytes(), "{src}");
        assert!(!line.has_opaque(), "{src}");
    }
}

#[test]
fn lowercase_addresses_are_uppercased() {
    assert_eq!(
        k("g1 x10 y.5 m3"),
        ["G=1", "_", "X=10", "_", "Y=0.5", "_", "M=3"]
    );
}

#[test]
fn spaces_between_letter_sign_and_digits() {
    let line = parse(b"G 1 X 10 Y - 2.5 Z\t+3");
    assert_eq!(
        kinds(&line),
        ["G=1", "_", "X=10", "_", "Y=-2.5", "_", "Z=3"]
    );
    let y = line.word("Y").unwrap();
    assert_eq!(line.value_text(y), b"- 2.5");
    assert_eq!(item_text(&line, &line.items[4]), "Y - 2.5");
    // The impeller demo's aligned columns.
    assert_eq!(
        k("G1  X   6.302  Y -11.560  A -71.841  F 318"),
        [
            "G=1",
            "_",
            "X=6.302",
            "_",
            "Y=-11.56",
            "_",
            "A=-71.841",
            "_",
            "F=318"
        ]
    );
}

#[test]
fn value_ranges_point_at_the_number() {
    let line = parse(b"N10 G43.4 H1\r\n");
    let g = line.word("G").unwrap();
    assert_eq!((g.value_start, g.value_end), (5, 9));
    assert_eq!(&line.bytes[g.value_start..g.value_end], b"43.4");
}

#[test]
fn crlf_and_multiple_cr() {
    let line = parse(b"G1 X1\r\n");
    assert_eq!(kinds(&line), ["G=1", "_", "X=1", "EOL"]);
    assert_eq!(line.line_ending(), b"\r\n");
    assert_eq!(line.content(), b"G1 X1");
    assert_eq!(parse(b"G1\r\r\n").line_ending(), b"\r\r\n");
    assert_eq!(parse(b"\r\n").items.len(), 1);
}

#[test]
fn no_trailing_newline() {
    let line = parse(b"M30");
    assert_eq!(kinds(&line), ["M=30"]);
    assert_eq!(line.line_ending(), b"");
    // A lone trailing CR on a last line is a line ending too.
    assert_eq!(kinds(&parse(b"M30\r")), ["M=30", "EOL"]);
    assert!(parse(b"").items.is_empty());
}

#[test]
fn tabs_are_space() {
    assert_eq!(
        k("\tG0\tX1 \t Y2\t\n"),
        ["_", "G=0", "_", "X=1", "_", "Y=2", "_", "EOL"]
    );
}

#[test]
fn blank_lines() {
    assert!(parse(b"\n").is_blank());
    assert!(parse(b"  \t \r\n").is_blank());
    assert!(!parse(b"G1\n").is_blank());
}

#[test]
fn paren_and_semicolon_comments() {
    let line = parse(b"G0 X1 (rapid; not a semicolon comment) ; tail (not paren)\n");
    assert_eq!(kinds(&line), ["G=0", "_", "X=1", "_", "C", "_", "C", "EOL"]);
    let comments: Vec<_> = line.comments().collect();
    assert_eq!(
        comments,
        [
            &b"(rapid; not a semicolon comment)"[..],
            b"; tail (not paren)"
        ]
    );
    assert_eq!(k("(only a comment)"), ["C"]);
    assert_eq!(
        k("G00 X1.82 Y6.05;(Go to start point)"),
        ["G=0", "_", "X=1.82", "_", "Y=6.05", "C"]
    );
    assert_eq!(k("G1(a)X1(b)"), ["G=1", "C", "X=1", "C"]);
}

#[test]
fn unterminated_comment_is_opaque() {
    assert_eq!(k(" ( brocken comment\n"), ["_", "?", "EOL"]);
    assert_eq!(k("(;;))"), ["C", "?"]);
}

#[test]
fn non_utf8_bytes_in_comments() {
    let src = b"G6 B20 R1 ; 20\xB0 counter-clockwise \xff\xfe\r\n";
    let line = parse(src);
    assert_eq!(
        kinds(&line),
        ["G=6", "_", "B=20", "_", "R=1", "_", "C", "EOL"]
    );
    assert_eq!(kinds(&parse(b"(caf\xe9) G1\n")), ["C", "_", "G=1", "EOL"]);
    // Outside a comment, non-UTF-8 bytes are not understood.
    assert_eq!(kinds(&parse(b"G1 \xe9X1\n")), ["G=1", "_", "?", "EOL"]);
}

#[test]
fn reprap_checksums() {
    assert_eq!(k("N3 T0*57"), ["N=3", "_", "T=0", "*57"]);
    assert_eq!(
        k("N4 G1 X10*71 ; ok\n"),
        ["N=4", "_", "G=1", "_", "X=10", "*71", "_", "C", "EOL"]
    );
    assert_eq!(
        k("N4 G1 X10 *71"),
        ["N=4", "_", "G=1", "_", "X=10", "_", "*71"]
    );
    // Not checksums.
    assert_eq!(k("G1 *X"), ["G=1", "_", "?"]);
    assert_eq!(k("G1 *99999999999"), ["G=1", "_", "?"]);
    assert_eq!(k("G1 *12X"), ["G=1", "_", "?"]);
}

#[test]
fn block_delete() {
    assert_eq!(k("/G1 X1"), ["/", "G=1", "_", "X=1"]);
    assert_eq!(k("/1 N10 M0"), ["/", "_", "N=10", "_", "M=0"]);
    assert_eq!(k("  /9G0"), ["_", "/", "G=0"]);
    let line = parse(b"/3 M1\n");
    assert!(line.has_block_delete());
    assert_eq!(item_text(&line, &line.items[0]), "/3");
    // Only at the start of a block.
    assert_eq!(k("G1 /X1"), ["G=1", "_", "?"]);
    // `/12` is not a block delete level; `/0` neither.
    assert_eq!(k("/12 G1"), ["/", "?"]);
    assert_eq!(k("/0 G1"), ["/", "?"]);
}

#[test]
fn percent_lines() {
    assert_eq!(k("%\n"), ["%", "EOL"]);
    assert_eq!(k("%\r\n"), ["%", "EOL"]);
    assert_eq!(k("% (program start)"), ["%", "_", "C"]);
    assert_eq!(k("%;x"), ["%", "C"]);
    assert_eq!(k("%_N_MAIN_MPF\n"), ["%", "?", "EOL"]);
    assert!(parse(b"%").is_percent());
    // `%` elsewhere is not understood.
    assert_eq!(k("G1 %"), ["G=1", "_", "?"]);
}

#[test]
fn n_and_o_numbers() {
    assert_eq!(k("O1000"), ["O=1000"]);
    assert_eq!(k("O0001 (MAIN)"), ["O=1", "_", "C"]);
    assert_eq!(k("N98765 G0 Z30"), ["N=98765", "_", "G=0", "_", "Z=30"]);
    assert_eq!(k("n000   G1 X20"), ["N=0", "_", "G=1", "_", "X=20"]);
}

#[test]
fn oword_flow_is_opaque() {
    for src in [
        "o100 sub",
        "o100 endsub",
        "O100 call [1] [2]",
        "o101 if [#1 GT 5]",
        "o101 else",
        "o101 endif",
        "o103 repeat [5]",
        "o104 while [#1 LT 3]",
        "o104 endwhile",
        "o105 do",
        "o100 return [#1]",
        "o100sub",
    ] {
        assert_eq!(k(src), ["?"], "{src}");
    }
    assert_eq!(k("  o<probe> sub\n"), ["_", "?", "EOL"]);
    assert_eq!(k("o[#101+2] call"), ["?"]);
}

#[test]
fn parameters_and_expressions_are_opaque() {
    assert_eq!(k("#1=2"), ["?"]);
    assert_eq!(k("#<_endmill_dia> = 0.049"), ["?"]);
    assert_eq!(k("[1 + acos[0]]"), ["?"]);
    assert_eq!(k("G1 X[#1+2] Y3"), ["G=1", "_", "?"]);
    assert_eq!(k("G0 X#1"), ["G=0", "_", "?"]);
    assert_eq!(k("N90G0Z[#<zscale>*10.]"), ["N=90", "G=0", "?"]);
}

#[test]
fn siemens_assign_words() {
    let line = parse(b"G1 A3=0.5 R1=2 X=10 AP = -45 ; polar\n");
    assert_eq!(
        kinds(&line),
        [
            "G=1", "_", "A3=0.5!", "_", "R1=2!", "_", "X=10!", "_", "AP=-45!", "_", "C", "EOL"
        ]
    );
    let a3 = line.word("a3").unwrap();
    assert!(a3.assign);
    assert_eq!(line.value_text(a3), b"0.5");
    // Expressions on the right are not understood.
    assert_eq!(k("X=R1+2"), ["?"]);
    assert_eq!(k("X=10+R1"), ["?"]);
    assert_eq!(k("X=IC(10)"), ["?"]);
    assert_eq!(k("G1 X=10Y=5"), ["G=1", "_", "?"]);
}

#[test]
fn siemens_keywords() {
    let line = parse(b"N20 TRAORI\n");
    assert_eq!(kinds(&line), ["N=20", "_", "K:TRAORI", "EOL"]);
    assert_eq!(line.keywords().collect::<Vec<_>>(), ["TRAORI"]);
    assert_eq!(k("TRAFOOF ; off"), ["K:TRAFOOF", "_", "C"]);
    assert_eq!(k("supa g0 z100"), ["K:SUPA", "_", "G=0", "_", "Z=100"]);
    // Calls and labels are not understood.
    assert_eq!(k("TRAORI(1)"), ["?"]);
    assert_eq!(k("CYCLE800(1,\"TC1\",0)"), ["?"]);
    assert_eq!(k("LABEL1:"), ["?"]);
}

#[test]
fn malformed_numbers_make_the_rest_opaque() {
    assert_eq!(k("G1 X1.2.3 Y5"), ["G=1", "_", "?"]);
    assert_eq!(k("G1 X- Y5"), ["G=1", "_", "?"]);
    assert_eq!(k("G1 X"), ["G=1", "_", "?"]);
    assert_eq!(k("G28 X Z"), ["G=28", "_", "?"]);
    assert_eq!(k("G1 X. Y1"), ["G=1", "_", "?"]);
    assert_eq!(k("G1 Xabc1"), ["G=1", "_", "?"]);
    assert_eq!(k("X1 0"), ["X=1", "_", "?"]);
    assert_eq!(k("M563 P0 D0:2:3"), ["M=563", "_", "P=0", "_", "?"]);
}

#[test]
fn nan_and_infinity_are_not_numbers() {
    for src in [
        "XNAN",
        "Xnan",
        "X NaN",
        "Xinf",
        "XINF",
        "X inf",
        "X-inf",
        "X=NAN",
        "X=inf",
        "Xinfinity",
    ] {
        let line = parse(src.as_bytes());
        assert_eq!(kinds(&line), ["?"], "{src}");
        assert!(line.words().next().is_none(), "{src}");
    }
}

#[test]
fn overflowing_numbers_are_opaque() {
    let big = format!("G1 X{} Y1", "9".repeat(400));
    assert_eq!(k(&big), ["G=1", "_", "?"]);
    let big_assign = format!("X={}", "1".repeat(400));
    assert_eq!(k(&big_assign), ["?"]);
    // Many digits that still fit are fine; tiny ones too.
    let w = words(format!("X{}", "1".repeat(300)).as_bytes());
    assert!(w[0].1.is_finite());
    let tiny = format!("X0.{}1", "0".repeat(400));
    assert_eq!(words(tiny.as_bytes()), [("X".to_string(), 0.0)]);
    // `E` is an address, not an exponent.
    assert_eq!(k("X1e999"), ["X=1", "E=999"]);
}

#[test]
fn byte_order_mark_on_line_one() {
    let line = parse_line(b"\xEF\xBB\xBFG1 X1\n", 1);
    assert!(line.is_tiled());
    assert_eq!(kinds(&line), ["Bom", "G=1", "_", "X=1", "EOL"]);
}

#[test]
fn polar_and_other_dialect_symbols_are_opaque() {
    assert_eq!(k("F100 G1 @.5 ^90"), ["F=100", "_", "G=1", "_", "?"]);
    assert_eq!(k("G1 ,C1."), ["G=1", "_", "?"]);
    assert_eq!(k(":1000"), ["?"]);
}

#[test]
fn interior_newlines_and_control_bytes_do_not_break_tiling() {
    // A word must be followed by a separator; a stray CR or LF is none.
    assert_eq!(k("G1\nX1\n"), ["?", "EOL"]);
    assert_eq!(k("G1\rX1"), ["?"]);
    assert_eq!(k("G1 \rX1"), ["G=1", "_", "?"]);
    assert_eq!(
        k(" x58.667 y58.669\u{1}\n"),
        ["_", "X=58.667", "_", "?", "EOL"]
    );
}

#[test]
fn word_helpers() {
    let line = parse(b"G1 X10 x20\n");
    assert_eq!(line.word("x").unwrap().value, 10.0);
    assert!(line.word("Y").is_none());
    let w: &Word = line.word("G").unwrap();
    assert!(w.is("g"));
    let first = &line.items[0];
    assert_eq!((first.col(), first.len(), first.is_empty()), (1, 2, false));
    assert_eq!(line.text_lossy(), "G1 X10 x20");
}

#[test]
fn line_reader_numbers_lines_and_streams() {
    let src = b"%\r\nO1000\r\n\r\nG1 X1\r\nM30";
    let lines: Vec<Line> = LineReader::new(&src[..]).collect::<Result<_, _>>().unwrap();
    assert_eq!(lines.len(), 5);
    assert_eq!(
        lines.iter().map(|l| l.number).collect::<Vec<_>>(),
        [1, 2, 3, 4, 5]
    );
    assert_eq!(lines[4].line_ending(), b"");
    let mut out = Vec::new();
    echo(&src[..], &mut out).unwrap();
    assert_eq!(out, src);
    assert_eq!(LineReader::new(&b""[..]).count(), 0);
}

#[test]
fn line_reader_stops_after_an_io_error() {
    struct Failing;
    impl std::io::Read for Failing {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk on fire"))
        }
    }
    let mut r = LineReader::new(BufReader::new(Failing));
    assert!(r.next().unwrap().is_err());
    assert!(r.next().is_none());
}

#[test]
fn summary_counts() {
    let src = b"%\r\n(head)\r\n/N10 G1 X1 Y2 *12\r\nTRAORI\r\n#1=2\r\n\r\nG1 X\xff\r\nM30";
    let s = summarize(&src[..]).unwrap();
    assert_eq!(s.lines, 8);
    assert_eq!(s.bytes, src.len() as u64);
    assert_eq!(s.blank_lines, 1);
    assert_eq!(s.blocks_with_words, 3);
    assert_eq!(s.words, 6);
    assert_eq!(s.comments, 1);
    assert_eq!(s.keyword_items, 1);
    assert_eq!(s.keywords.get("TRAORI"), Some(&1));
    assert_eq!(s.addresses.get("G"), Some(&2));
    assert_eq!(s.opaque_lines, 2);
    assert_eq!(s.first_opaque_line, Some(5));
    assert_eq!(s.percent_lines, 1);
    assert_eq!(s.block_delete_lines, 1);
    assert_eq!(s.checksums, 1);
    assert_eq!(s.crlf_lines, 7);
    assert_eq!(s.non_utf8_lines, 1);
    assert!(!s.final_newline);
    let json = serde_json::to_value(&s).unwrap();
    assert_eq!(json["blocks_with_words"], 3);
    assert_eq!(json["keywords"]["TRAORI"], 1);
    let text = s.to_string();
    assert!(
        text.contains("opaque lines:      2 (first: line 5)"),
        "{text}"
    );
}

#[test]
fn tiling_check_detects_broken_trees() {
    let good = parse(b"G1 X1\n");
    assert!(good.is_tiled());
    let mut gap = good.clone();
    gap.items.remove(1);
    assert!(!gap.is_tiled());
    let mut overlap = good.clone();
    overlap.items[1].start = 1;
    assert!(!overlap.is_tiled());
    let mut short = good.clone();
    short.items.pop();
    assert!(!short.is_tiled());
    let mut empty = good.clone();
    empty.items.insert(
        0,
        Item {
            start: 0,
            end: 0,
            kind: ItemKind::Space,
        },
    );
    assert!(!empty.is_tiled());
    let mut bad_value = good.clone();
    if let ItemKind::Word(w) = &mut bad_value.items[0].kind {
        w.value_end = 5;
    }
    assert!(!bad_value.is_tiled());
    // Out-of-range items never panic.
    let stray = Item {
        start: 10,
        end: 20,
        kind: ItemKind::Opaque,
    };
    assert_eq!(good.item_bytes(&stray), b"");
}
