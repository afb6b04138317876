//! Messages for text the G-code parser did not understand (an opaque item)
//! in a block that must be converted: a malformed number, a number that is
//! not finite or does not fit, or syntax kinpost does not evaluate.

use crate::gcode::{ItemKind, Line};

/// Why `TRAORI(…)` with more than the transformation's number is refused.
pub const TRAORI_ARGUMENTS: &str = "TRAORI with arguments after the transformation's number (a basic tool orientation, as `TRAORI(1,0,1,0)` for the tool along Y, or rotary offsets) is not converted: kinpost converts with the machine file's tool direction and no offsets; give the tool direction in the machine file and program TRAORI or TRAORI(1)";

/// The longest piece of offending text quoted in a message.
const QUOTE_MAX: usize = 48;

/// What is wrong with the opaque text `bytes` (the not-understood rest of a
/// block), naming the offending text and what was expected.
pub fn describe_opaque(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(bytes);
    let text = text.trim_end_matches(['\r', '\n']);
    if text.contains('\r') {
        return "a carriage return (CR) inside the line: the file seems to use CR-only (old Mac) line endings, which are not line breaks here; convert them to LF or CR LF (e.g. `tr '\\r' '\\n'`)".into();
    }
    if text.contains('\0') {
        return format!(
            "a NUL byte inside the block (`{}`): the file is damaged or not a text NC program",
            quote(&crate::error::visible(text))
        );
    }
    if sinumerik_at_instruction(token(text)) && !text.contains('^') {
        return format!(
            "`{}` in pose mode: a Sinumerik 840/840C `@` instruction (its parameter arithmetic, tests and jumps), or LinuxCNC's polar radius `@`; kinpost evaluates neither, so it cannot know what the blocks after it do; keep it outside TCP, or have the CAM system write the moves",
            quote(token(text))
        );
    }
    if positioning_axis(text) {
        return format!(
            "`{}` in pose mode: a Sinumerik positioning-axis move (POS, POSA) of an axis kinpost writes itself; under TRAORI the controller turns it with the tool, in kinpost's machine words it would be a bare turn of the table; give the orientation as A3 B3 C3 in the poses",
            quote(text.trim())
        );
    }
    if super::fagor::instruction(text).is_some() {
        return format!(
            "a Fagor instruction (`{}`) in pose mode: it switches the control's tool centre point control or a coordinate system or transformation, which would move the axis words kinpost writes; kinpost does not convert Fagor programs",
            quote(text.trim())
        );
    }
    if token(text).starts_with(',') {
        return format!(
            "`{}`: a corner rounding or chamfer (Fanuc, Haas `,R` / `,C`): the controller inserts an arc or a chamfer at the corner, a path kinpost does not convert; have the CAM system write the corner",
            quote(token(text))
        );
    }
    if token(text).starts_with(['@', '^']) {
        return format!(
            "polar coordinates (`{}`: LinuxCNC `@` radius, `^` angle) in pose mode are not converted: tool poses must be given as X Y Z; write Cartesian coordinates in the CAM post",
            quote(token(text))
        );
    }
    if let Some(name) = call_name(text) {
        if known_call(text) == Some("TRAORI(…)") {
            return TRAORI_ARGUMENTS.into();
        }
        if name.eq_ignore_ascii_case("TRAORI") {
            return format!(
                "`{}` is followed by more text on its line: kinpost converts TRAORI(…) on a line of its own (a comment may follow); put the rest on the next line",
                quote(text.trim())
            );
        }
        return format!(
            "a cycle or subprogram call (`{}`) in pose mode is not converted: kinpost cannot see what it moves{}; call it outside TRAORI / G43.4, or have the CAM system write its moves",
            quote(&name),
            if name.eq_ignore_ascii_case("CYCLE800") {
                " (CYCLE800 swivels the work plane)"
            } else {
                ""
            }
        );
    }
    if let Some(statement) = o_word_statement(text) {
        return format!(
            "an o-word control statement (`{}`: LinuxCNC flow control) in pose mode: kinpost does not evaluate it, so it cannot know which pose blocks run, or how often; have the CAM system write the moves without flow control, or keep it outside G43.4 / TCP",
            quote(&statement)
        );
    }
    if text.trim_start().starts_with('(') && !text.contains(')') {
        return format!(
            "unclosed comment `{}`: a `(` without its `)`; in a block that must be converted it would hide the words after it",
            quote(text.trim_start())
        );
    }
    let token: &str = token(text);
    let quoted = quote(token);
    let letters = token
        .bytes()
        .take_while(|b| b.is_ascii_alphabetic())
        .count();
    let generic = || {
        format!(
            "this block must be converted but holds syntax kinpost does not evaluate (`{quoted}`: an expression, parameter or macro call); expected plain numeric words such as X12.5"
        )
    };
    if letters == 0 {
        return generic();
    }
    // `XNAN`, `X-inf`, `A3=inf`: the address is one letter (and digits, `=`).
    let first = &token[..1];
    let tail = token[1..]
        .trim_start_matches(|c: char| {
            c.is_ascii_digit() || matches!(c, '=' | ' ' | '\t' | '+' | '-')
        })
        .to_ascii_lowercase();
    if ["nan", "inf"].iter().any(|w| tail.starts_with(w)) {
        return format!("`{quoted}` is not a finite number; expected a number such as {first}12.5");
    }
    let (address, rest) = token.split_at(letters);
    // Address digits (`A3`) and `=` belong to the address.
    let rest = rest.trim_start_matches(|c: char| c.is_ascii_digit() && address.len() > 1);
    let value = rest.trim_start_matches([' ', '\t', '=']);
    if let Some(m) = sinumerik_value(token, text) {
        return m;
    }
    if value.is_empty() && address.len() >= 3 {
        return format!(
            "`{quoted}` is a keyword kinpost does not read (such as Sinumerik ORIVIRT1, ORIRPY2 or DIAM90, modes that change what later words mean); expected plain numeric words such as X12.5"
        );
    }
    if value.is_empty() {
        return format!(
            "`{quoted}`: the word {address} has no number; expected a number such as {address}12.5"
        );
    }
    // A name (`CYCLE_974`, `CGTECH_MACRO`: a call, a variable, a keyword),
    // not an address with a bad number.
    if value.starts_with(['[', '#', '<', '_']) || address.len() >= 3 {
        return generic();
    }
    let unsigned = value.trim_start_matches(['+', '-']).trim_start();
    let numeric = |c: char| c.is_ascii_digit() || c == '.';
    if !unsigned.starts_with(numeric) {
        return format!("malformed number `{quoted}`; expected a number such as {address}12.5");
    }
    let body: String = unsigned.chars().take_while(|&c| numeric(c)).collect();
    let after = &unsigned[body.len()..];
    if body.matches('.').count() > 1 {
        return format!(
            "malformed number `{quoted}`: more than one decimal point; expected a number such as {address}12.5"
        );
    }
    if after.starts_with(',') {
        return format!(
            "malformed number `{quoted}`: a comma is not a decimal point; expected a number such as {address}12.5"
        );
    }
    if body.parse::<f64>().is_ok_and(f64::is_infinite) {
        return format!(
            "number out of range `{quoted}` ({} digits): it does not fit a 64-bit float (beyond ±1.8e308); expected a coordinate in mm or inch",
            body.chars().filter(char::is_ascii_digit).count()
        );
    }
    format!("malformed number `{quoted}`; expected a number such as {address}12.5")
}

