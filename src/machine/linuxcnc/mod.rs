//! A machine file from a LinuxCNC configuration (`kinpost machine
//! --from-linuxcnc config.ini`).
//!
//! The INI is read as LinuxCNC reads it (`ini.rs`: `#INCLUDE` files,
//! continued lines). Its `[KINS] KINEMATICS` names the kinematics module;
//! its HAL parameters come from the HAL files of `[HAL] HALFILE` (relative
//! to the INI), the INI's own `[HAL] HALCMD` lines and `[HAL]
//! POSTGUI_HALFILE`, in that order, read as halcmd reads them (`hal.rs`).
//! A wrapped rotary axis (`WRAPPED_ROTARY`) is refused: LinuxCNC turns it
//! the way its word's sign says, which kinpost does not write.
//!
//! The chains (`docs/integration.md`), with `con` = +1 when
//! `conventional-directions` is 1 and −1 otherwise, `R` the rotation point,
//! `D` the offsets and `T` the tool length:
//!
//! - `xyzac-trt-kins`: translate R, revolute C `[0,0,con]`, translate
//!   D = (0, y-offset, z-offset), revolute A `[con,0,0]`, prismatic X, Y, Z,
//!   translate −(R + D), translate `[0,0,−T]`.
//! - `xyzbc-trt-kins`: the same with D = (x-offset, 0, z-offset) and
//!   revolute B `[0,con,0]`.
//! - `xyzab_tdr_kins` (a tilting A table carrying a B table; its TCP
//!   kinematics, type 1): translate R + (0, 0, z-offset), revolute A
//!   `[1,0,0]`, translate `[0,0,−z-offset]`, revolute B `[0,1,0]`,
//!   prismatic X, Y, Z, translate −R, translate `[0,0,−T]` (T =
//!   `tool-offset-z`; `x-offset` moves the A axis along itself and changes
//!   no pose).
//! - `5axiskins`: prismatic X, Y, Z, translate `[0,0,L]`, revolute C
//!   `[0,0,1]`, revolute B `[0,−1,0]`, translate `[0,0,−(L+T)]`
//!   (L = `pivot-length`, default 250).
//!
//! - `trivkins` (identity kinematics, the common mill): its axes are those
//!   of its `coordinates=` parameter, else `[TRAJ] COORDINATES`. X, Y, Z
//!   alone: prismatic X, Y, Z, translate `[0,0,−T]`. X, Y, Z and one rotary
//!   L of A, B, C: a rotary table turning the part about +X, +Y or +Z
//!   through the workpiece origin, a positive command turning it by +q
//!   (LinuxCNC's table kinematics with `conventional-directions` 0), so
//!   revolute L `−e` first, then prismatic X, Y, Z and translate
//!   `[0,0,−T]`. U, V, W are not part of the chain. Without Y (a lathe), or
//!   with two or more rotaries (whose arrangement the configuration does
//!   not say), it is refused.
//!
//! Lengths in inch (`[TRAJ] LINEAR_UNITS = inch`) are converted to mm: the
//! linear limits and the HAL lengths. `maxkins` is refused: it turns the X/Y
//! slides with C but adds the B head's offset unturned, which no rigid chain
//! reproduces.

mod hal;
mod ini;

use crate::error::{Error, Location, Result};
use hal::Hal;
use ini::{Ini, IniEntry};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};

/// The kinematics modules understood.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kins {
    TrtAc,
    TrtBc,
    /// `xyzab_tdr_kins`: a tilting A table carrying a B table.
    TdrAb,
    FiveAxis,
}

/// The modules named in messages.
const SUPPORTED: &str = "xyzac-trt-kins, xyzbc-trt-kins, xyzab_tdr_kins, 5axiskins or trivkins";

/// mm per inch.
const MM_PER_INCH: f64 = 25.4;

