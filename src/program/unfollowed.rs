//! What kinpost does not follow in a block: words that give the tool
//! orientation otherwise than by a tool vector, and G codes and Sinumerik
//! transformations that move the machine otherwise than the block's axis
//! words say (a probing move, a pocket cycle), or make later words mean
//! something else (polar or cylindrical interpolation, a diameter). Such a
//! block is refused in pose mode, and by the commands that follow a
//! program's motion in machine axes (`analyze`, `simulate`, `linkage`);
//! outside pose mode `post` passes it through. G codes are checked against
//! the list of those kinpost reads or knows to leave the axes' meaning
//! alone, so a code it has never met is refused too (docs/programs.md).

/// Words that give the tool orientation, or something tied to it, in a
/// pose block other than a tool vector; refused in pose mode.
pub const ORIENTATION_WORDS: &[&str] = &[
    "A", "B", "C", "A2", "B2", "C2", "A4", "B4", "C4", "A5", "B5", "C5", "A6", "B6", "C6", "A7",
    "B7", "C7", "A8", "B8", "C8", "XH", "YH", "ZH", "LEAD", "TILT", "THETA",
];

/// Sinumerik words that add motion between a block and the next, or
/// define a contour otherwise than by its end point: a rounding (`RND`,
/// modal `RNDM`), a chamfer (`CHF`, `CHR`), a contour angle (`ANG`), an
/// arc's opening angle or radius (`AR`, `CR`), polar coordinates (`AP`,
/// `RP`).
pub const PATH_WORDS: &[&str] = &["RND", "RNDM", "CHF", "CHR", "ANG", "AR", "CR", "AP", "RP"];

/// Why a word with `address` is refused in a pose block: one of
/// [`ORIENTATION_WORDS`] or [`PATH_WORDS`]; `None` for any other.
pub fn pose_word(address: &str) -> Option<String> {
    // Of the one-letter addresses only A B C are among them.
    if address.len() == 1 && !matches!(address, "A" | "B" | "C") {
        return None;
    }
    if ORIENTATION_WORDS.contains(&address) {
        return Some(orientation_message(address));
    }
    PATH_WORDS
        .contains(&address)
        .then(|| format!("`{address}=` {}: not converted in pose mode; have the CAM system write the path as straight G1 poses", path_word(address)))
}

/// What the Sinumerik word `address` (one of [`PATH_WORDS`]) does.
pub fn path_word(address: &str) -> &'static str {
    match address {
        "RND" | "RNDM" | "CHF" | "CHR" => {
            "makes the controller insert a rounding or a chamfer at the corner (Sinumerik RND, RNDM, CHF, CHR), a path kinpost does not follow"
        }
        "AP" | "RP" => "is a polar coordinate (Sinumerik AP= angle, RP= radius)",
        _ => {
            "defines the contour by an angle or an arc's radius or opening (Sinumerik ANG, AR, CR)"
        }
    }
}

/// What a Fanuc lathe's `G50 X Z` does (a set-up, refused in pose mode).
pub const LATHE_G50: &str = "sets the coordinate system (lathe G50 X Z, as G92)";

/// What a lathe's cutting cycle does ([`lathe_cycle`]).
pub const LATHE_CYCLE: &str = "a lathe's cutting cycle (Fanuc G70–G74 with the contour's sequence numbers P Q or its allowances and depths U W R; LinuxCNC G70–G72 with the contour's subroutine Q): it cuts a contour with moves of its own that its words do not give";

/// Whether the G code `code` (ten times its value), in a block holding
/// the addresses `has` tells, is a lathe's cutting cycle: Fanuc's
/// multiple repetitive cycles `G70`–`G73` (finishing, stock removal in
/// turning and facing, pattern repeating: the contour between the
/// sequence numbers `P` and `Q`, the allowances `U` `W`, or the depth and
/// retract `U R` / `W R` of their first block), `G74` with a `Q` (end
/// face peck drilling; a mill's `G74` tapping cycle has none), and
/// LinuxCNC's `G70`–`G72.2` with `Q` (the contour's subroutine).
/// Sinumerik's `G70`/`G71` (inch / mm) carry none of these words, nor does
/// a mill's peck drilling `G73` (`X Y Z R Q`) carry `P` with `Q`, `U`
/// or `W`.
pub fn lathe_cycle(code: i64, has: impl Fn(&str) -> bool) -> bool {
    match code {
        700 | 710 | 720 => ["P", "Q", "U", "W", "D"].iter().any(|a| has(a)),
        711 | 712 | 721 | 722 => has("Q"),
        730 => has("U") || has("W") || (has("P") && has("Q")),
        740 => has("Q"),
        _ => false,
    }
}

