//! `I J K` that are not a tool vector (`src/program/ijk.rs`), and text that
//! only looks like one. A straight move with `I J K` starts pose mode by
//! itself; on real programs the same letters are a thread's pitch (an NX
//! lathe post's `G32 Z3.46 K.05`), a cutter compensation's exit direction
//! (Fanuc `G40 G1 X Y I J`), a work offset's index (MillPlus `G54 I1`, an
//! NX post for a DMC 160U), a macro's arguments, and Fanuc's `G05 P10000`
//! and `G05.1 Q1` are modes, not spline moves. Before, a pitch of 1 mm or a
//! unit exit direction was converted into machine axis words, exit 0.

/// Runs `kinpost post` on xyzbc-trt: (exit code, stdout, stderr).
fn post(name: &str, bytes: &[u8]) -> (i32, Vec<u8>, String) {
    crate::util::post_file("xyzbc-trt", name, bytes)
}

/// `program` passes through byte for byte with exit 0.
fn passes(name: &str, program: &[u8]) {
    let (code, out, err) = post(name, program);
    assert_eq!(code, 0, "{name}: {err}");
    assert_eq!(
        String::from_utf8_lossy(&out),
        String::from_utf8_lossy(program),
        "{name}: {err}"
    );
}

#[test]
fn threads_and_tapping_are_not_poses() {
    // Fanuc lathe thread with a 1 mm lead; Sinumerik rigid tapping.
    passes(
        "g32.nc",
        b"O0001\nG21 G18 G99\nT0101\nG97 S800 M3\nG0 X20. Z5.\nG0 X9.2\nG32 Z-20. K1.\nG0 X12.\nZ5.\nM30\n",
    );
    passes(
        "g331.mpf",
        b"G90\nG0 X0 Y0 Z5\nG331 Z-20 K1\nG332 Z5 K1\nM30\n",
    );
    passes("g34.nc", b"G0 X9.2 Z5.\nG34 Z-20. K1. F0.1\nG0 X12.\nM30\n");
    // Under TCP a thread is refused like any non-straight motion.
    let (code, _, err) = post(
        "tcp.nc",
        b"G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG32 Z-20. K1.\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("tcp.nc:3:"), "{err}");
}

#[test]
fn words_of_other_codes_do_not_start_pose_mode() {
    // Fanuc: I J of G40 give the direction the tool leaves the contour.
    passes(
        "g40.nc",
        b"G17 G90 G21\nG0 X-20 Y0 Z5\nG1 Z-2 F200\nG41 G1 X0 Y0 D1\nG1 X50\nY50\nX0\nY0\nG40 G1 X-10 Y-10 I1 J0\nG0 Z50\nM30\n",
    );
    // MillPlus: G54 I1 selects a work offset (before: the tool vector
    // (1, 0, 0) of every later move, `G54 X145.0000 … B90.0000 C180.0000`).
    passes(
        "g54.nc",
        b"G17 G90\nG0 X0 Y0 Z100\nG54 I1\nG0 X10 Y20 Z50\nG1 Z-1 F100\nM30\n",
    );
    // A probing macro's arguments (before: refused as a call in pose mode).
    passes(
        "g65.nc",
        b"G17 G90 G21\nG0 X0 Y0 Z50\nG65 P9810 X10 Y20 Z30 I0 J0 K1\nG0 Z100\nM30\n",
    );
    // A pose program still starts where its first tool vector is.
    let (code, out, err) = post("pose.nc", b"G0 X10 Y0 Z50 I0 J0 K1\nM30\n");
    assert_eq!(code, 0, "{err}");
    assert!(String::from_utf8_lossy(&out).contains("B0.0000 C0.0000"));
}

#[test]
fn fanuc_contour_control_modes_are_not_splines() {
    // AI contour control and high-precision contour control around poses
    // that carry no G1 (before: refused as "a canned cycle, a thread or a
    // spline" at the first of them).
    for mode in ["G05.1 Q1 R5", "G05 P10000"] {
        let program = format!(
            "G90 G21\nG43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\n{mode}\nX12 Y0 Z5 I0 J0.1 K0.994987\nX14\nM30\n"
        );
        let (code, out, err) = post("aicc.nc", program.as_bytes());
        assert_eq!(code, 0, "{mode}: {err}");
        let out = String::from_utf8(out).unwrap();
        assert!(out.contains(&format!("{mode}\n")), "{out}");
        assert_eq!(out.matches(" C").count(), 3, "three poses converted: {out}");
    }
    // LinuxCNC's cubic spline, with its end point and control points, is
    // still a motion kinpost does not convert.
    let (code, _, err) = post(
        "g5.ngc",
        b"G43.4 H1\nG1 X10 Y0 Z5 I0 J0 K1 F500\nG5 X20 Y5 I1 J1 P2 Q-1\nM30\n",
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("g5.ngc:3:"), "{err}");
}

#[test]
fn letters_inside_a_name_are_not_a_tool_vector() {
    // The header of an NX information listing saved with the program.
    passes(
        "listing.nc",
        b"============\nInformation listing created by :  Suderman\nNode name                      :  cyi3w080\n============\nO0001\nG0 X1 Y2 Z3\nM30\n",
    );
    // A malformed pose line is still refused at its number.
    let (code, _, err) = post("bad.nc", b"G1X1.2.3Y0Z0I0J0K1\nM30\n");
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("bad.nc:1:3:"), "{err}");
}