/// Reads the LinuxCNC configuration `ini` and returns the machine file
/// (JSON) for its kinematics. `tool_length_mm` (T) overrides the
/// kinematics' `tool-offset` pin (trt; default 0).
pub fn machine_from_linuxcnc(ini_path: &Path, tool_length_mm: Option<f64>) -> Result<Value> {
    let file = ini_path.display().to_string();
    let ini = Ini::load(ini_path)?;
    let whole = |msg: String| Error::input(Location::new(&file, 0, 0), msg);

    let kins_e = ini.get("KINS", "KINEMATICS").ok_or_else(|| {
        whole(format!(
            "no [KINS] KINEMATICS entry; expected the kinematics module ({SUPPORTED})"
        ))
    })?;
    let module = kins_e.value.split_whitespace().next().unwrap_or("");
    let kins = match module {
        "xyzac-trt-kins" | "xyzac-trt" => Kins::TrtAc,
        "xyzbc-trt-kins" | "xyzbc-trt" => Kins::TrtBc,
        "xyzab_tdr_kins" => Kins::TdrAb,
        "5axiskins" => Kins::FiveAxis,
        "trivkins" => {
            let mm_per_unit = linear_unit(&ini)?;
            angular_unit(&ini)?;
            return trivial_machine(ini_path, &ini, kins_e, mm_per_unit, tool_length_mm);
        }
        "maxkins" => {
            return Err(ini.err(
                kins_e,
                "maxkins cannot be converted: it turns the X and Y slides with C but adds the B head's offset without turning it, which no rigid kinematic chain reproduces; describe the machine by hand (kinpost machine --template 2R3T)",
            ));
        }
        other => {
            return Err(ini.err(
                kins_e,
                format!("kinematics `{other}` is not supported; expected {SUPPORTED}"),
            ));
        }
    };
    let mm_per_unit = linear_unit(&ini)?;
    angular_unit(&ini)?;

    // HAL sources, in the order HAL runs them.
    let dir: PathBuf = ini_path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    let prefix = match kins {
        Kins::TrtAc => "xyzac-trt-kins",
        Kins::TrtBc => "xyzbc-trt-kins",
        Kins::TdrAb => "xyzab_tdr_kins",
        Kins::FiveAxis => "5axiskins",
    };
    let mut hal = Hal {
        dir: dir.clone(),
        module: format!("{prefix}."),
        ..Hal::default()
    };
    let mut skipped: Vec<String> = Vec::new();
    let mut read_file = |hal: &mut Hal, e: &IniEntry| -> Result<()> {
        let name = e.value.split_whitespace().next().unwrap_or("");
        let path = ini::home_path(name).unwrap_or_else(|| dir.join(name));
        // `LIB:name`, or a name LinuxCNC finds in its HAL library
        // (`HALLIB_PATH`) rather than beside the INI: LinuxCNC's own files,
        // which set no kinematics pins.
        if name.starts_with("LIB:") || (!path.exists() && !name.contains('/')) {
            skipped.push(name.to_string());
            return Ok(());
        }
        let text = crate::text::read_text_file(&path)?;
        if name.ends_with(".tcl") {
            // Tcl is not run; a Tcl file that touches the module's pins
            // would leave the geometry unread.
            tcl_touches(&text, &path, prefix)?;
            skipped.push(name.to_string());
            return Ok(());
        }
        hal.read(&ini, &text, &path.display().to_string(), 1, 0)
    };
    for e in ini.all("HAL", "HALFILE") {
        read_file(&mut hal, e)?;
    }
    for e in ini.all("HAL", "HALCMD") {
        hal.read(&ini, &e.value, ini.file_of(e), e.line, e.col - 1)?;
    }
    for e in ini.all("HAL", "POSTGUI_HALFILE") {
        read_file(&mut hal, e)?;
    }

    let pin = |p: &str| format!("{prefix}.{p}");
    // A HAL length in the configuration's units, in mm.
    let length = |hal: &Hal, p: &str, default: f64| -> Result<f64> {
        Ok(to_mm(hal.number(p, default)?, mm_per_unit))
    };
    let tool = |hal: &Hal| -> Result<f64> {
        match tool_length_mm {
            Some(t) => Ok(t),
            None if kins == Kins::FiveAxis => Ok(0.0),
            None => {
                let p = pin(if kins == Kins::TdrAb {
                    "tool-offset-z"
                } else {
                    "tool-offset"
                });
                Ok(to_mm(hal.undriven_number(&p, 0.0)?, mm_per_unit))
            }
        }
    };
    let t = tool(&hal)?;
    let v3 = |x: f64, y: f64, z: f64| json!([x, y, z]);
    let joint = |kind: &str, name: &str, axis: Value| json!({ kind: {"name": name, "axis": axis} });
    let translate = |v: Value| json!({ "translate": v });
    let (chain, order, summary): (Vec<Value>, Vec<&str>, String) = match kins {
        Kins::TrtAc | Kins::TrtBc => {
            let con = if hal.flag(&pin("conventional-directions"))? {
                1.0
            } else {
                -1.0
            };
            let r = [
                length(&hal, &pin("x-rot-point"), 0.0)?,
                length(&hal, &pin("y-rot-point"), 0.0)?,
                length(&hal, &pin("z-rot-point"), 0.0)?,
            ];
            let d = if kins == Kins::TrtAc {
                [
                    0.0,
                    length(&hal, &pin("y-offset"), 0.0)?,
                    length(&hal, &pin("z-offset"), 0.0)?,
                ]
            } else {
                [
                    length(&hal, &pin("x-offset"), 0.0)?,
                    0.0,
                    length(&hal, &pin("z-offset"), 0.0)?,
                ]
            };
            let (tilt, tilt_axis) = if kins == Kins::TrtAc {
                ("A", v3(con, 0.0, 0.0))
            } else {
                ("B", v3(0.0, con, 0.0))
            };
            let chain = vec![
                translate(v3(r[0], r[1], r[2])),
                joint("revolute", "C", v3(0.0, 0.0, con)),
                translate(v3(d[0], d[1], d[2])),
                joint("revolute", tilt, tilt_axis),
                joint("prismatic", "X", v3(1.0, 0.0, 0.0)),
                joint("prismatic", "Y", v3(0.0, 1.0, 0.0)),
                joint("prismatic", "Z", v3(0.0, 0.0, 1.0)),
                translate(v3(-(r[0] + d[0]), -(r[1] + d[1]), -(r[2] + d[2]))),
                translate(v3(0.0, 0.0, -t)),
            ];
            let summary = format!(
                "conventional-directions {} (con = {con}), rot-point ({}, {}, {}) mm, offsets ({}, {}, {}) mm",
                if con > 0.0 { 1 } else { 0 },
                r[0],
                r[1],
                r[2],
                d[0],
                d[1],
                d[2]
            );
            (chain, vec!["X", "Y", "Z", tilt, "C"], summary)
        }
        Kins::TdrAb => {
            // The A table turns about X through the rotation point raised
            // by z-offset, and carries the B table, which turns about Y
            // through the rotation point. x-offset moves the A axis along
            // itself: it changes no pose (the module's forward kinematics
            // leaves it out; its inverse adds and takes it away again).
            let r = [
                length(&hal, &pin("x-rot-point"), 0.0)?,
                length(&hal, &pin("y-rot-point"), 0.0)?,
                length(&hal, &pin("z-rot-point"), 0.0)?,
            ];
            let dx = length(&hal, &pin("x-offset"), 0.0)?;
            let dz = length(&hal, &pin("z-offset"), 0.0)?;
            let chain = vec![
                translate(v3(r[0], r[1], r[2] + dz)),
                joint("revolute", "A", v3(1.0, 0.0, 0.0)),
                translate(v3(0.0, 0.0, -dz)),
                joint("revolute", "B", v3(0.0, 1.0, 0.0)),
                joint("prismatic", "X", v3(1.0, 0.0, 0.0)),
                joint("prismatic", "Y", v3(0.0, 1.0, 0.0)),
                joint("prismatic", "Z", v3(0.0, 0.0, 1.0)),
                translate(v3(-r[0], -r[1], -r[2])),
                translate(v3(0.0, 0.0, -t)),
            ];
            let summary = format!(
                "rot-point ({}, {}, {}) mm, z-offset {dz} mm, x-offset {dx} mm (along the A axis: it moves no pose)",
                r[0], r[1], r[2]
            );
            (chain, vec!["X", "Y", "Z", "A", "B"], summary)
        }
        Kins::FiveAxis => {
            let l = length(&hal, &pin("pivot-length"), 250.0)?;
            let chain = vec![
                joint("prismatic", "X", v3(1.0, 0.0, 0.0)),
                joint("prismatic", "Y", v3(0.0, 1.0, 0.0)),
                joint("prismatic", "Z", v3(0.0, 0.0, 1.0)),
                translate(v3(0.0, 0.0, l)),
                joint("revolute", "C", v3(0.0, 0.0, 1.0)),
                joint("revolute", "B", v3(0.0, -1.0, 0.0)),
                translate(v3(0.0, 0.0, -(l + t))),
            ];
            (
                chain,
                vec!["X", "Y", "Z", "B", "C"],
                format!("pivot-length {l} mm"),
            )
        }
    };

    let default = match kins {
        Kins::TrtAc => "XYZAC",
        Kins::TrtBc => "XYZBC",
        Kins::TdrAb => "XYZAB",
        Kins::FiveAxis => "XYZBCW",
    };
    let axes = axis_limits(&ini, &order, &joint_letters(kins_e, default), mm_per_unit)?;

    let name = machine_name(ini_path, &ini);
    let mut description = format!(
        "From the LinuxCNC configuration {file} ({module}{}): {summary}, tool length {t} mm at the end of the chain. Run kinpost's output under identity kinematics with zero work offsets and no tool length compensation (docs/integration.md).",
        inch_note(mm_per_unit)
    );
    if !skipped.is_empty() {
        description.push_str(&format!(
            " HAL files not read (library or Tcl files): {}.",
            skipped.join(", ")
        ));
    }
    Ok(machine_file(
        &name,
        &description,
        &file,
        chain,
        axes,
        &order,
        t,
    ))
}

