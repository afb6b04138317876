//! The error model: fitted error splines per axis plus fixed error elements,
//! bound to a kinematic chain as a
//! [`JointErrors`](crate::machine::chain::JointErrors) source ([`BoundErrors`]).

use std::path::Path;

use nalgebra::Matrix4;
use serde::{Deserialize, Serialize};

pub use super::axis_errors::{AxisErrors, ColumnSpline, Origin};
pub use super::bound::BoundErrors;
use super::bspline::{self, BSpline, Extrapolation, KnotChoice, SplineOptions};
use super::cache::{FitCache, Hit};
use super::iso230_2::{self, Iso230_2};
use super::table::{
    Component, ErrorTable, RAD_PER_ARCSEC, angle_unit, is_rotary_axis, length_unit, parse_tables,
};
use crate::error::{Error, Location, Result};
use crate::geometric::effects::{BoundEffect, Effect, EffectSpec, StaticTerm};
use crate::machine::chain::{Chain, ErrorMotion, JointKind, error_matrix};

/// Value of the `format` field of a model JSON file.
pub const MODEL_FORMAT: &str = "kinpost-error-model";
/// Current model JSON version.
pub const MODEL_VERSION: u32 = 1;

/// Options for [`ErrorModel::fit`].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FitOptions {
    /// Interior knot count: cross-validated (default) or fixed.
    pub knots: KnotChoice,
    /// Behaviour outside the measured travel (default: hold the end value).
    pub extrapolation: Extrapolation,
}

impl FitOptions {
    /// Options with a fixed number of uniform interior knots.
    pub fn fixed_knots(n: usize) -> Self {
        FitOptions {
            knots: KnotChoice::Fixed(n),
            ..Default::default()
        }
    }

    fn spline(&self) -> SplineOptions {
        SplineOptions {
            knots: self.knots,
            extrapolation: self.extrapolation,
        }
    }
}

/// A position-independent error (squareness, axis location or orientation),
/// a fixed element of the small-angle form placed in the chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FixedError {
    /// Description, e.g. `"squareness XZ"`.
    pub name: String,
    /// Placed right after this joint's element (and its error motion); at the
    /// start of the chain (workpiece side) when `None`.
    pub after_joint: Option<String>,
    /// `[δx, δy, δz, εx, εy, εz]` in mm and rad.
    pub motion: [f64; 6],
}

impl FixedError {
    /// Returns a copy of `chain` with this error element inserted.
    pub fn apply(&self, chain: &Chain) -> Result<Chain> {
        let at = match &self.after_joint {
            None => 0,
            Some(name) => {
                let j = chain.joint_index(name).ok_or_else(|| {
                    Error::input(
                        Location::new("<error model>", 0, 0),
                        format!(
                            "fixed error `{}`: joint {name} is not in the chain (joints: {})",
                            self.name,
                            chain.joint_names()
                        ),
                    )
                })?;
                chain.joints()[j].element + 1
            }
        };
        Ok(chain.with_fixed_inserted(at, self.matrix()))
    }

    /// The small-angle error matrix of this element.
    pub fn matrix(&self) -> Matrix4<f64> {
        error_matrix(&ErrorMotion::from_column_slice(&self.motion))
    }
}

/// Where a model came from.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ModelMeta {
    /// The error-table file(s) it was fitted from, if known.
    #[serde(default)]
    pub source: Option<String>,
    /// Program and version that wrote it.
    #[serde(default)]
    pub generator: Option<String>,
    /// Free text.
    #[serde(default)]
    pub description: Option<String>,
    /// Fit options used.
    #[serde(default)]
    pub fit: Option<FitOptions>,
}