/// Why polar coordinates are refused in pose mode.
pub const POLAR: &str = "polar coordinates (Sinumerik G110–G112 pole, AP= angle, RP= radius) in pose mode are not converted: tool poses must be given as X Y Z; write Cartesian coordinates in the CAM post";

/// Why a move in the block of `G16` is not followed.
pub const POLAR_MOVE: &str =
    "a polar move (G16 with axis words in its block: X the radius, Y the angle)";

/// Why Fanuc's `G43.5 … Q` is refused.
pub const TCP_INCLINATION: &str =
    "a tool inclination angle (Fanuc G43.5 … Q: the tool tilted Q degrees from I J K)";

/// Why Sinumerik `ORIMKS` is refused in pose mode.
pub const ORIMKS: &str = "Sinumerik ORIMKS in pose mode: the tool vectors (A3 B3 C3) are then in machine coordinates, not in the workpiece frame kinpost converts from; program ORIWKS (the default) with TRAORI";

/// Why cutter radius compensation is refused in pose mode.
pub const CUTTER_COMP: &str = "cutter radius compensation (G41, G42, G41.1, G42.1, G41.2, G42.2) in pose mode is not converted: the controller would offset kinpost's machine axis words by the tool radius; give the poses of the tool tip with the radius applied in the CAM system (G40 cancels it)";

/// Whether `address` names a machine axis by a number (Sinumerik `X1=`,
/// `Z1=`, `C1=`, `AX4=`: a channel's or machine's axis identifier), not
/// one of the pose and orientation words (`A3`, `A2`, …, [`ORIENTATION_WORDS`]).
pub fn numbered_axis(address: &str) -> bool {
    let ax = address.len() > 2
        && address.starts_with("AX")
        && address[2..].bytes().all(|b| b.is_ascii_digit());
    (indexed_axis(address)
        && !matches!(address, "A3" | "B3" | "C3")
        && !ORIENTATION_WORDS.contains(&address))
        || ax
}

/// Whether `address` is an axis letter (`X Y Z A B C U V W`) with a
/// number after it (`Z1`, `X2`; also the pose words `A3`, `A2`, …), as
/// Sinumerik names an axis by its channel index.
pub fn indexed_axis(address: &str) -> bool {
    let b = address.as_bytes();
    b.len() > 1
        && matches!(
            b[0],
            b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W'
        )
        && b[1..].iter().all(u8::is_ascii_digit)
}

/// Why a secondary axis word (`U`, `V`, `W`, `E`), or an axis named by a
/// number ([`numbered_axis`]), is refused in pose mode.
pub fn secondary_axis_message(address: &str) -> String {
    if numbered_axis(address) {
        return format!(
            "`{address}=` names a machine axis by its number (Sinumerik X1, Z1, AX4): it would move that axis beside kinpost's machine axis words, off the converted pose; not converted; leave it out of the blocks between TRAORI / G43.4 and TRAFOOF / G49"
        );
    }
    format!(
        "`{address}` in pose mode: {} would move the tool off the converted pose; not converted; leave it out of the blocks between G43.4 / TRAORI and G49 / TRAFOOF",
        if address == "E" {
            "E: an extruder or seventh axis in some dialects"
        } else {
            "U/V/W: a secondary linear axis (a quill, a second slide)"
        }
    )
}