/// The machine of a `trivkins` configuration (see the module docs):
/// three linear axes and at most one rotary table.
/// Refuses a Tcl HAL file (`HALFILE = x.tcl`, which kinpost does not run)
/// that names a pin of the kinematics module `prefix`.
fn tcl_touches(text: &str, path: &Path, prefix: &str) -> Result<()> {
    for (n, line) in text.lines().enumerate() {
        let code = line.split('#').next().unwrap_or("");
        if let Some(at) = code.find(&format!("{prefix}.")) {
            return Err(Error::input_with(
                Location::new(path.display().to_string(), n + 1, at + 1),
                format!(
                    "a Tcl HAL file sets pins of {prefix}, and kinpost does not run Tcl; expected the module's parameters in a .hal file or a [HAL] HALCMD line"
                ),
                line,
            ));
        }
    }
    Ok(())
}

fn trivial_machine(
    ini_path: &Path,
    ini: &Ini,
    kins_e: &IniEntry,
    mm_per_unit: f64,
    tool_length_mm: Option<f64>,
) -> Result<Value> {
    let file = ini_path.display().to_string();
    // The axes: the module's `coordinates=`, else [TRAJ] COORDINATES.
    let (letters, from) = match (coordinates_param(kins_e), ini.get("TRAJ", "COORDINATES")) {
        (Some(v), _) => (v.to_string(), kins_e),
        (None, Some(e)) => (e.value.clone(), e),
        (None, None) => {
            return Err(ini.err(
                kins_e,
                "trivkins without coordinates= and without [TRAJ] COORDINATES: the axes of the machine are not given; expected e.g. KINEMATICS = trivkins coordinates=xyz",
            ));
        }
    };
    let letters = letters.to_ascii_uppercase();
    if let Some(c) = letters
        .chars()
        .find(|c| !c.is_whitespace() && !"XYZABCUVW".contains(*c))
    {
        return Err(ini.err(
            from,
            format!("coordinates `{letters}`: `{c}` is not an axis; expected letters of XYZABCUVW"),
        ));
    }
    let has = |c: char| letters.contains(c);
    if !(has('X') && has('Y') && has('Z')) {
        return Err(ini.err(
            from,
            format!(
                "trivkins with coordinates `{letters}`: the machine lacks X, Y or Z (a lathe, a foam cutter), and kinpost converts tool poses for mills with all three; describe such a machine by hand (kinpost machine --template)"
            ),
        ));
    }
    let rotaries: Vec<&str> = ["A", "B", "C"]
        .into_iter()
        .filter(|l| letters.contains(*l))
        .collect();
    let (rotary, about) = match rotaries.as_slice() {
        [] => (None, ""),
        ["A"] => (Some(("A", [-1.0, 0.0, 0.0])), "X"),
        ["B"] => (Some(("B", [0.0, -1.0, 0.0])), "Y"),
        ["C"] => (Some(("C", [0.0, 0.0, -1.0])), "Z"),
        _ => {
            return Err(ini.err(
                from,
                format!(
                    "trivkins with the rotary axes {}: identity kinematics do not say how they are arranged (table-table, head-head, head-table) nor where they turn; describe the machine by hand (kinpost machine --template 2R3T)",
                    rotaries.join(" and ")
                ),
            ));
        }
    };
    let t = tool_length_mm.unwrap_or(0.0);
    let joint =
        |kind: &str, name: &str, axis: [f64; 3]| json!({ kind: {"name": name, "axis": axis} });
    let mut chain = Vec::new();
    let mut order = vec!["X", "Y", "Z"];
    if let Some((name, axis)) = rotary {
        chain.push(joint("revolute", name, axis));
        order.push(name);
    }
    chain.push(joint("prismatic", "X", [1.0, 0.0, 0.0]));
    chain.push(joint("prismatic", "Y", [0.0, 1.0, 0.0]));
    chain.push(joint("prismatic", "Z", [0.0, 0.0, 1.0]));
    chain.push(json!({ "translate": [0.0, 0.0, -t] }));
    let axes = axis_limits(
        ini,
        &order,
        &joint_letters(kins_e, "XYZABCUVW"),
        mm_per_unit,
    )?;
    let others: String = letters.chars().filter(|c| "UVW".contains(*c)).collect();
    let mut description = match rotary {
        None => format!(
            "From the LinuxCNC configuration {file} (trivkins, coordinates {letters}{}): a three-axis mill, the tool along +Z, tool length {t} mm at the end of the chain.",
            inch_note(mm_per_unit)
        ),
        Some((name, _)) => format!(
            "From the LinuxCNC configuration {file} (trivkins, coordinates {letters}{}): a rotary table {name} turning the part about {about} through the workpiece origin (set the work offset there, as four-axis CAM output assumes), a positive {name} turning the part by +{name} about +{about} (LinuxCNC's table kinematics with conventional-directions 0; negate the axis of {name} in this file for the opposite sense), tool length {t} mm at the end of the chain.",
            inch_note(mm_per_unit)
        ),
    };
    if !others.is_empty() {
        description.push_str(&format!(
            " The axes {others} are not part of the chain: kinpost writes no words for them."
        ));
    }
    let name = machine_name(ini_path, ini);
    Ok(machine_file(
        &name,
        &description,
        &file,
        chain,
        axes,
        &order,
        t,
    ))
}

