//! Clustered cables (issue 32): one cable run through several members, sliding without
//! friction over the nodes between them. Its tangent is the derivative of its force and its
//! force the gradient of its energy (finite differences); an Atwood machine falls as the
//! closed form says; and a clustered prism under an uneven load is in the same equilibrium
//! as the same prism with the cable cut into members at the clustered state's rest lengths.
//!
//! Run with `cargo test --release --test cluster`.

mod common;

use common::{assert_field_errors, cable, node, Dense};
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::sync::Arc;
use tsim::dynamics::Loads;
use tsim::law::{ForceLaw, LinearElastic, OgdenCord};
use tsim::model::{Cluster, Member, Model, Node};
use tsim::record::{Frame, RecordResult, Recorder, Stage};
use tsim::stage::transient::Initial;
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::{Assembly, DofMap, Elements};

/// A model of `nodes` and cables `members`, the cables `clustered` (member indices in
/// order) one cluster `c`.
fn model(nodes: Vec<Node>, members: Vec<Member>, clustered: Vec<usize>) -> Model {
    let mut m = Model {
        nodes,
        members,
        node_groups: BTreeMap::new(),
        clusters: Vec::new(),
    };
    let c = Cluster::through(&m, "c", clustered, &[]).unwrap_or_else(|e| panic!("{e}"));
    m.clusters.push(c);
    m.validate().unwrap();
    m
}

/// The zig-zag cable of `common::zigzag` (frictionless) with `law`, rest lengths 10 %
/// under the lengths, the cluster's shared out unevenly (the first evaluation
/// redistributes them).
fn zigzag(law: Arc<dyn ForceLaw>) -> (Model, Elements, Vec<Vector3<f64>>) {
    let (m, moved) = common::zigzag(0.0);
    let x = m.positions();
    let rest = m
        .members
        .iter()
        .enumerate()
        .map(|(k, mem)| 0.9 * (x[mem.nodes[1]] - x[mem.nodes[0]]).norm() * if k < 4 { 1.0 + 0.05 * k as f64 } else { 1.0 })
        .collect();
    let elements = Elements { laws: vec![law; 7], rest };
    (m, elements, moved)
}

