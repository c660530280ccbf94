//! Helpers shared by the integration tests.

// Each test binary compiles this module and uses a part of it.
#![allow(dead_code)]

use nalgebra::Vector3;
use tsim::dynamics::{DampingTangent, Loads, NewmarkParams, Rayleigh};
use tsim::model::Model;
use tsim::record::NoRecorder;
use tsim::record::{Stage, StageKind};
use tsim::solve::NewtonSettings;
use tsim::stage::formfind::SelfEquilibrium;
use tsim::stage::transient::{Initial, Transient};
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::Elements;

/// A form-found shape and its members' forces.
pub struct Found {
    pub positions: Vec<Vector3<f64>>,
    pub forces: Vec<f64>,
    pub lengths: Vec<f64>,
    pub max_reaction: f64,
    pub iterations: usize,
    /// The lowest eigenvalue of the measure structure's K_T at the shape [N/m].
    pub lowest_stiffness: f64,
}

/// Form-finding of `model` with `elements` from its coordinates, through the stage interface.
pub fn form_find(model: &Model, elements: &Elements, newton: &NewtonSettings) -> tsim::Result<Found> {
    let structure = Structure::massless(model.clone(), elements.clone());
    let settings = Settings {
        newton: *newton,
        ..Default::default()
    };
    let (state, eq) = SelfEquilibrium::FORM_FINDING.run(&structure, State::at_rest(model.positions()), &settings, &mut NoRecorder)?;
    Ok(Found {
        positions: state.positions,
        forces: eq.forces,
        lengths: eq.lengths,
        max_reaction: eq.max_reaction,
        iterations: eq.residuals.len() - 1,
        lowest_stiffness: eq.lowest_stiffness,
    })
}

/// Asserts that the error text `errors` has, for each (line, field, message), a line
/// `<file>:<line>: `<field>`: …` containing the message.
pub fn assert_field_errors(errors: &str, file: &str, expect: &[(usize, &str, &str)]) {
    for (line, field, message) in expect {
        let at = format!("{file}:{line}: `{field}`: ");
        assert!(
            errors.lines().any(|l| l.starts_with(&at) && l.contains(message)),
            "no `{at}…{message}` in\n{errors}"
        );
    }
}

/// The largest gap between the recorded `reactions` of a frame and what the members'
/// recorded forces put into the supports less the load applied there: at each constrained
/// direction −Σ N e − f, e the unit vector from the support's node to the member's other
/// end (`ends`: each member's nodes). Where the supports do not move, no inertia enters,
/// and with objective damping a member's whole damping force is along it, so this is
/// round-off when `forces` are the totals the step's equation balanced.
pub fn reaction_gap(
    ends: &[[usize; 2]],
    constraints: &tsim::record::Constraints,
    (positions, forces): (&[Vector3<f64>], &[f64]),
    (applied, reactions): (&[Vector3<f64>], &[f64]),
) -> f64 {
    let mut worst: f64 = 0.0;
    for (c, r) in constraints.0.iter().zip(reactions) {
        let mut from_members = 0.0;
        for (m, &[a, b]) in ends.iter().enumerate() {
            let other = match c.node {
                n if n == a => b,
                n if n == b => a,
                _ => continue,
            };
            let e = (positions[other] - positions[c.node]).normalize();
            from_members -= forces[m] * e[c.axis];
        }
        worst = worst.max((r - (from_members - applied[c.node][c.axis])).abs());
    }
    worst
}

/// An undamped Newmark (average acceleration) transient `name` of `steps` steps of `dt`,
/// never cut, with `loads` and `initial` conditions.
pub fn transient(name: &str, dt: f64, steps: usize, loads: Loads, initial: Initial) -> Transient {
    Transient {
        stage: Stage::new(StageKind::Transient, name),
        params: NewmarkParams {
            dt,
            max_cuts: 0,
            ..Default::default()
        },
        duration: dt * steps as f64,
        rayleigh: Rayleigh::default(),
        tangent: DampingTangent::Objective,
        loads,
        actuators: Vec::new(),
        initial,
    }
}

/// A node `id` at `xyz`, supported where `support` says.
pub fn node(id: &str, xyz: [f64; 3], support: [bool; 3]) -> tsim::model::Node {
    tsim::model::Node {
        id: id.into(),
        xyz: Vector3::from(xyz),
        support,
    }
}

/// A cable member `id` between `nodes`.
pub fn cable(id: &str, nodes: [usize; 2]) -> tsim::model::Member {
    tsim::model::Member {
        id: id.into(),
        nodes,
        kind: tsim::model::MemberKind::Cable,
        groups: vec![],
    }
}

