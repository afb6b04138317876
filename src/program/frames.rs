//! Sinumerik frame instructions: statements that move, turn, scale or
//! mirror the coordinate system the axis words after them are read in.
//! The controller keeps them until they are deleted, so kinpost's machine
//! axis words would be moved by them too: pose mode may not start under
//! one and refuses one (`modal`), and the commands that follow a program's
//! motion in machine axes refuse a move under one (`source`).

/// Frame instructions with their own values (`TRANS X10`, `AROT Z30`,
/// `ROT RPL=45`), and the ones that turn the frame to the tool or the
/// workpiece (`TOFRAME`, `TOROT`, `PAROT` and their X/Y/Z forms).
pub const SETTING: [&str; 20] = [
    "TRANS", "ATRANS", "ROT", "AROT", "SCALE", "ASCALE", "MIRROR", "AMIRROR", "ROTS", "AROTS",
    "CROTS", "TOFRAME", "TOFRAMEX", "TOFRAMEY", "TOFRAMEZ", "TOROT", "TOROTX", "TOROTY", "TOROTZ",
    "PAROT",
];

/// The pseudo-keyword of an assignment to a Sinumerik frame variable
/// (`$P_PFRAME=CTRANS(X,10)`, `$P_BFRAME=…`): a frame set, as `TRANS`
/// ([`frame_variable`]).
pub const FRAME_VARIABLE: &str = "$P_…FRAME=";

/// The pseudo-keyword of an assignment of the null frame to a Sinumerik
/// frame variable (`$P_PFRAME=CTRANS()`): the frame deleted, as by
/// `TRANS` alone ([`frame_variable`]).
pub const NULL_FRAME_VARIABLE: &str = "$P_…FRAME=C…()";

/// Whether the unparsed text `text` assigns a Sinumerik frame variable
/// (`$P_PFRAME`, `$P_IFRAME`, `$P_BFRAME`, `$P_CHBFRAME[1]`, `$P_TOOLFRAME`,
/// … `=`): the active frame changes, as by `TRANS` or `ROT`. (The settable
/// frames' data, `$P_UIFR[1]=…`, change a work offset, as `G10 L2` does.)
pub fn frame_variable(text: &str) -> Option<&'static str> {
    let t = text.trim_start().to_ascii_uppercase();
    let rest = t.strip_prefix("$P_")?;
    let name_len = rest
        .bytes()
        .take_while(|b| b.is_ascii_alphanumeric() || *b == b'_')
        .count();
    let after = rest[name_len..].trim_start();
    // An index (`[1]`) may stand between the name and the `=`.
    let after = match after.strip_prefix('[') {
        Some(x) => x.split_once(']').map_or("", |(_, r)| r).trim_start(),
        None => after,
    };
    if !rest[..name_len].ends_with("FRAME") || !after.starts_with('=') || after.starts_with("==") {
        return None;
    }
    // `CTRANS()`, `CROT()`, `CSCALE()`, `CMIRROR()` without arguments: the
    // null frame.
    let value: String = after[1..].chars().filter(|c| !c.is_whitespace()).collect();
    let null = value.starts_with('C')
        && value.ends_with("()")
        && value[1..value.len() - 2]
            .bytes()
            .all(|b| b.is_ascii_alphabetic());
    Some(if null {
        NULL_FRAME_VARIABLE
    } else {
        FRAME_VARIABLE
    })
}

/// Why a frame in pose mode is refused.
pub const IN_POSE_MODE: &str = "a frame (G68, G68.2–G68.4, G51 scaling, G51.1 mirroring, G16 polar coordinates, Haas G254 dynamic work offset, Fanuc G54.2 rotary table dynamic fixture offset; Sinumerik TRANS, ATRANS, ROT, AROT, SCALE, MIRROR, TOFRAME, TOROT, PAROT, CYCLE800, G58/G59 with axis words, $P_PFRAME= and the other frame variables; Fagor #CS, #ACS, #MCS, #FACE, #CYL, #TOOL AX) in pose mode is not converted: the poses must be in the machine's workpiece frame; apply the frame in the CAM system";