/// Fitted geometric errors of a machine.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ErrorModel {
    /// Position-dependent errors per axis.
    pub axes: Vec<AxisErrors>,
    /// Position-independent error elements, in order.
    pub fixed: Vec<FixedError>,
    /// Provenance.
    pub meta: ModelMeta,
    /// Effects found by `kinpost diagnose` (`formats.md` §4). Static ones
    /// (scale, zero offset, cyclic, squareness, rotary centre offset) act
    /// through [`ErrorModel::bind`]; the pivot length through
    /// [`ErrorModel::apply_fixed`]; dynamic ones (backlash, servo lag,
    /// thermal drift) need the motion and are applied by
    /// [`crate::diagnose::compensate_dynamic`] / [`crate::diagnose::DynamicErrors`].
    pub effects: Vec<EffectSpec>,
}

/// Fit statistics of one column. In JSON the residuals and scores carry
/// their unit in the key (`rms_residual_um` for a translation,
/// `rms_residual_urad` for a rotation, and so on), and `value_unit` names
/// the unit of the fitted values (`mm` or `rad`).
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnReport {
    /// Axis letter.
    pub axis: String,
    /// Column name (`EXX`, …).
    pub name: String,
    /// Component.
    pub component: Component,
    /// Internal unit of the values (`mm` or `rad`).
    pub unit: String,
    /// Unit of the residuals and scores below (`µm` or `µrad`).
    pub display_unit: String,
    /// Unit of the positions (`mm` or `deg`).
    pub position_unit: String,
    /// Number of samples.
    pub points: usize,
    /// Number of distinct positions.
    pub positions: usize,
    /// Measured travel `[first, last]`.
    pub range: [f64; 2],
    /// Spline degree (3 unless fewer than 4 positions).
    pub degree: usize,
    /// Number of uniform interior knots.
    pub knots: usize,
    /// `"cross-validation"` or `"fixed"`.
    pub knots_chosen_by: String,
    /// Cross-validation score of the chosen count (RMS prediction error).
    pub cv_score: Option<f64>,
    /// All cross-validation scores `(knots, score)`.
    pub cv_scores: Vec<(usize, f64)>,
    /// RMS residual.
    pub rms_residual: f64,
    /// Largest absolute residual.
    pub max_residual: f64,
    /// RMS residual in arc seconds (rotations only).
    pub rms_residual_arcsec: Option<f64>,
    /// Largest residual in arc seconds (rotations only).
    pub max_residual_arcsec: Option<f64>,
    /// Policy outside the measured travel.
    pub extrapolation: Extrapolation,
}

impl Serialize for ColumnReport {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        // `µm` → `um`, `µrad` → `urad`: the suffix of the residual keys.
        let suffix = self.display_unit.replace('µ', "u");
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("axis", &self.axis)?;
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("component", &self.component)?;
        m.serialize_entry("value_unit", &self.unit)?;
        m.serialize_entry("position_unit", &self.position_unit)?;
        m.serialize_entry("points", &self.points)?;
        m.serialize_entry("positions", &self.positions)?;
        m.serialize_entry(&format!("range_{}", self.position_unit), &self.range)?;
        m.serialize_entry("degree", &self.degree)?;
        m.serialize_entry("knots", &self.knots)?;
        m.serialize_entry("knots_chosen_by", &self.knots_chosen_by)?;
        m.serialize_entry(&format!("cv_score_{suffix}"), &self.cv_score)?;
        m.serialize_entry(&format!("cv_scores_{suffix}"), &self.cv_scores)?;
        m.serialize_entry(&format!("rms_residual_{suffix}"), &self.rms_residual)?;
        m.serialize_entry(&format!("max_residual_{suffix}"), &self.max_residual)?;
        if self.rms_residual_arcsec.is_some() {
            m.serialize_entry("rms_residual_arcsec", &self.rms_residual_arcsec)?;
            m.serialize_entry("max_residual_arcsec", &self.max_residual_arcsec)?;
        }
        m.serialize_entry("extrapolation", &self.extrapolation)?;
        m.end()
    }
}

/// What [`ErrorModel::fit`] found.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct FitReport {
    /// Per fitted column.
    pub columns: Vec<ColumnReport>,
    /// ISO 230-2 figures per axis where the positioning error was measured
    /// in both directions.
    pub iso230_2: Vec<Iso230_2>,
}

