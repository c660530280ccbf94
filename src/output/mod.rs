//! The output files: `result.h5` ([`h5`]) and `replay.mcap` ([`replay`]), each a
//! [`Recorder`], and the one writer thread that can stream them ([`Background`]). The only
//! module below `run` that knows files and threads.

mod background;
mod chunk;
pub mod collected;
pub mod h5;
pub mod replay;

pub use background::Background;

use crate::config::OutputSpec;
use crate::record::{Recorder, Recorders};
use std::path::Path;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// The file `create` makes at `path`, made under a temporary name beside it and renamed
/// over it only once it exists: a file that cannot be created (the disk full, the old one
/// locked by a reader) leaves the previous one whole, and a reader that has the previous
/// one open keeps reading it. The recorder writes on through its open handle.
fn replacing<T>(path: &Path, create: impl FnOnce(&Path) -> Result<T, Error>) -> Result<T, Error> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let new = path.with_file_name(format!(".{name}.{}.new", std::process::id()));
    // The entry of a killed run's leftover (never what a link there points to).
    let _ = std::fs::remove_file(&new);
    let created = create(&new).and_then(|file| Ok(std::fs::rename(&new, path).map(|()| file)?));
    if created.is_err() {
        let _ = std::fs::remove_file(&new);
    }
    created.map_err(|e| format!("{}: {e}", path.display()).into())
}

/// The file recorders a case's `outputs` asks for, `result.h5` and `replay.mcap` in `dir`,
/// as one recorder. With `background`, both stream on one writer thread; that pays only
/// when a core is free for it, so the runner asks for it only then (with every core
/// running a case, a writer thread just takes turns with the solvers). One thread, not one
/// per file: each frame is copied into one queue instead of two, and the writers do not
/// take turns with each other and the solver on the one free core (wall time on the paper
/// case was the same within noise either way).
/// `params` (a sweep case's parameters) become root attributes of result.h5.
/// `outputs.every` is not theirs to apply: the stages call `frame` only for the steps to
/// record.
pub fn file_recorders(
    outputs: &OutputSpec,
    dir: &Path,
    case_id: &str,
    config_yaml: &str,
    params: &[(String, h5::ParamValue)],
    background: bool,
) -> Result<Box<dyn Recorder + Send>, Error> {
    let mut files: Vec<Box<dyn Recorder + Send>> = Vec::new();
    if outputs.hdf5 {
        let mut h5 = replacing(&dir.join("result.h5"), |p| h5::Hdf5Recorder::create(p, case_id, config_yaml))?;
        h5.write_params(params)?;
        files.push(Box::new(h5));
    }
    if outputs.mcap {
        let mcap = replacing(&dir.join("replay.mcap"), |p| {
            replay::McapRecorder::create(p, case_id, outputs.replay_rate)
        })?;
        files.push(Box::new(mcap));
    }
    let files = Recorders(files);
    Ok(if background && !files.0.is_empty() {
        Box::new(Background::new(files, "tsim-writer"))
    } else {
        Box::new(files)
    })
}
