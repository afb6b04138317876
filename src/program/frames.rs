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

/// Why a frame in pose mode is refused.
pub const IN_POSE_MODE: &str = "a frame (G68, G68.2–G68.4, G51 scaling, G51.1 mirroring, G16 polar coordinates, Haas G254 dynamic work offset, Fanuc G54.2 rotary table dynamic fixture offset; Sinumerik TRANS, ATRANS, ROT, AROT, SCALE, MIRROR, TOFRAME, TOROT, PAROT, CYCLE800; Fagor #CS, #ACS, #MCS, #FACE, #CYL, #TOOL AX) in pose mode is not converted: the poses must be in the machine's workpiece frame; apply the frame in the CAM system";

/// Why pose mode may not start under a frame set earlier.
pub const AT_POSE_START: &str = "pose mode starts while a frame set earlier in the program (G68…, G51, G51.1, G16, G254, G54.2 P1–P8, TRANS, ROT, AROT, SCALE, MIRROR, TOFRAME, TOROT, PAROT, CYCLE800, Fagor #CS, #ACS, #MCS, #FACE, #CYL, #TOOL AX) is active: the controller would move kinpost's machine axis words by it; cancel the frame before, or apply it in the CAM system";

/// What a keyword of a block does to the programmable frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameChange {
    /// Sets (or adds to) a frame.
    Set,
    /// Deletes it: `TRANS`, `ROT`, `SCALE` or `MIRROR` without values
    /// (the whole programmable frame), `TOROTOF`, `PAROTOF` (the rotation
    /// they set), `CYCLE800()` (the swivelled plane; a pseudo-keyword of
    /// the call, `opaque::known_call`).
    Delete,
}

/// Whether a block with words of `addresses` gives a frame instruction
/// values: `X`, `Y`, `Z` (offsets, angles, factors) or `RPL` (a rotation
/// in the plane).
pub fn has_values<'a>(mut addresses: impl Iterator<Item = &'a str>) -> bool {
    addresses.any(|a| matches!(a, "X" | "Y" | "Z" | "RPL"))
}

/// What `keyword` does to the frame; `values`: [`has_values`] of the
/// block. `None` for a keyword that is no
/// frame instruction.
pub fn change(keyword: &str, values: bool) -> Option<FrameChange> {
    match keyword {
        "TRANS" | "ROT" | "SCALE" | "MIRROR" if !values => Some(FrameChange::Delete),
        "TOROTOF" | "PAROTOF" | "CYCLE800()" => Some(FrameChange::Delete),
        "CYCLE800" | super::fagor::FRAME_ON => Some(FrameChange::Set),
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
        // `ROT RPL=90` has no X Y Z, but turns the plane by 90°.
        assert_eq!(change("ROT", true), Some(FrameChange::Set));
        assert_eq!(change("ROT", false), Some(FrameChange::Delete));
        assert_eq!(change("TRANS", true), Some(FrameChange::Set));
        assert_eq!(change("TOFRAME", false), Some(FrameChange::Set));
        assert_eq!(change("TOROTOF", false), Some(FrameChange::Delete));
        assert_eq!(change("TRAORI", false), None);
    }
}
