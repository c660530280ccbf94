//! The real binary on small sweeps: summaries, determinism across thread counts, resume,
//! config errors, and a failing case among complete ones.

use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Child processes are spawned under the read lock, HDF5 files are opened in this process
/// under the write lock. HDF5 opens files without close-on-exec, so a child spawned (by a
/// test on another thread) while this process has a file open inherits the descriptor
/// and its lock; the lock then outlives the read, and a later tsim fails to create that
/// file (EAGAIN: seen once in the signal test's rerun).
static SPAWN: std::sync::RwLock<()> = std::sync::RwLock::new(());

fn spawn(cmd: &mut Command) -> std::process::Child {
    let _guard = SPAWN.read().unwrap_or_else(|e| e.into_inner());
    cmd.spawn().expect("tsim starts")
}

/// Opens an HDF5 file in this process with no child being spawned meanwhile.
fn with_h5<T>(path: &Path, read: impl FnOnce(&hdf5::File) -> T) -> T {
    let _guard = SPAWN.write().unwrap_or_else(|e| e.into_inner());
    read(&hdf5::File::open(path).unwrap())
}

fn tsim(args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
    cmd.args(args).env("CI", "1").stdout(Stdio::piped()).stderr(Stdio::piped());
    spawn(&mut cmd).wait_with_output().expect("tsim runs")
}

/// A fresh directory under the system's temp dir for one test, removed when dropped.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("tsim-cli-{name}-")).tempdir().unwrap()
}

/// A file in a scratch directory, which is removed when this is dropped.
struct ScratchFile {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl std::ops::Deref for ScratchFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

const SWEEP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/small_sweep.yaml");

fn outcomes(dir: &Path) -> Vec<serde_json::Value> {
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("small/summary.json")).unwrap()).unwrap();
    v.as_array().unwrap().clone()
}

#[test]
fn sweep_runs_in_stable_order_and_resumes() {
    let check = tsim(&["check", SWEEP]);
    assert!(check.status.success());
    let listed = String::from_utf8_lossy(&check.stdout);
    // One indented line per case: its id, then its estimated output and memory.
    let ids: Vec<&str> = listed
        .lines()
        .filter(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(listed.lines().nth(1).unwrap().contains("output ") && listed.contains("estimated: output "));
    // First axis slowest: the contract that names output directories.
    assert_eq!(
        ids,
        [
            "cable-rubber_zeta-0.05",
            "cable-rubber_zeta-0.1",
            "cable-nylon_zeta-0.05",
            "cable-nylon_zeta-0.1"
        ]
    );

    let out_dir = scratch("resume");
    let out = out_dir.path();
    let run = tsim(&["run", SWEEP, "--out", out.to_str().unwrap(), "--jobs", "2"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let csv = std::fs::read_to_string(out.join("small/summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4, "header + one row per case:\n{csv}");
    assert!(csv.lines().next().unwrap().starts_with("case_id,cable,zeta,status,"));
    for id in &ids {
        assert!(out.join("small").join(id).join("case.yaml").exists());
    }
    assert!(outcomes(out).iter().all(|o| o["status"] == "complete"));

    assert!(outcomes(out).iter().all(|o| o["run"] == "computed"));

    // A resume reuses the complete cases: their status stays `complete` (a pandas filter
    // on it must find them), and the `run` column says they were reused.
    let again = tsim(&["run", SWEEP, "--out", out.to_str().unwrap()]);
    assert!(again.status.success());
    // One line for the reused cases, not one per case (with `--quiet` too).
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("4 complete cases reused") && !err.contains("skipped"), "{err}");
    let quiet = tsim(&["run", SWEEP, "--out", out.to_str().unwrap(), "--quiet"]);
    let err = String::from_utf8_lossy(&quiet.stderr);
    assert!(err.contains("4 complete cases reused") && !err.contains("skipped"), "{err}");
    assert!(
        outcomes(out).iter().all(|o| o["status"] == "complete" && o["run"] == "reused"),
        "{:?}",
        outcomes(out)
    );
    let csv = std::fs::read_to_string(out.join("small/summary.csv")).unwrap();
    let column = |name: &str| -> Vec<String> {
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let k = header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no `{name}` in {header:?}"));
        csv.lines().skip(1).map(|l| l.split(',').nth(k).unwrap().to_string()).collect()
    };
    assert_eq!(column("status"), ["complete"; 4], "{csv}");
    assert_eq!(column("run"), ["reused"; 4], "{csv}");
    // Counts and yes/no verdicts are whole numbers (they were `1.000000e0`).
    let whole = |name: &str| column(name).iter().all(|c| !c.is_empty() && c.bytes().all(|b| b.is_ascii_digit()));
    let counts = [
        "self_stress_states",
        "mechanisms",
        "internal_mechanisms",
        "prestress_stable",
        "super_stable",
    ];
    assert!(counts.iter().all(|c| whole(c)), "{csv}");
    let forced = tsim(&["run", SWEEP, "--out", out.to_str().unwrap(), "--force"]);
    assert!(forced.status.success());
    assert!(outcomes(out).iter().all(|o| o["status"] == "complete" && o["run"] == "computed"));
}

/// `tsim --version`: the crate version and the git revision it was built from.
#[test]
fn version_names_the_git_revision() {
    let out = tsim(&["--version"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.starts_with(&format!("tsim {} (git ", env!("CARGO_PKG_VERSION"))) && text.trim_end().ends_with(')'),
        "{text}"
    );
    let rev = text.split("(git ").nth(1).unwrap().trim_end().trim_end_matches(')');
    assert!(
        rev == "unknown" || rev.trim_end_matches("-dirty").chars().all(|c| c.is_ascii_hexdigit()),
        "{text}"
    );
}

/// Cases are independent and each runs sequentially inside, so the thread count must not
/// change a single bit of any result.
/// summary.json's outcomes without the wall times, the only figures allowed to differ
/// between two runs of a config.
fn outcomes_without_times(dir: &Path) -> Vec<serde_json::Value> {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(o) => {
                o.remove("wall_seconds");
                o.remove("stage_seconds");
                o.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut o = outcomes(dir);
    o.iter_mut().for_each(strip);
    o
}

#[test]
fn parallel_equals_serial() {
    let (serial_dir, parallel_dir) = (scratch("serial"), scratch("parallel"));
    let (serial, parallel) = (serial_dir.path(), parallel_dir.path());
    assert!(tsim(&["run", SWEEP, "--out", serial.to_str().unwrap(), "--jobs", "1"])
        .status
        .success());
    assert!(tsim(&["run", SWEEP, "--out", parallel.to_str().unwrap(), "--jobs", "2"])
        .status
        .success());
    assert_eq!(outcomes_without_times(serial), outcomes_without_times(parallel));
}

/// Two shards at once in one directory (as a job array runs them), merged by `collect`:
/// the unsharded run's summary; a case killed mid-way is reported and fails the merge.
#[test]
fn shards_run_side_by_side_and_merge_to_the_unsharded_summary() {
    let (sharded_dir, plain_dir) = (scratch("sharded"), scratch("plain"));
    let (sharded, plain) = (sharded_dir.path(), plain_dir.path());
    let shard = |i: &str| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
        cmd.args(["run", SWEEP, "--out", sharded.to_str().unwrap(), "--quiet", "--shard", i])
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        spawn(&mut cmd)
    };
    let both = [shard("0/2"), shard("1/2")];
    for child in both {
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let dir = sharded.join("small");
    assert!(!dir.join("summary.json").exists(), "shards write manifests, not summaries");
    let merged = tsim(&["collect", dir.to_str().unwrap()]);
    assert_eq!(merged.status.code(), Some(0), "{}", String::from_utf8_lossy(&merged.stderr));
    assert!(tsim(&["run", SWEEP, "--out", plain.to_str().unwrap(), "--quiet"]).status.success());
    assert_eq!(outcomes_without_times(sharded), outcomes_without_times(plain));

    // A task killed mid-case leaves no outcome.json: interrupted, whatever its manifest says.
    std::fs::remove_file(dir.join("cable-nylon_zeta-0.1/outcome.json")).unwrap();
    let partial = tsim(&["collect", dir.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&partial.stderr);
    assert_eq!(partial.status.code(), Some(1), "{err}");
    assert!(
        err.contains("not complete: cable-nylon_zeta-0.1: started but no outcome.json"),
        "{err}"
    );
    assert!(outcomes(sharded).iter().any(|o| o["status"] == "interrupted"));

    let bad = tsim(&["run", SWEEP, "--shard", "2/2"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("numbered from 0 to N-1"));
}

fn bad_config(text: &str) -> (Output, ScratchFile) {
    // By content: tests run in parallel, and two bad texts may have the same length.
    let mut hasher = std::hash::DefaultHasher::new();
    text.hash(&mut hasher);
    let dir = scratch(&format!("bad{:x}", hasher.finish()));
    let path = dir.path().join("bad.yaml");
    std::fs::write(&path, text).unwrap();
    let start = Instant::now();
    let out = tsim(&["run", path.to_str().unwrap(), "--out", dir.path().join("runs").to_str().unwrap()]);
    // Validation happens before any work: a second is generous for a parse.
    assert!(start.elapsed() < Duration::from_secs(1));
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.path().join("runs").exists(), "a bad config must write nothing");
    (out, ScratchFile { _dir: dir, path })
}

/// `path:line` of the first line of `text` containing `needle`.
fn at(path: &Path, text: &str, needle: &str) -> String {
    let line = text.lines().position(|l| l.contains(needle)).expect("needle in text") + 1;
    format!("{}:{line}", path.display())
}

#[test]
fn bad_configs_fail_fast_with_location() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.replace("masses: paper", "masses: paper\nmassess: 3");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("{}:8:", path.display())) && err.contains("massess"), "{err}");

    let text = good.replace("duration: 0.1\n", "duration: 0.1\n  dt: -0.001\n");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&at(&path, &text, "dt: -0.001")) && err.contains("deployment.dt") && err.contains("> 0"),
        "{err}"
    );

    let text = good.replace("modes: [1, 6]", "modes: [1, 60]");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&at(&path, &text, "modes: [1, 60]")) && err.contains("eigen.rayleigh.modes[1]") && err.contains("1..=12"),
        "{err}"
    );

    // A bad value set by a sweep axis points at that axis value.
    let text = good.replace("[0.1, 0.1] } }", "[1.5, 0.1] } }");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&at(&path, &text, "[1.5, 0.1]")) && err.contains("ratios[0]") && err.contains("zeta=0.1"),
        "{err}"
    );

    let text = good.replace("groups: [top], force: [0.0", "groups: [tip], force: [0.0");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&at(&path, &text, "groups: [tip]")) && err.contains("deployment.load.groups") && err.contains("tip"),
        "{err}"
    );

    let (out, path) = bad_config(&good.replace("name: small", "name: small\nmodel: [unclosed"));
    assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("{}:", path.display())));
}

