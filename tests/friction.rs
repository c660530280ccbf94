//! Capstan friction on clustered cables (issue 32): a rope over a fixed drum holds until
//! the tensions either side reach the Euler–Eytelwein ratio e^{μθ}, then slips at it; the
//! slipping state is the closed form's; μ → 0 is the frictionless cable; the tangent with
//! slipping pulleys (not symmetric) is the derivative of the force; the friction's
//! dissipation closes the energy ledger.
//!
//! Run with `cargo test --release --test friction`.

mod common;

use nalgebra::Vector3;
use std::f64::consts::PI;
use std::sync::Arc;
use tsim::law::{ForceLaw, LinearElastic, OgdenCord};
use tsim::model::Model;
use tsim::record::{Frame, RecordResult, Recorder, Stage};
use tsim::tsm::{Assembly, DofMap, Elements};

const CAPSTAN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/capstan.yaml");

/// The capstan's rope: prestress T0, EA, μ, the drum's radius and its seven pulleys'
/// turns (π/12 at the two ends of the wrap, π/6 between: π in all), as in capstan.yaml.
const T0: f64 = 1000.0;
const EA: f64 = 1.0e5;
const MU: f64 = 0.2;

fn turns() -> [f64; 7] {
    [PI / 12.0, PI / 6.0, PI / 6.0, PI / 6.0, PI / 6.0, PI / 6.0, PI / 12.0]
}

/// The capstan's state in full slip, in closed form, with the anchor end risen by `da`:
/// the tensions of the rope's eight spans (anchor side first) and the load on the free
/// end that holds it. Every pulley at its cone's edge: T_{j+1} = T_j e^{μθ_j}; the anchor
/// span's tension is its spring's (both vertical, the spring stretched by da); the rope's
/// total rest length is kept, Σ l_i/(1 + T_i/EA); the loaded span's length fixes the free
/// end's drop d_e, and the load is its tension less its spring's.
fn full_slip(da: f64) -> (Vec<f64>, f64) {
    let chord = 2.0 * 0.5 * (PI / 12.0).sin();
    let rest = |l: f64, t: f64| l / (1.0 + t / EA);
    let total = 2.0 * rest(1.0, T0) + 6.0 * rest(chord, T0);
    let spring = rest(1.0, T0);
    let t1 = EA * ((1.0 + da) / spring - 1.0);
    let mut tensions = vec![t1];
    let mut wrap = 0.0;
    for theta in turns() {
        wrap += theta;
        tensions.push(t1 * (MU * wrap).exp());
    }
    let held = rest(1.0 - da, t1) + (1..7).map(|j| rest(chord, tensions[j])).sum::<f64>();
    let drop = (total - held) * (1.0 + tensions[7] / EA) - 1.0;
    let load = tensions[7] - EA * ((1.0 - drop) / spring - 1.0);
    (tensions, load)
}

/// The anchor's rise at which the closed form's load is `p` (bisection: the load grows
/// with the rise), and its tensions.
fn full_slip_under(p: f64) -> Vec<f64> {
    let (mut lo, mut hi) = (0.0, 0.5);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if full_slip(mid).1 < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    full_slip(lo).0
}

/// One frame: the load down on the nodes (the `pull` stage's) or the time (`drop`'s),
/// member forces, positions, reactions and the energies.
type Kept = (f64, Vec<f64>, Vec<Vector3<f64>>, Vec<f64>, tsim::record::Energy);

/// Each frame of the stage `keep`.
struct Pull {
    keep: &'static str,
    stage: String,
    frames: Vec<Kept>,
}

impl Recorder for Pull {
    fn begin_stage(&mut self, stage: &Stage, _: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage == self.keep {
            let load = -f.applied.iter().map(|a| a.z).sum::<f64>();
            let at = if self.keep == "pull" { load } else { f.time };
            self.frames
                .push((at, f.forces.to_vec(), f.positions.to_vec(), f.reactions.to_vec(), f.energy));
        }
        Ok(())
    }
}

fn capstan() -> tsim::config::CaseConfig {
    capstan_in(30)
}

