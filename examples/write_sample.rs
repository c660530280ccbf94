//! Writes `result.h5` and `replay.mcap` for the paper's tower with synthetic but known data,
//! for the Python interop tests (tests/python/test_outputs.py), which recompute the same
//! values:
//! - form-finding: residuals 1, 1e-3, 1e-9; positions = the nominal geometry; forces −10 N
//!   (struts) and 5 N (cables); eigen: ω² = 1, 4, 9, 16, no damping modes;
//! - free vibration and deployment: steps 0..=301, time = 1e-3 s × step; folding: steps
//!   0..=21, fraction = step / 21;
//! - at step s: position = initial + 1e-3 s (every component), velocity = s, member length =
//!   1 + s, energies kinetic 0.5 s, strain 100 − 0.5 s, damping 0.01 s, external 0.02 s,
//!   smallest clearance 0.5 − 1e-3 s [m] between members 0 and 1, no clearance event;
//!   form-finding: clearance not followed.
//!
//! Usage: `write_sample OUTDIR [--every N] [--slow]`. `--every N` records, as the stages do
//! for `outputs.every`, the steps with `step % N == 0` and the last. `--slow` runs 3000
//! free-vibration steps at 2 ms each (about 6 s) so that a reader can watch the file grow or
//! the process be killed. The recorders run as in `tsim run`: each on a background thread.

use nalgebra::Vector3;
use std::path::PathBuf;
use tsim::model::generate::TowerSpec;
use tsim::model::{MemberKind, Model};
use tsim::output::h5::Hdf5Recorder;
use tsim::output::replay::McapRecorder;
use tsim::output::Background;
use tsim::record::{
    Constraints, EigenRecord, Energy, FormFindRecord, Frame, FrameClearance, ModelRecord, Nearest, Outcome, RecordResult, Recorder, Stage,
    StageKind, StageLayout,
};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// The command line: output directory, `--every`, `--slow`.
fn args() -> Result<(PathBuf, usize, bool)> {
    let mut args = std::env::args().skip(1);
    let (mut out, mut every, mut slow) = (None, 1, false);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--every" => every = args.next().ok_or("--every needs a value")?.parse()?,
            "--slow" => slow = true,
            _ => out = Some(PathBuf::from(arg)),
        }
    }
    let out = out.ok_or("usage: write_sample OUTDIR [--every N] [--slow]")?;
    if every == 0 {
        return Err("--every must be at least 1".into());
    }
    Ok((out, every, slow))
}

/// `f` on each recorder in turn.
fn each(recorders: &mut [&mut dyn Recorder], mut f: impl FnMut(&mut dyn Recorder) -> RecordResult) -> RecordResult {
    recorders.iter_mut().try_for_each(|r| f(&mut **r))
}

