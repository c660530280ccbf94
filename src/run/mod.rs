//! The batch runner: a config file expands to cases (a sweep's cross product), cases run
//! in parallel with rayon, each into its own directory, and a summary table collects them.
//! The only place that knows about files, threads and progress display.

mod collect;
pub mod figures;
mod files;
mod interrupt;
mod merge;
mod progress;
mod shard;
mod submit;
mod sweep;

pub use collect::{collect, Collected};
pub use files::{OutputFile, OutputFiles};
pub use interrupt::{clear_stop, install as install_interrupt, interrupted, request_stop, EXIT_INTERRUPTED};
pub use merge::{merge, Merged};
pub use progress::Progress;
pub use shard::{Plan, Shard};
pub use submit::{submit, SubmitOptions, Submitted};
pub use sweep::{expand, Case, Expanded};

use crate::config::ConfigError;
use crate::pipeline::{run_case, CaseSummary};
use crate::record::{Outcome, Recorder, Recorders};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `tsim run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub out: PathBuf,
    pub jobs: usize,
    pub force: bool,
    pub quiet: bool,
    /// Run only the cases whose id matches one of these (see [`selected`]); empty: all.
    pub only: Vec<String>,
    /// Run only this shard's cases, and write its manifest in place of the summaries.
    pub shard: Option<Shard>,
}

/// Whether case `id` matches one of `patterns`: a glob (`*`, `?`, `[...]`) matched against
/// the whole id, or else a substring of it. No pattern selects every case.
pub fn selected(id: &str, patterns: &[String]) -> bool {
    patterns.is_empty()
        || patterns.iter().any(|p| match glob::Pattern::new(p) {
            Ok(glob) if p.contains(['*', '?', '[']) => glob.matches(id),
            _ => id.contains(p.as_str()),
        })
}

/// An error naming the first of `patterns` that selects none of the cases `ids` of
/// `config`: a run or a listing would silently leave it out (a typo, an id of another
/// config), so it is refused.
pub fn require_matches(patterns: &[String], ids: &[&str], config: &Path) -> Result<(), String> {
    let Some(p) = patterns
        .iter()
        .find(|p| !ids.iter().any(|id| selected(id, std::slice::from_ref(p))))
    else {
        return Ok(());
    };
    let hint = crate::model::names::hint(p, ids.iter().copied());
    let example = ids.first().map_or_else(String::new, |id| format!(", such as `{id}`"));
    Err(format!(
        "`--only {p}` matches none of the {} case(s) of {}{hint}; `tsim check {}` lists their ids{example}",
        ids.len(),
        config.display(),
        config.display()
    ))
}

/// Where a case stands on disk before a run, as `tsim check` lists it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnDisk {
    /// Nothing written yet.
    New,
    /// Complete with this config, outputs intact: a run reuses it.
    Complete,
    /// Written with another config (its `case.yaml` differs): a run redoes it.
    Changed,
    /// Started with this config but not complete (failed, interrupted, or outputs gone).
    Incomplete,
}

impl OnDisk {
    pub fn of(case: &Case, dir: &Path) -> Self {
        match std::fs::read_to_string(dir.join("case.yaml")) {
            Err(_) => OnDisk::New,
            Ok(yaml) if !same_config(case, &yaml) => OnDisk::Changed,
            Ok(_) if complete_outputs(case, dir).is_some() => OnDisk::Complete,
            Ok(_) => OnDisk::Incomplete,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            OnDisk::New => "new",
            OnDisk::Complete => "complete",
            OnDisk::Changed => "changed",
            OnDisk::Incomplete => "incomplete",
        }
    }
}

/// How one case stands at the end of this run: one of a fixed set of words, whatever the
/// run did to it (`CaseOutcome::run` says that).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseStatus {
    /// Every stage finished (in this run or, reused, in an earlier one).
    Complete,
    /// A stage failed (or its outputs could not be written); the reason is beside it.
    Failed,
    /// Stopped, or not started, because a signal asked the run to stop.
    Interrupted,
    /// Not complete and left out of this run by `--only` (its directory as an earlier run
    /// left it).
    Pending,
}

impl CaseStatus {
    /// "complete", "failed", "interrupted" or "pending": the `status` column of the
    /// summaries.
    pub fn as_str(self) -> &'static str {
        match self {
            CaseStatus::Complete => "complete",
            CaseStatus::Failed => "failed",
            CaseStatus::Interrupted => "interrupted",
            CaseStatus::Pending => "pending",
        }
    }
}

impl std::fmt::Display for CaseStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What this run did with a case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunKind {
    /// Run now (to its end, a failure or an interruption).
    Computed,
    /// Complete from an earlier run with the same resolved config, outputs verified; not rerun.
    Reused,
    /// Not started: the run was interrupted first, or `--only` left it out (the directory
    /// is as an earlier run left it).
    NotStarted,
}

impl RunKind {
    /// "computed", "reused" or "not_started": the `run` column of the summaries.
    pub fn as_str(self) -> &'static str {
        match self {
            RunKind::Computed => "computed",
            RunKind::Reused => "reused",
            RunKind::NotStarted => "not_started",
        }
    }
}

/// How one case ended.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CaseOutcome {
    pub id: String,
    pub params: Vec<(String, String)>,
    pub status: CaseStatus,
    /// Why it failed (status `failed` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    pub run: RunKind,
    pub wall_seconds: f64,
    #[serde(default)]
    pub summary: Option<CaseSummary>,
    /// With `outputs.figures`: "written to <dir>" or why not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub figures: Option<String>,
    /// The output files of a complete case, their lengths and checksums: a resume and
    /// `tsim collect` check them before they trust the case.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub files: files::OutputFiles,
}

impl CaseOutcome {
    pub fn failed(&self) -> bool {
        self.status == CaseStatus::Failed
    }

    /// The progress line's word for it: "complete", "skipped (complete)" (reused),
    /// "failed: <reason>" or "interrupted"; a computed case's figures, where they went.
    pub fn describe(&self) -> String {
        let figures = self.figures.as_ref().map_or_else(String::new, |f| format!("; figures {f}"));
        match (self.status, self.run, &self.reason) {
            (CaseStatus::Complete, RunKind::Reused, _) => "skipped (complete)".into(),
            (CaseStatus::Failed, _, Some(reason)) => format!("failed: {reason}"),
            (status, _, _) => format!("{status}{figures}"),
        }
    }
}

/// Default worker count: `SLURM_CPUS_PER_TASK` when set (a Slurm task sees every core of
/// the node but owns only these), else `SLURM_CPUS_ON_NODE` (a job's CPUs on this node,
/// set when `--cpus-per-task` was not given), else the available cores.
pub fn default_jobs() -> usize {
    let slurm = |name: &str| std::env::var(name).ok().and_then(|v| v.parse().ok()).filter(|&n: &usize| n > 0);
    slurm("SLURM_CPUS_PER_TASK")
        .or_else(|| slurm("SLURM_CPUS_ON_NODE"))
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Reads, expands and validates a config file: everything that can fail before work.
/// `allow_large` lifts the limits on estimated output, memory and steps.
pub fn load(path: &Path, allow_large: bool) -> Result<Expanded, ConfigError> {
    let origin = path.display().to_string();
    let io = |message: String| ConfigError::Io {
        file: origin.clone(),
        message,
    };
    let bytes = crate::config::read_input(path).map_err(io)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
        io(format!("line {line}, byte {at}: not UTF-8 text; save the file as UTF-8"))
    })?;
    expand(&text, &origin, allow_large)
}

/// Runs every case of a sweep (or of its shard) into `out/<name>/<case id>/`, then
/// writes `summary.csv` and `summary.json` (a shard: its manifest, the merge writes the
/// summaries). A failing case is recorded with its reason; the rest go on.
pub fn run(name: &str, cases: &[Case], opts: &RunOptions) -> std::io::Result<Vec<CaseOutcome>> {
    let dir = opts.out.join(name);
    std::fs::create_dir_all(&dir)?;
    let Some(shard) = opts.shard else {
        let _lock = files::RunLock::acquire(&dir, files::Holder::Run)?;
        let outcomes = run_cases(&dir, &cases.iter().collect::<Vec<_>>(), opts)?;
        sweep::write_summaries(&dir, &outcomes)?;
        // The cases in one xarray-ready file: cheap (each case's energies only); a failure
        // here loses nothing (`tsim collect` writes it again).
        if let Err(e) = collect::collect_outcomes(&dir, &outcomes, collect::Verify::Trusted) {
            eprintln!("warning: {e}");
        }
        return Ok(outcomes);
    };
    let _lock = files::RunLock::shard(&dir, shard.index, shard.count)?;
    // Written first, so that the merge knows every case even if every shard is killed.
    let plan = Plan::new(cases, shard.count)?;
    plan.write(&dir)?;
    let mine: Vec<&Case> = cases
        .iter()
        .zip(&plan.cases)
        .filter(|(_, p)| p.shard == shard.index)
        .map(|(c, _)| c)
        .collect();
    eprintln!("shard {} of {}: {} of {} cases", shard.index, shard.count, mine.len(), cases.len());
    let outcomes = run_cases(&dir, &mine, opts)?;
    shard::Manifest::write(&dir, shard, &outcomes)?;
    Ok(outcomes)
}

/// Runs `cases` in the run directory `dir`, reusing the complete ones (not with `--force`).
fn run_cases(dir: &Path, cases: &[&Case], opts: &RunOptions) -> std::io::Result<Vec<CaseOutcome>> {
    files::keep_tables(dir, cases)?;
    // Complete cases are reused, reported in one line rather than one each.
    let reused: Vec<Option<CaseOutcome>> = cases
        .iter()
        .map(|case| (!opts.force).then(|| already_complete(case, &dir.join(&case.id))).flatten())
        .collect();
    let count = reused.iter().flatten().count();
    if count > 0 {
        eprintln!(
            "{count} complete case{} reused (same config, outputs intact); --force reruns them",
            if count == 1 { "" } else { "s" }
        );
    }
    let to_run = cases
        .iter()
        .zip(&reused)
        .filter(|(c, done)| done.is_none() && selected(&c.id, &opts.only))
        .count();
    let progress = Progress::new(to_run, opts.quiet);
    let pool = rayon::ThreadPoolBuilder::new()
        // No more workers than cases to run: each is a thread (and `--jobs 100000` was
        // 100 000 of them before any work).
        .num_threads(opts.jobs.clamp(1, to_run.max(1)))
        .build()
        .map_err(std::io::Error::other)?;
    // Output writer threads only when a core is left over for them.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let background = opts.jobs.max(1).min(cases.len()) < cores;
    let outcomes: Vec<CaseOutcome> = pool.install(|| {
        cases
            .par_iter()
            .zip(reused)
            .map(|(case, done)| {
                done.unwrap_or_else(|| match selected(&case.id, &opts.only) {
                    true => run_one(case, &dir.join(&case.id), background, &progress),
                    false => not_started(case, CaseStatus::Pending),
                })
            })
            .collect()
    });
    progress.finish();
    Ok(outcomes)
}

/// A case is complete on disk when its `outcome.json` (written last, after the outputs
/// are closed) says so, its `case.yaml` is the same resolved config, and its output files
/// are still the ones the outcome recorded (same lengths, format signatures and CRC-32).
/// An outcome that lists no files or no checksums (written by an earlier tsim) cannot be
/// checked: rerun.
fn already_complete(case: &Case, dir: &Path) -> Option<CaseOutcome> {
    let yaml = std::fs::read_to_string(dir.join("case.yaml")).ok()?;
    same_config(case, &yaml).then(|| complete_outputs(case, dir)).flatten()
}

/// Whether `yaml`, a case.yaml on disk, is the case's resolved config.
fn same_config(case: &Case, yaml: &str) -> bool {
    case.yaml().is_ok_and(|own| own == yaml)
}

/// The case's outcome when its `outcome.json` says complete and its outputs are the files
/// it recorded.
fn complete_outputs(case: &Case, dir: &Path) -> Option<CaseOutcome> {
    let outcome: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("outcome.json")).ok()?).ok()?;
    let recorded: files::OutputFiles = serde_json::from_value(outcome["files"].clone()).ok()?;
    let expected = usize::from(case.config.outputs.hdf5) + usize::from(case.config.outputs.mcap);
    if outcome["status"] != "complete" || recorded.len() != expected || files::changed(dir, &recorded).is_some() {
        return None;
    }
    Some(CaseOutcome {
        id: case.id.clone(),
        params: case.params.clone(),
        status: CaseStatus::Complete,
        reason: None,
        run: RunKind::Reused,
        wall_seconds: outcome["wall_seconds"].as_f64().unwrap_or_default(),
        summary: serde_json::from_value(outcome["summary"].clone()).ok(),
        figures: outcome["figures"].as_str().map(str::to_string),
        files: recorded,
    })
}

/// A case this run does not start: its directory is left as an earlier run left it.
fn not_started(case: &Case, status: CaseStatus) -> CaseOutcome {
    CaseOutcome {
        id: case.id.clone(),
        params: case.params.clone(),
        status,
        reason: None,
        run: RunKind::NotStarted,
        wall_seconds: 0.0,
        summary: None,
        figures: None,
        files: Default::default(),
    }
}

fn run_one(case: &Case, dir: &Path, background: bool, progress: &Progress) -> CaseOutcome {
    if interrupted() {
        return not_started(case, CaseStatus::Interrupted);
    }
    // Nothing, outcome.json included, is written through a link out of the run directory.
    if let Err(reason) = files::unlink_planted(dir) {
        let outcome = CaseOutcome {
            reason: Some(reason),
            ..not_started(case, CaseStatus::Failed)
        };
        progress.done(&case.id, &outcome.describe(), 0.0);
        return outcome;
    }
    let start = Instant::now();
    let result = execute(case, dir, background, progress);
    let wall_seconds = start.elapsed().as_secs_f64();
    let (status, reason, summary) = match result {
        Ok(s) => (CaseStatus::Complete, None, Some(s)),
        Err(_) if interrupted() => (CaseStatus::Interrupted, None, None),
        Err(reason) => (CaseStatus::Failed, Some(reason), None),
    };
    let figures = (case.config.outputs.figures && summary.is_some()).then(|| draw_figures(dir));
    let mut outcome = CaseOutcome {
        id: case.id.clone(),
        params: case.params.clone(),
        files: if summary.is_some() {
            files::output_files(dir)
        } else {
            Default::default()
        },
        status,
        reason,
        run: RunKind::Computed,
        wall_seconds,
        summary,
        figures,
    };
    // Written last, whole or not at all: its presence with "complete" marks the case done.
    let written = serde_json::to_vec_pretty(&outcome)
        .map_err(std::io::Error::other)
        .and_then(|text| files::write_atomic(&dir.join("outcome.json"), &text));
    if let Err(e) = written {
        // The case's own failure (a full disk: its result.h5 could not be written) first.
        let before = outcome.reason.take().map_or(String::new(), |r| format!("{r}; then "));
        outcome.status = CaseStatus::Failed;
        outcome.reason = Some(format!("{before}cannot write outcome.json: {e}"));
    }
    progress.done(&case.id, &outcome.describe(), wall_seconds);
    outcome
}

/// Draws a finished case's figures: with the command in `TSIM_FIGURES` if set, else the
/// figures script built into tsim ([`figures::draw`]), into `dir`/figures. Python is
/// optional for tsim, so a missing Python or a failure is reported, never fatal.
fn draw_figures(dir: &Path) -> String {
    let drawn = match std::env::var_os("TSIM_FIGURES") {
        Some(script) => std::process::Command::new(&script)
            .arg(dir)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .output()
            .map(|out| (out.status, out.stderr))
            .map_err(|e| format!("cannot run {}: {e}", PathBuf::from(script).display())),
        None => figures::draw(dir, &[], (std::process::Stdio::null(), std::process::Stdio::piped())).map(|out| (out.status, out.stderr)),
    };
    match drawn {
        Ok((status, _)) if status.success() => format!("written to {}", dir.join("figures").display()),
        Ok((_, stderr)) => format!(
            "failed: {}",
            String::from_utf8_lossy(&stderr).lines().last().unwrap_or("figures script failed")
        ),
        Err(e) => format!("not drawn: {e}"),
    }
}

/// Runs one case with its recorders; any error or panic becomes the failure reason.
fn execute(case: &Case, dir: &Path, background: bool, progress: &Progress) -> Result<CaseSummary, String> {
    let _ = std::fs::remove_file(dir.join("outcome.json"));
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let yaml = case.yaml().map_err(|e| e.to_string())?;
    std::fs::write(dir.join("case.yaml"), &yaml).map_err(|e| format!("cannot write case.yaml: {e}"))?;
    let files = crate::output::file_recorders(&case.config.outputs, dir, &case.id, &yaml, &case.attrs, background)
        .map_err(|e| format!("cannot create outputs: {e}"))?;
    let mut recorder = Recorders(vec![Box::new(interrupt::Check), Box::new(progress.case_bar(&case.id)), files]);
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run_case(&case.config, &mut recorder)));
    let result = match run {
        Ok(Ok(summary)) => Ok(summary),
        Ok(Err(e)) => Err(e.to_string()),
        Err(panic) => Err(format!(
            "panic: {}",
            panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        )),
    };
    let outcome = match &result {
        Ok(_) => Outcome::Complete,
        Err(_) if interrupted() => Outcome::Interrupted,
        Err(reason) => Outcome::Failed(reason.clone()),
    };
    recorder.finish(&outcome).map_err(|e| format!("cannot finish outputs: {e}"))?;
    result
}

/// What a run did, in the closing message: how many cases stand complete (computed now or
/// reused), failed, interrupted or pending, and, after an interruption, which are complete
/// and what a rerun does.
pub struct Tally<'a>(pub &'a [CaseOutcome]);

impl Tally<'_> {
    fn count(&self, f: impl Fn(&CaseOutcome) -> bool) -> usize {
        self.0.iter().filter(|o| f(o)).count()
    }

    /// The one-line tally: "27 case(s): 10 complete (3 computed, 7 reused), 2 failed, ...".
    pub fn line(&self) -> String {
        let of = |s: CaseStatus| self.count(|o| o.status == s);
        let computed = self.count(|o| o.status == CaseStatus::Complete && o.run == RunKind::Computed);
        let mut parts = vec![format!(
            "{} complete ({computed} computed, {} reused)",
            of(CaseStatus::Complete),
            of(CaseStatus::Complete) - computed
        )];
        parts.push(format!("{} failed", of(CaseStatus::Failed)));
        for status in [CaseStatus::Interrupted, CaseStatus::Pending] {
            if of(status) > 0 {
                parts.push(format!("{} {status}", of(status)));
            }
        }
        format!("{} case(s): {}", self.0.len(), parts.join(", "))
    }

    /// After an interruption: the complete cases by id (up to ten, else their number), and
    /// what rerunning the same command does.
    pub fn interrupted(&self) -> String {
        let complete: Vec<&str> = self
            .0
            .iter()
            .filter(|o| o.status == CaseStatus::Complete)
            .map(|o| o.id.as_str())
            .collect();
        let named = match complete.len() {
            0 => "no case is complete".to_string(),
            1..=10 => format!("complete: {}", complete.join(", ")),
            n => format!("{n} cases are complete (summary.csv lists them)"),
        };
        format!(
            "interrupted: {named}; the others are marked `interrupted` (or `pending`, or `failed`), \
             never complete. Rerunning the same command reuses the complete cases and runs the rest."
        )
    }
}
