//! Issue 14, transient loads: nodal loads with time functions, ground acceleration, the
//! structure's constant load (gravity), initial conditions, CSV time tables and their
//! errors, and the energy ledger with all of them.
//!
//! Most checks run a linear oscillator, where Newmark's average acceleration is exactly the
//! trapezoidal rule on (x, v): its recurrence is known in closed form for any load history,
//! so the stage is checked against it to round-off, and against the continuous closed form
//! within the scheme's known discretisation error.
//!
//! Run with `cargo test --release --test loads`.

mod common;

use common::assert_field_errors;
use nalgebra::{Matrix2, Vector2, Vector3};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;
use tsim::config::{parse_case, CaseConfig, NodalForceSpec, TimeFunctionSpec, TimeStep};
use tsim::dynamics::{GroundMotion, Loads, NodalLoad, Rayleigh, TimeFunction};
use tsim::law::{ForceLaw, LinearElastic};
use tsim::model::{Member, MemberKind, Model, Node};
use tsim::pipeline::run_case;
use tsim::record::{Energy, Frame, ModelRecord, RecordResult, Recorder, Stage};
use tsim::stage::transient::{Initial, Transient, TransientSummary};
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::Elements;

// ---------------------------------------------------------------------------------------
// A recorder and a linear oscillator
// ---------------------------------------------------------------------------------------

/// One recorded frame: (stage, time, positions, velocities, energy).
type Logged = (Stage, f64, Vec<Vector3<f64>>, Vec<Vector3<f64>>, Energy);

/// Every frame of every stage, and the lumped masses, rest lengths and members (id and
/// end nodes) of the model record.
#[derive(Default)]
struct Log {
    stage: Option<Stage>,
    frames: Vec<Logged>,
    masses: Vec<f64>,
    rest: Vec<f64>,
    members: Vec<(String, [usize; 2])>,
}

impl Recorder for Log {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        self.masses = record.masses.to_vec();
        self.rest = record.rest_lengths.to_vec();
        self.members = record.model.members.iter().map(|m| (m.id.clone(), m.nodes)).collect();
        Ok(())
    }
    fn begin_stage(&mut self, stage: &Stage, _constraints: &tsim::record::Constraints) -> RecordResult {
        self.stage = Some(stage.clone());
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        let v = f.velocities.map_or_else(Vec::new, <[_]>::to_vec);
        self.frames.push((
            self.stage.clone().expect("frame inside a stage"),
            f.time,
            f.positions.to_vec(),
            v,
            f.energy,
        ));
        Ok(())
    }
}

impl Log {
    fn stage<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Logged> {
        self.frames.iter().filter(move |f| f.0.name() == name)
    }
}

/// A chain of linear-elastic bars (not tension-only) along x: a fixed node at x = −1,
/// then `masses.len()` free nodes at x = 0, 1, ... (rest length 1 m each, so the start is
/// unstrained), each free in x only. N = EA (l − l0)/l0 is linear in l and l is a
/// difference of x coordinates, so the x motion is exactly linear: m ẍ + K x = f. With one
/// free node it is the oscillator m ẍ + k x = f, k = EA/l0. The rest position of the
/// first free node is the origin (a rest position far from it raises Newton's round-off
/// floor: tests/pipeline.rs `newmark_newton_floor_at_small_steps`).
fn chain(k: f64, masses: &[f64]) -> Structure {
    let node = |id: String, x: f64, support: [bool; 3]| Node {
        id,
        xyz: Vector3::new(x, 0.0, 0.0),
        support,
    };
    let mut nodes = vec![node("ground".into(), -1.0, [true; 3])];
    let mut members = Vec::new();
    for i in 0..masses.len() {
        nodes.push(node(format!("m{i}"), i as f64, [false, true, true]));
        members.push(Member {
            id: format!("bar{i}"),
            nodes: [i, i + 1],
            kind: MemberKind::Strut,
            groups: vec![],
        });
    }
    let model = Model {
        nodes,
        members,
        node_groups: BTreeMap::new(),
        clusters: Vec::new(),
    };
    let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
        ea: k,
        tension_only: false,
    });
    let elements = Elements {
        laws: vec![law; masses.len()],
        rest: vec![1.0; masses.len()],
    };
    let mut s = Structure::massless(model, elements);
    s.masses = std::iter::once(0.0).chain(masses.iter().copied()).collect();
    s
}

fn transient(dt: f64, steps: usize, loads: Loads, initial: Initial) -> Transient {
    common::transient("free_vibration", dt, steps, loads, initial)
}

/// Runs `stage` on `s` from rest at the model's positions; the log and the summary.
fn run(s: &Structure, stage: &Transient) -> (Log, TransientSummary) {
    let mut log = Log::default();
    let settings = Settings {
        every: 1,
        ..Default::default()
    };
    let start = State::at_rest(s.model.positions());
    let (_, summary) = stage
        .run(s, start, &settings, &mut log)
        .unwrap_or_else(|e| panic!("transient failed: {e}"));
    (log, summary)
}

/// (x, v) of the first free node after every step, step 0 first.
fn trajectory(log: &Log) -> Vec<(f64, f64)> {
    log.frames.iter().map(|f| (f.2[1].x, f.3[1].x)).collect()
}

/// The exact Newmark (average acceleration) recurrence of m ẍ + k x = f(t) from rest:
/// the trapezoidal rule on z = (x, v), z' = A z + b(t),
/// z_{n+1} = (I − h/2 A)⁻¹ [(I + h/2 A) z_n + h/2 (b_n + b_{n+1})], b = (0, f/m)
/// (Chopra, Dynamics of Structures, ch. 5.4; the consistent initial acceleration is
/// implied by evaluating b at t_0).
fn recurrence(m: f64, k: f64, dt: f64, steps: usize, z0: (f64, f64), f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    let a = Matrix2::new(0.0, 1.0, -k / m, 0.0);
    let i = Matrix2::identity();
    let left = (i - a * (dt / 2.0)).try_inverse().unwrap();
    let right = i + a * (dt / 2.0);
    let mut z = Vector2::new(z0.0, z0.1);
    let mut out = vec![(z[0], z[1])];
    for n in 0..steps {
        let b = Vector2::new(0.0, (f(n as f64 * dt) + f((n + 1) as f64 * dt)) / m);
        z = left * (right * z + b * (dt / 2.0));
        out.push((z[0], z[1]));
    }
    out
}

/// Largest |x − x_ref| over the run.
fn worst(run: &[(f64, f64)], reference: impl Fn(usize) -> f64) -> f64 {
    run.iter().enumerate().map(|(n, p)| (p.0 - reference(n)).abs()).fold(0.0, f64::max)
}

