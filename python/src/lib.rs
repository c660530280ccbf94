//! `tsim._tsim`, the Python package's extension: the `tsim` command line and a run of a
//! config (a file, or the text of a dict), both the tsim library's. The package around it
//! (py/tsim) reads the results back with h5py, h5netcdf, xarray and pandas.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::time::Duration;
use tsim::run::{clear_stop, load, request_stop, require_matches, run, Expanded, RunOptions};

pyo3::create_exception!(
    _tsim,
    ConfigError,
    PyValueError,
    "A config that does not load: every bad value, each with its file, line and field."
);

/// How often a running sweep looks for a KeyboardInterrupt (Ctrl-C, a notebook's stop
/// button): Python handles signals only on its main thread, between bytecodes.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// The `tsim` command with `args` (`args[0]` the program name); its exit code. For the
/// package's console script: it installs tsim's own SIGINT/SIGTERM handling, as the
/// binary does, which replaces Python's for the rest of the process.
#[pyfunction]
fn cli(py: Python<'_>, args: Vec<String>) -> u8 {
    py.detach(|| tsim::cli::main(args.into_iter().map(Into::into)))
}

/// Runs every case of a config into `out/<name>/` as `tsim run` does, and returns the run
/// directory and the cases' outcomes as JSON (summary.json's records). `config` is the
/// config file, or with `text` the name the text goes by in messages (its relative paths
/// start from its directory). A config that does not load raises ConfigError, a run that
/// cannot write its directory OSError; a failing case fails alone (its outcome says why).
/// A KeyboardInterrupt stops the running cases at their next step, closes their files as
/// `interrupted`, writes the summaries, and is raised then.
#[pyfunction]
#[pyo3(signature = (config, out, text=None, jobs=None, force=false, quiet=true, only=Vec::new(), allow_large=false))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per `tsim run` option
fn run_config(
    py: Python<'_>,
    config: PathBuf,
    out: PathBuf,
    text: Option<String>,
    jobs: Option<u64>,
    force: bool,
    quiet: bool,
    only: Vec<String>,
    allow_large: bool,
) -> PyResult<(PathBuf, String)> {
    let loaded = py.detach(|| match &text {
        Some(text) => tsim::run::expand(text, &config.display().to_string(), allow_large),
        None => load(&config, allow_large),
    });
    let Expanded { name, cases, .. } = loaded.map_err(|e| ConfigError::new_err(e.to_string()))?;
    let ids: Vec<&str> = cases.iter().map(|c| c.id.as_str()).collect();
    require_matches(&only, &ids, &config).map_err(PyValueError::new_err)?;
    let opts = RunOptions {
        out,
        // Capped as `--jobs` is, with its warning (the run cuts it to the cases it runs).
        jobs: tsim::cli::capped_jobs(jobs),
        force,
        quiet,
        only,
        shard: None,
    };
    let dir = opts.out.join(&name);
    let outcomes = supervised(py, move || run(&name, &cases, &opts))?.map_err(PyOSError::new_err)?;
    let json = serde_json::to_string(&outcomes).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    Ok((dir, json))
}

/// `work` on its own thread, with the main thread free to see a KeyboardInterrupt: one
/// asks the work to stop (as a first SIGINT does) and is raised once the work has closed
/// its files.
fn supervised<T: Send + 'static>(py: Python<'_>, work: impl FnOnce() -> T + Send + 'static) -> PyResult<T> {
    clear_stop();
    let handle = std::thread::spawn(work);
    let mut stopped: Option<PyErr> = None;
    while !handle.is_finished() {
        py.detach(|| std::thread::sleep(SIGNAL_POLL));
        if stopped.is_none() {
            if let Err(e) = py.check_signals() {
                request_stop();
                stopped = Some(e);
            }
        }
    }
    let done = handle
        .join()
        .map_err(|_| PyRuntimeError::new_err("tsim: the run panicked (a bug: please report it with the config)"))?;
    stopped.map_or(Ok(done), Err)
}

/// The HDF5 linked into the extension, "major.minor.release" (h5py's own is
/// `h5py.version.hdf5_version`: two libraries, each with its files and state).
#[pyfunction]
fn hdf5_version() -> PyResult<String> {
    let (mut major, mut minor, mut release) = (0, 0, 0);
    // SAFETY: three valid out-pointers; the crate's lock serializes every HDF5 call.
    let status = {
        let _lock = hdf5_sys::LOCK.lock();
        unsafe { hdf5_sys::h5::H5get_libversion(&mut major, &mut minor, &mut release) }
    };
    if status < 0 {
        return Err(PyRuntimeError::new_err("H5get_libversion failed"));
    }
    Ok(format!("{major}.{minor}.{release}"))
}

#[pymodule]
fn _tsim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(cli, m)?)?;
    m.add_function(wrap_pyfunction!(run_config, m)?)?;
    m.add_function(wrap_pyfunction!(hdf5_version, m)?)?;
    m.add("ConfigError", m.py().get_type::<ConfigError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