impl FitReport {
    /// A human-readable report; every number carries its unit.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        s.push_str("Least-squares cubic B-spline fit of the error tables\n");
        for c in &self.columns {
            let u = &c.display_unit;
            let arc = |v: Option<f64>| v.map_or(String::new(), |a| format!(" ({a:.3} arcsec)"));
            s.push_str(&format!(
                "  {} {:<4} {}: {} points at {} positions over {}…{} {}; degree {}, {} interior knots ({})",
                c.axis,
                c.name,
                c.component,
                c.points,
                c.positions,
                c.range[0],
                c.range[1],
                c.position_unit,
                c.degree,
                c.knots,
                c.knots_chosen_by
            ));
            if let Some(cv) = c.cv_score {
                s.push_str(&format!(", CV score {cv:.4} {u}"));
            }
            s.push_str(&format!(
                "\n      residual RMS {:.4} {u}{}, max {:.4} {u}{}; outside travel: {}\n",
                c.rms_residual,
                arc(c.rms_residual_arcsec),
                c.max_residual,
                arc(c.max_residual_arcsec),
                c.extrapolation
            ));
        }
        for iso in &self.iso230_2 {
            s.push_str(&iso.to_text());
        }
        s
    }
}

/// Whether `text` is a model JSON (first character after a byte-order mark
/// and blanks is `{`) rather than an error table.
fn is_model_json(text: &str) -> bool {
    text.trim_start_matches(['\u{feff}', ' ', '\t', '\r', '\n'])
        .starts_with('{')
}

/// Error location for a table (header line).
fn table_loc(t: &ErrorTable) -> Location {
    t.location()
}