/// Why `address` (one of [`ORIENTATION_WORDS`]) is refused in pose mode.
pub fn orientation_message(address: &str) -> String {
    if matches!(address, "A" | "B" | "C") {
        return format!(
            "`{address}` gives the tool orientation as a rotary axis position, which kinpost reads only under the TCP codes that take it (Fanuc G43.4, type 1; Haas G234; Sinumerik TRAORI): not converted here, in a pose mode started by G43.5 (type 2: I J K), by a tool vector or by --pose-start on; switch TCP on with G43.4 / TRAORI, or give the tool vector as I J K"
        );
    }
    format!(
        "`{address}` gives the tool orientation another way than by a tool vector ({}): not converted; give the tool vector as I J K (G43.5 / LinuxCNC) or A3 B3 C3 (Sinumerik ORIVECT) in the CAM post",
        match address {
            "A2" | "B2" | "C2" => "Euler or RPY angles",
            "A6" | "B6" | "C6" | "A7" | "B7" | "C7" => {
                "a rotation or cone axis, or an intermediate orientation (Sinumerik ORICONxx, ORIPLANE)"
            }
            "XH" | "YH" | "ZH" => "a second point of the tool (Sinumerik ORICURVE)",
            "A8" | "B8" | "C8" => "a direction of the tool's retract (Sinumerik A8 B8 C8)",
            "LEAD" | "TILT" => "lead and tilt angles",
            "THETA" => "a rotation of the tool about itself",
            _ => "a surface normal for 3-D tool compensation",
        }
    )
}

/// G codes (ten times their value) that reach the modal state's catch-all
/// and leave the meaning of the axis words alone: planes and arc-centre
/// modes (read by `program::arc`), plain tool length compensation
/// (`program::length_comp`), exact stop and path control (`G8` look-ahead
/// or LinuxCNC's radius mode, `G9`, `G60`, `G61`, `G61.1`, `G62`, `G63`,
/// `G64`, Haas `G103`, `G187`), spindle modes (`G96`, `G97`), canned-cycle
/// return levels and Fanuc lathe feed modes (`G98`, `G99`), the cancels
/// `G11`, `G13.1`, `G15`, `G23`, `G67`, `G100` (Haas mirror off), storing
/// a position (`G28.1`, `G30.1`), LinuxCNC's end of a NURBS block (`G5.3`)
/// and additional tool length offset (`G43.2`), Mazak's `G69.5`,
/// Sinumerik's exact-stop windows (`G601`–`G603`), corner deceleration
/// (`G621`) and continuous-path modes with corner rounding (`G641`–`G645`,
/// the forms of `G64` its high-speed programs set), Okuma's `G168` (its
/// tool centre point control off), Sinumerik's corner behaviour under
/// cutter compensation (`G450`, `G451`).
const LEAVES_AXES_ALONE: &[i64] = &[
    53, 432, 695, 80, 90, 110, 131, 170, 180, 190, 230, 281, 301, 430, 431, 440, 600, 610, 611,
    620, 630, 640, 670, 901, 911, 960, 970, 980, 990, 1000, 1030, 1870, 6010, 6020, 6030, 6210,
    6410, 6420, 6430, 6440, 6450, 1680, 4500, 4510,
];

/// What the G code `code` (ten times its value) does that kinpost does
/// not follow, or `None` when it is read or leaves the axes alone
/// (the list above). Codes the modal state reads itself never get
/// here.
/// Whether G code `code` (its value times ten) is a probing or skip
/// move (`G31`–`G31.4`, `G38.2`–`G38.5`), which stops where a signal
/// comes.
pub fn is_probe(code: i64) -> bool {
    matches!(code, 310..=314 | 382..=385)
}