/// capstan.yaml with its pull in `steps` steps.
fn capstan_in(steps: usize) -> tsim::config::CaseConfig {
    let text = std::fs::read_to_string(CAPSTAN).unwrap();
    assert!(text.contains("steps: 30"), "capstan.yaml pulls in 30 steps");
    let text = text.replace("steps: 30", &format!("steps: {steps}"));
    tsim::config::parse_case(&text, CAPSTAN).unwrap_or_else(|e| panic!("{e}"))
}

/// The frames of stage `keep` of `cfg`'s run.
fn run(cfg: &tsim::config::CaseConfig, keep: &'static str) -> Pull {
    let mut out = Pull {
        keep,
        stage: String::new(),
        frames: Vec::new(),
    };
    tsim::pipeline::run_case(cfg, &mut out).unwrap_or_else(|e| panic!("{e}"));
    assert!(!out.frames.is_empty(), "the {keep} stage recorded");
    out
}

fn pull(cfg: &tsim::config::CaseConfig) -> Pull {
    run(cfg, "pull")
}

/// configs/examples/capstan.yaml: 3 kN pulled down on the rope's free end in 30 steps.
/// - Below the closed form's onset load (full_slip(0): 2358.2 N, the anchor end at rest
///   and every pulley at its cone's edge), the anchor span keeps T0 exactly (1e-12: the
///   pulleys next to it hold) — the pulleys near the load slip first (a drum of seven
///   pulleys slips from the loaded side in, the discrete form of the capstan's creep
///   zone), so the loaded span's tension is not the stuck rope's T0 + P/2.
/// - Above it, the rope slips round at T_last/T_first = e^{μπ} = 1.874 (1e-12 relative:
///   the return map solves the cone's edge to round-off), and every tension equals the
///   closed form's state under that load to 1e-9 (Newton's force tolerance against 1 kN
///   tensions; measured 3e-14).
/// - The ledger: the load's work is the strain energy plus what the pulleys dissipated,
///   to 1e-6 of the work (the trapezoidal rule's O(step²) error; measured 2.7e-7 of it),
///   the dissipation grows, and the gap falls at second order as the steps halve (> 3 per
///   halving; measured 4.06, 4.05 from 30 to 60 to 120 steps).
#[test]
fn capstan_holds_to_euler_eytelwein_then_slips_at_it() {
    let out = pull(&capstan());
    let onset = full_slip(0.0).1;
    assert!((2000.0..3000.0).contains(&onset), "onset within the pull: {onset}");
    let ratio = (MU * PI).exp();
    let (mut stuck, mut slipping) = (0, 0);
    for (p, forces, ..) in &out.frames {
        let rope = &forces[1..9];
        if *p < onset {
            assert!((rope[0] - T0).abs() <= 1e-12 * T0, "P = {p}: anchor span {} against T0", rope[0]);
            assert!(rope[7] / rope[0] < ratio, "P = {p}: inside the cone");
            stuck += 1;
        } else {
            assert!(
                (rope[7] / rope[0] / ratio - 1.0).abs() <= 1e-12,
                "P = {p}: ratio {} against e^(μπ) = {ratio}",
                rope[7] / rope[0]
            );
            let expected = full_slip_under(*p);
            for (t, e) in rope.iter().zip(&expected) {
                assert!((t - e).abs() <= 1e-9 * e, "P = {p}: tension {t} against the closed form's {e}");
            }
            slipping += 1;
        }
    }
    assert!(
        stuck >= 20 && slipping >= 6,
        "both regimes stepped through: {stuck} stuck, {slipping} slipping"
    );
    let last = out.frames.last().unwrap().4;
    assert!(last.damping > 1.0, "the pulleys dissipated {} J", last.damping);
    let gap = (last.external - last.strain - last.damping).abs();
    eprintln!(
        "onset {onset:.1} N; {stuck} stuck and {slipping} slipping steps; dissipated {:.4} J; ledger gap {gap:.2e} of {:.3} J",
        last.damping, last.external
    );
    assert!(gap <= 1e-6 * last.external, "ledger gap {gap:e} J of {} J", last.external);
    let dissipated: Vec<f64> = out.frames.iter().map(|f| f.4.damping).collect();
    assert!(
        dissipated.windows(2).all(|w| w[1] >= w[0]),
        "friction only dissipates: {dissipated:?}"
    );
    let gaps: Vec<f64> = [30, 60, 120]
        .iter()
        .map(|&n| {
            let e = pull(&capstan_in(n)).frames.last().unwrap().4;
            (e.external - e.strain - e.damping).abs()
        })
        .collect();
    eprintln!("ledger gaps at 30, 60, 120 steps: {gaps:?}");
    assert!(gaps.windows(2).all(|w| w[0] > 3.0 * w[1]), "second order in the step: {gaps:?}");
}