fn laws() -> [(&'static str, Arc<dyn ForceLaw>); 2] {
    [
        (
            "elastic",
            Arc::new(LinearElastic {
                ea: 2.0e5,
                tension_only: true,
            }),
        ),
        ("ogden", Arc::new(OgdenCord::new(OgdenCord::paper_terms(), 1e-4, 0.9, 0.5))),
    ]
}

/// K_T of a clustered cable against central differences of its internal force, and that
/// force against central differences of its strain energy, for a linear and a hyperelastic
/// law. Step h = 1e-6 m on lengths ~1 m: the truncation error h² |p'''| ~ 1e-12 of the
/// stiffness and the cancellation error ε |p| / h ~ 1e-10 of it, so 1e-7 of the largest
/// entry is met with room, while leaving out the cable's sliding (the members' own
/// material blocks, "stick") is wrong by O(1) of it, and a force that were not the
/// energy's gradient would be wrong by the difference of two members' tensions.
#[test]
fn cluster_tangent_and_force_are_derivatives() {
    for (name, law) in laws() {
        let (m, elements, x) = zigzag(law);
        let dofs = DofMap::new(&m, &[]);
        let asm = Assembly::new(&m, &elements, &dofs, x.clone());
        let tensions: Vec<f64> = (0..4).map(|k| asm.states[k].force).collect();
        assert!(
            tensions.iter().all(|&t| (t - tensions[0]).abs() <= 1e-12 * t.abs() && t > 0.0),
            "{name}: one tension {tensions:?}"
        );
        let h = 1e-6;
        let mut energy_gap = 0.0_f64;
        let (_, worst) = common::tangent_check(&m, &elements, &x, h, |j, plus, minus| {
            let energy = (plus.strain_energy() - minus.strain_energy()) / (2.0 * h);
            energy_gap = energy_gap.max((energy - asm.p_free(j)).abs() / tensions[0]);
        });
        assert!(
            worst < 1e-7,
            "{name}: K_T against differences of p: {worst:.2e} of the largest entry"
        );
        assert!(
            energy_gap < 1e-7,
            "{name}: p against differences of U: {energy_gap:.2e} of the tension"
        );
    }
}

/// Frames' times, positions and forces.
#[derive(Default)]
struct Track(Vec<(f64, Vec<Vector3<f64>>, Vec<f64>)>);

impl Recorder for Track {
    fn frame(&mut self, f: &Frame) -> RecordResult {
        self.0.push((f.time, f.positions.to_vec(), f.forces.to_vec()));
        Ok(())
    }
}

/// An Atwood machine: masses m1 = 3 kg and m2 = 1 kg hang from the two ends of one elastic
/// cable over a fixed frictionless pulley node. Closed form (e.g. Halliday & Resnick):
/// a = g (m1 − m2)/(m1 + m2), T = 2 m1 m2 g/(m1 + m2). Started at rest with the cable
/// stretched to carry T, its length stays constant, the tension stays T and each mass moves
/// at constant acceleration, which Newmark's average acceleration integrates exactly: so
/// positions and tension are checked to 1e-9 relative (Newton's force tolerance, not the
/// step), over 0.6 s at Δt = 0.01 s (m1 falls 0.88 m, m2 stays 0.62 m below the pulley).
#[test]
fn atwood_machine_matches_closed_form() {
    let (m1, m2, g, ea) = (3.0, 1.0, 9.81, 5.0e4);
    let free = [false; 3];
    let nodes = vec![
        node("pulley", [0.0, 0.0, 0.0], [true; 3]),
        node("m1", [0.0, 0.0, -1.0], free),
        node("m2", [0.0, 0.0, -1.5], free),
    ];
    let m = model(nodes, vec![cable("left", [0, 1]), cable("right", [0, 2])], vec![0, 1]);
    let tension = 2.0 * m1 * m2 * g / (m1 + m2);
    let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic { ea, tension_only: true });
    let stretch = 1.0 + tension / ea;
    let elements = Elements {
        laws: vec![law; 2],
        rest: vec![1.0 / stretch, 1.5 / stretch],
    };
    let mut s = Structure::massless(m, elements);
    s.masses = vec![0.0, m1, m2];
    s.gravity = Vector3::new(0.0, 0.0, -g);
    let (dt, steps) = (0.01, 60);
    let stage = common::transient("fall", dt, steps, Loads::default(), Initial::default());
    let mut track = Track::default();
    let start = State::at_rest(s.model.positions());
    stage
        .run(&s, start, &Settings::default(), &mut track)
        .unwrap_or_else(|e| panic!("{e}"));
    let a = g * (m1 - m2) / (m1 + m2);
    assert_eq!(track.0.len(), steps + 1);
    for (t, x, forces) in &track.0 {
        let fall = 0.5 * a * t * t;
        assert!(
            (x[1].z - (-1.0 - fall)).abs() <= 1e-9 * (1.0 + fall),
            "m1 at t = {t}: {} against {}",
            x[1].z,
            -1.0 - fall
        );
        assert!(
            (x[2].z - (-1.5 + fall)).abs() <= 1e-9 * (1.0 + fall),
            "m2 at t = {t}: {} against {}",
            x[2].z,
            -1.5 + fall
        );
        for f in forces {
            assert!((f - tension).abs() <= 1e-9 * tension, "tension at t = {t}: {f} against {tension}");
        }
    }
    assert!(track.0.last().unwrap().1[2].z < -0.6, "m2 stays below the pulley");
}

const PRISM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/prism_cluster.yaml");

/// The last frame of the `push` stage and the `modes` stage's ω².
#[derive(Default)]
struct Pushed {
    stage: String,
    positions: Vec<Vector3<f64>>,
    forces: Vec<f64>,
    rest: Vec<f64>,
    omega2: Vec<f64>,
}

