//! The `tsim` binary: the command line of `tsim::cli`.

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(tsim::cli::main(std::env::args_os()))
}
