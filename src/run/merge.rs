//! The merge of a sharded run (`tsim collect` on a directory with `shards/plan.json`): the
//! summaries and collected.h5 rebuilt from every case directory the plan lists, and the
//! shards' manifests checked against the plan (each case in exactly one manifest, the one
//! of its shard). A case directory's `outcome.json` is the truth: a manifest only says
//! what its shard did.

use super::shard::{fingerprint, Manifest, Plan, Planned, Shard};
use super::{collect, files, sweep, CaseOutcome, CaseStatus, Collected, RunKind};
use std::path::Path;

/// What the merge found and wrote.
#[derive(Clone, Debug)]
pub struct Merged {
    pub cases: usize,
    pub shards: usize,
    /// (case id, why) of each case not complete: failed, interrupted, or not run.
    pub not_complete: Vec<(String, String)>,
    /// Manifests missing, or not matching the plan.
    pub manifest_problems: Vec<String>,
    /// collected.h5 as written, or why not.
    pub collected: Result<Collected, String>,
}

/// Merges the sharded run directory `dir`. Err: no readable plan (nothing is written), or
/// the summaries cannot be written.
pub fn merge(dir: &Path) -> Result<Merged, String> {
    let plan = Plan::read(dir)?.ok_or_else(|| {
        format!(
            "{}: no plan; `tsim run --shard` or `tsim submit` writes one",
            Plan::path(dir).display()
        )
    })?;
    let _lock = files::RunLock::acquire(dir, files::Holder::Collect).map_err(|e| e.to_string())?;
    let outcomes: Vec<CaseOutcome> = plan.cases.iter().map(|p| on_disk(dir, p)).collect();
    let not_complete = outcomes
        .iter()
        .filter(|o| o.status != CaseStatus::Complete)
        .map(|o| {
            let shard = plan.cases.iter().find(|p| p.id == o.id).map_or(0, |p| p.shard);
            let why = o.reason.clone().unwrap_or_else(|| o.status.to_string());
            (o.id.clone(), format!("{} (shard {shard} of {})", why, plan.shards))
        })
        .collect();
    let manifest_problems = check_manifests(dir, &plan);
    sweep::write_summaries(dir, &outcomes).map_err(|e| format!("cannot write the summaries in {}: {e}", dir.display()))?;
    Ok(Merged {
        cases: outcomes.len(),
        shards: plan.shards,
        not_complete,
        manifest_problems,
        collected: collect::collect_outcomes(dir, &outcomes, collect::Verify::Trusted),
    })
}

/// How a planned case stands in its directory: its `outcome.json` when written with the
/// planned config and (complete) its outputs intact; else interrupted (started, no
/// outcome: its task was killed) or pending (not started, or another config's results).
fn on_disk(dir: &Path, p: &Planned) -> CaseOutcome {
    let case_dir = dir.join(&p.id);
    let missing = |status: CaseStatus, why: &str| CaseOutcome {
        id: p.id.clone(),
        params: p.params.clone(),
        status,
        reason: Some(why.to_string()),
        run: RunKind::NotStarted,
        wall_seconds: 0.0,
        summary: None,
        figures: None,
        files: Default::default(),
    };
    let Ok(yaml) = std::fs::read_to_string(case_dir.join("case.yaml")) else {
        return missing(CaseStatus::Pending, "not started");
    };
    if fingerprint(&yaml) != p.config {
        return missing(
            CaseStatus::Pending,
            "its directory holds another config's case (case.yaml differs); not rerun yet",
        );
    }
    let read = std::fs::read_to_string(case_dir.join("outcome.json")).ok();
    let Some(mut outcome) = read.and_then(|t| serde_json::from_str::<CaseOutcome>(&t).ok()) else {
        return missing(
            CaseStatus::Interrupted,
            "started but no outcome.json: its task was killed before the case ended",
        );
    };
    if outcome.status == CaseStatus::Complete {
        if let Some(why) = files::changed(&case_dir, &outcome.files) {
            return missing(CaseStatus::Pending, &format!("complete, but its outputs changed since: {why}"));
        }
    }
    outcome.params = p.params.clone();
    outcome
}

/// Each planned case in exactly one manifest of the plan's partition, its shard's; the
/// manifests of shards that have not ended are missing.
fn check_manifests(dir: &Path, plan: &Plan) -> Vec<String> {
    let mut problems = Vec::new();
    let mut seen = vec![0_usize; plan.cases.len()];
    let mut written = vec![false; plan.shards];
    for (index, written) in written.iter_mut().enumerate() {
        let shard = Shard { index, count: plan.shards };
        let manifest = match Manifest::read(dir, shard) {
            Ok(Some(m)) => m,
            Ok(None) => {
                problems.push(format!(
                    "shard {index} of {}: no manifest (its task has not ended, or was killed)",
                    plan.shards
                ));
                continue;
            }
            Err(e) => {
                problems.push(e);
                continue;
            }
        };
        *written = true;
        for entry in &manifest.cases {
            match plan.cases.iter().position(|p| p.id == entry.id) {
                Some(k) if plan.cases[k].shard == index => seen[k] += 1,
                Some(k) => problems.push(format!(
                    "shard {index} of {} lists `{}`, planned for shard {}",
                    plan.shards, entry.id, plan.cases[k].shard
                )),
                None => problems.push(format!("shard {index} of {} lists `{}`, not in the plan", plan.shards, entry.id)),
            }
        }
    }
    for (p, &n) in plan.cases.iter().zip(&seen) {
        if n > 1 {
            problems.push(format!("`{}` is listed {n} times by shard {}", p.id, p.shard));
        } else if n == 0 && written[p.shard] {
            problems.push(format!("`{}` is missing from the manifest of its shard {}", p.id, p.shard));
        }
    }
    problems
}