/// The message for a Sinumerik value that is not a number: `X=IC(2)`
/// (an incremental or absolute dimension function), `X=R1` (an R
/// parameter). `token` is the first token of `text`.
fn sinumerik_value(token: &str, text: &str) -> Option<String> {
    let eq = token.find('=')?;
    let address = &token[..eq];
    let value = text.trim_start()[eq + 1..].trim_start();
    let name: String = value
        .chars()
        .take_while(char::is_ascii_alphabetic)
        .collect::<String>()
        .to_ascii_uppercase();
    let after = value[name.len()..].trim_start();
    if after.starts_with('(')
        && matches!(
            name.as_str(),
            "IC" | "AC" | "DC" | "ACP" | "ACN" | "CIC" | "CAC" | "CACP" | "CACN"
        )
    {
        let call = call_len(value).map_or(value, |n| &value[..n]);
        return Some(format!(
            "`{}={}`: a Sinumerik dimension function ({name}(…): {}) that kinpost does not evaluate; in pose mode expected a plain absolute number such as {address}=12.5 (have the CAM post write absolute values)",
            quote(address),
            quote(call),
            match name.as_str() {
                "IC" | "CIC" => "incremental for this word",
                "AC" | "CAC" => "absolute for this word",
                _ => "a rotary axis position by the shortest way or in one direction",
            }
        ));
    }
    if name == "R" && after.starts_with(|c: char| c.is_ascii_digit()) {
        let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
        return Some(format!(
            "`{}=R{digits}`: an R parameter (a Sinumerik variable) that kinpost does not evaluate; in pose mode expected a plain number such as {address}=12.5 (have the CAM post write the values)",
            quote(address)
        ));
    }
    None
}