impl Recorder for Pushed {
    fn begin_stage(&mut self, stage: &Stage, _: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage == "push" {
            self.positions = f.positions.to_vec();
            self.forces = f.forces.to_vec();
            self.rest = f.rest_lengths.map(<[f64]>::to_vec).unwrap_or_default();
        }
        Ok(())
    }

    fn eigen(&mut self, record: &tsim::record::EigenRecord) -> RecordResult {
        self.omega2 = record.omega2.to_vec();
        Ok(())
    }
}

fn push(cfg: &tsim::config::CaseConfig) -> Pushed {
    let mut out = Pushed::default();
    tsim::pipeline::run_case(cfg, &mut out).unwrap_or_else(|e| panic!("{e}"));
    out
}

/// configs/examples/prism_cluster.yaml (without gravity): the prism with its top ring one
/// clustered loop, pushed sideways at t0. Clustered, the ring's three spans end with one tension; the same
/// prism with the ring cut into three members whose rest lengths are the clustered state's
/// is in the same equilibrium under the same load (positions to 1e-9 m, Newton's
/// displacement scale on a 1.5 m prism; forces to 1e-6 of the largest, round-off of
/// 1e4 N forces through the 1e-9 m positions and 5e5 N/m member stiffnesses). The split
/// ring carries three tensions elsewhere on its path, so this is not the trivial case: the
/// unloaded split prism is out of balance at the clustered rest lengths' first shape.
/// And the clustered prism is softer at that state in every mode (ω²_i ≤ the split one's,
/// Courant–Fischer: K_split − K_cluster = Σ k_i J_i J_iᵀ − k_c g gᵀ is positive
/// semidefinite for springs in series), strictly in some.
#[test]
fn clustered_and_split_prisms_share_their_equilibrium() {
    let text = std::fs::read_to_string(PRISM).unwrap();
    let mut cfg = tsim::config::parse_case(&text, PRISM).unwrap_or_else(|e| panic!("{e}"));
    // Without gravity: masses are lumped from the rest lengths a structure starts with, so
    // the split prism's ring (its rest lengths the slipped ones) would weigh ~1e-4 kg
    // otherwise per node, and carry another load.
    cfg.gravity = None;
    let clustered = push(&cfg);
    let ring: Vec<usize> = ["ct0", "ct1", "ct2"]
        .iter()
        .map(|id| cfg.model.members.iter().position(|m| m.id == *id).unwrap())
        .collect();
    assert_eq!(
        clustered.rest.len(),
        cfg.model.members.len(),
        "a clustered structure's frames carry rest lengths"
    );
    let tensions: Vec<f64> = ring.iter().map(|&m| clustered.forces[m]).collect();
    assert!(
        tensions.iter().all(|t| (t - tensions[0]).abs() < 1e-9 * t),
        "one tension round the loop: {tensions:?}"
    );
    let spread =
        ring.iter().map(|&m| clustered.rest[m]).fold(f64::NAN, f64::max) - ring.iter().map(|&m| clustered.rest[m]).fold(f64::NAN, f64::min);
    assert!(spread > 1e-4, "the load made the loop slip: rest lengths spread by {spread:e} m");
    cfg.model.clusters.clear();
    for &m in &ring {
        cfg.model.members[m].rest_length = Some(clustered.rest[m]);
    }
    let split = push(&cfg);
    let moved = clustered
        .positions
        .iter()
        .zip(&split.positions)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(moved < 1e-9, "positions differ by {moved:e} m");
    let largest = clustered.forces.iter().fold(0.0_f64, |a, f| a.max(f.abs()));
    let forces = clustered
        .forces
        .iter()
        .zip(&split.forces)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(forces < 1e-6 * largest, "forces differ by {forces:e} N");
    eprintln!("clustered vs split: positions {moved:.2e} m, forces {forces:.2e} N (largest {largest:.0} N), ring rest lengths spread {spread:.3e} m");
    eprintln!("ω² clustered {:.4?}\nω² split     {:.4?}", clustered.omega2, split.omega2);
    let softer = clustered.omega2.iter().zip(&split.omega2).all(|(c, s)| *c <= s * (1.0 + 1e-9));
    let strictly = clustered.omega2.iter().zip(&split.omega2).any(|(c, s)| *c < 0.99 * s);
    assert!(
        softer && strictly,
        "ω²: clustered {:?} against split {:?}",
        clustered.omega2,
        split.omega2
    );
}

