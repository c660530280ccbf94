//! Eigen benchmark (not a test): the eigen analysis of the benchmark tower (12 struts per
//! stage, nominal geometry, aluminium struts and rubber cables; examples/common/tower.rs),
//! dense (every mode) or partial (the lowest MODES), printing one JSON line with the DOF
//! count, the wall time of the analysis and of the set-up, and the lowest ω².
//! `scripts/bench_eigen` runs it under `/usr/bin/time -v` for the peak RSS.
//!
//! Usage: bench_eigen STAGES [dense|partial] [MODES]

#[path = "common/tower.rs"]
mod tower;

use std::time::Instant;
use tsim::stage::eigen::{modes, EigenSolverChoice, ModeSolver, DEFAULT_PARTIAL_MODES};
use tsim::tsm::{Assembly, DofMap};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: bench_eigen STAGES [dense|partial] [MODES]";
    let stages: usize = args.get(1).and_then(|s| s.parse().ok()).expect(usage);
    let choice = match args.get(2).map(String::as_str) {
        Some("dense") => EigenSolverChoice::Dense,
        None | Some("partial") => EigenSolverChoice::Partial,
        Some(_) => panic!("{usage}"),
    };
    let count: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(DEFAULT_PARTIAL_MODES);
    let start = Instant::now();
    let structure = tower::nominal_tower(12, stages);
    let model = &structure.model;
    let dofs = DofMap::new(model, &[]);
    let asm = Assembly::new(model, &structure.elements, &dofs, model.positions());
    let mass = structure.free_masses(&dofs);
    let setup = start.elapsed().as_secs_f64();
    let solver = ModeSolver {
        choice,
        modes: count,
        shift: None,
    };
    let start = Instant::now();
    let m = modes(&asm, &mass, &solver).expect("eigen analysis of the benchmark tower");
    let eigen = start.elapsed().as_secs_f64();
    println!(
        "{{\"stages\": {stages}, \"dof\": {}, \"solver\": \"{choice:?}\", \"modes\": {}, \"eigen_s\": {eigen:.4}, \"setup_s\": {setup:.4}, \"omega2_1\": {:e}, \"omega2_last\": {:e}}}",
        dofs.len(),
        m.omega2.len(),
        m.omega2[0],
        m.omega2[m.omega2.len() - 1]
    );
}
