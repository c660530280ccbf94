//! Sweep expansion: the cross product of the axes, first axis slowest (a tested contract:
//! case ids name output directories), each case a full config validated before any work.

use super::CaseOutcome;
use crate::config::{
    self, bytes_text, CaseConfig, ConfigError, Estimate, LimitSpec, Limits, Part, SharedTables, SweepAxis, TableError, TableFiles,
    ValueError,
};
use crate::output::h5::ParamValue;
use serde_json::Value;
use std::collections::HashSet;
use std::path::Path;

/// One case of a sweep.
#[derive(Clone, Debug)]
pub struct Case {
    /// `axis-label` parts joined by `_`, or the config's name without a sweep.
    pub id: String,
    /// (axis name, value label) per axis.
    pub params: Vec<(String, String)>,
    pub config: CaseConfig,
    /// Its estimated output and peak memory.
    pub estimate: Estimate,
    /// Its sweep parameters as result.h5's root attributes: `sweep.<axis>` (the label, a
    /// number when every label of the axis is one) and `set.<dotted path>` (each value set).
    pub attrs: Vec<(String, ParamValue)>,
}

impl Case {
    /// The resolved config as YAML (`case.yaml`; resume compares it), written when asked
    /// for rather than held: with a table of 10⁶ rows it has some 30 MB, in every case.
    pub fn yaml(&self) -> std::io::Result<String> {
        serde_saphyr::to_string(&self.config.recorded()).map_err(|e| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("case {}: cannot write the resolved config as YAML: {e}", self.id),
            )
        })
    }
}

/// Whether an axis' labels are all numbers: then its coordinate is numeric (in result.h5's
/// attributes and `tsim collect`).
pub fn numeric_labels<'a>(mut labels: impl Iterator<Item = &'a str>) -> bool {
    labels.all(|l| l.parse::<f64>().is_ok_and(f64::is_finite))
}

/// A label as a coordinate value: a number on a numeric axis, else the text.
pub fn label_value(label: &str, numeric: bool) -> ParamValue {
    match label.parse::<f64>() {
        Ok(x) if numeric => ParamValue::Number(x),
        _ => ParamValue::Text(label.into()),
    }
}

/// A value a sweep sets, as an attribute: numbers stay numbers, lists of numbers arrays,
/// strings text, anything else its JSON text.
fn json_value(v: &Value) -> ParamValue {
    match v {
        Value::Number(n) => n.as_f64().map_or_else(|| ParamValue::Text(n.to_string()), ParamValue::Number),
        Value::String(s) => ParamValue::Text(s.clone()),
        Value::Array(a) if !a.is_empty() && a.iter().all(Value::is_number) => {
            ParamValue::Numbers(a.iter().filter_map(Value::as_f64).collect())
        }
        other => ParamValue::Text(other.to_string()),
    }
}

fn set_path(v: &mut Value, path: &str, new: Value) -> Result<(), String> {
    let mut cur = v;
    for key in path.split('.') {
        let missing = |keys: &[&str]| {
            format!(
                "`{path}` is not a setting of the case config (no `{key}` there{})",
                crate::model::names::closest(key, keys.iter().copied()).map_or_else(String::new, |k| format!("; did you mean `{k}`?"))
            )
        };
        cur = match cur.as_object_mut() {
            Some(o) if o.contains_key(key) => o.get_mut(key).expect("the key is there"),
            Some(o) => return Err(missing(&o.keys().map(String::as_str).collect::<Vec<_>>())),
            None => return Err(missing(&[])),
        };
    }
    *cur = new;
    Ok(())
}

/// Line of an axis value: the first `label:` line carrying `label` after the axis' `name:`.
fn value_line(text: &str, axis: &str, label: &str) -> Option<usize> {
    value_lines(text, axis, label).first().copied()
}

/// The line of the `nth` axis `name: axis` (1-based; nth from 0, for axes of one name).
fn axis_line(text: &str, axis: &str, nth: usize) -> Option<usize> {
    let name = format!("name: {axis}");
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().trim_start_matches("- ").trim_start() == name)
        .nth(nth)
        .map(|(k, _)| k + 1)
}