/// The equilibrium-matrix analysis with clustering (A S, S the members' incidence on the
/// independent tensions): the prism of prism_cluster.yaml has b = 12 members and
/// n_f = 12 free DOFs, one self-stress and one internal mechanism (the twist); with its top
/// ring one loop it has 10 tensions, and Maxwell's rule s − m = b − n_f gives m = 3 for the
/// same s = 1: the loop slides two ways more. The self-stress is the same state, one
/// tension round the loop, and the prism stays prestress stable.
#[test]
fn clustering_counts_in_the_equilibrium_matrix() {
    let text = std::fs::read_to_string(PRISM).unwrap();
    let cfg = tsim::config::parse_case(&text, PRISM).unwrap_or_else(|e| panic!("{e}"));
    let model = cfg.model.build().unwrap();
    let x = model.positions();
    let unclustered = Model {
        clusters: Vec::new(),
        ..model.clone()
    };
    let plain = tsim::rigidity::analyse(&unclustered, &x, None).unwrap();
    assert_eq!((plain.s, plain.m, plain.rigid_body_modes), (1, 1, 0));
    // The state's prestress, one tension round the loop: the coordinates are given to 12
    // digits, so it balances to ~1e-13 there, which sets the rank tolerance (10 ‖A t‖/‖t‖)
    // as it does for a converged state in a run.
    let mut prestress = plain.proper_self_stress.clone().expect("a proper self-stress");
    let ring = model.clusters[0].members.clone();
    let mean = ring.iter().map(|&m| prestress[m]).sum::<f64>() / 3.0;
    ring.iter().for_each(|&m| prestress[m] = mean);
    let clustered = tsim::rigidity::analyse(&model, &x, Some(&prestress)).unwrap();
    assert_eq!((clustered.s, clustered.m, clustered.rigid_body_modes), (1, 3, 0));
    let t = clustered.proper_self_stress.expect("a proper self-stress");
    let u = plain.proper_self_stress.unwrap();
    eprintln!(
        "clustered prism: s = {}, m = {}; Q on its mechanisms {:?} N/m",
        clustered.s, clustered.m, clustered.stability.mechanism_stiffness
    );
    assert!(
        ring.iter().all(|&m| (t[m] - t[ring[0]]).abs() < 1e-12),
        "one tension round the loop: {t:?}"
    );
    assert!(
        t.iter().zip(&u).all(|(a, b)| (a - b).abs() < 1e-9),
        "the same state: {t:?} against {u:?}"
    );
    assert!(clustered.stability.prestress_stable && !clustered.stability.super_stable);
}

/// The objective damping of the zigzag cable at velocities `v` and its step Jacobian.
struct Damped {
    model: Model,
    elements: Elements,
    dofs: DofMap,
}

impl Damped {
    /// The zigzag with no supports: a rigid motion moves every node.
    fn new(law: Arc<dyn ForceLaw>) -> (Self, Vec<Vector3<f64>>) {
        let (mut model, elements, x) = zigzag(law);
        model.nodes.iter_mut().for_each(|n| n.support = [false; 3]);
        let dofs = DofMap::new(&model, &[]);
        (Damped { model, elements, dofs }, x)
    }

    /// The damping force on the free DOFs at positions `x`, velocities `v`, β = 0.01 s,
    /// every member taut.
    fn force(&self, x: &[Vector3<f64>], v: &[f64]) -> Vec<f64> {
        let asm = Assembly::new(&self.model, &self.elements, &self.dofs, x.to_vec());
        let mut out = vec![0.0; v.len()];
        self.with(&asm, v, |d| d.add_force(&mut out));
        out
    }

