use super::{Constraints, EigenRecord, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, RigidityRecord, Stage};

/// Several recorders behind one: each call goes to all, in order.
pub struct Recorders(pub Vec<Box<dyn Recorder + Send>>);

impl Recorder for Recorders {
    fn model(&mut self, r: &ModelRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.model(r))
    }
    fn formfinding(&mut self, r: &FormFindRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.formfinding(r))
    }
    fn rigidity(&mut self, r: &RigidityRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.rigidity(r))
    }
    fn eigen(&mut self, r: &EigenRecord) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.eigen(r))
    }
    fn begin_stage(&mut self, s: &Stage, c: &Constraints) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.begin_stage(s, c))
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.frame(f))
    }
    fn end_stage(&mut self, s: &Stage) -> RecordResult {
        self.0.iter_mut().try_for_each(|x| x.end_stage(s))
    }
    /// Finishes every recorder even if one fails, so each file gets its final status.
    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        let results: Vec<RecordResult> = self.0.iter_mut().map(|x| x.finish(outcome)).collect();
        results.into_iter().collect()
    }
}