const M: f64 = 2.0;
const K: f64 = 800.0; // ω = 20 rad/s, T = 0.314 s

// ---------------------------------------------------------------------------------------
// (a) Step load
// ---------------------------------------------------------------------------------------

/// A step force F on the oscillator from rest: x(t) = F/k (1 − cos ωt).
///
/// Against the recurrence (the scheme's exact answer): x_n = F/k (1 − cos nφ),
/// φ = 2 atan(ωΔt/2) (a rotation in (x − F/k, v/ω)); 1e-10 of F/k, the round-off budget of
/// tests/pipeline.rs `newmark_sdof_matches_closed_form_recurrence` (each step adds ~1e-16
/// m to x ~ 1e-2 m; Newton solves a linear step to its floor in one iteration).
///
/// Against the continuous solution: |cos nφ − cos nωΔt| ≤ n (ωΔt − φ), Newmark's period
/// elongation accumulated over n steps (ωΔt − φ ≈ (ωΔt)³/12 per step). That bound is
/// exact, so the tolerance is it (plus the round-off budget); it is ~1e-3 F/k here, and a
/// load off by one step (Δt/T = 0.5 %) or a wrong magnitude would exceed it.
#[test]
fn step_load_matches_closed_form() {
    let (f, steps) = (8.0, 400); // F/k = 1 cm; two periods
    let w = (K / M).sqrt();
    let dt = 2.0 * PI / w / 200.0;
    let load = NodalLoad {
        nodes: vec![1],
        force: Vector3::new(f, 0.0, 0.0),
        time: TimeFunction::Step { duration: 1e3 },
    };
    let loads = Loads {
        nodal: vec![load],
        ground: None,
    };
    let (log, summary) = run(&chain(K, &[M]), &transient(dt, steps, loads, Initial::default()));
    let x = trajectory(&log);
    assert_eq!(x.len(), steps + 1);
    let (xs, phi) = (f / K, 2.0 * (w * dt / 2.0).atan());
    let discrete = worst(&x, |n| xs * (1.0 - (n as f64 * phi).cos()));
    let continuous = worst(&x, |n| xs * (1.0 - (w * n as f64 * dt).cos()));
    let bound = xs * steps as f64 * (w * dt - phi);
    eprintln!(
        "step load: vs recurrence {:.2e}, vs x(t) {:.2e} (period-error bound {:.2e}) of F/k",
        discrete / xs,
        continuous / xs,
        bound / xs
    );
    assert!(discrete < 1e-10 * xs, "vs the recurrence: {:.3e} of F/k", discrete / xs);
    assert!(continuous <= bound + 1e-10 * xs, "vs x(t): {continuous:.3e} m, bound {bound:.3e} m");
    // The peak is the dynamic amplification 2 F/k (reached at t = T/2 and 3T/2).
    let peak = x.iter().map(|p| p.0).fold(0.0, f64::max);
    assert!((peak / xs - 2.0).abs() < 1e-3, "peak {:.6} F/k", peak / xs);
    // Undamped and linear: the ledger (with the load's work) closes to round-off.
    assert!(summary.max_balance_error < 1e-12 * summary.max_energy, "{summary:?}");
}

// ---------------------------------------------------------------------------------------
// (b) Harmonic load
// ---------------------------------------------------------------------------------------

/// F sin Ωt from rest, Ω = ω/2: x(t) = F/k/(1 − r²) (sin Ωt − r sin ωt), r = Ω/ω.
///
/// Against the recurrence: 1e-10 of F/k as in (a). Against x(t): the leading error is the
/// free part's phase drift, A_f ω t (ωΔt)²/12 with A_f = F/k r/(1 − r²): ~3.7e-4 F/k at
/// the end (t = 3T, ωΔt = 2π/400); the forced part's error is (ΩΔt)²-small (2e-6). So
/// 1e-3 F/k; and halving Δt must cut the error fourfold (second order: 3.6–4.4 allows
/// the higher-order terms, ~ (ωΔt)² ≈ 2.5e-4 relative, and the round-off share).
#[test]
fn harmonic_load_matches_closed_form() {
    let f0 = 8.0;
    let w = (K / M).sqrt();
    let r = 0.5;
    let omega = r * w;
    let periods = 3.0;
    let xs = f0 / K;
    let exact = |t: f64| xs / (1.0 - r * r) * ((omega * t).sin() - r * (w * t).sin());
    let error_at = |per_period: usize| {
        let dt = 2.0 * PI / w / per_period as f64;
        let steps = (periods * per_period as f64) as usize;
        let load = NodalLoad {
            nodes: vec![1],
            force: Vector3::new(f0, 0.0, 0.0),
            time: TimeFunction::Harmonic {
                frequency: omega / (2.0 * PI),
                phase: 0.0,
                duration: None,
            },
        };
        let loads = Loads {
            nodal: vec![load],
            ground: None,
        };
        let (log, _) = run(&chain(K, &[M]), &transient(dt, steps, loads, Initial::default()));
        let x = trajectory(&log);
        let rec = recurrence(M, K, dt, steps, (0.0, 0.0), |t| f0 * (omega * t).sin());
        let discrete = worst(&x, |n| rec[n].0);
        let continuous = worst(&x, |n| exact(n as f64 * dt));
        (discrete, continuous)
    };
    let (d1, c1) = error_at(400);
    let (d2, c2) = error_at(800);
    eprintln!(
        "harmonic load: vs recurrence {:.2e} / {:.2e}, vs x(t) {:.2e} / {:.2e} of F/k (Δt, Δt/2): ratio {:.3}",
        d1 / xs,
        d2 / xs,
        c1 / xs,
        c2 / xs,
        c1 / c2
    );
    assert!(d1.max(d2) < 1e-10 * xs, "vs the recurrence: {:.3e} of F/k", d1.max(d2) / xs);
    assert!(c1 < 1e-3 * xs, "vs x(t): {:.3e} of F/k", c1 / xs);
    assert!((3.6..=4.4).contains(&(c1 / c2)), "error ratio at Δt/2: {:.3}", c1 / c2);
}

// ---------------------------------------------------------------------------------------
// (c) Ground motion
// ---------------------------------------------------------------------------------------

