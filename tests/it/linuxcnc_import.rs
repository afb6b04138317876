//! `kinpost machine --from-linuxcnc`: the machine file made from a LinuxCNC
//! configuration reproduces LinuxCNC's own forward kinematics.
//!
//! The reference below restates the forward kinematics of LinuxCNC's
//! `trtfuncs.c` (xyzac-trt-kins, xyzbc-trt-kins) and `5axiskins.c` as
//! formulas, written independently of kinpost's chain. LinuxCNC's pose is
//! the programmed point with the tool length offset added along Z (its
//! `tool-offset` pin is added to `z-offset`; 5axiskins' `pivot-length` is
//! the mechanical pivot plus the tool length), so kinpost's tool tip plus
//! (0, 0, T) must equal it.

use kinpost::machine::linuxcnc::machine_from_linuxcnc;
use kinpost::machine::{Machine, NoErrors};
use std::path::{Path, PathBuf};

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/linuxcnc");

/// The geometry of one test configuration.
#[derive(Clone, Copy)]
struct Geometry {
    /// x/y/z-rot-point.
    r: [f64; 3],
    /// x/y/z-offset (the one of the other family is unused).
    d: [f64; 3],
    /// Tool length.
    t: f64,
    /// +1 with conventional-directions 1, −1 otherwise.
    con: f64,
    /// 5axiskins: the mechanical pivot length.
    pivot: f64,
}

/// xyzac-trt-kins forward kinematics (joints x, y, z mm; a, c deg).
fn lcnc_xyzac(g: &Geometry, [x, y, z, a, c]: [f64; 5]) -> [f64; 3] {
    let (sa, ca) = a.to_radians().sin_cos();
    let (sc, cc) = c.to_radians().sin_cos();
    let k = g.con;
    let dy = g.d[1];
    let dz = g.d[2] + g.t;
    let ex = x - g.r[0];
    let ey = y - dy - g.r[1];
    let ez = z - dz - g.r[2];
    [
        cc * ex - k * sc * ca * ey + sc * sa * ez - k * sc * dy + g.r[0],
        k * sc * ex + cc * ca * ey - k * cc * sa * ez + cc * dy + g.r[1],
        k * sa * ey + ca * ez + dz + g.r[2],
    ]
}

/// xyzbc-trt-kins forward kinematics (joints x, y, z mm; b, c deg).
fn lcnc_xyzbc(g: &Geometry, [x, y, z, b, c]: [f64; 5]) -> [f64; 3] {
    let (sb, cb) = b.to_radians().sin_cos();
    let (sc, cc) = c.to_radians().sin_cos();
    let k = g.con;
    let dx = g.d[0];
    let dz = g.d[2] + g.t;
    let ex = x - dx - g.r[0];
    let ey = y - g.r[1];
    let ez = z - dz - g.r[2];
    [
        cc * cb * ex - k * sc * ey + k * cc * sb * ez + cc * dx + g.r[0],
        k * sc * cb * ex + cc * ey + sc * sb * ez + k * sc * dx + g.r[1],
        -k * sb * ex + cb * ez + dz + g.r[2],
    ]
}

/// xyzab_tdr_kins forward kinematics with TCP (switchkins type 1; joints
/// x, y, z mm; a, b deg), as the module's documentation gives it; its
/// `x-offset` does not appear.
fn lcnc_xyzab_tdr(g: &Geometry, [x, y, z, a, b]: [f64; 5]) -> [f64; 3] {
    let (sa, ca) = a.to_radians().sin_cos();
    let (sb, cb) = b.to_radians().sin_cos();
    let dz = g.d[2];
    let px = x - g.r[0];
    let py = y - g.r[1];
    let pz = z - g.r[2] - g.t;
    [
        cb * px + sb * pz + g.r[0],
        sa * sb * px + ca * py - cb * sa * pz + sa * dz + g.r[1],
        -ca * sb * px + sa * py + ca * cb * pz - ca * dz + g.r[2] + dz + g.t,
    ]
}

/// 5axiskins forward kinematics (joints x, y, z mm; b, c deg; W = 0): the
/// pivot point sits `p` above the spindle end and the tool hangs from it
/// at polar angle 180° − b and azimuth c.
fn lcnc_5axis(g: &Geometry, [x, y, z, b, c]: [f64; 5]) -> [f64; 3] {
    let p = g.pivot + g.t;
    let polar = (180.0 - b).to_radians();
    let azimuth = c.to_radians();
    [
        x + p * polar.sin() * azimuth.cos(),
        y + p * polar.sin() * azimuth.sin(),
        z + p + p * polar.cos(),
    ]
}

