//! The main job, configs/sweep.yaml (the README's first command), is the sound paper case
//! swept over axes that change the result (issue 30): every case completes, deploys and
//! settles back to its pre-fold shape, and no two cases give the same deployment.

use std::process::Command;

#[test]
fn every_case_of_the_main_sweep_deploys_and_settles() {
    let out = tempfile::Builder::new().prefix("tsim-main-sweep-").tempdir().unwrap();
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/sweep.yaml");
    let status = Command::new(env!("CARGO_BIN_EXE_tsim"))
        .args(["run", config, "--quiet", "--out"])
        .arg(out.path())
        .args(["--jobs", "2"])
        .status()
        .unwrap();
    assert!(status.success(), "tsim run configs/sweep.yaml: {status}");
    let csv = std::fs::read_to_string(out.path().join("sweep/summary.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (status, shape, peak) = (column("status"), column("deploy_shape_error"), column("deploy_peak_kinetic_j"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 27);
    let mut peaks = Vec::new();
    for row in &rows {
        assert_eq!(row[status], "complete", "{}", row[0]);
        let error: f64 = row[shape].parse().unwrap();
        // Settled: within 1e-3 H of the pre-fold shape after the deployment (issue 30's
        // bound; measured at most 2.4e-4, steel struts with ζ = 0.15).
        assert!(error <= 1e-3, "{}: shape error {error} H", row[0]);
        peaks.push(row[peak].parse::<f64>().unwrap());
    }
    // Every axis changes the result: no two cases reach the same peak kinetic energy (the
    // fold-step axis this sweep had gave results equal to 7 digits).
    peaks.sort_by(f64::total_cmp);
    for w in peaks.windows(2) {
        assert!(w[1] - w[0] > 1e-6 * w[1], "two cases with peak kinetic energy {} J", w[0]);
    }
}