/// `:N:` of the first line of `text` containing `needle`, the line of a YAML parser error
/// (then its column).
fn parser_line(text: &str, needle: &str) -> String {
    format!(":{}:", text.lines().position(|l| l.contains(needle)).expect("needle in text") + 1)
}

/// `dt` is a number or `auto`: a word is told so at its line, and `dt: auto`'s settings are
/// checked (a tolerance outside (0, 1)).
#[test]
fn a_time_step_is_a_number_or_auto() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let (out, path) = bad_config(&good.replace("duration: 0.1\n", "duration: 0.1\n  dt: fast\n"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("{}:", path.display())) && err.contains("or `auto`"), "{err}");
    let text = good.replace("duration: 0.1\n", "duration: 0.1\n  dt: auto\n  dt_tolerance: 2\n");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&at(&path, &text, "dt_tolerance: 2")) && err.contains("`deployment.dt_tolerance`: is 2; must lie in (0, 1)"),
        "{err}"
    );
}

/// `scheme: midpoint` has no β, γ and takes fixed steps: a β or `dt: auto` given is named
/// at its line, with the two ways out.
#[test]
fn the_midpoint_rule_takes_no_newmark_parameters() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    for scheme in ["midpoint", "energy_momentum"] {
        let text = good.replace(
            "duration: 0.1\n",
            &format!("duration: 0.1\n  scheme: {scheme}\n  newmark_beta: 0.3\n"),
        );
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&at(&path, &text, "newmark_beta: 0.3"))
                && err.contains("`deployment.newmark_beta`: applies to `scheme: newmark`")
                && err.contains("remove `newmark_beta`, or set `scheme: newmark`"),
            "{scheme}: {err}"
        );
        let text = good.replace("duration: 0.1\n", &format!("duration: 0.1\n  scheme: {scheme}\n  dt: auto\n"));
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&at(&path, &text, "dt: auto")) && err.contains("`deployment.dt`: `auto` applies to `scheme: newmark`"),
            "{scheme}: {err}"
        );
    }
}

#[test]
fn every_bad_value_is_reported_at_its_line() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good
        .replace("modes: [1, 6]", "modes: [1, 60]")
        .replace("duration: 0.1\n", "duration: 0.1\n  dt: -0.001\n")
        .replace("steps: 4", "steps: 0");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 3, "one line per error:\n{err}");
    // In file order, each `error: file:line: `field`: message` once.
    for (line, (needle, field)) in lines.iter().zip([
        ("modes: [1, 60]", "eigen.rayleigh.modes[1]"),
        ("steps: 0", "folding.steps"),
        ("dt: -0.001", "deployment.dt"),
    ]) {
        assert!(
            line.starts_with(&format!("error: {}: `{field}`: ", at(&path, &text, needle))),
            "{err}"
        );
    }

    // Bad values set by two axes: each once, at its own sweep value, with the first case it fails.
    let text = good
        .replace("{ substitution.cable: nylon }", "{ substitution.cable: nylon, folding.steps: 0 }")
        .replace("[0.1, 0.1] } }", "[1.5, 0.1] } }");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "each bad sweep value once:\n{err}");
    assert!(
        lines[0].contains(&at(&path, &text, "[1.5, 0.1]")) && lines[0].contains("ratios[0]"),
        "{err}"
    );
    assert!(
        lines[1].contains(&at(&path, &text, "folding.steps: 0")) && lines[1].contains("cable=nylon, zeta=0.05"),
        "{err}"
    );
}