pub fn g_code(code: i64) -> Option<String> {
    if LEAVES_AXES_ALONE.contains(&code) {
        return None;
    }
    let what = match code {
        685 => "an inclined work plane (Mazak G68.5): a frame",
        71 | 1070 => {
            "cylindrical interpolation (Fanuc G7.1, Haas G107): the rotary's words become lengths on a cylinder"
        }
        121 => {
            "polar coordinate interpolation (Fanuc G12.1): X and the rotary move as Cartesian X and Y"
        }
        650 | 660 | 661 => "a macro call (G65, G66, G66.1): its moves stand elsewhere",
        70 => {
            "diameter mode (LinuxCNC G7: X is a diameter) or hypothetical axis interpolation (Fanuc G07)"
        }
        c if is_probe(c) => {
            "a probing or skip move (G31, G38.x): it stops where a signal comes, not where its words say"
        }
        21 | 22 | 23 | 24 | 31 | 32 | 33 | 34 => {
            "a special interpolation (spiral, involute, exponential or 3-D circle)"
        }
        120 | 130 => "circular pocket milling (Haas G12, G13): a cycle that moves the tool",
        220 => "stored stroke limits (Fanuc G22): its X Y Z I J K are limits, not a move",
        270 | 290 => {
            "a reference position check or return (G27, G29): it moves through points its words do not give"
        }
        470 => {
            "text engraving (Haas G47: a cycle that writes its text with moves of its own) or a tool offset change (Fanuc G47) that moves the tool off its words"
        }
        390 | 450 | 460 | 480 => {
            "a corner offset or tool offset change (G39, G45–G48) that moves the tool off its words"
        }
        512 => "polygon turning (G51.2): an axis synchronised with the spindle",
        531 => "tool axis direction control (G53.1): the controller turns the rotaries",
        1010 | 2680 => "mirror imaging or feature coordinates (Haas G101, G268): a frame",
        1360 | 1500 | 1740 | 1840 => {
            "a probing, pocket or tapping cycle (Haas G136, G150, G174, G184)"
        }
        1410 | 1430 => "3-D cutter or five-axis tool length compensation (Haas G141, G143)",
        171 | 181 | 191 => "a plane of the U V W axes (LinuxCNC G17.1–G19.1)",
        _ => "",
    };
    Some(if what.is_empty() {
        format!(
            "G{} is a code kinpost does not know: it may move the machine otherwise than the axis words say, or change what later words mean",
            g_name(code)
        )
    } else {
        format!("G{} is {what}", g_name(code))
    })
}

/// Whether the G code `code` (ten times its value) switches on
/// (`Some(true)`) or off an interpolation mode that changes what later
/// axis words mean: Fanuc polar coordinate interpolation `G12.1` (off:
/// `G13.1`), cylindrical interpolation `G7.1` and Haas `G107` with a
/// radius (`radius`: the block has a `C` other than 0; off: with `C0`),
/// LinuxCNC's diameter mode `G7` (off: `G8`), Okuma's tool centre point control `G169` (off: `G168`), which would
/// transform kinpost's machine axis words a second time.
pub fn interpolation_mode(code: i64, radius: bool) -> Option<bool> {
    match code {
        121 | 1690 => Some(true),
        131 | 1680 => Some(false),
        // LinuxCNC's lathe diameter mode (G7; G8 radius).
        70 => Some(true),
        80 => Some(false),
        71 | 1070 => Some(radius),
        _ => None,
    }
}

/// Why pose mode may not start under a shift of the coordinates.
pub const SHIFT_AT_POSE_START: &str = "pose mode starts while a shift of the program's coordinates set earlier (G52 with an offset, G92) is on: the controller would move kinpost's machine axis words by it, which on a machine with rotaries is not the move of the tool tip it stands for; cancel it before TCP is switched on (G52 X0 Y0 Z0, G92.1), or give the poses in the workpiece frame (--work-offset)";

/// Why pose mode may not start under an [`interpolation_mode`].
pub const MODE_AT_POSE_START: &str = "pose mode starts while an interpolation mode set earlier in the program (Fanuc G12.1 polar coordinate interpolation, G7.1 or Haas G107 cylindrical interpolation, diameter programming: Sinumerik DIAMON, LinuxCNC G7; the controller's own tool centre point control: Okuma G169, Heidenhain ISO M128, Fagor #RTCP ON or #TLC ON) is on: the controller would read kinpost's machine axis words in it; switch it off before (G13.1, G7.1 C0, G107 C0, DIAMOF, G8, G168, M129, #RTCP OFF)";

/// `G` code ten times `code` as written: `12.1`, `154`.
fn g_name(code: i64) -> String {
    match code % 10 {
        0 => format!("{}", code / 10),
        d => format!("{}.{d}", code / 10),
    }
}

