//! The figures of a run, drawn by the figures script this binary carries (scripts/figures.py,
//! built in), so that `tsim figures` and `outputs.figures` work from any directory and
//! after `cargo install`: the script is fed to Python on its standard input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// scripts/figures.py as it was when this binary was built.
const SCRIPT: &str = include_str!("../../scripts/figures.py");

/// The Python packages the script imports.
const PACKAGES: &str = "matplotlib, xarray, h5netcdf, pandas";

/// The Python that draws: `TSIM_PYTHON`, else the virtualenv of the checkout this binary
/// was built in (`scripts/setup --python` makes it), else `python3`.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("TSIM_PYTHON") {
        return p.into();
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python");
    if venv.exists() {
        venv
    } else {
        "python3".into()
    }
}

/// Draws the figures of `path` (a case or sweep directory, or a result.h5) with the
/// script's options `args`; its output goes to `stdout`/`stderr` as given (what is piped
/// comes back in the `Output`). Err: Python could not be started or lacks a package, said
/// with the fix.
pub fn draw(path: &Path, args: &[String], (stdout, stderr): (Stdio, Stdio)) -> Result<Output, String> {
    let python = python();
    let missing = || {
        format!(
            "{} cannot draw the figures: it needs Python 3 with {PACKAGES} (`scripts/setup --python` in a checkout, \
             or pip install them; TSIM_PYTHON names the Python to use)",
            python.display()
        )
    };
    let check = Command::new(&python)
        .args([
            "-c",
            &format!(
                "import importlib.util as u, sys; sys.exit(not all(u.find_spec(m) for m in {:?}.split(', ')))",
                PACKAGES
            ),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !check.is_ok_and(|s| s.success()) {
        return Err(missing());
    }
    let mut child = Command::new(&python)
        .arg("-")
        .arg(path)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(stdout)
        .stderr(stderr)
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", python.display()))?;
    // Python reads the whole program before it runs it, so this cannot wait on its output.
    let fed = child.stdin.take().expect("stdin is piped").write_all(SCRIPT.as_bytes());
    let output = child.wait_with_output().map_err(|e| format!("{}: {e}", python.display()))?;
    fed.map_err(|e| format!("cannot pass the figures script to {}: {e}", python.display()))?;
    Ok(output)
}