/// Every `label:` line carrying `label` after the axis' `name:` (1-based).
fn value_lines(text: &str, axis: &str, label: &str) -> Vec<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let Some(start) = axis_line(text, axis, 0).map(|l| l - 1) else {
        return Vec::new();
    };
    let quoted = [
        format!("label: {label}"),
        format!("label: \"{label}\""),
        format!("label: '{label}'"),
    ];
    (start..lines.len())
        .filter(|&k| quoted.iter().any(|q| lines[k].contains(q.as_str())))
        .map(|k| k + 1)
        .collect()
}

/// A config file expanded: the run's name (the directory under `--out`), its cases, and
/// the limits they were checked against.
#[derive(Clone, Debug)]
pub struct Expanded {
    pub name: String,
    pub cases: Vec<Case>,
    pub limits: Limits,
}

/// Most cases one sweep may expand to: each is a validated config held in memory before
/// any runs (a sweep of 8 axes × 10 values asked for 79 GB).
pub const MAX_CASES: usize = 100_000;

/// Expands a config file's text into its cases; every case is validated, and every error
/// of the file is reported (each distinct one once, with the first case it occurs in).
/// `origin` is the file's path: time tables (CSV) are read relative to its directory.
/// The file's `limits` hold for every case and for the run's total output;
/// `allow_large` (`--allow-large`) lifts them.
pub fn expand(text: &str, origin: &str, allow_large: bool) -> Result<Expanded, ConfigError> {
    let mut base = config::parse(text, origin)?;
    let mut read = TableFiles::default();
    config::resolve_tables(&mut base, text, origin, &mut read)?;
    let axes = base.sweep.clone().unwrap_or_default().axes;
    let limits = Limits::new(&base.limits, allow_large);
    // The base must be valid on its own; cases built on a broken one would only repeat it.
    let mut errors = config::locate_errors(origin, text, base.validate_with(&limits).err().unwrap_or_default());
    errors.extend(axis_errors(&axes, origin, text));
    if !errors.is_empty() {
        return Err(ConfigError::Values(errors));
    }
    let (tables, base_value) = case_base(&base).map_err(|e| ConfigError::Io {
        file: origin.into(),
        message: e.to_string(),
    })?;
    let sweep = Sweep {
        text,
        origin,
        axes: &axes,
        limits,
        tables,
        read: std::cell::RefCell::new(read),
    };
    let total = axes.iter().fold(1_usize, |n, a| n.saturating_mul(a.values.len()));
    if total > MAX_CASES {
        return Err(ConfigError::Values(vec![ValueError {
            file: origin.into(),
            line: config::locate_line(text, "sweep"),
            field: "sweep.axes".into(),
            message: format!("the axes' cross product has {total} cases; at most {MAX_CASES} are allowed in one run"),
        }]));
    }
    let numeric: Vec<bool> = axes
        .iter()
        .map(|a| numeric_labels(a.values.iter().map(|v| v.label.as_str())))
        .collect();
    let mut cases = Vec::with_capacity(total);
    let mut seen = HashSet::new();
    // The largest output part of any case: (case index, its chosen values, the part).
    let mut largest: Option<(usize, Vec<usize>, Part)> = None;
    for flat in 0..total {
        let chosen = digits(flat, &axes);
        let params = labels(&axes, &chosen);
        match sweep.case(&chosen, &base_value) {
            Ok((config, estimate)) => {
                if largest.as_ref().is_none_or(|(_, _, p)| estimate.output_part.bytes > p.bytes) {
                    largest = Some((cases.len(), chosen.clone(), estimate.output_part.clone()));
                }
                cases.push(sweep.named(&chosen, params, config, estimate, &numeric)?);
            }
            Err(case_errors) => {
                let name = params.iter().map(|(a, l)| format!("{a}={l}")).collect::<Vec<_>>().join(", ");
                for mut e in case_errors {
                    // A bad sweep value fails every case it is in: report it once.
                    if seen.insert((e.line, e.field.clone(), e.message.clone())) {
                        e.message = format!("{} (in sweep case {name})", e.message);
                        errors.push(e);
                    }
                }
            }
        }
    }
    if let (true, Some((k, chosen, part))) = (errors.is_empty(), largest) {
        errors.extend(sweep.output_error(&cases, k, &chosen, &part));
    }
    if errors.is_empty() {
        Ok(Expanded {
            name: base.name,
            cases,
            limits,
        })
    } else {
        Err(ConfigError::Values(errors))
    }
}

