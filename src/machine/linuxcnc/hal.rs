//! The HAL files of a LinuxCNC configuration: what their commands give
//! the kinematics module's pins.

use super::ini::{Ini, resolve_ini_ref};
use crate::error::{Error, Location, Result};
use std::collections::HashMap;
use std::path::PathBuf;

/// A value given to a pin or signal, and where.
#[derive(Clone)]
pub(super) struct Given {
    pub(super) value: String,
    pub(super) loc: Location,
    pub(super) snippet: String,
    /// Order of the command over all HAL sources.
    pub(super) seq: usize,
}

/// What the HAL sources set.
#[derive(Default)]
pub(super) struct Hal {
    /// `setp PIN VALUE`.
    pub(super) pins: HashMap<String, Given>,
    /// `sets SIGNAL VALUE`.
    pub(super) signals: HashMap<String, Given>,
    /// `net SIGNAL pins…`: the signal of each pin.
    pub(super) net_of: HashMap<String, String>,
    pub(super) seq: usize,
    /// The directory halcmd runs in (the INI's): `source FILE` is relative
    /// to it.
    pub(super) dir: PathBuf,
    /// How many `source` commands the file being read is nested in.
    pub(super) depth: usize,
    /// The kinematics module's pin prefix (`xyzac-trt-kins.`): its pins
    /// start at the module's defaults, any other pin at 0.
    pub(super) module: String,
    /// Signals with a pin linked (`net`).
    pub(super) linked: std::collections::HashSet<String>,
    /// The first pin that drives each signal (after `<=`, before `=>`, or
    /// named as an output: `….out`), where it was linked.
    pub(super) writers: HashMap<String, Given>,
}

