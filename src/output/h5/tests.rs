use super::*;
use crate::model::generate::TowerSpec;
use crate::model::Model;
use crate::record::{ClearanceEvent, Constraints, EigenRecord, Energy, EventKind, Nearest, StageLayout};
use hdf5::types::VarLenUnicode;
use nalgebra::Vector3;

/// A path `name` in a fresh directory, which is removed when the guard is dropped.
pub(in crate::output) fn temp_path(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::Builder::new().prefix("tsim-record-").tempdir().unwrap();
    let path = dir.path().join(name);
    (dir, path)
}

/// Drives `rec` through every stage of a synthetic case: form-finding, eigen, then steps
/// 0..=steps of free vibration (dt 0.01 s), folding and deployment, of which, like the
/// stages, it records those with `step % every == 0` and the last. Energies are (step,
/// 2 step, 3 step, 4 step).
pub(in crate::output) fn drive(rec: &mut dyn Recorder, model: &Model, steps: usize, every: usize) -> RecordResult {
    let (n, m) = (model.node_count(), model.members.len());
    let x0 = model.positions();
    // Folding prescribes z of the last node besides the supports.
    let folding = Constraints::new(model, &[(n - 1, 2)]);
    let layout = |kind, name| StageLayout::plain(model, Stage::new(kind, name));
    let stages = [
        StageLayout {
            placeholder: true,
            ..layout(StageKind::Static, "static")
        },
        layout(StageKind::Eigen, "eigen"),
        layout(StageKind::Transient, "free_vibration"),
        StageLayout {
            constraints: folding.clone(),
            ..layout(StageKind::Folding, "folding")
        },
        StageLayout {
            actuated: true,
            ..layout(StageKind::Transient, "deployment")
        },
    ];
    rec.model(&ModelRecord {
        model,
        rest_lengths: &vec![1.0; m],
        masses: &vec![2.0; n],
        mass_reading: "paper",
        stages: &stages,
    })?;
    let forces: Vec<f64> = model
        .members
        .iter()
        .map(|mb| if mb.kind == crate::model::MemberKind::Strut { -10.0 } else { 5.0 })
        .collect();
    rec.formfinding(&FormFindRecord {
        stage: &Stage::of(StageKind::FormFinding),
        residuals: &[1.0, 1e-3, 1e-9],
        positions: &x0,
        forces: &forces,
        clearance: None,
    })?;
    // The analysis itself is tested in crate::rigidity; here it is only written.
    let analysis = crate::rigidity::analyse(model, &x0, None).map_err(|e| e.to_string())?;
    rec.rigidity(&RigidityRecord { analysis: Ok(&analysis) })?;
    let shapes = vec![vec![Vector3::new(0.0, 0.0, 1.0); n]; 4];
    rec.eigen(&EigenRecord {
        stage: &stages[1].stage,
        omega2: &[1.0, 4.0, 9.0, 16.0],
        mode_shapes: &shapes,
        rayleigh_alpha: 0.1,
        rayleigh_beta: 0.01,
        damping_modes: &[1, 2],
        damping_ratio: &[0.02, 0.02],
    })?;
    for layout in &stages[2..] {
        drive_stage(rec, layout, &x0, &forces, steps, every)?;
    }
    Ok(())
}

/// Steps 0..=steps of one stepped stage of [`drive`] (`x0`: the positions at step 0).
fn drive_stage(
    rec: &mut dyn Recorder,
    layout: &StageLayout,
    x0: &[Vector3<f64>],
    forces: &[f64],
    steps: usize,
    every: usize,
) -> RecordResult {
    let StageLayout {
        stage,
        constraints,
        actuated,
        ..
    } = layout;
    let (n, m) = (x0.len(), forces.len());
    let is_folding = stage.kind == StageKind::Folding;
    rec.begin_stage(stage, constraints)?;
    for step in (0..=steps).filter(|s| s % every == 0 || *s == steps) {
        let s = step as f64;
        let positions: Vec<_> = x0.iter().map(|p| p + Vector3::repeat(1e-3 * s)).collect();
        let velocities = vec![Vector3::repeat(s); n];
        let time = if is_folding { s / steps as f64 } else { 0.01 * s };
        let energy = Energy {
            kinetic: s,
            strain: 2.0 * s,
            contact: 6.0 * s,
            damping: 3.0 * s,
            external: 4.0 * s,
            actuation: 5.0 * s,
        };
        let rest = vec![1.0 - 0.001 * s; m];
        let lengths = vec![1.0 + s; m];
        let velocities = (!is_folding).then_some(velocities.as_slice());
        // Struts 0 and 1 approach by 0.01 m a step; a touch is reported at the last.
        let touch = ClearanceEvent {
            kind: EventKind::Touch,
            members: [0, 1],
            step,
            time,
            clearance: -0.01 * s,
        };
        let events = if step == steps { vec![touch] } else { vec![] };
        let nearest = Nearest {
            clearance: -0.01 * s,
            members: [0, 1],
            points: [Vector3::zeros(); 2],
            radius: 0.05,
        };
        let viscous: Vec<f64> = forces.iter().map(|f| 1e-3 * s * f).collect();
        rec.frame(&Frame {
            step,
            time,
            positions: &positions,
            velocities,
            forces,
            viscous_forces: velocities.map(|_| viscous.as_slice()),
            lengths: &lengths,
            rest_lengths: actuated.then_some(rest.as_slice()),
            energy,
            applied: &vec![Vector3::new(0.0, 0.0, -s); n],
            reactions: &(0..constraints.len()).map(|k| k as f64 + s).collect::<Vec<_>>(),
            equilibrium_error: 1e-12 * s,
            modes: None,
            clearance: Some(crate::record::FrameClearance {
                nearest: Some(nearest),
                events: &events,
            }),
            contacts: &[],
        })?;
    }
    rec.end_stage(stage)
}