    fn with(&self, asm: &Assembly, v: &[f64], f: impl FnOnce(&tsim::tsm::ObjectiveDamping)) {
        let n = self.model.members.len();
        let mut moduli = vec![tsim::tsm::DampingModulus::default(); n];
        tsim::tsm::damping_moduli(&self.elements.laws, &asm.rest, &asm.states, &vec![true; n], &mut moduli);
        f(&tsim::tsm::ObjectiveDamping {
            model: &self.model,
            dofs: &self.dofs,
            states: &asm.states,
            moduli: &moduli,
            v,
            beta: 0.01,
            rest_rate: &[],
        });
    }
}

/// A rigid motion of a clustered cable, and a slide of it over its pulleys at constant
/// length, damp nothing: objective damping acts on the cable's extension rate L̇ alone
/// (its members' own rates would damp the slide: β k_i l̇_i ≠ 0 where the members trade
/// length). 1e-12 of the force the same speeds give when they stretch the cable.
#[test]
fn cluster_damping_ignores_rigid_motion_and_free_slide() {
    let (d, x) = Damped::new(laws()[0].1.clone());
    let free: Vec<(usize, usize)> = (0..d.dofs.len()).map(|i| d.dofs.owner(i)).collect();
    let field = |f: &dyn Fn(Vector3<f64>) -> Vector3<f64>| -> Vec<f64> { free.iter().map(|&(n, a)| f(x[n])[a]).collect() };
    let (c, w) = (Vector3::new(0.3, -0.2, 0.5), Vector3::new(0.7, 0.1, -0.4));
    let rigid = field(&|p| c + w.cross(&p));
    // Move p2 alone normal to ∂L/∂x_p2 (L̇ = g_p2 · v = 0: the cable's members trade
    // length) and to its spring k2 (which stays as long).
    let asm = Assembly::new(&d.model, &d.elements, &d.dofs, x.clone());
    let g = tsim::tsm::cluster::length_gradient(&d.model, &d.model.clusters[0], &asm.states);
    let gp2 = g.iter().find(|(n, _)| *n == 2).unwrap().1;
    let along = gp2.cross(&asm.states[5].dir).normalize();
    let slide: Vec<f64> = free.iter().map(|&(n, a)| if n == 2 { along[a] } else { 0.0 }).collect();
    let stretch: Vec<f64> = free.iter().map(|&(n, a)| if n == 2 { gp2.normalize()[a] } else { 0.0 }).collect();
    let norm = |f: &[f64]| f.iter().map(|v| v * v).sum::<f64>().sqrt();
    let reference = norm(&d.force(&x, &stretch));
    assert!(reference > 1.0, "stretching is damped: {reference} N");
    for (name, v) in [("rigid", &rigid), ("slide", &slide)] {
        let f = norm(&d.force(&x, v));
        assert!(
            f < 1e-12 * reference,
            "{name}: damping force {f:e} N against {reference:e} N stretching"
        );
    }
    // The members' own tensions' rates do differ on the slide: the test is not trivial.
    let rates: Vec<f64> = (0..4)
        .map(|m| {
            asm.states[m].dir.dot(
                &(if d.model.members[m].nodes.contains(&2) {
                    along
                } else {
                    Vector3::zeros()
                } * if d.model.members[m].nodes[1] == 2 { 1.0 } else { -1.0 }),
            )
        })
        .collect();
    assert!(rates.iter().any(|r| r.abs() > 0.1), "the slide lengthens a member: {rates:?}");
}