/// A tangent on the free DOFs, dense.
pub struct Dense(pub Vec<Vec<f64>>);

impl tsim::solve::TangentSink for Dense {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        self.0[row][col] += value;
    }
}

/// A cable zig-zagging from a support over three free pulley nodes (p1, p2, p3; members
/// s0 … s3, s1 against the cable's direction, since orientation must not matter) to
/// another support, an off-cable spring k1 … k3 from each pulley to a fixed node so that it
/// stands: the model with the four spans one cluster `c` of capstan friction `friction`,
/// and a shape moved off its nodes' positions, where the tests evaluate it.
pub fn zigzag(friction: f64) -> (Model, Vec<Vector3<f64>>) {
    let fixed = [true; 3];
    let nodes = vec![
        node("a", [0.0, 0.0, 0.0], fixed),
        node("p1", [0.7, 0.3, 0.9], [false; 3]),
        node("p2", [1.5, -0.2, 0.1], [false; 3]),
        node("p3", [2.1, 0.4, 1.2], [false; 3]),
        node("b", [3.0, 0.1, 0.2], fixed),
        node("g", [1.4, 2.0, -1.0], fixed),
    ];
    let members = vec![
        cable("s0", [0, 1]),
        cable("s1", [2, 1]),
        cable("s2", [2, 3]),
        cable("s3", [3, 4]),
        cable("k1", [1, 5]),
        cable("k2", [2, 5]),
        cable("k3", [3, 5]),
    ];
    let mut m = Model {
        nodes,
        members,
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    let c = tsim::model::Cluster::through(&m, "c", vec![0, 1, 2, 3], &[]).and_then(|c| c.with_friction(friction));
    m.clusters.push(c.unwrap_or_else(|e| panic!("{e}")));
    m.validate().unwrap();
    let moved = (m.nodes.iter().enumerate())
        .map(|(n, node)| node.xyz + Vector3::new(0.03, -0.02, 0.05) * (n as f64).sin())
        .collect();
    (m, moved)
}

/// K_T of `model` at `x` (dense, on every free DOF) and its largest difference from
/// central differences (step `h`) of the internal force, relative to K_T's largest entry;
/// `each(j, plus, minus)` is shown the two assemblies perturbed along free DOF j.
pub fn tangent_check(
    model: &Model,
    elements: &Elements,
    x: &[Vector3<f64>],
    h: f64,
    mut each: impl FnMut(usize, &tsim::tsm::Assembly, &tsim::tsm::Assembly),
) -> (Vec<Vec<f64>>, f64) {
    use tsim::tsm::{Assembly, DofMap};
    let dofs = DofMap::new(model, &[]);
    let asm = Assembly::new(model, elements, &dofs, x.to_vec());
    let n = dofs.len();
    let mut k = Dense(vec![vec![0.0; n]; n]);
    asm.add_tangent(1.0, &mut k);
    let at = |i: usize, d: f64| {
        let mut a = Assembly::new(model, elements, &dofs, x.to_vec());
        let mut u = a.free_coordinates();
        u[i] += d;
        a.set_free(&u);
        a
    };
    let scale = k.0.iter().flatten().fold(0.0_f64, |s, v| s.max(v.abs()));
    let mut worst = 0.0_f64;
    for j in 0..n {
        let (plus, minus) = (at(j, h), at(j, -h));
        for i in 0..n {
            let fd = (plus.p_free(i) - minus.p_free(i)) / (2.0 * h);
            worst = worst.max((fd - k.0[i][j]).abs() / scale);
        }
        each(j, &plus, &minus);
    }
    (k.0, worst)
}

/// The config of a 6 × 6 grid with steel cables (tension-only, stretched 2e-5 by their
/// prestress) pushed down 5 cm and released for `duration` [s] in steps of `dt` [s], with
/// objective Rayleigh damping `rayleigh` (the keys of `eigen.rayleigh`) and `deployment`
/// (more lines of its section, each indented two spaces and ending in a newline).
pub fn slack_grid(rayleigh: &str, dt: f64, duration: f64, deployment: &str) -> String {
    format!(
        "name: slack\nmodel:\n  grid: {{ nx: 6, ny: 6 }}\nformfinding: {{}}\n\
         substitution: {{ strut: aluminium, cable: steel_cable, prestress_scale: 100.0 }}\n\
         eigen:\n  solver: partial\n  modes: 20\n  rayleigh: {{ {rayleigh} }}\n\
         folding:\n  steps: 5\n  prescribe:\n    - {{ group: top, axis: z, displacement: -0.05 }}\n\
         deployment:\n  dt: {dt}\n  duration: {duration}\n  damped: true\n{deployment}"
    )
}
