//! Cost of the equilibrium-matrix analysis (not a test): the full dense SVD of A, the
//! rigid-body and mechanism bases, Q and the stress matrix, on a 12-strut tower of k
//! stages at its nominal geometry (not an equilibrium: the size, not the mechanics, is
//! measured). Prints one JSON line: free DOFs, members, seconds (median of `reps`).
//!
//! Usage: bench_rigidity STAGES [REPS]

use std::time::Instant;
use tsim::model::generate::TowerSpec;
use tsim::rigidity::analyse;

fn main() {
    let mut args = std::env::args().skip(1);
    let stages: usize = args
        .next()
        .and_then(|a| a.parse().ok())
        .expect("usage: bench_rigidity STAGES [REPS]");
    let reps: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(3);
    let model = TowerSpec {
        struts: 12,
        stages,
        ..TowerSpec::paper()
    }
    .build();
    let x = model.positions();
    let mut seconds: Vec<f64> = (0..reps)
        .map(|_| {
            let start = Instant::now();
            let r = analyse(&model, &x, None).expect("within the dense limit");
            std::hint::black_box(r.rank);
            start.elapsed().as_secs_f64()
        })
        .collect();
    seconds.sort_by(f64::total_cmp);
    let dofs = 3 * model.node_count() - model.support_count();
    println!(
        "{{\"stages\": {stages}, \"dofs\": {dofs}, \"members\": {}, \"seconds\": {}}}",
        model.members.len(),
        seconds[reps / 2]
    );
}