/// What every case is built from: the base without its sweep and limits, as JSON, and
/// the tables left out of that copy (shared, put back into each case).
fn case_base(base: &CaseConfig) -> serde_json::Result<(SharedTables, Value)> {
    let mut plain = base.clone();
    plain.sweep = None;
    // The run's limits are not part of a case: case.yaml stays the same whatever they are.
    plain.limits = LimitSpec::default();
    let tables = plain.take_tables();
    Ok((tables, serde_json::to_value(&plain)?))
}

/// Empty axes and labels unfit for case ids.
fn axis_errors(axes: &[SweepAxis], origin: &str, text: &str) -> Vec<ValueError> {
    // The longest case id: every axis `name-label`, joined by `_` (checked once each
    // name and label is within its own bound).
    let longest: usize = axes
        .iter()
        .map(|a| a.name.len() + 1 + a.values.iter().map(|v| v.label.len()).max().unwrap_or(0))
        .sum::<usize>()
        + axes.len().saturating_sub(1);
    let within_bounds = axes
        .iter()
        .all(|a| a.name.len() <= MAX_AXIS_NAME && a.values.iter().all(|v| v.label.len() <= MAX_LABEL));
    let mut errors = Vec::new();
    let mut error = |line: Option<usize>, field: String, message: String| {
        errors.push(ValueError {
            file: origin.into(),
            line: line.or_else(|| config::locate_line(text, "sweep")),
            field,
            message,
        })
    };
    for (a, axis) in axes.iter().enumerate() {
        // The name is part of every case id, a directory under --out: no separator, no
        // `-` (it parts name from label), bounded, and one name per axis.
        let name = &axis.name;
        if name.is_empty() || name.len() > MAX_AXIS_NAME || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            error(
                axis_line(text, name, 0).filter(|_| !name.is_empty()),
                format!("sweep.axes[{a}].name"),
                format!("`{name}`: use 1–{MAX_AXIS_NAME} letters, digits and `_` (it names the case directories under --out)"),
            );
        } else if let Some(j) = axes[..a].iter().position(|b| b.name == *name) {
            let nth = axes[..a].iter().filter(|b| b.name == *name).count();
            error(
                axis_line(text, name, nth),
                format!("sweep.axes[{a}].name"),
                format!("`{name}` is also the name of sweep.axes[{j}]: each axis needs its own"),
            );
        }
        if axis.values.is_empty() {
            error(None, format!("sweep.axes[{a}].values"), "is empty; give at least one value".into());
        }
        for (i, v) in axis.values.iter().enumerate() {
            // Two values with one label would be two cases in one directory.
            if let Some(j) = axis.values[..i].iter().position(|w| w.label == v.label) {
                let lines = value_lines(text, &axis.name, &v.label);
                let at = |k: usize| lines.get(k).map_or_else(String::new, |l| format!(" (line {l})"));
                error(
                    lines.get(1).copied(),
                    format!("sweep.axes[{a}].values[{i}].label"),
                    format!(
                        "`{}` is also the label of values[{j}]{}: labels name case directories and must differ within an axis",
                        v.label,
                        at(0)
                    ),
                );
            }
            let safe = |c: char| c.is_ascii_alphanumeric() || c == '-' || c == '.';
            if v.label.is_empty() || v.label.len() > MAX_LABEL || !v.label.chars().all(safe) {
                // An empty label would match every `label:` line.
                let line = (!v.label.is_empty()).then(|| value_line(text, &axis.name, &v.label)).flatten();
                error(
                    line,
                    format!("sweep.axes[{a}].values[{i}].label"),
                    format!("`{}`: use 1–{MAX_LABEL} letters, digits, `-` and `.`", v.label),
                );
            }
        }
    }
    if within_bounds && longest > MAX_CASE_ID {
        error(
            None,
            "sweep.axes".into(),
            format!("case ids would be up to {longest} characters (`<name>-<label>` of every axis, joined by `_`); a file name holds {MAX_CASE_ID}: shorten the axis names or labels"),
        );
    }
    errors
}

/// Longest axis name and value label: together they name a case's directory.
const MAX_AXIS_NAME: usize = 32;
const MAX_LABEL: usize = 64;
/// Longest case id, a directory name: the 255 bytes of a file name on Linux and macOS
/// file systems, less room for the temporary names tsim writes beside it.
const MAX_CASE_ID: usize = 200;