fn main() -> Result<()> {
    let (out, every, slow) = args()?;
    std::fs::create_dir_all(&out)?;
    let h5 = Hdf5Recorder::create(&out.join("result.h5"), "sample", "case: sample\n")?;
    // Replay rate 0: every frame, which the interop tests count.
    let mcap = McapRecorder::create(&out.join("replay.mcap"), "sample", 0.0)?;
    let (mut h5, mut mcap) = (Background::new(h5, "hdf5"), Background::new(mcap, "mcap"));
    let recorders: &mut [&mut dyn Recorder] = &mut [&mut h5, &mut mcap];

    let model = TowerSpec::paper().build();
    let (n, m) = (model.node_count(), model.members.len());
    let x0 = model.positions();
    let forces: Vec<f64> = model
        .members
        .iter()
        .map(|mb| if mb.kind == MemberKind::Strut { -10.0 } else { 5.0 })
        .collect();
    let (rest, masses) = (vec![1.0; m], vec![2.0; n]);
    let layout = |kind, name| StageLayout::plain(&model, Stage::new(kind, name));
    let stages = [
        StageLayout {
            placeholder: true,
            ..layout(StageKind::Static, "static")
        },
        layout(StageKind::Eigen, "eigen"),
        layout(StageKind::Transient, "free_vibration"),
        layout(StageKind::Folding, "folding"),
        layout(StageKind::Transient, "deployment"),
    ];
    each(recorders, |r| {
        r.model(&ModelRecord {
            model: &model,
            rest_lengths: &rest,
            masses: &masses,
            mass_reading: "physical",
            stages: &stages,
        })
    })?;
    each(recorders, |r| {
        r.formfinding(&FormFindRecord {
            stage: &Stage::of(StageKind::FormFinding),
            residuals: &[1.0, 1e-3, 1e-9],
            positions: &x0,
            forces: &forces,
            clearance: None,
        })
    })?;
    let shapes = vec![vec![Vector3::new(0.0, 0.0, 1.0); n]; 4];
    let eigen = EigenRecord {
        stage: &stages[1].stage,
        omega2: &[1.0, 4.0, 9.0, 16.0],
        mode_shapes: &shapes,
        rayleigh_alpha: 0.1,
        rayleigh_beta: 0.01,
        damping_modes: &[],
        damping_ratio: &[],
    };
    each(recorders, |r| r.eigen(&eigen))?;
    for stage in stages[2..].iter().map(|l| &l.stage) {
        let steps = match stage.name() {
            "folding" => 21,
            "free_vibration" if slow => 3000,
            _ => 301,
        };
        let pace = (slow && stage.name() == "free_vibration").then_some(std::time::Duration::from_millis(2));
        write_stage(recorders, &model, &forces, stage, Steps { steps, every, pace })?;
    }
    each(recorders, |r| r.finish(&Outcome::Complete))?;
    Ok(())
}

/// How a stage of the sample steps: steps 0..=`steps`, recording every `every`-th and the
/// last, each step `pace` apart in wall time (None: at once).
struct Steps {
    steps: usize,
    every: usize,
    pace: Option<std::time::Duration>,
}

/// One stepped stage of the sample (the module's doc gives its values).
fn write_stage(recorders: &mut [&mut dyn Recorder], model: &Model, forces: &[f64], stage: &Stage, pacing: Steps) -> RecordResult {
    let Steps { steps, every, pace } = pacing;
    let (n, m) = (model.node_count(), model.members.len());
    let x0 = model.positions();
    let folding = stage.kind == StageKind::Folding;
    let supports = Constraints::new(model, &[]);
    each(recorders, |r| r.begin_stage(stage, &supports))?;
    // 1 N down on every node, carried by the vertical supports alike.
    let applied = vec![Vector3::new(0.0, 0.0, -1.0); n];
    let vertical = supports.0.iter().filter(|c| c.axis == 2).count() as f64;
    let reactions: Vec<f64> = supports
        .0
        .iter()
        .map(|c| if c.axis == 2 { n as f64 / vertical } else { 0.0 })
        .collect();
    for step in 0..=steps {
        if let Some(pace) = pace {
            std::thread::sleep(pace);
        }
        if step % every != 0 && step != steps {
            continue;
        }
        let s = step as f64;
        let positions: Vec<_> = x0.iter().map(|p| p + Vector3::repeat(1e-3 * s)).collect();
        let velocities = vec![Vector3::repeat(s); n];
        let lengths = vec![1.0 + s; m];
        let viscous = vec![0.0; m];
        let frame = Frame {
            step,
            time: if folding { s / steps as f64 } else { 1e-3 * s },
            positions: &positions,
            velocities: (!folding).then_some(velocities.as_slice()),
            forces,
            viscous_forces: (!folding).then_some(&viscous[..]),
            lengths: &lengths,
            rest_lengths: None,
            energy: Energy {
                kinetic: 0.5 * s,
                strain: 100.0 - 0.5 * s,
                contact: 0.0,
                damping: 0.01 * s,
                external: 0.02 * s,
                actuation: 0.0,
            },
            applied: &applied,
            reactions: &reactions,
            equilibrium_error: 0.0,
            modes: None,
            clearance: Some(FrameClearance {
                nearest: Some(Nearest {
                    clearance: 0.5 - 1e-3 * s,
                    members: [0, 1],
                    points: [x0[0], x0[1]],
                    radius: 0.05,
                }),
                events: &[],
            }),
            contacts: &[],
        };
        each(recorders, |r| r.frame(&frame))?;
    }
    each(recorders, |r| r.end_stage(stage))
}