pub(in crate::output) fn status(path: &Path) -> String {
    let file = File::open(path).unwrap();
    file.attr("status")
        .unwrap()
        .read_scalar::<FixedUnicode<STATUS_LEN>>()
        .unwrap()
        .as_str()
        .to_string()
}

/// The file [`drive`] writes for a 1-stage, 3-strut tower, recording steps 0, 3, 6, 9
/// and 10 of each stepped stage, finished complete.
fn layout_file() -> (tempfile::TempDir, std::path::PathBuf, Model) {
    let model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    let (dir, path) = temp_path("layout.h5");
    let mut rec = Hdf5Recorder::create(&path, "case-7", "a: 1\n").unwrap();
    // Stride 3 over steps 0..=10: the last step is not a multiple of 3.
    drive(&mut rec, &model, 10, 3).unwrap();
    assert_eq!(status(&path), "running");
    rec.finish(&Outcome::Complete).unwrap();
    assert_eq!(status(&path), "complete");
    (dir, path, model)
}

#[test]
fn writes_the_layout_and_status() {
    let (_dir, path, model) = layout_file();
    let file = File::open(&path).unwrap();
    assert_eq!(
        file.attr("case_id").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
        "case-7"
    );
    assert_eq!(
        file.attr("units").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
        "SI (m, N, kg, s)"
    );
    let (n, m) = (6, 12);
    assert_eq!((model.node_count(), model.members.len()), (n, m));
    assert_eq!(file.dataset("model/member_nodes").unwrap().shape(), vec![m, 2]);
    let mass = file.dataset("model/mass").unwrap();
    assert_eq!(
        mass.attr("mass_reading").unwrap().read_scalar::<VarLenUnicode>().unwrap().as_str(),
        "paper"
    );
    assert_eq!(file.dataset("eigen/mode_shape").unwrap().shape(), vec![4, n, 3]);
    assert_eq!(
        file.group("eigen")
            .unwrap()
            .attr("damping_modes")
            .unwrap()
            .read_raw::<i64>()
            .unwrap(),
        vec![1, 2]
    );
}

/// No object carries a timestamp, so a rerun writes the same bytes and outcome.json's CRC
/// compares results (with the root group's times, two runs a second apart differed).
#[test]
fn no_object_records_when_it_was_written() {
    let (_dir, path, _model) = layout_file();
    let file = File::open(&path).unwrap();
    let mut names = vec!["/".to_string()];
    for group in file.groups().unwrap() {
        names.push(group.name());
        names.extend(group.datasets().unwrap().iter().map(|d| d.name()));
    }
    assert!(names.len() > 20, "{names:?}");
    for name in names {
        let info = file.loc_info_by_name(&name).unwrap();
        assert_eq!((info.atime, info.mtime, info.ctime, info.btime), (0, 0, 0, 0), "{name}");
    }
}