/// μ → 0 is the frictionless cable: the capstan pulled with μ = 1e-2, 1e-3, 1e-4 ends
/// within O(μ) of the same rope without friction (positions and forces), each decade of μ
/// a decade closer (ratio 10 ± 20 %: the cone's width e^{μθ} − 1 is linear in μ; measured
/// 9.98–10.00), and no force further off than the cone's width allows (measured 0.24 N at
/// μ = 1e-4 against 0.64 N).
#[test]
fn friction_vanishing_is_the_frictionless_cable() {
    let end = |mu: Option<f64>| {
        let mut cfg = capstan();
        cfg.model.clusters[0].friction = mu;
        let out = pull(&cfg);
        let (_, forces, x, ..) = out.frames.last().unwrap().clone();
        (forces, x)
    };
    let (f0, x0) = end(None);
    let gaps: Vec<(f64, f64)> = [1e-2, 1e-3, 1e-4]
        .iter()
        .map(|&mu| {
            let (f, x) = end(Some(mu));
            let dx = x.iter().zip(&x0).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            let df = f.iter().zip(&f0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            (dx, df)
        })
        .collect();
    eprintln!("{gaps:?}");
    for w in gaps.windows(2) {
        for (coarse, fine, what) in [(w[0].0, w[1].0, "positions"), (w[0].1, w[1].1, "forces")] {
            let r = coarse / fine;
            assert!((8.0..12.0).contains(&r), "{what}: gap falls {r} per decade of μ ({gaps:?})");
        }
    }
    // And within the cone's width: no tension is off by more than (e^{μπ} − 1) × the
    // largest (2.03 kN).
    let largest = f0.iter().fold(0.0_f64, |m, f| m.max(f.abs()));
    for (mu, (_, df)) in [1e-2, 1e-3, 1e-4].iter().zip(&gaps) {
        assert!(
            *df <= ((mu * PI).exp() - 1.0) * largest,
            "μ = {mu}: forces within the cone: {gaps:?}"
        );
    }
}

/// The zig-zag cable of `common::zigzag` with friction μ = 0.3 and `law`, committed at
/// rest lengths shared out so unevenly that, at the moved shape, some pulleys slip and one
/// sticks.
fn zigzag(law: Arc<dyn ForceLaw>) -> (Model, Elements, Vec<Vector3<f64>>) {
    let (m, moved) = common::zigzag(0.3);
    let x = m.positions();
    let stretch = [0.90, 0.97, 0.91, 0.80, 0.9, 0.9, 0.9];
    let rest = (m.members.iter().zip(stretch))
        .map(|(mem, s)| s * (x[mem.nodes[1]] - x[mem.nodes[0]]).norm())
        .collect();
    let elements = Elements { laws: vec![law; 7], rest };
    (m, elements, moved)
}

/// K_T with slipping pulleys against central differences of the internal force (the
/// return map from the same committed rest lengths at every perturbed shape), for a linear
/// and a hyperelastic law: < 1e-7 of the largest entry (step h = 1e-6 m: truncation
/// h² |p'''| and cancellation ε |p|/h both ~1e-10 of it). The state has slipping and stuck
/// pulleys (asserted), and the tangent is not symmetric. Without the wrap angle's gradient
/// (the e^{μθ} ratio moving with the pulleys) it is wrong by 1.3e-2 of it (measured,
/// elastic), so the check sees that term.
#[test]
fn friction_tangent_is_the_derivative_of_the_force() {
    let laws: [(&str, Arc<dyn ForceLaw>); 2] = [
        (
            "elastic",
            Arc::new(LinearElastic {
                ea: 2.0e5,
                tension_only: true,
            }),
        ),
        ("ogden", Arc::new(OgdenCord::new(OgdenCord::paper_terms(), 1e-4, 0.9, 0.5))),
    ];
    for (name, law) in laws {
        let (m, elements, x) = zigzag(law);
        let dofs = DofMap::new(&m, &[]);
        let asm = Assembly::new(&m, &elements, &dofs, x.clone());
        let slip = asm.friction.as_ref().unwrap().slip[0].clone();
        assert!(
            slip.iter().any(|&s| s != 0) && slip.contains(&0),
            "{name}: slipping and stuck pulleys: {slip:?}"
        );
        assert!(!asm.symmetric_tangent(), "{name}: a slipping pulley's tangent is not symmetric");
        let (k, worst) = common::tangent_check(&m, &elements, &x, 1e-6, |_, plus, minus| {
            for a in [plus, minus] {
                assert_eq!(a.friction.as_ref().unwrap().slip[0], slip, "{name}: the same pulleys slip at ± h");
            }
        });
        let n = k.len();
        let scale = k.iter().flatten().fold(0.0_f64, |s, v| s.max(v.abs()));
        eprintln!("{name}: K_T against differences of p: {worst:.2e} of the largest entry; slip {slip:?}");
        assert!(
            worst < 1e-7,
            "{name}: K_T against differences of p: {worst:.2e} of the largest entry"
        );
        let skew = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .fold(0.0_f64, |s, (i, j)| s.max((k[i][j] - k[j][i]).abs()));
        assert!(skew > 1e-6 * scale, "{name}: skew part {skew:e} of {scale:e}");
    }
}

/// How far apart two runs' frames are in one quantity.
type Difference = fn(&Kept, &Kept) -> f64;

/// The largest magnitude of `v`.
fn largest(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0_f64, |m, d| m.max(d.abs()))
}

