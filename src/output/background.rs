//! Runs a recorder's streaming on a thread of its own, so that the solver never waits for
//! compression, encoding or disk.
//!
//! [`Background`] wraps a file recorder. The one-off calls (`model`, `formfinding`, `rigidity`, `eigen`,
//! `finish`) run on the caller's thread, as before. At `begin_stage` the recorder moves to a
//! worker thread; the stage's frames are copied into blocks (at most [`BLOCK_FRAMES`] frames
//! or about [`BLOCK_BYTES`]) and sent through a channel of at most [`QUEUE_BLOCKS`] blocks,
//! so memory stays bounded whatever the number of steps: when the worker falls behind, the
//! solver waits rather than buffers. Any call other than `begin_stage`, `frame` and
//! `end_stage` first hands the pending block over, waits for the worker to drain the queue,
//! and takes the recorder back, so the wrapped recorder sees exactly the calls, in exactly
//! the order, it would have seen without the wrapper.
//!
//! Errors: a failure on the worker stops it; the next call returns that error (the file's
//! status is then set by `finish`, which turns a "complete" into "failed: recording failed:
//! <error>", since the file is missing data). A wrapper dropped without `finish` takes its
//! recorder back and drops it, which records "failed: recorder dropped before finish" as a
//! direct recorder would.

use crate::contact::Active;
use crate::record::{
    ClearanceEvent, Constraints, EigenRecord, Energy, FormFindRecord, Frame, FrameClearance, FrameModes, ModelRecord, Nearest, Outcome,
    RecordResult, Recorder, RigidityRecord, Stage,
};
use nalgebra::Vector3;
use std::sync::mpsc::{channel, sync_channel, Receiver, Sender, SyncSender};
use std::thread::JoinHandle;

type Error = Box<dyn std::error::Error + Send + Sync>;

/// Most frames in one block sent to the worker.
pub const BLOCK_FRAMES: usize = 64;
/// A block is sent once it holds this many bytes of frame data (at least one frame).
pub const BLOCK_BYTES: usize = 1 << 20;
/// Most blocks queued for the worker; with the block being filled and the one being written,
/// at most `QUEUE_BLOCKS + 2` blocks are in memory.
pub const QUEUE_BLOCKS: usize = 4;

enum Command {
    Begin(Stage, Constraints),
    Frames(Vec<OwnedFrame>),
    End(Stage),
}

/// A recorder whose time-stepping stages are recorded on a worker thread.
pub struct Background<R: Recorder + Send + 'static> {
    name: String,
    state: State<R>,
    /// The block being filled; `filled` of its frames are in use, the rest are spares.
    block: Vec<OwnedFrame>,
    filled: usize,
    /// First failure of the worker, reported again by every later call.
    failed: Option<String>,
}

enum State<R> {
    /// On the caller's thread.
    Direct(R),
    /// On the worker.
    Running {
        commands: SyncSender<Command>,
        /// Blocks the worker has written, for reuse.
        spent: Receiver<Vec<OwnedFrame>>,
        worker: JoinHandle<(R, RecordResult)>,
    },
    /// Lost to a panic on the worker.
    Lost,
}

