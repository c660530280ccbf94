//! `tsim submit` on a real Slurm: the one-node test cluster of
//! scripts/slurm/start-test-cluster (scripts/test starts it). A sharded sweep merges to the
//! summary an unsharded run writes, and a task cancelled while it runs (SIGTERM, as at a
//! time limit) leaves its case interrupted, the merge says so and fails, and a re-submit
//! sends that shard alone and completes the sweep. Without a cluster the tests say so and
//! pass, unless TSIM_SLURM_TEST=1 (scripts/test sets it once the cluster is up).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// The two tests share the cluster's two CPUs: one at a time keeps their timing apart.
static CLUSTER: std::sync::Mutex<()> = std::sync::Mutex::new(());

const SWEEP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/small_sweep.yaml");

/// Longest wait for a submission's jobs: the slow sweep's tasks take ~15 s on the test
/// cluster; a minute more covers a busy machine.
const JOB_TIMEOUT: Duration = Duration::from_secs(240);

fn cmd(program: &str, args: &[&str]) -> Output {
    Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{program}: {e}"))
}

fn tsim(args: &[&str]) -> Output {
    cmd(env!("CARGO_BIN_EXE_tsim"), args)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Whether the test cluster answers; false (the test then passes, saying why) only when
/// scripts/test did not promise one.
fn cluster_up() -> bool {
    let up = Command::new("sinfo")
        .args(["-h", "-o", "%t"])
        .output()
        .is_ok_and(|o| o.status.success() && ["idle", "mix", "alloc"].iter().any(|s| text(&o.stdout).contains(s)));
    if !up {
        assert!(
            std::env::var("TSIM_SLURM_TEST").as_deref() != Ok("1"),
            "TSIM_SLURM_TEST=1 but no Slurm node answers `sinfo`: see /var/log/slurm/"
        );
        eprintln!("SKIPPED: no Slurm cluster here (scripts/slurm/start-test-cluster starts one, as root with apt)");
    }
    up
}

/// A fresh directory under the system's temp dir for one test, removed when dropped.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("tsim-slurm-{name}-")).tempdir().unwrap()
}