/// A LinuxCNC o-word control statement at the start of `text` (`o100 if`,
/// `o<loop> while`, `o100 endsub`), as `o100 if`: kinpost does not
/// evaluate flow control. `o100 call` is a call ([`call_name`]).
pub fn o_word_statement(text: &str) -> Option<String> {
    let t = text.trim_start();
    let rest = t.strip_prefix(['o', 'O'])?;
    let name_len = if rest.starts_with('<') {
        rest.find('>')? + 1
    } else {
        rest.chars().take_while(char::is_ascii_digit).count()
    };
    if name_len == 0 {
        return None;
    }
    let keyword = rest[name_len..]
        .trim_start()
        .split(|c: char| !c.is_ascii_alphabetic())
        .next()
        .unwrap_or_default();
    const FLOW: &[&str] = &[
        "if",
        "elseif",
        "else",
        "endif",
        "while",
        "endwhile",
        "do",
        "repeat",
        "endrepeat",
        "break",
        "continue",
        "sub",
        "endsub",
        "return",
    ];
    FLOW.iter()
        .any(|k| k.eq_ignore_ascii_case(keyword))
        .then(|| format!("o{} {}", &rest[..name_len], keyword))
}

/// `@` and three digits (`@136`): the form of the Sinumerik 840/840C `@`
/// language's instructions (`@136 R102 K5 K900`), which LinuxCNC would read
/// as a polar radius.
fn sinumerik_at_instruction(token: &str) -> bool {
    token
        .strip_prefix('@')
        .is_some_and(|n| n.len() == 3 && n.bytes().all(|b| b.is_ascii_digit()))
}

/// The first blank-separated token of `text` (comments cut off).
fn token(text: &str) -> &str {
    let t = text.trim_start();
    let end = t
        .char_indices()
        .find(|&(i, c)| matches!(c, '(' | ';') || (matches!(c, ' ' | '\t') && !sign_only(&t[..i])))
        .map_or(t.len(), |(i, _)| i);
    &t[..end]
}

/// `X-` or `X+`: the blank after a sign belongs to the number (`X- 3`).
fn sign_only(t: &str) -> bool {
    let t = t.trim_end();
    t.ends_with(['+', '-'])
        && t.trim_end_matches(['+', '-'])
            .chars()
            .all(|c| c.is_ascii_alphabetic())
}

/// `s`, shortened to [`QUOTE_MAX`] characters with an ellipsis.
fn quote(s: &str) -> String {
    let s = &crate::error::visible(s);
    if s.chars().count() <= QUOTE_MAX {
        s.to_string()
    } else {
        let head: String = s.chars().take(QUOTE_MAX).collect();
        format!("{head}…")
    }
}