/// A model that does not build skips the checks that need it (here the fold group), not the others.
#[test]
fn a_broken_model_skips_only_the_checks_that_need_it() {
    let text = "name: m
model:
  nodes:
    - { id: a, xyz: [0.0, 0.0, 0.0], fix: [x, y, z] }
    - { id: b, xyz: [1.0, 0.0, 0.0] }
  members:
    - { id: c1, nodes: [a, q], kind: cable, rest_length: 1.0 }
substitution: { strut: aluminium, cable: rubber }
folding:
  steps: 0
  prescribe: [{ group: tip, axis: z, displacement: 0.1 }]
";
    let (out, path) = bad_config(text);
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "{err}");
    assert!(
        lines[0].contains(&at(&path, text, "id: c1")) && lines[0].contains("`model.members[0]`") && lines[0].contains("q"),
        "{err}"
    );
    assert!(
        lines[1].contains(&at(&path, text, "steps: 0")) && lines[1].contains("folding.steps"),
        "{err}"
    );
}

/// Exclusive choices (Rayleigh damping's keys, a fold target) are checked when parsing:
/// a wrong combination names its section and the line, in the file or in a sweep value.
#[test]
fn conflicting_keys_are_named_at_their_line() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let rayleigh = "{ modes: [1, 6], ratios: [0.1, 0.1] }";
    for (from, to, section, problem) in [
        (rayleigh, "{ alpha: 0.5 }", "eigen.rayleigh", "`alpha` without `beta`"),
        (
            rayleigh,
            "{ modes: [1, 6], auto_modes: z, ratios: [0.1, 0.1] }",
            "eigen.rayleigh",
            "`modes` and `auto_modes` both given",
        ),
        (rayleigh, "{ modes: [1, 6] }", "eigen.rayleigh", "`ratios` missing"),
        (
            rayleigh,
            "{ alpha: 0.5, beta: 0.01, ratios: [0.1, 0.1] }",
            "eigen.rayleigh",
            "`alpha` and `beta` exclude",
        ),
        (
            "displacement: -0.5",
            "displacement: -0.5, to_base: true",
            "folding.prescribe",
            "`to_base: true` and `displacement` both given",
        ),
        ("displacement: -0.5", "to_base: false", "folding.prescribe", "give either"),
    ] {
        let text = good.replace(from, to);
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with(&format!("error: {}{}", path.display(), parser_line(&text, to)))
                && err.contains(&format!("`{section}`: {problem}")),
            "{err}"
        );
    }

    // Set by a sweep value: that value's line, under the path it sets.
    for (to, set, section) in [
        ("{ eigen.rayleigh.auto_modes: z }", "eigen.rayleigh.auto_modes", "eigen.rayleigh"),
        (
            "{ folding.prescribe: [{ group: top, axis: z }] }",
            "folding.prescribe",
            "folding.prescribe",
        ),
    ] {
        let text = good.replace("{ eigen.rayleigh.ratios: [0.05, 0.05] }", to);
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with(&format!("error: {}: `{set}`: ", at(&path, &text, to)))
                && err.contains(&format!("`{section}`: "))
                && err.contains("zeta=0.05")
                && err.lines().count() == 1,
            "{err}"
        );
    }
}

/// One case cannot converge (one Newton iteration, no step cutting); the others complete
/// and the run exits 1 with the reason in the summary.
#[test]
fn a_failing_case_does_not_stop_the_others() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.replace(
        "        - { label: \"0.1\", set: { eigen.rayleigh.ratios: [0.1, 0.1] } }",
        "        - { label: \"0.1\", set: { eigen.rayleigh.ratios: [0.1, 0.1], newton.max_iterations: 1, deployment.max_cuts: 0, folding.max_cuts: 0 } }",
    );
    let scratch_dir = scratch("diverge");
    let dir = scratch_dir.path();
    let path = dir.join("sweep.yaml");
    std::fs::write(&path, text).unwrap();
    let out = tsim(&["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let o = outcomes(dir);
    let failed: Vec<_> = o.iter().filter(|c| c["status"] == "failed").collect();
    assert_eq!(failed.len(), 2, "{o:?}");
    for f in failed {
        let s = f["reason"].as_str().unwrap();
        assert!(s.contains("did not converge"), "{s}");
    }
    // summary.csv: status is the bare word, the reason in its own column.
    let csv = std::fs::read_to_string(dir.join("small/summary.csv")).unwrap();
    assert_eq!(csv.lines().filter(|l| l.contains(",failed,computed,")).count(), 2, "{csv}");
    assert_eq!(o.iter().filter(|c| c["status"] == "complete").count(), 2);
}

/// `outputs.figures` runs the figures command on a finished case; without Python (here: a
/// command that does not exist) the case still completes and the outcome says why.
#[test]
fn figures_are_optional() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.split("sweep:").next().unwrap().to_string() + "outputs: { figures: true, hdf5: false, mcap: false }\n";
    let scratch_dir = scratch("figures");
    let dir = scratch_dir.path();
    let path = dir.join("one.yaml");
    std::fs::write(&path, text).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
    cmd.args(["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap()])
        .env("CI", "1")
        .env("TSIM_FIGURES", dir.join("no-such-figures-command"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let out = spawn(&mut cmd).wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let outcome: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("small/small/outcome.json")).unwrap()).unwrap();
    assert_eq!(outcome["status"], "complete");
    assert!(outcome["figures"].as_str().unwrap().starts_with("not drawn"), "{outcome}");

    // The built-in script with a Python that cannot draw: the case completes, and the
    // outcome and `tsim figures` (exit 2) say what is needed.
    let python = dir.join("no-such-python");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
    cmd.args(["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap(), "--force"])
        .env("CI", "1")
        .env("TSIM_PYTHON", &python)
        .env_remove("TSIM_FIGURES")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let out = spawn(&mut cmd).wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let outcome: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("small/small/outcome.json")).unwrap()).unwrap();
    let needs = "cannot draw the figures: it needs Python 3 with matplotlib, xarray, h5netcdf, pandas";
    assert!(outcome["figures"].as_str().unwrap().contains(needs), "{outcome}");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
    cmd.args(["figures", dir.join("small/small").to_str().unwrap()])
        .env("TSIM_PYTHON", &python)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let out = spawn(&mut cmd).wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains(needs));
}

/// Two values of one axis with the same label would share a case directory (case.yaml
/// from one, result.h5 from the other): `check` rejects them, naming both lines.
#[test]
fn duplicate_sweep_labels_are_rejected() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.replace("label: \"0.05\"", "label: \"0.1\"");
    assert_ne!(text, good, "the sweep fixture has a value labelled 0.05");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.contains("label: \"0.1\""))
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(lines.len(), 2, "{text}");
    assert!(
        err.contains(&format!("{}:{}", path.display(), lines[1]))
            && err.contains(&format!("(line {})", lines[0]))
            && err.contains("must differ"),
        "{err}"
    );
}

/// Axis names are part of every case id, a directory under --out (issue 29: `../../victim`
/// wrote into another run's case, an absolute name anywhere): a name with a separator,
/// `.` or `-`, two axes of one name, and a label too long for a file name are each
/// refused at their line, before anything is written (`bad_config` checks that).
#[test]
fn axis_names_and_labels_cannot_leave_the_run_directory() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let long = "9".repeat(300);
    for (from, to, field, needle) in [
        ("name: cable", "name: ../../victim", "sweep.axes[0].name", "name: ../../victim"),
        ("name: cable", "name: /tmp/elsewhere", "sweep.axes[0].name", "name: /tmp/elsewhere"),
        ("name: zeta", "name: cable", "sweep.axes[1].name", "- name: cable"),
        (
            "label: nylon",
            &format!("label: \"{long}\""),
            "sweep.axes[0].values[1].label",
            "label: \"999",
        ),
    ] {
        let text = good.replacen(from, to, 1);
        assert_ne!(text, good, "the fixture has `{from}`");
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        // The duplicate is reported at the second axis' line.
        let line = text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.contains(needle))
            .map(|(i, _)| i + 1)
            .last()
            .unwrap();
        assert!(
            err.contains(&format!("{}:{line}", path.display())) && err.contains(&format!("`{field}`")),
            "{to}: {err}"
        );
    }
}