#[test]
fn writes_each_stage_series() {
    let (_dir, path, _model) = layout_file();
    let file = File::open(&path).unwrap();
    let (n, m) = (6, 12);
    // Steps 0, 3, 6, 9 and the last, 10.
    let time = file.dataset("free_vibration/time").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(time, [0.0, 3.0, 6.0, 9.0, 10.0].map(|s| 0.01 * s));
    assert_eq!(
        file.dataset("folding/time").unwrap().read_raw::<f64>().unwrap(),
        vec![0.0, 3.0, 6.0, 9.0, 10.0]
    );
    assert_eq!(
        file.dataset("folding/fraction").unwrap().read_raw::<f64>().unwrap(),
        vec![0.0, 0.3, 0.6, 0.9, 1.0]
    );
    assert_eq!(file.dataset("deployment/position").unwrap().shape(), vec![5, n, 3]);
    assert_eq!(file.dataset("deployment/velocity").unwrap().shape(), vec![5, n, 3]);
    assert!(file.dataset("folding/velocity").is_err());
    assert_eq!(
        file.dataset("deployment/kinetic_energy").unwrap().read_raw::<f64>().unwrap(),
        vec![0.0, 3.0, 6.0, 9.0, 10.0]
    );
    assert_eq!(file.dataset("deployment/member_length").unwrap().shape(), vec![5, m]);
    // The actuated stage (deployment in `drive`) records rest lengths and the actuators'
    // work; the others do not have them.
    let rest = file.dataset("deployment/rest_length").unwrap().read_2d::<f64>().unwrap();
    assert_eq!(rest.shape(), [5, m]);
    assert_eq!(rest[[4, 0]], 1.0 - 0.001 * 10.0);
    assert_eq!(
        file.dataset("deployment/actuator_work").unwrap().read_raw::<f64>().unwrap(),
        vec![0.0, 15.0, 30.0, 45.0, 50.0]
    );
    assert!(file.dataset("free_vibration/rest_length").is_err() && file.dataset("free_vibration/actuator_work").is_err());
}

#[test]
fn writes_the_constrained_directions_and_clearance() {
    let (_dir, path, model) = layout_file();
    let file = File::open(&path).unwrap();
    let n = model.node_count();
    // 6 supported directions, and in folding the prescribed z of the last node.
    assert_eq!(file.dataset("deployment/reaction").unwrap().shape(), vec![5, 6]);
    let reaction = file.dataset("folding/reaction").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(reaction.len(), 5 * 7);
    assert_eq!(reaction[7..14], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0].map(|k| k + 3.0));
    let labels = |name: &str| -> Vec<String> {
        let ds = file.dataset(name).unwrap();
        ds.read_raw::<VarLenUnicode>().unwrap().iter().map(|s| s.to_string()).collect()
    };
    assert_eq!(labels("folding/support")[6], format!("{}.z", model.nodes[n - 1].id));
    assert_eq!(labels("folding/support_kind")[6], "prescribed");
    assert_eq!(labels("folding/support_node")[0], model.nodes[0].id);
    assert_eq!(labels("deployment/support_axis")[..2], ["x", "y"]);
    assert_eq!(
        file.dataset("free_vibration/applied_load").unwrap().read_raw::<f64>().unwrap()[3 * n * 4 + 2],
        -10.0
    );
    assert_eq!(
        file.dataset("folding/equilibrium_error").unwrap().read_raw::<f64>().unwrap()[4],
        1e-12 * 10.0
    );
    assert_eq!(
        file.dataset("structure_analysis/mechanism").unwrap().shape(),
        vec![
            3 * n - model.support_count(),
            file.group("structure_analysis")
                .unwrap()
                .attr("m_internal")
                .unwrap()
                .read_scalar::<i64>()
                .unwrap() as usize
        ]
    );
    let read = |name: &str| file.dataset(name).unwrap().read_raw::<f64>().unwrap();
    assert_eq!(read("deployment/min_clearance"), [0.0, 3.0, 6.0, 9.0, 10.0].map(|s| -0.01 * s));
    assert_eq!(read("folding/min_clearance_pair"), [0.0, 1.0].repeat(5));
    assert_eq!(read("folding/clearance_event_time"), [1.0]);
    assert_eq!(read("deployment/clearance_event_clearance"), [-0.1]);
    let ints = |name: &str| file.dataset(name).unwrap().read_raw::<i64>().unwrap();
    assert_eq!(ints("deployment/clearance_event_step"), [10]);
    assert_eq!(ints("deployment/clearance_event_pair"), [0, 1]);
    assert_eq!(
        file.dataset("deployment/clearance_event_kind").unwrap().read_raw::<i8>().unwrap(),
        [0]
    );
    assert!(file.dataset("formfinding/min_clearance").is_err(), "not followed there");
    for group in [
        "model",
        "formfinding",
        "structure_analysis",
        "eigen",
        "free_vibration",
        "folding",
        "deployment",
    ] {
        let g = file.group(group).unwrap();
        for name in g.member_names().unwrap() {
            let ds = g.dataset(&name).unwrap();
            let attrs = ds.attr_names().unwrap();
            assert!(
                attrs.contains(&"units".to_string()) && attrs.contains(&"long_name".to_string()),
                "{group}/{name}"
            );
            // A dimension scale (CLASS) or attached to scales (DIMENSION_LIST).
            assert!(
                attrs.contains(&"CLASS".to_string()) || attrs.contains(&"DIMENSION_LIST".to_string()),
                "{group}/{name}: {attrs:?}"
            );
        }
    }
}

