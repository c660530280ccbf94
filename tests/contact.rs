//! Contact (issue 31): bodies kept apart by a barrier, checked against closed forms. A
//! bar dropped onto the ground gives back the energy its impact took and rebounds to the
//! height it fell from; its contact time is the barrier law's, by quadrature, at second
//! order in Δt; a bar at rest on the ground carries its weight there; a strut driven
//! across another stops at contact, the force balanced through both.

use nalgebra::Vector3;
use tsim::config::parse_case;
use tsim::contact::{Barrier, Touch};
use tsim::pipeline::{run_case, CaseSummary};
use tsim::record::{Constraints, Frame, RecordResult, Recorder, Stage};

/// What a case's stage `stage` records, frame by frame.
#[derive(Default)]
struct Log {
    stage: &'static str,
    recording: bool,
    frames: Vec<Logged>,
}

struct Logged {
    time: f64,
    positions: Vec<Vector3<f64>>,
    kinetic: f64,
    contact: f64,
    /// Σ of the ground's contact forces [N].
    ground: Vector3<f64>,
    /// Strut pairs in contact: (force, gap).
    pairs: Vec<(f64, f64)>,
    reactions: Vec<f64>,
}

impl Recorder for Log {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &Constraints) -> RecordResult {
        self.recording = stage.name() == self.stage;
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.recording {
            let ground = f
                .contacts
                .iter()
                .filter(|c| matches!(c.touch, Touch::Ground(_)))
                .map(|c| c.normal * c.force)
                .sum();
            let pairs = f
                .contacts
                .iter()
                .filter(|c| matches!(c.touch, Touch::Struts(_)))
                .map(|c| (c.force, c.gap))
                .collect();
            self.frames.push(Logged {
                time: f.time,
                positions: f.positions.to_vec(),
                kinetic: f.energy.kinetic,
                contact: f.energy.contact,
                ground,
                pairs,
                reactions: f.reactions.to_vec(),
            });
        }
        Ok(())
    }
}