/// (axis name, value label) of each axis' `chosen` value.
fn labels(axes: &[SweepAxis], chosen: &[usize]) -> Vec<(String, String)> {
    axes.iter()
        .zip(chosen)
        .map(|(a, &i)| (a.name.clone(), a.values[i].label.clone()))
        .collect()
}

/// The value index of each axis for the `flat`-th case: its mixed-radix digits, the last
/// axis fastest.
fn digits(flat: usize, axes: &[SweepAxis]) -> Vec<usize> {
    let mut rem = flat;
    let mut chosen = vec![0; axes.len()];
    for (a, axis) in axes.iter().enumerate().rev() {
        chosen[a] = rem % axis.values.len();
        rem /= axis.values.len();
    }
    chosen
}

/// The sweep of a file, for building its cases and locating their errors.
struct Sweep<'a> {
    text: &'a str,
    origin: &'a str,
    axes: &'a [SweepAxis],
    /// The run's limits, from the file's `limits` and `--allow-large`.
    limits: Limits,
    /// The base's tables, left out of its JSON copy and shared by every case.
    tables: SharedTables,
    /// The table files read, shared by the cases whose sweep values name them.
    read: std::cell::RefCell<TableFiles>,
}

impl Sweep<'_> {
    /// The case of the `chosen` values (`params`, their axes and labels) with its id,
    /// resolved YAML and the attributes its files carry (`sweep.<axis>`, `set.<path>`);
    /// `numeric`: per axis, whether its labels are numbers.
    fn named(
        &self,
        chosen: &[usize],
        params: Vec<(String, String)>,
        config: CaseConfig,
        estimate: Estimate,
        numeric: &[bool],
    ) -> Result<Case, ConfigError> {
        let id = if params.is_empty() {
            config.name.clone()
        } else {
            params.iter().map(|(a, l)| format!("{a}-{l}")).collect::<Vec<_>>().join("_")
        };
        let mut attrs: Vec<(String, ParamValue)> = params
            .iter()
            .zip(numeric)
            .map(|((axis, label), &numeric)| (format!("sweep.{axis}"), label_value(label, numeric)))
            .collect();
        for (a, &i) in chosen.iter().enumerate() {
            for (path, v) in &self.axes[a].values[i].set {
                // Two axes setting one path: the later wins, as in the case config.
                let name = format!("set.{path}");
                attrs.retain(|(n, _)| *n != name);
                attrs.push((name, json_value(v)));
            }
        }
        Ok(Case {
            id,
            params,
            config,
            estimate,
            attrs,
        })
    }

    /// The run's output over its limit, pointed at the largest part of any case (`part`
    /// of case `k`, its `chosen` values) and the sweep value or field that sets it; None
    /// within the limit.
    fn output_error(&self, cases: &[Case], k: usize, chosen: &[usize], part: &Part) -> Option<ValueError> {
        let output: f64 = cases.iter().map(|c| c.estimate.output).sum();
        if output <= self.limits.max_output {
            return None;
        }
        let line = self
            .setter_line(chosen, &part.field)
            .or_else(|| config::locate_line(self.text, &part.field))
            .or_else(|| config::locate_line(self.text, "name"));
        Some(ValueError {
            file: self.origin.into(),
            line,
            field: part.field.clone(),
            message: format!(
                "estimated output {} (uncompressed result.h5 and replay.mcap of {} case(s)) exceeds the limit of {} per run; the largest part: case `{}`, {}: {}; record fewer steps (`outputs.every`), or {}",
                bytes_text(output),
                cases.len(),
                bytes_text(self.limits.max_output),
                cases[k].id,
                part.what,
                bytes_text(part.bytes),
                Limits::remedy("max_output_gb")
            ),
        })
    }
    /// The base with the chosen value of each axis set, deserialized and validated, with
    /// its estimate. An error points at the sweep value that set its field, else at the
    /// field in the base.
    fn case(&self, chosen: &[usize], base: &Value) -> Result<(CaseConfig, Estimate), Vec<ValueError>> {
        let mut v = base.clone();
        let mut errors = Vec::new();
        for (a, &i) in chosen.iter().enumerate() {
            for (path, new) in &self.axes[a].values[i].set {
                if let Err(m) = set_path(&mut v, path, new.clone()) {
                    errors.push(self.error(self.value_line(a, i), format!("sweep.axes[{a}].values[{i}].set"), m));
                }
            }
        }
        if !errors.is_empty() {
            return Err(errors);
        }
        let mut config: CaseConfig = serde_json::from_value(v).map_err(|e| self.unreadable(chosen, base, e.to_string()))?;
        let set: Vec<&str> = chosen
            .iter()
            .enumerate()
            .flat_map(|(a, &i)| self.axes[a].values[i].set.keys().map(String::as_str))
            .collect();
        config.share_tables(&self.tables, &set);
        // A sweep value may name a table file the base does not.
        config
            .resolve_tables(config::config_dir(self.origin), &mut self.read.borrow_mut())
            .map_err(|errors| {
                errors
                    .into_iter()
                    .map(|e| match e {
                        TableError::Field(e) => {
                            let line = self
                                .setter_line(chosen, &e.field)
                                .or_else(|| config::locate_line(self.text, &e.field));
                            self.error(line, e.field, e.message)
                        }
                        TableError::Csv(e) => e,
                    })
                    .collect::<Vec<_>>()
            })?;
        let estimate = config.validate_with(&self.limits).map_err(|errors| {
            errors
                .into_iter()
                .map(|e| {
                    let line = self
                        .setter_line(chosen, &e.field)
                        .or_else(|| config::locate_line(self.text, &e.field));
                    self.error(line, e.field, e.message)
                })
                .collect::<Vec<_>>()
        })?;
        Ok((config, estimate))
    }

    /// A case that does not deserialize (a wrong type or conflicting keys): each chosen
    /// value that breaks the base on its own is named at its line, under the dotted path
    /// it sets (the first of its settings that breaks the base alone, else the value's
    /// `set`); when only their combination fails, the case is, at the `sweep` line.
    fn unreadable(&self, chosen: &[usize], base: &Value, message: String) -> Vec<ValueError> {
        let breaks = |sets: &mut dyn Iterator<Item = (&String, &Value)>| -> Option<String> {
            let mut v = base.clone();
            for (path, new) in sets {
                set_path(&mut v, path, new.clone()).ok()?;
            }
            serde_json::from_value::<CaseConfig>(v).err().map(|e| plain_serde(&e.to_string()))
        };
        let errors: Vec<ValueError> = chosen
            .iter()
            .enumerate()
            .filter_map(|(a, &i)| {
                let set = &self.axes[a].values[i].set;
                let whole = breaks(&mut set.iter())?;
                let (field, message) = set
                    .iter()
                    .find_map(|(path, new)| breaks(&mut std::iter::once((path, new))).map(|m| (path.clone(), m)))
                    .unwrap_or_else(|| (format!("sweep.axes[{a}].values[{i}].set"), whole));
                Some(self.error(self.value_line(a, i), field, message))
            })
            .collect();
        if errors.is_empty() {
            vec![self.error(config::locate_line(self.text, "sweep"), "sweep".into(), plain_serde(&message))]
        } else {
            errors
        }
    }

    /// Line of the chosen sweep value that set `field`, or a section holding it, or a key inside it.
    fn setter_line(&self, chosen: &[usize], field: &str) -> Option<usize> {
        chosen.iter().enumerate().find_map(|(a, &i)| {
            let mut paths = self.axes[a].values[i].set.keys();
            paths
                .any(|p| inside(p, field) || inside(field, p))
                .then(|| self.value_line(a, i))
                .flatten()
        })
    }

    fn value_line(&self, axis: usize, value: usize) -> Option<usize> {
        let axis = &self.axes[axis];
        value_line(self.text, &axis.name, &axis.values[value].label)
    }

    fn error(&self, line: Option<usize>, field: String, message: String) -> ValueError {
        ValueError {
            file: self.origin.into(),
            line,
            field,
            message,
        }
    }
}