/// A ground acceleration a_g(t) (a table) on the oscillator: the relative motion is that
/// under the force −m a_g, bit for bit (the relative formulation: the same force on the
/// free DOF), and against the recurrence for that force to 1e-10 as in (a). A ground
/// acceleration along a supported direction (y) moves the structure rigidly with the
/// ground: no relative motion, no force, exactly.
#[test]
fn ground_acceleration_is_the_load_minus_m_a_g() {
    let w = (K / M).sqrt();
    let dt = 2.0 * PI / w / 200.0;
    let steps = 400;
    let table = TimeFunction::Table(vec![[0.0, 0.0], [0.05, 1.0], [0.1, -0.5], [0.2, 0.0]].into());
    let ag = Vector3::new(3.0, 0.0, 0.0);
    let s = chain(K, &[M]);
    let ground = Loads {
        nodal: vec![],
        ground: Some(GroundMotion {
            acceleration: ag,
            time: table.clone(),
        }),
    };
    let force = Loads {
        nodal: vec![NodalLoad {
            nodes: vec![1],
            force: -M * ag,
            time: table.clone(),
        }],
        ground: None,
    };
    let (by_ground, _) = run(&s, &transient(dt, steps, ground, Initial::default()));
    let (by_force, _) = run(&s, &transient(dt, steps, force, Initial::default()));
    let (xg, xf) = (trajectory(&by_ground), trajectory(&by_force));
    assert_eq!(xg, xf, "relative motion under a_g vs under −m a_g");
    let rec = recurrence(M, K, dt, steps, (0.0, 0.0), |t| -M * ag.x * table.at(t));
    let scale = M * ag.x / K;
    let discrete = worst(&xg, |n| rec[n].0);
    eprintln!("ground motion: vs recurrence {:.2e} of m a_g/k", discrete / scale);
    assert!(discrete < 1e-10 * scale);
    assert!(xg.iter().map(|p| p.0.abs()).fold(0.0, f64::max) > 0.5 * scale, "it moved");

    // Along y, which the support holds: rigid motion with the ground, nothing else.
    let sideways = Loads {
        nodal: vec![],
        ground: Some(GroundMotion {
            acceleration: Vector3::new(0.0, 3.0, 0.0),
            time: table,
        }),
    };
    let (log, summary) = run(&s, &transient(dt, steps, sideways, Initial::default()));
    for f in &log.frames {
        assert_eq!(f.2, s.model.positions(), "t = {}", f.1);
        assert!(f.3.iter().all(|v| *v == Vector3::zeros()), "t = {}", f.1);
    }
    assert_eq!((summary.max_kinetic, summary.max_energy), (0.0, 0.0));
}

/// The same on a form-found 3-strut prism through the config: ground motion in x and z
/// (a table) against per-node loads −m_n a_g on every node, each node with its own lumped
/// mass. Every free DOF gets the same force either way, so the two runs agree bit for
/// bit; both are nonlinear (large rotations are not involved, but K_T changes).
#[test]
fn ground_motion_on_a_prism_equals_nodal_inertia_loads() {
    let text = include_str!("../configs/prism3.yaml");
    let mut cfg = parse_case(text, "configs/prism3.yaml").unwrap();
    cfg.eigen = None;
    let fv = cfg.free_vibration.as_mut().unwrap();
    (fv.load, fv.duration, fv.dt, fv.damped) = (None, 0.1, TimeStep::Fixed(0.0005), false);
    let time = TimeFunctionSpec::table(vec![[0.0, 0.0], [0.02, 1.0], [0.04, -1.0], [0.06, 0.0]]);
    let ag = [2.0, 0.0, -1.0];
    fv.ground_motion = Some(tsim::config::GroundMotionSpec {
        acceleration: ag,
        time: time.clone(),
    });
    let mut by_ground = Log::default();
    run_case(&cfg, &mut by_ground).unwrap_or_else(|e| panic!("{e}"));
    let model = cfg.model.build().unwrap();
    let fv = cfg.free_vibration.as_mut().unwrap();
    fv.ground_motion = None;
    fv.loads = model
        .nodes
        .iter()
        .zip(&by_ground.masses)
        .map(|(n, &m)| NodalForceSpec {
            nodes: vec![n.id.clone()],
            groups: vec![],
            force: ag.map(|a| -m * a),
            time: time.clone(),
        })
        .collect();
    let mut by_force = Log::default();
    run_case(&cfg, &mut by_force).unwrap_or_else(|e| panic!("{e}"));
    let (g, f): (Vec<_>, Vec<_>) = (
        by_ground.stage("free_vibration").collect(),
        by_force.stage("free_vibration").collect(),
    );
    assert_eq!(g.len(), 201);
    let moved = g.iter().map(|a| (a.2[5] - g[0].2[5]).norm()).fold(0.0, f64::max);
    eprintln!("prism under ground motion: top node moved up to {moved:.3e} m");
    assert!(moved > 1e-6, "the ground motion moved the prism");
    for (a, b) in g.iter().zip(&f) {
        assert_eq!((a.1, &a.2, &a.3), (b.1, &b.2, &b.3), "t = {}", a.1);
    }
}

// ---------------------------------------------------------------------------------------
// (d) Initial displacement: free vibration at the eigen frequency
// ---------------------------------------------------------------------------------------

