//! SIGINT and SIGTERM (Ctrl-C, a scheduler's time limit): the running cases stop at their
//! next recorded step, their files are closed with the status `interrupted` (so that h5py
//! and xarray open them), cases not started are not started, and the summaries are written
//! as for any run. A second signal exits at once.

use crate::record::{Frame, RecordResult, Recorder, Stage};
use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit code of an interrupted run (128 + SIGINT, the shell's convention).
pub const EXIT_INTERRUPTED: u8 = 130;

/// Installs the handler (once per process; `tsim run` calls it).
pub fn install() -> Result<(), ctrlc::Error> {
    ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::SeqCst) {
            std::process::exit(i32::from(EXIT_INTERRUPTED));
        }
    })
}

/// Whether a signal has asked the run to stop.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// The reason a stage stops with, recognised by the runner.
pub const REASON: &str = "interrupted";

/// A recorder that fails the case's next stage start or step once a signal has come.
pub struct Check;

impl Check {
    fn now() -> RecordResult {
        if interrupted() {
            Err(REASON.into())
        } else {
            Ok(())
        }
    }
}

impl Recorder for Check {
    fn begin_stage(&mut self, _stage: &Stage, _constraints: &crate::record::Constraints) -> RecordResult {
        Self::now()
    }
    fn frame(&mut self, _frame: &Frame) -> RecordResult {
        Self::now()
    }
}
