//! A sweep in shards, for job arrays: `tsim run --shard I/N` runs the I-th of N disjoint
//! slices of the cases. The slices depend only on the cases (ids and estimated work), never
//! on what is complete, so a resumed or re-submitted shard runs the same cases. Shards
//! share the run directory (each case its own directory) and each writes its manifest,
//! `shards/shard-I-of-N.json`, in place of the summaries that one run writes; the plan,
//! `shards/plan.json`, lists every case with its shard for the merge (`tsim collect`).

use super::{files, Case, CaseOutcome, CaseStatus, RunKind};
use std::path::{Path, PathBuf};

/// Shard `index` of `count`, numbered from 0 as Slurm numbers array tasks
/// (`sbatch --array=0-(N-1)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// `I/N` (0 ≤ I < N) or `auto`: the task of a Slurm job array, from
    /// `SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_MIN` and `SLURM_ARRAY_TASK_COUNT` (read
    /// through `env`), the array's ids contiguous (`--array=0-8` or `1-9`).
    pub fn parse(text: &str, env: impl Fn(&str) -> Option<String>) -> Result<Shard, String> {
        if text == "auto" {
            return Self::from_slurm(env);
        }
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| format!("`{text}`: give I/N (shard I of N, I from 0 to N-1) or `auto` (a Slurm array task)"))?;
        let number = |s: &str, what: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| format!("`{text}`: {what} `{s}` is not a whole number ≥ 0"))
        };
        let (index, count) = (number(i, "I")?, number(n, "N")?);
        if count == 0 || index >= count {
            return Err(format!(
                "`{text}`: shards are numbered from 0 to N-1 (0/{n} to {}/{n}), as Slurm numbers the tasks of --array=0-{}",
                count.max(1) - 1,
                count.max(1) - 1
            ));
        }
        Ok(Shard { index, count })
    }

    fn from_slurm(env: impl Fn(&str) -> Option<String>) -> Result<Shard, String> {
        let var = |name: &str| -> Result<usize, String> {
            let value = env(name).ok_or_else(|| {
                format!("--shard auto needs {name}: run it as a task of a Slurm job array (sbatch --array), or give --shard I/N")
            })?;
            value.trim().parse().map_err(|_| format!("{name}={value} is not a whole number"))
        };
        let (id, min, max, count) = (
            var("SLURM_ARRAY_TASK_ID")?,
            var("SLURM_ARRAY_TASK_MIN")?,
            var("SLURM_ARRAY_TASK_MAX")?,
            var("SLURM_ARRAY_TASK_COUNT")?,
        );
        if max + 1 != min + count || id < min || id > max {
            return Err(format!(
                "--shard auto: the array's task ids ({min} to {max}, {count} tasks) are not contiguous; give the shard itself, --shard $SLURM_ARRAY_TASK_ID/N"
            ));
        }
        Ok(Shard { index: id - min, count })
    }

    /// `shard-I-of-N`: the manifest's name and the lock's.
    pub fn name(self) -> String {
        format!("shard-{}-of-{}", self.index, self.count)
    }
}

/// The shard of each case (in the order of `cases`): longest work first, each to the
/// shard with the least work so far (ties: the lower shard), equal works in id order.
/// Greedy LPT: its longest shard is within 4/3 of the best possible.
pub fn assign(cases: &[Case], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cases.len()).collect();
    order.sort_by(|&a, &b| {
        (cases[b].estimate.work)
            .total_cmp(&cases[a].estimate.work)
            .then_with(|| cases[a].id.cmp(&cases[b].id))
    });
    let mut load = vec![0.0_f64; count.max(1)];
    let mut shard = vec![0; cases.len()];
    for k in order {
        let least = (0..load.len()).min_by(|&a, &b| load[a].total_cmp(&load[b])).unwrap_or(0);
        load[least] += cases[k].estimate.work;
        shard[k] = least;
    }
    shard
}

/// 64-bit FNV-1a of a case's resolved config, in hex: the merge tells a case directory
/// written with this config from one an earlier config left (the ids may be the same).
pub fn fingerprint(yaml: &str) -> String {
    let hash = yaml
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    format!("{hash:016x}")
}

/// One case of the plan.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Planned {
    pub id: String,
    pub params: Vec<(String, String)>,
    pub shard: usize,
    /// [`fingerprint`] of its `case.yaml`.
    pub config: String,
}

/// `shards/plan.json`: every case of the sweep with its shard, in sweep order.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Plan {
    pub shards: usize,
    pub cases: Vec<Planned>,
}

impl Plan {
    pub fn new(cases: &[Case], count: usize) -> std::io::Result<Plan> {
        let shards = assign(cases, count);
        Ok(Plan {
            shards: count,
            cases: cases
                .iter()
                .zip(shards)
                .map(|(c, shard)| {
                    Ok(Planned {
                        id: c.id.clone(),
                        params: c.params.clone(),
                        shard,
                        config: fingerprint(&c.yaml()?),
                    })
                })
                .collect::<std::io::Result<_>>()?,
        })
    }

    pub fn path(dir: &Path) -> PathBuf {
        dir.join("shards").join("plan.json")
    }

