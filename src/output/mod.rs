//! The output files: `result.h5` ([`h5`]) and `replay.mcap` ([`replay`]), each a
//! [`Recorder`], and the one writer thread that can stream them ([`Background`]). The only
//! module below `run` that knows files and threads.

mod background;
mod chunk;
pub mod collected;
pub mod h5;
pub mod replay;

pub use background::Background;

use crate::config::OutputSpec;
use crate::record::{Recorder, Recorders};
use std::path::Path;

/// The file recorders a case's `outputs` asks for, `result.h5` and `replay.mcap` in `dir`,
/// as one recorder. With `background`, both stream on one writer thread; that pays only
/// when a core is free for it, so the runner asks for it only then (with every core
/// running a case, a writer thread just takes turns with the solvers). One thread, not one
/// per file: each frame is copied into one queue instead of two, and the writers do not
/// take turns with each other and the solver on the one free core (wall time on the paper
/// case was the same within noise either way).
/// `params` (a sweep case's parameters) become root attributes of result.h5.
/// `outputs.every` is not theirs to apply: the stages call `frame` only for the steps to
/// record.
pub fn file_recorders(
    outputs: &OutputSpec,
    dir: &Path,
    case_id: &str,
    config_yaml: &str,
    params: &[(String, h5::ParamValue)],
    background: bool,
) -> Result<Box<dyn Recorder + Send>, Box<dyn std::error::Error + Send + Sync>> {
    let mut files: Vec<Box<dyn Recorder + Send>> = Vec::new();
    if outputs.hdf5 {
        let mut h5 = h5::Hdf5Recorder::create(&dir.join("result.h5"), case_id, config_yaml)?;
        h5.write_params(params)?;
        files.push(Box::new(h5));
    }
    if outputs.mcap {
        files.push(Box::new(replay::McapRecorder::create(
            &dir.join("replay.mcap"),
            case_id,
            outputs.replay_rate,
        )?));
    }
    let files = Recorders(files);
    Ok(if background && !files.0.is_empty() {
        Box::new(Background::new(files, "tsim-writer"))
    } else {
        Box::new(files)
    })
}
