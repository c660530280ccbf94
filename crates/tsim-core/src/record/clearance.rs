//! The case's clearance record: an [`Observer`] that keeps, from the frames' clearance, the
//! smallest clearance of the case (its pair, stage, step and time) and the events, for the
//! case summary.

use super::{ClearanceEvent, FormFindRecord, Frame, FrameClearance, ModelRecord, Nearest, Observer, Stage, StageKind};

/// Most events listed in the summary (all are counted, and all are in `result.h5`): a long
/// vibration with struts in contact would otherwise fill `summary.json`.
pub const SUMMARY_EVENTS: usize = 1000;

/// Keeps the clearance record of the records it observes. Its storage is reserved at
/// creation: a step allocates nothing.
pub struct ClearanceLog {
    stage: Stage,
    member_ids: Vec<String>,
    /// Whether any record carried clearance.
    tracked: bool,
    nearest: Option<(Stage, usize, f64, Nearest)>,
    events: Vec<(Stage, ClearanceEvent)>,
    event_count: usize,
}

/// The smallest clearance of a case and its events.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClearanceSummary {
    /// Where the clearance was smallest; absent without two non-adjacent struts.
    pub nearest: Option<NearestSummary>,
    /// Touches and pass-throughs, in the order they happened (the first [`SUMMARY_EVENTS`]).
    pub events: Vec<EventSummary>,
    /// Number of events, all of them.
    pub event_count: usize,
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NearestSummary {
    /// Surface gap [m]; ≤ 0: touching.
    pub clearance: f64,
    /// Member ids of the pair.
    pub members: [String; 2],
    pub stage: String,
    pub step: usize,
    /// Time within the stage [s] (folding, static: the applied fraction).
    pub time: f64,
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EventSummary {
    /// `touch` or `pass_through`.
    pub kind: String,
    pub members: [String; 2],
    pub stage: String,
    pub step: usize,
    /// Time within the stage [s] (folding, static: the applied fraction); a pass-through's
    /// is the interpolated moment of crossing.
    pub time: f64,
    /// Clearance at `step` [m].
    pub clearance: f64,
}

impl Default for ClearanceLog {
    /// A log with nothing recorded yet.
    fn default() -> Self {
        ClearanceLog {
            stage: Stage::of(StageKind::FormFinding),
            member_ids: Vec::new(),
            tracked: false,
            nearest: None,
            events: Vec::with_capacity(SUMMARY_EVENTS),
            event_count: 0,
        }
    }
}

impl ClearanceLog {
    fn note(&mut self, stage: &Stage, step: usize, time: f64, clearance: Option<FrameClearance>) {
        let Some(c) = clearance else { return };
        self.tracked = true;
        if let Some(n) = c.nearest {
            if self.nearest.as_ref().is_none_or(|(.., m)| n.clearance < m.clearance) {
                self.nearest = Some((stage.clone(), step, time, n));
            }
        }
        self.event_count += c.events.len();
        let room = SUMMARY_EVENTS - self.events.len();
        self.events.extend(c.events.iter().take(room).map(|e| (stage.clone(), *e)));
    }

    /// The record so far; `None` when no record carried clearance.
    pub fn summary(&self) -> Option<ClearanceSummary> {
        let ids = |m: [usize; 2]| m.map(|k| self.member_ids.get(k).cloned().unwrap_or_else(|| k.to_string()));
        self.tracked.then(|| ClearanceSummary {
            nearest: self.nearest.as_ref().map(|(stage, step, time, n)| NearestSummary {
                clearance: n.clearance,
                members: ids(n.members),
                stage: stage.name().into(),
                step: *step,
                time: *time,
            }),
            events: self
                .events
                .iter()
                .map(|(stage, e)| EventSummary {
                    kind: e.kind.as_str().into(),
                    members: ids(e.members),
                    stage: stage.name().into(),
                    step: e.step,
                    time: e.time,
                    clearance: e.clearance,
                })
                .collect(),
            event_count: self.event_count,
        })
    }
}

impl Observer for ClearanceLog {
    fn model(&mut self, record: &ModelRecord) {
        self.member_ids = record.model.members.iter().map(|m| m.id.clone()).collect();
    }
    fn formfinding(&mut self, record: &FormFindRecord) {
        self.note(record.stage, 0, 0.0, record.clearance);
    }
    fn begin_stage(&mut self, stage: &Stage) {
        self.stage = stage.clone();
    }
    fn frame(&mut self, frame: &Frame) {
        let stage = self.stage.clone();
        self.note(&stage, frame.step, frame.time, frame.clearance);
    }
}