/// The capstan's `drop` stage (2.5 kN on the rope's end from t = 0, 10 kg on each end,
/// undamped Newmark; the rope slips and sticks as the end swings) at Δt = 1, 0.5, 0.25,
/// 0.125 ms:
/// - the ledger KE + SE + D − W (D the pulleys' dissipation) closes to 1e-5 of the load's
///   work at 0.5 ms (measured 1.8e-6 of 23.3 J) and falls at second order (> 3 per
///   halving; measured 3.87, 3.94, 4.23);
/// - positions, member forces, reactions, kinetic and strain energy and the dissipation at
///   t = 0.02, 0.05, 0.1 s converge: the differences of successive halvings fall by more
///   than 2 each time and by more than 3.5 at 0.02 s, before the first stick. Measured:
///   3.7–4.2 at 0.02 s, 2.4–15.7 later — a pulley switching between stick and slip inside
///   a step makes that step's path non-smooth, so the ratios scatter about 4 there rather
///   than sit on it (a finding, not tuned away: the per-halving assertion is the weaker
///   one). Over two halvings together every quantity falls by more than 12 (second order:
///   16; measured 15.9–71).
#[test]
fn dropped_capstan_converges_and_its_ledger_closes() {
    let runs: Vec<Vec<Kept>> = [0.001, 0.0005, 0.00025, 0.000125]
        .iter()
        .map(|dt| {
            let text = std::fs::read_to_string(CAPSTAN).unwrap();
            assert!(text.contains("dt: 0.0005"), "capstan.yaml drops at dt 0.5 ms");
            let text = text.replace("dt: 0.0005", &format!("dt: {dt}"));
            let cfg = tsim::config::parse_case(&text, CAPSTAN).unwrap_or_else(|e| panic!("{e}"));
            run(&cfg, "drop").frames
        })
        .collect();
    let ledger = |f: &[Kept]| {
        let e = |k: &Kept| k.4.kinetic + k.4.strain + k.4.damping - k.4.external;
        (e(f.last().unwrap()) - e(&f[0])).abs()
    };
    let gaps: Vec<f64> = runs.iter().map(|f| ledger(f)).collect();
    let work = runs[1].last().unwrap().4.external;
    eprintln!("ledger gaps at Δt = 1, 0.5, 0.25, 0.125 ms: {gaps:?} (work {work} J)");
    assert!(gaps[1] <= 1e-5 * work, "ledger at 0.5 ms: {} of {work} J", gaps[1]);
    assert!(gaps.windows(2).all(|w| w[0] > 3.0 * w[1]), "ledger second order: {gaps:?}");
    assert!(
        runs[1].last().unwrap().4.damping > 10.0,
        "the rope slipped: dissipated {} J",
        runs[1].last().unwrap().4.damping
    );
    for t in [0.02, 0.05, 0.1] {
        let at: Vec<&Kept> = runs
            .iter()
            .map(|f| f.iter().min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs())).unwrap())
            .collect();
        assert!(at.iter().all(|k| (k.0 - t).abs() < 1e-9), "a frame at t = {t}");
        let quantities: [(&str, Difference); 6] = [
            ("positions", |a, b| largest(a.2.iter().zip(&b.2).map(|(p, q)| (p - q).norm()))),
            ("forces", |a, b| largest(a.1.iter().zip(&b.1).map(|(p, q)| p - q))),
            ("reactions", |a, b| largest(a.3.iter().zip(&b.3).map(|(p, q)| p - q))),
            ("kinetic", |a, b| a.4.kinetic - b.4.kinetic),
            ("strain", |a, b| a.4.strain - b.4.strain),
            ("dissipation", |a, b| a.4.damping - b.4.damping),
        ];
        for (what, diff) in quantities {
            let d: Vec<f64> = at.windows(2).map(|w| diff(w[0], w[1]).abs()).collect();
            let ratios: Vec<f64> = d.windows(2).map(|w| w[0] / w[1]).collect();
            eprintln!("t = {t}: {what}: differences {d:?}, ratios {ratios:.2?}");
            let floor = if t < 0.03 { 3.5 } else { 2.0 };
            assert!(ratios.iter().all(|&r| r > floor), "t = {t}: {what} converges: ratios {ratios:?}");
            assert!(d[0] > 12.0 * d[2], "t = {t}: {what} second order over two halvings: {d:?}");
        }
    }
}