/// A serde message in plain words: `invalid type: string "x", expected f64` reads
/// `is the string "x"; expected a number (f64)`.
fn plain_serde(message: &str) -> String {
    let message = message.split(" at line ").next().unwrap_or(message);
    let Some(rest) = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))
    else {
        return message.to_string();
    };
    let (found, expected) = rest.split_once(", expected ").unwrap_or((rest, "another value"));
    let expected = match expected {
        "f64" | "f32" => "a number",
        "usize" | "u64" | "u32" | "u8" => "a whole number ≥ 0",
        "i64" | "i32" => "a whole number",
        "a boolean" | "bool" => "true or false",
        e => e,
    };
    format!("is {}; expected {expected}", found.replacen("string ", "the string ", 1))
}

/// Whether the dotted path `inner` is `outer` or lies inside it (`a.b` in `a`, `a[0]` in `a`).
fn inside(outer: &str, inner: &str) -> bool {
    inner
        .strip_prefix(outer)
        .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
}

/// One value of a summary column.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    Text(String),
    /// NaN when the case has no such figure (written empty in summary.csv).
    Number(f64),
}

/// The per-case columns of `summary.csv` after `case_id` and the swept axes, with their
/// units (docs/outputs.md documents each): (name, unit).
pub const COLUMNS: [(&str, &str); 36] = [
    ("status", ""),
    ("run", ""),
    ("reason", ""),
    ("wall_s", "s"),
    ("formfinding_s", "s"),
    ("static_s", "s"),
    ("eigen_s", "s"),
    ("free_vibration_s", "s"),
    ("folding_s", "s"),
    ("deployment_s", "s"),
    ("equilibrium_residual_n", "N"),
    ("self_stress_states", "1"),
    ("mechanisms", "1"),
    ("internal_mechanisms", "1"),
    ("prestress_stable", "1"),
    ("super_stable", "1"),
    ("f1_hz", "Hz"),
    ("omega2_min_rad2_s2", "rad2 s-2"),
    ("omega2_max_rad2_s2", "rad2 s-2"),
    ("rayleigh_alpha_per_s", "s-1"),
    ("rayleigh_beta_s", "s"),
    ("free_vibration_peak_kinetic_j", "J"),
    ("free_vibration_peak_tension_n", "N"),
    ("free_vibration_peak_compression_n", "N"),
    ("fold_height_ratio", "1"),
    ("deploy_peak_kinetic_j", "J"),
    ("deploy_ke_final_over_max", "1"),
    ("deploy_peak_tension_n", "N"),
    ("deploy_peak_compression_n", "N"),
    ("deploy_max_strut_compression_n", "N"),
    ("deploy_max_cable_stretch", "1"),
    ("deploy_shape_error", "1"),
    ("deploy_mirror_shape_error", "1"),
    ("deploy_settle_time_s", "s"),
    ("min_clearance_m", "m"),
    ("clearance_events", "1"),
];

