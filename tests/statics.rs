//! The static-load stage against closed forms: a hanging bar under gravity and a point
//! mass (load control), and the von Mises truss through its limit point and snap-through
//! (displacement control), where load control must stop.

use nalgebra::Vector3;
use std::sync::Arc;
use tsim::law::{ForceLaw, LinearElastic};
use tsim::model::{Member, MemberKind, Model, Node};
use tsim::record::{Frame, RecordResult, Recorder, Stage, StageKind};
use tsim::stage::static_load::{Control, StaticLoad};
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::Elements;

/// Keeps the positions and load factor of every recorded step.
#[derive(Default)]
struct Path {
    steps: Vec<(f64, Vec<Vector3<f64>>)>,
    /// The lowest ω² and mode of each frame that has them.
    modes: Vec<(f64, Vec<Vector3<f64>>)>,
}

impl Recorder for Path {
    fn frame(&mut self, frame: &Frame) -> RecordResult {
        self.steps.push((frame.time, frame.positions.to_vec()));
        if let Some(m) = frame.modes {
            self.modes.push((m.omega2[0], m.lowest.to_vec()));
        }
        Ok(())
    }
}

fn node(id: &str, xyz: [f64; 3], support: [bool; 3]) -> Node {
    Node {
        id: id.into(),
        xyz: Vector3::from(xyz),
        support,
    }
}

fn bar(id: &str, nodes: [usize; 2]) -> Member {
    Member {
        id: id.into(),
        nodes,
        kind: MemberKind::Strut,
        groups: vec![],
    }
}

fn elastic(ea: f64, count: usize, rest: Vec<f64>) -> Elements {
    let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic { ea, tension_only: false });
    Elements {
        laws: vec![law; count],
        rest,
    }
}

