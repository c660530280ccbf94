//! The `tsim` command line: parse, call the library, map outcomes to exit codes
//! (0 every case complete, 1 a case failed, 2 a config or usage error, 130 interrupted by
//! SIGINT or SIGTERM). In the library so that the `tsim` binary and the Python package's
//! `tsim` command (python/) are one program.

use crate::config::{bytes_text, json_schema, ConfigError};
use crate::run::{
    collect, default_jobs, install_interrupt, interrupted, load, merge, require_matches, run, selected, submit, Expanded, OnDisk, Plan,
    RunOptions, Shard, SubmitOptions, Tally, EXIT_INTERRUPTED,
};
use clap::{CommandFactory, Parser, Subcommand};
use std::path::{Path, PathBuf};

/// A write to stdout, with a reader that stopped early (`| head`: a closed pipe) taken
/// as the end of the output, not as an error.
fn unless_closed(written: std::io::Result<()>) -> std::io::Result<()> {
    match written {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}

/// Most cases `tsim run` runs at once per core: each is a thread, and more only queue for
/// the same cores.
const JOBS_PER_CORE: usize = 4;

/// `--jobs` (or the default), capped at [`JOBS_PER_CORE`] × the cores here with a warning:
/// `--jobs 100000` built 100 000 threads before any work.
pub fn capped_jobs(jobs: Option<u64>) -> usize {
    let Some(asked) = jobs else { return default_jobs() };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cap = JOBS_PER_CORE * cores;
    match usize::try_from(asked) {
        Ok(n) if n <= cap => n,
        _ => {
            eprintln!("warning: --jobs {asked} capped at {cap} ({JOBS_PER_CORE} × the {cores} cores here)");
            cap
        }
    }
}

#[derive(Parser)]
#[command(
    name = "tsim",
    // The git revision is read at build time by build.rs ("unknown" without git).
    version = concat!(env!("CARGO_PKG_VERSION"), " (git ", env!("TSIM_GIT_REVISION"), ")"),
    about = "Tensegrity simulation by the tangent stiffness method: form-finding, real materials, vibration, folding, deployment",
    after_help = "Examples:\n  tsim check configs/sweep.yaml\n  tsim run configs/paper.yaml\n  tsim run configs/sweep.yaml --jobs 2 --out runs\n  tsim run configs/sweep.yaml --force   # rerun complete cases too\n  tsim run big.yaml --allow-large       # past the output, memory and step limits"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run every case of a config (a sweep's cross product) in parallel.
    Run {
        /// The YAML config.
        config: PathBuf,
        /// Output root; cases go to OUT/<name>/<case id>/.
        #[arg(long, default_value = "runs")]
        out: PathBuf,
        /// Cases run at once [default: SLURM_CPUS_PER_TASK, else the available cores;
        /// at most 4 per core, and never more than the cases to run].
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        jobs: Option<u64>,
        /// Rerun cases that are already complete.
        #[arg(long)]
        force: bool,
        /// No progress bars; one line per finished case.
        #[arg(long)]
        quiet: bool,
        /// Run only the cases whose id matches (a glob such as `strut-steel_*`, or a
        /// substring; repeatable). Complete cases are still reused and the others are
        /// summarized as `pending`; with --force the matching ones are rerun. A pattern
        /// that matches no case is an error (`tsim check --only` previews a selection).
        #[arg(long, value_name = "PATTERN")]
        only: Vec<String>,
        /// Lift the limits on estimated output (per run), peak memory (per case) and steps
        /// (per stage); the config's `limits` section raises them one by one.
        #[arg(long)]
        allow_large: bool,
        /// Run only shard I of N (I from 0 to N-1; disjoint slices balanced by estimated
        /// work, the same on every resume) and write OUT/<name>/shards/shard-I-of-N.json in
        /// place of the summaries; `auto`: the task of a Slurm job array
        /// (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT).
        /// `tsim collect` merges the shards.
        #[arg(long, value_name = "I/N|auto", value_parser = parse_shard)]
        shard: Option<Shard>,
    },
    /// Submit a sweep to Slurm: a job array of shards (`tsim run --shard`) and a merge job
    /// (`tsim collect`) after it; prints both job ids. A re-submit sends only the shards
    /// with a case not complete. docs/cluster.md tells the rest.
    Submit {
        config: PathBuf,
        /// Output root, on a file system the compute nodes share.
        #[arg(long, default_value = "runs")]
        out: PathBuf,
        /// Array tasks [default: as planned by an earlier submit, else one per case, at most
        /// 1000]; more than the cases are cut to one per case.
        #[arg(long, value_parser = at_least_one)]
        shards: Option<usize>,
        /// Most array tasks running at once (`--array=...%K`).
        #[arg(long, value_name = "K", value_parser = at_least_one)]
        throttle: Option<usize>,
        /// Lift the limits on estimated output, peak memory and steps, as `run` would.
        #[arg(long)]
        allow_large: bool,
        /// Options for both `sbatch` calls, after `--` (e.g. -- --partition=short --time=2:00:00).
        #[arg(last = true, value_name = "SBATCH OPTIONS")]
        sbatch: Vec<String>,
    },
    /// Gather a run directory's cases into one xarray-ready file, RUN_DIR/collected.h5
    /// (also written at the end of `tsim run`): a `case` dimension with the swept
    /// parameters as coordinates, the summary's figures and the energy histories. Of a
    /// sharded run (`--shard`, `tsim submit`) it first merges the shards: summary.csv and
    /// summary.json from every case directory, the manifests checked against the plan
    /// (warnings). Exits 1 when a case is missing or not complete (listed; the files are
    /// still written), 2 while a `tsim run` holds the directory.
    Collect {
        /// A run directory (OUT/<name>, holding summary.json).
        run_dir: PathBuf,
    },
    /// Print the config's JSON Schema (draft 2020-12), for editors that complete and check
    /// YAML keys; the repository keeps a copy in docs/tsim.schema.json.
    Schema {
        /// Write it to this file instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Print a completion script for a shell, e.g. `tsim completions bash >
    /// ~/.local/share/bash-completion/completions/tsim`.
    Completions { shell: clap_complete::Shell },
    /// Draw the figures of a case or sweep directory (or a result.h5) into PATH/figures, from
    /// any directory: the figures script is built into tsim and run by Python (TSIM_PYTHON,
    /// else the checkout's .venv, else python3, with matplotlib, xarray, h5netcdf, pandas).
    Figures {
        path: PathBuf,
        /// The figures script's options: --out DIR, --svg, --dpi N, --only NAME...,
        /// --node ID, and for a sweep --x, --y, --hue, --facet (docs/figures.md).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        options: Vec<String>,
    },
    /// Validate a config and list the cases it would run, with their estimated output
    /// and peak memory.
    Check {
        config: PathBuf,
        /// Output root the cases would go to, to show each as new, complete (reused by a
        /// run), changed (another config was run there) or incomplete.
        #[arg(long, default_value = "runs")]
        out: PathBuf,
        /// Lift the limits on estimated output, peak memory and steps, as `run` would.
        #[arg(long)]
        allow_large: bool,
        /// List only the cases whose id matches, as `run --only` would select them.
        #[arg(long, value_name = "PATTERN")]
        only: Vec<String>,
    },
}

/// One `error: ` line per bad value (a syntax error's message runs on with its snippet).
fn report(e: &ConfigError) {
    match e {
        ConfigError::Values(errors) => errors.iter().for_each(|v| eprintln!("error: {v}")),
        e => eprintln!("error: {e}"),
    }
}

fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("`{text}`: give a whole number ≥ 1")),
    }
}

