//! The hold stage (rest lengths changed in static steps, the loads held) against a closed
//! form, its energy ledger's convergence, its hand-off to the stages after it and the
//! checks of its config entry.

mod common;

use common::assert_field_errors;
use nalgebra::Vector3;
use std::sync::Arc;
use tsim::config::parse_case;
use tsim::dynamics::{Actuator, TimeFunction};
use tsim::law::{ForceLaw, LinearElastic};
use tsim::model::{Member, MemberKind, Model, Node};
use tsim::pipeline::run_case;
use tsim::record::{Frame, RecordResult, Recorder, Stage, StageKind};
use tsim::stage::hold::{Hold, HoldSummary};
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::Elements;

/// A frame's stage name, positions and rest lengths (when it records them).
type Logged = (String, Vec<Vector3<f64>>, Option<Vec<f64>>);

/// Keeps every frame's positions and rest lengths.
#[derive(Default)]
struct Log {
    frames: Vec<Logged>,
    stage: String,
}

impl Recorder for Log {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        self.frames
            .push((self.stage.clone(), f.positions.to_vec(), f.rest_lengths.map(<[f64]>::to_vec)));
        Ok(())
    }
}

/// Two linear-elastic bars in series along x, A–B–C, A and C fixed, B free along x only:
/// with rest lengths l1, l2 and span L, equal forces EA (x − l1)/l1 = EA (L − x − l2)/l2
/// put B at x = L l1 / (l1 + l2).
fn series(rest: [f64; 2], span: f64) -> (Structure, State) {
    let node = |id: &str, x: f64, support: [bool; 3]| Node {
        id: id.into(),
        xyz: Vector3::new(x, 0.0, 0.0),
        support,
    };
    let bar = |id: &str, nodes| Member {
        id: id.into(),
        nodes,
        kind: MemberKind::Cable,
        groups: vec![],
    };
    let x_b = span * rest[0] / (rest[0] + rest[1]);
    let model = Model {
        nodes: vec![
            node("a", 0.0, [true; 3]),
            node("b", x_b, [false, true, true]),
            node("c", span, [true; 3]),
        ],
        members: vec![bar("ab", [0, 1]), bar("bc", [1, 2])],
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
        ea: 2.0e4,
        tension_only: false,
    });
    let elements = Elements {
        laws: vec![law; 2],
        rest: rest.to_vec(),
    };
    let state = State::at_rest(model.positions());
    (Structure::massless(model, elements), state)
}

fn shorten_first(scale: f64, steps: usize) -> Hold {
    Hold {
        stage: Stage::new(StageKind::Hold, "reel"),
        actuators: vec![Actuator {
            members: vec![0],
            scale,
            time: TimeFunction::Ramp { duration: 1.0 },
        }],
        steps,
        max_cuts: 0,
        start_loaded: true,
    }
}

fn hold(steps: usize) -> (State, HoldSummary, Log) {
    let (structure, state) = series([1.0, 1.0], 2.2);
    let mut log = Log::default();
    let (end, summary) = shorten_first(0.8, steps)
        .run(&structure, state, &Settings::default(), &mut log)
        .unwrap();
    (end, summary, log)
}

/// Shortening bar AB to 0.8 of its rest length moves B to L·0.8/1.8, step by step along
/// the closed form of each step's rest length; the end state carries the new rest
/// lengths, and the frames record them.
#[test]
fn shortening_a_bar_moves_the_node_to_the_closed_form() {
    let (end, summary, log) = hold(8);
    assert_eq!(log.frames.len(), 9, "step 0 and 8 steps");
    for (k, (_, x, rest)) in log.frames.iter().enumerate() {
        let l1 = 1.0 - 0.2 * k as f64 / 8.0;
        let rest = rest.as_ref().expect("a hold frame records the rest lengths");
        assert!((rest[0] - l1).abs() < 1e-15 && rest[1] == 1.0, "{rest:?}");
        // Newton stops at a residual of ~1e-10 of the force scale (EA·strain ~ 2e3 N)
        // over a stiffness of ~4e4 N/m: positions within 1e-10 m, far below 1e-9.
        let exact = 2.2 * l1 / (l1 + 1.0);
        assert!((x[1].x - exact).abs() < 1e-9, "step {k}: {} vs {exact}", x[1].x);
    }
    assert_eq!(end.rest_lengths.as_deref(), Some(&[0.8, 1.0][..]));
    assert!(summary.lowest_stiffness > 0.0 && summary.max_displacement > 0.1);
}

/// With no load, the rest lengths' work is all the strain energy gained (ΔU = W_a). The
/// ledger integrates W_a by the trapezoidal rule over the steps, so its error must fall
/// as 1/steps²: 4× per doubling.
#[test]
fn the_rest_lengths_work_closes_the_energy_ledger_at_second_order() {
    let errors: Vec<(f64, f64)> = [4, 8, 16, 32]
        .map(|n| {
            let (_, s, _) = hold(n);
            (s.energy_balance_error, s.actuator_work)
        })
        .to_vec();
    let work = errors[3].1;
    assert!(work > 1.0, "the bars gain {work} J");
    for w in errors.windows(2) {
        let ratio = w[0].0 / w[1].0;
        // Second order: 4 per halving; 3.5–4.5 leaves room for the higher-order terms
        // at 4 steps and Newton's residual (1e-10 of the force scale, far below).
        assert!((3.5..4.5).contains(&ratio), "{:e} → {:e}: ratio {ratio}", w[0].0, w[1].0);
    }
    assert!(errors[3].0 < 1e-3 * work, "{:e} of {work} J", errors[3].0);
}

