//! The config's `stages` list: the paper's sections are shorthand for a list (the same
//! list gives bit-identical results), entries start from named states with the loads that
//! hold them, damping is passed from an eigen stage by name, and a bad list is reported at
//! the entry's line.

mod common;

use common::assert_field_errors;
use nalgebra::Vector3;
use tsim::config::{parse_case, CaseConfig, RayleighSpec, StageEntry, StaticSpec, TransientSpec};
use tsim::pipeline::{run_case, CaseSummary};
use tsim::record::{Frame, RecordResult, Recorder, Stage};

const GROUND_MOTION: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/tower_ground_motion.yaml");
const STAGES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/tower_stages.yaml");

fn config(path: &str) -> CaseConfig {
    let text = std::fs::read_to_string(path).unwrap();
    let mut cfg = parse_case(&text, path).unwrap_or_else(|e| panic!("{e}"));
    tsim::config::resolve_tables(&mut cfg, &text, path, &mut Default::default()).unwrap_or_else(|e| panic!("{e}"));
    cfg
}

/// One frame: (stage name, step, time, positions, forces, energy terms).
type Logged = (String, usize, f64, Vec<Vector3<f64>>, Vec<f64>, [f64; 5]);

/// Every frame of every stage.
#[derive(Default)]
struct Frames {
    stage: Option<Stage>,
    frames: Vec<Logged>,
}

impl Recorder for Frames {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &tsim::record::Constraints) -> RecordResult {
        self.stage = Some(stage.clone());
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        let e = f.energy;
        let name = self.stage.as_ref().expect("a frame inside a stage").name().to_string();
        self.frames.push((
            name,
            f.step,
            f.time,
            f.positions.to_vec(),
            f.forces.to_vec(),
            [e.kinetic, e.strain, e.damping, e.external, e.actuation],
        ));
        Ok(())
    }
}

fn run(cfg: &CaseConfig) -> (CaseSummary, Frames) {
    let mut frames = Frames::default();
    let summary = run_case(cfg, &mut frames).unwrap_or_else(|e| panic!("{}: {e}", cfg.name));
    (summary, frames)
}

/// The summary without its wall times, as JSON.
fn figures(s: &CaseSummary) -> serde_json::Value {
    let mut v = serde_json::to_value(s).unwrap();
    let case = v.as_object_mut().unwrap();
    case.remove("stage_seconds");
    for stage in case.values_mut().filter_map(|s| s.as_object_mut()) {
        stage.remove("wall_seconds");
    }
    v
}

/// The paper's sections (gravity, eigen with Rayleigh damping, damped free vibration)
/// and the `stages` list that names the same stages give the same frames and figures to
/// the last bit: the shorthand is that list.
#[test]
fn the_paper_sections_are_shorthand_for_a_list() {
    let mut paper = config(GROUND_MOTION);
    paper.eigen.as_mut().unwrap().rayleigh = Some(RayleighSpec::Modes {
        modes: [1, 6],
        ratios: [0.02, 0.02],
    });
    paper.free_vibration.as_mut().unwrap().damped = true;
    let entry = |name: &str| StageEntry {
        name: name.into(),
        from: None,
        statics: None,
        eigen: None,
        transient: None,
        folding: None,
        hold: None,
    };
    let transient = TransientSpec {
        damped: false,
        rayleigh_from: Some("eigen".into()),
        ..paper.free_vibration.clone().unwrap()
    };
    let listed = CaseConfig {
        stages: vec![
            StageEntry {
                statics: Some(StaticSpec::default()),
                ..entry("static")
            },
            StageEntry {
                eigen: paper.eigen.clone(),
                ..entry("eigen")
            },
            // From the loaded equilibrium, as the paper's free vibration starts.
            StageEntry {
                from: Some("static".into()),
                transient: Some(transient),
                ..entry("free_vibration")
            },
        ],
        eigen: None,
        free_vibration: None,
        ..paper.clone()
    };
    listed.validate().unwrap_or_else(|e| panic!("{e:?}"));
    let ((a, fa), (b, fb)) = (run(&paper), run(&listed));
    assert!(a.eigen("eigen").unwrap().rayleigh_beta > 0.0, "the case is damped");
    assert_eq!(figures(&a), figures(&b));
    assert_eq!(fa.frames.len(), fb.frames.len());
    for (x, y) in fa.frames.iter().zip(&fb.frames) {
        assert!(x == y, "{} step {} differs", x.0, x.1);
    }
}