fn parse_shard(text: &str) -> Result<Shard, String> {
    Shard::parse(text, |name| std::env::var(name).ok())
}

/// `tsim collect`: a sharded run directory is merged first.
fn collect_command(run_dir: &Path) -> u8 {
    match Plan::read(run_dir) {
        Ok(Some(_)) => {}
        Ok(None) => return collect_unsharded(run_dir),
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    }
    match merge(run_dir) {
        Ok(m) => {
            for (id, why) in &m.not_complete {
                eprintln!("not complete: {id}: {why}");
            }
            // The case directories decide the exit code; a manifest only says what its
            // shard did (a case finished by an unsharded run has none).
            for problem in &m.manifest_problems {
                eprintln!("warning: manifest: {problem}");
            }
            match &m.collected {
                Ok(c) => eprintln!("written {}", c.path.display()),
                Err(e) => eprintln!("warning: {e}"),
            }
            eprintln!(
                "{} case(s) in {} shard(s): {} not complete, {} manifest problem(s); summaries written in {}",
                m.cases,
                m.shards,
                m.not_complete.len(),
                m.manifest_problems.len(),
                run_dir.display()
            );
            u8::from(!m.not_complete.is_empty())
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

fn collect_unsharded(run_dir: &std::path::Path) -> u8 {
    match collect(run_dir) {
        Ok(c) => {
            for (id, why) in &c.missing {
                eprintln!("missing: {id}: {why}");
            }
            eprintln!(
                "{} case(s), {} missing or not complete; written {}",
                c.cases,
                c.missing.len(),
                c.path.display()
            );
            u8::from(!c.missing.is_empty())
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// `tsim submit`.
fn submit_command(opts: SubmitOptions) -> u8 {
    let Expanded { name, cases, .. } = match load(&opts.config, opts.allow_large) {
        Ok(x) => x,
        Err(e) => {
            report(&e);
            return 2;
        }
    };
    match submit(&name, &cases, &opts) {
        Ok(Some(s)) => {
            eprintln!(
                "{} case(s) not complete; submitted shard(s) {} of {} into {}",
                s.incomplete,
                s.shards.iter().map(ToString::to_string).collect::<Vec<_>>().join(","),
                s.count,
                s.dir.display()
            );
            println!("array job {}", s.array_job);
            println!("merge job {}", s.merge_job);
            0
        }
        Ok(None) => {
            eprintln!(
                "every case is complete and every shard's manifest written: nothing submitted; `tsim collect {}` merges them",
                opts.out.join(&name).display()
            );
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// The `tsim` command with its arguments (`args[0]` the program name); the exit code.
/// Help, the version and usage errors are printed here, as clap prints them.
pub fn main(args: impl IntoIterator<Item = std::ffi::OsString>) -> u8 {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // Help and the version on stdout (exit 0), usage errors on stderr (exit 2).
            let _ = e.print();
            return u8::try_from(e.exit_code()).unwrap_or(2);
        }
    };
    match cli.command {
        Command::Collect { run_dir } => collect_command(&run_dir),
        Command::Submit {
            config,
            out,
            shards,
            throttle,
            allow_large,
            sbatch,
        } => submit_command(SubmitOptions {
            config,
            out,
            shards,
            throttle,
            allow_large,
            sbatch,
        }),
        Command::Schema { out } => schema_command(out.as_deref()),
        Command::Figures { path, options } => figures_command(&path, &options),
        Command::Completions { shell } => {
            clap_complete::generate(shell, &mut Cli::command(), "tsim", &mut std::io::stdout());
            0
        }
        Command::Check {
            config,
            out,
            allow_large,
            only,
        } => check_command(&config, &out, allow_large, &only),
        Command::Run {
            config,
            out,
            jobs,
            force,
            quiet,
            only,
            allow_large,
            shard,
        } => {
            let opts = RunOptions {
                out,
                jobs: capped_jobs(jobs),
                force,
                quiet,
                only,
                shard,
            };
            run_command(&config, allow_large, &opts)
        }
    }
}

/// `tsim figures`: the script's own progress and paths on the terminal; exit 2 when Python
/// cannot draw, 1 when the script fails.
fn figures_command(path: &Path, options: &[String]) -> u8 {
    eprintln!(
        "tsim figures: drawing {} with {}",
        path.display(),
        crate::run::figures::python().display()
    );
    match crate::run::figures::draw(path, options, (std::process::Stdio::inherit(), std::process::Stdio::inherit())) {
        Ok(out) if out.status.success() => 0,
        Ok(_) => 1,
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// `tsim schema`: the config's JSON Schema to stdout or `out`.
fn schema_command(out: Option<&Path>) -> u8 {
    let schema = json_schema();
    match out {
        None => {
            if let Err(e) = unless_closed(std::io::Write::write_all(&mut std::io::stdout().lock(), schema.as_bytes())) {
                eprintln!("error: cannot write the schema: {e}");
                return 2;
            }
        }
        Some(path) => {
            if let Err(e) = std::fs::write(path, schema) {
                eprintln!("error: cannot write {}: {e}", path.display());
                return 2;
            }
        }
    }
    0
}

/// `tsim check`: each case's id, what is on disk for it and its estimates, then the run's.
fn check_command(config: &Path, out: &Path, allow_large: bool, only: &[String]) -> u8 {
    let expanded = match load(config, allow_large) {
        Ok(x) => x,
        Err(e) => {
            report(&e);
            return 2;
        }
    };
    if let Err(e) = require_matches(only, &ids(&expanded.cases), config) {
        eprintln!("error: {e}");
        return 2;
    }
    match unless_closed(print_check(config, out, &expanded, only, &mut std::io::stdout().lock())) {
        Err(e) => {
            eprintln!("error: cannot write the listing: {e}");
            2
        }
        Ok(()) => 0,
    }
}

/// The ids of `cases`.
fn ids(cases: &[crate::run::Case]) -> Vec<&str> {
    cases.iter().map(|c| c.id.as_str()).collect()
}

/// The listing of `tsim check` into `w`: the cases `only` selects (all without it).
fn print_check(config: &Path, out: &Path, expanded: &Expanded, only: &[String], w: &mut impl std::io::Write) -> std::io::Result<()> {
    let Expanded { name, cases, limits } = expanded;
    let dir = out.join(name);
    let all = cases.len();
    let cases: Vec<&crate::run::Case> = cases.iter().filter(|c| selected(&c.id, only)).collect();
    let of = if cases.len() < all { format!(" of {all}") } else { String::new() };
    writeln!(w, "{}: {}{of} case(s) into {}/", config.display(), cases.len(), dir.display())?;
    let width = cases.iter().map(|c| c.id.len()).max().unwrap_or(0);
    let mut counts = std::collections::BTreeMap::new();
    for c in &cases {
        let state = OnDisk::of(c, &dir.join(&c.id)).as_str();
        *counts.entry(state).or_insert(0) += 1;
        writeln!(
            w,
            "  {:width$}  {state:10}  output {}, peak memory {}",
            c.id,
            bytes_text(c.estimate.output),
            bytes_text(c.estimate.memory)
        )?;
    }
    let counts: Vec<String> = counts.iter().map(|(s, n)| format!("{n} {s}")).collect();
    writeln!(w, "cases: {} (a run reuses the complete ones)", counts.join(", "))?;
    let output: f64 = cases.iter().map(|c| c.estimate.output).sum();
    let memory = cases.iter().map(|c| c.estimate.memory).fold(0.0, f64::max);
    let limit = |b: f64| {
        if b.is_finite() {
            bytes_text(b)
        } else {
            "none: --allow-large".into()
        }
    };
    writeln!(
        w,
        "estimated: output {} in all, uncompressed (limit {}); peak memory {} per case (limit {}; cases running at once add up)",
        bytes_text(output),
        limit(limits.max_output),
        bytes_text(memory),
        limit(limits.max_memory)
    )?;
    let tables = distinct_tables(&cases);
    if !tables.is_empty() {
        let points: usize = tables.iter().map(|t| t.len()).sum();
        writeln!(
            w,
            "time tables: {} of {points} points in all, {} held once for every case (in each case's peak above)",
            tables.len(),
            bytes_text(16.0 * points as f64)
        )?;
    }
    Ok(())
}

/// The time tables of `cases`, each once however many cases share it.
fn distinct_tables(cases: &[&crate::run::Case]) -> Vec<crate::config::TablePoints> {
    let mut seen = std::collections::HashSet::new();
    cases
        .iter()
        .flat_map(|c| c.config.table_points())
        .filter(|t| seen.insert(std::sync::Arc::as_ptr(t) as *const f64))
        .collect()
}

/// `tsim run`: every case of `config` (or this shard's); exit 1 when one failed or the run
/// could not write its directory, 2 when another `tsim run` holds the directory (as
/// `collect` exits then: nothing was run), 130 when interrupted.
fn run_command(config: &Path, allow_large: bool, opts: &RunOptions) -> u8 {
    let Expanded { name, cases, .. } = match load(config, allow_large) {
        Ok(x) => x,
        Err(e) => {
            report(&e);
            return 2;
        }
    };
    if let Err(e) = require_matches(&opts.only, &ids(&cases), config) {
        eprintln!("error: {e}");
        return 2;
    }
    if let Err(e) = install_interrupt() {
        eprintln!("warning: cannot handle SIGINT/SIGTERM ({e}); an interrupted run leaves its files marked running");
    }
    match run(&name, &cases, opts) {
        Ok(outcomes) => {
            let failed = outcomes.iter().filter(|o| o.failed()).count();
            let tally = Tally(&outcomes);
            eprintln!("{}; results in {}", tally.line(), opts.out.join(&name).display());
            if interrupted() {
                eprintln!("{}", tally.interrupted());
                EXIT_INTERRUPTED
            } else if failed > 0 {
                1
            } else {
                0
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            if e.kind() == std::io::ErrorKind::WouldBlock {
                2
            } else {
                1
            }
        }
    }
}
