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
