//! `tsim submit`: a sweep as a Slurm job array, one shard per task, and a merge job that
//! runs once every task has ended (`--dependency=afterany`). The batch scripts are written
//! into the run directory (`slurm/`), so what ran can be read and resubmitted by hand. A
//! re-submit sends only the shards with a case not complete (or without a manifest); the
//! shards reuse their complete cases as any resumed run does.

use super::shard::{Manifest, Plan, Shard};
use super::{Case, OnDisk};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Most tasks in one array by default: Slurm's default `MaxArraySize` (1001) allows the
/// ids 0 to 1000.
pub const MAX_DEFAULT_SHARDS: usize = 1000;

/// Options of `tsim submit`.
#[derive(Clone, Debug)]
pub struct SubmitOptions {
    /// The config file, as given.
    pub config: PathBuf,
    pub out: PathBuf,
    /// Shards [default: the run directory's plan's, else one per case up to 1000].
    pub shards: Option<usize>,
    /// Most array tasks running at once (`--array=...%K`).
    pub throttle: Option<usize>,
    pub allow_large: bool,
    /// Passed to both `sbatch` calls (partition, account, time, memory...).
    pub sbatch: Vec<String>,
}

/// What was submitted.
#[derive(Clone, Debug)]
pub struct Submitted {
    pub array_job: String,
    pub merge_job: String,
    /// The shards sent (array task ids), of `count`.
    pub shards: Vec<usize>,
    pub count: usize,
    /// Cases not complete when submitted.
    pub incomplete: usize,
    pub dir: PathBuf,
}

/// Plans the run directory's shards, writes the batch scripts and submits them; None when
/// every case is complete and every manifest written (nothing to do).
pub fn submit(name: &str, cases: &[Case], opts: &SubmitOptions) -> Result<Option<Submitted>, String> {
    let out = std::path::absolute(&opts.out).map_err(|e| format!("{}: {e}", opts.out.display()))?;
    for (what, path) in [("--out", out.as_path()), ("the config", opts.config.as_path())] {
        one_line(what, path)?;
    }
    let dir = out.join(name);
    std::fs::create_dir_all(dir.join("slurm")).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let earlier = Plan::read(&dir)?;
    let count = opts
        .shards
        .or(earlier.as_ref().map(|p| p.shards))
        .unwrap_or(cases.len().min(MAX_DEFAULT_SHARDS))
        .clamp(1, cases.len().max(1));
    let plan = Plan::new(cases, count).map_err(|e| e.to_string())?;
    let changed = earlier.as_ref() != Some(&plan);
    let incomplete: Vec<usize> = cases
        .iter()
        .zip(&plan.cases)
        .filter(|(c, _)| OnDisk::of(c, &dir.join(&c.id)) != OnDisk::Complete)
        .map(|(_, p)| p.shard)
        .collect();
    // A shard goes again when the plan changed (its old manifest lists other cases), when
    // it has a case not complete, or when it never wrote its manifest.
    let shards: Vec<usize> = (0..count)
        .filter(|&index| changed || incomplete.contains(&index) || !matches!(Manifest::read(&dir, Shard { index, count }), Ok(Some(_))))
        .collect();
    if shards.is_empty() {
        return Ok(None);
    }
    plan.write(&dir)
        .map_err(|e| format!("cannot write {}: {e}", Plan::path(&dir).display()))?;
    let config = std::fs::canonicalize(&opts.config).map_err(|e| format!("{}: {e}", opts.config.display()))?;
    let tsim = std::env::current_exe().map_err(|e| format!("cannot find the tsim executable: {e}"))?;
    let scripts = Scripts {
        tsim: &tsim,
        config: &config,
        out: &out,
        dir: &dir,
        name,
        count,
        allow_large: opts.allow_large,
    };
    let (array, merge) = scripts.write()?;
    let mut spec = ranges(&shards);
    if let Some(k) = opts.throttle {
        spec.push_str(&format!("%{}", k.max(1)));
    }
    let array_job = sbatch(&[format!("--array={spec}")], &opts.sbatch, &array)?;
    let merge_job = sbatch(&[format!("--dependency=afterany:{array_job}")], &opts.sbatch, &merge)?;
    Ok(Some(Submitted {
        array_job,
        merge_job,
        shards,
        count,
        incomplete: incomplete.len(),
        dir,
    }))
}

