//! Fagor high-level instructions that change what the axis words after
//! them mean: `#RTCP ON` and `#TLC ON` (the control's tool centre point
//! control: the X Y Z after them are tool-tip positions), and the
//! coordinate systems and transformations `#CS`, `#ACS` (inclined planes),
//! `#MCS` (machine coordinates), `#FACE`, `#CYL` (face and cylinder
//! transformations) and `#TOOL AX` (the tool axis moved to another axis).
//!
//! kinpost does not convert Fagor programs. The G-code parser keeps these
//! lines as opaque text, which passes through unchanged; read as the
//! pseudo-keywords below they keep pose mode from starting under them
//! (`modal`), are refused in it, and make the commands that follow a
//! program in machine axes refuse the moves after them (`source`).

/// Pseudo-keyword: the control's tool centre point control on
/// (`#RTCP ON`, `#TLC ON`).
pub const TCP_ON: &str = "#RTCP ON";
/// Pseudo-keyword: `#RTCP OFF`, `#TLC OFF`.
pub const TCP_OFF: &str = "#RTCP OFF";
/// Pseudo-keyword: a coordinate system or transformation set (`#CS ON`,
/// `#CS NEW`, `#ACS ON`, `#MCS ON`, `#FACE [...]`, `#CYL [...]`,
/// `#TOOL AX [...]`).
pub const FRAME_ON: &str = "#CS ON";
/// Pseudo-keyword: one switched off (`#CS OFF`, `#ACS OFF`, `#FACE OFF`,
/// ...).
pub const FRAME_OFF: &str = "#CS OFF";

/// The pseudo-keyword of the Fagor instruction that `text` (a line's opaque
/// text) starts with, or `None` for any other text (a LinuxCNC or Fanuc
/// parameter `#1=…`, `#<name>=…` starts with a digit or `<`).
pub fn instruction(text: &str) -> Option<&'static str> {
    let rest = text.trim_start().strip_prefix('#')?;
    let name_len = rest.bytes().take_while(u8::is_ascii_alphabetic).count();
    let name = rest[..name_len].to_ascii_uppercase();
    let arg = rest[name_len..].trim_start();
    let arg_len = arg.bytes().take_while(u8::is_ascii_alphabetic).count();
    let arg = arg[..arg_len].to_ascii_uppercase();
    let off = arg == "OFF";
    match name.as_str() {
        "RTCP" | "TLC" => Some(if off { TCP_OFF } else { TCP_ON }),
        // `#CS DEF` only stores a coordinate system.
        "CS" | "ACS" if arg == "DEF" => None,
        "CS" | "ACS" | "MCS" | "FACE" | "CYL" => Some(if off { FRAME_OFF } else { FRAME_ON }),
        "TOOL" if arg == "AX" => Some(FRAME_ON),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instructions_and_parameters() {
        assert_eq!(instruction("#RTCP ON"), Some(TCP_ON));
        assert_eq!(instruction("  #rtcp off ; end"), Some(TCP_OFF));
        assert_eq!(instruction("#TLC ON [50]"), Some(TCP_ON));
        assert_eq!(
            instruction("#CS NEW [1] [MODE 1, 0, 0, 0, 30, 0, 0]"),
            Some(FRAME_ON)
        );
        assert_eq!(instruction("#CS DEF [1] [MODE 1, 0, 0, 0, 30, 0, 0]"), None);
        assert_eq!(instruction("#ACS OFF"), Some(FRAME_OFF));
        assert_eq!(instruction("#FACE [C, X, Y]"), Some(FRAME_ON));
        assert_eq!(instruction("#TOOL AX [X+]"), Some(FRAME_ON));
        assert_eq!(instruction("#KIN ID [2]"), None);
        assert_eq!(instruction("#1 = 5"), None);
        assert_eq!(instruction("#<depth> = 5"), None);
        assert_eq!(instruction("TRAORI"), None);
    }
}
