//! The sixth hunt for real-world input (docs/robustness.md, "Sixth hunt"):
//! constructs of real programs and configurations that kinpost converted
//! or followed wrongly with exit 0. Each case failed before its fix.

use crate::fifth_hunt::{follow, post_converts, post_refuses};

/// A Sinumerik `CYCLE800(…)` swivels the work plane (and turns the
/// rotaries): the moves after it are in the swivelled frame. `analyze`,
/// `simulate` and `linkage` followed them as machine axes with exit 0
/// (the call was read as neither a frame nor a call); they now refuse the
/// first move under it, and `CYCLE800()` resets it.
#[test]
fn a_move_under_cycle800_is_refused_where_motion_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    let swivel = "CYCLE800(1,\"TABLE\",200000,57,0,0,0,0,30,0,0,0,0,-1,100,1)\n";
    follow(
        dir.path(),
        &format!("G0 X0 Y0 Z50\n{swivel}G1 X10 Y0 Z5 F1000\nM30\n"),
        Some("m.ngc:3:4: a move under the Sinumerik frame CYCLE800 (line 2)"),
    );
    follow(
        dir.path(),
        &format!("G0 X0 Y0 Z50\n{swivel}CYCLE800()\nG1 X10 Y0 Z5 F1000\nM30\n"),
        None,
    );
}

/// Fagor `#RTCP ON` (and `#TLC ON`) is the control's tool centre point
/// control, and `#CS`, `#ACS`, `#MCS`, `#FACE`, `#CYL` and `#TOOL AX`
/// change the coordinate system the axis words are read in. kinpost kept
/// these lines as opaque text: `linkage` inserted 138 points into two
/// RTCP moves and `analyze` measured 11 mm of nonlinear error on them, and
/// `post` converted a tool vector under `#RTCP ON` (the control would have
/// applied its RTCP to kinpost's machine axes a second time).
#[test]
fn fagor_rtcp_and_coordinate_systems_are_not_followed_or_converted_under() {
    let dir = tempfile::tempdir().unwrap();
    for (on, want) in [
        ("#RTCP ON", "m.ngc:2:1: tool centre point control"),
        ("#TLC ON [50]", "m.ngc:2:1: tool centre point control"),
        (
            "N10 #CS ON [1]",
            "m.ngc:3:4: a move under a Fagor coordinate system",
        ),
        (
            "#ACS NEW [1] [MODE 1, 0, 0, 0, 30, 0, 0]",
            "m.ngc:3:4: a move under a Fagor",
        ),
        ("#FACE [C, X, Y]", "m.ngc:3:4: a move under a Fagor"),
    ] {
        follow(
            dir.path(),
            &format!("G0 X0 Y0 Z50\n{on}\nG1 X10 Y0 Z5 A30 C45 F1000\nM30\n"),
            Some(want),
        );
    }
    // A coordinate system switched off again, or only defined: followed
    // (TCP switched on is refused where it stands, as G43.4 and M128 are).
    for ok in [
        "#CS ON [1]\n#CS OFF",
        "#CS DEF [1] [MODE 1, 0, 0, 0, 30, 0, 0]",
        "#KIN ID [2]",
    ] {
        follow(
            dir.path(),
            &format!("G0 X0 Y0 Z50\n{ok}\nG1 X10 Y0 Z5 A30 C45 F1000\nM30\n"),
            None,
        );
    }
    // `post`: pose mode does not start under them, and they are refused in it.
    let pose = "G1 X10 Y0 Z5 I0 J0 K1 F1000\n";
    post_refuses(
        dir.path(),
        "rtcp.nc",
        &format!("G0 X0 Y0 Z50\n#RTCP ON\n{pose}"),
        &[],
        "rtcp.nc:3:1: pose mode starts while an interpolation mode",
    );
    post_refuses(
        dir.path(),
        "cs.nc",
        &format!("G0 X0 Y0 Z50\n#CS NEW [1] [MODE 1, 0, 0, 0, 30, 0, 0]\n{pose}"),
        &[],
        "cs.nc:3:1: pose mode starts while a frame set earlier",
    );
    post_refuses(
        dir.path(),
        "in.nc",
        &format!("G43.4 H1\n{pose}#ACS ON\n{pose}"),
        &[],
        "in.nc:3:1: a Fagor instruction (`#ACS ON`) in pose mode",
    );
    let out = post_converts(
        dir.path(),
        "off.nc",
        &format!("#RTCP ON\nG1 X5 A10\n#RTCP OFF\n#CS ON [1]\n#CS OFF\n{pose}"),
        &[],
    );
    assert!(out.starts_with("#RTCP ON\nG1 X5 A10\n#RTCP OFF\n"), "{out}");
    assert!(out.contains("G1 X10.0000 Y0.0000 Z5.0000"), "{out}");
}