/// Why pose mode may not start under a frame set earlier.
/// What a command that follows the machine's axes (`simulate`, `analyze
/// --nonlinear`, `linkage`) says of a move under `what`, a frame set at
/// line `at`.
pub fn move_under(what: &str, at: usize) -> String {
    format!(
        "a move under {what} (line {at}): the controller moves the axes otherwise than its words say, and this command follows the words as they stand; cancel the frame before the moves, or apply it in the CAM system"
    )
}

/// Where the G-code frame in force was set, after `line`: `since` while
/// one stays on (`frame_seen`), `line` where one starts, none once off.
pub fn frame_since(frame_seen: bool, since: Option<usize>, line: usize) -> Option<usize> {
    frame_seen.then(|| since.unwrap_or(line))
}

/// The G-code frames the modal state follows, as [`move_under`] names them.
pub const GCODE_FRAMES: &str =
    "a frame (G68 rotation, G51 scaling, G51.1 mirroring, G16 polar coordinates, G254, G54.2)";

pub const AT_POSE_START: &str = "pose mode starts while a frame set earlier in the program (G68…, G51, G51.1, G16, G254, G54.2 P1–P8, TRANS, ROT, AROT, SCALE, MIRROR, TOFRAME, TOROT, PAROT, CYCLE800, $P_PFRAME= and the other frame variables, Fagor #CS, #ACS, #MCS, #FACE, #CYL, #TOOL AX) is active: the controller would move kinpost's machine axis words by it; cancel the frame before, or apply it in the CAM system";

/// What a keyword of a block does to the programmable frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameChange {
    /// Sets (or adds to) a frame.
    Set,
    /// Deletes it: `TRANS`, `ROT`, `SCALE` or `MIRROR` without values
    /// (the whole programmable frame), `TRANS` or `ROT` whose values are
    /// all 0 and `SCALE` whose factors are all 1 (a programmable frame
    /// replaced by the identity: NX writes `TRANS X0 Y0 Z0` inside
    /// `TRAORI`), `TOROTOF`, `PAROTOF` (the rotation they set),
    /// `CYCLE800()` (the swivelled plane; a pseudo-keyword of the call,
    /// `opaque::known_call`).
    Delete,
    /// Leaves it as it is: `ATRANS` or `AROT` of all 0, `ASCALE` of all 1
    /// (the identity added to the frame in force). Its X Y Z are still
    /// values, not a move.
    Keep,
}

/// The values a block gives a frame instruction: the words `X`, `Y`, `Z`
/// (offsets, angles, factors) and `RPL` (a rotation in the plane).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameValues {
    /// At least one value is given.
    pub any: bool,
    /// Every value given is 0: a translation or rotation by nothing.
    pub all_zero: bool,
    /// Every value given is 1: a scaling by nothing.
    pub all_one: bool,
}

/// The [`FrameValues`] of a block's words, `(address, value)`.
pub fn values<'a>(words: impl Iterator<Item = (&'a str, f64)>) -> FrameValues {
    let mut v = FrameValues {
        any: false,
        all_zero: true,
        all_one: true,
    };
    for (_, value) in words.filter(|(a, _)| matches!(*a, "X" | "Y" | "Z" | "RPL")) {
        v.any = true;
        v.all_zero &= value == 0.0;
        v.all_one &= value == 1.0;
    }
    v
}

