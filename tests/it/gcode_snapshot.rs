//! How a mixed-dialect sample is classified, as an insta snapshot: a change
//! in the parser's reading of any of these lines shows up in review.

use kinpost::gcode::{ItemKind, LineReader};

const SAMPLE: &[u8] = b"%\r
O1000 (MIXED DIALECT SAMPLE)\r
N10 G90 G94 G17 G21\r
N20 T1 M6 ; tool change\r
/N30 M1\r
N40 G43.4 H1\r
N50 G0 X 16.339 Y -25.409 Z33.353 A-71.841 C-35.93\r
N60 G1X10Y20F.5\r
N70 TRAORI\r
N80 G1 A3=0.5 R1=2 X=10\r
N90 X=R1+2\r
N3 T0*57\r
#<depth> = [#1 * 2]\r
o100 sub\r
G1 X[#<depth>] (param)\r
G1 X1.2.3 Y5\r
G28 X Z\r
(caf\xe9 \xff)\r
\tG1\tx.5 y5.\r
M30\r
%";

fn render() -> String {
    let mut out = String::new();
    for line in LineReader::new(SAMPLE) {
        let line = line.unwrap();
        out.push_str(&format!("{:>2}:", line.number));
        for item in &line.items {
            let text = String::from_utf8_lossy(line.item_bytes(item))
                .escape_debug()
                .to_string();
            let kind = match &item.kind {
                ItemKind::Space => continue,
                ItemKind::EndOfLine => "EOL".to_string(),
                ItemKind::Word(w) => format!(
                    "Word {}{}{} ({})",
                    w.address,
                    if w.assign { "=" } else { " " },
                    w.value,
                    String::from_utf8_lossy(line.value_text(w))
                ),
                ItemKind::Keyword(k) => format!("Keyword {k}"),
                ItemKind::Checksum(v) => format!("Checksum {v}"),
                other => format!("{other:?}"),
            };
            out.push_str(&format!(" [{kind} `{text}`]"));
        }
        out.push('\n');
    }
    out
}

#[test]
fn mixed_dialect_sample() {
    insta::assert_snapshot!(render());
}
