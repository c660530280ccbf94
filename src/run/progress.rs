//! Progress display: an overall bar and one bar per running case showing its stage and
//! simulated time. Hidden when stderr is not a terminal, when `CI` is set, or with
//! `--quiet`; then each finished case prints one plain line instead.

use crate::record::{Frame, Outcome, RecordResult, Recorder, Stage};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

pub struct Progress {
    multi: MultiProgress,
    overall: ProgressBar,
    hidden: bool,
}

impl Progress {
    pub fn new(cases: usize, quiet: bool) -> Self {
        let hidden = quiet || std::env::var_os("CI").is_some() || !std::io::stderr().is_terminal();
        let multi = MultiProgress::with_draw_target(if hidden {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        });
        let overall = multi.add(ProgressBar::new(cases as u64));
        overall.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} cases  {elapsed_precise} (eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Progress { multi, overall, hidden }
    }

    /// A recorder that shows one case's progress.
    pub fn case_bar(&self, id: &str) -> CaseBar {
        let bar = self.multi.insert_before(&self.overall, ProgressBar::new_spinner());
        bar.set_style(ProgressStyle::with_template("  {spinner} {prefix}: {msg}").unwrap_or_else(|_| ProgressStyle::default_spinner()));
        bar.set_prefix(id.to_string());
        CaseBar { bar, stage: "".into() }
    }

    /// Records a finished case: on the bars, or as one log line when they are hidden.
    pub fn done(&self, id: &str, status: &str, wall: f64) {
        self.overall.inc(1);
        let line = format!(
            "[{}/{}] {id}: {status} ({wall:.1} s)",
            self.overall.position(),
            self.overall.length().unwrap_or(0)
        );
        if self.hidden {
            eprintln!("{line}");
        } else {
            self.multi.suspend(|| eprintln!("{line}"));
        }
    }

    pub fn finish(&self) {
        self.overall.finish_and_clear();
    }
}

/// One case's bar; as a [`Recorder`] it learns the stage and time from the pipeline.
pub struct CaseBar {
    bar: ProgressBar,
    stage: std::sync::Arc<str>,
}

impl Recorder for CaseBar {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &crate::record::Constraints) -> RecordResult {
        self.stage = stage.name.clone();
        self.bar.set_message(self.stage.to_string());
        Ok(())
    }
    fn frame(&mut self, frame: &Frame) -> RecordResult {
        // A hidden bar (--quiet, CI, no terminal) draws nothing: no message to format.
        if frame.step % 50 == 0 && !self.bar.is_hidden() {
            self.bar.set_message(format!("{} t = {:.2}", self.stage, frame.time));
            self.bar.tick();
        }
        Ok(())
    }
    fn finish(&mut self, _outcome: &Outcome) -> RecordResult {
        self.bar.finish_and_clear();
        Ok(())
    }
}