/// `tsim check ... | head` and `tsim schema | head` end quietly when the reader stops
/// (issue 29: a panic, exit 101): the listing of a 4000-case sweep (some 250 kB, beyond
/// a pipe's 64 kB buffer) read for one line, the pipe then closed.
#[test]
fn a_reader_that_stops_early_is_not_an_error() {
    use std::io::BufRead;
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let values: String = (0..4000)
        .map(|k| format!("        - {{ label: v{k}, set: {{ outputs.every: 1 }} }}\n"))
        .collect();
    let text = format!(
        "{}sweep:\n  axes:\n    - name: many\n      values:\n{values}",
        good.split("sweep:").next().unwrap()
    );
    let dir = scratch("pipe");
    let path = dir.path().join("many.yaml");
    std::fs::write(&path, text).unwrap();
    let path = path.to_str().unwrap();
    for args in [&["check", path][..], &["schema"][..]] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_tsim"));
        cmd.args(args).stdout(Stdio::piped()).stderr(Stdio::piped());
        let mut child = spawn(&mut cmd);
        let mut first = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
        assert!(!first.is_empty(), "{args:?} printed nothing");
        // The reader is dropped here: the pipe is closed with most of the listing unread.
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// `--jobs 0` is a usage error; `--jobs 100000` (each job is a thread: it built 100 000
/// before any work) runs, capped at 4 per core, and says so.
#[test]
fn jobs_are_capped() {
    let out = tsim(&["run", SWEEP, "--jobs", "0", "--out", "/nonexistent/never-written"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(2) && err.contains("--jobs"), "{err}");
    let dir = scratch("jobs");
    let out = tsim(&["run", SWEEP, "--jobs", "100000", "--quiet", "--out", dir.path().to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    let cores = std::thread::available_parallelism().unwrap().get();
    assert!(out.status.success(), "{err}");
    assert!(err.contains(&format!("--jobs 100000 capped at {}", 4 * cores)), "{err}");
}

/// Links planted inside --out are not written through (issue 29: a case's result.h5 or
/// case.yaml linked to a file outside was overwritten): a case whose files are links gets
/// fresh files and leaves the targets alone; a case directory that is a link fails, naming
/// it, with nothing written where it points; the other cases complete.
#[test]
fn planted_links_are_not_followed() {
    let dir = scratch("links");
    let (out, victim) = (dir.path().join("runs"), dir.path().join("victim"));
    std::fs::create_dir_all(&victim).unwrap();
    for name in ["case.yaml", "result.h5"] {
        std::fs::write(victim.join(name), "precious").unwrap();
    }
    let run = out.join("small");
    let files = run.join("cable-rubber_zeta-0.05");
    std::fs::create_dir_all(&files).unwrap();
    for name in ["case.yaml", "result.h5"] {
        std::os::unix::fs::symlink(victim.join(name), files.join(name)).unwrap();
    }
    std::os::unix::fs::symlink(&victim, run.join("cable-nylon_zeta-0.1")).unwrap();
    let result = tsim(&["run", SWEEP, "--quiet", "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "one case fails: {err}");
    assert!(err.contains("cable-nylon_zeta-0.1") && err.contains("is a symbolic link"), "{err}");
    for name in ["case.yaml", "result.h5"] {
        assert_eq!(std::fs::read_to_string(victim.join(name)).unwrap(), "precious", "{name}");
        assert!(!files.join(name).symlink_metadata().unwrap().file_type().is_symlink());
    }
    let names: Vec<_> = std::fs::read_dir(&victim).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 2, "written into the linked directory: {names:?}");
    let outcomes = outcomes(&out);
    let complete = outcomes.iter().filter(|o| o["status"] == "complete").count();
    assert_eq!(complete, 3, "{outcomes:?}");
}

/// `tsim collect` takes the run's lock (issue 29: a run re-creating a result.h5 that
/// collect was reading failed, its earlier file left truncated): while a live run holds
/// the directory collect refuses, naming the holder; once it is free, collect writes.
#[test]
fn collect_waits_for_no_run() {
    let dir = scratch("collect-lock");
    let out = dir.path().to_str().unwrap();
    assert!(tsim(&["run", SWEEP, "--quiet", "--out", out]).status.success());
    let run = dir.path().join("small");
    // A lock held by a live process on this host: this test's own.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    std::fs::write(run.join(".lock"), format!("{} {}", host.trim(), std::process::id())).unwrap();
    let held = tsim(&["collect", run.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&held.stderr);
    assert_eq!(held.status.code(), Some(2), "{err}");
    assert!(err.contains("is in use") && err.contains(&std::process::id().to_string()), "{err}");
    std::fs::remove_file(run.join(".lock")).unwrap();
    let free = tsim(&["collect", run.to_str().unwrap()]);
    assert!(free.status.success(), "{}", String::from_utf8_lossy(&free.stderr));
}

/// A rerun that cannot take over a result.h5 must leave it whole (issue 29: a reader's
/// lock on it made `--force` fail and truncated the complete file). The outputs are created
/// beside the old ones and renamed over them: the rerun succeeds while a reader holds the
/// old file (an HDF5 reader's shared lock), and that reader goes on reading the old bytes.
#[test]
fn a_rerun_replaces_a_file_a_reader_holds_without_harming_it() {
    use std::io::Read;
    use std::os::fd::AsRawFd;
    let dir = scratch("replace");
    let out = dir.path().to_str().unwrap();
    assert!(tsim(&["run", SWEEP, "--quiet", "--out", out]).status.success());
    let case = dir.path().join("small/cable-nylon_zeta-0.1");
    let old = std::fs::read(case.join("result.h5")).unwrap();
    let mut held = std::fs::File::open(case.join("result.h5")).unwrap();
    // The lock an HDF5 reader takes (flock, shared), which a truncating create cannot get.
    assert_eq!(unsafe { libc::flock(held.as_raw_fd(), libc::LOCK_SH | libc::LOCK_NB) }, 0);
    let rerun = tsim(&["run", SWEEP, "--quiet", "--out", out, "--force", "--only", "cable-nylon_zeta-0.1"]);
    assert!(rerun.status.success(), "{}", String::from_utf8_lossy(&rerun.stderr));
    let mut seen = Vec::new();
    held.read_to_end(&mut seen).unwrap();
    assert!(
        seen == old,
        "the reader's file changed under it ({} of {} bytes)",
        seen.len(),
        old.len()
    );
    let status = with_h5(&case.join("result.h5"), |f| {
        f.attr("status")
            .unwrap()
            .read_scalar::<hdf5::types::FixedUnicode<512>>()
            .unwrap()
            .as_str()
            .to_string()
    });
    assert_eq!(status, "complete");
    let leftovers: Vec<_> = std::fs::read_dir(&case)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().ends_with(".new"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// Values that would run forever, overflow the stack or find nothing are rejected before
/// any work, each at its line: a step longer than its stage, a bisection deeper than 30
/// halvings (it recurses once per halving), negative or zero measure coefficients, a
/// name that would leave `--out`.
#[test]
fn nonsense_values_are_rejected_at_their_lines() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good
        .split("sweep:")
        .next()
        .unwrap()
        .replace(
            "formfinding: {}",
            "formfinding: { measure: { strut_ea: -1.0, cable_n: 0.0, cable_c: { uniform: 0.0 } } }",
        )
        .replace("  duration: 0.1\n", "  duration: 0.1\n  dt: 0.5\n  max_cuts: 10000\n")
        .replace("name: small", "name: ../escape");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    let ff = at(&path, &text, "formfinding:");
    for needle in [
        format!("{ff}: `formfinding.measure.strut_ea`"),
        format!("{ff}: `formfinding.measure.cable_n`"),
        format!("{ff}: `formfinding.measure.cable_c.uniform`"),
        format!("{}: `deployment.dt`", at(&path, &text, "dt: 0.5")),
        format!("{}: `deployment.max_cuts`", at(&path, &text, "max_cuts: 10000")),
        format!("{}: `name`", at(&path, &text, "name: ../escape")),
    ] {
        assert!(err.contains(&needle), "missing {needle} in\n{err}");
    }
}

/// A prestress scaled to nothing leaves a real structure without stiffness against its
/// mechanisms: the case fails at substitution, naming the softest direction, instead of
/// running eigen analysis and dynamics about an unstable state.
#[test]
fn an_unstable_structure_fails_at_substitution() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good
        .split("sweep:")
        .next()
        .unwrap()
        .replace("cable: rubber }", "cable: rubber, prestress_scale: 1.0e-300 }");
    let scratch_dir = scratch("unstable");
    let dir = scratch_dir.path();
    let path = dir.join("unstable.yaml");
    std::fs::write(&path, &text).unwrap();
    let out = tsim(&["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let o = outcomes(dir);
    assert_eq!(o[0]["status"], "failed");
    let reason = o[0]["reason"].as_str().unwrap();
    // The prestress scaled to 1e-300 leaves the mechanisms of the tower no stiffness that
    // round-off can resolve: their eigenvalue lies in the band, and the remedy is the
    // form-found prestress.
    assert!(
        reason.starts_with("substitution: the real structure's stability is indeterminate at round-off")
            && reason.contains("node `")
            && reason.contains("`substitution.prestress_scale`"),
        "{reason}"
    );
    // The refused structure stays on record, so that the user can look at what to change:
    // result.h5 holds the model (its rest lengths) and the form-found shape.
    let h5 = dir.join("small").join(o[0]["id"].as_str().unwrap()).join("result.h5");
    let (shape, rest): (Vec<f64>, Vec<f64>) = with_h5(&h5, |f| {
        let read = |name: &str| f.dataset(name).unwrap().read_raw::<f64>().unwrap();
        (read("formfinding/position"), read("model/rest_length"))
    });
    assert_eq!(shape.len(), 3 * 6, "the prism's 6 nodes");
    assert!(shape.iter().chain(&rest).all(|x| x.is_finite()) && rest.len() == 12);
}

/// A resume checks what it trusts: a truncated result.h5, a deleted replay.mcap and a
/// result.h5 with one byte flipped in its middle (same length and signature; issue 29:
/// served as complete) make their cases run again, the intact ones are skipped; `tsim
/// collect` lists the flipped one as changed rather than reading it. And a second `tsim run` into a
/// directory in use (its `.lock` names a live process on this host: this test's own) is
/// refused with the holder named, writing nothing.
#[test]
fn resume_verifies_outputs_and_a_used_directory_is_locked() {
    let out_dir = scratch("verify");
    let out = out_dir.path();
    let run = |extra: &[&str]| tsim(&[&["run", SWEEP, "--out", out.to_str().unwrap()], extra].concat());
    assert!(run(&[]).status.success());
    let dir = out.join("small");
    let h5 = dir.join("cable-rubber_zeta-0.05/result.h5");
    let len = std::fs::metadata(&h5).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&h5).unwrap().set_len(len / 2).unwrap();
    std::fs::remove_file(dir.join("cable-nylon_zeta-0.1/replay.mcap")).unwrap();
    let flipped = dir.join("cable-rubber_zeta-0.1/result.h5");
    let mut bytes = std::fs::read(&flipped).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x01;
    std::fs::write(&flipped, &bytes).unwrap();
    let collected = tsim(&["collect", dir.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&collected.stderr);
    assert_eq!(collected.status.code(), Some(1), "{err}");
    assert!(
        err.contains("missing: cable-rubber_zeta-0.1: result.h5's contents changed"),
        "{err}"
    );
    assert!(run(&[]).status.success());
    let status: Vec<(String, String, String)> = outcomes(out)
        .iter()
        .map(|o| {
            let text = |k: &str| o[k].as_str().unwrap().to_string();
            (text("id"), text("status"), text("run"))
        })
        .collect();
    for (id, s, run) in &status {
        let damaged = ["cable-rubber_zeta-0.05", "cable-nylon_zeta-0.1", "cable-rubber_zeta-0.1"].contains(&id.as_str());
        assert_eq!(s, "complete", "{status:?}");
        assert_eq!(run, if damaged { "computed" } else { "reused" }, "{status:?}");
    }

    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    std::fs::write(dir.join(".lock"), format!("{} {}", host.trim(), std::process::id())).unwrap();
    let before = std::fs::metadata(dir.join("summary.json")).unwrap().modified().unwrap();
    let locked = run(&[]);
    let err = String::from_utf8_lossy(&locked.stderr);
    // 2, as collect exits then: nothing was run (it was 1, a failed case's code).
    assert_eq!(locked.status.code(), Some(2), "{err}");
    assert!(err.contains("in use") && err.contains(&std::process::id().to_string()), "{err}");
    assert_eq!(std::fs::metadata(dir.join("summary.json")).unwrap().modified().unwrap(), before);
    std::fs::remove_file(dir.join(".lock")).unwrap();
}

/// SIGINT and SIGTERM in the middle of a run, and SIGINT twice 5 ms apart (issue 29:
/// the second exited at once, leaving a result.h5 `running`, no outcome, a stale lock):
/// exit code 130, every case complete or marked `interrupted` (in the summary and in its
/// result.h5, which opens as a finished file), no lock left, and a rerun completes the
/// sweep. A long deployment (400 s of the small prism, about a second per case, one case
/// at a time, every 1000th step recorded) keeps the run busy when the signal comes 0.5 s
/// in.
#[test]
fn a_signal_interrupts_cleanly_and_a_rerun_finishes() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good
        .replace("deployment:\n  duration: 0.1", "deployment:\n  duration: 400.0")
        .replace("sweep:", "outputs: { every: 1000 }\nsweep:");
    assert_ne!(text, good);
    for (signal, count) in [(libc::SIGINT, 1), (libc::SIGTERM, 1), (libc::SIGINT, 2)] {
        let scratch_dir = scratch(&format!("signal{signal}x{count}"));
        let dir = scratch_dir.path();
        let path = dir.join("long.yaml");
        std::fs::write(&path, &text).unwrap();
        let args = [
            "run",
            path.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--jobs",
            "1",
            "--quiet",
        ];
        let child = spawn(
            Command::new(env!("CARGO_BIN_EXE_tsim"))
                .args(args)
                .stderr(std::process::Stdio::piped()),
        );
        std::thread::sleep(Duration::from_millis(500));
        // libc, not the `kill` program: a minimal Debian has no procps (found by the
        // clean-machine transcript, docs/transcripts/clean_debian.md).
        let pid = libc::pid_t::try_from(child.id()).unwrap();
        for k in 0..count {
            if k > 0 {
                std::thread::sleep(Duration::from_millis(5));
            }
            assert_eq!(unsafe { libc::kill(pid, signal) }, 0, "kill {pid}");
        }
        let output = child.wait_with_output().unwrap();
        assert_eq!(output.status.code(), Some(130), "{signal}");
        // It says so, names the complete cases and what a rerun does.
        let err = String::from_utf8_lossy(&output.stderr);
        assert!(
            err.contains("interrupted: ") && err.contains("Rerunning the same command reuses"),
            "{err}"
        );
        let o = outcomes(dir);
        for case in o.iter().filter(|c| c["status"] == "complete") {
            assert!(err.contains(case["id"].as_str().unwrap()), "{err}");
        }
        assert_eq!(o.len(), 4);
        assert!(o.iter().any(|c| c["status"] == "interrupted"), "{signal}: {o:?}");
        for case in o.iter().filter(|c| c["status"] == "interrupted") {
            let h5 = dir.join("small").join(case["id"].as_str().unwrap()).join("result.h5");
            if h5.exists() {
                let s: hdf5::types::FixedUnicode<512> = with_h5(&h5, |file| file.attr("status").unwrap().read_scalar().unwrap());
                assert_eq!(s.as_str(), "interrupted", "{}", h5.display());
            }
        }
        assert!(o.iter().all(|c| c["status"] == "complete" || c["status"] == "interrupted"), "{o:?}");
        assert!(!dir.join("small/.lock").exists(), "the lock is released");
        let again = tsim(&args);
        assert!(again.status.success(), "{}", String::from_utf8_lossy(&again.stderr));
        let o = outcomes(dir);
        assert!(o.iter().all(|c| c["status"] == "complete"), "{o:?}");
    }
}

/// Work past a limit is refused by `check` and `run` with the estimate, the limit, the
/// largest part at its line and the override; `--allow-large` or a `limits` section lets
/// it pass `check`. The three limits: output of the run (a deployment of 5·10⁷ steps,
/// about 90 GB), peak memory of a case (the dense eigen stage of a 2000-stage prism tower,
/// 36 000 free DOF), steps of a stage (10⁹ folding steps).
#[test]
fn work_over_a_limit_is_refused_naming_the_override() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let base = good.split("sweep:").next().unwrap().to_string();
    let cases = [
        (
            base.replace("  duration: 0.1\n", "  duration: 50000.0\n"),
            "duration: 50000.0",
            "`deployment.duration`: estimated output ",
            "limits: { max_output_gb: 1000 }",
        ),
        (
            // The dense eigen path asked for: the default (partial above 1500 DOF) fits.
            base.replace("stages: 1,", "stages: 2000,")
                .replace("eigen:\n", "eigen:\n  solver: dense\n"),
            "eigen:",
            "`eigen`: estimated peak memory ",
            "limits: { max_memory_gb: 100 }",
        ),
        (
            base.replace("steps: 4", "steps: 1000000000"),
            "steps: 1000000000",
            "`folding.steps`: is 1.000e9 steps",
            "limits: { max_steps: 1000000000, max_output_gb: 10000 }",
        ),
    ];
    for (text, needle, message, raised) in cases {
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("{}: {message}", at(&path, &text, needle)))
                && err.contains("--allow-large")
                && err.contains("raise `limits."),
            "{err}"
        );
        let path = path.to_str().unwrap();
        let check = tsim(&["check", path]);
        assert_eq!(check.status.code(), Some(2));
        assert_eq!(String::from_utf8_lossy(&check.stderr), err);
        let allowed = tsim(&["check", path, "--allow-large"]);
        assert!(allowed.status.success(), "{}", String::from_utf8_lossy(&allowed.stderr));
        let listed = String::from_utf8_lossy(&allowed.stdout);
        assert!(listed.contains("limit none: --allow-large"), "{listed}");
        std::fs::write(path, format!("{text}{raised}\n")).unwrap();
        let raised = tsim(&["check", path]);
        assert!(raised.status.success(), "{}", String::from_utf8_lossy(&raised.stderr));
    }
}

/// The `limits` section belongs to the run: every case's resolved config (`case.yaml`,
/// which a resume compares) is the same with it or without it, and a bad limit is an
/// error at its line.
#[test]
fn limits_stay_out_of_case_yaml() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let with = good.replace("masses: paper", "masses: paper\nlimits: { max_memory_gb: 1, max_steps: 1000 }");
    let yaml = |text: &str| -> Vec<String> {
        tsim::run::expand(text, "small.yaml", false)
            .unwrap()
            .cases
            .into_iter()
            .map(|c| c.yaml().unwrap())
            .collect()
    };
    assert_eq!(yaml(&good), yaml(&with));
    assert!(!yaml(&with)[0].contains("limits"));
    let bad = good.replace("masses: paper", "masses: paper\nlimits: { max_output_gb: -1 }");
    let (out, path) = bad_config(&bad);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{}: `limits.max_output_gb`", at(&path, &bad, "max_output_gb"))),
        "{err}"
    );
    // A limit lowered below the case's steps (100 deployment steps) refuses it.
    let low = good.replace("masses: paper", "masses: paper\nlimits: { max_steps: 50 }");
    let (out, _) = bad_config(&low);
    assert!(String::from_utf8_lossy(&out.stderr).contains("at most 5e1 are allowed"));
}

/// `tsim run` ends with `collected.h5`; `tsim collect` writes it again and exits 0 when
/// every case is complete, 1 listing a case whose result.h5 is gone (the file still
/// written, that case's row kept), and 2 for a directory that is no run.
#[test]
fn collect_lists_missing_cases_in_its_exit_code() {
    let out_dir = scratch("collect");
    let out = out_dir.path();
    let run = tsim(&["run", SWEEP, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let dir = out.join("small");
    assert!(dir.join("collected.h5").is_file());
    let all = tsim(&["collect", dir.to_str().unwrap()]);
    assert_eq!(all.status.code(), Some(0), "{}", String::from_utf8_lossy(&all.stderr));

    std::fs::remove_file(dir.join("cable-nylon_zeta-0.05/result.h5")).unwrap();
    let some = tsim(&["collect", dir.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&some.stderr);
    assert_eq!(some.status.code(), Some(1), "{err}");
    assert!(err.contains("missing: cable-nylon_zeta-0.05: "), "{err}");
    assert_eq!(err.matches("missing: ").count(), 1, "{err}");
    let cases = with_h5(&dir.join("collected.h5"), |file| file.dataset("case").unwrap().size());
    assert_eq!(cases, 4);

    let none = tsim(&["collect", out.to_str().unwrap()]);
    assert_eq!(none.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&none.stderr).contains("summary.json"));
}

/// A value of the wrong type set by a sweep axis is reported at that value's line, under
/// the dotted path it sets, in plain words.
#[test]
fn a_bad_type_in_a_sweep_value_names_its_path_and_line() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.replace("{ eigen.rayleigh.ratios: [0.05, 0.05] }", "{ eigen.rayleigh.ratios: \"x\" }");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!("error: {}: `eigen.rayleigh.ratios`", at(&path, &text, "ratios: \"x\"")))
            && err.contains("zeta=0.05")
            && err.contains("expected")
            && !err.contains("invalid type")
            && err.lines().count() == 1,
        "{err}"
    );
    // Two settings in one value: the one that breaks is named.
    let text = good.replace(
        "{ substitution.cable: nylon }",
        "{ substitution.cable: nylon, folding.steps: many }",
    );
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!("error: {}: `folding.steps`", at(&path, &text, "steps: many"))),
        "{err}"
    );
}