/// What a Sinumerik transformation keyword or call name does that kinpost
/// does not follow: `TRANSMIT`, `TRACYL`, `TRAANG`, `TRACON` (the axes'
/// words are then in another coordinate system); `None` for any other.
pub fn transformation(name: &str) -> Option<String> {
    let upper = name.to_ascii_uppercase();
    if ["DIAMON", "DIAM90"].contains(&upper.as_str()) {
        return Some(format!(
            "{upper} is Sinumerik diameter programming: the X words after it are diameters"
        ));
    }
    ["TRANSMIT", "TRACYL", "TRAANG", "TRACON"]
        .contains(&upper.as_str())
        .then(|| format!("{upper} is a Sinumerik transformation (face, cylinder surface or inclined axis): the axis words after it are in another coordinate system"))
}

/// Sinumerik keywords that call a subprogram.
pub const CALL_KEYWORDS: &[&str] = &["CALL", "PCALL", "MCALL", "EXTCALL"];

/// Whether the word `address``value` calls a subprogram or macro: Fanuc
/// `M98`, `M198`, `G65`, `G66`, `G66.1`, Haas `M97`.
pub fn call_word(address: &str, value: f64) -> bool {
    (address == "M" && [97.0, 98.0, 198.0].contains(&value))
        || (address == "G" && [65.0, 66.0, 66.1].iter().any(|g| (value - g).abs() < 1e-9))
}

/// Refuses `line` for the commands that follow a program's motion in
/// machine axes (`analyze`, `simulate`, `linkage`) when it holds what they
/// do not follow ([`in_line`]), naming file, line and column.
pub fn check_line(
    line: &crate::gcode::Line,
    file: &str,
    coded: Option<(usize, String)>,
) -> crate::error::Result<()> {
    match in_line(line, coded) {
        None => Ok(()),
        Some((i, what)) => Err(crate::error::Error::input_with(
            crate::error::Location::new(file, line.number, line.items[i].start + 1),
            message(&what, false),
            line.text_lossy(),
        )),
    }
}

/// What in `line` makes the commands that follow a program's motion
/// refuse it, with its item: `coded` (the modal state's
/// [`BlockMeaning::unfollowed`](super::BlockMeaning::unfollowed)), a
/// Sinumerik transformation written as a keyword or a call, or a
/// subprogram or macro call (`M98`, Haas `M97`, `G65`, `G66`, `CALL`,
/// `o100 call`), whose moves stand elsewhere (and a subprogram's moves
/// where it is defined). Heidenhain's `TOOL CALL` is a tool change.
pub fn in_line(
    line: &crate::gcode::Line,
    coded: Option<(usize, String)>,
) -> Option<(usize, String)> {
    use crate::gcode::ItemKind;
    let bytes = |it| String::from_utf8_lossy(line.item_bytes(it)).into_owned();
    coded.or_else(|| {
        line.items.iter().enumerate().find_map(|(i, it)| {
            let name = match &it.kind {
                ItemKind::Keyword(k) => k.clone(),
                ItemKind::Opaque => super::opaque::call_name(&bytes(it))?,
                _ => return None,
            };
            transformation(&name).map(|m| (i, m))
        })
    })
    .or_else(|| {
        line.items.iter().enumerate().find_map(|(i, it)| {
            let name = match &it.kind {
                ItemKind::Word(w) if call_word(&w.address, w.value) => {
                    bytes(it).trim().to_string()
                }
                ItemKind::Keyword(k)
                    if CALL_KEYWORDS.contains(&k.as_str())
                        && !String::from_utf8_lossy(&line.bytes[..it.start])
                            .trim_end()
                            .to_ascii_uppercase()
                            .ends_with("TOOL") =>
                {
                    k.clone()
                }
                ItemKind::Opaque => {
                    let name = super::opaque::call_name(&bytes(it))?;
                    let upper = name.to_ascii_uppercase();
                    // `O1200(NAME)`: a program number and its comment.
                    let program_number = upper.starts_with('O')
                        && upper.len() > 1
                        && upper[1..].bytes().all(|b| b.is_ascii_digit());
                    if program_number {
                        return None;
                    } else if name.ends_with(" call") {
                        name
                    } else if super::opaque::HARMLESS_CALLS.contains(&upper.as_str())
                        || ["TRAORI", "CYCLE800"].contains(&upper.as_str())
                        || transformation(&name).is_some()
                    {
                        return None;
                    } else {
                        format!("{name}(…)")
                    }
                }
                // Sinumerik `L100` on a block of its own (but its N): a
                // subprogram called by its number.
                ItemKind::Word(w)
                    if w.address == "L"
                        && line.words().all(|o| o.address == "L" || o.address == "N") =>
                {
                    bytes(it).trim().to_string()
                }
                _ => return None,
            };
            Some((
                i,
                format!("a subprogram or macro call ({name}): its moves stand elsewhere in the program or in another file (or, for a cycle, are the controller's own)"),
            ))
        })
    })
    .or_else(|| {
        line.items.iter().enumerate().find_map(|(i, it)| {
            let name = match &it.kind {
                ItemKind::Keyword(k) => k.to_ascii_uppercase(),
                ItemKind::Opaque => {
                    let text = bytes(it);
                    match super::opaque::o_word_statement(&text) {
                        Some(statement) => statement,
                        None => text
                            .trim_start()
                            .chars()
                            .take_while(char::is_ascii_alphabetic)
                            .collect::<String>()
                            .to_ascii_uppercase(),
                    }
                }
                _ => return None,
            };
            let o_word = name.starts_with(['o', 'O']) && name.contains(' ');
            (o_word || FLOW_KEYWORDS.contains(&name.as_str())).then(|| {
                (
                    i,
                    format!("flow control (`{name}`: a jump, a loop, a condition or a subprogram's definition), which kinpost does not evaluate: it follows the blocks once, top to bottom, so it cannot know which of them run, or how often"),
                )
            })
        })
    })
}

