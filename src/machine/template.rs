//! Starting machine files, one per IK family (`kinpost machine --template
//! FAMILY`), and the one-line list of the embedded machines (`kinpost
//! machine --list`).
//!
//! A template is a complete machine file that loads and is solved by the
//! family it is named after; comment keys (`"_"`) say what each element is
//! and what to change. JSON has no comments, so they are keys the loader
//! ignores (`docs/machines.md`).

use super::file::Machine;
use super::ik::IkSolver;

/// The families a template exists for, by their short names
/// ([`super::ik::Family::short_name`]), with one line on each.
pub const TEMPLATE_FAMILIES: [(&str, &str); 4] = [
    (
        "2R3T",
        "five-axis: two rotaries and X, Y, Z (table-table, head-head or table-head)",
    ),
    ("1R3T", "four-axis: X, Y, Z and one rotary (a rotary table)"),
    (
        "RTTR",
        "four-axis: a rotary spindle carrying the part, two linear axes, a tool swivel",
    ),
    ("3T", "three-axis: X, Y, Z"),
];

const TEMPLATE_2R3T: &str = r#"{
  "_": "kinpost machine file, five-axis table-table (2R3T). The chain runs from the workpiece to the tool tip; lengths in mm, angles in degrees. Keys starting with _ are comments. See docs/machines.md.",
  "name": "my-xyzac-trt",
  "description": "Trunnion tilting about X (A) carrying the rotary table C; vertical spindle.",
  "source": "",
  "chain": [
    {"_": "The rotary table turns the part by +C about +Z: written with a negated axis, because the chain starts at the part.",
     "revolute": {"name": "C", "axis": [0, 0, -1]}},
    {"_": "From the table top (workpiece origin) down to the A axis: measure it on your machine.",
     "translate": [0, 0, -60]},
    {"_": "The trunnion tilts the table by +A about +X (negated axis, as for C).",
     "revolute": {"name": "A", "axis": [-1, 0, 0]}},
    {"_": "Linear axes: the tool's motion relative to the part (ISO 841).",
     "prismatic": {"name": "X", "axis": [1, 0, 0]}},
    {"prismatic": {"name": "Y", "axis": [0, 1, 0]}},
    {"prismatic": {"name": "Z", "axis": [0, 0, 1]}},
    {"_": "Back up to the tool tip: at X = Y = Z = A = C = 0 the tip sits at the workpiece origin.",
     "translate": [0, 0, 60]}
  ],
  "axes": {
    "_": "Travel limits (mm, degrees) and decimals written per axis. A rotary axis needs limits or a rotary mode (continuous, modulo or wrapped).",
    "X": {"min": -500, "max": 500, "decimals": 4},
    "Y": {"min": -400, "max": 400, "decimals": 4},
    "Z": {"min": -400, "max": 400, "decimals": 4},
    "A": {"min": -30, "max": 110, "decimals": 4},
    "C": {"rotary": "continuous", "decimals": 4}
  },
  "output_order": ["X", "Y", "Z", "A", "C"]
}
"#;

const TEMPLATE_1R3T: &str = r#"{
  "_": "kinpost machine file, four-axis X, Y, Z + rotary table (1R3T). The chain runs from the workpiece to the tool tip; lengths in mm, angles in degrees. Keys starting with _ are comments. See docs/machines.md.",
  "name": "my-xyza",
  "description": "Three-axis mill with a rotary table turning about X (A).",
  "source": "",
  "chain": [
    {"_": "The rotary table turns the part by +A about +X: written with a negated axis, because the chain starts at the part. The workpiece origin lies on the A axis.",
     "revolute": {"name": "A", "axis": [-1, 0, 0]}},
    {"_": "Linear axes: the tool's motion relative to the part (ISO 841).",
     "prismatic": {"name": "X", "axis": [1, 0, 0]}},
    {"prismatic": {"name": "Y", "axis": [0, 1, 0]}},
    {"prismatic": {"name": "Z", "axis": [0, 0, 1]}}
  ],
  "axes": {
    "_": "Travel limits (mm, degrees) and decimals written per axis.",
    "X": {"min": -500, "max": 500, "decimals": 4},
    "Y": {"min": -200, "max": 200, "decimals": 4},
    "Z": {"min": -300, "max": 300, "decimals": 4},
    "A": {"rotary": "continuous", "decimals": 4}
  },
  "output_order": ["X", "Y", "Z", "A"]
}
"#;