/// YAML errors read as `file:line:col: what is wrong`, in plain words: no parser
/// internals (`invalid u64`, `DuplicateKeyPolicy`, `--> <input>`), no doubled prefix.
#[test]
fn yaml_errors_are_plain_words_at_file_line_col() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let plain = |err: &str| {
        !err.contains("<input>")
            && !err.contains("invalid u64")
            && !err.contains("DuplicateKeyPolicy")
            && !err.contains("Options")
            && err.matches("error:").count() == 1
    };
    // A missing comma in a flow mapping.
    let text = good.replace("struts: 3, stages: 1,", "struts: 3 stages: 1,");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    let col = text.lines().nth(3).unwrap().find("3 stages").unwrap() + 1;
    assert!(
        err.starts_with(&format!("error: {}:4:{col}: ", path.display())) && err.contains("comma") && plain(&err),
        "{err}"
    );
    // A key given twice: both lines, and the fix.
    let text = good.replace("masses: paper", "masses: paper\nmasses: none");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!("error: {}:8:1: ", path.display()))
            && err.contains("key `masses` appears twice (lines 7 and 8); keep one")
            && plain(&err),
        "{err}"
    );
    // A line added after `masses:` (line 8), and the start of its error: an unknown key
    // gets the closest known one; a single value where a list is expected, the key and
    // the list's form.
    for (line, expected) in [
        ("massess: 3", "8:1: unknown key `massess` (did you mean `masses`?)"),
        (
            "gravity: -9.81",
            "8:10: `gravity` takes a list here, not a single value: its items in brackets",
        ),
    ] {
        let text = good.replace("masses: paper", &format!("masses: paper\n{line}"));
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with(&format!("error: {}:{expected}", path.display())) && plain(&err),
            "{err}"
        );
    }
    // A sweep setting misspelt: the closest key where it goes astray.
    let text = good.replace("set: { substitution.cable: nylon }", "set: { substitution.cabel: nylon }");
    let (out, _) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`substitution.cabel` is not a setting of the case config (no `cabel` there; did you mean `cable`?)"),
        "{err}"
    );
}

