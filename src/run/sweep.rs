//! Sweep expansion: the cross product of the axes, first axis slowest (a tested contract:
//! case ids name output directories), each case a full config validated before any work.

use super::CaseOutcome;
use crate::config::{located, parse_case, CaseConfig, ConfigError};
use serde_json::Value;
use std::path::Path;

/// One case of a sweep.
#[derive(Clone, Debug)]
pub struct Case {
    /// `axis-label` parts joined by `_`, or the config's name without a sweep.
    pub id: String,
    /// (axis name, value label) per axis.
    pub params: Vec<(String, String)>,
    pub config: CaseConfig,
    /// The resolved config as YAML (`case.yaml`; resume compares it).
    pub yaml: String,
}

fn set_path(v: &mut Value, path: &str, new: Value) -> Result<(), String> {
    let mut cur = v;
    for key in path.split('.') {
        cur = cur
            .as_object_mut()
            .and_then(|o| o.get_mut(key))
            .ok_or_else(|| format!("`{path}` is not a setting of the case config (no `{key}` there)"))?;
    }
    *cur = new;
    Ok(())
}

/// Line of an axis value: the first `label:` line carrying `label` after the axis' `name:`.
fn value_line(text: &str, axis: &str, label: &str) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.trim_start().trim_start_matches("- ").trim_start() == format!("name: {axis}"))?;
    let quoted = [
        format!("label: {label}"),
        format!("label: \"{label}\""),
        format!("label: '{label}'"),
    ];
    lines[start..]
        .iter()
        .position(|l| quoted.iter().any(|q| l.contains(q.as_str())))
        .map(|k| start + k + 1)
}

/// Expands a config file's text into its cases; every case is validated.
pub fn expand(text: &str, origin: &str) -> Result<(String, Vec<Case>), ConfigError> {
    let base = parse_case(text, origin)?;
    let axes = base.sweep.clone().unwrap_or_default().axes;
    let mut plain = base.clone();
    plain.sweep = None;
    let base_value = serde_json::to_value(&plain).map_err(|e| ConfigError::Io {
        file: origin.into(),
        message: e.to_string(),
    })?;
    // `at` is the line an error points to (the offending sweep value, or the base field).
    let value_err_at = |at: Option<usize>, field: String, message: String| ConfigError::Value {
        file: at.map_or_else(|| origin.to_string(), |line| format!("{origin}:{line}")),
        field,
        message,
    };
    let value_err = |field: String, message: String| ConfigError::Value {
        file: located(origin, text, "sweep"),
        field,
        message,
    };
    for (a, axis) in axes.iter().enumerate() {
        if axis.values.is_empty() {
            return Err(value_err(
                format!("sweep.axes[{a}].values"),
                "is empty; give at least one value".into(),
            ));
        }
        for (i, v) in axis.values.iter().enumerate() {
            if v.label.is_empty() || !v.label.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '.') {
                return Err(value_err(
                    format!("sweep.axes[{a}].values[{i}].label"),
                    format!("`{}`: use letters, digits, `-` and `.` only", v.label),
                ));
            }
        }
    }
    let total: usize = axes.iter().map(|a| a.values.len()).product();
    let mut cases = Vec::with_capacity(total);
    for flat in 0..total {
        // Mixed-radix digits of `flat`, last axis fastest.
        let mut rem = flat;
        let mut idx = vec![0; axes.len()];
        for (a, axis) in axes.iter().enumerate().rev() {
            idx[a] = rem % axis.values.len();
            rem /= axis.values.len();
        }
        let mut v = base_value.clone();
        let mut params = Vec::new();
        for (a, axis) in axes.iter().enumerate() {
            let value = &axis.values[idx[a]];
            for (path, new) in &value.set {
                set_path(&mut v, path, new.clone()).map_err(|m| {
                    value_err_at(
                        value_line(text, &axis.name, &value.label),
                        format!("sweep.axes[{a}].values[{}].set", idx[a]),
                        m,
                    )
                })?;
            }
            params.push((axis.name.clone(), value.label.clone()));
        }
        let field = || {
            format!(
                "sweep case {}",
                params.iter().map(|(a, l)| format!("{a}={l}")).collect::<Vec<_>>().join(", ")
            )
        };
        let config: CaseConfig = serde_json::from_value(v).map_err(|e| value_err(field(), e.to_string()))?;
        config.validate().map_err(|(f, m)| {
            // Point at the sweep value that set this field, else at the field in the base config.
            let setter = axes.iter().zip(&idx).find_map(|(axis, &i)| {
                let value = &axis.values[i];
                value
                    .set
                    .keys()
                    .any(|p| f.starts_with(p.as_str()))
                    .then(|| value_line(text, &axis.name, &value.label))
                    .flatten()
            });
            let at = setter.or_else(|| crate::config::locate_line(text, &f));
            value_err_at(at, format!("{f} (in {})", field()), m)
        })?;
        let id = if params.is_empty() {
            config.name.clone()
        } else {
            params.iter().map(|(a, l)| format!("{a}-{l}")).collect::<Vec<_>>().join("_")
        };
        let yaml = serde_saphyr::to_string(&config).map_err(|e| ConfigError::Io {
            file: origin.into(),
            message: e.to_string(),
        })?;
        cases.push(Case { id, params, config, yaml });
    }
    Ok((base.name, cases))
}