/// Copies the fixture configuration `ini` (and its HAL files) into `dir`,
/// with conventional-directions set to `con` (0 or 1).
fn config(dir: &Path, ini: &str, con: u8) -> PathBuf {
    for entry in std::fs::read_dir(FIXTURES).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let text = text.replace(
            "conventional-directions 0",
            &format!("conventional-directions {con}"),
        );
        std::fs::write(dir.join(path.file_name().unwrap()), text).unwrap();
    }
    dir.join(ini)
}

/// A deterministic stream of numbers in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

fn check(ini: &str, g: Geometry, fk: fn(&Geometry, [f64; 5]) -> [f64; 3], tool: Option<f64>) {
    let dir = tempfile::tempdir().unwrap();
    let con = if g.con > 0.0 { 1 } else { 0 };
    let path = config(dir.path(), ini, con);
    let file = machine_from_linuxcnc(&path, tool).unwrap_or_else(|e| panic!("{e}"));
    let text = serde_json::to_string_pretty(&file).unwrap();
    let m =
        Machine::from_json_str(&text, "generated.json").unwrap_or_else(|e| panic!("{e}\n{text}"));
    let names: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
    let mut rng = Lcg(0x5eed + con as u64);
    let mut worst = 0.0f64;
    for _ in 0..2000 {
        let j = [
            300.0 * rng.next(),
            300.0 * rng.next(),
            300.0 * rng.next(),
            180.0 * rng.next(),
            720.0 * rng.next(),
        ];
        // Output order is X Y Z (A|B) C, the joint order of the reference.
        assert_eq!(names[..3], ["X", "Y", "Z"]);
        let q = m.to_internal(&j);
        let tip = m.chain.pose(&q, &NoErrors).tip;
        let want = fk(&g, j);
        let d = ((tip.x - want[0]).powi(2)
            + (tip.y - want[1]).powi(2)
            + (tip.z + g.t - want[2]).powi(2))
        .sqrt();
        worst = worst.max(d);
    }
    eprintln!("{ini} conventional-directions {con}: worst difference {worst:e} mm");
    assert!(worst <= 5e-13, "{ini} con {con}: {worst:e} mm");
}

#[test]
fn xyzac_trt_matches_linuxcnc() {
    for con in [-1.0, 1.0] {
        let g = Geometry {
            r: [12.5, -7.75, -3.25],
            d: [0.0, 20.5, 10.125],
            t: 42.5,
            con,
            pivot: 0.0,
        };
        check("xyzac-trt.ini", g, lcnc_xyzac, None);
        check(
            "xyzac-trt.ini",
            Geometry { t: 3.5, ..g },
            lcnc_xyzac,
            Some(3.5),
        );
    }
}

#[test]
fn xyzbc_trt_matches_linuxcnc() {
    for con in [-1.0, 1.0] {
        let g = Geometry {
            r: [-4.5, 3.0, 8.25],
            d: [5.5, 0.0, 41.75],
            t: 60.0,
            con,
            pivot: 0.0,
        };
        check("xyzbc-trt.ini", g, lcnc_xyzbc, None);
    }
}

/// LinuxCNC's own sim configuration of this module sets its offsets with
/// `sets` on signals netted to the pins; the fixture does the same.
#[test]
fn xyzab_tdr_matches_linuxcnc() {
    let g = Geometry {
        r: [15.5, -6.25, 30.0],
        d: [-20.0, 0.0, -10.25],
        t: 48.5,
        con: 1.0,
        pivot: 0.0,
    };
    check("xyzab-tdr.ini", g, lcnc_xyzab_tdr, None);
    check(
        "xyzab-tdr.ini",
        Geometry { t: 3.5, ..g },
        lcnc_xyzab_tdr,
        Some(3.5),
    );
    // x-offset moves no pose; z-offset does.
    let tip_at = |ini_edit: &dyn Fn(&str) -> String| {
        let dir = tempfile::tempdir().unwrap();
        let path = config(dir.path(), "xyzab-tdr.ini", 1);
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, ini_edit(&text)).unwrap();
        let v = machine_from_linuxcnc(&path, None).unwrap();
        let m = Machine::from_json_str(&v.to_string(), "g.json").unwrap();
        m.chain
            .pose(&m.to_internal(&[10.0, 20.0, 30.0, 25.0, -40.0]), &NoErrors)
            .tip
    };
    let base = tip_at(&|t| t.to_string());
    let dx = tip_at(&|t| t.replace("sets :x-offset -20", "sets :x-offset 75"));
    let dz = tip_at(&|t| t.replace("sets :z-offset -10.25", "sets :z-offset 5"));
    assert!((base - dx).norm() < 1e-12, "{base} {dx}");
    assert!((base - dz).norm() > 1.0, "{base} {dz}");
}