/// The axis words of a `post` output line, by address.
fn word(line: &str, address: char) -> f64 {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(address)?.parse().ok())
        .unwrap_or_else(|| panic!("no {address} in {line}"))
}

/// A `G91` pose after blocks kinpost passed through that moved the
/// machine: the controller adds the increments to where those blocks left
/// it. kinpost took them from the last pose it wrote, so a `G91 G1 Z5`
/// retract between TCP segments was counted twice (the tool 5 mm above the
/// programmed point; a plunge would have put it 5 mm into the part).
#[test]
fn an_incremental_pose_after_a_machine_move_starts_where_the_move_ended() {
    let dir = tempfile::tempdir().unwrap();
    let program = |vector: &str| {
        format!(
            "G21 G90\nG0 X0 Y0 Z50 B0 C0\nG43.4 H1\nG1 X10 Y5 Z5 {vector} F500\nG49\nG91 G1 Z5\nG43.4 H1\nG1 X2\nG90\nG49\nM30\n"
        )
    };
    // Vertical tool on xyzbc-trt (B0 C0: machine axes are the tip): the
    // tip goes from (10, 5, 10) to (12, 5, 10), +2 in X only.
    let out = post_converts(dir.path(), "v.nc", &program("I0 J0 K1"), &[]);
    let line = out.lines().nth(7).unwrap();
    assert_eq!(line, "G1 X2.0000 Y0.0000 Z0.0000 B0.0000 C0.0000", "{out}");
    // Tilted (B−30): the retract moves the tip along machine Z, and the
    // pose then goes +2 in workpiece X from where the retract left the tip.
    // The controller's position after the G91 pose (the first pose's words,
    // the retract, the increments) must put the tip there.
    let out = post_converts(dir.path(), "t.nc", &program("I0.5 J0 K0.8660254"), &[]);
    let (first, inc) = (out.lines().nth(3).unwrap(), out.lines().nth(7).unwrap());
    let m = kinpost::machine::Machine::embedded("xyzbc-trt").unwrap();
    let tip = |x: f64, y: f64, z: f64, b: f64, c: f64| {
        m.chain
            .pose(
                &m.to_internal(&[x, y, z, b, c]),
                &kinpost::machine::NoErrors,
            )
            .tip
    };
    let at = |l: &str, a: char| word(l, a);
    let retracted = tip(
        at(first, 'X'),
        at(first, 'Y'),
        at(first, 'Z') + 5.0,
        at(first, 'B'),
        at(first, 'C'),
    );
    let landed = tip(
        at(first, 'X') + at(inc, 'X'),
        at(first, 'Y') + at(inc, 'Y'),
        at(first, 'Z') + 5.0 + at(inc, 'Z'),
        at(first, 'B') + at(inc, 'B'),
        at(first, 'C') + at(inc, 'C'),
    );
    let want = retracted + nalgebra::Vector3::new(2.0, 0.0, 0.0);
    assert!(
        (landed - want).norm() < 2e-4,
        "{landed} against {want}: {out}"
    );
}