/// A prestressed star: three linear cables (strain 1 %, tension N) from fixed anchors at
/// distance L along −x, +x and −z to a middle node held in z, the cables' mass lumped there
/// (m = 3 · ½ ρ A l0). Its y direction is stiffened by geometry only: ω² = 3N/(mL). (Three
/// anchors, not the string's two, because a model on one line leaves the rotation about
/// it unsupported.) The middle node is displaced in y by `initial.displacement` (1e-4 L)
/// and released: the period of the free vibration (mean over 10 periods, from linearly
/// interpolated zero crossings) against 2π/ω of the eigen stage, after Newmark's period
/// elongation T̄/T = (ωΔt/2)/atan(ωΔt/2) (ωΔt = 2π/200: 8e-5) is taken out.
///
/// Tolerance 1e-6 relative: what remains is the amplitude nonlinearity, the tension's
/// rise (EA/N)(a/L)²/2 ≈ 100 · 1e-8/2 = 5e-7 at the peak (less on average), the
/// interpolation of a crossing (O((ωΔt)³) with a sine's zero curvature there: ~1e-7 of a
/// step, 1e-9 of the period), and the eigenvalue's own ~1e-14 (tests/pipeline.rs
/// `string_with_mid_mass_lateral_frequency`).
#[test]
fn initial_displacement_vibrates_at_the_eigen_frequency() {
    let (half, l0, ea, area, density): (f64, f64, f64, f64, f64) = (1.5, 1.485, 1000.0, 1e-4, 1000.0);
    let m = 1.5 * density * area * l0;
    let n = ea * (half - l0) / l0;
    let w2 = 3.0 * n / (m * half);
    let w = w2.sqrt();
    let dt = 2.0 * PI / w / 200.0;
    let a = 1e-4 * half;
    let text = format!(
        "name: star\n{STAR}eigen: {{}}\nfree_vibration:\n  dt: {dt}\n  duration: {}\n  initial:\n    displacement:\n      - {{ nodes: [mid], value: [0, {a}, 0] }}\n",
        10.5 * 2.0 * PI / w
    );
    let cfg = parse_case(&text, "star.yaml").unwrap_or_else(|e| panic!("{e}"));
    let mut log = Log::default();
    let summary = run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
    let eigen = summary.eigen("eigen").expect("eigen ran").clone();
    let w_eigen = eigen.omega2[0].sqrt();
    assert!(
        (eigen.omega2[0] / w2 - 1.0).abs() < 1e-9,
        "eigen ω² {} vs 3N/(mL) {w2}",
        eigen.omega2[0]
    );
    // Zero crossings of y(t) of the middle node, interpolated.
    let y: Vec<(f64, f64)> = log.stage("free_vibration").map(|f| (f.1, f.2[MID].y)).collect();
    assert!((y[0].1 - a).abs() < 1e-15, "started displaced: {}", y[0].1);
    let crossings: Vec<f64> = y
        .windows(2)
        .filter(|p| p[0].1 > 0.0 && p[1].1 <= 0.0)
        .map(|p| p[0].0 + (p[1].0 - p[0].0) * p[0].1 / (p[0].1 - p[1].1))
        .collect();
    assert!(crossings.len() >= 10, "{} downward crossings", crossings.len());
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let elongation = (w_eigen * dt / 2.0) / (w_eigen * dt / 2.0).atan();
    let expected = 2.0 * PI / w_eigen * elongation;
    eprintln!(
        "star: period {measured:.9} s vs eigen {:.9} s × elongation {elongation:.7}: {:+.2e} relative",
        2.0 * PI / w_eigen,
        measured / expected - 1.0
    );
    assert!((measured / expected - 1.0).abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------
// (e) Gravity in a transient: at rest at the loaded equilibrium
// ---------------------------------------------------------------------------------------

/// Gravity along the oscillator (g = −9.81 m/s² in x): the weight m g is a load in the
/// transient. Started at the loaded equilibrium x = m g/k (an initial displacement), it
/// stays there: |x − m g/k| and |v| stay at round-off (1e-12 of the static deflection:
/// the start's residual k x − m g is ~ε k x, and a step adds ~ε x), over 1000 steps with
/// no drift. Started at the unloaded position, it swings to 2 m g/k: gravity does act.
#[test]
fn gravity_at_the_loaded_equilibrium_stays_at_rest() {
    let w = (K / M).sqrt();
    let dt = 2.0 * PI / w / 200.0;
    let mut s = chain(K, &[M]);
    s.gravity = Vector3::new(-9.81, 0.0, 0.0);
    let sag = M * s.gravity.x / K;
    let at_sag = Initial {
        displacement: vec![(1, Vector3::new(sag, 0.0, 0.0))],
        ..Default::default()
    };
    let (log, summary) = run(&s, &transient(dt, 1000, Loads::default(), at_sag));
    let x = trajectory(&log);
    let drift = x.iter().map(|p| (p.0 - sag).abs()).fold(0.0, f64::max);
    let speed = x.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
    eprintln!(
        "gravity at rest: drift {:.2e}, speed {:.2e} (of m g/k, ω m g/k)",
        drift / sag.abs(),
        speed / (w * sag.abs())
    );
    assert!(drift < 1e-12 * sag.abs() && speed < 1e-12 * w * sag.abs());
    assert!(summary.max_mechanical_rise <= 1e-12 * summary.max_energy, "{summary:?}");
    let (log, _) = run(&s, &transient(dt, 200, Loads::default(), Initial::default()));
    let lowest = trajectory(&log).iter().map(|p| p.0).fold(0.0, f64::min);
    assert!((lowest / sag - 2.0).abs() < 1e-3, "swing {:.6} m g/k", lowest / sag);
}

// ---------------------------------------------------------------------------------------
// (g) The energy ledger with every kind of load
// ---------------------------------------------------------------------------------------

/// Two masses in a linear chain, Rayleigh damped (α M and the objective β term), under
/// gravity, a harmonic force on the outer mass, a ramped force on the inner one and a
/// ground acceleration table, started with an initial velocity and zero acceleration:
/// KE + SE + D − W − E0 stays at round-off. The system is linear, so the trapezoidal
/// work the ledger counts is the scheme's exact energy identity; what is left is
/// round-off: each step's increment Δu is a difference of coordinates of ~1 m (ε·1 m
/// off), times forces of ~30 N, accumulated over 2000 steps: up to ~1.3e-11 J if it adds
/// up linearly, 5e-12 of the 2.7 J energy scale (measured: 3e-12). 1e-10 leaves that
/// margin and is still 1e-8 of the loads' work W (2.6 J): a load left out of the ledger,
/// or counted at the wrong time, shows at the size of W.
#[test]
fn energy_balance_closes_with_time_varying_and_ground_loads() {
    let mut s = chain(K, &[M, 0.5 * M]);
    s.gravity = Vector3::new(-9.81, 0.0, 0.0);
    let loads = Loads {
        nodal: vec![
            NodalLoad {
                nodes: vec![2],
                force: Vector3::new(5.0, 0.0, 0.0),
                time: TimeFunction::Harmonic {
                    frequency: 2.0,
                    phase: 0.3,
                    duration: Some(0.6),
                },
            },
            NodalLoad {
                nodes: vec![1],
                force: Vector3::new(-3.0, 0.0, 0.0),
                time: TimeFunction::Ramp { duration: 0.4 },
            },
        ],
        ground: Some(GroundMotion {
            acceleration: Vector3::new(4.0, 0.0, 0.0),
            time: TimeFunction::Table(vec![[0.0, 0.0], [0.1, 1.0], [0.3, -1.0], [0.5, 0.0]].into()),
        }),
    };
    let initial = Initial {
        velocity: vec![(2, Vector3::new(0.2, 0.0, 0.0))],
        zero_acceleration: true,
        ..Default::default()
    };
    let mut stage = transient(0.0005, 2000, loads, initial);
    stage.rayleigh = Rayleigh { alpha: 0.5, beta: 0.002 };
    let (log, summary) = run(&s, &stage);
    let last = log.frames.last().unwrap().4;
    eprintln!(
        "energy ledger: max |KE + SE + D − W − E0| {:.2e} J of max energy {:.3e} J; W = {:.4e} J, D = {:.4e} J",
        summary.max_balance_error, summary.max_energy, last.external, last.damping
    );
    assert!(last.external.abs() > 1e-3 * summary.max_energy && last.damping > 1e-3 * summary.max_energy);
    assert!(summary.max_balance_error < 1e-10 * summary.max_energy, "{summary:?}");
    assert!(log.frames[0].3[2].x == 0.2, "the initial velocity is set");
}

// ---------------------------------------------------------------------------------------
// (f) CSV tables and the errors of loads, from files
// ---------------------------------------------------------------------------------------

/// A fresh directory under the system's temp dir for one test, removed when dropped.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("tsim-loads-{name}-")).tempdir().unwrap()
}

/// The star of (d): 13 lines, from `model:` to `substitution:`.
const STAR: &str = "model:
  nodes:
    - { id: a, xyz: [-1.5, 0, 0], fix: [x, y, z] }
    - { id: b, xyz: [1.5, 0, 0], fix: [x, y, z] }
    - { id: c, xyz: [0, 0, -1.5], fix: [x, y, z] }
    - { id: mid, xyz: [0, 0, 0], fix: [z] }
  members:
    - { id: left, nodes: [a, mid], kind: cable, rest_length: 1.485 }
    - { id: right, nodes: [mid, b], kind: cable, rest_length: 1.485 }
    - { id: down, nodes: [c, mid], kind: cable, rest_length: 1.485 }
materials:
  wire: { law: { elastic: { youngs_modulus: 1.0e7, tension_only: false } }, area: 1.0e-4, density: 1000.0 }
substitution: { strut: wire, cable: wire }
";

/// Index of the star's middle node.
const MID: usize = 3;

/// The star with ground motion along y from `table` (a YAML flow value) on line 20.
fn star_config(table: &str) -> String {
    format!("name: star\n{STAR}free_vibration:\n  dt: 0.001\n  duration: 0.1\n  ground_motion:\n    acceleration: [0, 1.0, 0]\n    time: {table}\n")
}

fn load_errors(path: &std::path::Path) -> String {
    match tsim::run::load(path, false) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("{} loaded without error", path.display()),
    }
}