/// The machine file's JSON: its chain (workpiece → tool tip), axes and
/// output order, with the tool length `t` (mm) at the end of the chain.
fn machine_file(
    name: &str,
    description: &str,
    file: &str,
    chain: Vec<Value>,
    axes: Map<String, Value>,
    order: &[&str],
    t: f64,
) -> Value {
    json!({
        "name": name,
        "description": description,
        "source": format!("kinpost machine --from-linuxcnc {file}"),
        "chain": chain,
        "axes": axes,
        "output_order": order,
        "tool_length": t,
    })
}

/// `[TRAJ] LINEAR_UNITS`: mm per unit of the configuration (1 for mm,
/// 25.4 for inch; mm when absent, LinuxCNC's default).
fn linear_unit(ini: &Ini) -> Result<f64> {
    let Some(u) = ini.get("TRAJ", "LINEAR_UNITS") else {
        return Ok(1.0);
    };
    match u.before_comment().to_ascii_lowercase().as_str() {
        "mm" | "metric" | "millimeter" | "millimetre" => Ok(1.0),
        "inch" | "in" | "imperial" => Ok(MM_PER_INCH),
        _ => Err(ini.err(
            u,
            format!(
                "LINEAR_UNITS `{}` is not a length unit; expected mm or inch",
                u.value
            ),
        )),
    }
}

