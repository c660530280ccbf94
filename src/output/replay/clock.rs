//! The replay's log timeline: stages back to back, static steps of [`STATIC_STEP`], log
//! times strictly increasing on every topic.

use super::STATIC_STEP;
use crate::record::Frame;

/// Places stages and steps on the log timeline (see [`super`]'s documentation).
#[derive(Default)]
pub(super) struct Clock {
    /// Log time at which the next stage starts [s].
    next: f64,
    /// Start of the current stage [s].
    pub(super) origin: f64,
    folding: bool,
    /// Time within the stage of the latest frame, and the increment that led to it [s].
    latest: Option<f64>,
    step: f64,
    last_step_ns: Option<u64>,
    last_stage_ns: Option<u64>,
}

impl Clock {
    pub(super) fn begin(&mut self, folding: bool) {
        self.origin = self.next;
        self.folding = folding;
        self.latest = None;
        self.step = STATIC_STEP;
    }

    /// Log time of `frame` [s]; also tracks the stage's last step.
    pub(super) fn frame_time(&mut self, frame: &Frame) -> f64 {
        let t = if self.folding {
            frame.step as f64 * STATIC_STEP
        } else {
            frame.time
        };
        if let Some(prev) = self.latest.filter(|&p| t > p) {
            self.step = t - prev;
        }
        self.latest = Some(t);
        self.origin + t
    }

    pub(super) fn end(&mut self) {
        self.next = self.origin + self.latest.unwrap_or(0.0) + self.step;
    }

    /// Advances past a static stage of one step.
    pub(super) fn static_step(&mut self) -> f64 {
        let t = self.next;
        self.next += STATIC_STEP;
        t
    }

    pub(super) fn step_stamp(&mut self, t: f64) -> u64 {
        let ns = nanos(t).max(self.last_step_ns.map_or(0, |l| l + 1));
        self.last_step_ns = Some(ns);
        ns
    }

    /// Never before the previous step: a stage message opens its stage.
    pub(super) fn stage_stamp(&mut self, t: f64) -> u64 {
        let after = |last: Option<u64>| last.map_or(0, |l| l + 1);
        let ns = nanos(t).max(after(self.last_stage_ns)).max(after(self.last_step_ns));
        self.last_stage_ns = Some(ns);
        ns
    }
}

fn nanos(t: f64) -> u64 {
    (t.max(0.0) * 1e9).round() as u64
}