/// Names that are not known get the closest known one: keys, materials, node groups, node ids.
#[test]
fn unknown_names_suggest_the_closest() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    for (from, to, needle, suggestion) in [
        ("strut: aluminium", "strut: aluminum", "aluminum", "`aluminium`"),
        (
            "groups: [top], force: [0.0",
            "groups: [tops], force: [0.0",
            "groups: [tops]",
            "`top`",
        ),
        ("radius: 2.0,", "radius: 2.0, strut_lenght: 5.0,", "strut_lenght", "`strut_length`"),
    ] {
        let text = good.replace(from, to);
        let (out, path) = bad_config(&text);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("{}:", at(&path, &text, needle))) && err.contains(&format!("did you mean {suggestion}?")),
            "{err}"
        );
    }
    let text = "name: m
model:
  nodes:
    - { id: base1, xyz: [0.0, 0.0, 0.0], fix: [x, y, z] }
    - { id: tip, xyz: [1.0, 0.0, 0.0] }
  members:
    - { id: c1, nodes: [base1, tpi], kind: cable, restlength: 1.0 }
substitution: { strut: aluminium, cable: rubber }
";
    let (out, path) = bad_config(text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{}:", at(&path, text, "restlength"))) && err.contains("did you mean `rest_length`?"),
        "{err}"
    );
    let text = text.replace("restlength", "rest_length");
    let (out, _) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unknown node `tpi` (did you mean `tip`?)"), "{err}");
}