#[test]
fn fiveaxiskins_matches_linuxcnc() {
    // 5axiskins has no conventional-directions pin; both fixture variants
    // give the same machine.
    for con in [-1.0, 1.0] {
        for t in [0.0, 37.25] {
            let g = Geometry {
                r: [0.0; 3],
                d: [0.0; 3],
                t,
                con,
                pivot: 180.5,
            };
            check("5axis.ini", g, lcnc_5axis, Some(t));
        }
    }
}

#[test]
fn limits_modes_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let m = |ini: &str| {
        let v = machine_from_linuxcnc(&config(dir.path(), ini, 0), None).unwrap();
        Machine::from_json_str(&v.to_string(), "g.json").unwrap()
    };
    let ac = m("xyzac-trt.ini");
    assert_eq!(ac.name, "test-xyzac-trt");
    let a = ac.axis("A").unwrap();
    assert_eq!((a.min, a.max), (Some(-30.0), Some(110.0)));
    assert_eq!(
        ac.axis("C").unwrap().rotary,
        kinpost::machine::RotaryMode::Continuous
    );
    assert_eq!(ac.axis("Z").unwrap().min, Some(-250.0));
    // `WRAPPED_ROTARY = no` (LinuxCNC's booleans in any spelling): not
    // wrapped, and without limits continuous.
    let bc = m("xyzbc-trt.ini");
    assert_eq!(
        bc.axis("C").unwrap().rotary,
        kinpost::machine::RotaryMode::Continuous
    );
    // A wrapped rotary turns the way its word's sign says (LinuxCNC's
    // `unwrap_rotary`): A350 after A10 is +340°, where kinpost's modulo axis
    // takes the short way (−20°). It was written `modulo` once (the table
    // turned the long way), then refused; now it is kinpost's `wrapped`
    // mode, whose words carry the turn's sign (`wrapped_rotary.rs`), in
    // each spelling LinuxCNC reads as true, also with a comment after it
    // as real configurations write (`WRAPPED_ROTARY = 1 ; indexing`,
    // which LinuxCNC's `sscanf` reads as 1; before, "not a boolean"). A
    // value that is no boolean is refused.
    let path = config(dir.path(), "xyzbc-trt.ini", 0);
    let text = std::fs::read_to_string(&path).unwrap();
    let with = |value: &str| {
        std::fs::write(
            &path,
            text.replace("WRAPPED_ROTARY = no", &format!("WRAPPED_ROTARY = {value}"))
                .replace("MAX_LIMIT = 110", "MAX_LIMIT = 110      ; soft limit, deg")
                .replace("LINEAR_UNITS = mm", "LINEAR_UNITS = mm # metric"),
        )
        .unwrap();
        machine_from_linuxcnc(&path, None)
    };
    for value in [
        "1",
        "Yes",
        "ON",
        "1       ; for indexing only",
        "true # wraps",
    ] {
        let v = with(value).unwrap_or_else(|e| panic!("{value}: {e}"));
        let m = Machine::from_json_str(&v.to_string(), "g.json").unwrap();
        assert_eq!(
            m.axis("C").unwrap().rotary,
            kinpost::machine::RotaryMode::Wrapped,
            "{value}"
        );
        let b = m.axis("B").unwrap();
        assert_eq!((b.min, b.max), (Some(-35.0), Some(110.0)), "{value}");
    }
    let e = with("maybe").unwrap_err().to_string();
    assert!(
        e.contains("xyzbc-trt.ini:20:18: WRAPPED_ROTARY `maybe` is not a boolean"),
        "{e}"
    );
    // Text after a number that is not a comment is still refused.
    std::fs::write(&path, text.replace("MAX_LIMIT = 110", "MAX_LIMIT = 110deg")).unwrap();
    let e = machine_from_linuxcnc(&path, None).unwrap_err().to_string();
    assert!(e.contains("MAX_LIMIT `110deg` is not a number"), "{e}");
    // maxkins is refused with the reason, at the KINEMATICS value.
    let e = machine_from_linuxcnc(&config(dir.path(), "maxkins.ini", 0), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("maxkins.ini:3:14: maxkins cannot be converted"),
        "{e}"
    );
    // An unknown module, a bad setp value and a missing HAL file.
    std::fs::write(
        dir.path().join("u.ini"),
        "[KINS]\nKINEMATICS = genhexkins\n",
    )
    .unwrap();
    let e = machine_from_linuxcnc(&dir.path().join("u.ini"), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("u.ini:2:14: kinematics `genhexkins` is not supported"),
        "{e}"
    );
    std::fs::write(
        dir.path().join("b.hal"),
        "setp 5axiskins.pivot-length abc\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("b.ini"),
        "[KINS]\nKINEMATICS = 5axiskins\n[HAL]\nHALFILE = b.hal\n",
    )
    .unwrap();
    let e = machine_from_linuxcnc(&dir.path().join("b.ini"), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.hal:1:29: `abc` for 5axiskins.pivot-length is not a number"),
        "{e}"
    );
    std::fs::write(
        dir.path().join("c.ini"),
        "[KINS]\nKINEMATICS = 5axiskins\n[HAL]\nHALFILE = nothere.hal\n",
    )
    .unwrap();
    // A HALFILE name not beside the INI is one LinuxCNC finds in its HAL
    // library (`core_sim.hal`): skipped and named, as `LIB:` files are.
    let v = machine_from_linuxcnc(&dir.path().join("c.ini"), None).unwrap();
    assert!(
        v["description"]
            .as_str()
            .unwrap()
            .contains("HAL files not read (library or Tcl files): nothere.hal."),
        "{}",
        v["description"]
    );
    // A path with a directory is the configuration's own: it must be there.
    std::fs::write(
        dir.path().join("c.ini"),
        "[KINS]\nKINEMATICS = 5axiskins\n[HAL]\nHALFILE = sub/nothere.hal\n",
    )
    .unwrap();
    let e = machine_from_linuxcnc(&dir.path().join("c.ini"), None).unwrap_err();
    assert!(matches!(e, kinpost::Error::Io { .. }), "{e}");
    // An INI saved with a byte-order mark reads the same.
    std::fs::write(
        dir.path().join("bom.ini"),
        "\u{feff}[KINS]\nKINEMATICS = 5axiskins\n[HAL]\nHALFILE = 5axis.hal\n",
    )
    .unwrap();
    let v = machine_from_linuxcnc(&dir.path().join("bom.ini"), None).unwrap();
    assert_eq!(v["chain"][3]["translate"][2], 180.5);
}

