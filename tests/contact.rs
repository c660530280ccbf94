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
    /// Node velocities (zero in static stages) [m/s].
    velocities: Vec<Vector3<f64>>,
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
                velocities: f
                    .velocities
                    .map_or_else(|| vec![Vector3::zeros(); f.positions.len()], <[_]>::to_vec),
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
        let log = impact(dt, energy, v0, 2.0 * exact + 4.0 * distance / v0);
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

/// A quantity a user reads off a frame, by name.
type Quantity = (&'static str, fn(&Logged) -> f64);

/// The bar arriving at `v0` [m/s] on the ground from a gap of twice the activation
/// distance (1 % of its radius), no gravity, on a barrier of energy scale `energy`, for
/// `duration` in steps of `dt`.
fn impact(dt: f64, energy: f64, v0: f64, duration: f64) -> Log {
    let distance = 1e-2 * radius();
    let extra = format!(
        "contact: {{ ground: {{}}, energy: {energy} }}
stages:
  - name: impact
    transient:
      duration: {duration}
      dt: {dt}
      scheme: energy_momentum
      initial: {{ velocity: [ {{ nodes: [a, b], value: [0, 0, -{v0}] }} ] }}
"
    );
    run(&bar(2.0 * distance + radius(), "", &extra), "impact").0
}

/// The same impact, every quantity a user reads at the times the coarsest run records
/// (4 µs apart, 0.2 ms: before, through and after the 0.1 ms contact): the position, the
/// ground's force (the reaction), the kinetic and the barrier energy converge at second
/// order as Δt halves from 4 µs to 0.5 µs.
#[test]
fn the_impact_s_positions_forces_and_energies_converge_at_second_order() {
    let logs: Vec<Log> = [4e-6, 2e-6, 1e-6, 5e-7].iter().map(|&dt| impact(dt, 1.0, 1.0, 2e-4)).collect();
    let read: [Quantity; 4] = [
        ("position", |f| f.positions[0].z),
        ("ground force", |f| f.ground.z),
        ("kinetic energy", |f| f.kinetic),
        ("contact energy", |f| f.contact),
    ];
    for (what, value) in read {
        // Each run at the coarsest run's times (every 2^k-th frame of the k-th run).
        let at = |k: usize| -> Vec<f64> { logs[k].frames.iter().step_by(1 << k).map(value).collect() };
        let runs: Vec<Vec<f64>> = (0..logs.len()).map(at).collect();
        let differences: Vec<f64> = runs
            .windows(2)
            .map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
            .collect();
        let ratios: Vec<f64> = differences.windows(2).map(|d| d[0] / d[1]).collect();
        let shown: Vec<String> = differences.iter().map(|d| format!("{d:.3e}")).collect();
        println!("{what}: largest differences {shown:?}, ratios {ratios:.2?}");
        // Second order: 4 per halving; 3 allows for the pre-asymptotic coarsest pair.
        assert!(ratios.iter().all(|&r| r > 3.0), "{what}: {differences:?}");
    }
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

/// Two free struts (no support, no gravity, 1 kg at each end), `high` moving at 0.5 m/s
/// onto `low`'s middle and spinning about z, collide: the contact forces are central and
/// balanced, so linear and angular momentum are kept to round-off (Newton to round-off,
/// `force_tolerance: 0`), and the energy too (the discrete gradient's identity is exact
/// to O(Δx³) per step; here below round-off): equal masses in a central impact exchange
/// their velocities along the normal, `high` stops and `low` leaves at 0.5 m/s.
#[test]
fn two_free_struts_collide_keeping_momentum() {
    for dt in [2e-4, 1e-4] {
        let stage = format!(
            "transient:
      duration: 0.05
      dt: {dt}
      scheme: energy_momentum
      initial: {{ velocity: [ {{ nodes: [h0], value: [0.05, 0, -0.5] }}, {{ nodes: [h1], value: [-0.05, 0, -0.5] }} ] }}
newton: {{ force_tolerance: 0 }}"
        );
        let yaml = cross(&stage, 0.01 + 2.0 * radius())
            .replace(", fix: [x, y, z]", "")
            .replace(", fix: [x, y]", "")
            + "point_masses: [ { nodes: [l0, l1, h0, h1], mass: 1.0 } ]\n";
        let (log, summary) = run(&yaml, "press");
        let momentum = |f: &Logged| -> (Vector3<f64>, Vector3<f64>) {
            let p = f.velocities.iter().sum();
            let l = f.positions.iter().zip(&f.velocities).map(|(x, v)| x.cross(v)).sum();
            (p, l)
        };
        let (p0, l0) = momentum(&log.frames[0]);
        let drift = log.frames.iter().map(|f| {
            let (p, l) = momentum(f);
            ((p - p0).norm(), (l - l0).norm())
        });
        let (dp, dl) = drift.fold((0.0_f64, 0.0_f64), |(a, b), (p, l)| (a.max(p), b.max(l)));
        let touched = log.frames.iter().any(|f| !f.pairs.is_empty());
        let last = log.frames.last().unwrap();
        let (low, high) = (
            0.5 * (last.velocities[0].z + last.velocities[1].z),
            0.5 * (last.velocities[2].z + last.velocities[3].z),
        );
        let error = match &summary.stages["press"] {
            tsim::stage::sequence::StageSummary::Transient(t) => t.transient.max_balance_error,
            other => panic!("{other:?}"),
        };
        println!(
            "Δt {dt}: momentum drift {:.1e}, angular {:.1e} (relative), ledger {error:.2e} J, low {low:.9} m/s, high {high:.2e} m/s",
            dp / p0.norm(),
            dl / l0.norm()
        );
        // 1e-9 of the speed: what the energy's round-off (below) leaves of the exchange.
        assert!(
            touched && (low + 0.5).abs() < 0.5e-9 && high.abs() < 0.5e-9,
            "Δt {dt}: low {low}, high {high}"
        );
        // 1e-10: the issue-30 bound for the members' forces; the contacts' are as central.
        assert!(dp <= 1e-10 * p0.norm() && dl <= 1e-10 * l0.norm(), "Δt {dt}: {dp:e}, {dl:e}");
        // 1e-10 of the kinetic energy (0.25 J): round-off over the 250–500 steps.
        assert!(error <= 1e-10 * 0.25, "Δt {dt}: ledger {error:e} J");
    }
}