/// The capstan's `reel` stage (a `hold`: the pulled rope's rest length cut by 1 % in 20,
/// 40, 80 static steps under the 3 kN): the ledger SE + D − W − W_a closes to 1e-5 of the
/// winch's work at 20 steps (measured 1.6e-6 of 66.8 J) and falls at second order (> 3
/// per halving; measured 4.00, 4.00); the pulleys dissipate at every step (the friction's
/// work kept out of the winch's), 0.74 J in all.
#[test]
fn reeled_capstan_ledger_splits_winch_and_friction() {
    let runs: Vec<Vec<Kept>> = [20, 40, 80]
        .iter()
        .map(|n| {
            let text = std::fs::read_to_string(CAPSTAN).unwrap();
            assert!(text.contains("steps: 20"), "capstan.yaml reels in 20 steps");
            let text = text.replace("steps: 20", &format!("steps: {n}"));
            let cfg = tsim::config::parse_case(&text, CAPSTAN).unwrap_or_else(|e| panic!("{e}"));
            run(&cfg, "reel").frames
        })
        .collect();
    let gap = |f: &[Kept]| {
        let e = |k: &Kept| k.4.strain + k.4.damping - k.4.external - k.4.actuation;
        (e(f.last().unwrap()) - e(&f[0])).abs()
    };
    let gaps: Vec<f64> = runs.iter().map(|f| gap(f)).collect();
    let last = runs[0].last().unwrap().4;
    eprintln!(
        "ledger gaps at 20, 40, 80 steps: {gaps:?}; winch {} J, friction {} J",
        last.actuation, last.damping
    );
    assert!(
        gaps[0] <= 1e-5 * last.actuation.abs(),
        "ledger {gaps:?} of the winch's {} J",
        last.actuation
    );
    assert!(gaps.windows(2).all(|w| w[0] > 3.0 * w[1]), "second order: {gaps:?}");
    let dissipated: Vec<f64> = runs[0].iter().map(|k| k.4.damping).collect();
    assert!(
        dissipated.windows(2).all(|w| w[1] > w[0]),
        "the pulleys dissipate at every step: {dissipated:?}"
    );
}