/// What `keyword` does to the frame, given the block's [`values`]. `None`
/// for a keyword that is no frame instruction. (`MIRROR X0` mirrors X:
/// its value says nothing, so a mirror with values always sets one.)
pub fn change(keyword: &str, values: FrameValues) -> Option<FrameChange> {
    let identity = values.any
        && match keyword {
            "TRANS" | "ROT" | "ATRANS" | "AROT" => values.all_zero,
            "SCALE" | "ASCALE" => values.all_one,
            _ => false,
        };
    match keyword {
        "TRANS" | "ROT" | "SCALE" | "MIRROR" if !values.any => Some(FrameChange::Delete),
        "TRANS" | "ROT" | "SCALE" if identity => Some(FrameChange::Delete),
        "ATRANS" | "AROT" | "ASCALE" if identity => Some(FrameChange::Keep),
        "TOROTOF" | "PAROTOF" | "CYCLE800()" | NULL_FRAME_VARIABLE => Some(FrameChange::Delete),
        "CYCLE800" | super::fagor::FRAME_ON | FRAME_VARIABLE => Some(FrameChange::Set),
        super::fagor::FRAME_OFF => Some(FrameChange::Delete),
        k if SETTING.contains(&k) => Some(FrameChange::Set),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rotation_in_the_plane_sets_a_frame() {
        let of = |words: &[(&'static str, f64)]| values(words.iter().copied());
        // `ROT RPL=90` has no X Y Z, but turns the plane by 90°.
        assert_eq!(change("ROT", of(&[("RPL", 90.0)])), Some(FrameChange::Set));
        assert_eq!(change("ROT", of(&[])), Some(FrameChange::Delete));
        assert_eq!(change("TRANS", of(&[("X", 10.0)])), Some(FrameChange::Set));
        assert_eq!(change("TOFRAME", of(&[])), Some(FrameChange::Set));
        assert_eq!(change("TOROTOF", of(&[])), Some(FrameChange::Delete));
        assert_eq!(change("TRAORI", of(&[])), None);
        assert_eq!(change(FRAME_VARIABLE, of(&[])), Some(FrameChange::Set));
    }

    #[test]
    fn frame_variables_are_told_from_other_assignments() {
        for t in [
            "$P_PFRAME=CTRANS(X,10)",
            " $p_pframe = crot(z,30)",
            "$P_CHBFRAME[1]=CTRANS(Z,5)",
            "$P_TOOLFRAME=CROT(Y,90)",
        ] {
            assert_eq!(frame_variable(t), Some(FRAME_VARIABLE), "{t}");
        }
        for t in ["$P_PFRAME=CTRANS()", "$P_BFRAME = CROT( )"] {
            assert_eq!(frame_variable(t), Some(NULL_FRAME_VARIABLE), "{t}");
        }
        for t in [
            "$P_UIFR[1]=CTRANS(X,10)",
            "R1=$P_PFRAME",
            "IF $P_PFRAME==CTRANS()",
            "$P_PFRAME==x",
            "$AA_IM[X]=1",
        ] {
            assert_eq!(frame_variable(t), None, "{t}");
        }
    }

    #[test]
    fn an_identity_frame_sets_none() {
        let of = |words: &[(&'static str, f64)]| values(words.iter().copied());
        let zero = of(&[("X", 0.0), ("Y", 0.0), ("Z", 0.0)]);
        let one = of(&[("X", 1.0), ("Y", 1.0), ("Z", 1.0)]);
        // NX inside TRAORI: the programmable frame replaced by nothing.
        assert_eq!(change("TRANS", zero), Some(FrameChange::Delete));
        assert_eq!(
            change("ROT", of(&[("RPL", 0.0)])),
            Some(FrameChange::Delete)
        );
        assert_eq!(change("SCALE", one), Some(FrameChange::Delete));
        assert_eq!(change("ATRANS", zero), Some(FrameChange::Keep));
        assert_eq!(change("AROT", zero), Some(FrameChange::Keep));
        assert_eq!(change("ASCALE", one), Some(FrameChange::Keep));
        // Not the identity: a factor of 0, a scaling of 0, a shift of 1,
        // one value off, a mirror (its value says nothing).
        assert_eq!(change("SCALE", zero), Some(FrameChange::Set));
        assert_eq!(change("TRANS", one), Some(FrameChange::Set));
        let mixed = of(&[("X", 0.0), ("Z", 1e-9)]);
        assert_eq!(change("TRANS", mixed), Some(FrameChange::Set));
        assert_eq!(change("ATRANS", mixed), Some(FrameChange::Set));
        assert_eq!(change("MIRROR", zero), Some(FrameChange::Set));
        assert_eq!(change("ROTS", zero), Some(FrameChange::Set));
    }
}