/// The Newmark Jacobian of a clustered cable's damping force (velocities following the
/// coordinates as v = c_v u + const) against central differences, for both laws, with
/// the cable stretching and turning: 1e-7 of the largest entry (as for K_T above).
#[test]
fn cluster_damping_jacobian_is_its_derivative() {
    for (name, law) in laws() {
        let (d, x) = Damped::new(law);
        let n = d.dofs.len();
        let v: Vec<f64> = (0..n).map(|i| 0.3 * (1.7 * i as f64).sin()).collect();
        let c_v = 400.0;
        let asm = Assembly::new(&d.model, &d.elements, &d.dofs, x.clone());
        let mut k = Dense(vec![vec![0.0; n]; n]);
        d.with(&asm, &v, |dmp| dmp.add_jacobian(c_v, false, &mut k));
        let h = 1e-7;
        let at = |j: usize, s: f64| {
            let mut xs = x.clone();
            let (node, a) = d.dofs.owner(j);
            xs[node][a] += s * h;
            let mut vs = v.clone();
            vs[j] += s * c_v * h;
            d.force(&xs, &vs)
        };
        let scale = k.0.iter().flatten().fold(0.0_f64, |s, e| s.max(e.abs()));
        let mut worst = 0.0_f64;
        for j in 0..n {
            let (plus, minus) = (at(j, 1.0), at(j, -1.0));
            for i in 0..n {
                worst = worst.max(((plus[i] - minus[i]) / (2.0 * h) - k.0[i][j]).abs() / scale);
            }
        }
        assert!(
            worst < 1e-7,
            "{name}: damping Jacobian against differences: {worst:.2e} of the largest entry {scale:.3e}"
        );
    }
}

/// One frame as a user reads it: positions, member forces, reactions, rest lengths, energies.
type Sample = (Vec<Vector3<f64>>, Vec<f64>, Vec<f64>, Vec<f64>, tsim::record::Energy);

/// What a user reads of the `reel` stage at the sample times.
#[derive(Default)]
struct Reel {
    stage: String,
    times: Vec<f64>,
    kept: Vec<Sample>,
}

impl Recorder for Reel {
    fn begin_stage(&mut self, stage: &Stage, _: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage == "reel" && self.times.iter().any(|t| (t - f.time).abs() < 1e-9) {
            let rest = f.rest_lengths.expect("rest lengths").to_vec();
            self.kept
                .push((f.positions.to_vec(), f.forces.to_vec(), f.reactions.to_vec(), rest, f.energy));
        }
        Ok(())
    }
}