/// A vertical bar of rest length L0 hangs from a fixed node with a point mass M at its
/// free end (moving only vertically). Its own mass ρA·L0 is lumped half to each end, so
/// the end carries N = (M + ρA L0/2) g and, N = EA (l − L0)/L0 being exact for this law,
/// l = L0 (1 + N/EA). Load control in 4 steps must land there.
#[test]
fn hanging_bar_stretches_by_its_weight() {
    let (l0, ea, rho_a, point, g) = (2.0, 1.0e5, 3.0, 40.0, 9.81);
    let model = Model {
        nodes: vec![
            node("top", [0.0, 0.0, 0.0], [true; 3]),
            node("end", [0.0, 0.0, -l0], [true, true, false]),
        ],
        members: vec![bar("bar", [0, 1])],
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    let mut structure = Structure::with_lumped_masses(model.clone(), elastic(ea, 1, vec![l0]), &[rho_a], &[0.0, point]);
    structure.gravity = Vector3::new(0.0, 0.0, -g);
    let stage = StaticLoad {
        stage: Stage::of(StageKind::Static),
        start_loaded: false,
        loads: vec![],
        steps: 4,
        max_cuts: 0,
        control: None,
    };
    let mut path = Path::default();
    let (state, summary) = stage
        .run(&structure, State::at_rest(model.positions()), &Settings::default(), &mut path)
        .unwrap();
    let n = (point + 0.5 * rho_a * l0) * g;
    let expected = l0 * (1.0 + n / ea);
    // The Newton tolerance is 1e-10 of the force; the length follows to that relative
    // order (times EA/N ~ 5 here), so 1e-9 relative leaves no room for a wrong load.
    assert!(
        ((-state.positions[1].z) - expected).abs() <= 1e-9 * expected,
        "{} vs {expected}",
        -state.positions[1].z
    );
    assert_eq!(path.steps.len(), 5, "the unloaded state and 4 load steps");
    assert_eq!(path.steps.iter().map(|s| s.0).collect::<Vec<_>>(), [0.0, 0.25, 0.5, 0.75, 1.0]);
    assert_eq!(summary.load_factor, 1.0);
}

/// The von Mises truss: two bars from (∓a, 0, 0) to an apex at (0, 0, h), the apex
/// pushed down by P. With the apex at height z, l = √(a² + z²) and N = EA (l − L0)/L0,
/// vertical equilibrium gives P(z) = −2 N z / l. P rises to a limit point, falls through
/// zero at z = 0 (both bars flat) and turns negative: load control cannot pass the
/// limit, displacement control follows the whole curve to the mirror image z = −h.
fn von_mises() -> (Structure, f64, f64, f64) {
    let (a, h, ea) = (2.0, 0.5, 1.0e6);
    let model = Model {
        nodes: vec![
            node("left", [-a, 0.0, 0.0], [true; 3]),
            node("right", [a, 0.0, 0.0], [true; 3]),
            node("apex", [0.0, 0.0, h], [false, true, false]),
        ],
        members: vec![bar("l", [0, 2]), bar("r", [1, 2])],
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    let l0 = (a * a + h * h).sqrt();
    let structure = Structure::massless(model, elastic(ea, 2, vec![l0, l0]));
    (structure, a, h, ea)
}

fn load_down(p: f64) -> Vec<Vector3<f64>> {
    vec![Vector3::zeros(), Vector3::zeros(), Vector3::new(0.0, 0.0, -p)]
}

#[test]
fn displacement_control_passes_the_limit_point_of_the_von_mises_truss() {
    let (structure, a, h, ea) = von_mises();
    let l0 = (a * a + h * h).sqrt();
    let p_of = |z: f64| {
        let l = (a * a + z * z).sqrt();
        -2.0 * ea * (l - l0) / l0 * z / l
    };
    let reference = 1000.0;
    let stage = StaticLoad {
        stage: Stage::of(StageKind::Static),
        start_loaded: false,
        loads: load_down(reference),
        steps: 40,
        max_cuts: 4,
        control: Some(Control {
            node: 2,
            axis: 2,
            displacement: -2.0 * h,
        }),
    };
    let mut path = Path::default();
    let start = State::at_rest(structure.model.positions());
    let (state, summary) = stage.run(&structure, start, &Settings::default(), &mut path).unwrap();
    assert_eq!(path.steps.len(), 41);
    let (mut peak, mut trough) = (0.0_f64, 0.0_f64);
    for (k, (lambda, x)) in path.steps.iter().enumerate() {
        let z = x[2].z;
        let expected_z = h - 2.0 * h * k as f64 / 40.0;
        // The controlled coordinate is imposed, exactly up to the rounding of start + s·d.
        assert!((z - expected_z).abs() <= 4.0 * f64::EPSILON * h, "step {k}: z = {z}");
        // λ·reference is the apex load; the residual tolerance is 1e-10 of the largest
        // force (the bars' N, ~1e4 N at the flat state), which bounds the load error.
        let n_scale = ea * (l0 - a) / l0;
        assert!(
            (lambda * reference - p_of(z)).abs() <= 1e-9 * n_scale,
            "step {k}: λP = {} vs P(z) = {}",
            lambda * reference,
            p_of(z)
        );
        assert!(x[2].x.abs() <= 1e-12, "the apex stays on the axis of symmetry");
        peak = peak.max(lambda * reference);
        trough = trough.min(lambda * reference);
    }
    // The path passed both limit points: up to +P_max, through zero at the flat state,
    // down to −P_max (the curve is odd in z), back to zero at the mirror image. 0.99:
    // the 40 steps of 2.5 cm sample the peak to within 0.2 %.
    let limit = (0..4000).map(|i| p_of(h * i as f64 / 4000.0)).fold(0.0, f64::max);
    assert!(
        peak > 0.99 * limit && trough < -0.99 * limit,
        "peak {peak}, trough {trough}, limit {limit}"
    );
    assert!(summary.load_factor.abs() * reference <= 1e-9 * ea, "unstressed at the mirror image");
    assert!((state.positions[2].z + h).abs() <= 4.0 * f64::EPSILON * h);

    // Load control to more than the limit load has no equilibrium near the upper branch:
    // the energy line search snaps through to the inverted branch (z < −h), where the
    // same closed form holds; the states in between are only reachable by control.
    let beyond = StaticLoad {
        stage: Stage::of(StageKind::Static),
        start_loaded: false,
        loads: load_down(1.2 * limit),
        steps: 10,
        max_cuts: 3,
        control: None,
    };
    let start = State::at_rest(structure.model.positions());
    let (snapped, _) = beyond.run(&structure, start, &Settings::default(), &mut Path::default()).unwrap();
    let z = snapped.positions[2].z;
    assert!(z < -h, "snapped through to the inverted branch: z = {z}");
    // As above: the residual tolerance relative to the bars' force.
    assert!((p_of(z) - 1.2 * limit).abs() <= 1e-9 * ea, "P(z) = {} vs {}", p_of(z), 1.2 * limit);
}

/// A pendulum: a point mass M on an elastic bar hanging from a support, under gravity.
/// The bar carries N = M g, so l = L0 (1 + M g/EA), and the lateral stiffness is pure
/// geometric stiffness N/l: ω² = g/l whatever the suspension point does. Folding moves
/// the support sideways by 1 m; the mass follows quasi-statically under gravity (the
/// dead load stays on in folding) and the lowest eigenvalue at every step is g/l.
#[test]
fn folding_under_gravity_tracks_the_pendulum_frequency() {
    use tsim::stage::fold::{Folding, Prescription, Target};
    let (l0, ea, mass, g) = (2.0, 1.0e5, 40.0, 9.81);
    let model = Model {
        // Pre-stretched by 1 %: a slack bar has no lateral stiffness to start from.
        nodes: vec![
            node("top", [0.0, 0.0, 0.0], [true; 3]),
            node("end", [0.0, 0.0, -1.01 * l0], [false, true, false]),
        ],
        members: vec![bar("bar", [0, 1])],
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    let mut structure = Structure::with_lumped_masses(model.clone(), elastic(ea, 1, vec![l0]), &[0.0], &[0.0, mass]);
    structure.gravity = Vector3::new(0.0, 0.0, -g);
    let gravity = StaticLoad {
        stage: Stage::of(StageKind::Static),
        start_loaded: false,
        loads: vec![],
        steps: 1,
        max_cuts: 0,
        control: None,
    };
    let settings = Settings::default();
    let (hanging, _) = gravity
        .run(&structure, State::at_rest(model.positions()), &settings, &mut Path::default())
        .unwrap();
    let folding = Folding {
        stage: Stage::of(StageKind::Folding),
        steps: 4,
        max_cuts: 0,
        prescribe: vec![Prescription {
            nodes: vec![0],
            axis: 0,
            target: Target::Displacement(1.0),
        }],
        modes: 2,
    };
    let mut path = Path::default();
    let (end, summary) = folding.run(&structure, hanging, &settings, &mut path).unwrap();
    let l = l0 * (1.0 + mass * g / ea);
    // Equilibrium to the Newton tolerance (1e-10 of the force, ~1e-9 m of position
    // through EA/l ~ 5e4 N/m and N ~ 400 N); 1e-9 m bounds it.
    assert!(
        (end.positions[1] - Vector3::new(1.0, 0.0, -l)).norm() <= 1e-9,
        "{:?}",
        end.positions[1]
    );
    assert_eq!(summary.modes.len(), 5, "the start and every step");
    for m in &summary.modes {
        // ω² = g/l from the geometric stiffness; the dense eigensolver resolves it to
        // ε times the axial ω² (EA/(l0 M) ~ 1250 rad²/s², ~300 g/l): 1e-9 is far above.
        assert!(
            (m.omega2[0] - g / l).abs() <= 1e-9 * g / l,
            "step {}: ω² = {} vs g/l = {}",
            m.step,
            m.omega2[0],
            g / l
        );
        assert_eq!(m.lowest_at, "node `end` direction x");
    }
    // The frames carry the same: ω² and the mass-normalised lowest mode, a sideways swing
    // of the mass, φ_x = ±1/√M (as exact as ω² above).
    assert_eq!(path.modes.len(), 5);
    for (omega2, shape) in &path.modes {
        assert!((omega2 - g / l).abs() <= 1e-9 * g / l);
        assert!((shape[1].x.abs() - 1.0 / mass.sqrt()).abs() <= 1e-9 / mass.sqrt(), "{:?}", shape[1]);
        assert!(shape[0] == Vector3::zeros() && shape[1].y == 0.0, "the support and y do not move");
    }
}

/// The prism of configs/examples/prism_selfweight.yaml with `replace` applied to its text:
/// the expansion error (as `tsim check` prints it).
fn example_error(replace: &[(&str, &str)]) -> String {
    let mut text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/prism_selfweight.yaml")).unwrap();
    for (from, to) in replace {
        assert!(text.contains(from), "the example no longer has `{from}`");
        text = text.replacen(from, to, 1);
    }
    let e = match tsim::run::expand(&text, "prism.yaml", false) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted: {replace:?}"),
    };
    for line in e.lines() {
        let at = line.strip_prefix("prism.yaml:").and_then(|r| r.split(':').next());
        assert!(at.is_some_and(|n| n.parse::<usize>().is_ok()), "no line in `{line}`");
    }
    e
}

/// Bad input of the new keys is refused at its line, naming the fix.
#[test]
fn loading_errors_name_the_line_and_the_fix() {
    // Gravity on a model without mass: both materials massless, no point mass.
    let e = example_error(&[
        ("  - { groups: [top], mass: 20.0 }   # kg on each node of the group\n", ""),
        ("point_masses:\n", ""),
        ("density: 7850.0\n    source: \"S355", "density: 0.0\n    source: \"S355"),
        (
            "density: 7850.0\n    source: \"steel tension",
            "density: 0.0\n    source: \"steel tension",
        ),
    ]);
    assert!(e.contains("`gravity`: the model has no mass") && e.contains("prism.yaml:"), "{e}");
    // A material assigned to no member: an unknown member group and an unknown member.
    let e = example_error(&[(
        "  cable: steel_rod    # every member of kind cable\n",
        "  cable: steel_rod\n  assign:\n    - { groups: [rings], material: steel_tube }\n    - { members: [x9], material: steel_tube }\n",
    )]);
    assert!(
        e.contains(
            "`substitution.assign[0]`: unknown member group `rings`; the model's member groups: ring_bottom, ring_top, strut, vertical"
        ),
        "{e}"
    );
    assert!(e.contains("`substitution.assign[1]`: unknown member `x9`"), "{e}");
    // A point mass on an unknown node, and a static load on an unknown group.
    let e = example_error(&[("{ groups: [top], mass: 20.0 }", "{ nodes: [hub], mass: 20.0 }")]);
    assert!(e.contains("`point_masses[0]`: unknown node `hub`"), "{e}");
    // Displacement control of a supported direction.
    let e = example_error(&[(
        "static:\n  steps: 4\n",
        "static:\n  steps: 4\n  loads: [{ nodes: [t0], force: [0, 0, -1] }]\n  control: { node: b0, axis: z, displacement: -0.1 }\n",
    )]);
    assert!(
        e.contains("`static.control.axis`: node `b0` is supported in z: control a free direction"),
        "{e}"
    );
}

/// The last folding frame's positions, and the Newton iterations folding took.
#[derive(Default)]
struct FoldEnd {
    folding: bool,
    last: Vec<Vector3<f64>>,
}

impl Recorder for FoldEnd {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &tsim::record::Constraints) -> RecordResult {
        self.folding = stage.name() == "folding";
        Ok(())
    }
    fn frame(&mut self, frame: &Frame) -> RecordResult {
        if self.folding {
            self.last = frame.positions.to_vec();
        }
        Ok(())
    }
}

/// Folding a 6 × 6 grid (its top layer pushed down 5 cm, steel cables that slacken) in 5
/// or in 20 steps ends in the same equilibrium: the steps after the first start from the
/// path extrapolated along the last step's secant (fold.rs, `predict`), which must change
/// where Newton starts, not where it ends. Tolerance: both ends are equilibria to the
/// Newton tolerance (1e-10 of the largest member force, ~1e3 N, through stiffnesses of
/// ≥ ~1e3 N/m: ~1e-10 m), so 1e-8 m leaves a wide margin, while a start that led Newton to
/// another equilibrium would differ by the folding's own scale, centimetres.
#[test]
fn folding_a_grid_in_5_or_20_steps_ends_in_the_same_equilibrium() {
    let end = |steps: usize| {
        let text = format!(
            "name: fold\nmodel:\n  grid: {{ nx: 6, ny: 6 }}\nformfinding: {{}}\n\
             substitution: {{ strut: aluminium, cable: steel_cable, prestress_scale: 100.0 }}\n\
             folding:\n  steps: {steps}\n  prescribe:\n    - {{ group: top, axis: z, displacement: -0.05 }}\n"
        );
        let cfg = tsim::config::parse_case(&text, "fold.yaml").unwrap_or_else(|e| panic!("{e}"));
        let mut log = FoldEnd::default();
        let summary = tsim::pipeline::run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
        let folding = summary.folding("folding").expect("folding ran").clone();
        eprintln!(
            "{steps} steps: {} Newton iterations, {} cut",
            folding.newton_iterations, folding.cut_steps
        );
        log.last
    };
    let (five, twenty) = (end(5), end(20));
    let apart = five.iter().zip(&twenty).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    eprintln!("largest distance between the ends: {apart:.3e} m");
    assert!(apart <= 1e-8, "the ends are {apart:.3e} m apart");
}