impl ErrorModel {
    /// Fits every column of `tables` (several tables of one axis are merged;
    /// samples of the same column in two tables are fitted together).
    pub fn fit(tables: &[ErrorTable], opts: &FitOptions) -> Result<(ErrorModel, FitReport)> {
        let mut model = ErrorModel {
            meta: ModelMeta {
                source: {
                    let mut files: Vec<&str> = tables.iter().map(|t| t.file.as_str()).collect();
                    files.dedup();
                    (!files.is_empty()).then(|| files.join(", "))
                },
                generator: Some(format!("kinpost {}", env!("CARGO_PKG_VERSION"))),
                description: None,
                fit: Some(*opts),
            },
            ..Default::default()
        };
        let mut report = FitReport::default();
        // Axes in order of first appearance.
        let mut axis_names: Vec<String> = Vec::new();
        for t in tables {
            let a = t.axis.to_uppercase();
            if !axis_names.contains(&a) {
                axis_names.push(a);
            }
        }
        // Every column's samples, in order (axis, then component).
        struct ColumnData<'t> {
            axis: usize,
            comp: Component,
            name: String,
            first_table: &'t ErrorTable,
            x: Vec<f64>,
            y: Vec<f64>,
        }
        let mut data: Vec<ColumnData> = Vec::new();
        for (a, axis) in axis_names.iter().enumerate() {
            for comp in Component::ALL {
                let mut column: Option<ColumnData> = None;
                for t in tables.iter().filter(|t| t.axis.eq_ignore_ascii_case(axis)) {
                    if let Some(c) = t.column(comp) {
                        let d = column.get_or_insert_with(|| ColumnData {
                            axis: a,
                            comp,
                            name: c.name.clone(),
                            first_table: t,
                            x: Vec::new(),
                            y: Vec::new(),
                        });
                        d.x.extend_from_slice(&t.positions);
                        d.y.extend_from_slice(&c.values);
                    }
                }
                data.extend(column);
            }
        }
        // The fits are independent (cross-validation makes each one a
        // few milliseconds): one per core.
        let fits: Vec<_> = {
            use rayon::prelude::*;
            data.par_iter()
                .map(|d| bspline::fit(&d.x, &d.y, &opts.spline()))
                .collect()
        };
        let mut fitted = data.into_iter().zip(fits).peekable();
        for (a, axis) in axis_names.into_iter().enumerate() {
            let of_axis: Vec<&ErrorTable> = tables
                .iter()
                .filter(|t| t.axis.eq_ignore_ascii_case(&axis))
                .collect();
            let rotary = is_rotary_axis(&axis);
            let mut columns = Vec::new();
            while let Some((d, f)) = fitted.next_if(|(d, _)| d.axis == a) {
                let (comp, name, t0) = (d.comp, d.name, d.first_table);
                let f = f.map_err(|e| {
                    Error::input(table_loc(t0), format!("axis {axis}, column {name}: {e}"))
                })?;
                let k = comp.display_factor();
                let arcsec = (!comp.is_translation()).then_some(1.0 / RAD_PER_ARCSEC);
                let (lo, hi) = f.spline.range();
                report.columns.push(ColumnReport {
                    axis: axis.clone(),
                    name: name.clone(),
                    component: comp,
                    unit: comp.internal_unit().to_string(),
                    display_unit: comp.display_unit().to_string(),
                    position_unit: if rotary { "deg" } else { "mm" }.to_string(),
                    points: f.points,
                    positions: f.positions,
                    range: [lo, hi],
                    degree: f.spline.degree(),
                    knots: f.interior_knots,
                    knots_chosen_by: match opts.knots {
                        KnotChoice::Fixed(_) => "fixed",
                        KnotChoice::CrossValidation { .. } if f.cv.is_some() => "cross-validation",
                        KnotChoice::CrossValidation { .. } => "too few positions to cross-validate",
                    }
                    .to_string(),
                    cv_score: f.cv.as_ref().map(|c| c.score * k),
                    cv_scores: f
                        .cv
                        .as_ref()
                        .map(|c| c.scores.iter().map(|&(m, s)| (m, s * k)).collect())
                        .unwrap_or_default(),
                    rms_residual: f.rms * k,
                    max_residual: f.max * k,
                    rms_residual_arcsec: arcsec.map(|a| f.rms * a),
                    max_residual_arcsec: arcsec.map(|a| f.max * a),
                    extrapolation: opts.extrapolation,
                });
                columns.push(ColumnSpline {
                    component: comp,
                    name,
                    spline: f.spline,
                });
            }
            for t in &of_axis {
                if let Some(iso) = iso230_2::from_table(t) {
                    report.iso230_2.push(iso);
                }
            }
            let origin = Origin(
                of_axis
                    .first()
                    .map(|t| (table_loc(t), t.header_text.clone())),
            );
            model.axes.push(AxisErrors {
                axis,
                rotary,
                columns,
                origin,
            });
        }
        Ok((model, report))
    }

    /// The errors of axis `name` (case-insensitive), if modelled.
    pub fn axis(&self, name: &str) -> Option<&AxisErrors> {
        self.axes.iter().find(|a| a.axis.eq_ignore_ascii_case(name))
    }

    /// The model as JSON (see `docs/error-tables.md`).
    pub fn to_json(&self) -> serde_json::Value {
        let doc = ModelJson {
            format: MODEL_FORMAT.to_string(),
            version: MODEL_VERSION,
            meta: self.meta.clone(),
            axes: self
                .axes
                .iter()
                .map(|a| AxisJson {
                    axis: a.axis.clone(),
                    rotary: a.rotary,
                    position_unit: if a.rotary { "deg" } else { "mm" }.to_string(),
                    columns: a
                        .columns
                        .iter()
                        .map(|c| ColumnJson {
                            name: c.name.clone(),
                            component: c.component,
                            unit: c.component.internal_unit().to_string(),
                            degree: c.spline.degree(),
                            knots: c.spline.knots().to_vec(),
                            coefficients: c.spline.coefficients().to_vec(),
                            extrapolation: c.spline.extrapolation(),
                        })
                        .collect(),
                })
                .collect(),
            fixed: self.fixed.clone(),
            effects: self.effects.iter().map(|e| e.to_json(None)).collect(),
        };
        serde_json::to_value(doc).unwrap_or(serde_json::Value::Null)
    }

    /// Reads a model from JSON text; `file` is used in messages.
    pub fn from_json_str(text: &str, file: &str) -> Result<ErrorModel> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let no_axes = strict_keys(text, file)?;
        let doc: ModelJson = serde_json::from_str(text).map_err(|e| {
            Error::input(
                Location::new(file, e.line(), e.column()),
                format!("error model JSON: {e}"),
            )
        })?;
        let whole = |msg: String| Error::input(Location::new(file, 0, 0), msg);
        if doc.format != MODEL_FORMAT {
            return Err(whole(format!(
                "`format` is `{}`, expected `{MODEL_FORMAT}`",
                doc.format
            )));
        }
        if doc.version != MODEL_VERSION {
            return Err(whole(format!(
                "model version {} is not supported (this program reads version {MODEL_VERSION})",
                doc.version
            )));
        }
        if let Some(e) = no_axes {
            return Err(e);
        }
        let mut axes: Vec<AxisErrors> = Vec::new();
        for (ai, a) in doc.axes.into_iter().enumerate() {
            let axis = a.axis.trim().to_uppercase();
            let at = |needle: &str, msg: String| {
                Error::input(
                    locate(text, file, needle),
                    format!("axes[{ai}] ({axis}): {msg}"),
                )
            };
            if axis.is_empty() {
                return Err(at("\"axis\"", "empty axis name".into()));
            }
            if axes.iter().any(|b| b.axis == axis) {
                return Err(at(&a.axis, "axis given twice".into()));
            }
            // Rescale the knots to degrees / mm.
            let pos_factor = match (a.rotary, a.position_unit.as_str()) {
                (false, "mm") | (true, "deg") => 1.0,
                (false, u) => length_unit(u).ok_or_else(|| {
                    at(
                        u,
                        format!("unknown position unit `{u}` for a linear axis (mm)"),
                    )
                })?,
                (true, u) => angle_unit(u).map(|f| f.to_degrees()).ok_or_else(|| {
                    at(
                        u,
                        format!("unknown position unit `{u}` for a rotary axis (deg)"),
                    )
                })?,
            };
            let mut columns: Vec<ColumnSpline> = Vec::new();
            for (ci, c) in a.columns.into_iter().enumerate() {
                let ctx = |m: String| at(&c.name, format!("columns[{ci}] ({}): {m}", c.name));
                if columns.iter().any(|d| d.component == c.component) {
                    return Err(ctx(format!("component {} given twice", c.component)));
                }
                let vf = if c.component.is_translation() {
                    length_unit(&c.unit)
                } else {
                    angle_unit(&c.unit)
                }
                .ok_or_else(|| ctx(format!("unknown unit `{}`", c.unit)))?;
                let knots: Vec<f64> = c.knots.iter().map(|t| t * pos_factor).collect();
                let coef: Vec<f64> = c.coefficients.iter().map(|v| v * vf).collect();
                let spline = BSpline::new(c.degree, knots, coef, c.extrapolation)
                    .map_err(|e| ctx(e.to_string()))?;
                columns.push(ColumnSpline {
                    component: c.component,
                    name: c.name.to_uppercase(),
                    spline,
                });
            }
            let needle = format!("\"{}\"", a.axis);
            let loc = locate(text, file, &needle);
            let origin = Origin((loc.line > 0).then(|| {
                let line = text.lines().nth(loc.line - 1).unwrap_or("").to_string();
                (loc, line)
            }));
            axes.push(AxisErrors {
                axis,
                rotary: a.rotary,
                columns,
                origin,
            });
        }
        for f in &doc.fixed {
            if f.motion.iter().any(|v| !v.is_finite()) {
                return Err(Error::input(
                    locate(text, file, &f.name),
                    format!("fixed error `{}`: motion values must be finite", f.name),
                ));
            }
        }
        let mut effects = Vec::new();
        for (k, e) in doc.effects.iter().enumerate() {
            let spec = EffectSpec::from_json(e).map_err(|m| {
                Error::input(
                    locate(text, file, "\"effects\""),
                    format!("effects[{k}]: {m}"),
                )
            })?;
            effects.push(spec);
        }
        Ok(ErrorModel {
            axes,
            fixed: doc.fixed,
            meta: doc.meta,
            effects,
        })
    }

    /// Loads a model from a file: a model JSON (first non-blank character
    /// `{`) or an error-table CSV, fitted on the fly with default options.
    pub fn load(path: &Path) -> Result<ErrorModel> {
        let name = path.display().to_string();
        let text = crate::text::read_text_file(path)?;
        if text.trim_start_matches('\u{feff}').trim().is_empty() {
            return Err(crate::text::empty_file(
                &name,
                "an error model (JSON from `kinpost fit`) or an error table (CSV)",
            ));
        }
        if is_model_json(&text) {
            Self::from_json_str(&text, &name)
        } else {
            Self::fit_table_cached(&text, &name)
        }
    }

    /// Like [`ErrorModel::load`], from text already read (without the
    /// fitted-model cache: the text need not be a file's).
    pub fn from_str_auto(text: &str, file: &str) -> Result<ErrorModel> {
        if is_model_json(text) {
            Self::from_json_str(text, file)
        } else {
            Self::fit_table(text, file)
        }
    }

    /// The error table `text` fitted with default options.
    fn fit_table(text: &str, file: &str) -> Result<ErrorModel> {
        let tables = parse_tables(text, file)?;
        Ok(Self::fit(&tables, &FitOptions::default())?.0)
    }

    /// [`ErrorModel::fit_table`] through the fitted-model cache
    /// ([`super::cache`]): the model of an entry for these exact bytes if
    /// there is one, else the fit, stored for the next run. The cache never
    /// changes the result: an entry is used only if it reads back, and a
    /// model is stored only if its JSON reads back equal to it.
    fn fit_table_cached(text: &str, file: &str) -> Result<ErrorModel> {
        let Some(cache) = FitCache::from_env() else {
            return Self::fit_table(text, file);
        };
        let opts = FitOptions::default();
        let key = cache.key(text.as_bytes(), &format!("{opts:?}"));
        if let Some(model) = cache
            .get(&key, file)
            .and_then(|hit| Self::from_cache_hit(hit, file))
        {
            return Ok(model);
        }
        let tables = parse_tables(text, file)?;
        let model = Self::fit(&tables, &opts)?.0;
        if let Some(json) = model.json_reading_back_equal(file) {
            let origins: Vec<Origin> = model.axes.iter().map(|a| a.origin.clone()).collect();
            // Best effort: a cache that cannot be written is no cache.
            let _ = cache.put(&key, &json, &origins);
        }
        Ok(model)
    }

    /// The model of a cache entry, named after the table `file` as a fit of
    /// it would be; `None` if the entry does not make a model.
    fn from_cache_hit(hit: Hit, file: &str) -> Option<ErrorModel> {
        let mut model = Self::from_json_str(&hit.model, file).ok()?;
        if model.axes.len() != hit.origins.len() || !model.effects.is_empty() {
            return None;
        }
        for (axis, origin) in model.axes.iter_mut().zip(hit.origins) {
            axis.origin = origin;
        }
        if model.meta.source.is_some() {
            model.meta.source = Some(file.to_string());
        }
        Some(model)
    }

    /// The model's JSON, if it reads back as an equal model.
    fn json_reading_back_equal(&self, file: &str) -> Option<serde_json::Value> {
        let json = self.to_json();
        let back = Self::from_json_str(&json.to_string(), file).ok()?;
        (back == *self).then_some(json)
    }

    /// Binds the model to a chain: every modelled axis must be a joint of the
    /// chain, of the same kind (rotary axes on revolute joints).
    pub fn bind<'a>(&'a self, chain: &Chain) -> Result<BoundErrors<'a>> {
        let mut per_joint: Vec<Option<&'a AxisErrors>> = vec![None; chain.joints().len()];
        let source = self
            .meta
            .source
            .clone()
            .unwrap_or_else(|| "<error model>".into());
        for a in &self.axes {
            let j = chain.joint_index(&a.axis).ok_or_else(|| {
                a.origin.error(
                    &source,
                    format!(
                        "the error model has errors for axis {}, which is not a joint of the machine (joints: {}); expected only the machine's axes",
                        a.axis,
                        chain.joint_names()
                    ),
                )
            })?;
            let revolute = chain.joints()[j].kind == JointKind::Revolute;
            if revolute != a.rotary {
                return Err(a.origin.error(
                    &source,
                    format!(
                        "axis {} is {} in the error model but {} in the machine",
                        a.axis,
                        if a.rotary {
                            "rotary (positions in degrees)"
                        } else {
                            "linear"
                        },
                        if revolute { "revolute" } else { "prismatic" }
                    ),
                ));
            }
            if per_joint[j].is_some() {
                return Err(a.origin.error(
                    &source,
                    format!("axis {} is given twice in the error model", a.axis),
                ));
            }
            per_joint[j] = Some(a);
        }
        let mut terms = Vec::new();
        for e in &self.effects {
            if e.effect.kind().is_dynamic() {
                continue;
            }
            let b = BoundEffect::new(e, chain)?;
            if let Some(t) = StaticTerm::new(&b, chain) {
                terms.push(t);
            }
        }
        Ok(BoundErrors::new(per_joint, terms))
    }

    /// Returns `chain` with every fixed error element inserted (in order).
    pub fn apply_fixed(&self, chain: &Chain) -> Result<Chain> {
        let mut c = chain.clone();
        // Inserting in reverse keeps the listed order for elements that share
        // an anchor.
        for f in self.fixed.iter().rev() {
            c = f.apply(&c)?;
        }
        // A pivot length error is a translation along the tool axis at the tip.
        for e in &self.effects {
            if let Effect::PivotLength { delta_mm } = e.effect {
                c.translate(nalgebra::Vector3::new(0.0, 0.0, delta_mm));
            }
        }
        Ok(c)
    }
}