/// A table file relative to the config is read into `points` when the config loads; the
/// resolved config (case.yaml) names the run's copy of it, whose rows read back to the
/// same points exactly; and the run is the one with the same points written inline, bit
/// for bit.
#[test]
fn csv_table_is_read_into_the_resolved_config() {
    let scratch_dir = scratch("csv-ok");
    let dir = scratch_dir.path();
    let fixture = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/ground_pulse.csv");
    std::fs::copy(fixture, dir.join("pulse.csv")).unwrap();
    let path = dir.join("case.yaml");
    std::fs::write(&path, star_config("{ table: { file: pulse.csv } }")).unwrap();
    let cases = tsim::run::load(&path, false).unwrap_or_else(|e| panic!("{e}")).cases;
    let yaml = &cases[0].yaml().unwrap();
    let spec = cases[0].config.free_vibration.as_ref().unwrap().ground_motion.as_ref().unwrap();
    let TimeFunctionSpec::Table { file: None, points, .. } = &spec.time else {
        panic!("{:?}", spec.time)
    };
    let rows: Vec<[f64; 2]> = std::fs::read_to_string(fixture)
        .unwrap()
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut c = l.split(',').map(|c| c.trim().parse::<f64>().unwrap());
            [c.next().unwrap(), c.next().unwrap()]
        })
        .collect();
    assert_eq!(&points[..], &rows[..]);
    let kept = cases[0].config.kept_tables();
    let [(name, _)] = &kept[..] else { panic!("{kept:?}") };
    assert!(
        name.starts_with("pulse-") && yaml.contains(&format!("file: ../tables/{name}")),
        "{yaml}"
    );
    let copy = tsim::config::table_csv(points);
    assert_eq!(tsim::config::parse_table(&copy, "copy.csv", "f").unwrap(), rows, "{copy}");
    let inline = format!("{{ table: {{ points: {rows:?} }} }}");
    let inline_cfg: CaseConfig = parse_case(&star_config(&inline), "inline.yaml").unwrap();
    let (mut a, mut b) = (Log::default(), Log::default());
    run_case(&cases[0].config, &mut a).unwrap_or_else(|e| panic!("{e}"));
    run_case(&inline_cfg, &mut b).unwrap_or_else(|e| panic!("{e}"));
    let ys: Vec<f64> = a.stage("free_vibration").map(|f| f.2[MID].y).collect();
    assert!(ys.iter().any(|y| y.abs() > 1e-6), "the ground motion moved the star");
    assert_eq!(ys, b.stage("free_vibration").map(|f| f.2[MID].y).collect::<Vec<_>>());
}