#[test]
fn the_command_writes_a_machine_file() {
    let dir = tempfile::tempdir().unwrap();
    let ini = config(dir.path(), "xyzbc-trt.ini", 1);
    let out_path = dir.path().join("m.json");
    let out = std::process::Command::new(crate::util::BIN)
        .args(["machine", "--from-linuxcnc"])
        .arg(&ini)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stdout.is_empty());
    let m = Machine::load(&out_path).unwrap();
    assert_eq!(m.name, "test-xyzbc-trt");
    assert_eq!(
        m.chain.joints()[0].axis.z,
        1.0,
        "conventional-directions 1: C about +Z"
    );
}

/// A configuration in inch: the HAL lengths and the linear limits are
/// converted to mm, so that the machine with its joints in mm puts the tip
/// where LinuxCNC's forward kinematics in inch put it, times 25.4.
#[test]
fn an_inch_configuration_is_converted_to_mm() {
    let dir = tempfile::tempdir().unwrap();
    let path = config(dir.path(), "xyzac-trt.ini", 1);
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        text.replace("LINEAR_UNITS = mm", "LINEAR_UNITS = inch"),
    )
    .unwrap();
    let file = machine_from_linuxcnc(&path, None).unwrap_or_else(|e| panic!("{e}"));
    let m = Machine::from_json_str(&file.to_string(), "inch.json").unwrap();
    // The fixture's values, now read as inch.
    let g = Geometry {
        r: [12.5, -7.75, -3.25],
        d: [0.0, 20.5, 10.125],
        t: 42.5,
        con: 1.0,
        pivot: 0.0,
    };
    let mut rng = Lcg(0x1ac4);
    let mut worst = 0.0f64;
    for _ in 0..500 {
        let j_inch = [
            10.0 * rng.next(),
            10.0 * rng.next(),
            10.0 * rng.next(),
            180.0 * rng.next(),
            720.0 * rng.next(),
        ];
        let j_mm = [
            j_inch[0] * 25.4,
            j_inch[1] * 25.4,
            j_inch[2] * 25.4,
            j_inch[3],
            j_inch[4],
        ];
        let tip = m.chain.pose(&m.to_internal(&j_mm), &NoErrors).tip;
        let want = lcnc_xyzac(&g, j_inch);
        let d = ((tip.x - 25.4 * want[0]).powi(2)
            + (tip.y - 25.4 * want[1]).powi(2)
            + (tip.z + 25.4 * g.t - 25.4 * want[2]).powi(2))
        .sqrt();
        worst = worst.max(d);
    }
    assert!(worst <= 1e-11, "{worst:e} mm");
    assert_eq!(file["tool_length"], 42.5 * 25.4);
    let z = m.axis("Z").unwrap();
    assert_eq!((z.min, z.max), (Some(-250.0 * 25.4), Some(150.0 * 25.4)));
    assert!(
        file["description"]
            .as_str()
            .unwrap()
            .contains("in inch, converted to mm"),
        "{}",
        file["description"]
    );
}

