//! `tsim collect RUN_DIR`: the cases of a run directory (as its `summary.json` lists them)
//! in one xarray-ready file, `RUN_DIR/collected.h5` (see `output::collected`). A case that
//! is not complete, or whose result.h5 is gone or unreadable, keeps its row (NaN values,
//! its status) and is listed as missing.

use super::sweep::{cells, label_value, numeric_labels, Cell, COLUMNS};
use super::{CaseOutcome, CaseStatus};
use crate::output::collected::{read_frames, read_history, read_layout, write, Collection, Column, Frames, History, Variable, MAX_FRAMES};
use crate::output::h5::ParamValue;
use crate::pipeline::StageSummary;
use std::path::{Path, PathBuf};

/// What `collect` wrote.
#[derive(Clone, Debug)]
pub struct Collected {
    pub path: PathBuf,
    pub cases: usize,
    /// (case id, why) of each case without complete results.
    pub missing: Vec<(String, String)>,
}

/// Collects `dir` (a run directory holding `summary.json`) into `dir/collected.h5`,
/// holding the run's lock while it reads: a `tsim run` re-creating a case's result.h5
/// meanwhile found it open and failed, its earlier file left truncated.
/// Err: the directory is in use by a run, or holds no readable `summary.json` (nothing is
/// written).
pub fn collect(dir: &Path) -> Result<Collected, String> {
    let _lock = super::files::RunLock::acquire(dir, super::files::Holder::Collect).map_err(|e| e.to_string())?;
    let summary = dir.join("summary.json");
    let text =
        std::fs::read_to_string(&summary).map_err(|e| format!("{}: {e} (a run directory of `tsim run` holds one)", summary.display()))?;
    let outcomes: Vec<CaseOutcome> = serde_json::from_str(&text).map_err(|e| {
        format!(
            "{}: {e} (written by an older tsim? rerun `tsim run` on its config)",
            summary.display()
        )
    })?;
    collect_outcomes(dir, &outcomes, Verify::Outputs)
}

/// Whether to check a complete case's outputs against its outcome before reading them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verify {
    /// Their lengths, signatures and checksums (`tsim collect`: they may have changed
    /// since).
    Outputs,
    /// Trusted: just written (the end of `tsim run`, which recorded them).
    Trusted,
}