/// The values of [`COLUMNS`] for one case, in that order.
pub fn cells(o: &CaseOutcome) -> Vec<Cell> {
    let s = o.summary.as_ref();
    let f = |v: Option<f64>| Cell::Number(v.unwrap_or(f64::NAN));
    // The paper's stages, by their names (a `stages` list fills the columns of the
    // stages it names so).
    let eig = s.and_then(|s| s.eigen("eigen"));
    let free = s.and_then(|s| s.transient("free_vibration")).map(|t| &t.transient);
    let dep = s.and_then(|s| s.transient("deployment"));
    let analysis = s.map(|s| &s.structure_analysis).filter(|a| a.skipped.is_none());
    let clearance = s.and_then(|s| s.clearance.as_ref());
    // A model given with rest lengths solves its equilibrium in place of form-finding.
    let stage = |name: &str| s.and_then(|s| s.stage_seconds.get(name).copied());
    let shaping = stage("formfinding").or_else(|| stage("equilibrium"));
    vec![
        Cell::Text(o.status.to_string()),
        Cell::Text(o.run.as_str().into()),
        Cell::Text(o.reason.clone().unwrap_or_default()),
        Cell::Number(o.wall_seconds),
        f(shaping),
        f(stage("static")),
        f(stage("eigen")),
        f(stage("free_vibration")),
        f(stage("folding")),
        f(stage("deployment")),
        f(s.map(|s| s.substitution.residual)),
        // The equilibrium-matrix analysis: counts, and verdicts as 1 / 0 (empty if skipped).
        f(analysis.map(|a| a.s as f64)),
        f(analysis.map(|a| a.m as f64)),
        f(analysis.map(|a| a.m_internal as f64)),
        f(analysis.map(|a| f64::from(u8::from(a.prestress_stable)))),
        f(analysis.map(|a| f64::from(u8::from(a.super_stable)))),
        // f1 = √ω²/2π of the lowest mode (NaN when ω² < 0: unstable).
        f(eig.and_then(|e| e.omega2.first()).map(|&w2| w2.sqrt() / std::f64::consts::TAU)),
        f(eig.and_then(|e| e.omega2.first().copied())),
        f(eig.and_then(|e| e.omega2.last().copied())),
        f(eig.map(|e| e.rayleigh_alpha)),
        f(eig.map(|e| e.rayleigh_beta)),
        f(free.map(|t| t.max_kinetic)),
        f(free.map(|t| t.max_tension)),
        f(free.map(|t| t.max_compression)),
        f(s.and_then(|s| s.folding("folding")).map(|f| f.height_ratio)),
        f(dep.map(|d| d.transient.max_kinetic)),
        f(dep.map(|d| d.transient.final_kinetic / d.transient.max_kinetic)),
        f(dep.map(|d| d.transient.max_tension)),
        f(dep.map(|d| d.transient.max_compression)),
        f(dep.map(|d| d.transient.max_strut_compression)),
        f(dep.map(|d| d.transient.max_cable_stretch)),
        f(dep.and_then(|d| d.shape_error)),
        f(dep.and_then(|d| d.mirror_shape_error)),
        f(dep.and_then(|d| d.transient.settle_time)),
        f(clearance.and_then(|c| c.nearest.as_ref()).map(|n| n.clearance)),
        f(clearance.map(|c| c.event_count as f64)),
    ]
}