/// `tsim submit`'s two job ids (array, merge).
fn submit(args: &[&str]) -> (String, String) {
    let out = tsim(&[&["submit"], args].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let id = |what: &str| {
        stdout
            .lines()
            .find_map(|l| l.strip_prefix(what))
            .unwrap_or_else(|| panic!("no `{what}` line in {stdout}"))
            .trim()
            .to_string()
    };
    (id("array job "), id("merge job "))
}

/// Waits until none of `jobs` is pending or running.
fn wait(jobs: &[&str]) {
    let start = Instant::now();
    while !text(&cmd("squeue", &["-h", "-j", &jobs.join(",")]).stdout).trim().is_empty() {
        assert!(start.elapsed() < JOB_TIMEOUT, "jobs {jobs:?} still queued after {JOB_TIMEOUT:?}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// `scontrol show job`'s `key=value` of a finished job (kept by the controller for
/// MinJobAge, 600 s on the test cluster).
fn job_field(job: &str, key: &str) -> String {
    let show = text(&cmd("scontrol", &["show", "job", job]).stdout);
    show.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("no {key} in {show}"))
        .to_string()
}

/// summary.csv without the wall-time columns (they differ between any two runs).
fn summary_without_times(dir: &Path) -> Vec<Vec<String>> {
    let csv = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
    let rows: Vec<Vec<String>> = csv.lines().map(|l| l.split(',').map(str::to_string).collect()).collect();
    let times = [
        "wall_s",
        "formfinding_s",
        "static_s",
        "eigen_s",
        "free_vibration_s",
        "folding_s",
        "deployment_s",
    ];
    let keep: Vec<bool> = rows[0].iter().map(|h| !times.contains(&h.as_str())).collect();
    rows.iter()
        .map(|r| r.iter().zip(&keep).filter(|(_, &k)| k).map(|(c, _)| c.clone()).collect())
        .collect()
}

/// Every case id in the manifests of a plan of `count` shards, with the shard listing it.
fn manifest_cases(run: &Path, count: usize) -> Vec<(String, usize)> {
    (0..count)
        .flat_map(|i| {
            let path = run.join(format!("shards/shard-{i}-of-{count}.json"));
            let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            assert_eq!((m["shard"].as_u64(), m["of"].as_u64()), (Some(i as u64), Some(count as u64)));
            m["cases"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| (c["id"].as_str().unwrap().to_string(), i))
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn a_sharded_sweep_on_slurm_merges_to_the_unsharded_summary() {
    let _one = CLUSTER.lock().unwrap_or_else(|e| e.into_inner());
    if !cluster_up() {
        return;
    }
    let out_dir = scratch("sharded");
    let out = out_dir.path();
    let root = out.to_str().unwrap();
    let (array, merge) = submit(&[SWEEP, "--out", root, "--shards", "3", "--throttle", "2"]);
    wait(&[&array, &merge]);
    let run = out.join("small");
    assert_eq!(
        (job_field(&merge, "JobState"), job_field(&merge, "ExitCode")),
        ("COMPLETED".into(), "0:0".into()),
        "the merge job: {}",
        std::fs::read_to_string(run.join(format!("slurm/merge-job-{merge}.out"))).unwrap_or_default()
    );
    // Every case in exactly one manifest, the one its plan names.
    let mut listed = manifest_cases(&run, 3);
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("shards/plan.json")).unwrap()).unwrap();
    let mut planned: Vec<(String, usize)> = plan["cases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["id"].as_str().unwrap().to_string(), c["shard"].as_u64().unwrap() as usize))
        .collect();
    listed.sort();
    planned.sort();
    assert_eq!(listed.len(), 4);
    assert_eq!(listed, planned);

    let plain = out.join("plain");
    let unsharded = tsim(&["run", SWEEP, "--out", plain.to_str().unwrap(), "--quiet"]);
    assert!(unsharded.status.success(), "{}", text(&unsharded.stderr));
    assert_eq!(summary_without_times(&run), summary_without_times(&plain.join("small")));
}

/// small_sweep.yaml with a long deployment in small steps (~4 s a case here), so that a
/// task is surely still running when it is cancelled.
fn slow_sweep(dir: &Path) -> PathBuf {
    let fixture = std::fs::read_to_string(SWEEP).unwrap();
    let slow = fixture.replacen("name: small", "name: slow", 1).replacen(
        "deployment:\n  duration: 0.1\n",
        "deployment:\n  duration: 80.0\n  dt: 0.0001\n",
        1,
    ) + "outputs: { every: 2000 }\n";
    assert!(
        slow.contains("duration: 80.0") && slow.contains("name: slow"),
        "the fixture changed: {fixture}"
    );
    let path = dir.join("slow.yaml");
    std::fs::write(&path, slow).unwrap();
    path
}

#[test]
fn a_cancelled_task_is_reported_and_a_resubmit_completes_it() {
    let _one = CLUSTER.lock().unwrap_or_else(|e| e.into_inner());
    if !cluster_up() {
        return;
    }
    let out_dir = scratch("cancel");
    let out = out_dir.path();
    let config = slow_sweep(out);
    let args = [config.to_str().unwrap(), "--out", out.to_str().unwrap()];
    // One task at a time: shard 0, then shard 1, which is cancelled once a case of it runs.
    let (array, merge) = submit(&[&args[..], &["--shards", "2", "--throttle", "1"]].concat());
    let run = out.join("slow");
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("shards/plan.json")).unwrap()).unwrap();
    let second: Vec<String> = plan["cases"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["shard"] == 1)
        .map(|c| c["id"].as_str().unwrap().to_string())
        .collect();
    let task = format!("{array}_1");
    let start = Instant::now();
    while !second.iter().any(|id| run.join(id).join("case.yaml").exists()) {
        assert!(start.elapsed() < JOB_TIMEOUT, "shard 1 never started");
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(cmd("scancel", &[&task]).status.success());
    wait(&[&array, &merge]);
    // The task stopped on SIGTERM: its running case is interrupted, none of its cases complete.
    assert_eq!(job_field(&task, "JobState"), "CANCELLED");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("shards/shard-1-of-2.json")).unwrap()).unwrap();
    let statuses: Vec<&str> = manifest["cases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["status"].as_str().unwrap())
        .collect();
    assert!(statuses.iter().all(|&s| s == "interrupted"), "{manifest}");
    // The merge job ran after it, reported the shard's cases and failed.
    assert_eq!(job_field(&merge, "ExitCode"), "1:0");
    let merged = std::fs::read_to_string(run.join(format!("slurm/merge-job-{merge}.out"))).unwrap();
    for id in &second {
        assert!(merged.contains(&format!("not complete: {id}: ")), "{id} not reported: {merged}");
    }
    assert!(merged.contains("2 not complete"), "{merged}");

    // The re-submit sends shard 1 alone (the plan's partition), and the sweep completes.
    let resubmitted = tsim(&[&["submit"], &args[..]].concat());
    assert!(resubmitted.status.success(), "{}", text(&resubmitted.stderr));
    assert!(
        text(&resubmitted.stderr).contains("submitted shard(s) 1 of 2"),
        "{}",
        text(&resubmitted.stderr)
    );
    let stdout = text(&resubmitted.stdout);
    let ids: Vec<&str> = stdout.lines().filter_map(|l| l.split_whitespace().nth(2)).collect();
    wait(&ids);
    assert_eq!(job_field(ids[1], "ExitCode"), "0:0");
    let collect = tsim(&["collect", run.to_str().unwrap()]);
    assert!(collect.status.success(), "{}", text(&collect.stderr));
    let listed = manifest_cases(&run, 2);
    let distinct: std::collections::BTreeSet<&String> = listed.iter().map(|(id, _)| id).collect();
    assert_eq!(
        (listed.len(), distinct.len()),
        (4, 4),
        "every case in exactly one manifest: {listed:?}"
    );
}