/// A Newton failure names its stage (`equilibrium` for a model given with rest lengths,
/// not form-finding), the criterion that failed against its tolerance, and the settings
/// to change: the tolerances, `newton.max_iterations`, and for a stepped stage smaller
/// steps (its `dt` or `steps`, its `max_cuts`).
#[test]
fn newton_failures_name_the_criterion_and_the_settings() {
    let text = "name: eq
model:
  nodes:
    - { id: a, xyz: [0.0, 0.0, 0.0], fix: [x, y, z] }
    - { id: b, xyz: [0.7, 0.3, 0.0], fix: [y, z] }
    - { id: c, xyz: [2.0, 0.0, 0.0], fix: [x, y, z] }
  members:
    - { id: c1, nodes: [a, b], kind: cable, rest_length: 0.5 }
    - { id: c2, nodes: [b, c], kind: cable, rest_length: 0.5 }
substitution: { strut: aluminium, cable: rubber }
newton: { max_iterations: 1 }
";
    let scratch_dir = scratch("newton-eq");
    let dir = scratch_dir.path();
    let path = dir.join("eq.yaml");
    std::fs::write(&path, text).unwrap();
    let out = tsim(&["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("eq/summary.json")).unwrap()).unwrap();
    assert_eq!(v[0]["status"], "failed");
    let s = v[0]["reason"].as_str().unwrap();
    assert!(
        s.starts_with("equilibrium: ")
            && s.contains("force residual")
            && s.contains("tolerance")
            && s.contains("`newton.max_iterations`")
            && s.contains("node `b` direction x"),
        "{s}"
    );

    // A tower's form-finding at one iteration: the criterion that failed, its tolerance.
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.split("sweep:").next().unwrap().to_string() + "newton: { max_iterations: 1 }\n";
    let scratch_dir = scratch("newton-ff");
    let dir = scratch_dir.path();
    let path = dir.join("ff.yaml");
    std::fs::write(&path, text).unwrap();
    let out = tsim(&["run", path.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("small/summary.json")).unwrap()).unwrap();
    assert_eq!(v[0]["status"], "failed");
    let s = v[0]["reason"].as_str().unwrap();
    assert!(
        s.starts_with("form-finding: ")
            && (s.contains("force residual") || s.contains("displacement increment"))
            && s.contains("exceeds its tolerance")
            && s.contains("`newton.max_iterations`"),
        "{s}"
    );
}

/// `struts: 2` is refused as such, before any model building could report its ring
/// members as duplicates.
#[test]
fn a_tower_of_two_struts_is_refused_plainly() {
    let good = std::fs::read_to_string(SWEEP).unwrap();
    let text = good.replace("struts: 3,", "struts: 2,");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!("error: {}: `model.tower`", at(&path, &text, "struts: 2")))
            && err.contains("at least 3 struts")
            && !err.contains("join the same nodes")
            && err.lines().count() == 1,
        "{err}"
    );
}

