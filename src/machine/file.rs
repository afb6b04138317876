//! Machine files: a JSON description of one machine (its kinematic chain,
//! axis limits, rotary behaviour and output format) and the [`Machine`] type
//! built from it.
//!
//! The format is described, with a complete example, in `docs/machines.md`.
//! Files use millimetres and degrees; the [`Chain`] inside a [`Machine`] uses
//! millimetres and radians.
//!
//! Every problem found in a file is an [`Error::Input`] naming the file, line
//! and column: syntax errors at the position `serde_json` reports, semantic
//! errors (an unknown element kind, a zero axis vector, a duplicate joint,
//! ...) at the key or value concerned.

use super::axis::{AxisSpec, RotaryMode};
use super::chain::{Chain, ChainPart, Element, JointKind, JointValues, MAX_JOINTS};
use super::jsonpos::{Seg, Target, first_duplicate_key, line_col, line_text, locate};
use super::rotary::{input_value, output_value};
use crate::error::{Error, Location, Result};
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde_json::{Map, Value};
use std::path::Path;

/// A machine: its kinematic chain and how its axes are driven and written.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// Short name (e.g. `zhao2022-xzbc`).
    pub name: String,
    /// Free text: the machine, the choices made in the file.
    pub description: String,
    /// Where the machine comes from (paper, manual), if stated.
    pub source: String,
    /// The kinematic chain, workpiece to tool tip, internal units (mm, rad).
    pub chain: Chain,
    /// The axes in output order (the order words are written in a block).
    pub axes: Vec<AxisSpec>,
    /// Length of the tool whose tip the chain ends at, mm (`tool_length`;
    /// 0: the chain ends at the gauge line). A job's own tool replaces it
    /// (`crate::machine::job`).
    pub tool_length_mm: f64,
}

/// Default decimals for an axis (mm and degrees alike).
pub const DEFAULT_DECIMALS: u32 = 4;

/// Largest number of decimals accepted for an axis.
pub const MAX_DECIMALS: u32 = 12;

/// The machine files shipped inside the program (`fixtures/machines/`).
const EMBEDDED: &[(&str, &str)] = &[
    (
        "zhao2022-xzbc",
        include_str!("../../fixtures/machines/zhao2022-xzbc.json"),
    ),
    (
        "wang2023-xyzab",
        include_str!("../../fixtures/machines/wang2023-xyzab.json"),
    ),
    (
        "xyzac-trt",
        include_str!("../../fixtures/machines/xyzac-trt.json"),
    ),
    (
        "xyzbc-trt",
        include_str!("../../fixtures/machines/xyzbc-trt.json"),
    ),
    (
        "xyzac-head",
        include_str!("../../fixtures/machines/xyzac-head.json"),
    ),
    (
        "xyzbc-nutating",
        include_str!("../../fixtures/machines/xyzbc-nutating.json"),
    ),
    (
        "xyza-4axis",
        include_str!("../../fixtures/machines/xyza-4axis.json"),
    ),
    (
        "xyz-3axis",
        include_str!("../../fixtures/machines/xyz-3axis.json"),
    ),
];

/// Largest number of chain elements a machine file may have. Real machines
/// have about ten (five joints and a few offsets); the cap keeps a runaway
/// generated file from costing time before it is refused.
pub const MAX_CHAIN_ELEMENTS: usize = 256;

/// The NC addresses a joint may be named by: the axis words of ISO 6983 /
/// RS-274. Any other letter (`M`, `G`, `S`, `T`, `F`, `N`, `I`, `J`, `K`,
/// `R`, `P`, `Q`, `H`, `D`, `L`, `O`, …) would be written into the program
/// as a different word, and more than one letter or a digit would not be
/// read back as one axis word.
pub const AXIS_ADDRESSES: [&str; 9] = ["X", "Y", "Z", "U", "V", "W", "A", "B", "C"];

/// Order in which axes are written when a file gives no `output_order`.
const NC_ORDER: &str = "XYZUVWABC";

