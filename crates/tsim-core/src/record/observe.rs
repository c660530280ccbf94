//! Logs that keep what the case summary needs from the records a case streams (the
//! clearance, the clustered cables), each an [`Observer`] behind one pass-through
//! recorder, [`Observed`].

use super::{Constraints, EigenRecord, FormFindRecord, Frame, ModelRecord, Outcome, RecordResult, Recorder, RigidityRecord, Stage};

/// What a log sees of the records; it cannot fail a case.
pub trait Observer {
    /// The model record ([`Recorder::model`]).
    fn model(&mut self, _record: &ModelRecord) {}
    /// Form-finding's (or the given model's) equilibrium.
    fn formfinding(&mut self, _record: &FormFindRecord) {}
    /// A time-stepping stage begins.
    fn begin_stage(&mut self, _stage: &Stage) {}
    /// One converged step of it.
    fn frame(&mut self, _frame: &Frame) {}
}

/// Two logs side by side.
impl<A: Observer, B: Observer> Observer for (A, B) {
    fn model(&mut self, record: &ModelRecord) {
        self.0.model(record);
        self.1.model(record);
    }
    fn formfinding(&mut self, record: &FormFindRecord) {
        self.0.formfinding(record);
        self.1.formfinding(record);
    }
    fn begin_stage(&mut self, stage: &Stage) {
        self.0.begin_stage(stage);
        self.1.begin_stage(stage);
    }
    fn frame(&mut self, frame: &Frame) {
        self.0.frame(frame);
        self.1.frame(frame);
    }
}

/// Passes every call on to `inner`, showing the records to `observer` first.
pub struct Observed<'r, O> {
    inner: &'r mut dyn Recorder,
    /// The logs.
    pub observer: O,
}

impl<'r, O: Observer> Observed<'r, O> {
    /// `observer` in front of `inner`.
    pub fn new(inner: &'r mut dyn Recorder, observer: O) -> Self {
        Observed { inner, observer }
    }
}

impl<O: Observer> Recorder for Observed<'_, O> {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        self.observer.model(record);
        self.inner.model(record)
    }
    fn formfinding(&mut self, record: &FormFindRecord) -> RecordResult {
        self.observer.formfinding(record);
        self.inner.formfinding(record)
    }
    fn rigidity(&mut self, record: &RigidityRecord) -> RecordResult {
        self.inner.rigidity(record)
    }
    fn eigen(&mut self, record: &EigenRecord) -> RecordResult {
        self.inner.eigen(record)
    }
    fn begin_stage(&mut self, stage: &Stage, constraints: &Constraints) -> RecordResult {
        self.observer.begin_stage(stage);
        self.inner.begin_stage(stage, constraints)
    }
    fn frame(&mut self, frame: &Frame) -> RecordResult {
        self.observer.frame(frame);
        self.inner.frame(frame)
    }
    fn end_stage(&mut self, stage: &Stage) -> RecordResult {
        self.inner.end_stage(stage)
    }
    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        self.inner.finish(outcome)
    }
}