/// trivkins, three axes in inch: the identity chain, limits in mm to the
/// digit (3 inch is 76.2 mm, not 76.19999999999999), no HAL file read.
#[test]
fn trivkins_three_axes_in_inch() {
    let dir = tempfile::tempdir().unwrap();
    let path = config(dir.path(), "trivkins-xyz-inch.ini", 0);
    let file = machine_from_linuxcnc(&path, None).unwrap_or_else(|e| panic!("{e}"));
    let m = Machine::from_json_str(&file.to_string(), "xyz.json").unwrap();
    assert_eq!(m.name, "test-trivkins-inch");
    let limits = |n: &str| {
        let a = m.axis(n).unwrap();
        (a.min.unwrap(), a.max.unwrap())
    };
    assert_eq!(limits("X"), (-76.2, 254.0));
    assert_eq!(limits("Y"), (-0.0254, 313.580018));
    assert_eq!(limits("Z"), (-203.2, 3.048));
    assert_eq!(file["output_order"], serde_json::json!(["X", "Y", "Z"]));
    let mut rng = Lcg(0x3a);
    for _ in 0..200 {
        let j = [300.0 * rng.next(), 300.0 * rng.next(), 300.0 * rng.next()];
        let p = m.chain.pose(&m.to_internal(&j), &NoErrors);
        assert_eq!([p.tip.x, p.tip.y, p.tip.z], j);
        assert_eq!([p.axis.x, p.axis.y, p.axis.z], [0.0, 0.0, 1.0]);
    }
}

/// trivkins with a fourth axis: a rotary table A about X through the
/// workpiece origin, a positive A turning the part by +A about +X. The
/// reference turns the tool's machine position back into the part:
/// `p_part = Rx(−A) · (X, Y, Z − T)`, the tool axis `Rx(−A) · (0, 0, 1)`.
#[test]
fn trivkins_fourth_axis_is_a_rotary_table() {
    let dir = tempfile::tempdir().unwrap();
    let path = config(dir.path(), "trivkins-xyza.ini", 0);
    for t in [0.0, 25.0] {
        let file = machine_from_linuxcnc(&path, Some(t)).unwrap_or_else(|e| panic!("{e}"));
        let m = Machine::from_json_str(&file.to_string(), "xyza.json").unwrap();
        assert_eq!(
            file["output_order"],
            serde_json::json!(["X", "Y", "Z", "A"])
        );
        assert_eq!(
            m.axis("A").unwrap().rotary,
            kinpost::machine::RotaryMode::Continuous
        );
        let mut rng = Lcg(0x4a);
        let mut worst = 0.0f64;
        for _ in 0..1000 {
            let j = [
                200.0 * rng.next(),
                100.0 * rng.next(),
                150.0 * rng.next(),
                1080.0 * rng.next(),
            ];
            let p = m.chain.pose(&m.to_internal(&j), &NoErrors);
            let (s, c) = (-j[3]).to_radians().sin_cos();
            let rx = |v: [f64; 3]| [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]];
            let tip = rx([j[0], j[1], j[2] - t]);
            let axis = rx([0.0, 0.0, 1.0]);
            for k in 0..3 {
                worst = worst.max((p.tip[k] - tip[k]).abs());
                worst = worst.max((p.axis[k] - axis[k]).abs());
            }
        }
        assert!(worst <= 1e-12, "tool length {t}: {worst:e}");
    }
}

/// trivkins configurations kinpost cannot describe are refused at the
/// entry that says why: a lathe (no Y), two rotaries (their arrangement is
/// not in the file), no axes given; units other than mm, inch and degrees.
#[test]
fn trivkins_and_unit_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "[KINS]\nKINEMATICS = trivkins coordinates=xz\n",
            "2:14: trivkins with coordinates `XZ`: the machine lacks X, Y or Z",
        ),
        (
            "[KINS]\nKINEMATICS = trivkins\n[TRAJ]\nCOORDINATES = XYZAC\n",
            "4:15: trivkins with the rotary axes A and C: identity kinematics do not say how they are arranged",
        ),
        (
            "[KINS]\nKINEMATICS = trivkins\n",
            "2:14: trivkins without coordinates= and without [TRAJ] COORDINATES",
        ),
        (
            "[KINS]\nKINEMATICS = trivkins coordinates=xyq\n",
            "2:14: coordinates `XYQ`: `Q` is not an axis",
        ),
        (
            "[KINS]\nKINEMATICS = trivkins coordinates=xyz\n[TRAJ]\nLINEAR_UNITS = furlong\n",
            "4:16: LINEAR_UNITS `furlong` is not a length unit; expected mm or inch",
        ),
        (
            "[KINS]\nKINEMATICS = 5axiskins\n[TRAJ]\nANGULAR_UNITS = grad\n",
            "4:17: ANGULAR_UNITS `grad`: machine files are in degrees",
        ),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("r{i}.ini"));
        std::fs::write(&path, text).unwrap();
        let e = machine_from_linuxcnc(&path, None).unwrap_err().to_string();
        assert!(e.contains(&format!("r{i}.ini:{want}")), "{e}");
    }
}