/// The item index of an opaque item in a block that must be converted (or may
/// carry coordinates in pose mode), or of a `TRAORI(…)` call followed by
/// other text on its line (in any mode: it switches TCP on, and kinpost
/// cannot rewrite it).
pub fn opaque_in_pose_block(
    line: &Line,
    pose_mode: bool,
    is_pose: bool,
    straight: bool,
) -> Option<usize> {
    // Only opaque items are looked at (their text copied only then: this
    // runs for every line, and most lines have none).
    if !line
        .items
        .iter()
        .any(|it| matches!(it.kind, ItemKind::Opaque))
    {
        return None;
    }
    if let Some(i) = line.items.iter().position(|it| {
        matches!(it.kind, ItemKind::Opaque) && {
            let text = String::from_utf8_lossy(line.item_bytes(it));
            call_name(&text).is_some_and(|n| n.eq_ignore_ascii_case("TRAORI"))
                && known_call(&text).is_none()
        }
    }) {
        return Some(i);
    }
    if !(pose_mode || is_pose) {
        if !straight {
            return None;
        }
        // Outside pose mode a straight move whose unreadable text holds a
        // tool vector (`G1 X1.2.3 Y0 Z0 I0 J0 K1`: the parser stops at the
        // malformed number) still asks for pose conversion: refuse it
        // rather than pass it through unconverted.
        return line.items.iter().position(|it| {
            matches!(it.kind, ItemKind::Opaque) && holds_tool_vector(line.item_bytes(it))
        });
    }
    line.items.iter().position(|it| {
        if !matches!(it.kind, ItemKind::Opaque) {
            return false;
        }
        let text = String::from_utf8_lossy(line.item_bytes(it));
        !matches!(known_call(&text), Some("TRAORI" | "MSG"))
            && (is_pose || !harmless_call(&text))
            && (is_pose
                || call_name(&text).is_some()
                || positioning_axis(&text)
                || o_word_statement(&text).is_some()
                || line.item_bytes(it).iter().any(|b| {
                    matches!(
                        b.to_ascii_uppercase(),
                        b'X' | b'Y' | b'Z' | b'I' | b'J' | b'K' | b'@' | b'^'
                    )
                }))
    })
}

/// Sinumerik calls that move nothing: a message, the high-speed settings
/// cycle, the blank for the simulation, the master spindle, feed groups,
/// waits, the piece counter and an alarm set by the program.
pub const HARMLESS_CALLS: &[&str] = &[
    "MSG",
    "SETAL",
    "CYCLE832",
    "WORKPIECE",
    "SETMS",
    "FGROUP",
    "WAITM",
    "WAITMC",
    "WAITS",
    "SETPIECE",
];

/// Whether the opaque `text` is one of the calls that move nothing
/// ([`HARMLESS_CALLS`]: `CYCLE832(…)`, `MSG(…)`, `WAITM(…)`, …) standing
/// alone (a comment after it allowed): in pose mode it passes, as outside
/// it (NX and Autodesk 840D posts call `CYCLE832` per operation, with
/// TRAORI still on).
pub fn harmless_call(text: &str) -> bool {
    let Some(name) = call_name(text) else {
        return false;
    };
    let Some(end) = call_len(text) else {
        return false;
    };
    let rest = text[end..].trim_start();
    HARMLESS_CALLS.contains(&name.to_ascii_uppercase().as_str())
        && (rest.is_empty() || rest.starts_with([';', '(', '\r', '\n']))
}

/// Whether `text` moves a Sinumerik positioning axis (`POS[C]=90`,
/// `POSA[B]=10`): under `TRAORI` a turn of a rotary that kinpost's machine
/// words, written for `TRAFOOF`, would make as a bare turn of the table.
pub fn positioning_axis(text: &str) -> bool {
    let t = text.trim_start().to_ascii_uppercase();
    t.starts_with("POS[") || t.starts_with("POSA[")
}