impl<R: Recorder + Send + 'static> Background<R> {
    /// Wraps `recorder`; `name` names its worker thread.
    pub fn new(recorder: R, name: &str) -> Self {
        Background {
            name: name.into(),
            state: State::Direct(recorder),
            block: Vec::new(),
            filled: 0,
            failed: None,
        }
    }

    fn check(&self) -> RecordResult {
        match &self.failed {
            Some(e) => Err(e.clone().into()),
            None => Ok(()),
        }
    }

    /// The recorder on this thread, after the worker (if any) has drained its queue.
    fn direct(&mut self) -> Result<&mut R, Error> {
        self.join()?;
        match &mut self.state {
            State::Direct(r) => Ok(r),
            _ => Err(format!("{}: recorder lost to a panic", self.name).into()),
        }
    }

    /// Moves the recorder to a new worker thread.
    fn spawn(&mut self) -> RecordResult {
        if !matches!(self.state, State::Direct(_)) {
            return Ok(());
        }
        let State::Direct(recorder) = std::mem::replace(&mut self.state, State::Lost) else {
            unreachable!("checked above");
        };
        let (commands, inbox) = sync_channel(QUEUE_BLOCKS);
        let (give_back, spent) = channel();
        let worker = std::thread::Builder::new()
            .name(self.name.clone())
            .spawn(move || work(recorder, inbox, give_back))?;
        self.state = State::Running { commands, spent, worker };
        Ok(())
    }

    /// Hands the pending block over, stops the worker once its queue is written and takes the
    /// recorder back; returns the worker's error, if any.
    fn join(&mut self) -> RecordResult {
        if matches!(self.state, State::Running { .. }) {
            // A failure here has joined already and is reported below.
            let _ = self.send_block();
        }
        self.state = match std::mem::replace(&mut self.state, State::Lost) {
            State::Running { commands, worker, .. } => {
                drop(commands);
                match worker.join() {
                    Ok((recorder, result)) => {
                        if let Err(e) = result {
                            self.failed.get_or_insert_with(|| e.to_string());
                        }
                        State::Direct(recorder)
                    }
                    Err(_) => {
                        self.failed
                            .get_or_insert_with(|| format!("{}: recorder thread panicked", self.name));
                        State::Lost
                    }
                }
            }
            other => other,
        };
        self.check()
    }

    /// Sends `command`; if the worker has stopped, takes the recorder back and returns why.
    fn send(&mut self, command: Command) -> RecordResult {
        self.check()?;
        if let State::Running { commands, .. } = &self.state {
            if commands.send(command).is_ok() {
                return Ok(());
            }
            // The worker stopped on an error: `join` reports it.
            self.join()?;
            return Err(format!("{}: recorder thread stopped", self.name).into());
        }
        Ok(())
    }

    fn send_block(&mut self) -> RecordResult {
        if self.filled == 0 {
            return Ok(());
        }
        let mut block = match &self.state {
            State::Running { spent, .. } => spent.try_recv().unwrap_or_default(),
            _ => Vec::new(),
        };
        std::mem::swap(&mut block, &mut self.block);
        block.truncate(self.filled);
        self.filled = 0;
        self.send(Command::Frames(block))
    }
}

/// The worker: records the commands in order until the channel closes or a call fails.
fn work<R: Recorder>(mut recorder: R, inbox: Receiver<Command>, give_back: Sender<Vec<OwnedFrame>>) -> (R, RecordResult) {
    let run = || -> RecordResult {
        for command in inbox {
            match command {
                Command::Begin(stage, constraints) => recorder.begin_stage(&stage, &constraints)?,
                Command::Frames(block) => {
                    for frame in &block {
                        recorder.frame(&frame.as_frame())?;
                    }
                    let _ = give_back.send(block);
                }
                Command::End(stage) => recorder.end_stage(&stage)?,
            }
        }
        Ok(())
    };
    let result = run();
    (recorder, result)
}

impl<R: Recorder + Send + 'static> Recorder for Background<R> {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        self.direct()?.model(record)
    }

    fn formfinding(&mut self, record: &FormFindRecord) -> RecordResult {
        self.direct()?.formfinding(record)
    }

    fn rigidity(&mut self, record: &RigidityRecord) -> RecordResult {
        self.direct()?.rigidity(record)
    }

    fn eigen(&mut self, record: &EigenRecord) -> RecordResult {
        self.direct()?.eigen(record)
    }

    fn begin_stage(&mut self, stage: &Stage, constraints: &Constraints) -> RecordResult {
        self.check()?;
        self.spawn()?;
        self.send(Command::Begin(stage.clone(), constraints.clone()))
    }

    fn frame(&mut self, frame: &Frame) -> RecordResult {
        if !matches!(self.state, State::Running { .. }) {
            return self.direct()?.frame(frame);
        }
        self.check()?;
        match self.block.get_mut(self.filled) {
            Some(spare) => spare.copy_from(frame),
            None => self.block.push(OwnedFrame::from(frame)),
        }
        self.filled += 1;
        let bytes = self.filled * self.block[0].bytes();
        if self.filled >= BLOCK_FRAMES || bytes >= BLOCK_BYTES {
            self.send_block()?;
        }
        Ok(())
    }

    fn end_stage(&mut self, stage: &Stage) -> RecordResult {
        if !matches!(self.state, State::Running { .. }) {
            return self.direct()?.end_stage(stage);
        }
        self.send_block()?;
        self.send(Command::End(stage.clone()))
    }

    /// Waits for the worker to write everything, then finishes on this thread.
    fn finish(&mut self, outcome: &Outcome) -> RecordResult {
        let joined = self.join();
        let State::Direct(recorder) = &mut self.state else {
            return joined;
        };
        let finished = recorder.finish(&outcome.unless_recording_failed(&joined));
        // The worker's error came first; what finishing then failed on follows from it.
        joined.and(finished)
    }
}