/// `[TRAJ] ANGULAR_UNITS` must be degrees (the machine file's unit).
fn angular_unit(ini: &Ini) -> Result<()> {
    match ini.get("TRAJ", "ANGULAR_UNITS") {
        Some(u)
            if !matches!(
                u.before_comment().to_ascii_lowercase().as_str(),
                "deg" | "degree" | "degrees"
            ) =>
        {
            Err(ini.err(
                u,
                format!(
                    "ANGULAR_UNITS `{}`: machine files are in degrees; expected a configuration in degrees",
                    u.value
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// A length of the configuration in mm. Converted from inch it is rounded
/// to 1e-9 mm: a value of up to five decimal places in inch has six in mm,
/// and the rounding drops the binary noise of the product (3 × 25.4 is
/// 76.19999999999999 in f64).
fn to_mm(v: f64, mm_per_unit: f64) -> f64 {
    if mm_per_unit == 1.0 {
        v
    } else {
        (v * mm_per_unit * 1e9).round() / 1e9
    }
}

/// The description's note on a configuration in inch.
fn inch_note(mm_per_unit: f64) -> &'static str {
    if mm_per_unit == 1.0 {
        ""
    } else {
        "; its lengths in inch, converted to mm"
    }
}

/// The machine's name: `[EMC] MACHINE`, else the INI's file name.
fn machine_name(ini_path: &Path, ini: &Ini) -> String {
    ini.get("EMC", "MACHINE")
        .map(|e| e.value.clone())
        .unwrap_or_else(|| {
            ini_path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "linuxcnc".into())
        })
}

/// The axes of `order` with their limits from `[AXIS_L] MIN_LIMIT` and
/// `MAX_LIMIT` (linear ones converted to mm by `mm_per_unit`), rotary mode
/// and decimals.
/// The kinematics module's `coordinates=` parameter, when given.
fn coordinates_param(kins_e: &IniEntry) -> Option<&str> {
    kins_e.value.split_whitespace().find_map(|p| {
        let (k, v) = p.split_once('=')?;
        k.eq_ignore_ascii_case("coordinates").then_some(v)
    })
}

/// The axis letter of each joint of the kinematics module: its
/// `coordinates=` parameter, else the module's default (`XYZABCUVW` for
/// trivkins, the required letters for the others).
fn joint_letters(kins_e: &IniEntry, default: &str) -> Vec<char> {
    coordinates_param(kins_e)
        .unwrap_or(default)
        .chars()
        .filter(char::is_ascii_alphabetic)
        .map(|c| c.to_ascii_uppercase())
        .collect()
}

/// The limits of the axes of `order` (`[AXIS_L]`), narrowed by those of
/// the joints that carry each (`[JOINT_n]`, `joints` giving each joint's
/// letter): kinpost's output runs under identity kinematics, where both
/// hold.
fn axis_limits(
    ini: &Ini,
    order: &[&str],
    joints: &[char],
    mm_per_unit: f64,
) -> Result<Map<String, Value>> {
    let mut axes = Map::new();
    for name in order {
        let section = format!("AXIS_{name}");
        let num = |section: &str, key: &str| -> Result<Option<f64>> {
            match ini.get(section, key) {
                None => Ok(None),
                Some(e) => match e.number() {
                    Some(v) => Ok(Some(v)),
                    None => Err(ini.err(
                        e,
                        format!("[{section}] {key} `{}` is not a number", e.value),
                    )),
                },
            }
        };
        let (mut lo, mut hi) = (num(&section, "MIN_LIMIT")?, num(&section, "MAX_LIMIT")?);
        let letter = name.chars().next().unwrap_or(' ');
        for j in (0..joints.len()).filter(|&j| joints[j] == letter) {
            let joint = format!("JOINT_{j}");
            if let Some(v) = num(&joint, "MIN_LIMIT")? {
                lo = Some(lo.map_or(v, |l: f64| l.max(v)));
            }
            if let Some(v) = num(&joint, "MAX_LIMIT")? {
                hi = Some(hi.map_or(v, |h: f64| h.min(v)));
            }
        }
        let mut o = Map::new();
        let rotary = matches!(*name, "A" | "B" | "C");
        // LinuxCNC's booleans (`IniFile::convertBool`), in any case. A
        // wrapped rotary turns the way the sign of its word says
        // (`machine::wrapped`): kinpost's `wrapped` mode, whose words it
        // writes so; its travel wraps, and MIN_LIMIT / MAX_LIMIT are not
        // used.
        let mut wrapped = false;
        if let Some(e) = ini.get(&section, "WRAPPED_ROTARY") {
            match e.before_comment().to_ascii_lowercase().as_str() {
                "false" | "no" | "0" | "off" => {}
                "true" | "yes" | "1" | "on" => wrapped = rotary,
                other => {
                    return Err(ini.err(
                        e,
                        format!("WRAPPED_ROTARY `{other}` is not a boolean; expected 1 or 0 (true, yes, on; false, no, off)"),
                    ));
                }
            }
        }
        match (rotary, lo, hi) {
            (true, _, _) if wrapped => {
                o.insert("rotary".into(), "wrapped".into());
            }
            // Limits a turn-counting controller uses for "no limit".
            (true, Some(lo), Some(hi)) if hi - lo < 36_000.0 && lo <= hi => {
                o.insert("min".into(), lo.into());
                o.insert("max".into(), hi.into());
            }
            (true, _, _) => {
                o.insert("rotary".into(), "continuous".into());
            }
            (false, lo, hi) => {
                if let (Some(lo), Some(hi)) = (lo, hi)
                    && lo <= hi
                {
                    o.insert("min".into(), to_mm(lo, mm_per_unit).into());
                    o.insert("max".into(), to_mm(hi, mm_per_unit).into());
                }
            }
        }
        o.insert("decimals".into(), 4.into());
        axes.insert((*name).to_string(), Value::Object(o));
    }
    Ok(axes)
}