/// Array task ids as Slurm's `--array` takes them: `0-8`, `1,4-5`.
pub fn ranges(ids: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut k = 0;
    while k < ids.len() {
        let start = ids[k];
        while k + 1 < ids.len() && ids[k + 1] == ids[k] + 1 {
            k += 1;
        }
        parts.push(if ids[k] == start {
            start.to_string()
        } else {
            format!("{start}-{}", ids[k])
        });
        k += 1;
    }
    parts.join(",")
}

/// Err when `path` has a control character (a newline): the batch scripts carry the run
/// directory in `#SBATCH` lines and a comment, where a newline would start a command that
/// every array task runs.
fn one_line(what: &str, path: &Path) -> Result<(), String> {
    match path.to_string_lossy().chars().any(char::is_control) {
        true => Err(format!(
            "{what} {path:?} has a control character (a newline?): Slurm batch scripts cannot hold it; choose a path without one"
        )),
        false => Ok(()),
    }
}

/// A path as one shell word.
fn quoted(path: &Path) -> String {
    format!("'{}'", path.display().to_string().replace('\'', r"'\''"))
}

/// The two batch scripts of a submission.
struct Scripts<'a> {
    tsim: &'a Path,
    config: &'a Path,
    out: &'a Path,
    dir: &'a Path,
    name: &'a str,
    count: usize,
    allow_large: bool,
}

impl Scripts<'_> {
    /// Writes `slurm/array.sbatch` and `slurm/merge.sbatch` in the run directory; their paths.
    fn write(&self) -> Result<(PathBuf, PathBuf), String> {
        let slurm = self.dir.join("slurm");
        let header = |job: &str, log: &str| {
            format!(
                "#!/bin/bash\n# Written by `tsim submit` for {}; submitted with `sbatch`, options on its command line.\n#SBATCH --job-name={job}\n#SBATCH --output={}\n",
                self.dir.display(),
                slurm.join(log).display()
            )
        };
        // `exec`: tsim itself gets Slurm's SIGTERM at the time limit or on scancel, and
        // marks its running cases interrupted.
        let array = format!(
            "{}exec {} run {} --out {} --shard \"$SLURM_ARRAY_TASK_ID/{}\" --quiet{}\n",
            header(&format!("tsim-{}", self.name), "shard-%a-job-%A.out"),
            quoted(self.tsim),
            quoted(self.config),
            quoted(self.out),
            self.count,
            if self.allow_large { " --allow-large" } else { "" }
        );
        let merge = format!(
            "{}exec {} collect {}\n",
            header(&format!("tsim-{}-merge", self.name), "merge-job-%j.out"),
            quoted(self.tsim),
            quoted(self.dir)
        );
        let paths = (slurm.join("array.sbatch"), slurm.join("merge.sbatch"));
        for (path, text) in [(&paths.0, array), (&paths.1, merge)] {
            std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        }
        Ok(paths)
    }
}

/// Submits `script` with `ours` then the user's options; the job id.
fn sbatch(ours: &[String], theirs: &[String], script: &Path) -> Result<String, String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(ours)
        .args(theirs)
        .arg(script)
        .output()
        .map_err(|e| format!("cannot run sbatch: {e} (Slurm's client commands must be on PATH: `module load slurm` on some clusters)"))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    // --parsable prints `id` or `id;cluster`.
    let id = stdout.trim().split(';').next().unwrap_or("").to_string();
    if !out.status.success() || id.is_empty() {
        return Err(format!(
            "sbatch {} {}: {}",
            ours.join(" "),
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_ids_are_written_as_ranges() {
        assert_eq!(ranges(&[0, 1, 2, 3]), "0-3");
        assert_eq!(ranges(&[1, 4, 5, 7]), "1,4-5,7");
        assert_eq!(ranges(&[6]), "6");
    }

    #[test]
    fn a_path_with_a_newline_is_refused() {
        assert!(one_line("--out", Path::new("/runs/a b")).is_ok());
        let err = one_line("--out", Path::new("/runs/x\ntouch /tmp/pwned")).unwrap_err();
        assert!(err.contains("--out") && err.contains("control character"), "{err}");
    }

    #[test]
    fn paths_are_quoted_for_the_shell() {
        assert_eq!(quoted(Path::new("/a b/it's")), r"'/a b/it'\''s'");
    }
}