/// Folding and eigen commit and read the pulleys' state as statics does. The capstan's end
/// pulled down by prescribed displacement (a `folding` stage of 30 steps) to where the
/// `pull` left it ends in the same state (every tension within 1e-9 of the pull's end:
/// both are the full-slip state of that drop, which the closed form fixes whatever the
/// path). And an `eigen` stage after the pull takes the pulleys as stuck (small vibrations
/// do not overcome friction): each end node bounces on its spring and its span alone,
/// ω² = (k_spring + k_span)/m (k = EA/l0 at the pull's rest lengths, m the 10 kg and the
/// members' lumped halves), to 1e-9.
#[test]
fn folding_and_eigen_read_the_pulleys_like_statics() {
    let pulled = pull(&capstan());
    let (_, pulled_forces, x, ..) = pulled.frames.last().unwrap().clone();
    let drop = -1.0 - x[9].z;
    let text = std::fs::read_to_string(CAPSTAN).unwrap();
    let stages = format!(
        "  - name: fold\n    from: equilibrium\n    folding:\n      steps: 30\n      prescribe:\n        - {{ group: end, axis: z, displacement: {} }}\n  - name: modes\n    from: pull\n    eigen: {{}}\n",
        -drop
    );
    let text = text.replace("  - name: reel\n", &format!("{stages}  - name: reel\n"));
    let cfg = tsim::config::parse_case(&text, CAPSTAN).unwrap_or_else(|e| panic!("{e}"));
    let folded = run(&cfg, "fold");
    let (_, forces, ..) = folded.frames.last().unwrap();
    for (f, p) in forces.iter().zip(&pulled_forces).skip(1).take(8) {
        assert!((f - p).abs() <= 1e-9 * p, "folded {f} against pulled {p}");
    }
    let mut modes = Modes::default();
    tsim::pipeline::run_case(&cfg, &mut modes).unwrap_or_else(|e| panic!("{e}"));
    let rest = modes.rest_after_pull;
    let k = |m: usize| EA / rest[m];
    // Masses are lumped from the rest lengths the structure starts with (1 m / 1.01 for the
    // springs and the end spans), 1000 kg/m³ × 1e-4 m².
    let mass = 10.0 + 0.5 * 1000.0 * 1e-4 * 2.0 / 1.01;
    let mut expected = [(k(0) + k(1)) / mass, (k(8) + k(9)) / mass];
    expected.sort_by(f64::total_cmp);
    eprintln!("ω² {:?} against stuck {expected:?}", modes.omega2);
    for (w, e) in modes.omega2.iter().zip(&expected) {
        assert!((w - e).abs() <= 1e-9 * e, "ω² {w} against the stuck pulleys' {e}");
    }
}

/// The `modes` stage's ω² and the rest lengths at the end of the `pull`.
#[derive(Default)]
struct Modes {
    stage: String,
    omega2: Vec<f64>,
    rest_after_pull: Vec<f64>,
}

impl Recorder for Modes {
    fn begin_stage(&mut self, stage: &Stage, _: &tsim::record::Constraints) -> RecordResult {
        self.stage = stage.name().to_string();
        Ok(())
    }

    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.stage == "pull" {
            self.rest_after_pull = f.rest_lengths.expect("a clustered structure's frames carry rest lengths").to_vec();
        }
        Ok(())
    }

    fn eigen(&mut self, record: &tsim::record::EigenRecord) -> RecordResult {
        self.omega2 = record.omega2.to_vec();
        Ok(())
    }
}

