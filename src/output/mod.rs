//! The output files: `result.h5` ([`h5`]), `replay.mcap` ([`replay`]) and
//! `paraview/<stage>.vtkhdf` ([`paraview`]), each a [`Recorder`], and the one writer thread that can stream them ([`Background`]). The only
//! module below `run` that knows files and threads.

mod background;
mod chunk;
pub mod collected;
pub mod h5;
pub mod paraview;
pub mod replay;

pub use background::Background;

use crate::config::OutputSpec;
use crate::record::{
    Constraints, EigenRecord, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, Recorders, RigidityRecord, Stage,
};
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

/// A file's recorder whose errors name the file (a full disk otherwise reads
/// "H5Dwrite_chunk failed" of no file).
struct Named<R> {
    path: String,
    inner: R,
}

impl<R> Named<R> {
    fn new(path: &Path, inner: R) -> Self {
        Named {
            path: path.display().to_string(),
            inner,
        }
    }
}

/// `result` with its error prefixed by `path`.
fn named(path: &str, result: RecordResult) -> RecordResult {
    result.map_err(|e| format!("{path}: {e}").into())
}

impl<R: Recorder> Recorder for Named<R> {
    fn model(&mut self, r: &ModelRecord) -> RecordResult {
        named(&self.path, self.inner.model(r))
    }
    fn formfinding(&mut self, r: &FormFindRecord) -> RecordResult {
        named(&self.path, self.inner.formfinding(r))
    }
    fn rigidity(&mut self, r: &RigidityRecord) -> RecordResult {
        named(&self.path, self.inner.rigidity(r))
    }
    fn eigen(&mut self, r: &EigenRecord) -> RecordResult {
        named(&self.path, self.inner.eigen(r))
    }
    fn begin_stage(&mut self, s: &Stage, c: &Constraints) -> RecordResult {
        named(&self.path, self.inner.begin_stage(s, c))
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        named(&self.path, self.inner.frame(f))
    }
    fn end_stage(&mut self, s: &Stage) -> RecordResult {
        named(&self.path, self.inner.end_stage(s))
    }
    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        named(&self.path, self.inner.finish(outcome))
    }
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
        let path = dir.join("result.h5");
        let mut h5 = replacing(&path, |p| h5::Hdf5Recorder::create(p, case_id, config_yaml))?;
        h5.write_params(params)?;
        files.push(Box::new(Named::new(&path, h5)));
    }
    if outputs.mcap {
        let path = dir.join("replay.mcap");
        let mcap = replacing(&path, |p| replay::McapRecorder::create(p, case_id, outputs.replay_rate))?;
        files.push(Box::new(Named::new(&path, mcap)));
    }
    if outputs.paraview {
        files.push(Box::new(paraview::ParaviewRecorder::new(&dir.join(paraview::DIR))));
    }
    let files = Recorders(files);
    Ok(if background && !files.0.is_empty() {
        Box::new(Background::new(files, "tsim-writer"))
    } else {
        Box::new(files)
    })
}