/// The keys a model file may hold, per object (`None`: the object's
/// content is checked elsewhere). Keys starting with `_` or `//` and keys
/// named `comment` are comments, as in machine files.
const TOP_KEYS: &[&str] = &["format", "version", "meta", "axes", "fixed", "effects"];
const META_KEYS: &[&str] = &["source", "generator", "description", "fit"];
const FIT_KEYS: &[&str] = &["knots", "extrapolation"];
const AXIS_KEYS: &[&str] = &["axis", "rotary", "position_unit", "columns"];
const COLUMN_KEYS: &[&str] = &[
    "name",
    "component",
    "unit",
    "degree",
    "knots",
    "coefficients",
    "extrapolation",
];
const FIXED_KEYS: &[&str] = &["name", "after_joint", "motion"];

/// Checks a model's JSON before it is read: no key twice in one object, no
/// unknown key (a misspelt key would otherwise be dropped silently), and an
/// `axes` list present (a model without it compensates nothing; that
/// error is returned, not raised, so that a wrong `format` or `version` is
/// reported first). Errors name file:line:col of the key.
fn strict_keys(text: &str, file: &str) -> Result<Option<Error>> {
    use crate::machine::jsonpos::{Seg, Target, first_duplicate_key, line_col, line_text};
    let Ok(value) = serde_json::from_str::<serde_json::Value>(text) else {
        // Syntax errors are reported, with their position, by the typed read.
        return Ok(None);
    };
    let at_offset = |offset: usize, msg: String| {
        let (line, col) = line_col(text, offset);
        Error::input_with(Location::new(file, line, col), msg, line_text(text, line))
    };
    if let Some((offset, k)) = first_duplicate_key(text) {
        return Err(at_offset(
            offset,
            format!(
                "duplicate key `{k}`: it is already given in this object; every key may appear once (a JSON reader would keep only the last)"
            ),
        ));
    }
    let at_path = |path: &[Seg], target: Target, msg: String| {
        at_offset(crate::machine::jsonpos::locate(text, path, target), msg)
    };
    let check = |v: &serde_json::Value, path: &[Seg], allowed: &[&str], what: &str| -> Result<()> {
        let Some(obj) = v.as_object() else {
            return Ok(());
        };
        for k in obj.keys() {
            let comment = k.starts_with('_') || k.starts_with("//") || k == "comment";
            if !comment && !allowed.contains(&k.as_str()) {
                let mut p = path.to_vec();
                p.push(Seg::Key(k.clone()));
                let known: Vec<String> = allowed.iter().map(|a| format!("`{a}`")).collect();
                return Err(at_path(
                    &p,
                    Target::Key,
                    format!(
                        "unknown key `{k}` in {what}; expected one of {}",
                        known.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    };
    let key = |k: &str| Seg::Key(k.to_string());
    check(&value, &[], TOP_KEYS, "the error model")?;
    let no_axes = (value.is_object() && value.get("axes").is_none()).then(|| {
        at_path(
            &[],
            Target::Value,
            "the error model has no `axes`: it would compensate nothing; expected `axes` (the list written by `kinpost fit`; `[]` when the model has only fixed errors or effects)".to_string(),
        )
    });
    if let Some(meta) = value.get("meta") {
        check(meta, &[key("meta")], META_KEYS, "`meta`")?;
        if let Some(fit) = meta.get("fit") {
            check(fit, &[key("meta"), key("fit")], FIT_KEYS, "`meta.fit`")?;
        }
    }
    if let Some(axes) = value.get("axes").and_then(|a| a.as_array()) {
        for (i, a) in axes.iter().enumerate() {
            let ap = [key("axes"), Seg::Index(i)];
            check(a, &ap, AXIS_KEYS, &format!("axes[{i}]"))?;
            if let Some(cols) = a.get("columns").and_then(|c| c.as_array()) {
                for (j, c) in cols.iter().enumerate() {
                    let cp = [key("axes"), Seg::Index(i), key("columns"), Seg::Index(j)];
                    check(c, &cp, COLUMN_KEYS, &format!("axes[{i}].columns[{j}]"))?;
                }
            }
        }
    }
    if let Some(fixed) = value.get("fixed").and_then(|f| f.as_array()) {
        for (i, f) in fixed.iter().enumerate() {
            check(
                f,
                &[key("fixed"), Seg::Index(i)],
                FIXED_KEYS,
                &format!("fixed[{i}]"),
            )?;
        }
    }
    Ok(no_axes)
}

/// Location of the first occurrence of `needle` in `text` (line 0 if absent).
fn locate(text: &str, file: &str, needle: &str) -> Location {
    if needle.is_empty() {
        return Location::new(file, 0, 0);
    }
    match text.find(needle) {
        Some(off) => {
            let before = &text[..off];
            let line = before.matches('\n').count() + 1;
            let col = off - before.rfind('\n').map_or(0, |i| i + 1) + 1;
            Location::new(file, line, col)
        }
        None => Location::new(file, 0, 0),
    }
}

#[derive(Serialize, Deserialize)]
struct ModelJson {
    format: String,
    version: u32,
    #[serde(default)]
    meta: ModelMeta,
    #[serde(default)]
    axes: Vec<AxisJson>,
    #[serde(default)]
    fixed: Vec<FixedError>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    effects: Vec<serde_json::Value>,
}

#[derive(Serialize, Deserialize)]
struct AxisJson {
    axis: String,
    rotary: bool,
    position_unit: String,
    columns: Vec<ColumnJson>,
}

#[derive(Serialize, Deserialize)]
struct ColumnJson {
    name: String,
    component: Component,
    unit: String,
    degree: usize,
    knots: Vec<f64>,
    coefficients: Vec<f64>,
    #[serde(default)]
    extrapolation: Extrapolation,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_finds_line_and_column() {
        let l = locate("{\n  \"a\": \"EXX\"\n}", "m.json", "\"EXX\"");
        assert_eq!((l.line, l.col), (2, 8));
    }
}
