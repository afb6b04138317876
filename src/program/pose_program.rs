//! Whether a program gives tool poses (APT CL, or G-code with tool
//! vectors or a TCP code) or positions of the machine's axes: what
//! `analyze`, `simulate` and `linkage` read it as.

use crate::gcode::ItemKind;

/// Whether the start of a program looks like a pose program (APT CL, or
/// G-code carrying tool vectors `I J K` / `A3= B3= C3=` or a TCP code) rather
/// than a program in machine axes.
pub fn looks_like_poses(head: &[u8]) -> bool {
    if crate::cl::looks_like_cl(head) {
        return true;
    }
    // I J K are a tool vector only on straight moves: on an arc (G2/G3,
    // modal) they are its centre, on threads, splines, G68.2, G87/G88,
    // Haas G12/G13 and Fanuc G22 and with G40–G42, G54–G59, G65 something
    // else again (`program::ijk`, `program::unfollowed`).
    let mut straight = true;
    for (n, raw) in head.split(|b| *b == b'\n').enumerate() {
        let line = crate::gcode::parse_line(raw, n + 1);
        let pairs: Vec<(&str, f64)> = line
            .words()
            .map(|w| (w.address.as_str(), w.value))
            .collect();
        let mut other_ijk = super::ijk::owner(pairs.iter().copied()).is_some();
        for w in line.words() {
            if w.address == "G" {
                let g = w.value;
                let c = (g * 10.0).round() as i64;
                if g == 0.0 || g == 1.0 {
                    straight = true;
                } else if g == 2.0 || g == 3.0 || is_canned_cycle(c) {
                    // A canned cycle's K is its repeat count (Fanuc), I J
                    // shifts (G76, G87): modal, as G2 is.
                    straight = false;
                } else if super::ijk::other_motion(c, pairs.iter().copied())
                    || [682, 870, 880, 120, 130, 220].contains(&c)
                {
                    other_ijk = true;
                }
            }
        }
        for w in line.words() {
            let vector = matches!(w.address.as_str(), "A3" | "B3" | "C3")
                || (matches!(w.address.as_str(), "I" | "J" | "K") && straight && !other_ijk);
            if vector {
                return true;
            }
            // Fanuc G43.4 / G43.5, Haas G234.
            if w.address == "G"
                && [43.4, 43.5, 234.0]
                    .iter()
                    .any(|c| (w.value - c).abs() < 1e-9)
            {
                return true;
            }
        }
        if line.keywords().any(|k| k == "TRAORI")
            || line.items.iter().any(|it| {
                it.kind == ItemKind::Opaque
                    && super::opaque::known_call(&String::from_utf8_lossy(line.item_bytes(it)))
                        .is_some_and(|c| c.starts_with("TRAORI"))
            })
        {
            return true;
        }
    }
    false
}

/// Whether the G code `c` (ten times its value) is a canned cycle: `G73`,
/// `G74`, `G76`, `G81`–`G89`.
pub fn is_canned_cycle(c: i64) -> bool {
    matches!(c, 730 | 740 | 760 | 810..=890)
}

#[cfg(test)]
mod tests {
    use super::looks_like_poses;

    #[test]
    fn arc_centres_are_not_tool_vectors() {
        // Found by tests/it/scenarios.rs: a machine-axis program with arcs was
        // taken for a pose program, and linkage then passed it through
        // without dividing a single five-axis block.
        assert!(!looks_like_poses(
            b"G0 X10 Y0\nG2 X0 Y10 I-10 J0 F500\nX-10 Y0 I0 J-10\nG1 X1 A5 B3\n"
        ));
        assert!(!looks_like_poses(
            b"G33.1 Z-10 K1.5\nG76 P2 Z-5 I-0.1 J0.1 K1\n"
        ));
        assert!(!looks_like_poses(b"G68.2 X0 Y0 Z0 I0 J45 K0\n"));
        // A straight move with a tool vector, also after an arc.
        assert!(looks_like_poses(
            b"G2 X0 Y10 I-10 J0\nG1 X1 Y2 Z3 I0 J0 K1\n"
        ));
        assert!(looks_like_poses(b"G1 X1 Y2 Z3 A3=0 B3=0 C3=1\n"));
        assert!(looks_like_poses(b"G43.4 H1\n"));
        assert!(looks_like_poses(b"G234 H1\n"));
    }
}