/// `#INCLUDE` (LinuxCNC 2.8 and later): the included file's entries are
/// read in its place, nested includes relative to the file that includes
/// them, so the configuration split into files gives the machine of the
/// same configuration in one file. Before, the entries of an included file
/// were not read: `[KINS]` there was "no [KINS] KINEMATICS entry", and
/// `LINEAR_UNITS = inch` there would have been read as mm.
#[test]
fn an_ini_reads_the_files_it_includes() {
    let dir = tempfile::tempdir().unwrap();
    let whole = config(dir.path(), "xyzac-trt.ini", 1);
    let text = std::fs::read_to_string(&whole)
        .unwrap()
        .replace("LINEAR_UNITS = mm", "LINEAR_UNITS = inch");
    std::fs::write(&whole, &text).unwrap();
    let want = machine_from_linuxcnc(&whole, None).unwrap_or_else(|e| panic!("{e}"));

    // The same entries over three files: [KINS] and [TRAJ] in inc/kins.inc,
    // which includes its neighbour axes.inc (the limits); the HALCMD of
    // [HAL] in an include that starts no section.
    let (head, rest) = text.split_at(text.find("[KINS]").unwrap());
    let (kins, rest) = rest.split_at(rest.find("[HAL]").unwrap());
    let (hal, rest) = rest.split_at(rest.find("HALCMD").unwrap());
    let (halcmd, rest) = rest.split_at(rest.find("\n[GEOMETRY]").unwrap() + 1);
    let (geometry, axes) = rest.split_at(rest.find("[AXIS_X]").unwrap());
    std::fs::create_dir(dir.path().join("inc")).unwrap();
    std::fs::write(
        dir.path().join("inc/kins.inc"),
        format!("{kins}#INCLUDE axes.inc\n"),
    )
    .unwrap();
    std::fs::write(dir.path().join("inc/axes.inc"), axes).unwrap();
    std::fs::write(dir.path().join("halcmd.inc"), halcmd).unwrap();
    let split = dir.path().join("split.ini");
    std::fs::write(
        &split,
        format!("{head}#INCLUDE inc/kins.inc\n{hal}#INCLUDE\thalcmd.inc\n{geometry}"),
    )
    .unwrap();
    let got = machine_from_linuxcnc(&split, None).unwrap_or_else(|e| panic!("{e}"));
    let strip = |mut v: serde_json::Value| {
        v["name"] = "-".into();
        v["description"] = "-".into();
        v["source"] = "-".into();
        v
    };
    assert_eq!(strip(got.clone()), strip(want));
    assert!(
        got["description"]
            .as_str()
            .unwrap()
            .contains("in inch, converted to mm"),
        "{}",
        got["description"]
    );

    // Errors name the file and line that include.
    let refuse = |main: &str, want: &str| {
        let path = dir.path().join("bad.ini");
        std::fs::write(&path, main).unwrap();
        let e = machine_from_linuxcnc(&path, None).unwrap_err().to_string();
        assert!(e.contains(want), "{main:?}: {e}");
    };
    std::fs::write(dir.path().join("loop.inc"), "[EMC]\n#INCLUDE bad.ini\n").unwrap();
    refuse(
        "[KINS]\nKINEMATICS = trivkins\n#INCLUDE loop.inc\n",
        "loop.inc:2:1: `bad.ini` includes itself",
    );
    refuse(
        "[KINS]\n#INCLUDE nowhere.inc\n",
        "bad.ini:2:1: cannot include",
    );
    refuse("#INCLUDE\n", "bad.ini:1:1: `#INCLUDE` without a file name");
    refuse(
        "#INCLUDEkins.inc\n",
        "bad.ini:1:1: `#INCLUDE` without a file name",
    );
    // An error inside an included file names that file.
    std::fs::write(
        dir.path().join("units.inc"),
        "[TRAJ]\nLINEAR_UNITS = furlong\n",
    )
    .unwrap();
    refuse(
        "[KINS]\nKINEMATICS = trivkins coordinates=xyz\n#INCLUDE units.inc\n",
        "units.inc:2:16: LINEAR_UNITS `furlong` is not a length unit",
    );
}