fn run(yaml: &str, stage: &'static str) -> (Log, CaseSummary) {
    let cfg = parse_case(yaml, "test.yaml").unwrap_or_else(|e| panic!("{e}"));
    let mut log = Log { stage, ..Log::default() };
    let summary = run_case(&cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
    (log, summary)
}

/// The bar: 1 m of steel (A = 1e-4 m², radius √(A/π)), massless, 1 kg at each end, its
/// axis at height `z`; `fix` supports of each end; `extra` appended to the config.
fn bar(z: f64, fix: &str, extra: &str) -> String {
    format!(
        "name: bar
model:
  nodes:
    - {{ id: a, xyz: [0, 0, {z}], fix: [{fix}] }}
    - {{ id: b, xyz: [1, 0, {z}], fix: [{fix}] }}
  members:
    - {{ id: bar, nodes: [a, b], kind: strut, rest_length: 1.0 }}
materials:
  steel: {{ law: {{ elastic: {{ youngs_modulus: 2.0e11 }} }}, area: 1.0e-4, density: 0.0 }}
substitution: {{ strut: steel, cable: steel }}
point_masses: [ {{ nodes: [a, b], mass: 1.0 }} ]
{extra}"
    )
}

fn radius() -> f64 {
    (1.0e-4 / std::f64::consts::PI).sqrt()
}

/// Dropped from rest 0.1 m (gap) under gravity onto the ground, 0.6 s (an impact and most
/// of a second fall), Δt = 1 and 0.5 ms: the ledger (kinetic + m g z + barrier) closes,
/// no energy is gained, and the rebound's apex is the drop height to the sampling of a
/// parabola's top, g Δt²/8.
#[test]
fn a_bar_dropped_on_the_ground_rebounds_to_its_drop_height() {
    let (h, g, m) = (0.1, 9.81, 2.0);
    for dt in [1e-3, 5e-4] {
        let extra = format!(
            "gravity: [0, 0, -{g}]
contact: {{ ground: {{}} }}
stages:
  - name: drop
    transient: {{ duration: 0.6, dt: {dt}, scheme: energy_momentum }}
"
        );
        let (log, _) = run(&bar(h + radius(), "", &extra), "drop");
        let gap = |f: &Logged| f.positions[0].z - radius();
        let e0 = m * g * h;
        let energy = |f: &Logged| f.kinetic + m * g * gap(f) + f.contact;
        // 1e-9 of m g h: the step equations are solved to 1e-10 of the force scale, and
        // the scheme's energy identity holds to that per step over 600–1200 steps.
        let gain = log.frames.iter().map(|f| energy(f) - e0).fold(f64::NEG_INFINITY, f64::max);
        assert!(gain <= 1e-9 * e0, "Δt {dt}: energy rose by {gain:e} J");
        let impact = log.frames.iter().position(|f| f.contact > 0.0).expect("the bar reaches the ground");
        let apex = log.frames[impact..].iter().map(gap).fold(0.0, f64::max);
        let sampling = g * dt * dt / 8.0;
        println!("Δt {dt}: rebound apex {apex:.12} m of {h} m, largest energy change {gain:.2e} J");
        assert!(apex <= h + 1e-9 * h && apex >= h - sampling - 1e-9 * h, "Δt {dt}: apex {apex}");
        assert!(log.frames.iter().all(|f| gap(f) > 0.0), "Δt {dt}: the bar entered the ground");
    }
}

/// Contact time of the bar arriving at 1 m/s without gravity, from gap 2ĝ: the energy
/// ½ M v² + 2 b(g) is kept, so the time spent below ĝ is T = 2 ∫_{g*}^{ĝ} dg / v(g),
/// v² = v0² − 4 b(g)/M, 2 b(g*) = ½ M v0² (two ends, each a barrier). The simulated
/// time (crossings of ĝ interpolated linearly) converges to it at second order.
#[test]
fn the_contact_time_is_the_barrier_law_s_at_second_order() {
    let (m, v0, energy) = (2.0_f64, 1.0_f64, 1.0_f64);
    let distance = 1e-2 * radius();
    let exact = contact_time(Barrier::with_energy(distance, energy), m, v0);
    let mut errors = Vec::new();
    for dt in [4e-6, 2e-6, 1e-6] {
        let extra = format!(
            "contact: {{ ground: {{}}, energy: {energy} }}
stages:
  - name: impact
    transient:
      duration: {}
      dt: {dt}
      scheme: energy_momentum
      initial: {{ velocity: [ {{ nodes: [a, b], value: [0, 0, -{v0}] }} ] }}
",
            2.0 * exact + 4.0 * distance / v0
        );
        let (log, _) = run(&bar(2.0 * distance + radius(), "", &extra), "impact");
        let gap: Vec<(f64, f64)> = log.frames.iter().map(|f| (f.time, f.positions[0].z - radius())).collect();
        let crossing = |w: &[(f64, f64)]| {
            let ((t0, g0), (t1, g1)) = (w[0], w[1]);
            t0 + (distance - g0) / (g1 - g0) * (t1 - t0)
        };
        let entry = gap
            .windows(2)
            .find(|w| w[0].1 >= distance && w[1].1 < distance)
            .map(crossing)
            .unwrap();
        let exit = gap
            .windows(2)
            .find(|w| w[0].1 < distance && w[1].1 >= distance)
            .map(crossing)
            .unwrap();
        let error = (exit - entry - exact).abs();
        println!(
            "Δt {dt:e}: contact time {:.6e} s, closed form {exact:.6e} s, error {error:.2e}",
            exit - entry
        );
        errors.push(error);
    }
    for w in errors.windows(2) {
        // Second order: halving Δt quarters the error; 3 allows the crossings' linear
        // interpolation (also second order) to shift the ratio.
        assert!(w[0] / w[1] > 3.0, "errors {errors:?}");
    }
    assert!(errors[2] < 1e-2 * exact, "errors {errors:?} of {exact:e}");
}

/// At rest on the ground under gravity (a static stage from a shape within the activation
/// distance, where the barrier already holds it: a static solve needs a stiffness along
/// every free direction; a held in x, y and b in y, so that no rigid motion is free): the
/// ground carries the weight to the solver's tolerance, and the supports nothing.
#[test]
fn a_bar_at_rest_on_the_ground_carries_its_weight_there() {
    let extra = "gravity: [0, 0, -9.81]
contact: { ground: {} }
stages:
  - name: rest
    static: {}
";
    let yaml = bar(0.5e-2 * radius() + radius(), "y", extra).replacen("fix: [y] }", "fix: [x, y] }", 1);
    let (log, _) = run(&yaml, "rest");
    let last = log.frames.last().unwrap();
    let weight = 2.0 * 9.81;
    // 1e-9: the static solve's force tolerance is 1e-10 of the force scale (the weight).
    assert!((last.ground.z / weight - 1.0).abs() < 1e-9, "ground {:?}", last.ground);
    assert!(last.reactions.iter().all(|r| r.abs() < 1e-9 * weight), "{:?}", last.reactions);
    let gap = last.positions[0].z - radius();
    assert!(gap > 0.0 && gap < 1e-2 * radius(), "gap {gap}");
}

/// Strut `low` along x held at both ends; strut `high` along y 0.2 m above it, its ends
/// driven 0.4 m down (through `low`, without contact; `high` free in z only, which the
/// fold prescribes, so the structure is a mechanism before: `allow_unstable`): the fold
/// stops short of contact, the gap open and less than a step's travel (0.05 m).
#[test]
fn a_strut_driven_across_another_stops_at_contact() {
    let (log, summary) = run(
        &cross(
            "folding: { steps: 8, prescribe: [ { group: driven, axis: z, displacement: -0.4 } ] }",
            0.2,
        ),
        "press",
    );
    let stopped = match &summary.stages["press"] {
        tsim::stage::sequence::StageSummary::Folding(f) => f.stopped_by_contact.clone(),
        other => panic!("{other:?}"),
    };
    let stopped = stopped.expect("the fold stops at contact");
    let gap = |f: &Logged| f.positions[2].z - 2.0 * radius();
    let last = log.frames.last().unwrap();
    println!("stopped at {:.4} of the fold, gap {:.3e} m", stopped.fraction, gap(last));
    assert!(stopped.fraction < 0.5, "{stopped:?}");
    assert!(log.frames.iter().all(|f| gap(f) > 0.0) && gap(last) < 0.05, "gap {}", gap(last));
}

/// The same struts, `high` pressed onto `low` by 100 N at each end (a static stage from
/// within the activation distance): the contact carries the 200 N, and `low`'s supports
/// take it back, each to the solver's tolerance.
#[test]
fn a_strut_pressed_onto_another_balances_through_the_contact() {
    let load = "static: { loads: [ { groups: [driven], force: [0, 0, -100] } ] }";
    let (log, _) = run(&cross(load, 2.0 * radius() + 0.5e-2 * radius()), "press");
    let last = log.frames.last().unwrap();
    let &(force, gap) = last.pairs.first().expect("the struts touch");
    println!("contact force {force:.9e} N at gap {gap:.3e} m");
    // Reactions: l0 x y z, l1 x y z, then h0 x y, h1 x y, in node order.
    let low = last.reactions[2] + last.reactions[5];
    // 1e-9 of the load: the static solve's tolerance is 1e-10 of the force scale.
    assert!((force / 200.0 - 1.0).abs() < 1e-9, "contact {force}");
    assert!((low - 200.0).abs() < 1e-9 * 200.0, "low's supports {low}");
    assert!(gap > 0.0 && gap < 1e-2 * radius(), "gap {gap}");
}

/// Strut `low` along x, held; strut `high` along y with its axis `height` above, its ends
/// held in x and y; `stage` the one stage, named `press`.
fn cross(stage: &str, height: f64) -> String {
    format!(
        "name: cross
model:
  nodes:
    - {{ id: l0, xyz: [-1, 0, 0], fix: [x, y, z] }}
    - {{ id: l1, xyz: [1, 0, 0], fix: [x, y, z] }}
    - {{ id: h0, xyz: [0, -1, {height}], fix: [x, y] }}
    - {{ id: h1, xyz: [0, 1, {height}], fix: [x, y] }}
  groups: {{ driven: [h0, h1] }}
  members:
    - {{ id: low, nodes: [l0, l1], kind: strut, rest_length: 2.0 }}
    - {{ id: high, nodes: [h0, h1], kind: strut, rest_length: 2.0 }}
materials:
  steel: {{ law: {{ elastic: {{ youngs_modulus: 2.0e11 }} }}, area: 1.0e-4, density: 0.0 }}
substitution: {{ strut: steel, cable: steel, allow_unstable: true }}
contact: {{}}
stages:
  - name: press
    {stage}
"
    )
}

/// The closed-form contact time of mass `m` (two ends, each on `barrier`) arriving at `v0`.
fn contact_time(barrier: Barrier, m: f64, v0: f64) -> f64 {
    let distance = barrier.distance;
    let b = |g: f64| barrier.at(g).map_or(0.0, |v| v.energy);
    // g*: bisection on 2 b(g) = ½ M v0².
    let (mut lo, mut hi) = (1e-12 * distance, distance);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 2.0 * b(mid) > 0.5 * m * v0 * v0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let g_star = 0.5 * (lo + hi);
    // g = g* + s²: dg / v = 2 s ds / v, finite at s = 0; Simpson on 20 000 panels.
    let speed = |g: f64| (v0 * v0 - 4.0 * b(g) / m).max(0.0).sqrt();
    let top = (distance - g_star).sqrt();
    let panels = 20_000;
    let f = |s: f64| {
        if s == 0.0 {
            2.0 / (-4.0 * barrier.at(g_star).unwrap().slope / m).sqrt()
        } else {
            2.0 * s / speed(g_star + s * s)
        }
    };
    let hs = top / panels as f64;
    let simpson: f64 = (0..=panels)
        .map(|k| {
            let w = if k == 0 || k == panels {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f(k as f64 * hs)
        })
        .sum::<f64>()
        * hs
        / 3.0;
    2.0 * simpson
}
