//! Recorded member forces are the forces the members carry (issue 30): in a transient stage
//! `member_force` is the elastic force plus the viscous one, which is what balances the
//! reactions and what converges as Δt halves. The elastic part alone does neither: a
//! rotating stiff strut gets from Newmark a spurious axial rate of order Δt², which
//! β EA/l0 (≈ 5e5 N s/m on the paper's struts) turns into a large elastic swing that its
//! damping force cancels.

mod common;

use nalgebra::Vector3;
use tsim::config::{parse_case, CaseConfig, TimeStep};
use tsim::dynamics::Scheme;
use tsim::pipeline::run_case;
use tsim::record::{Constraints, Frame, ModelRecord, RecordResult, Recorder, Stage};

/// The deployment's frames: time, positions, total and viscous member forces, applied
/// loads, reactions; with the stage's constraints and the member end nodes.
#[derive(Default)]
struct Deployment {
    recording: bool,
    ends: Vec<[usize; 2]>,
    constraints: Option<Constraints>,
    frames: Vec<Logged>,
}

struct Logged {
    time: f64,
    positions: Vec<Vector3<f64>>,
    forces: Vec<f64>,
    viscous: Vec<f64>,
    applied: Vec<Vector3<f64>>,
    reactions: Vec<f64>,
}

impl Recorder for Deployment {
    fn model(&mut self, record: &ModelRecord) -> RecordResult {
        self.ends = record.model.members.iter().map(|m| m.nodes).collect();
        Ok(())
    }
    fn begin_stage(&mut self, stage: &Stage, constraints: &Constraints) -> RecordResult {
        self.recording = stage.name() == "deployment";
        if self.recording {
            self.constraints = Some(constraints.clone());
        }
        Ok(())
    }
    fn frame(&mut self, f: &Frame) -> RecordResult {
        if self.recording {
            self.frames.push(Logged {
                time: f.time,
                positions: f.positions.to_vec(),
                forces: f.forces.to_vec(),
                viscous: f.viscous_forces.expect("a transient frame has its viscous forces").to_vec(),
                applied: f.applied.to_vec(),
                reactions: f.reactions.to_vec(),
            });
        }
        Ok(())
    }
}

/// configs/paper.yaml (objective damping) with its deployment at `dt` for `duration`.
fn paper(dt: f64, duration: f64) -> CaseConfig {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/paper.yaml");
    let mut cfg = parse_case(&std::fs::read_to_string(path).unwrap(), path).unwrap();
    cfg.free_vibration = None;
    let deployment = cfg.deployment.as_mut().unwrap();
    (deployment.dt, deployment.duration) = (TimeStep::Fixed(dt), duration);
    cfg
}

fn deploy(cfg: &CaseConfig) -> Deployment {
    let mut log = Deployment::default();
    run_case(cfg, &mut log).unwrap_or_else(|e| panic!("{e}"));
    log
}

/// At every support direction the reaction is what the members' recorded forces put into
/// the support, less the load applied there: −Σ N e (e from the support's node to the
/// member's other end) − f. With the elastic force alone recorded (before), this missed
/// the viscous part, up to the largest viscous force itself; with the total it closes to
/// round-off. (Objective damping acts along each member, so its viscous force is all of a
/// member's damping force; the supports do not move, so no inertia enters.)
#[test]
fn recorded_member_forces_balance_the_reactions() {
    let log = deploy(&paper(0.001, 0.3));
    let constraints = log.constraints.as_ref().unwrap();
    let (mut worst, mut largest_viscous, mut largest) = (0.0_f64, 0.0_f64, 0.0_f64);
    for f in &log.frames {
        largest = f.forces.iter().fold(largest, |m, n| m.max(n.abs()));
        largest_viscous = f.viscous.iter().fold(largest_viscous, |m, n| m.max(n.abs()));
        let gap = common::reaction_gap(&log.ends, constraints, (&f.positions, &f.forces), (&f.applied, &f.reactions));
        worst = worst.max(gap);
    }
    // The launch makes the viscous forces large enough to matter.
    assert!(largest_viscous > 1.0, "largest viscous force {largest_viscous} N");
    // Round-off of sums of forces up to `largest` (~1e3 N) over a few members: 1e-9 of it.
    assert!(
        worst <= 1e-9 * largest,
        "reactions off the members' forces by {worst:.3e} N (largest force {largest:.1} N)"
    );
}