/// A HAL file's `source FILE` reads FILE in its place (halcmd runs in the
/// INI's directory): the kinematics parameters set there count, in order.
/// Before, they were not read, and the rotation point stayed at 0 without a
/// word.
#[test]
fn a_hal_file_reads_the_files_it_sources() {
    let dir = tempfile::tempdir().unwrap();
    let whole = config(dir.path(), "xyzac-trt.ini", 1);
    let want = machine_from_linuxcnc(&whole, None).unwrap_or_else(|e| panic!("{e}"));
    // The HAL file's setp lines moved into a file it sources.
    let hal = dir.path().join("xyzac-trt.hal");
    let text = std::fs::read_to_string(&hal).unwrap();
    std::fs::create_dir(dir.path().join("hal")).unwrap();
    std::fs::write(dir.path().join("hal/kins.hal"), &text).unwrap();
    std::fs::write(&hal, "# the geometry\nsource hal/kins.hal\n").unwrap();
    let got = machine_from_linuxcnc(&whole, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(got["chain"], want["chain"]);
    assert_ne!(got["chain"][0]["translate"][0], 0.0, "{}", got["chain"]);

    // A file that sources itself is refused at the command.
    std::fs::write(&hal, "source xyzac-trt.hal\n").unwrap();
    let e = machine_from_linuxcnc(&whole, None).unwrap_err().to_string();
    assert!(
        e.contains("xyzac-trt.hal:1:8: `source xyzac-trt.hal`: HAL files source each other"),
        "{e}"
    );

    // A Tcl HAL file is not run: one that sets the module's pins is
    // refused (before, it was skipped, and the geometry left at 0).
    std::fs::write(&hal, "source hal/kins.hal\n").unwrap();
    std::fs::write(
        dir.path().join("geometry.tcl"),
        "# Tcl\nsetp xyzac-trt-kins.z-offset [expr 2 * 5]\n",
    )
    .unwrap();
    let ini = std::fs::read_to_string(&whole).unwrap();
    std::fs::write(
        &whole,
        ini.replace(
            "HALFILE = xyzac-trt.hal",
            "HALFILE = xyzac-trt.hal\nHALFILE = geometry.tcl",
        ),
    )
    .unwrap();
    let e = machine_from_linuxcnc(&whole, None).unwrap_err().to_string();
    assert!(
        e.contains("geometry.tcl:2:6: a Tcl HAL file sets pins of xyzac-trt-kins"),
        "{e}"
    );
}

/// HAL commands as halcmd reads them (the sixth hunt: each gave the
/// module's default, 0, without a word, a tip up to 28 mm from LinuxCNC's):
/// `PIN = VALUE` is `setp`; a line ending in `\` goes on in the next (in
/// the HAL file and in the INI); `[SECTION](KEY)` is an INI reference;
/// HAL's first link copies the pin's value onto the signal, so a `sets`
/// before it is lost; a pin driven by another component is refused, since
/// its value is what that component computes.
#[test]
fn hal_commands_are_read_as_halcmd_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let ini = config(dir.path(), "xyzac-trt.ini", 0);
    let want = machine_from_linuxcnc(&ini, None).unwrap_or_else(|e| panic!("{e}"));
    let hal = dir.path().join("xyzac-trt.hal");
    let base = std::fs::read_to_string(&hal).unwrap();
    let same = |text: &str| {
        std::fs::write(&hal, text).unwrap();
        let got = machine_from_linuxcnc(&ini, None).unwrap_or_else(|e| panic!("{text}\n{e}"));
        assert_eq!(got["chain"], want["chain"], "{text}");
    };
    // `PIN = VALUE`, a continued `setp`, a continued `net`, `[S](K)`.
    same(&base.replace(
        "setp xyzac-trt-kins.x-rot-point 12.5",
        "xyzac-trt-kins.x-rot-point = 12.5",
    ));
    same(&base.replace(
        "setp xyzac-trt-kins.x-rot-point 12.5",
        "setp xyzac-trt-kins.x-rot-point \\\n    12.5",
    ));
    same(&base.replace(
        "net :z-offset xyzac-trt-kins.z-offset",
        "net :z-offset \\\n    xyzac-trt-kins.z-offset",
    ));
    let ini_text = std::fs::read_to_string(&ini).unwrap();
    std::fs::write(
        &ini,
        ini_text
            .replace("[GEOMETRY]Z_ROT_POINT", "[GEOMETRY](Z_ROT_POINT)")
            .replace("Z_ROT_POINT = -3.25", "Z_ROT_POINT = \\\n  -3.25"),
    )
    .unwrap();
    same(&base);
    std::fs::write(&ini, &ini_text).unwrap();
    // A value set on the signal before its first pin is linked is lost; a
    // `setp` of the pin before the link is what the signal carries.
    std::fs::write(
        &hal,
        base.replace(
            "net :z-offset xyzac-trt-kins.z-offset\n",
            "newsig :z-offset float\nsets :z-offset 99\nsetp xyzac-trt-kins.z-offset 10.125\nnet :z-offset xyzac-trt-kins.z-offset\n",
        )
        .replace("sets :z-offset 10.125\n", ""),
    )
    .unwrap();
    let got = machine_from_linuxcnc(&ini, None).unwrap();
    assert_eq!(got["chain"], want["chain"]);
    // Driven by another component: refused at the link.
    for (net, at) in [
        (
            "net :z-offset zsum.out xyzac-trt-kins.z-offset",
            "xyzac-trt.hal:7:15",
        ),
        (
            "net :z-offset <= offs.z => xyzac-trt-kins.z-offset",
            "xyzac-trt.hal:7:18",
        ),
        (
            "net :z-offset offs.z => xyzac-trt-kins.z-offset",
            "xyzac-trt.hal:7:15",
        ),
    ] {
        std::fs::write(
            &hal,
            base.replace("net :z-offset xyzac-trt-kins.z-offset", net)
                .replace("sets :z-offset 10.125\n", ""),
        )
        .unwrap();
        let e = machine_from_linuxcnc(&ini, None).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "{at}: xyzac-trt-kins.z-offset is on signal :z-offset, which"
            )),
            "{net}: {e}"
        );
    }
    // The tool offset, which motion.tooloffset.z drives while the machine
    // runs, is the tool length given (or 0).
    std::fs::write(
        &hal,
        base.replace(
            "setp xyzac-trt-kins.tool-offset 42.5",
            "net :tool-offset motion.tooloffset.z => xyzac-trt-kins.tool-offset",
        ),
    )
    .unwrap();
    let got = machine_from_linuxcnc(&ini, Some(42.5)).unwrap();
    assert_eq!(got["chain"], want["chain"]);
    assert_eq!(
        machine_from_linuxcnc(&ini, None).unwrap()["tool_length"],
        0.0
    );
}