/// A Sinumerik call that the parser leaves opaque but kinpost understands,
/// as the pseudo-keyword the modal state reads: `TRAORI(…)` (TCP on, like
/// `TRAORI`), `MSG(…)` (a message: no motion), `CYCLE800(…)` (the work
/// plane swivelled: a frame) and `CYCLE800()` (the swivel reset). The call
/// must stand alone: followed only by blanks or a comment. Any other text
/// gives `None`.
pub fn known_call(text: &str) -> Option<&'static str> {
    let name = call_name(text)?;
    let end = call_len(text)?;
    let rest = text[end..].trim_start();
    if !(rest.is_empty() || rest.starts_with([';', '(', '\r', '\n'])) {
        return None;
    }
    let args = text[..end].trim();
    let empty = args[name.len()..]
        .trim_start()
        .trim_start_matches('(')
        .trim_end_matches(')')
        .trim()
        .is_empty();
    match name.to_ascii_uppercase().as_str() {
        // `TRAORI(1)`: the transformation's number alone; more arguments
        // set a basic tool orientation or rotary offsets.
        "TRAORI" if args.contains(',') => Some("TRAORI(…)"),
        "TRAORI" => Some("TRAORI"),
        "MSG" => Some("MSG"),
        "CYCLE800" if empty => Some("CYCLE800()"),
        "CYCLE800" => Some("CYCLE800"),
        _ => None,
    }
}

/// The length in bytes of the call `NAME(…)` at the start of `text`
/// (leading blanks included), up to its matching `)`; `None` when the
/// parentheses do not close. Parentheses inside `"…"` strings do not count.
pub fn call_len(text: &str) -> Option<usize> {
    let open = text.find('(')?;
    let mut depth = 0usize;
    let mut quoted = false;
    for (i, c) in text[open..].char_indices() {
        match c {
            '"' => quoted = !quoted,
            '(' if !quoted => depth += 1,
            ')' if !quoted => {
                depth -= 1;
                if depth == 0 {
                    return Some(open + i + 1);
                }
            }
            _ => {}
        }
    }
    None
}

/// The name of a call: Sinumerik-style `NAME(…)` (`CYCLE800(1,…)`: a
/// letter, then letters, digits or `_`, at least two characters, then
/// `(`), or a LinuxCNC o-word call (`o100 call`, `o<probe> call [1]`).
pub fn call_name(text: &str) -> Option<String> {
    let t = text.trim_start();
    if t.starts_with(['o', 'O']) {
        let mut parts = t.split_whitespace();
        let name = parts.next().unwrap_or_default();
        if parts.next().is_some_and(|w| w.eq_ignore_ascii_case("call")) {
            return Some(format!("{name} call"));
        }
    }
    let name: String = t
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    let first_letter = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic());
    (first_letter && name.len() >= 2 && t[name.len()..].trim_start().starts_with('('))
        .then_some(name)
}

/// Whether unreadable text holds a tool-vector word: `I`, `J` or `K`
/// followed by a number, or `A3=`, `B3=`, `C3=`.
fn holds_tool_vector(bytes: &[u8]) -> bool {
    // Names (`o<i0>`, `#<i1>`), expressions (`[...]`) and comments left out.
    let mut depth = 0i32;
    let up: Vec<u8> = bytes
        .iter()
        .filter(|&&b| {
            match b {
                b'<' | b'[' | b'(' => depth += 1,
                b'>' | b']' | b')' => depth -= 1,
                _ => return depth <= 0,
            }
            false
        })
        .map(u8::to_ascii_uppercase)
        .collect();
    // A word starts where no letter comes before it: the `I3` inside a
    // name (`Node name : cyi3w080`, a line of an NX listing's header) is
    // no tool vector.
    let starts_word = |i: usize| i == 0 || !up[i - 1].is_ascii_alphabetic();
    let ijk = |i: usize| {
        matches!(up[i], b'I' | b'J' | b'K')
            && up
                .get(i + 1)
                .is_some_and(|n| n.is_ascii_digit() || matches!(n, b'-' | b'+' | b'.'))
    };
    let abc3 =
        |i: usize| matches!(up[i], b'A' | b'B' | b'C') && up.get(i + 1..i + 3) == Some(&b"3="[..]);
    (0..up.len()).any(|i| (ijk(i) || abc3(i)) && starts_word(i))
}