/// The `reel` stage of prism_cluster.yaml: the loop reeled in by a winch over 0.5 s, then
/// held, under objective Rayleigh damping. At Δt = 2, 1, 0.5 ms: the loop's rest length
/// follows the schedule (1e-12), its three spans carry one total (elastic + viscous)
/// tension (1e-9), the ledger KE + SE + D − W − W_a closes to ≤ 1e-6 of the actuator's
/// work, and every quantity a user reads converges at second order (Richardson ratio ≥ 3
/// between successive differences, 4 in the limit; two exceptions at 0.25 s below).
#[test]
fn reeled_loop_follows_its_winch_and_converges_at_second_order() {
    let times = [0.25, 0.6, 1.0];
    let text = std::fs::read_to_string(PRISM).unwrap();
    let run = |dt: f64| {
        let text = text.replace("      dt: 0.001\n", &format!("      dt: {dt}\n"));
        let mut cfg = tsim::config::parse_case(&text, PRISM).unwrap_or_else(|e| panic!("{e}"));
        cfg.outputs.every = 1;
        let mut reel = Reel {
            times: times.to_vec(),
            ..Default::default()
        };
        let summary = tsim::pipeline::run_case(&cfg, &mut reel).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(reel.kept.len(), times.len(), "every sample time is a step at Δt = {dt}");
        let ledger = summary.transient("reel").unwrap().transient.max_balance_error;
        (reel.kept, ledger, cfg.model.build().unwrap(), cfg.rest_lengths())
    };
    let runs: Vec<_> = [2e-3, 1e-3, 5e-4].into_iter().map(run).collect();
    let model = &runs[0].2;
    let ring = &model.clusters[0].members;
    let (first, _, _, rest0) = &runs[1];
    let total = |rest: &[f64]| ring.iter().map(|&m| rest[m]).sum::<f64>();
    // The loop's rest length at the stage's start: the given one (`push` slides it, keeping
    // its total).
    let start = total(rest0);
    for ((_, forces, _, rest, _), t) in first.iter().zip(times) {
        let expected = start * (1.0 - 0.001 * (t / 0.5).min(1.0));
        assert!(
            (total(rest) - expected).abs() < 1e-12 * start,
            "loop rest length at t = {t}: {} vs {expected}",
            total(rest)
        );
        assert!(
            ring.iter().all(|&m| (forces[m] - forces[ring[0]]).abs() < 1e-9 * forces[ring[0]]),
            "one tension at t = {t}"
        );
    }
    let work = first.last().unwrap().4.actuation;
    let ledger: Vec<f64> = runs.iter().map(|r| r.1).collect();
    eprintln!("actuator work {work:.6e} J; ledger errors at Δt = 2, 1, 0.5 ms: {ledger:?} J");
    assert!(work > 0.0 && ledger.iter().all(|&e| e <= 1e-6 * work));
    let flat = |k: usize, r: usize| {
        let (x, f, reactions, _, e) = &runs[r].0[k];
        vec![
            ("position", x.iter().flat_map(|p| p.iter().copied()).collect::<Vec<f64>>()),
            ("member force", f.clone()),
            ("reaction", reactions.clone()),
            ("kinetic", vec![e.kinetic]),
            ("strain", vec![e.strain]),
            ("damping", vec![e.damping]),
            ("actuation", vec![e.actuation]),
        ]
    };
    for (k, t) in times.iter().enumerate() {
        let [a, b, c] = [0, 1, 2].map(|r| flat(k, r));
        for (((name, x), (_, y)), (_, z)) in a.iter().zip(&b).zip(&c) {
            let diff = |p: &[f64], q: &[f64]| p.iter().zip(q).fold(0.0_f64, |d, (u, v)| d.max((u - v).abs()));
            let (coarse, fine) = (diff(x, y), diff(y, z));
            eprintln!(
                "t = {t} s, {name}: differences {coarse:.3e}, {fine:.3e}, ratio {:.2}",
                coarse / fine
            );
            if *t < 0.5 && (*name == "reaction" || *name == "damping") {
                // Not asserted: at 0.25 s the reactions and the damping energy still hold
                // the prism's stiff axial modes (up to 424 Hz, ωΔt = 5.3 at 2 ms) that the
                // ramp's start excited, damped but not yet in their asymptotic range:
                // measured ratios 2.76 and 2.71. The same prism with the ring as three
                // members shows the same (2.22 for its reactions), so it is not the cluster.
                continue;
            }
            assert!(coarse / fine > 3.0, "t = {t} s, {name}: differences {coarse:e}, {fine:e}");
        }
    }
}

/// Bad clusters are refused when the config loads, at the cluster's line, naming what is
/// wrong and the fix; a cable of two materials and a winch on part of a cable when the
/// case runs, naming the member or the cable.
#[test]
fn cluster_errors_name_the_cable_and_the_fix() {
    let text = std::fs::read_to_string(PRISM).unwrap();
    let line = "    - { id: top_ring, members: [ct0, ct1, ct2] }";
    assert!(text.contains(line));
    let at = text[..text.find(line).unwrap()].lines().count() + 1;
    for (members, message) in [
        ("[ct0, s0]", "member `s0` is a strut; only cables slide over nodes"),
        ("[ct0, ct9]", "unknown member `ct9`"),
        (
            "[cb0, ct0]",
            "members `cb0` and `ct0` follow each other in the list but share no node",
        ),
        ("[ct0]", "runs through at least two members"),
        ("[ct0, ct1, ct0]", "member `ct0` is listed twice"),
    ] {
        let bad = text.replace(line, &format!("    - {{ id: top_ring, members: {members} }}"));
        let e = match tsim::run::expand(&bad, "bad.yaml", false) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("{members} accepted"),
        };
        assert_field_errors(&e, "bad.yaml", &[(at, "model.clusters[0]", message)]);
    }
    let two = text.replace(line, &format!("{line}\n    - {{ id: again, members: [ct1, ct2] }}"));
    let e = tsim::run::expand(&two, "bad.yaml", false)
        .map(|_| ())
        .expect_err("a member in two cables")
        .to_string();
    assert_field_errors(
        &e,
        "bad.yaml",
        &[(at + 1, "model.clusters[1]", "member `ct1` is already in cluster `top_ring`")],
    );
    let run = |text: &str| {
        let cfg = tsim::config::parse_case(text, PRISM).unwrap_or_else(|e| panic!("{e}"));
        tsim::pipeline::run_case(&cfg, &mut tsim::record::NoRecorder)
            .map(|_| ())
            .expect_err("refused")
            .to_string()
    };
    let mixed = text.replace(
        "substitution:\n",
        "substitution:\n  assign: [{ members: [ct1], material: steel_tube }]\n",
    );
    assert!(
        run(&mixed).contains("member `ct1`: in cluster `top_ring` it has another material than `ct0`"),
        "{}",
        run(&mixed)
    );
    let partial = text.replace(
        "        - { members: [ct0, ct1, ct2], scale: 0.999 }",
        "        - { members: [ct0], scale: 0.999 }",
    );
    assert!(
        run(&partial).contains("winch: an actuator changes part of the clustered cable `top_ring`"),
        "{}",
        run(&partial)
    );
}