const TOWER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/tower_stages.yaml");

fn tower_with(stages: &str) -> tsim::config::CaseConfig {
    let text = std::fs::read_to_string(TOWER).unwrap();
    let head = &text[..text.find("\nstages:").unwrap()];
    parse_case(&format!("{head}\nstages:\n{stages}"), "tower.yaml").unwrap_or_else(|e| panic!("{e}"))
}

/// After gravity, the first stage's side cables are shortened 0.5 % in a hold: its end is a
/// static equilibrium under the held loads with the new rest lengths, so a transient from
/// it, with nothing more applied, stays at rest (a hold that lost the loads or the rest
/// lengths would set the tower swinging by millimetres).
#[test]
fn a_transient_from_a_hold_starts_at_rest_with_its_rest_lengths() {
    let cfg = tower_with(
        "  - { name: gravity, static: { steps: 5 } }
  - { name: reel, hold: { steps: 5, actuation: [{ groups: [side0], scale: 0.995 }] } }
  - { name: after, transient: { dt: 0.002, duration: 0.1 } }
",
    );
    let mut log = Log::default();
    let summary = run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
    let frames = |name: &str| log.frames.iter().filter(move |f| f.0 == name).cloned().collect::<Vec<_>>();
    let (gravity, reel, after) = (frames("gravity"), frames("reel"), frames("after"));
    let moved = |a: &[Vector3<f64>], b: &[Vector3<f64>]| a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    let reel_end = &reel.last().unwrap().1;
    assert!(moved(&gravity.last().unwrap().1, reel_end) > 1e-3, "the hold moved the tower");
    let drift = after.iter().map(|f| moved(&f.1, reel_end)).fold(0.0, f64::max);
    // Newton's tolerance leaves a residual of ~1e-10 of the member forces (kN): the
    // transient drifts by far less than a micrometre from an equilibrium.
    assert!(drift < 1e-7, "drifted {drift:e} m");
    let s = match summary.stage("reel") {
        Some(tsim::pipeline::StageSummary::Hold(s)) => s,
        other => panic!("{other:?}"),
    };
    assert!(
        s.actuator_work != 0.0 && s.equilibrium.max_equilibrium_error_relative < 1e-8,
        "{s:?}"
    );
}

/// A bad hold entry is reported at its line, with the fix.
#[test]
fn a_bad_hold_names_the_field_and_the_fix() {
    let text = "\
name: bad
model: { tower: { struts: 3, stages: 1 } }
formfinding: {}
substitution: { strut: aluminium, cable: nylon }
stages:
  - name: none
    hold: { steps: 0, actuation: [] }
  - name: twice
    hold:
      actuation:
        - { groups: [side0], scale: 0.9 }
        - { groups: [side0, nowhere], scale: -1.0 }
  - name: both
    static: {}
    hold: { actuation: [{ members: [], scale: 0.9 }] }
";
    let e = match parse_case(text, "bad.yaml") {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    let expect = [
        (7, "stages[0].hold.steps", "is 0; must be ≥ 1"),
        (7, "stages[0].hold.actuation", "changes no rest length"),
        (12, "stages[1].hold.actuation[1].scale", "must be a finite number > 0"),
        (12, "stages[1].hold.actuation[1]", "nowhere"),
        (
            13,
            "stages[2]",
            "give exactly one of `static`, `eigen`, `transient`, `folding`, `hold`",
        ),
    ];
    assert_field_errors(&e, "bad.yaml", &expect);
}

const TOWER_HOLD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/tower_hold.yaml");

/// The quasi-static limit: the paper's rubber tower with its vertical cables shortened by
/// 20 % in a hold (`reel`) and, from the same loaded state, by a transient that ramps the
/// same change over 2 s and then rests, damped with ζ = 0.2 (`slow`), end in one shape.
/// A hold with another rest-length rule, or without the held weight, ends centimetres
/// away (the change moves nodes by 2 m).
#[test]
fn a_slow_damped_actuation_ends_where_the_hold_does() {
    let text = std::fs::read_to_string(TOWER_HOLD).unwrap();
    let cfg = parse_case(&text, TOWER_HOLD).unwrap_or_else(|e| panic!("{e}"));
    let summary = run_case(&cfg, &mut Log::default()).unwrap_or_else(|e| panic!("{e}"));
    let slow = summary.transient("slow").unwrap();
    let reel = match summary.stage("reel") {
        Some(tsim::pipeline::StageSummary::Hold(s)) => s,
        other => panic!("{other:?}"),
    };
    assert!(
        reel.max_displacement > 1.0,
        "the change moves the tower by {} m",
        reel.max_displacement
    );
    // 6 s of ζ = 0.2 decay leave a kinetic energy of ~1e-9 J: the shapes agree to the
    // Newton tolerance (1e-9 of the model size) times the tangent's conditioning, far
    // below 1e-5 of the height, which a wrong hold (cm to m) exceeds a thousandfold.
    let error = slow.shape_error.unwrap();
    assert!(error < 1e-5, "RMS distance {error:e} of the tower height");
}