/// [`unreadable_motion`] of the opaque item `index` of `line`: whether
/// its text may hold where an axis goes, the item following a word of the
/// block or not.
pub fn unreadable_motion_at(line: &Line, index: usize) -> bool {
    let text = String::from_utf8_lossy(line.item_bytes(&line.items[index]));
    let after_word = line.items[..index]
        .iter()
        .rev()
        .find(|it| it.kind != ItemKind::Space)
        .is_some_and(|it| matches!(it.kind, ItemKind::Word(_)));
    unreadable_motion(text.trim(), after_word)
}

/// Whether the unreadable text `text` of a block may hold where an axis
/// goes: a motion address followed by what is not a plain number (`Y#1`,
/// `Y [2]`, `Y sqrt[2]`, `X=R1`: a parameter, an expression or a
/// function), or digits that continue a number cut by a blank (`Y50 0`,
/// which LinuxCNC reads as Y500) or a malformed one (`after_word`: the
/// text follows a word of the block; Heidenhain's block numbers start
/// their lines).
pub fn unreadable_motion(text: &str, after_word: bool) -> bool {
    let mut chars = text.chars();
    let Some(first) = chars.next() else {
        return false;
    };
    // A number cut by a blank or malformed; a letter alone (`Y5O`).
    if after_word
        && (first.is_ascii_digit()
            || "+-.".contains(first)
            || (first.is_ascii_alphabetic() && chars.as_str().is_empty()))
    {
        return true;
    }
    if !"XYZABCUVWIJKF".contains(first.to_ascii_uppercase()) {
        return false;
    }
    let after = chars.as_str();
    let rest = after.trim_start();
    let blank = rest.len() < after.len();
    let name_len = rest.bytes().take_while(u8::is_ascii_alphabetic).count();
    let applied = rest[name_len..].trim_start();
    match rest.chars().next() {
        None => false,
        // Letters after the axis letter: a function applied to it
        // (LinuxCNC `Y sqrt[2]`, `Ysqrt[2]`, `Y sin (…)` after a blank);
        // else a keyword or a call that starts with an axis letter
        // (`CYCLE81(…)`, `XOR`).
        Some(c) if c.is_ascii_alphabetic() => {
            applied.starts_with('[') || (blank && applied.starts_with('('))
        }
        Some(_) => true,
    }
}

#[cfg(test)]
mod tests {
    use super::describe_opaque as d;

    #[test]
    fn names_the_problem() {
        assert!(d(b"X1.2.3 Y5").starts_with("malformed number `X1.2.3`: more than one"));
        assert!(d(b"XNAN Y0").starts_with("`XNAN` is not a finite number"));
        assert!(d(b"X-inf").starts_with("`X-inf` is not a finite number"));
        let long = format!("X{}", "9".repeat(400));
        let m = d(long.as_bytes());
        assert!(m.starts_with("number out of range `X999"), "{m}");
        assert!(m.contains("400 digits") && m.contains('…'), "{m}");
        assert!(d(b"X1,5").contains("comma"));
        assert!(d(b"X[#1+2]").contains("expression"));
        assert!(d(b"#1=5").contains("expression"));
        assert!(d(b"X").contains("has no number"));
        assert!(d(b"A3=abc").starts_with("malformed number `A3=abc`"));
        assert!(d(b"X- 1.2.3").starts_with("malformed number `X- 1.2.3`"));
        assert!(d(b"X=IC(2) Y1").starts_with("`X=IC(2)`: a Sinumerik dimension function"));
        assert!(d(b"A3=R12").starts_with("`A3=R12`: an R parameter"));
        assert!(d(b"O<a> WHILE [1]").starts_with("an o-word control statement (`o<a> WHILE`"));
        assert!(d(b"o100").starts_with("malformed number"));
        // A name is not an address with a bad number (it was "expected a
        // number such as CYCLE12.5", on a Vericut Sinumerik file).
        for name in [&b"CYCLE_974"[..], b"CGTECH_MACRO", b"L_HOME"] {
            let m = d(name);
            assert!(
                m.contains("does not evaluate") && m.contains("such as X12.5"),
                "{m}"
            );
        }
    }
}