const TEMPLATE_RTTR: &str = r#"{
  "_": "kinpost machine file, four-axis RTTR (part on a C spindle, tool on a B swivel carried by X and Z). The chain runs from the workpiece to the tool tip; lengths in mm, angles in degrees. Keys starting with _ are comments. See docs/machines.md.",
  "name": "my-xzbc",
  "description": "Part on the C spindle; the tool swivels about Y (B) on the X-Z slides.",
  "source": "",
  "chain": [
    {"_": "The spindle turns the part by +C about +Z: written with a negated axis, because the chain starts at the part.",
     "revolute": {"name": "C", "axis": [0, 0, -1]}},
    {"_": "Linear axes: the tool's motion relative to the part (ISO 841).",
     "prismatic": {"name": "X", "axis": [1, 0, 0]}},
    {"prismatic": {"name": "Z", "axis": [0, 0, 1]}},
    {"_": "The swivel turns the tool about +Y.",
     "revolute": {"name": "B", "axis": [0, 1, 0]}},
    {"_": "From the B axis to the tool tip (the pivot length): measure it on your machine.",
     "translate": [0, 0, -20]}
  ],
  "axes": {
    "_": "Travel limits (mm, degrees) and decimals written per axis.",
    "X": {"min": -100, "max": 100, "decimals": 4},
    "Z": {"min": -100, "max": 100, "decimals": 4},
    "B": {"min": -90, "max": 90, "decimals": 4},
    "C": {"rotary": "continuous", "decimals": 4}
  },
  "output_order": ["X", "Z", "B", "C"]
}
"#;

const TEMPLATE_3T: &str = r#"{
  "_": "kinpost machine file, three-axis (3T). The chain runs from the workpiece to the tool tip; lengths in mm. Keys starting with _ are comments. See docs/machines.md.",
  "name": "my-xyz",
  "description": "Three-axis mill.",
  "source": "",
  "chain": [
    {"_": "Linear axes: the tool's motion relative to the part (ISO 841).",
     "prismatic": {"name": "X", "axis": [1, 0, 0]}},
    {"prismatic": {"name": "Y", "axis": [0, 1, 0]}},
    {"prismatic": {"name": "Z", "axis": [0, 0, 1]}}
  ],
  "axes": {
    "_": "Travel limits (mm) and decimals written per axis.",
    "X": {"min": -500, "max": 500, "decimals": 4},
    "Y": {"min": -400, "max": 400, "decimals": 4},
    "Z": {"min": -300, "max": 300, "decimals": 4}
  },
  "output_order": ["X", "Y", "Z"]
}
"#;

/// The template machine file for `family` (a short family name, any case),
/// or `None` for a family without a template.
pub fn template(family: &str) -> Option<&'static str> {
    let text = match family.to_ascii_uppercase().as_str() {
        "2R3T" => TEMPLATE_2R3T,
        "1R3T" => TEMPLATE_1R3T,
        "RTTR" => TEMPLATE_RTTR,
        "3T" => TEMPLATE_3T,
        _ => return None,
    };
    Some(text)
}

/// One line per embedded machine: name, IK family (short name) and axes in
/// output order, e.g. `zhao2022-xzbc  RTTR  X Z B C`.
pub fn embedded_list() -> String {
    let rows: Vec<(String, &str, String)> = Machine::embedded_names()
        .into_iter()
        .filter_map(Machine::embedded)
        .map(|m| {
            let family = IkSolver::new(&m).family().short_name();
            let axes: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
            (m.name.clone(), family, axes.join(" "))
        })
        .collect();
    let w = rows.iter().map(|r| r.0.len()).max().unwrap_or(0);
    rows.iter()
        .map(|(n, f, a)| format!("{n:<w$}  {f:<7}  {a}"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_template_loads_and_is_its_family() {
        for (family, _) in TEMPLATE_FAMILIES {
            let text = template(family).unwrap();
            let m = Machine::from_json_str(text, family).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(IkSolver::new(&m).family().short_name(), family);
            assert!(template(&family.to_lowercase()).is_some());
        }
        assert!(template("5X").is_none());
    }

    #[test]
    fn the_list_has_one_line_per_embedded_machine() {
        let list = embedded_list();
        assert_eq!(list.lines().count(), Machine::embedded_names().len());
        let zhao = list
            .lines()
            .find(|l| l.starts_with("zhao2022-xzbc"))
            .unwrap();
        assert!(zhao.contains("RTTR") && zhao.ends_with("X Z B C"), "{zhao}");
    }
}
