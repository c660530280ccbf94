use super::background::Background;
use super::{EigenRecord, FormFindRecord, Frame, ModelRecord, RecordResult, Recorder, Stage};
use crate::config::OutputSpec;
use std::path::Path;

/// Several recorders behind one: each call goes to all, in order.
pub struct Recorders(pub Vec<Box<dyn Recorder>>);

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

/// The file recorders a case's `outputs` asks for: `result.h5` and `replay.mcap` in `dir`.
/// With `background`, each streams on a thread of its own; that pays only when a core is
/// free for the writers, so the runner asks for it only then (with every core running a
/// case, writer threads just take turns with the solvers). `outputs.every` is not theirs
/// to apply: the stages call `frame` only for the steps to record.
pub fn file_recorders(
    outputs: &OutputSpec,
    dir: &Path,
    case_id: &str,
    config_yaml: &str,
    background: bool,
) -> Result<Vec<Box<dyn Recorder>>, Box<dyn std::error::Error + Send + Sync>> {
    fn boxed<R: Recorder + Send + 'static>(r: R, thread: &str, background: bool) -> Box<dyn Recorder> {
        if background {
            Box::new(Background::new(r, thread))
        } else {
            Box::new(r)
        }
    }
    let mut out: Vec<Box<dyn Recorder>> = Vec::new();
    if outputs.hdf5 {
        let h5 = super::h5::Hdf5Recorder::create(&dir.join("result.h5"), case_id, config_yaml)?;
        out.push(boxed(h5, "tsim-hdf5", background));
    }
    if outputs.mcap {
        let mcap = super::replay::McapRecorder::create(&dir.join("replay.mcap"), case_id)?;
        out.push(boxed(mcap, "tsim-mcap", background));
    }
    Ok(out)
}