/// tower_stages.yaml: gravity → eigen → ground motion damped by the eigen stage's α, β →
/// free decay from the end of the ground motion. Each transient starts where the one
/// before ended (positions and velocities), both are damped as the eigen stage says, and
/// the decay loses energy once the ground is still.
#[test]
fn a_listed_sequence_passes_states_and_damping_by_name() {
    let cfg = config(STAGES);
    let (summary, log) = run(&cfg);
    let names: Vec<&String> = summary.stages.keys().collect();
    assert_eq!(names, ["decay", "gravity", "modes", "quake"]);
    let modes = summary.eigen("modes").unwrap();
    assert!(modes.rayleigh_alpha > 0.0 && modes.rayleigh_beta > 0.0);
    let frames = |name: &'static str| log.frames.iter().filter(move |f| f.0 == name);
    let last = |name: &'static str| frames(name).next_back().unwrap();
    let quake_end = last("quake");
    let decay_start = frames("decay").next().unwrap();
    assert_eq!(quake_end.3, decay_start.3, "decay starts at the positions quake ended at");
    // Damping work accrues in both transients (both take `rayleigh_from: modes`).
    for name in ["quake", "decay"] {
        let end = last(name);
        assert!(end.5[2] > 0.0, "{name}: dissipated {:e} J", end.5[2]);
    }
    // In the decay nothing drives the tower: kinetic + strain − external work falls.
    let mechanical = |f: &Logged| f.5[0] + f.5[1] - f.5[3];
    let (first, end) = (decay_start, last("decay"));
    assert!(mechanical(end) < mechanical(first), "{} → {}", mechanical(first), mechanical(end));
}

/// A static stage from a loaded state steps only its own pattern: gravity, then a top load
/// in a second static stage, ends where one stage with gravity and the load together does
/// (the elastic equilibrium under the same total load), to the Newton tolerance.
#[test]
fn a_static_stage_from_a_loaded_state_adds_its_loads() {
    let base = config(STAGES);
    let load = |force| {
        let text = format!("{{ loads: [{{ groups: [top], force: [{force}, 0.0, -200.0] }}] }}");
        serde_saphyr::from_str::<StaticSpec>(&text).unwrap()
    };
    let entry = |name: &str, statics| StageEntry {
        name: name.into(),
        from: None,
        statics: Some(statics),
        eigen: None,
        transient: None,
        folding: None,
        hold: None,
    };
    let two = CaseConfig {
        stages: vec![entry("gravity", StaticSpec::default()), entry("load", load(150.0))],
        ..base.clone()
    };
    let one = CaseConfig {
        stages: vec![entry("both", load(150.0))],
        ..base
    };
    let ((_, a), (_, b)) = (run(&two), run(&one));
    let end = |f: &Frames, name: &str| f.frames.iter().rev().find(|x| x.0 == name).unwrap().3.clone();
    let (x2, x1) = (end(&a, "load"), end(&b, "both"));
    let gap = x2.iter().zip(&x1).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    // The Newton tolerance on displacement increments is ~1e-9 of the model size (3 m);
    // a stage that re-applied gravity from zero would be off by the whole gravity sag (mm).
    assert!(gap < 1e-7, "{gap:e} m apart");
    let first = a.frames.iter().find(|x| x.0 == "load").unwrap();
    let gravity_end = end(&a, "gravity");
    assert_eq!(first.3, gravity_end, "the second static stage starts at the first's end");
}

/// A bad list is reported at the entry's line, with what to write instead.
#[test]
fn a_bad_list_names_the_entry_and_the_fix() {
    let text = "\
name: bad
model: { tower: { struts: 3, stages: 1 } }
formfinding: {}
substitution: { strut: aluminium, cable: nylon }
eigen: {}
stages:
  - name: first
    from: formfindng
    static: { steps: 2 }
  - name: first
    eigen: {}
  - name: shake
    transient: { duration: 0.1, damped: true, rayleigh_from: first }
  - name: both
    static: {}
    eigen: {}
  - name: model
    transient: { duration: 0.1, compare_to: nowhere }
";
    let e = match parse_case(text, "bad.yaml") {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    let expect = [
        (5, "eigen", "move `eigen` into the list"),
        (8, "stages[0].from", "did you mean `formfinding`?"),
        (9, "stages[0].static", "nothing to apply: give `loads` or `gravity`"),
        (10, "stages[1].name", "`first` is taken"),
        (13, "stages[2].transient.damped", "`rayleigh_from: <name>`"),
        (13, "stages[2].transient.rayleigh_from", "is not an eigen stage with `rayleigh`"),
        (14, "stages[3]", "gives 2 kinds"),
        (17, "stages[4].name", "`model` is taken"),
        (18, "stages[4].transient.compare_to", "no earlier stage is named `nowhere`"),
    ];
    assert_field_errors(&e, "bad.yaml", &expect);
}