/// Joint limits narrow the axis limits: kinpost's output runs under
/// identity kinematics, where a joint's `[JOINT_n]` limits hold beside its
/// axis's. LinuxCNC's own xyzbc-trt sample gives B ±36000 in `[AXIS_B]`
/// and −100…50 in `[JOINT_3]`: it came out `continuous`, and a pose kinpost
/// solved beyond 50° stopped the machine at the joint limit. Joints map to
/// axes by the module's `coordinates=` or its default order.
#[test]
fn joint_limits_narrow_the_axis_limits() {
    let dir = tempfile::tempdir().unwrap();
    let path = config(dir.path(), "xyzac-trt.ini", 0);
    let text = std::fs::read_to_string(&path).unwrap();
    let with = |extra: &str, kins: &str| {
        std::fs::write(
            &path,
            format!(
                "{}\n{extra}",
                text.replace("KINEMATICS = xyzac-trt-kins", kins)
            ),
        )
        .unwrap();
        let v = machine_from_linuxcnc(&path, None).unwrap_or_else(|e| panic!("{e}"));
        Machine::from_json_str(&v.to_string(), "j.json").unwrap()
    };
    // A (joint 3): axis −30…110, joint −20…150 → −20…110. C (joint 4):
    // continuous in [AXIS_C], −200…200 in [JOINT_4]. X (joint 0): −400…400
    // and −350…500 → −350…400.
    let joints = "[JOINT_3]\nMIN_LIMIT = -20\nMAX_LIMIT = 150\n[JOINT_4]\nMIN_LIMIT = -200\nMAX_LIMIT = 200\n[JOINT_0]\nMIN_LIMIT = -350\nMAX_LIMIT = 500\n";
    let m = with(joints, "KINEMATICS = xyzac-trt-kins");
    let lim = |m: &Machine, a: &str| {
        let a = m.axis(a).unwrap();
        (a.min, a.max)
    };
    assert_eq!(lim(&m, "A"), (Some(-20.0), Some(110.0)));
    assert_eq!(lim(&m, "C"), (Some(-200.0), Some(200.0)));
    assert_eq!(lim(&m, "X"), (Some(-350.0), Some(400.0)));
    // `coordinates=` maps the joints otherwise: joint 3 is C, joint 4 A.
    let m = with(joints, "KINEMATICS = xyzac-trt-kins coordinates=xyzca");
    assert_eq!(lim(&m, "C"), (Some(-20.0), Some(150.0)));
    assert_eq!(lim(&m, "A"), (Some(-30.0), Some(110.0)));
}