    /// The plan in `dir`, if one was written (Err: there, but unreadable).
    pub fn read(dir: &Path) -> Result<Option<Plan>, String> {
        let path = Self::path(dir);
        match std::fs::read_to_string(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(format!("{}: {e}", path.display())),
            Ok(text) => serde_json::from_str(&text)
                .map(Some)
                .map_err(|e| format!("{}: {e} (remove it and submit again)", path.display())),
        }
    }

    /// Written whole (shards starting at once write the same plan).
    pub fn write(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir.join("shards"))?;
        let text = serde_json::to_vec_pretty(self).map_err(std::io::Error::other)?;
        files::write_atomic(&Self::path(dir), &text)
    }
}

/// One case in a manifest: how the shard left it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Entry {
    pub id: String,
    pub status: CaseStatus,
    pub run: RunKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// `shards/shard-I-of-N.json`, written when a shard's run ends (also on SIGTERM).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    pub shard: usize,
    pub of: usize,
    pub host: String,
    /// `SLURM_JOB_ID` of the task that ran it, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slurm_job: Option<String>,
    pub cases: Vec<Entry>,
}

impl Manifest {
    pub fn path(dir: &Path, shard: Shard) -> PathBuf {
        dir.join("shards").join(format!("{}.json", shard.name()))
    }

    pub fn write(dir: &Path, shard: Shard, outcomes: &[CaseOutcome]) -> std::io::Result<()> {
        let manifest = Manifest {
            shard: shard.index,
            of: shard.count,
            host: files::host(),
            slurm_job: std::env::var("SLURM_JOB_ID").ok(),
            cases: outcomes
                .iter()
                .map(|o| Entry {
                    id: o.id.clone(),
                    status: o.status,
                    run: o.run,
                    reason: o.reason.clone(),
                })
                .collect(),
        };
        let text = serde_json::to_vec_pretty(&manifest).map_err(std::io::Error::other)?;
        files::write_atomic(&Self::path(dir, shard), &text)
    }

    /// The manifest of `shard` in `dir`: None when not written (the shard has not ended).
    pub fn read(dir: &Path, shard: Shard) -> Result<Option<Manifest>, String> {
        let path = Self::path(dir, shard);
        match std::fs::read_to_string(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(format!("{}: {e}", path.display())),
            Ok(text) => serde_json::from_str(&text)
                .map(Some)
                .map_err(|e| format!("{}: {e}", path.display())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| vars.iter().find(|(n, _)| *n == name).map(|(_, v)| v.to_string())
    }

    #[test]
    fn shards_are_numbered_from_zero_and_slurm_arrays_read() {
        let none = env(&[]);
        assert_eq!(Shard::parse("0/3", &none), Ok(Shard { index: 0, count: 3 }));
        assert_eq!(Shard::parse("2/3", &none), Ok(Shard { index: 2, count: 3 }));
        assert!(Shard::parse("3/3", &none).unwrap_err().contains("0/3 to 2/3"));
        assert!(Shard::parse("0/0", &none).is_err());
        assert!(Shard::parse("x/3", &none).unwrap_err().contains("`x`"));
        assert!(Shard::parse("auto", &none).unwrap_err().contains("SLURM_ARRAY_TASK_ID"));
        // --array=1-9: task 5 is the fifth shard (index 4) of 9.
        let task = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "9"),
            ("SLURM_ARRAY_TASK_COUNT", "9"),
        ];
        assert_eq!(Shard::parse("auto", env(&task)), Ok(Shard { index: 4, count: 9 }));
        // --array=1,5: ids 1 and 5 of 2 tasks cannot name shards.
        let sparse = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ];
        assert!(Shard::parse("auto", env(&sparse)).unwrap_err().contains("not contiguous"));
    }

    /// Seven copies of one case with the given works, ids `c0`...
    fn cases(works: &[f64]) -> Vec<Case> {
        let fixture = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/small_sweep.yaml");
        let one = crate::run::load(Path::new(fixture), false).unwrap().cases.remove(0);
        works
            .iter()
            .enumerate()
            .map(|(k, &w)| {
                let mut c = one.clone();
                c.id = format!("c{k}");
                c.estimate.work = w;
                c
            })
            .collect()
    }

    #[test]
    fn longest_work_first_to_the_least_loaded_shard() {
        let works = [1.0, 7.0, 3.0, 5.0, 2.0, 6.0, 4.0];
        let shards = assign(&cases(&works), 3);
        // By hand: 7→0, 6→1, 5→2, 4→2 (9), 3→1 (9), 2→0 (9), 1→0 (10).
        assert_eq!(shards, [0, 0, 1, 2, 0, 1, 2]);
        // The slices depend on the cases, not on their order in the list.
        let mut reversed = cases(&works);
        reversed.reverse();
        let again: Vec<usize> = assign(&reversed, 3).into_iter().rev().collect();
        assert_eq!(again, shards);
        // More shards than cases: some are empty, none holds two.
        let spread = assign(&cases(&works), 9);
        assert!((0..9).all(|s| spread.iter().filter(|&&x| x == s).count() <= 1));
    }

    #[test]
    fn fingerprints_differ_with_the_config() {
        // FNV-1a's published value for "a" (a check that the constants are the standard ones).
        assert_eq!(fingerprint("a"), "af63dc4c8601ec8c");
        assert_ne!(fingerprint("dt: 0.001\n"), fingerprint("dt: 0.002\n"));
    }
}