const COLUMNS: [&str; 13] = [
    "status",
    "wall_seconds",
    "equilibrium_residual",
    "omega2_min",
    "omega2_max",
    "rayleigh_alpha",
    "rayleigh_beta",
    "fold_height_ratio",
    "deploy_shape_error",
    "deploy_mirror_shape_error",
    "deploy_ke_final_over_max",
    "max_cable_stretch",
    "max_strut_compression",
];

fn figures(o: &CaseOutcome) -> Vec<String> {
    let s = o.summary.as_ref();
    let f = |v: Option<f64>| v.map(|x| format!("{x:.6e}")).unwrap_or_default();
    let eig = s.and_then(|s| s.eigen.as_ref());
    let dep = s.and_then(|s| s.deployment.as_ref());
    vec![
        o.status.to_string().replace(['"', '\n'], "'"),
        format!("{:.3}", o.wall_seconds),
        f(s.map(|s| s.substitution.residual)),
        f(eig.and_then(|e| e.omega2.first().copied())),
        f(eig.and_then(|e| e.omega2.last().copied())),
        f(eig.map(|e| e.rayleigh_alpha)),
        f(eig.map(|e| e.rayleigh_beta)),
        f(s.and_then(|s| s.folding.as_ref()).map(|f| f.height_ratio)),
        f(dep.map(|d| d.shape_error)),
        f(dep.map(|d| d.mirror_shape_error)),
        f(dep.map(|d| d.transient.final_kinetic / d.transient.max_kinetic)),
        f(dep.map(|d| d.transient.max_cable_stretch)),
        f(dep.map(|d| d.transient.max_strut_compression)),
    ]
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
    for a in axes.iter().copied().chain(COLUMNS) {
        csv.push(',');
        csv.push_str(a);
    }
    csv.push('\n');
    for o in outcomes {
        let row: Vec<String> = std::iter::once(o.id.clone())
            .chain(o.params.iter().map(|(_, l)| l.clone()))
            .chain(figures(o))
            .collect();
        csv.push_str(
            &row.iter()
                .map(|c| if c.contains(',') { format!("\"{c}\"") } else { c.clone() })
                .collect::<Vec<_>>()
                .join(","),
        );
        csv.push('\n');
    }
    let write = |name: &str, text: &str| -> std::io::Result<()> {
        let tmp = dir.join(format!(".{name}.tmp"));
        std::fs::write(&tmp, text)?;
        std::fs::rename(tmp, dir.join(name))
    };
    write("summary.csv", &csv)?;
    write(
        "summary.json",
        &serde_json::to_string_pretty(outcomes).map_err(std::io::Error::other)?,
    )
}