impl Machine {
    /// Parses a machine file's text. `file` names it in error messages.
    pub fn from_json_str(text: &str, file: &str) -> Result<Machine> {
        // A UTF-8 byte-order mark is accepted (docs/cli.md). It is replaced
        // by three spaces, so byte columns stay those of the file.
        let unmarked;
        let text = match text.strip_prefix('\u{feff}') {
            Some(rest) => {
                unmarked = format!("   {rest}");
                unmarked.as_str()
            }
            None => text,
        };
        let value: Value = serde_json::from_str(text).map_err(|e| {
            let line = e.line();
            // serde_json appends " at line L column C"; the location says it already.
            let what = e.to_string();
            let what = what
                .rsplit_once(" at line ")
                .map_or(what.as_str(), |(w, _)| w);
            Error::input_with(
                Location::new(file, line, e.column()),
                format!("machine file is not valid JSON: {what}"),
                line_text(text, line),
            )
        })?;
        let parser = Parser { text, file };
        if let Some((at, k)) = first_duplicate_key(text) {
            return Err(parser.err_at(
                at,
                format!(
                    "duplicate key \"{k}\": it is already given in this object; every key may appear once (a JSON reader would keep only the last)"
                ),
            ));
        }
        parser.machine(&value)
    }

    /// Reads and parses a machine file.
    pub fn load(path: &Path) -> Result<Machine> {
        let name = path.display().to_string();
        let text = crate::text::read_text_file(path)?;
        if text.trim().is_empty() {
            return Err(crate::text::empty_file(&name, "a machine file (JSON)"));
        }
        Machine::from_json_str(&text, &name)
    }

    /// The default machine: `zhao2022-xzbc` (seed 000's RTTR lens machine).
    pub fn embedded_default() -> Machine {
        Machine::embedded("zhao2022-xzbc")
            .expect("the embedded zhao2022-xzbc machine file is valid")
    }

