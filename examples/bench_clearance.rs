//! Clearance benchmark (not a test): the cost of following strut clearance through one
//! step (`Tracker::observe`: the nearest pair, touches, pass-throughs) on n-strut, k-stage
//! towers, testing all pairs against the grid. Prints one markdown table row per size.
//!
//! The towers stand in their generated geometry, twisted a little more at every step
//! (each node turned about the axis by 2e-4 rad per metre of height per step), so that
//! consecutive steps differ as in a stage; the steps are computed before the clock runs.
//! Both searches must find the same nearest pair and events: the run stops otherwise.
//!
//! Usage: bench_clearance [STRUTS] [STAGES ...]   (default: 8 struts, 2 10 25 50 100 stages)

use nalgebra::{Rotation3, Vector3};
use std::sync::Arc;
use std::time::Instant;
use tsim::model::clearance::{Search, Struts, Tracker};
use tsim::model::generate::TowerSpec;

/// Steps per timed pass; passes per search (the median is reported).
const STEPS: usize = 200;
const PASSES: usize = 5;

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("whole numbers")).collect();
    let struts = args.first().copied().unwrap_or(8);
    let stages = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        vec![2, 10, 25, 50, 100]
    };
    println!("| struts × stages | struts | all pairs [µs/step] | grid [µs/step] | all pairs / grid | nearest clearance [m] |");
    println!("|---|---|---|---|---|---|");
    for k in stages {
        let model = TowerSpec {
            struts,
            stages: k,
            ..TowerSpec::paper()
        }
        .build();
        // The paper's aluminium struts, A = 0.01 m².
        let radii = vec![(0.01 / std::f64::consts::PI).sqrt(); model.members.len()];
        let x0 = model.positions();
        let steps: Vec<Vec<Vector3<f64>>> = (0..STEPS)
            .map(|s| {
                x0.iter()
                    .map(|p| Rotation3::from_axis_angle(&Vector3::z_axis(), 2e-4 * p.z * s as f64) * p)
                    .collect()
            })
            .collect();
        let mut results = Vec::new();
        for search in [Search::AllPairs, Search::Grid] {
            let struts = Arc::new(Struts::new(&model, &radii, search));
            let mut times = Vec::new();
            let mut seen = Vec::new();
            for _ in 0..PASSES {
                let mut tracker = Tracker::new(struts.clone());
                seen.clear();
                let start = Instant::now();
                for (s, x) in steps.iter().enumerate() {
                    let nearest = tracker.observe(x, s, s as f64);
                    seen.push((nearest, tracker.events().len()));
                    tracker.clear_events();
                }
                times.push(start.elapsed().as_secs_f64() / STEPS as f64 * 1e6);
            }
            times.sort_by(f64::total_cmp);
            results.push((times[PASSES / 2], seen.clone()));
        }
        assert_eq!(results[0].1, results[1].1, "all pairs and grid disagree at {k} stages");
        let nearest = results[0].1[0].0.map_or(f64::NAN, |n| n.clearance);
        println!(
            "| {struts} × {k} | {} | {:.1} | {:.1} | {:.1} | {nearest:.4} |",
            struts * k,
            results[0].0,
            results[1].0,
            results[0].0 / results[1].0
        );
    }
}
