//! SIGINT and SIGTERM (Ctrl-C, a scheduler's time limit): the running cases stop at their
//! next recorded step, their files are closed with the status `interrupted` (so that h5py
//! and xarray open them), cases not started are not started, and the summaries are written
//! as for any run. A second signal (an impatient Ctrl-C, a scheduler's follow-up) does the
//! same but gives the run at most [`GRACE`] to close its files before exiting; a third
//! exits at once.

use crate::record::{Frame, RecordResult, Recorder, Stage};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static SIGNALS: AtomicUsize = AtomicUsize::new(0);

/// Exit code of an interrupted run (128 + SIGINT, the shell's convention).
pub const EXIT_INTERRUPTED: u8 = 130;

/// How long a second signal waits for the running cases to reach their next step and
/// close their files: a step of the 100k-DOF grid takes well under a second; Slurm sends
/// SIGKILL 30 s after SIGTERM by default (KillWait).
pub const GRACE: Duration = Duration::from_secs(10);

/// Installs the handler (once per process; `tsim run` calls it).
pub fn install() -> Result<(), ctrlc::Error> {
    ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        match SIGNALS.fetch_add(1, Ordering::SeqCst) {
            0 => {}
            1 => {
                eprintln!(
                    "tsim: closing the open files (at most {} s); a third signal exits at once",
                    GRACE.as_secs()
                );
                // Not in the handler itself: it must stay free for a third signal.
                std::thread::spawn(|| {
                    std::thread::sleep(GRACE);
                    std::process::exit(i32::from(EXIT_INTERRUPTED));
                });
            }
            _ => std::process::exit(i32::from(EXIT_INTERRUPTED)),
        }
    })
}

/// Asks the running cases to stop as a first signal would: the Python package's
/// KeyboardInterrupt, where the process's signals are Python's.
pub fn request_stop() {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Forgets an earlier stop request, so that a process that runs several times (a Python
/// session) starts each run afresh.
pub fn clear_stop() {
    INTERRUPTED.store(false, Ordering::SeqCst);
    SIGNALS.store(0, Ordering::SeqCst);
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