/// Every CSV problem is reported at its file and line, with what to do; a missing file
/// names the resolved path at the config's `file:` line.
#[test]
fn csv_table_errors_name_file_and_line() {
    let scratch_dir = scratch("csv-errors");
    let dir = scratch_dir.path();
    let config = |name: &str, csv: Option<&str>| {
        if let Some(csv) = csv {
            std::fs::write(dir.join(format!("{name}.csv")), csv).unwrap();
        }
        let path = dir.join(format!("{name}.yaml"));
        std::fs::write(&path, star_config(&format!("{{ table: {{ file: {name}.csv }} }}"))).unwrap();
        (path, dir.join(format!("{name}.csv")).display().to_string())
    };
    // The `file:` key is on line 20 of `star_config`.
    let (path, csv) = config("missing", None);
    let e = load_errors(&path);
    eprintln!("{e}");
    assert!(
        e.contains(&format!("{}:20:", path.display())) && e.contains(&format!("cannot read `{csv}`")),
        "{e}"
    );
    let cases = [
        ("badrow", "t,a\n0,0\n0.1;1\n0.2,0\n", 3, "is not two numbers"),
        ("nan", "0,0\n0.1,NaN\n0.2,0\n", 2, "is not finite"),
        ("inf", "0,0\n0.1,1\ninf,0\n", 3, "is not finite"),
        ("unsorted", "0,0\n0.2,1\n0.1,0\n", 3, "time 0.1 is not after 0.2 at line 2"),
        ("duplicate", "0,0\n0.1,1\n0.1,0\n", 3, "time 0.1 is not after 0.1 at line 2"),
    ];
    for (name, text, line, message) in cases {
        let (path, csv) = config(name, Some(text));
        let e = load_errors(&path);
        eprintln!("{e}");
        assert!(e.contains(&format!("{csv}:{line}: ")) && e.contains(message), "{name}: {e}");
    }
    let (path, csv) = config("short", Some("time,accel\n0,1\n"));
    let e = load_errors(&path);
    eprintln!("{e}");
    assert!(e.contains(&csv) && e.contains("at least 2"), "{e}");
    // A 200 kB row (issue 29: quoted whole on stderr) is quoted as a short excerpt.
    let (path, _) = config("wide", Some(&format!("0,0\n0.1,{}\n0.2,0\n", "7;".repeat(100_000))));
    let e = load_errors(&path);
    assert!(e.contains("is not two numbers") && e.len() < 1000, "{} bytes", e.len());
    // A FIFO as a table (issue 29: `check` waited forever on it) is refused at once.
    let (path, csv) = config("fifo", None);
    let name = std::ffi::CString::new(csv.as_str()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    let e = load_errors(&path);
    assert!(e.contains(&format!("cannot read `{csv}`: is not a regular file")), "{e}");
}

/// A table is read only from beside the config (issue 29: `../../etc/passwd` was read and
/// its rows echoed): a name that leaves the config's directory, an absolute path or a link
/// pointing out is refused at the `file:` line naming the resolved path; `table_dirs`
/// opts a directory in, and one that does not exist is an error of its own line.
#[test]
fn tables_are_read_only_from_beside_the_config_unless_opted_in() {
    let scratch_dir = scratch("csv-outside");
    let (dir, data) = (scratch_dir.path().join("configs"), scratch_dir.path().join("data"));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::create_dir_all(&data).unwrap();
    std::fs::write(data.join("rec.csv"), "0,0\n0.05,1\n0.1,0\n").unwrap();
    std::os::unix::fs::symlink(data.join("rec.csv"), dir.join("linked.csv")).unwrap();
    let write = |name: &str, head: &str, file: &str| {
        let path = dir.join(format!("{name}.yaml"));
        std::fs::write(&path, format!("{head}{}", star_config(&format!("{{ table: {{ file: {file} }} }}")))).unwrap();
        path
    };
    let resolved = data.join("rec.csv").canonicalize().unwrap().display().to_string();
    for (name, file, shown) in [
        ("up", "../data/rec.csv", resolved.as_str()),
        ("absolute", "/etc/passwd", "/etc/passwd"),
        ("link", "linked.csv", resolved.as_str()),
    ] {
        let path = write(name, "", file);
        let e = load_errors(&path);
        // The `file:` key is on line 20 of `star_config`.
        assert!(e.contains(&format!("{}:20:", path.display())), "{name}: {e}");
        assert!(
            e.contains(&format!("`{shown}` lies outside the config's directory")) && e.contains("table_dirs"),
            "{name}: {e}"
        );
        assert!(!e.contains("root:"), "{name}: a row of the file was echoed: {e}");
    }
    let opted = write("opted", "table_dirs: [../data]\n", "../data/rec.csv");
    let loaded = tsim::run::load(&opted, false).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(loaded.cases.len(), 1);
    let missing = write("missing", "table_dirs: [../nowhere]\n", "../data/rec.csv");
    let e = load_errors(&missing);
    assert!(
        e.contains(&format!("{}:1:", missing.display())) && e.contains("`table_dirs[0]`") && e.contains("cannot resolve `../nowhere`"),
        "{e}"
    );
}

/// `tsim check rec.yaml`, run in the config's directory, reads the table beside it: the
/// config's directory was the empty path, which does not resolve, so every table was
/// refused as lying outside it.
#[test]
fn a_config_named_without_a_directory_reads_its_tables() {
    let dir = scratch("csv-bare");
    std::fs::write(dir.path().join("rec.csv"), "0,0\n0.05,1\n0.1,0\n").unwrap();
    std::fs::write(dir.path().join("bare.yaml"), star_config("{ table: { file: rec.csv } }")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tsim"))
        .args(["check", "bare.yaml"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Bad loads, ground motion and initial conditions are value errors at their lines: an
/// unknown node, an unknown group, an empty node set, a non-positive duration, inline
/// points out of order, ground motion with no support, an initial velocity on a fixed
/// direction (node and direction named), `from: folded` in free vibration.
#[test]
fn load_errors_name_the_field_and_line() {
    let text = format!(
        "name: bad
{STAR}free_vibration:
  duration: 0.1
  loads:
    - {{ nodes: [mid], force: [0, 1, 0] }}
    - {{ nodes: [nowhere], force: [0, 1, 0] }}
    - {{ groups: [top], force: [0, 1, 0], time: {{ ramp: {{ duration: 0 }} }} }}
    - {{ force: [0, 1, 0] }}
    - nodes: [mid]
      force: [1, 0, 0]
      time: {{ table: {{ points: [[0, 0], [0.2, 1], [0.1, 0]] }} }}
  initial:
    from: folded
    velocity:
      - {{ nodes: [mid], value: [0, 0.1, 0.5] }}
"
    );
    let e = match tsim::run::expand(&text, "bad.yaml", false) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    eprintln!("{e}");
    let expect = [
        (19, "free_vibration.loads[1].nodes", "unknown node `nowhere`"),
        (20, "free_vibration.loads[2].groups", "unknown node group `top`"),
        (20, "free_vibration.loads[2].time.ramp.duration", "must be a finite number > 0"),
        (21, "free_vibration.loads[3]", "names no node"),
        (
            24,
            "free_vibration.loads[4].time.table.points[2]",
            "time 0.1 is not after points[1]'s 0.2",
        ),
        (26, "free_vibration.initial.from", "folding runs after free vibration"),
        (28, "free_vibration.initial.velocity[0].value", "node `mid` is supported in z"),
    ];
    assert_field_errors(&e, "bad.yaml", &expect);
    // Ground motion needs a support to move.
    let free = "name: free
model:
  nodes:
    - { id: a, xyz: [0, 0, 0] }
    - { id: b, xyz: [1, 0, 0] }
  members:
    - { id: ab, nodes: [a, b], kind: strut, rest_length: 1.0 }
substitution: { strut: aluminium, cable: steel_cable }
free_vibration:
  duration: 0.1
  ground_motion: { acceleration: [1, 0, 0], time: constant }
";
    let e = match tsim::run::expand(free, "free.yaml", false) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    eprintln!("{e}");
    assert!(
        e.lines()
            .any(|l| l.starts_with("free.yaml:11: `free_vibration.ground_motion`: ") && l.contains("no support")),
        "{e}"
    );
}

/// `initial.from: previous` starts deployment at the end of free vibration (velocities
/// too), with no folding between; the default is the equilibrium for free vibration.
#[test]
fn previous_starts_where_the_last_stage_ended() {
    let text = star_config("{ harmonic: { frequency: 5.0 } }")
        + "deployment:
  dt: 0.001
  duration: 0.01
  initial: { from: previous }
";
    let cfg = parse_case(&text, "previous.yaml").unwrap_or_else(|e| panic!("{e}"));
    let mut log = Log::default();
    run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
    let end = log.stage("free_vibration").last().unwrap();
    let start = log.stage("deployment").next().unwrap();
    assert!(end.3[MID].norm() > 0.0, "free vibration ended moving");
    assert_eq!((&end.2, &end.3), (&start.2, &start.3));
}

/// The deployment frames' last positions and how often a member's force went to or from
/// zero (a tension-only cable going slack or taut) between frames.
#[derive(Default)]
struct SlackLog {
    stage: Option<Stage>,
    last: Vec<Vector3<f64>>,
    slack: Vec<bool>,
    switches: usize,
}

impl Recorder for SlackLog {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &tsim::record::Constraints) -> RecordResult {
        self.stage = Some(stage.clone());
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage.as_ref().is_some_and(|s| s.name() == "deployment") {
            let slack: Vec<bool> = f.forces.iter().map(|&n| n == 0.0).collect();
            if !self.slack.is_empty() {
                self.switches += slack.iter().zip(&self.slack).filter(|(a, b)| a != b).count();
            }
            self.slack = slack;
            self.last = f.positions.to_vec();
        }
        Ok(())
    }
}

/// A 6 × 6 grid with steel cables (tension-only, stretched 2e-5 by their prestress) pushed
/// down 5 cm and released with objective damping: about 2 000 slack/taut switches in
/// 0.2 s. The deployment's end positions must converge as Δt halves (1 ms … 1/64 ms), with
/// no step cut: the successive differences d_k (RMS over the nodes, Δt_k against Δt_k/2)
/// fall by a factor 4 per halving at second order (2 at first).
///
/// Measured d_k: 9.91e-5, 2.93e-5, 8.32e-6, 2.57e-6, 5.93e-7, 1.43e-7 m, ratios 3.38, 3.52,
/// 3.23, 4.34, 4.16; the order as the least-squares slope of log2 d_k against the halving
/// count: 1.88 (standard error 0.04). Each snapping cable carries its damping force's
/// impulse within the step (`tsm::SnapRate`), and a taut one is held on its mean force
/// over the step (`tsm::DampingModulus`'s allowance); with it held at −N at the step's
/// end instead, d_k were 1.24e-4 … 1.62e-7 m, order 1.92 ± 0.02. Before, with steps stopped where a cable
/// snapped taut: 5.40e-5 … 6.85e-7 m, order 1.33 ± 0.10; with the snapping cable undamped
/// for its step and the cables' damping able to push: order 1.08 ± 0.06. The same grid pushed 0.1 mm (no switch) gives ratios 4.01 and
/// 3.81 before the solver's floor (~4e-9 m).
#[test]
fn a_grid_with_slackening_cables_converges_as_dt_halves() {
    let ends: Vec<Vec<Vector3<f64>>> = (0..7)
        .map(|k| 1e-3 / f64::powi(2.0, k))
        .map(|dt| {
            let text = common::slack_grid("modes: [1, 20], ratios: [0.02, 0.02]", dt, 0.2, "");
            let cfg = parse_case(&text, "slack.yaml").unwrap_or_else(|e| panic!("{e}"));
            let mut log = SlackLog::default();
            let summary = run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
            let deployment = summary.transient("deployment").expect("deployment ran");
            assert_eq!(deployment.transient.cut_steps, 0, "Δt = {dt}: {:?}", deployment.transient);
            assert!(log.switches > 1000, "Δt = {dt}: only {} slack/taut switches", log.switches);
            log.last
        })
        .collect();
    let rms = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
        (a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum::<f64>() / a.len() as f64).sqrt()
    };
    let diffs: Vec<f64> = ends.windows(2).map(|w| rms(&w[0], &w[1])).collect();
    let ratios: Vec<f64> = diffs.windows(2).map(|w| w[0] / w[1]).collect();
    // Least-squares slope of log2 d_k against k, and its standard error.
    let n = diffs.len() as f64;
    let (x_mean, y_mean) = ((n - 1.0) / 2.0, diffs.iter().map(|d| d.log2()).sum::<f64>() / n);
    let sxx: f64 = (0..diffs.len()).map(|k| (k as f64 - x_mean).powi(2)).sum();
    let slope: f64 = diffs
        .iter()
        .enumerate()
        .map(|(k, d)| (k as f64 - x_mean) * (d.log2() - y_mean))
        .sum::<f64>()
        / sxx;
    let order = -slope;
    let rss: f64 = diffs
        .iter()
        .enumerate()
        .map(|(k, d)| (d.log2() - (y_mean - order * (k as f64 - x_mean))).powi(2))
        .sum();
    let error = (rss / (n - 2.0) / sxx).sqrt();
    let text: Vec<String> = diffs.iter().map(|d| format!("{d:.3e}")).collect();
    eprintln!("successive RMS differences: {text:?} m, ratios {ratios:.2?}; fitted order {order:.3} ± {error:.3}");
    // A Δt-dependent path would not fall at all.
    assert!(diffs.windows(2).all(|w| w[1] < w[0]), "{diffs:?}");
    // Second order is 2; 1.8 is 2 standard errors of the fit (0.039) below the measured
    // 1.88 (5 below the 1.92 of the end hold), and well above the 1.33 of steps stopped
    // at each snap.
    assert!(order >= 1.8, "fitted order {order:.3} ± {error:.3}: {diffs:?}");
}

/// The grid above damped as stiffly as its 105 × 105 sibling's Rayleigh fit damps that
/// one (β = 0.0747 s, modes 1 and 20 of configs/bench/pipeline_grid.yaml), and 4 times
/// more: at Δt = 1 ms its cables' β k Δt/m is 4.4–25 (and 4 times that), past the
/// 1/(1 − γ) = 2 above which the trapezoidal rule turns a dashpot's rate over each step.
/// The damping must still dissipate over every step: the ledger's damping energy never
/// falls, the mechanical energy never rises once released, and no step is cut. Before a
/// cable's no-push condition held on its mean force over the step (`tsm::DampingModulus`'s
/// allowance), β = 0.0747 s gained 44.3 J in a step with 45 steps cut, and at β = 0.3 s
/// Newton failed at step 192 (measured with the tsim of 677752a).
#[test]
fn a_stiffly_damped_grid_dissipates_over_every_step() {
    for beta in [0.0747, 0.3] {
        let text = common::slack_grid(&format!("alpha: 0.0037, beta: {beta}"), 1e-3, 0.3, "");
        let cfg = parse_case(&text, "stiff.yaml").unwrap_or_else(|e| panic!("{e}"));
        let mut log = Log::default();
        let summary = run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("β = {beta}: {e}"));
        let deployment = &summary.transient("deployment").expect("deployment ran").transient;
        let damping: Vec<f64> = log.stage("deployment").map(|f| f.4.damping).collect();
        let fall = damping.windows(2).map(|w| w[0] - w[1]).fold(f64::NEG_INFINITY, f64::max);
        eprintln!(
            "β = {beta}: largest fall of the damping energy {fall:.3e} J, largest mechanical rise {:.3e} J, max energy {:.3e} J, {} cut steps",
            deployment.max_mechanical_rise, deployment.max_energy, deployment.cut_steps
        );
        assert_eq!(deployment.cut_steps, 0, "β = {beta}: {deployment:?}");
        // The summary names the member whose dashpot is fastest against the step: a strut
        // (EA/l0 = 6.8e8 N/m over ~1 m against the cables' 8e6), β (EA/l0)(1/m_a + 1/m_b) Δt.
        let fastest = deployment.fastest_dashpot.as_ref().expect("β damping");
        let e = log.members.iter().position(|(id, _)| *id == fastest.member).expect("a member id");
        let [a, b] = log.members[e].1;
        let ratio = beta * 68e9 * 0.01 / log.rest[e] * (1.0 / log.masses[a] + 1.0 / log.masses[b]) * 1e-3;
        assert!(fastest.member.starts_with("strut"), "{fastest:?}");
        assert!(
            (fastest.steps_per_dashpot_time / ratio - 1.0).abs() < 1e-12,
            "{fastest:?} against {ratio}"
        );
        // Steps balance forces to 1e-10 of the largest (newton.force_tolerance), so a step's
        // work is exact to about 1e-10 of F·Δu, below 1e-9 of the energy scale here; the
        // failure was 44 J of ~2 kJ.
        let tolerance = 1e-9 * deployment.max_energy;
        assert!(fall <= tolerance, "β = {beta}: the damping energy fell by {fall:.3e} J in a step");
        assert!(deployment.max_mechanical_rise <= tolerance, "β = {beta}: {deployment:?}");
    }
}

/// The reproducer of issue 29: a long table in a large sweep. Every case shares the one
/// copy of its points (each case had its own, and its case.yaml quoted every row: a
/// 10⁶-row table in 1000 cases made `tsim check` abort at 3.9 GB); a sweep value naming
/// another file gives the cases holding it that file's points, read once; case.yaml names
/// the run's copy. 20 000 rows and 200 cases keep the test quick; the sharing is
/// structural, so the sizes only need to make a copy visible.
#[test]
fn the_cases_of_a_sweep_share_one_copy_of_a_table() {
    let dir = scratch("csv-shared");
    let rows = |scale: f64| -> String {
        (0..20_000)
            .map(|k| format!("{},{}\n", k as f64 * 1e-5, scale * (k as f64).sin()))
            .collect()
    };
    std::fs::write(dir.path().join("long.csv"), rows(1.0)).unwrap();
    std::fs::write(dir.path().join("other.csv"), rows(2.0)).unwrap();
    let values: String = (0..100)
        .map(|k| {
            format!(
                "        - {{ label: d{k}, set: {{ free_vibration.duration: {} }} }}\n",
                0.05 + 0.001 * k as f64
            )
        })
        .collect();
    let other = "{ acceleration: [0, 1.0, 0], time: { table: { file: other.csv } } }";
    let text = format!(
        "{}sweep:\n  axes:\n    - name: rec\n      values:\n        - {{ label: base, set: {{}} }}\n        - {{ label: other, set: {{ free_vibration.ground_motion: {other} }} }}\n    - name: duration\n      values:\n{values}",
        star_config("{ table: { file: long.csv } }")
    );
    let path = dir.path().join("sweep.yaml");
    std::fs::write(&path, text).unwrap();
    let cases = tsim::run::load(&path, false).unwrap_or_else(|e| panic!("{e}")).cases;
    assert_eq!(cases.len(), 200);
    let table = |c: &tsim::run::Case| c.config.table_points().pop().unwrap();
    let (base, other) = (table(&cases[0]), table(&cases[100]));
    assert_eq!((base.len(), other.len()), (20_000, 20_000));
    assert!(base.iter().zip(other.iter()).any(|(a, b)| a != b), "the two files differ");
    for (k, c) in cases.iter().enumerate() {
        let shared = if k < 100 { &base } else { &other };
        assert!(Arc::ptr_eq(&table(c), shared), "case {} holds its own copy", c.id);
        let yaml = c.yaml().unwrap();
        let stem = if k < 100 { "long-" } else { "other-" };
        assert!(
            yaml.len() < 4000 && yaml.contains(&format!("file: ../tables/{stem}")),
            "{}: {yaml}",
            c.id
        );
    }
}

/// A case.yaml runs as it is, from its directory, and gives the same result.h5, byte for
/// byte: the run keeps the table it names.
#[test]
fn a_case_yaml_with_a_table_reruns_to_the_same_result() {
    let dir = scratch("csv-rerun");
    std::fs::write(dir.path().join("rec.csv"), "0,0\n0.03,1\n0.06,-0.5\n0.1,0\n").unwrap();
    std::fs::write(dir.path().join("star.yaml"), star_config("{ table: { file: rec.csv } }")).unwrap();
    let run = |config: &std::path::Path, out: &str| {
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_tsim"))
            .args(["run", "--quiet", "--out", out])
            .arg(config)
            .current_dir(dir.path())
            .status()
            .unwrap();
        assert!(status.success(), "{}", config.display());
    };
    run(&dir.path().join("star.yaml"), "first");
    let case = dir.path().join("first/star/star");
    run(&case.join("case.yaml"), "second");
    let again = dir.path().join("second/star/star");
    for file in ["case.yaml", "result.h5"] {
        assert_eq!(
            std::fs::read(case.join(file)).unwrap(),
            std::fs::read(again.join(file)).unwrap(),
            "{file}"
        );
    }
    let kept: Vec<_> = std::fs::read_dir(dir.path().join("first/star/tables")).unwrap().collect();
    assert_eq!(kept.len(), 1);
}
