//! Measurement for the issue-3 note: the paper case's eigenvalue table (as the paper's
//! Table 2) with both mass readings, the α, β that modes 3 and 20 give with ζ = 0.2, and
//! the whole pipeline with physical masses.
//!
//! `cargo run --release --example eigen_table [configs/paper.yaml]`

use tsim::config::{parse_case, CaseConfig, MassReading};
use tsim::dynamics::Rayleigh;
use tsim::pipeline::{run_case, StageSummary};
use tsim::record::NoRecorder;

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| "configs/paper.yaml".into());
    let text = std::fs::read_to_string(&path).unwrap();
    let cfg = parse_case(&text, &path).unwrap_or_else(|e| panic!("{e}"));

    let mut tables = Vec::new();
    for reading in [MassReading::Paper, MassReading::Physical] {
        // Eigen analysis only: the dynamic stages are not needed for the table.
        let eigen_only = CaseConfig {
            masses: reading,
            free_vibration: None,
            folding: None,
            deployment: None,
            ..cfg.clone()
        };
        let s = run_case(&eigen_only, &mut NoRecorder).unwrap_or_else(|e| panic!("{e}"));
        let e = s.eigen("eigen").expect("paper.yaml has an eigen section").clone();
        println!("== masses: {reading:?} (total {:.6} kg)", s.substitution.total_mass);
        let (w3, w20) = (e.omega2[2], e.omega2[19]);
        let r = Rayleigh::from_modes(w3.sqrt(), w20.sqrt(), 0.2, 0.2);
        println!(
            "mode 3: ω² = {w3:.6e}, mode 20: ω² = {w20:.6e} → ζ = 0.2: α = {:.6e} 1/s, β = {:.6e} s",
            r.alpha, r.beta
        );
        let cables = e.omega2.len() - 10;
        println!(
            "highest cable mode ω² = {:.6e}, lowest strut mode ω² = {:.6e}, ratio {:.3e}",
            e.omega2[cables - 1],
            e.omega2[cables],
            e.omega2[cables] / e.omega2[cables - 1]
        );
        tables.push(e);
    }
    println!("\nmode | ω² paper masses [rad²/s²] | f [Hz] | ω² physical masses [rad²/s²] | f [Hz]");
    for k in 0..tables[0].omega2.len() {
        let (a, b) = (&tables[0], &tables[1]);
        println!(
            "{:4} | {:.6e} | {:.6e} | {:.6e} | {:.6e}",
            k + 1,
            a.omega2[k],
            a.frequency_hz[k],
            b.omega2[k],
            b.frequency_hz[k]
        );
    }

    for reading in [MassReading::Paper, MassReading::Physical] {
        let full = CaseConfig {
            masses: reading,
            ..cfg.clone()
        };
        let t = std::time::Instant::now();
        let result = run_case(&full, &mut NoRecorder);
        let wall = t.elapsed();
        println!("\n== whole pipeline, masses {reading:?}: wall {wall:.3?}");
        match result {
            Ok(mut s) => {
                if let Some(StageSummary::Eigen(e)) = s.stages.get_mut("eigen") {
                    e.omega2.clear();
                    e.frequency_hz.clear();
                }
                println!("{}", serde_json::to_string_pretty(&s).unwrap());
            }
            Err(e) => println!("ERROR {e}"),
        }
    }
}