/// The columns of [`COLUMNS`] that count (states, mechanisms, events) or say yes (1) or
/// no (0): whole numbers, written as such.
const COUNTS: [&str; 6] = [
    "self_stress_states",
    "mechanisms",
    "internal_mechanisms",
    "prestress_stable",
    "super_stable",
    "clearance_events",
];

/// A cell as summary.csv writes it: numbers to 7 significant digits (wall times to the
/// millisecond, counts whole), NaN as empty, text with quotes and line breaks replaced.
fn csv_cell(column: usize, c: &Cell) -> String {
    match c {
        Cell::Number(x) if x.is_nan() => String::new(),
        // The wall times, `wall_s` to `deployment_s`.
        Cell::Number(x) if (3..=9).contains(&column) => format!("{x:.3}"),
        Cell::Number(x) if COUNTS.contains(&COLUMNS[column].0) => format!("{x:.0}"),
        Cell::Number(x) => format!("{x:.6e}"),
        Cell::Text(t) => t.replace(['"', '\n'], "'"),
    }
}

/// `summary.csv` (one row per case: id, swept labels, status, wall time, key figures) and
/// `summary.json` (the same outcomes with full stage summaries), each written to a
/// temporary name and renamed so a reader never sees half a table.
pub fn write_summaries(dir: &Path, outcomes: &[CaseOutcome]) -> std::io::Result<()> {
    let axes: Vec<&str> = outcomes
        .first()
        .map(|o| o.params.iter().map(|(a, _)| a.as_str()).collect())
        .unwrap_or_default();
    let mut csv = String::from("case_id");
    for a in axes.iter().copied().chain(COLUMNS.iter().map(|(name, _)| *name)) {
        csv.push(',');
        csv.push_str(a);
    }
    csv.push('\n');
    for o in outcomes {
        let row: Vec<String> = std::iter::once(o.id.clone())
            .chain(o.params.iter().map(|(_, l)| l.clone()))
            .chain(cells(o).iter().enumerate().map(|(k, c)| csv_cell(k, c)))
            .collect();
        csv.push_str(
            &row.iter()
                .map(|c| if c.contains(',') { format!("\"{c}\"") } else { c.clone() })
                .collect::<Vec<_>>()
                .join(","),
        );
        csv.push('\n');
    }
    let write = |name: &str, text: &str| super::files::write_atomic(&dir.join(name), text.as_bytes());
    write("summary.csv", &csv)?;
    write(
        "summary.json",
        &serde_json::to_string_pretty(outcomes).map_err(std::io::Error::other)?,
    )
}
