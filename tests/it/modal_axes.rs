//! `--modal-axes` (and `linkage`, which writes modal axis words) after
//! lines kinpost passes through, found by metamorphic tests in session 18:
//! an axis word equal to the last one kinpost wrote was left out although
//! the machine had moved since (`G28`, a move in machine axes, a tool
//! change, a skipped block-delete block), so the next block ran from the
//! wrong place: `G28` then `G1 X50` alone plunged at the reference point.
//! And a modulo axis just below 360° was written `C360.0000`.

use crate::util::run_on as run;

#[test]
fn every_axis_is_written_after_a_line_that_may_have_moved_the_machine() {
    let pose = "G21 G90 G94\nG43.4 H1\nG1 X10 Y20 Z25 I0 J0 K1 F300\n";
    for (between, want) in [
        ("G28\n", "G28\nG1 X50.0000 Y20.0000 Z25.0000\n"),
        ("T2 M6\n", "T2 M6\nG1 X50.0000 Y20.0000 Z25.0000\n"),
        ("/G1 Z5\n", "/G1 Z5.0000\nG1 X50.0000 Y20.0000 Z25.0000\n"),
    ] {
        let text = format!("{pose}{between}G1 X50 Y20 Z25\nG1 Z-2\nG49\nM30\n");
        let (code, out, err) = run(&["post", "-m", "xyz-3axis", "--modal-axes"], "p.ngc", &text);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains(want), "{between}: {out}");
        // The block after is modal again.
        assert!(out.contains("\nG1 Z-2.0000\n"), "{between}: {out}");
        // linkage writes modal axis words the same way (after G28 or a tool
        // change it refuses the block, whose start is not known; after
        // `G28` alone, which sends every axis home, the rotaries too, so
        // the block's orientation is not known either: session 39).
        let (code, out, err) = run(&["linkage", "-m", "xyzac-trt"], "p.ngc", &text);
        if between == "G28\n" {
            assert_eq!(code, 1, "{out}");
            assert!(
                err.contains("p.ngc:5:4: the tool orientation is not known here: line 4"),
                "{err}"
            );
            continue;
        }
        if between == "T2 M6\n" {
            assert_eq!(code, 1, "{out}");
            assert!(
                err.contains("p.ngc:5:1: where this G1 block starts is not known"),
                "{err}"
            );
            continue;
        }
        assert_eq!(code, 0, "{err}");
        assert!(
            out.contains("G1 X50.0000 Y20.0000 Z25.0000 A0.000000 C0.000000\n"),
            "{between}: {out}"
        );
    }
    // A comment passes without it.
    let text = format!("{pose}(note)\nG1 X50 Y20 Z25\nG49\nM30\n");
    let (_, out, _) = run(&["post", "-m", "xyz-3axis", "--modal-axes"], "p.ngc", &text);
    assert!(out.contains("(note)\nG1 X50.0000\n"), "{out}");
    // APT CL: a tool change between two GOTOs.
    let cl = "UNITS/MM\nFEDRAT/300\nGOTO/10,20,25\nLOAD/TOOL,2\nGOTO/50,20,25\nFINI\n";
    let (code, out, err) = run(&["post", "-m", "xyz-3axis", "--modal-axes"], "t.apt", cl);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("G43 H2\nX50.0000 Y20.0000 Z25.0000\n"),
        "{out}"
    );
}

#[test]
fn a_modulo_axis_just_below_a_full_turn_is_written_zero() {
    // C about 1e-7° short of a full turn on xyzbc-trt (C modulo, 4 decimals).
    let text = "G21 G90 G94\nG43.4 H1\nG1 X-14 Y-30 Z18 I-0.104528463 J-0.00000001 K0.994521895 F500\nG49\nM30\n";
    let (code, out, err) = run(&["post", "-m", "xyzbc-trt"], "m.ngc", text);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains(" C0.0000"), "{out}");
    assert!(!out.contains("C360"), "{out}");
}