    /// An embedded machine by name (see [`Machine::embedded_names`]).
    pub fn embedded(name: &str) -> Option<Machine> {
        let (n, text) = EMBEDDED
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))?;
        Machine::from_json_str(text, &format!("<embedded {n}>")).ok()
    }

    /// Names of the embedded machines.
    pub fn embedded_names() -> Vec<&'static str> {
        EMBEDDED.iter().map(|(n, _)| *n).collect()
    }

    /// The axis called `name` (case-insensitive).
    pub fn axis(&self, name: &str) -> Option<&AxisSpec> {
        self.axes.iter().find(|a| a.name.eq_ignore_ascii_case(name))
    }

    /// The axis driving chain joint `joint`.
    pub fn axis_of_joint(&self, joint: usize) -> Option<&AxisSpec> {
        self.axes.iter().find(|a| a.joint == joint)
    }

    /// Axis values in output order and file units (mm, degrees) → joint
    /// values in chain order and internal units (mm, rad). Missing values
    /// count as 0.
    pub fn to_internal(&self, values: &[f64]) -> JointValues {
        let mut q: JointValues = std::iter::repeat_n(0.0, self.chain.dof()).collect();
        for (k, axis) in self.axes.iter().enumerate() {
            if let Some(slot) = q.get_mut(axis.joint) {
                *slot = input_value(axis, values.get(k).copied().unwrap_or(0.0));
            }
        }
        q
    }

    /// Joint values in chain order and internal units → axis values in
    /// output order and file units, as written ([`output_value`]: modulo
    /// axes wrapped to `[0, 360)`). Missing joints count as 0.
    pub fn to_external(&self, q: &[f64]) -> JointValues {
        self.axes
            .iter()
            .map(|a| output_value(a, q.get(a.joint).copied().unwrap_or(0.0)))
            .collect()
    }

    /// The machine as a machine file (the layout of `docs/machines.md`,
    /// full precision): loading it gives the same machine back. Element
    /// transforms that rotate are written as a `translate` followed by a
    /// `rotate` (axis and angle in degrees).
    pub fn to_file_json(&self) -> Value {
        let v3 = |v: &Vector3<f64>| serde_json::json!([v.x, v.y, v.z]);
        let mut chain = Vec::new();
        for el in self.chain.elements() {
            match el {
                Element::Joint(j) => {
                    let joint = &self.chain.joints()[*j];
                    let kind = match joint.kind {
                        JointKind::Prismatic => "prismatic",
                        JointKind::Revolute => "revolute",
                    };
                    chain.push(serde_json::json!({
                        kind: {"name": joint.name, "axis": v3(&joint.axis)}
                    }));
                }
                Element::Fixed(m) => {
                    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
                    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
                    let rot = (r != Matrix3::identity())
                        .then(|| Rotation3::from_matrix_unchecked(r).axis_angle())
                        .flatten();
                    if t != Vector3::zeros() || rot.is_none() {
                        chain.push(serde_json::json!({ "translate": v3(&t) }));
                    }
                    if let Some((axis, angle)) = rot {
                        chain.push(serde_json::json!({
                            "rotate": {"axis": v3(&axis), "angle": angle.to_degrees()}
                        }));
                    }
                }
            }
        }
        let mut axes = Map::new();
        for a in &self.axes {
            let mut o = Map::new();
            if let Some(lo) = a.min {
                o.insert("min".into(), lo.into());
            }
            if let Some(hi) = a.max {
                o.insert("max".into(), hi.into());
            }
            if a.kind == JointKind::Revolute && a.rotary != RotaryMode::Limited {
                o.insert("rotary".into(), a.rotary.name().into());
            }
            o.insert("decimals".into(), a.decimals.into());
            axes.insert(a.name.clone(), Value::Object(o));
        }
        let mut file = serde_json::json!({
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "chain": chain,
            "axes": axes,
            "output_order": self.axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>(),
        });
        if self.tool_length_mm != 0.0 {
            file["tool_length"] = self.tool_length_mm.into();
        }
        file
    }

    /// One line per chain element, in file units (`revolute C axis [0, 0, -1]`).
    pub fn element_descriptions(&self) -> Vec<String> {
        let fmt_v = |v: &Vector3<f64>| format!("[{}, {}, {}]", round(v.x), round(v.y), round(v.z));
        self.chain
            .elements()
            .iter()
            .map(|el| match el {
                Element::Joint(j) => {
                    let joint = &self.chain.joints()[*j];
                    let kind = match joint.kind {
                        JointKind::Prismatic => "prismatic",
                        JointKind::Revolute => "revolute",
                    };
                    format!("{kind} {} axis {}", joint.name, fmt_v(&joint.axis))
                }
                Element::Fixed(m) => {
                    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
                    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
                    let rot = Rotation3::from_matrix_unchecked(r);
                    match rot.axis_angle() {
                        None => format!("translate {}", fmt_v(&t)),
                        Some((axis, angle)) if t.norm() == 0.0 => {
                            format!(
                                "rotate axis {} angle {}",
                                fmt_v(&axis),
                                round(angle.to_degrees())
                            )
                        }
                        Some((axis, angle)) => format!(
                            "rotate axis {} angle {}, then translate {}",
                            fmt_v(&axis),
                            round(angle.to_degrees()),
                            fmt_v(&(r.transpose() * t))
                        ),
                    }
                }
            })
            .collect()
    }
}

/// Rounds to 9 decimals for display, without negative zero.
fn round(v: f64) -> f64 {
    let r = (v * 1e9).round() / 1e9;
    if r == 0.0 { 0.0 } else { r }
}

/// Keys ignored anywhere in a machine file (comments).
fn is_comment_key(k: &str) -> bool {
    k.starts_with('_') || k.starts_with("//") || k == "comment"
}

fn path(base: &[Seg], seg: Seg) -> Vec<Seg> {
    let mut p = base.to_vec();
    p.push(seg);
    p
}

fn key(k: &str) -> Seg {
    Seg::Key(k.to_string())
}

struct Parser<'a> {
    text: &'a str,
    file: &'a str,
}

