//! Scale benchmark (not a test): Newmark steps on an n-strut, k-stage tower, printing one
//! JSON line with DOF count, wall time, Newton iterations, factorizations and peak memory.
//!
//! The tower starts from its generated (nominal) geometry with real materials: aluminium
//! struts at their nominal length and rubber cables prestressed to λ = 1.2. That shape is
//! not an equilibrium, so the tower moves from t = 0 under the prestress and a launch
//! load on the top ring: every step is a genuine nonlinear Newton solve with the same
//! TSM tangent as a deployment. (Form-finding a 1000-stage tower is a separate problem.)
//!
//! Usage: bench_scale STAGES [STEPS] [auto|dense|sparse]

#[path = "common/tower.rs"]
mod tower;

use nalgebra::Vector3;
use tsim::dynamics::{DampingTangent, LoadProfile, Loads, NewmarkParams, NodalLoad, Rayleigh};
use tsim::record::{NoRecorder, Stage, StageKind};
use tsim::solve::{LinearSolverChoice, NewtonSettings};
use tsim::stage::transient::{Initial, Transient};
use tsim::stage::{Analysis, Settings};
use tsim::structure::State;
use tsim::tsm::DofMap;

/// Peak resident memory of this process [MiB] (Linux VmHWM).
fn peak_rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let stages: usize = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .expect("usage: bench_scale STAGES [STEPS] [auto|dense|sparse]");
    let steps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100);
    let choice = match args.get(3).map(String::as_str) {
        Some("dense") => LinearSolverChoice::Dense,
        Some("sparse") => LinearSolverChoice::Sparse,
        _ => LinearSolverChoice::Auto,
    };
    let structure = tower::nominal_tower(12, stages);
    let x0 = structure.model.positions();
    let model = &structure.model;
    let dof = DofMap::new(model, &[]).len();
    let load = NodalLoad::launch(
        model.node_groups["top"].clone(),
        Vector3::new(0.0, 0.0, 95.0),
        0.05,
        LoadProfile::Step,
    );
    let transient = Transient {
        stage: Stage::new(StageKind::Transient, "deployment"),
        params: NewmarkParams {
            dt: 0.001,
            ..Default::default()
        },
        duration: steps as f64 * 0.001,
        rayleigh: Rayleigh {
            alpha: 1.612,
            beta: 0.0052,
        },
        tangent: DampingTangent::LastConverged,
        loads: Loads {
            nodal: vec![load],
            ground: None,
        },
        actuators: Vec::new(),
        initial: Initial::default(),
    };
    let settings = Settings {
        newton: NewtonSettings {
            linear_solver: choice,
            ..Default::default()
        },
        every: 1,
    };
    let setup_rss = peak_rss_mib();
    let (_, summary) = transient
        .run(&structure, State::at_rest(x0), &settings, &mut NoRecorder)
        .expect("benchmark run converges");
    println!(
        "{{\"stages\": {stages}, \"nodes\": {}, \"dof\": {dof}, \"solver\": \"{choice:?}\", \"steps\": {steps}, \"wall_s\": {:.4}, \"newton_iterations\": {}, \"factorizations\": {}, \"s_per_iteration\": {:.6e}, \"steps_per_s\": {:.2}, \"peak_rss_mib\": {:.1}, \"setup_rss_mib\": {setup_rss:.1}}}",
        model.node_count(),
        summary.wall_seconds,
        summary.newton_iterations,
        summary.factorizations,
        summary.wall_seconds / summary.newton_iterations as f64,
        steps as f64 / summary.wall_seconds,
        peak_rss_mib()
    );
}