/// `--only` runs some cases of a sweep: the others are `pending` in the summaries, and
/// `check --out` shows each case as new, complete or changed before a run; a full rerun
/// then reuses the complete ones and computes the rest.
#[test]
fn only_runs_some_cases_and_check_shows_where_each_stands() {
    let out_dir = scratch("only");
    let out = out_dir.path();
    let o = out.to_str().unwrap();
    let states = |config: &str| -> Vec<(String, String)> {
        let check = tsim(&["check", config, "--out", o]);
        assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stderr));
        let text = String::from_utf8_lossy(&check.stdout).to_string();
        assert!(text.lines().next().unwrap().contains(&format!("{o}/small/")), "{text}");
        text.lines()
            .filter(|l| l.starts_with("  "))
            .map(|l| {
                let mut w = l.split_whitespace();
                (w.next().unwrap().to_string(), w.next().unwrap().to_string())
            })
            .collect()
    };
    assert!(states(SWEEP).iter().all(|(_, s)| s == "new"));

    let run = tsim(&["run", SWEEP, "--out", o, "--only", "cable-nylon_*", "--quiet"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let by_id: Vec<(String, String, String)> = outcomes(out)
        .iter()
        .map(|c| {
            (
                c["id"].as_str().unwrap().into(),
                c["status"].as_str().unwrap().into(),
                c["run"].as_str().unwrap().into(),
            )
        })
        .collect();
    for (id, status, run) in &by_id {
        let expected = if id.starts_with("cable-nylon_") {
            ("complete", "computed")
        } else {
            ("pending", "not_started")
        };
        assert_eq!((status.as_str(), run.as_str()), expected, "{id}");
    }
    assert!(
        !out.join("small/cable-rubber_zeta-0.05").exists(),
        "an unselected case is not touched"
    );
    let listed = states(SWEEP);
    assert_eq!(listed.iter().filter(|(_, s)| s == "complete").count(), 2, "{listed:?}");
    assert_eq!(listed.iter().filter(|(_, s)| s == "new").count(), 2, "{listed:?}");

    // A changed setting shows as `changed` for the cases written with the old one.
    let text = std::fs::read_to_string(SWEEP)
        .unwrap()
        .replace("\nsweep:", "\nnewton: { max_iterations: 49 }\nsweep:");
    assert!(text.contains("max_iterations: 49"));
    let changed = out.join("changed.yaml");
    std::fs::write(&changed, &text).unwrap();
    let listed = states(changed.to_str().unwrap());
    assert_eq!(listed.iter().filter(|(_, s)| s == "changed").count(), 2, "{listed:?}");

    let all = tsim(&["run", SWEEP, "--out", o, "--quiet"]);
    assert!(all.status.success());
    assert!(String::from_utf8_lossy(&all.stderr).contains("2 complete cases reused"));
    assert!(outcomes(out).iter().all(|c| c["status"] == "complete"));
}

/// `--only` that selects nothing is a typo, not a run: `run` and `check` refuse it with the
/// pattern, the config and the closest id, exit 2, and write nothing; `check --only` lists
/// just the cases a run with it would select.
#[test]
fn only_that_selects_nothing_is_refused_and_check_previews_a_selection() {
    let out_dir = scratch("only-none");
    let o = out_dir.path().to_str().unwrap();
    for command in ["run", "check"] {
        let refused = tsim(&[
            command,
            SWEEP,
            "--out",
            o,
            "--only",
            "cable-nylon_zeta-0.05",
            "--only",
            "cable-nylon_zeta-0.01",
        ]);
        let err = String::from_utf8_lossy(&refused.stderr);
        assert_eq!(refused.status.code(), Some(2), "{command}: {err}");
        assert!(
            err.starts_with("error: `--only cable-nylon_zeta-0.01` matches none of the 4 case(s) of ")
                && err.contains("(did you mean `cable-nylon_zeta-0.05`?)")
                && err.contains("`tsim check "),
            "{command}: {err}"
        );
    }
    assert!(!out_dir.path().join("small").exists(), "a refused run writes nothing");
    let check = tsim(&["check", SWEEP, "--out", o, "--only", "cable-nylon_*"]);
    assert!(check.status.success());
    let listed = String::from_utf8_lossy(&check.stdout);
    let ids: Vec<&str> = (listed.lines().filter(|l| l.starts_with("  ")))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(ids, ["cable-nylon_zeta-0.05", "cable-nylon_zeta-0.1"], "{listed}");
    assert!(listed.lines().next().unwrap().contains(": 2 of 4 case(s) into "), "{listed}");
}

/// A model's error points at the member or node it names, not at `model:`; a config with
/// no `substitution` says so at its first line, not at whatever key comes last.
#[test]
fn model_and_section_errors_point_where_the_fix_goes() {
    let text = "name: m
model:
  nodes:
    - { id: a, xyz: [0, 0, 0], fix: [x, y, z] }
    - { id: b, xyz: [1, 0, 0], fix: [y, z] }
  members:
    - { id: ab, nodes: [a, b], kind: strut, rest_length: 1.0 }
    - { id: ac, nodes: [a, bb], kind: strut, rest_length: 1.0 }
substitution: { strut: steel, cable: steel }
";
    let (out, path) = bad_config(text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!(
            "error: {}: `model.members[1]`: member `ac` refers to unknown node `bb` (did you mean `b`?)",
            at(&path, text, "id: ac")
        )),
        "{err}"
    );
    let text = text.replace("substitution: { strut: steel, cable: steel }\n", "");
    let (out, path) = bad_config(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim_end(),
        format!(
            "error: {}:1: the config has no `substitution` section: the real materials that replace the members, \
             e.g. `substitution: {{ strut: aluminium, cable: rubber }}` (docs/config.md)",
            path.display()
        )
    );
}

/// `tsim completions SHELL` prints a completion script that knows the subcommands and
/// their flags (fish spells them `-l only`); an unknown shell is a usage error.
#[test]
fn completions_know_the_commands() {
    for shell in ["bash", "zsh", "fish"] {
        let out = tsim(&["completions", shell]);
        assert!(out.status.success(), "{shell}");
        let script = String::from_utf8_lossy(&out.stdout);
        assert!(
            ["run", "check", "collect", "submit", "shard", "only", "allow-large"]
                .iter()
                .all(|w| script.contains(w)),
            "{shell}"
        );
    }
    assert_eq!(tsim(&["completions", "cmd.exe"]).status.code(), Some(2));
}

/// A grid's bad values are each named at their line: zero modules, a negative cell, a grid
/// beside a tower.
#[test]
fn a_bad_grid_is_refused_at_its_lines() {
    let text = "name: g\nmodel:\n  grid:\n    nx: 0\n    ny: 2\n    cell: -1.0\nformfinding: {}\nsubstitution: { strut: aluminium, cable: steel_cable }\n";
    let (out, path) = bad_config(text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{}: `model.grid.nx`: is 0", at(&path, text, "nx: 0"))),
        "{err}"
    );
    assert!(
        err.contains(&format!("{}: `model.grid.cell`", at(&path, text, "cell: -1.0"))),
        "{err}"
    );
    let both = text
        .replace("  grid:\n", "  tower: { struts: 3 }\n  grid:\n")
        .replace("nx: 0", "nx: 1")
        .replace("-1.0", "1.0");
    let (out, _) = bad_config(&both);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("`model`: give one of `tower`, `grid`"), "{err}");
}

/// An alias bomb (10⁹ values if expanded) is refused by the YAML parser's node budget at
/// the line that breaches it, quickly, not read until memory runs out.
#[test]
fn an_alias_bomb_is_refused_at_its_line() {
    let bomb = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/corpus/alias_bomb.yaml");
    let out = tsim(&["check", bomb]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("{bomb}:30:")) && err.contains("too large or too complex"),
        "{err}"
    );
}