impl<R: Recorder + Send + 'static> Drop for Background<R> {
    /// Takes the recorder back (waiting for its queue) and drops it here, so that its own
    /// `Drop` marks an unfinished file as failed.
    fn drop(&mut self) {
        let _ = self.join();
    }
}

/// A [`Frame`] that owns its data.
#[derive(Default)]
pub(super) struct OwnedFrame {
    step: usize,
    time: f64,
    positions: Vec<Vector3<f64>>,
    velocities: Option<Vec<Vector3<f64>>>,
    forces: Vec<f64>,
    lengths: Vec<f64>,
    rest_lengths: Option<Vec<f64>>,
    viscous_forces: Option<Vec<f64>>,
    energy: Energy,
    applied: Vec<Vector3<f64>>,
    reactions: Vec<f64>,
    equilibrium_error: f64,
    /// (ω², lowest mode) when the frame has modes.
    modes: Option<(Vec<f64>, Vec<Vector3<f64>>)>,
    /// (nearest pair, events) when the frame has clearance.
    clearance: Option<(Option<Nearest>, Vec<ClearanceEvent>)>,
    contacts: Vec<Active>,
}

impl OwnedFrame {
    /// Copies `f` reusing this frame's allocations.
    fn copy_from(&mut self, f: &Frame) {
        self.step = f.step;
        self.time = f.time;
        self.energy = f.energy;
        refill(&mut self.positions, f.positions);
        refill_some(&mut self.velocities, f.velocities);
        refill(&mut self.forces, f.forces);
        refill_some(&mut self.viscous_forces, f.viscous_forces);
        refill(&mut self.lengths, f.lengths);
        refill_some(&mut self.rest_lengths, f.rest_lengths);
        refill(&mut self.applied, f.applied);
        refill(&mut self.reactions, f.reactions);
        self.equilibrium_error = f.equilibrium_error;
        match f.modes {
            Some(m) => {
                let (omega2, lowest) = self.modes.get_or_insert_with(Default::default);
                refill(omega2, m.omega2);
                refill(lowest, m.lowest);
            }
            None => self.modes = None,
        }
        match f.clearance {
            Some(c) => {
                let (nearest, events) = self.clearance.get_or_insert_with(Default::default);
                *nearest = c.nearest;
                refill(events, c.events);
            }
            None => self.clearance = None,
        }
        refill(&mut self.contacts, f.contacts);
    }

    fn from(f: &Frame) -> Self {
        let mut owned = OwnedFrame::default();
        owned.copy_from(f);
        owned
    }

    /// Approximate size of the frame's data [bytes].
    fn bytes(&self) -> usize {
        let vectors = self.positions.len() + self.velocities.as_ref().map_or(0, Vec::len) + self.applied.len();
        let rest = self.rest_lengths.as_ref().map_or(0, Vec::len) + self.viscous_forces.as_ref().map_or(0, Vec::len);
        std::mem::size_of::<Self>() + 24 * vectors + 8 * (self.forces.len() + self.lengths.len() + rest + self.reactions.len())
    }

    fn as_frame(&self) -> Frame<'_> {
        Frame {
            step: self.step,
            time: self.time,
            positions: &self.positions,
            velocities: self.velocities.as_deref(),
            forces: &self.forces,
            viscous_forces: self.viscous_forces.as_deref(),
            lengths: &self.lengths,
            rest_lengths: self.rest_lengths.as_deref(),
            energy: self.energy,
            applied: &self.applied,
            reactions: &self.reactions,
            equilibrium_error: self.equilibrium_error,
            modes: self.modes.as_ref().map(|(omega2, lowest)| FrameModes { omega2, lowest }),
            clearance: self
                .clearance
                .as_ref()
                .map(|(nearest, events)| FrameClearance { nearest: *nearest, events }),
            contacts: &self.contacts,
        }
    }
}

fn refill<T: Copy>(v: &mut Vec<T>, src: &[T]) {
    v.clear();
    v.extend_from_slice(src);
}