/// Whether a HAL pin name is an output by the naming HAL components use
/// (`sum2.0.out`, `mux2.0.out`, `scale.0.out`, `….out-s`).
fn output_name(pin: &str) -> bool {
    let last = pin.rsplit('.').next().unwrap_or(pin);
    last == "out"
        || last.starts_with("out-")
        || last
            .strip_prefix("out")
            .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

/// How deep HAL files may `source` each other before kinpost takes it for
/// a file that sources itself.
pub(super) const MAX_SOURCE_DEPTH: usize = 16;

impl Hal {
    /// Reads the HAL commands of `text` (`file` names it; `first_line` is
    /// the number of its first line; `col0` is added to columns).
    pub(super) fn read(
        &mut self,
        ini: &Ini,
        text: &str,
        file: &str,
        first_line: usize,
        col0: usize,
    ) -> Result<()> {
        for (n, raw) in super::ini::logical_lines(text) {
            let raw = raw.as_str();
            let code = raw.split('#').next().unwrap_or("");
            let tokens: Vec<(usize, &str)> = code
                .split_whitespace()
                .map(|t| (t.as_ptr() as usize - code.as_ptr() as usize, t))
                .collect();
            let Some(&(_, cmd)) = tokens.first() else {
                continue;
            };
            let line = first_line + n;
            let given = |i: usize, seq: usize| -> Result<Given> {
                let (at, tok) = tokens[i];
                let loc = Location::new(file, line, col0 + at + 1);
                let value = resolve_ini_ref(ini, tok).ok_or_else(|| {
                    Error::input_with(
                        loc.clone(),
                        format!("`{tok}` refers to no INI entry; expected a value or [SECTION]KEY of the INI"),
                        raw,
                    )
                })?;
                Ok(Given {
                    value,
                    loc,
                    snippet: raw.to_string(),
                    seq,
                })
            };
            match cmd {
                // `PIN = VALUE` is halcmd's `setp PIN VALUE`.
                _ if tokens.len() == 3 && tokens[1].1 == "=" => {
                    self.seq += 1;
                    let g = given(2, self.seq)?;
                    self.pins.insert(cmd.to_string(), g);
                }
                "setp" | "sets" if tokens.len() >= 3 => {
                    self.seq += 1;
                    let g = given(2, self.seq)?;
                    let target = tokens[1].1.to_string();
                    if cmd == "setp" {
                        self.pins.insert(target, g);
                    } else {
                        self.signals.insert(target, g);
                    }
                }
                "source" if tokens.len() >= 2 => {
                    let (at, name) = tokens[1];
                    let loc = Location::new(file, line, col0 + at + 1);
                    if self.depth >= MAX_SOURCE_DEPTH {
                        return Err(Error::input_with(
                            loc,
                            format!(
                                "`source {name}`: HAL files source each other more than {MAX_SOURCE_DEPTH} deep; expected files that do not source themselves"
                            ),
                            raw,
                        ));
                    }
                    let path = self.dir.join(name);
                    let text = crate::text::read_text_file(&path)?;
                    self.depth += 1;
                    let read = self.read(ini, &text, &path.display().to_string(), 1, 0);
                    self.depth -= 1;
                    read?;
                }
                "net" if tokens.len() >= 2 => {
                    let signal = tokens[1].1.to_string();
                    let arrow = |t: &str| matches!(t, "<=" | "=>" | "<=>");
                    for (k, &(at, t)) in tokens.iter().enumerate().skip(2) {
                        if arrow(t) {
                            continue;
                        }
                        self.seq += 1;
                        let here = Given {
                            value: t.to_string(),
                            loc: Location::new(file, line, col0 + at + 1),
                            snippet: raw.to_string(),
                            seq: self.seq,
                        };
                        let writes = matches!(tokens[k - 1].1, "<=" | "<=>")
                            || tokens.get(k + 1).is_some_and(|&(_, a)| a == "=>")
                            || output_name(t);
                        if writes {
                            self.writers
                                .entry(signal.clone())
                                .or_insert_with(|| here.clone());
                        }
                        // HAL's first link copies the pin's own value onto
                        // the signal (`hal_link`): a `sets` before it is
                        // lost. A pin not set starts at its default: the
                        // module's (left to the caller), 0 for any other.
                        if self.linked.insert(signal.clone()) {
                            match self.pins.get(t) {
                                Some(g) => {
                                    let g = Given {
                                        seq: self.seq,
                                        ..g.clone()
                                    };
                                    self.signals.insert(signal.clone(), g);
                                }
                                None if t.starts_with(&self.module) => {
                                    self.signals.remove(&signal);
                                }
                                None => {
                                    let zero = Given {
                                        value: "0".into(),
                                        ..here
                                    };
                                    self.signals.insert(signal.clone(), zero);
                                }
                            }
                        }
                        self.net_of.insert(t.to_string(), signal.clone());
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The last value given to `pin`, directly or through its signal.
    fn given(&self, pin: &str) -> Option<&Given> {
        let direct = self.pins.get(pin);
        let via = self.net_of.get(pin).and_then(|s| self.signals.get(s));
        match (direct, via) {
            (Some(a), Some(b)) => Some(if a.seq > b.seq { a } else { b }),
            (a, b) => a.or(b),
        }
    }

    /// [`Self::given`], refused when a pin of another component drives the
    /// signal `pin` is on: its value is whatever that component computes.
    pub(super) fn value(&self, pin: &str) -> Result<Option<&Given>> {
        if let Some((signal, w)) = self.driver(pin) {
            return Err(Error::input_with(
                w.loc.clone(),
                format!(
                    "{pin} is on signal {signal}, which `{}` drives: kinpost does not run HAL components, so it cannot know the value; give it with `setp {pin} VALUE`, or with `sets` on a signal no pin drives",
                    w.value
                ),
                w.snippet.clone(),
            ));
        }
        Ok(self.given(pin))
    }

    /// A length pin's value, `default` when nothing sets it; a pin driven by
    /// another component counts as not set (the tool offset, which
    /// `motion.tooloffset.z` drives from the tool table while the machine
    /// runs).
    pub(super) fn undriven_number(&self, pin: &str, default: f64) -> Result<f64> {
        if self.driver(pin).is_some() {
            return Ok(default);
        }
        self.number(pin, default)
    }

    /// The signal `pin` is on and the pin of another component that drives
    /// it, when one does.
    fn driver(&self, pin: &str) -> Option<(&String, &Given)> {
        let signal = self.net_of.get(pin)?;
        let w = self.writers.get(signal)?;
        (w.value != pin).then_some((signal, w))
    }

    pub(super) fn number(&self, pin: &str, default: f64) -> Result<f64> {
        match self.value(pin)? {
            None => Ok(default),
            Some(g) => match g.value.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(Error::input_with(
                    g.loc.clone(),
                    format!(
                        "`{}` for {pin} is not a number; expected a length in mm",
                        g.value
                    ),
                    g.snippet.clone(),
                )),
            },
        }
    }

    pub(super) fn flag(&self, pin: &str) -> Result<bool> {
        match self.value(pin)? {
            None => Ok(false),
            Some(g) => match g.value.to_ascii_lowercase().as_str() {
                "1" | "true" => Ok(true),
                "0" | "false" => Ok(false),
                _ => Err(Error::input_with(
                    g.loc.clone(),
                    format!("`{}` for {pin} is not a bit; expected 0 or 1", g.value),
                    g.snippet.clone(),
                )),
            },
        }
    }
}