#[test]
fn streams_in_chunks_and_reports_failure() {
    let model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    let (_dir, path) = temp_path("chunks.h5");
    let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
    drive(&mut rec, &model, 600, 1).unwrap();
    rec.finish(&Outcome::Failed("é".repeat(400))).unwrap();
    let file = File::open(&path).unwrap();
    let time = file.dataset("free_vibration/time").unwrap();
    assert_eq!(time.shape(), vec![601]);
    assert_eq!(time.chunk(), Some(vec![CHUNK_STEPS]));
    assert_eq!(
        file.dataset("free_vibration/strain_energy").unwrap().read_raw::<f64>().unwrap()[600],
        1200.0
    );
    let status = status(&path);
    assert!(status.starts_with("failed: é") && status.len() <= STATUS_LEN && status.len() >= STATUS_LEN - 1);
}

/// A model without supports has an empty `support` dimension (folding here still
/// prescribes one direction): the datasets exist and are written.
#[test]
fn a_model_without_supports_has_an_empty_support_dimension() {
    let mut model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    model.nodes.iter_mut().for_each(|n| n.support = [false; 3]);
    let (_dir, path) = temp_path("free.h5");
    let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
    drive(&mut rec, &model, 5, 1).unwrap();
    rec.finish(&Outcome::Complete).unwrap();
    let file = File::open(&path).unwrap();
    assert_eq!(file.dataset("deployment/reaction").unwrap().shape(), vec![6, 0]);
    assert_eq!(file.dataset("deployment/support").unwrap().shape(), vec![0]);
    assert_eq!(file.dataset("folding/reaction").unwrap().shape(), vec![6, 1]);
    assert_eq!(file.dataset("deployment/applied_load").unwrap().shape(), vec![6, 6, 3]);
}

#[test]
fn dropped_recorder_is_not_complete() {
    let model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    let (_dir, path) = temp_path("dropped.h5");
    let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
    rec.model(&ModelRecord {
        model: &model,
        rest_lengths: &[1.0; 12],
        masses: &[1.0; 6],
        mass_reading: "physical",
        stages: &[StageLayout::plain(&model, Stage::new(StageKind::Transient, "free_vibration"))],
    })
    .unwrap();
    rec.begin_stage(&Stage::new(StageKind::Transient, "free_vibration"), &Constraints::new(&model, &[]))
        .unwrap();
    drop(rec);
    assert_eq!(status(&path), "failed: recorder dropped before finish");
}

/// When the last block cannot be written at `finish` (a full disk; here the dataset was
/// extended underneath), the status still says failed, with why: before, `finish` returned
/// on the block's error and the file read "running" forever.
#[test]
fn a_failing_last_block_still_fails_the_status() {
    let model = TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    let (_dir, path) = temp_path("last-block.h5");
    let mut rec = Hdf5Recorder::create(&path, "c", "").unwrap();
    let stage = Stage::new(StageKind::Transient, "free_vibration");
    rec.model(&ModelRecord {
        model: &model,
        rest_lengths: &[1.0; 12],
        masses: &[1.0; 6],
        mass_reading: "physical",
        stages: &[StageLayout::plain(&model, stage.clone())],
    })
    .unwrap();
    // Three frames, held in the unwritten block: the stage is not ended.
    struct Unended<'r>(&'r mut Hdf5Recorder);
    impl Recorder for Unended<'_> {
        fn begin_stage(&mut self, s: &Stage, c: &Constraints) -> RecordResult {
            self.0.begin_stage(s, c)
        }
        fn frame(&mut self, f: &Frame) -> RecordResult {
            self.0.frame(f)
        }
    }
    let layout = StageLayout::plain(&model, stage);
    drive_stage(&mut Unended(&mut rec), &layout, &model.positions(), &[1.0; 12], 2, 1).unwrap();
    let time = rec.open.as_ref().unwrap().file.dataset("free_vibration/time").unwrap();
    time.resize(vec![5]).unwrap();
    let err = rec.finish(&Outcome::Complete).unwrap_err().to_string();
    assert!(err.contains("does not continue the dataset"), "{err}");
    let status = status(&path);
    assert!(status.starts_with("failed: recording failed: /free_vibration/time"), "{status}");
}