impl Parser<'_> {
    fn err(&self, at: &[Seg], target: Target, msg: impl Into<String>) -> Error {
        self.err_at(locate(self.text, at, target), msg)
    }

    fn err_at(&self, offset: usize, msg: impl Into<String>) -> Error {
        let (line, col) = line_col(self.text, offset);
        Error::input_with(
            Location::new(self.file, line, col),
            msg,
            line_text(self.text, line),
        )
    }

    fn object<'v>(&self, v: &'v Value, at: &[Seg], what: &str) -> Result<&'v Map<String, Value>> {
        v.as_object().ok_or_else(|| {
            self.err(
                at,
                Target::Value,
                format!("expected {what} (a JSON object)"),
            )
        })
    }

    fn check_keys(
        &self,
        obj: &Map<String, Value>,
        at: &[Seg],
        allowed: &[&str],
        what: &str,
    ) -> Result<()> {
        for k in obj.keys() {
            if !is_comment_key(k) && !allowed.contains(&k.as_str()) {
                return Err(self.err(
                    &path(at, key(k)),
                    Target::Key,
                    format!("unknown key \"{k}\" in {what}; expected {}", list(allowed)),
                ));
            }
        }
        Ok(())
    }

    fn required<'v>(
        &self,
        obj: &'v Map<String, Value>,
        at: &[Seg],
        k: &str,
        what: &str,
    ) -> Result<&'v Value> {
        obj.get(k)
            .ok_or_else(|| self.err(at, Target::Value, format!("{what} needs \"{k}\"")))
    }

    fn string<'v>(&self, v: &'v Value, at: &[Seg], what: &str) -> Result<&'v str> {
        v.as_str()
            .ok_or_else(|| self.err(at, Target::Value, format!("expected {what} (a string)")))
    }

    fn number(&self, v: &Value, at: &[Seg], what: &str) -> Result<f64> {
        match v.as_f64() {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(
                at,
                Target::Value,
                format!("expected {what} (a finite number)"),
            )),
        }
    }

    fn vec3(&self, v: &Value, at: &[Seg], what: &str) -> Result<Vector3<f64>> {
        let arr = v
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| self.err(at, Target::Value, format!("expected {what} as [x, y, z]")))?;
        let mut out = Vector3::zeros();
        for (i, x) in arr.iter().enumerate() {
            out[i] = self.number(x, &path(at, Seg::Index(i)), &format!("{what} component"))?;
        }
        Ok(out)
    }

    fn direction(&self, v: &Value, at: &[Seg], what: &str) -> Result<Vector3<f64>> {
        let d = self.vec3(v, at, what)?;
        let n = d.norm();
        if n.is_nan() || n <= 1e-12 || !n.is_finite() {
            return Err(self.err(
                at,
                Target::Value,
                format!("{what} is a zero vector; expected a non-zero direction [x, y, z]"),
            ));
        }
        Ok(d / n)
    }

    fn machine(&self, v: &Value) -> Result<Machine> {
        let root: Vec<Seg> = Vec::new();
        let top = self.object(v, &root, "a machine description")?;
        self.check_keys(
            top,
            &root,
            &[
                "name",
                "description",
                "source",
                "chain",
                "axes",
                "output_order",
                "tool_length",
            ],
            "the machine description",
        )?;
        let text_field = |k: &str| -> Result<String> {
            match top.get(k) {
                None => Ok(String::new()),
                Some(v) => self
                    .string(v, &[key(k)], &format!("\"{k}\""))
                    .map(str::to_string),
            }
        };
        let mut name = text_field("name")?;
        if name.is_empty() {
            name = Path::new(self.file)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "machine".to_string());
        }
        let description = text_field("description")?;
        let source = text_field("source")?;
        let tool_length_mm = match top.get("tool_length") {
            None => 0.0,
            Some(v) => self.number(v, &[key("tool_length")], "\"tool_length\" (mm)")?,
        };

        let chain_v = self.required(top, &root, "chain", "a machine description")?;
        let chain_at = vec![key("chain")];
        let elements = chain_v.as_array().ok_or_else(|| {
            self.err(
                &chain_at,
                Target::Value,
                "expected \"chain\" as an array of elements",
            )
        })?;
        if elements.is_empty() {
            return Err(self.err(
                &chain_at,
                Target::Value,
                "the chain is empty; expected at least one joint",
            ));
        }
        if elements.len() > MAX_CHAIN_ELEMENTS {
            return Err(self.err(
                &path(&chain_at, Seg::Index(MAX_CHAIN_ELEMENTS)),
                Target::Value,
                format!(
                    "the chain has {} elements; a machine file may have at most {MAX_CHAIN_ELEMENTS}",
                    elements.len()
                ),
            ));
        }
        let mut parts: Vec<ChainPart> = Vec::with_capacity(elements.len());
        // Where each joint's name is written, for messages about the joint.
        let mut joints: Vec<Vec<Seg>> = Vec::new();
        for (i, el) in elements.iter().enumerate() {
            self.element(el, &path(&chain_at, Seg::Index(i)), &mut parts, &mut joints)?;
        }
        let chain = Chain::from_parts(parts);
        if chain.dof() == 0 {
            return Err(self.err(
                &chain_at,
                Target::Value,
                "the chain has no joints; expected at least one prismatic or revolute element",
            ));
        }
        let axes = self.axes(top, &chain, &joints)?;
        Ok(Machine {
            name,
            description,
            source,
            chain,
            axes,
            tool_length_mm,
        })
    }

    fn element(
        &self,
        v: &Value,
        at: &[Seg],
        parts: &mut Vec<ChainPart>,
        joints: &mut Vec<Vec<Seg>>,
    ) -> Result<()> {
        const KINDS: [&str; 4] = ["revolute", "prismatic", "translate", "rotate"];
        let obj = self.object(
            v,
            at,
            "a chain element such as {\"revolute\": {\"name\": \"C\", \"axis\": [0, 0, 1]}}",
        )?;
        // Internally tagged: {"type": kind, ...}; externally: {kind: body}.
        let (kind, kind_at, kind_target, body, body_at, tagged) = if let Some(t) = obj.get("type") {
            let t_at = path(at, key("type"));
            let kind = self.string(t, &t_at, "the element \"type\"")?;
            (kind, t_at, Target::Value, v, at.to_vec(), true)
        } else {
            let keys: Vec<&String> = obj.keys().filter(|k| !is_comment_key(k)).collect();
            if keys.len() != 1 {
                return Err(self.err(
                    at,
                    Target::Value,
                    format!(
                        "expected a chain element with exactly one of the keys {} (or a \"type\" key)",
                        list(&KINDS)
                    ),
                ));
            }
            let k = keys[0].as_str();
            let k_at = path(at, key(k));
            (k, k_at.clone(), Target::Key, &obj[k], k_at, false)
        };
        if !KINDS.contains(&kind) {
            return Err(self.err(
                &kind_at,
                kind_target,
                format!(
                    "unknown chain element kind \"{kind}\"; expected {}",
                    list(&KINDS)
                ),
            ));
        }
        let with_type = |keys: &[&'static str]| -> Vec<&'static str> {
            let mut v = keys.to_vec();
            if tagged {
                v.push("type");
            }
            v
        };
        match kind {
            "revolute" | "prismatic" => {
                let what = format!("{kind} joint");
                let b = self.object(
                    body,
                    &body_at,
                    &format!("a {what} {{\"name\": ..., \"axis\": [x, y, z]}}"),
                )?;
                self.check_keys(
                    b,
                    &body_at,
                    &with_type(&["name", "axis"]),
                    &format!("a {what}"),
                )?;
                let name_at = path(&body_at, key("name"));
                let name = self.string(
                    self.required(b, &body_at, "name", &format!("a {what}"))?,
                    &name_at,
                    "the joint name",
                )?;
                if !AXIS_ADDRESSES.iter().any(|a| a.eq_ignore_ascii_case(name)) {
                    let word = if name.is_empty() {
                        String::new()
                    } else {
                        format!(" (the program would get words such as \"{name}-90.0000\")")
                    };
                    return Err(self.err(
                        &name_at,
                        Target::Value,
                        format!(
                            "joint name \"{name}\" is not an NC address for an axis{word}; expected one of {}",
                            list(&AXIS_ADDRESSES)
                        ),
                    ));
                }
                let existing = parts.iter().find_map(|p| match p {
                    ChainPart::Joint { name: n, .. } if n.eq_ignore_ascii_case(name) => Some(n),
                    _ => None,
                });
                if let Some(first) = existing {
                    return Err(self.err(
                        &name_at,
                        Target::Value,
                        format!(
                            "duplicate joint name \"{name}\" (the chain already has joint \"{first}\"); every joint needs its own name"
                        ),
                    ));
                }
                if joints.len() >= MAX_JOINTS {
                    return Err(self.err(
                        at,
                        Target::Value,
                        format!("too many joints; a chain may have at most {MAX_JOINTS}"),
                    ));
                }
                let axis_at = path(&body_at, key("axis"));
                let axis = self.direction(
                    self.required(b, &body_at, "axis", &format!("a {what}"))?,
                    &axis_at,
                    "the joint axis",
                )?;
                let jk = if kind == "revolute" {
                    JointKind::Revolute
                } else {
                    JointKind::Prismatic
                };
                parts.push(ChainPart::Joint {
                    name: name.to_string(),
                    kind: jk,
                    axis,
                });
                joints.push(name_at);
            }
            "translate" => {
                let (vv, vat) = if tagged {
                    let b = self.object(body, &body_at, "a translate element")?;
                    self.check_keys(b, &body_at, &with_type(&["offset"]), "a translate element")?;
                    (
                        self.required(b, &body_at, "offset", "a translate element")?,
                        path(&body_at, key("offset")),
                    )
                } else {
                    (body, body_at.clone())
                };
                let t = self.vec3(vv, &vat, "the translation (mm)")?;
                parts.push(ChainPart::Translate(t));
            }
            _ => {
                let b = self.object(
                    body,
                    &body_at,
                    "a rotate element {\"axis\": [x, y, z], \"angle\": degrees}",
                )?;
                self.check_keys(
                    b,
                    &body_at,
                    &with_type(&["axis", "angle"]),
                    "a rotate element",
                )?;
                let axis = self.direction(
                    self.required(b, &body_at, "axis", "a rotate element")?,
                    &path(&body_at, key("axis")),
                    "the rotation axis",
                )?;
                let angle = self.number(
                    self.required(b, &body_at, "angle", "a rotate element")?,
                    &path(&body_at, key("angle")),
                    "the rotation angle (degrees)",
                )?;
                parts.push(ChainPart::Rotate {
                    axis,
                    angle: angle.to_radians(),
                });
            }
        }
        Ok(())
    }

    fn axes(
        &self,
        top: &Map<String, Value>,
        chain: &Chain,
        joints: &[Vec<Seg>],
    ) -> Result<Vec<AxisSpec>> {
        let n = chain.dof();
        let mut specs: Vec<Option<AxisSpec>> = vec![None; n];
        if let Some(av) = top.get("axes") {
            let axes_at = vec![key("axes")];
            let obj = self.object(av, &axes_at, "\"axes\": an object of axis name → settings")?;
            for (name, sv) in obj {
                if is_comment_key(name) {
                    continue;
                }
                let at = path(&axes_at, key(name));
                let Some(j) = chain.joint_index(name) else {
                    return Err(self.err(
                        &at,
                        Target::Key,
                        format!(
                            "\"axes\" names \"{name}\", which is not a joint of the chain; joints are {}",
                            list(&chain.joints().iter().map(|j| j.name.as_str()).collect::<Vec<_>>())
                        ),
                    ));
                };
                if specs[j].is_some() {
                    return Err(self.err(
                        &at,
                        Target::Key,
                        format!("axis \"{name}\" is given twice in \"axes\""),
                    ));
                }
                specs[j] = Some(self.axis_spec(sv, &at, chain, j)?);
            }
        }
        // Joints without settings: linear axes get no limits; rotary axes
        // must say how they turn.
        for j in 0..n {
            if specs[j].is_none() {
                let joint = &chain.joints()[j];
                if joint.kind == JointKind::Revolute {
                    return Err(self.err(
                        &joints[j],
                        Target::Value,
                        format!(
                            "rotary axis \"{}\" has no entry in \"axes\"; expected limits (\"min\", \"max\" in degrees) or \"rotary\": \"continuous\" or \"modulo\"",
                            joint.name
                        ),
                    ));
                }
                specs[j] = Some(AxisSpec {
                    name: joint.name.clone(),
                    joint: j,
                    kind: joint.kind,
                    min: None,
                    max: None,
                    rotary: RotaryMode::Limited,
                    decimals: DEFAULT_DECIMALS,
                });
            }
        }
        let specs: Vec<AxisSpec> = specs.into_iter().flatten().collect();
        let order = self.output_order(top, chain)?;
        Ok(order.into_iter().map(|j| specs[j].clone()).collect())
    }

    fn axis_spec(&self, v: &Value, at: &[Seg], chain: &Chain, j: usize) -> Result<AxisSpec> {
        let joint = &chain.joints()[j];
        let what = format!("the settings of axis \"{}\"", joint.name);
        let obj = self.object(v, at, &what)?;
        let rotary_joint = joint.kind == JointKind::Revolute;
        let allowed: &[&str] = if rotary_joint {
            &["min", "max", "rotary", "decimals"]
        } else {
            &["min", "max", "decimals"]
        };
        self.check_keys(obj, at, allowed, &what)?;
        let unit = if rotary_joint { "degrees" } else { "mm" };
        let limit = |k: &str| -> Result<Option<f64>> {
            obj.get(k)
                .map(|x| self.number(x, &path(at, key(k)), &format!("\"{k}\" ({unit})")))
                .transpose()
        };
        let min = limit("min")?;
        let max = limit("max")?;
        if let (Some(lo), Some(hi)) = (min, max)
            && lo > hi
        {
            return Err(self.err(
                &path(at, key("min")),
                Target::Key,
                format!("axis \"{}\": min {lo} is greater than max {hi}", joint.name),
            ));
        }
        let decimals = match obj.get("decimals") {
            None => DEFAULT_DECIMALS,
            Some(d) => match d.as_u64() {
                Some(d) if d <= u64::from(MAX_DECIMALS) => d as u32,
                _ => {
                    return Err(self.err(
                        &path(at, key("decimals")),
                        Target::Value,
                        format!("expected \"decimals\" as a whole number from 0 to {MAX_DECIMALS}"),
                    ));
                }
            },
        };
        let rotary = if rotary_joint {
            let mode_at = path(at, key("rotary"));
            let mode = match obj.get("rotary") {
                None => None,
                Some(m) => Some(match self.string(m, &mode_at, "\"rotary\"")? {
                    "limited" => RotaryMode::Limited,
                    "continuous" => RotaryMode::Continuous,
                    "modulo" => RotaryMode::Modulo,
                    "wrapped" => RotaryMode::Wrapped,
                    other => {
                        return Err(self.err(
                            &mode_at,
                            Target::Value,
                            format!("unknown rotary mode \"{other}\"; expected \"limited\", \"continuous\", \"modulo\" or \"wrapped\""),
                        ));
                    }
                }),
            };
            match mode {
                None | Some(RotaryMode::Limited) => {
                    if min.is_none() || max.is_none() {
                        let (target_at, target) = if mode.is_some() {
                            (mode_at, Target::Key)
                        } else {
                            (at.to_vec(), Target::Key)
                        };
                        return Err(self.err(
                            &target_at,
                            target,
                            format!(
                                "limited rotary axis \"{}\" needs both \"min\" and \"max\" (degrees); an axis that turns freely is \"rotary\": \"continuous\" or \"modulo\"",
                                joint.name
                            ),
                        ));
                    }
                    RotaryMode::Limited
                }
                Some(m) => {
                    if let Some(k) = ["min", "max"].into_iter().find(|k| obj.contains_key(*k)) {
                        return Err(self.err(
                            &path(at, key(k)),
                            Target::Key,
                            format!(
                                "a {m} rotary axis has no travel limits (\"{}\" has \"{k}\"); use \"rotary\": \"limited\" with \"min\" and \"max\" for an axis of limited (even multi-turn) travel",
                                joint.name
                            ),
                        ));
                    }
                    m
                }
            }
        } else {
            RotaryMode::Limited
        };
        Ok(AxisSpec {
            name: joint.name.clone(),
            joint: j,
            kind: joint.kind,
            min,
            max,
            rotary,
            decimals,
        })
    }

    /// Joint indices in output order.
    fn output_order(&self, top: &Map<String, Value>, chain: &Chain) -> Result<Vec<usize>> {
        let n = chain.dof();
        let Some(ov) = top.get("output_order") else {
            let rank = |name: &str| {
                let mut c = name.chars();
                match (c.next(), c.next()) {
                    (Some(ch), None) => NC_ORDER
                        .find(ch.to_ascii_uppercase())
                        .unwrap_or(NC_ORDER.len()),
                    _ => NC_ORDER.len(),
                }
            };
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by_key(|&j| (rank(&chain.joints()[j].name), j));
            return Ok(order);
        };
        let at = vec![key("output_order")];
        let arr = ov.as_array().ok_or_else(|| {
            self.err(
                &at,
                Target::Value,
                "expected \"output_order\" as an array of axis names",
            )
        })?;
        let mut order = Vec::with_capacity(n);
        for (i, nv) in arr.iter().enumerate() {
            let el_at = path(&at, Seg::Index(i));
            let name = self.string(nv, &el_at, "an axis name")?;
            let Some(j) = chain.joint_index(name) else {
                return Err(self.err(
                    &el_at,
                    Target::Value,
                    format!(
                        "\"output_order\" names \"{name}\", which is not a joint of the chain; joints are {}",
                        list(&chain.joints().iter().map(|j| j.name.as_str()).collect::<Vec<_>>())
                    ),
                ));
            };
            if order.contains(&j) {
                return Err(self.err(
                    &el_at,
                    Target::Value,
                    format!("\"output_order\" names \"{name}\" twice"),
                ));
            }
            order.push(j);
        }
        if let Some(missing) = (0..n).find(|j| !order.contains(j)) {
            return Err(self.err(
                &at,
                Target::Key,
                format!(
                    "\"output_order\" leaves out joint \"{}\"; it must name every joint exactly once",
                    chain.joints()[missing].name
                ),
            ));
        }
        Ok(order)
    }
}