/// Frames of the `deployment` stage: the largest spread of the listed members' forces
/// relative to their mean.
struct Spread {
    stage: String,
    members: Vec<usize>,
    worst: f64,
    frames: usize,
}

impl Recorder for Spread {
    fn begin_stage(&mut self, stage: &Stage, _: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage == "deployment" {
            let t: Vec<f64> = self.members.iter().map(|&m| f.forces[m]).collect();
            let mean = t.iter().sum::<f64>() / t.len() as f64;
            self.worst = t.iter().fold(self.worst, |w, x| w.max((x - mean).abs() / mean.abs()));
            self.frames += 1;
        }
        Ok(())
    }
}

/// The paper's whole chain (configs/paper.yaml: form-finding, substitution by Ogden rubber,
/// eigen with Rayleigh damping, damped free vibration, folding, the damped deployment) with
/// the tower's top ring one clustered cable: it runs through, the equilibrium-matrix
/// analysis counts the four extra sliding mechanisms (m = 3 + 4, s = 1, prestress stable),
/// the ring carries one tension at every deployment step (1e-9: round-off of the shared
/// rest lengths) and the tower deploys into its shape (within the 1 % settle tolerance).
#[test]
fn the_paper_tower_with_a_clustered_top_ring_runs_its_whole_chain() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/paper.yaml");
    let text = std::fs::read_to_string(path).unwrap();
    let tower = "  tower: { struts: 5, stages: 2, radius: 3.0, strut_length: 7.0, overlap: 0.1 }\n";
    assert!(text.contains(tower));
    let ring = "ring_top_0, ring_top_1, ring_top_2, ring_top_3, ring_top_4";
    let text = text.replace(tower, &format!("{tower}  clusters: [{{ id: top, members: [{ring}] }}]\n"));
    let mut cfg = tsim::config::parse_case(&text, path).unwrap_or_else(|e| panic!("{e}"));
    cfg.outputs.every = 1;
    let model = cfg.model.build().unwrap();
    let members = model.clusters[0].members.clone();
    let mut spread = Spread {
        stage: String::new(),
        members,
        worst: 0.0,
        frames: 0,
    };
    let summary = tsim::pipeline::run_case(&cfg, &mut spread).unwrap_or_else(|e| panic!("{e}"));
    let a = &summary.structure_analysis;
    assert_eq!((a.s, a.m, a.prestress_stable), (1, 7, true), "{a:?}");
    assert!(
        spread.frames > 1000 && spread.worst < 1e-9,
        "ring tensions spread {:e} over {} frames",
        spread.worst,
        spread.frames
    );
    let deployment = summary.transient("deployment").unwrap();
    let shape = deployment.shape_error.expect("deployment is compared with the equilibrium");
    let ledger = deployment.transient.max_balance_error;
    eprintln!(
        "clustered paper tower: ring spread {:.2e}, deployment shape error {shape:.2e}, ledger {ledger:.3e} J, clusters {:?}",
        spread.worst, summary.clusters
    );
    assert!(shape < 0.01, "deployed into shape: {shape}");
}