/// `refill` of an optional part of a frame: kept allocated while frames have it.
fn refill_some<T: Copy>(v: &mut Option<Vec<T>>, src: Option<&[T]>) {
    match src {
        Some(src) => refill(v.get_or_insert_with(Vec::new), src),
        None => *v = None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::generate::TowerSpec;
    use crate::output::h5::tests::{drive, temp_path};
    use crate::output::h5::Hdf5Recorder;
    use std::sync::{Arc, Mutex};

    fn small_tower() -> crate::model::Model {
        TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build()
    }

    /// Logs the calls it receives; fails its frame call at step `fail_at`, and then its
    /// `finish` too (as a file's last block fails to write on a full disk).
    struct Log {
        calls: Arc<Mutex<Vec<String>>>,
        fail_at: Option<usize>,
    }

    impl Recorder for Log {
        fn model(&mut self, _: &ModelRecord) -> RecordResult {
            self.calls.lock().unwrap().push("model".into());
            Ok(())
        }
        fn begin_stage(&mut self, stage: &Stage, constraints: &Constraints) -> RecordResult {
            self.calls
                .lock()
                .unwrap()
                .push(format!("begin {} ({} constrained)", stage.name(), constraints.len()));
            Ok(())
        }
        fn frame(&mut self, frame: &Frame) -> RecordResult {
            if Some(frame.step) == self.fail_at {
                return Err("disk full".into());
            }
            let kind = if frame.velocities.is_some() { "dynamic" } else { "static" };
            self.calls
                .lock()
                .unwrap()
                .push(format!("frame {} {} {kind}", frame.step, frame.time));
            Ok(())
        }
        fn end_stage(&mut self, stage: &Stage) -> RecordResult {
            self.calls.lock().unwrap().push(format!("end {}", stage.name()));
            Ok(())
        }
        fn finish(&mut self, outcome: &Outcome) -> RecordResult {
            self.calls.lock().unwrap().push(format!("finish {outcome}"));
            match self.fail_at {
                Some(_) => Err("cannot write the last block".into()),
                None => Ok(()),
            }
        }
    }

    #[test]
    fn forwards_every_call_in_order() {
        let model = small_tower();
        let calls = Arc::new(Mutex::new(Vec::new()));
        let log = |fail_at| Log {
            calls: calls.clone(),
            fail_at,
        };
        drive(&mut log(None), &model, 200, 1).unwrap();
        log(None).finish(&Outcome::Complete).unwrap();
        let direct = std::mem::take(&mut *calls.lock().unwrap());
        let mut bg = Background::new(log(None), "test");
        drive(&mut bg, &model, 200, 1).unwrap();
        bg.finish(&Outcome::Complete).unwrap();
        assert_eq!(*calls.lock().unwrap(), direct);
        assert!(direct.len() > 3 * 200 && direct.last().unwrap() == "finish complete");
    }

    #[test]
    fn a_worker_failure_surfaces_and_fails_the_status() {
        let model = small_tower();
        let calls = Arc::new(Mutex::new(Vec::new()));
        let mut bg = Background::new(
            Log {
                calls: calls.clone(),
                fail_at: Some(5),
            },
            "test",
        );
        // The failure shows at a later call, at the latest at `finish`; the first error is
        // the one reported, not what finishing then failed on (issue 29: a full disk was
        // reported as a block that "does not continue the dataset").
        let _ = drive(&mut bg, &model, 10, 1);
        let err = bg.finish(&Outcome::Complete).unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        assert!(bg.frame(&OwnedFrame::default().as_frame()).is_err());
        let calls = calls.lock().unwrap();
        assert_eq!(calls.last().unwrap(), "finish failed: recording failed: disk full");
        assert!(!calls.iter().any(|c| c.starts_with("frame 5")));
    }

    #[test]
    fn hdf5_through_the_worker_matches_and_a_drop_is_not_complete() {
        let model = small_tower();
        let (_dir, path) = temp_path("background.h5");
        let mut bg = Background::new(Hdf5Recorder::create(&path, "c", "").unwrap(), "h5");
        drive(&mut bg, &model, 700, 1).unwrap();
        bg.finish(&Outcome::Complete).unwrap();
        let file = hdf5::File::open(&path).unwrap();
        let kinetic = file.dataset("deployment/kinetic_energy").unwrap().read_raw::<f64>().unwrap();
        assert_eq!(kinetic, (0..=700).map(|s| s as f64).collect::<Vec<_>>());
        assert_eq!(crate::output::h5::tests::status(&path), "complete");
        drop(file);

        let mut bg = Background::new(Hdf5Recorder::create(&path, "c", "").unwrap(), "h5");
        bg.model(&ModelRecord {
            model: &model,
            rest_lengths: &[1.0; 12],
            masses: &[1.0; 6],
            mass_reading: "physical",
            stages: &[],
        })
        .unwrap();
        bg.begin_stage(
            &Stage::new(crate::record::StageKind::Transient, "free_vibration"),
            &Constraints::new(&model, &[]),
        )
        .unwrap();
        drop(bg);
        assert_eq!(crate::output::h5::tests::status(&path), "failed: recorder dropped before finish");
    }
}