/// `"a", "b" or "c"` for messages.
fn list(items: &[&str]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("\"{s}\"")).collect();
    match quoted.len() {
        0 => String::new(),
        1 => quoted[0].clone(),
        n => format!("{} or {}", quoted[..n - 1].join(", "), quoted[n - 1]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::chain::NoErrors;

    #[test]
    fn every_embedded_machine_loads() {
        for name in Machine::embedded_names() {
            let (_, text) = EMBEDDED.iter().find(|(n, _)| *n == name).unwrap();
            let m = Machine::from_json_str(text, name).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.name, name);
            assert_eq!(m.axes.len(), m.chain.dof());
        }
        assert_eq!(Machine::embedded_default().name, "zhao2022-xzbc");
    }

    #[test]
    fn zhao_fixture_is_the_spec_chain() {
        let m = Machine::embedded_default();
        let names: Vec<_> = m.axes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["X", "Z", "B", "C"]);
        // Output order X Z B C; chain order C X Z B.
        let q = m.to_internal(&[10.0, 5.0, 30.0, 90.0]);
        assert_eq!(q[1], 10.0);
        assert!((q[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        let p = m.chain.pose(&q, &NoErrors);
        let b = 30f64.to_radians();
        // At C = 90° the point (r, 0) of the machine appears at (0, −r).
        let r = 10.0 - 20.0 * b.sin();
        assert!((p.tip - Vector3::new(0.0, -r, 5.0 - 20.0 * b.cos())).norm() < 1e-12);
        let back = m.to_external(&q);
        assert!((back[3] - 90.0).abs() < 1e-12 && (back[2] - 30.0).abs() < 1e-12);
    }

    #[test]
    fn both_element_spellings_build_the_same_chain() {
        let a = r#"{"name": "t", "chain": [
            {"revolute": {"name": "C", "axis": [0, 0, -1]}},
            {"rotate": {"axis": [1, 0, 0], "angle": 90}},
            {"prismatic": {"name": "X", "axis": [2, 0, 0]}},
            {"translate": [0, 0, -20]}],
            "axes": {"C": {"rotary": "modulo"}}}"#;
        let b = r#"{"name": "t", "chain": [
            {"type": "revolute", "name": "C", "axis": [0, 0, -1]},
            {"type": "rotate", "axis": [1, 0, 0], "angle": 90},
            {"type": "prismatic", "name": "X", "axis": [1, 0, 0], "_note": "ignored"},
            {"type": "translate", "offset": [0, 0, -20]}],
            "axes": {"C": {"rotary": "modulo"}}}"#;
        let ma = Machine::from_json_str(a, "a.json").unwrap();
        let mb = Machine::from_json_str(b, "b.json").unwrap();
        assert_eq!(ma.chain, mb.chain);
        // Default output order: X before C.
        assert_eq!(ma.axes[0].name, "X");
        assert_eq!(ma.axes[1].rotary, RotaryMode::Modulo);
    }
}
