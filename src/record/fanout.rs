use super::background::Background;
use super::{EigenRecord, FormFindRecord, Frame, ModelRecord, RecordResult, Recorder, Stage};
use crate::config::OutputSpec;
use std::path::Path;

/// Several recorders behind one: each call goes to all, in order.
pub struct Recorders(pub Vec<Box<dyn Recorder + Send>>);

impl Recorder for Recorders {
    fn model(&mut self, r: &ModelRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.model(r))
    }
    fn formfinding(&mut self, r: &FormFindRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.formfinding(r))
    }
    fn eigen(&mut self, r: &EigenRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.eigen(r))
    }
    fn begin_stage(&mut self, s: Stage) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.begin_stage(s))
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.frame(f))
    }
    fn end_stage(&mut self, s: Stage) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.end_stage(s))
    }
    /// Finishes every recorder even if one fails, so each file gets its final status.
    fn finish(&mut self, status: &str) -> RecordResult {
        let results: Vec<RecordResult> = self.0.iter_mut().map(|x| x.finish(status)).collect();
        results.into_iter().collect()
    }
}

/// The file recorders a case's `outputs` asks for, `result.h5` and `replay.mcap` in `dir`,
/// as one recorder. With `background`, both stream on one writer thread; that pays only
/// when a core is free for it, so the runner asks for it only then (with every core
/// running a case, a writer thread just takes turns with the solvers). One thread, not one
/// per file: each frame is copied into one queue instead of two, and the writers do not
/// take turns with each other and the solver on the one free core (wall time on the paper
/// case was the same within noise either way).
/// `outputs.every` is not theirs to apply: the stages call `frame` only for the steps to
/// record.
pub fn file_recorders(
    outputs: &OutputSpec,
    dir: &Path,
    case_id: &str,
    config_yaml: &str,
    background: bool,
) -> Result<Box<dyn Recorder + Send>, Box<dyn std::error::Error + Send + Sync>> {
    let mut files: Vec<Box<dyn Recorder + Send>> = Vec::new();
    if outputs.hdf5 {
        files.push(Box::new(super::h5::Hdf5Recorder::create(
            &dir.join("result.h5"),
            case_id,
            config_yaml,
        )?));
    }
    if outputs.mcap {
        files.push(Box::new(super::replay::McapRecorder::create(&dir.join("replay.mcap"), case_id)?));
    }
    let files = Recorders(files);
    Ok(if background && !files.0.is_empty() {
        Box::new(Background::new(files, "tsim-writer"))
    } else {
        Box::new(files)
    })
}