/// The paper deployment's strut forces at t = 0.13 s (the elastic force of one strut swung
/// from −7426 to −710 N over Δt = 2 … 0.125 ms) and the largest strut compression over the
/// launch converge at second order: each halving of Δt (1, 0.5, 0.25 ms) divides the
/// change by 4 (within ±0.5: measured 3.98 and 4.00 at t = 0.13 s, 3.82 and 4.00 for the
/// largest compression). The elastic part converges at second order too, but with an error
/// constant some 10⁴ times larger: at the shipped 0.5 ms it is 47 % off its limit, the total
/// 6e-5 and the largest compression 2e-5 (against the Richardson extrapolation of the
/// three). That is why `member_force` records the total.
#[test]
fn total_strut_forces_converge_at_second_order_in_dt() {
    let at = 0.13;
    let (mut total, mut elastic, mut largest) = (Vec::new(), Vec::new(), Vec::new());
    for dt in [0.001, 0.0005, 0.00025] {
        let log = deploy(&paper(dt, 0.3));
        let f = log
            .frames
            .iter()
            .min_by(|a, b| (a.time - at).abs().total_cmp(&(b.time - at).abs()))
            .unwrap();
        assert!((f.time - at).abs() < 1e-9, "a frame at t = {at}");
        // The most compressed member at that instant (a strut).
        let m = (0..f.forces.len()).min_by(|&a, &b| f.forces[a].total_cmp(&f.forces[b])).unwrap();
        total.push(f.forces[m]);
        elastic.push(f.forces[m] - f.viscous[m]);
        largest.push(log.frames.iter().flat_map(|f| f.forces.iter()).fold(0.0_f64, |c, &n| c.max(-n)));
    }
    let ratio = |v: &[f64]| (v[0] - v[1]) / (v[1] - v[2]);
    // The error of the 0.5 ms value against the second-order extrapolation of the three.
    let error_at_half_ms = |v: &[f64]| {
        let limit = v[2] + (v[2] - v[1]) / 3.0;
        ((v[1] - limit) / limit).abs()
    };
    for (what, v) in [("strut force at 0.13 s", &total), ("largest strut compression", &largest)] {
        let r = ratio(v);
        assert!((3.5..=4.5).contains(&r), "{what}: {v:?}, ratio {r:.3}");
        // 1e-3: the bound of 1 % with a margin of 10; measured 6e-5 and 2e-5.
        assert!(
            error_at_half_ms(v) < 1e-3,
            "{what}: {v:?}, {:.2e} off at 0.5 ms",
            error_at_half_ms(v)
        );
    }
    // Far from converged at the shipped step: measured 47 %.
    assert!(error_at_half_ms(&elastic) > 0.1, "{elastic:?}");
}

/// The energy–momentum form (`scheme: energy_momentum`) balances the step at its midpoint;
/// its recorded end forces are the elastic force of the end state and the viscous force
/// extrapolated from the balanced midpoints (`dynamics::MidpointEnds`: the end state's own
/// gives the rotating struts a spurious axial rate, 10.1 kN of a 10.2 kN largest strut force
/// at 2 ms on the whole deployment). Its largest strut compression over the launch and its
/// reactions during it converge at second order to Newmark's limit, and the reactions close
/// on the recorded forces as Newmark's do ([`recorded_member_forces_balance_the_reactions`]).
#[test]
fn energy_momentum_strut_forces_converge_and_balance_the_reactions() {
    let largest = |log: &Deployment| log.frames.iter().flat_map(|f| f.forces.iter()).fold(0.0_f64, |c, &n| c.max(-n));
    // The supports' reactions at t = 0.1 s, every Δt's grid point, during the launch.
    let reaction = |log: &Deployment| {
        let f = (log.frames.iter())
            .min_by(|a, b| (a.time - 0.1).abs().total_cmp(&(b.time - 0.1).abs()))
            .unwrap();
        assert!((f.time - 0.1).abs() < 1e-9);
        f.reactions.clone()
    };
    let (mut em, mut reactions) = (Vec::new(), Vec::new());
    for dt in [0.002, 0.001, 0.0005, 0.00025] {
        let mut cfg = paper(dt, 0.3);
        cfg.deployment.as_mut().unwrap().scheme = Scheme::EnergyMomentum;
        let log = deploy(&cfg);
        let constraints = log.constraints.as_ref().unwrap();
        let gap = (log.frames.iter())
            .map(|f| common::reaction_gap(&log.ends, constraints, (&f.positions, &f.forces), (&f.applied, &f.reactions)))
            .fold(0.0_f64, f64::max);
        em.push(largest(&log));
        reactions.push(reaction(&log));
        // As Newmark's: round-off of sums of forces up to ~1e3 N, 1e-9 of the largest.
        assert!(
            gap <= 1e-9 * em.last().unwrap(),
            "dt {dt}: reactions off the members' forces by {gap:.3e} N"
        );
    }
    let newmark = deploy(&paper(0.00025, 0.3));
    let (newmark, newmark_reactions) = (largest(&newmark), reaction(&newmark));
    let ratios = |d: &[f64]| d.windows(2).map(|w| w[0] / w[1]).collect::<Vec<f64>>();
    let force_ratios = ratios(&em.windows(2).map(|w| (w[0] - w[1]).abs()).collect::<Vec<_>>());
    // Reactions: the largest change over the supports per halving.
    let change = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let reaction_ratios = ratios(&reactions.windows(2).map(|w| change(&w[0], &w[1])).collect::<Vec<_>>());
    let off = change(&reactions[3], &newmark_reactions);
    println!(
        "energy-momentum largest strut compression {em:?} (ratios {force_ratios:.2?}; Newmark at 0.25 ms {newmark}); \
         reactions at 0.1 s: ratios {reaction_ratios:.2?} per halving, {off:.1e} N from Newmark's at 0.25 ms"
    );
    // Second order: 4 per halving (measured 4.74, 4.86 for the compression, 4.08, 3.84 for
    // the reactions); 3 to 6 excludes first order (2) and third (8). (The largest reaction
    // over the run is no measure of order: it falls on a corner of the reaction's history
    // at 0.119 s, which the steps sample at first order under Newmark too.) At 2 ms the
    // compression is within 1e-3 of Newmark's converged value (the 1 % with a
    // margin of 10; measured 1.4e-4; the end state's own viscous force was 13 times the force).
    assert!(
        force_ratios.iter().chain(&reaction_ratios).all(|r| (3.0..=6.0).contains(r)),
        "{force_ratios:?}, {reaction_ratios:?}"
    );
    assert!(((em[0] - newmark) / newmark).abs() < 1e-3, "{em:?} against {newmark}");
}