/// Collects the cases `outcomes` of the run directory `dir`.
pub fn collect_outcomes(dir: &Path, outcomes: &[CaseOutcome], verify: Verify) -> Result<Collected, String> {
    let axes: Vec<String> = outcomes
        .first()
        .map(|o| o.params.iter().map(|(a, _)| a.clone()).collect())
        .unwrap_or_default();
    let mut missing = Vec::new();
    let stages = stepped_stages(outcomes);
    let histories = energy_histories(dir, outcomes, &stages, verify, &mut missing);
    let (nodes, members, frames) = stage_frames(dir, outcomes, &stages, &missing);
    let c = Collection {
        ids: outcomes.iter().map(|o| o.id.clone()).collect(),
        coords: axis_coordinates(&axes, outcomes),
        vars: summary_variables(outcomes),
        histories,
        nodes,
        members,
        frames,
        attrs: vec![
            ("tsim_version".into(), env!("CARGO_PKG_VERSION").into()),
            ("run_dir".into(), dir.display().to_string()),
            ("units".into(), "SI (m, N, kg, s)".into()),
            ("sweep_axes".into(), axes.join(" ")),
            (
                "missing".into(),
                missing
                    .iter()
                    .map(|(id, why)| format!("{id}: {why}"))
                    .collect::<Vec<_>>()
                    .join("\n"),
            ),
        ],
    };
    let path = dir.join("collected.h5");
    let partial = dir.join(".collected.h5.partial");
    write(&partial, &c).map_err(|e| format!("cannot write {}: {e}", partial.display()))?;
    std::fs::rename(&partial, &path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(Collected {
        path,
        cases: outcomes.len(),
        missing,
    })
}

/// The swept axes as coordinates: numbers when every label of the axis is one.
fn axis_coordinates(axes: &[String], outcomes: &[CaseOutcome]) -> Vec<Variable> {
    let mut coords = Vec::new();
    for (k, axis) in axes.iter().enumerate() {
        let labels: Vec<&str> = outcomes.iter().map(|o| o.params.get(k).map_or("", |(_, l)| l.as_str())).collect();
        let numeric = numeric_labels(labels.iter().copied());
        let integers: Option<Vec<i64>> = labels.iter().map(|l| l.parse().ok()).collect();
        let values = labels.iter().map(|l| label_value(l, numeric));
        // Whole-number labels stay whole, as summary.csv writes them (`steps: 4` is not 4.0).
        let values = match integers {
            Some(x) => Column::Integers(x),
            None if numeric => Column::Numbers(values.map(|v| if let ParamValue::Number(x) = v { x } else { f64::NAN }).collect()),
            None => Column::Texts(labels.iter().map(|l| l.to_string()).collect()),
        };
        coords.push(Variable {
            name: axis.clone(),
            units: "1".into(),
            long_name: format!("swept axis `{axis}` (its value labels)"),
            values,
        });
    }
    coords
}

/// The scalars of summary.csv, one variable per column.
fn summary_variables(outcomes: &[CaseOutcome]) -> Vec<Variable> {
    let rows: Vec<Vec<Cell>> = outcomes.iter().map(cells).collect();
    let mut vars = Vec::new();
    for (k, (name, unit)) in COLUMNS.iter().enumerate() {
        let values = match rows.first().map(|r| &r[k]) {
            Some(Cell::Text(_)) => Column::Texts(
                rows.iter()
                    .map(|r| match &r[k] {
                        Cell::Text(t) => t.clone(),
                        Cell::Number(x) => x.to_string(),
                    })
                    .collect(),
            ),
            _ => Column::Numbers(
                rows.iter()
                    .map(|r| match r[k] {
                        Cell::Number(x) => x,
                        Cell::Text(_) => f64::NAN,
                    })
                    .collect(),
            ),
        };
        vars.push(Variable {
            name: name.to_string(),
            units: if unit.is_empty() { "1".into() } else { unit.to_string() },
            long_name: format!("summary.csv column `{name}` (docs/outputs.md)"),
            values,
        });
    }
    vars
}

/// The stages whose histories and frames are collected: each stage with steps (static,
/// transient, folding, hold: not eigen) of any case's summary, by name, the paper's as a
/// stage list's (`push`, `rest`).
fn stepped_stages(outcomes: &[CaseOutcome]) -> Vec<String> {
    let names: std::collections::BTreeSet<&String> = outcomes
        .iter()
        .filter_map(|o| o.summary.as_ref())
        .flat_map(|s| {
            s.stages
                .iter()
                .filter(|(_, stage)| !matches!(stage, StageSummary::Eigen(_)))
                .map(|(name, _)| name)
        })
        .collect();
    names.into_iter().cloned().collect()
}

/// The node positions and member forces of `stages` at every k-th recorded step
/// ([`MAX_FRAMES`]) for every case not in `missing`, with the node and member ids they
/// share; none where the cases' models differ (their ids), or a case's file cannot be read
/// (it is in `missing` then: [`energy_histories`] read it first).
fn stage_frames(
    dir: &Path,
    outcomes: &[CaseOutcome],
    stages: &[String],
    missing: &[(String, String)],
) -> (Vec<String>, Vec<String>, Vec<Frames>) {
    let path = |o: &CaseOutcome| dir.join(&o.id).join("result.h5");
    let present: Vec<&CaseOutcome> = outcomes.iter().filter(|o| !missing.iter().any(|(id, _)| *id == o.id)).collect();
    let Ok(layouts) = present.iter().map(|o| read_layout(&path(o), stages)).collect::<Result<Vec<_>, _>>() else {
        return Default::default();
    };
    let Some((nodes, members, _)) = layouts.first() else {
        return Default::default();
    };
    if layouts.iter().any(|(n, m, _)| n != nodes || m != members) {
        return Default::default();
    }
    let mut frames = Vec::new();
    for (k, stage) in stages.iter().enumerate() {
        let longest = layouts.iter().map(|l| l.2[k]).max().unwrap_or(0);
        let stride = longest.div_ceil(MAX_FRAMES).max(1);
        let mut f = Frames {
            stage: stage.to_string(),
            time_units: "s".into(),
            stride,
            ..Default::default()
        };
        for o in outcomes {
            // A file that read for the energies and not here: the case's frames are NaN.
            let read = present
                .iter()
                .any(|p| p.id == o.id)
                .then(|| read_frames(&path(o), stage, stride).ok());
            let (time, position, force, units) = read.flatten().unwrap_or_default();
            if !time.is_empty() {
                f.time_units = units;
            }
            f.time.push(time);
            f.position.push(position);
            f.force.push(force);
        }
        frames.push(f);
    }
    (nodes.clone(), members.clone(), frames)
}

/// The energy histories of `stages` for every case, empty for a case without complete
/// results (or, verifying, whose outputs changed since), which is added to `missing`
/// with the reason.
fn energy_histories(
    dir: &Path,
    outcomes: &[CaseOutcome],
    stages: &[String],
    verify: Verify,
    missing: &mut Vec<(String, String)>,
) -> Vec<History> {
    let mut histories: Vec<History> = stages
        .iter()
        .map(|s| History {
            stage: s.to_string(),
            time_units: "s".into(),
            ..Default::default()
        })
        .collect();
    for o in outcomes {
        let mut rows = vec![(Vec::new(), Vec::new(), Vec::new()); stages.len()];
        let why = match (o.status, &o.reason) {
            (CaseStatus::Complete, _) if verify == Verify::Outputs => super::files::changed(&dir.join(&o.id), &o.files),
            (CaseStatus::Complete, _) => None,
            (CaseStatus::Failed, Some(reason)) => Some(format!("failed: {reason}")),
            (status, _) => Some(status.to_string()),
        };
        if let Some(why) = why {
            missing.push((o.id.clone(), why));
        } else {
            let path = dir.join(&o.id).join("result.h5");
            let read: Result<Vec<_>, _> = stages.iter().map(|s| read_history(&path, s)).collect();
            match read {
                Ok(read) => {
                    for ((h, row), (time, kinetic, strain, units)) in histories.iter_mut().zip(&mut rows).zip(read) {
                        if !time.is_empty() {
                            h.time_units = units;
                        }
                        *row = (time, kinetic, strain);
                    }
                }
                Err(e) if !path.exists() => missing.push((o.id.clone(), format!("{} is missing ({e})", path.display()))),
                Err(e) => missing.push((o.id.clone(), format!("{}: {e}", path.display()))),
            }
        }
        for (h, (time, kinetic, strain)) in histories.iter_mut().zip(rows) {
            h.time.push(time);
            h.kinetic.push(kinetic);
            h.strain.push(strain);
        }
    }
    histories
}
