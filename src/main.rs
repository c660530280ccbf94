//! The `tsim` command line: parse, call the library, map outcomes to exit codes
//! (0 every case complete, 1 a case failed, 2 a config or usage error, 130 interrupted by
//! SIGINT or SIGTERM).

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use tsim::config::ConfigError;
use tsim::run::{default_jobs, install_interrupt, interrupted, load, run, RunOptions, EXIT_INTERRUPTED};

#[derive(Parser)]
#[command(
    name = "tsim",
    version,
    about = "Tensegrity simulation by the tangent stiffness method: form-finding, real materials, vibration, folding, deployment",
    after_help = "Examples:\n  tsim check configs/sweep.yaml\n  tsim run configs/paper.yaml\n  tsim run configs/sweep.yaml --jobs 2 --out runs\n  tsim run configs/sweep.yaml --force   # rerun complete cases too"
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
        /// Cases run at once [default: SLURM_CPUS_PER_TASK, else the available cores].
        #[arg(long)]
        jobs: Option<usize>,
        /// Rerun cases that are already complete.
        #[arg(long)]
        force: bool,
        /// No progress bars; one line per finished case.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a config and list the cases it would run.
    Check { config: PathBuf },
}

/// One `error: ` line per bad value (a syntax error's message runs on with its snippet).
fn report(e: &ConfigError) {
    match e {
        ConfigError::Values(errors) => errors.iter().for_each(|v| eprintln!("error: {v}")),
        e => eprintln!("error: {e}"),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Check { config } => match load(&config) {
            Ok((name, cases)) => {
                println!("{}: {} case(s) into {name}/", config.display(), cases.len());
                for c in &cases {
                    println!("  {}", c.id);
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                report(&e);
                ExitCode::from(2)
            }
        },
        Command::Run {
            config,
            out,
            jobs,
            force,
            quiet,
        } => {
            let (name, cases) = match load(&config) {
                Ok(x) => x,
                Err(e) => {
                    report(&e);
                    return ExitCode::from(2);
                }
            };
            let opts = RunOptions {
                out,
                jobs: jobs.unwrap_or_else(default_jobs),
                force,
                quiet,
            };
            if let Err(e) = install_interrupt() {
                eprintln!("warning: cannot handle SIGINT/SIGTERM ({e}); an interrupted run leaves its files marked running");
            }
            match run(&name, &cases, &opts) {
                Ok(outcomes) => {
                    let failed = outcomes.iter().filter(|o| o.failed()).count();
                    eprintln!(
                        "{} case(s): {} failed; results in {}",
                        outcomes.len(),
                        failed,
                        opts.out.join(&name).display()
                    );
                    if interrupted() {
                        eprintln!("interrupted: cases not complete are marked `interrupted`; rerun to finish them");
                        ExitCode::from(EXIT_INTERRUPTED)
                    } else if failed > 0 {
                        ExitCode::from(1)
                    } else {
                        ExitCode::SUCCESS
                    }
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(1)
                }
            }
        }
    }
}