/// Keywords of flow control: Fanuc and Haas macro B (`GOTO`, `IF`,
/// `WHILE`), Sinumerik (`GOTOF`, `GOTOB`, `GOTOC`, `IF`/`ELSE`/`ENDIF`,
/// `WHILE`, `FOR`, `LOOP`, `REPEAT`, `REPEATB`, `UNTIL`, `CASE`, and their
/// ends).
const FLOW_KEYWORDS: &[&str] = &[
    "GOTO", "GOTOF", "GOTOB", "GOTOC", "IF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "FOR", "ENDFOR",
    "LOOP", "ENDLOOP", "REPEAT", "REPEATB", "UNTIL", "CASE",
];

/// The message of a block refused for `what` ([`g_code`],
/// [`transformation`]): in pose mode (`post`, `compensate`) or where a
/// program's motion in machine axes is followed.
pub fn message(what: &str, pose_mode: bool) -> String {
    if pose_mode {
        format!(
            "{what}; in pose mode it is not converted: give the moves it stands for as poses in the CAM system"
        )
    } else {
        format!(
            "{what}; this command follows the axis words as moves and would not follow it: give the moves it stands for in the CAM system, or run the program on the controller's own simulation"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_axes_are_told_from_pose_and_orientation_words() {
        for a in ["X1", "Z1", "C1", "A1", "U10", "AX4", "AX12"] {
            assert!(numbered_axis(a), "{a}");
        }
        for a in [
            "X", "A3", "B3", "C3", "A2", "C5", "AX", "AXA", "R1", "I1", "XH", "A",
        ] {
            assert!(!numbered_axis(a), "{a}");
        }
    }

    #[test]
    fn known_codes_pass_and_others_are_named() {
        assert_eq!(g_code(640), None);
        assert_eq!(g_code(170), None);
        assert!(
            g_code(121)
                .unwrap()
                .starts_with("G12.1 is polar coordinate interpolation")
        );
        assert!(
            g_code(54)
                .unwrap()
                .starts_with("G5.4 is a code kinpost does not know")
        );
        assert_eq!(g_code(53), None);
        assert!(g_code(383).unwrap().contains("probing"));
        assert!(
            transformation("tracyl")
                .unwrap()
                .starts_with("TRACYL is a Sinumerik transformation")
        );
        assert_eq!(transformation("TRAORI"), None);
    }
}