/// Friction that cannot be run is refused with the place and the fix: a negative μ and a
/// closed loop with friction at load (`file:line` of `model.clusters[0]`), the midpoint
/// rule and β damping when the transient runs (naming the cable and what to use).
#[test]
fn friction_errors_name_the_cable_and_the_fix() {
    let text = std::fs::read_to_string(CAPSTAN).unwrap();
    let line = "    - { id: rope, members: [c0, c1, c2, c3, c4, c5, c6, c7], friction: 0.2 }";
    assert!(text.contains(line));
    let at = text[..text.find(line).unwrap()].lines().count() + 1;
    let refused = |text: &str| match tsim::run::expand(text, "bad.yaml", false) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    let negative = text.replace("friction: 0.2 }", "friction: -0.1 }");
    common::assert_field_errors(
        &refused(&negative),
        "bad.yaml",
        &[(at, "model.clusters[0]", "friction -0.1 is not a coefficient: give μ ≥ 0")],
    );
    let prism = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/examples/prism_cluster.yaml")).unwrap();
    let ring = "    - { id: top_ring, members: [ct0, ct1, ct2] }";
    assert!(prism.contains(ring));
    let ring_at = prism[..prism.find(ring).unwrap()].lines().count() + 1;
    let looped = prism.replace(ring, "    - { id: top_ring, members: [ct0, ct1, ct2], friction: 0.1 }");
    common::assert_field_errors(
        &refused(&looped),
        "bad.yaml",
        &[(ring_at, "model.clusters[0]", "a closed loop with friction is not supported")],
    );
    let run = |text: &str| {
        let cfg = tsim::config::parse_case(text, CAPSTAN).unwrap_or_else(|e| panic!("{e}"));
        tsim::pipeline::run_case(&cfg, &mut tsim::record::NoRecorder)
            .map(|_| ())
            .expect_err("refused")
            .to_string()
    };
    let midpoint = text.replace("      dt: 0.0005\n", "      dt: 0.0005\n      scheme: midpoint\n");
    let e = run(&midpoint);
    assert!(
        e.contains("drop") && e.contains("`rope` has pulley friction, which the midpoint rule does not take yet; use `scheme: newmark`"),
        "{e}"
    );
    let damped = text.replace(
        "  - name: drop\n",
        "  - name: modes\n    eigen: { rayleigh: { modes: [1, 2], ratios: [0.02, 0.02] } }\n  - name: drop\n",
    );
    let damped = damped.replace("      dt: 0.0005\n", "      dt: 0.0005\n      rayleigh_from: modes\n");
    let e = run(&damped);
    assert!(
        e.contains("drop") && e.contains("stiffness-proportional (β) damping is not written for it yet"),
        "{e}"
    );
}

/// Friction is objective: the zig-zag cable with slipping and stuck pulleys, moved as a
/// rigid body (turned 0.7 rad about an oblique axis and shifted), returns the same
/// distribution of rest lengths, the same pulleys slipping, and internal forces turned with
/// it (to 1e-12 of the largest: round-off of lengths and angles, which a rigid motion keeps).
#[test]
fn friction_is_objective() {
    let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
        ea: 2.0e5,
        tension_only: true,
    });
    let (m, elements, x) = zigzag(law);
    let rotation = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(0.3, -1.0, 0.5)), 0.7);
    let shift = Vector3::new(2.0, -1.0, 0.5);
    let moved: Vec<Vector3<f64>> = x.iter().map(|p| rotation * p + shift).collect();
    let all = DofMap::new(&m, &[]);
    let (a, b) = (
        Assembly::new(&m, &elements, &all, x.clone()),
        Assembly::new(&m, &elements, &all, moved),
    );
    let slip = |asm: &Assembly| asm.friction.as_ref().unwrap().slip[0].clone();
    assert_eq!(slip(&a), slip(&b), "the same pulleys slip");
    assert!(slip(&a).iter().any(|&s| s != 0), "some pulley slips: {:?}", slip(&a));
    let largest = a.p.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
    for n in 0..m.node_count() {
        let (pa, pb) = (
            Vector3::from_column_slice(&a.p[3 * n..3 * n + 3]),
            Vector3::from_column_slice(&b.p[3 * n..3 * n + 3]),
        );
        assert!(
            (rotation * pa - pb).norm() <= 1e-12 * largest,
            "node {n}: {pa:?} turned against {pb:?}"
        );
    }
    for (ra, rb) in a.rest.iter().zip(&b.rest) {
        assert!((ra - rb).abs() <= 1e-12 * ra, "rest length {ra} against {rb}");
    }
}