/// A `G91` pose after `G20`/`G21`: the controller keeps its position and
/// reads the increments in the new unit. kinpost subtracted the last
/// words written in inch from the new position in mm (`X34.4` for +10 mm
/// in X, 27.7 mm off).
#[test]
fn an_incremental_pose_after_a_unit_change_is_in_the_new_unit() {
    let dir = tempfile::tempdir().unwrap();
    let out = post_converts(
        dir.path(),
        "u.nc",
        "G20 G90\nG0 X0 Y0 Z2. B0 C0\nG43.4 H1\nG1 X1. Y0.5 Z0.2 I0 J0 K1 F20.\nG21\nG91 G1 X10.\nG90\nG49\nM30\n",
        &[],
    );
    let line = out.lines().nth(5).unwrap();
    assert_eq!(
        line, "G91 G1 X10.0000 Y0.0000 Z0.0000 B0.0000 C0.0000",
        "{out}"
    );
    let out = post_converts(
        dir.path(),
        "m.nc",
        "G21 G90\nG0 X0 Y0 Z50 B0 C0\nG43.4 H1\nG1 X25.4 Y12.7 Z5.08 I0 J0 K1 F500\nG20\nG91 G1 X1.\nG90\nG49\nM30\n",
        &[],
    );
    let line = out.lines().nth(5).unwrap();
    assert_eq!(
        line, "G91 G1 X1.00000 Y0.00000 Z0.00000 B0.0000 C0.0000",
        "{out}"
    );
}

/// A block that gives some components of the tool vector gives all of
/// it: the others are 0 (Fanuc G43.5: "when any of I, J, and K is omitted,
/// the omitted I, J, or K is assumed to be 0"; Sinumerik A3= B3= C3=
/// alike). kinpost kept the previous block's components: `K1.` after
/// `I0.003 … K0.9999955` came out tilted by 0.24°, and `J0.6 K0.8` after
/// `I0.6 …` was refused as a vector of length 1.166.
#[test]
fn a_tool_vector_given_in_part_has_its_other_components_zero() {
    let dir = tempfile::tempdir().unwrap();
    let start = "G43.4 H1\nG1 X10 Y5 Z5 I0.003 J0 K0.9999955 F500\n";
    let out = post_converts(
        dir.path(),
        "k.nc",
        &format!("{start}G1 X12 K1.\nG49\n"),
        &["--decimals", "6"],
    );
    // Vertical on xyzbc-trt: B0, and the tip where it was programmed.
    let line = out.lines().nth(2).unwrap();
    assert_eq!(word(line, 'B'), 0.0, "{out}");
    let out = post_converts(
        dir.path(),
        "c3.mpf",
        "TRAORI\nG1 X10 Y5 Z5 A3=0.003 B3=0 C3=0.9999955 F500\nG1 X12 C3=1\nTRAFOOF\n",
        &["--decimals", "6"],
    );
    assert_eq!(word(out.lines().nth(2).unwrap(), 'B'), 0.0, "{out}");
    // (0, 0.6, 0.8) is a unit vector, whatever the block before gave.
    let out = post_converts(
        dir.path(),
        "j.nc",
        "G43.4 H1\nG1 X10 Y5 Z5 I0.6 J0 K0.8 F500\nG1 X11 J0.6 K0.8\nG49\n",
        &[],
    );
    assert_eq!(out.lines().count(), 4, "{out}");
    // A block with no component keeps the vector.
    let out = post_converts(
        dir.path(),
        "keep.nc",
        "G43.4 H1\nG1 X10 Y5 Z5 I0.6 J0 K0.8 F500\nG1 X11\nG49\n",
        &["--decimals", "6"],
    );
    let (a, b) = (out.lines().nth(1).unwrap(), out.lines().nth(2).unwrap());
    assert_eq!(word(a, 'B'), word(b, 'B'), "{out}");
}
