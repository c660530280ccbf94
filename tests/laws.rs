//! Every force law: force = d(energy)/dl, stiffness = dN/dl, curvature = d²N/dl², dN/dl0
//! and dU/dl0 by central differences;
//! the Ogden curve against the reference table of notes.md; the compression branch.

use tsim::law::{ogden_nominal_stress, ForceLaw, LinearElastic, MeasurePotential, OgdenCord};

/// Central differences with step h: truncation O(h²·f'''), round-off O(ε·f/h). With
/// h = 1e-6·l both stay below ~1e-8 relative for these smooth laws.
fn check_derivatives(law: &dyn ForceLaw, l0: f64, lengths: &[f64]) {
    for &l in lengths {
        let h = 1e-6 * l;
        let e = law.eval(l, l0);
        let de = (law.energy(l + h, l0) - law.energy(l - h, l0)) / (2.0 * h);
        let dn = (law.eval(l + h, l0).force - law.eval(l - h, l0).force) / (2.0 * h);
        let scale_f = e.force.abs().max(1e-12 * law.eval(2.0 * l0.max(1.0), l0).force.abs()).max(1e-300);
        assert!(
            (de - e.force).abs() <= 1e-7 * scale_f,
            "{}: dE/dl {de} vs N {} at l={l}",
            law.name(),
            e.force
        );
        let scale_k = e.stiffness.abs().max(1e-300);
        assert!(
            (dn - e.stiffness).abs() <= 1e-6 * scale_k,
            "{}: dN/dl {dn} vs k {} at l={l}",
            law.name(),
            e.stiffness
        );
        // The curvature against differences of the stiffness: the same budget one
        // derivative up; its scale is the stiffness over the length (a linear law has
        // curvature 0, and then the difference must vanish to round-off of k/l).
        let dk = (law.eval(l + h, l0).stiffness - law.eval(l - h, l0).stiffness) / (2.0 * h);
        let scale_c = e.curvature.abs().max(1e-6 * e.stiffness.abs() / l).max(1e-300);
        assert!(
            (dk - e.curvature).abs() <= 1e-6 * scale_c,
            "{}: d²N/dl² {dk} vs {} at l={l}",
            law.name(),
            e.curvature
        );
        let dr = (law.eval(l, l0 + h).force - law.eval(l, l0 - h).force) / (2.0 * h);
        let r = law.d_force_d_rest(l, l0);
        assert!(
            (dr - r).abs() <= 1e-6 * r.abs().max(1e-300),
            "{}: dN/dl0 {dr} vs {r} at l={l}",
            law.name()
        );
        // ∂U/∂l0, the actuator's work per metre of rest length: the budget of dE/dl
        // above, on the scale of the force (∂U/∂l0 is a force, −N to first order), plus
        // twice the difference's own truncation error, estimated by Richardson from the
        // difference at 2h (U is not symmetric in l0 about l: at l = l0 a linear bar's
        // central difference is off by h² EA/(2 l0²) = 3.4e-4 N, while ∂U/∂l0 = 0).
        let difference = |h: f64| (law.energy(l, l0 + h) - law.energy(l, l0 - h)) / (2.0 * h);
        let (du, truncation) = (difference(h), (difference(2.0 * h) - difference(h)).abs() / 3.0);
        let q = law.d_energy_d_rest(l, l0);
        assert!(
            (du - q).abs() <= 1e-7 * scale_f.max(q.abs()) + 2.0 * truncation,
            "{}: dU/dl0 {du} vs {q} at l={l}",
            law.name()
        );
    }
}

#[test]
fn measure_potential_derivatives() {
    check_derivatives(&MeasurePotential { c: 2e11 / 7.0, n: 1.0 }, 7.0, &[6.5, 6.99, 7.01, 7.5]);
    check_derivatives(&MeasurePotential { c: 0.8, n: 3.0 }, 0.0, &[0.5, 2.0, 5.0]);
    check_derivatives(&MeasurePotential { c: 1.3, n: 2.5 }, 1.0, &[0.5, 0.9, 1.1, 3.0]);
}

#[test]
fn measure_potential_is_the_paper_power_law() {
    let law = MeasurePotential { c: 0.8, n: 3.0 };
    assert_eq!(law.eval(2.0, 0.0).force, 0.8 * 8.0);
    // Odd extension: below l0 the force is compressive, the same power.
    let strut = MeasurePotential { c: 10.0, n: 1.0 };
    assert_eq!(strut.eval(6.0, 7.0).force, -10.0);
}

#[test]
fn linear_elastic_derivatives_and_slack() {
    let ea = 68e9 * 0.01;
    check_derivatives(&LinearElastic { ea, tension_only: false }, 7.0, &[6.9, 7.0, 7.1]);
    let cable = LinearElastic {
        ea: 2e5,
        tension_only: true,
    };
    check_derivatives(&cable, 2.0, &[2.01, 2.5]);
    let slack = cable.eval(1.9, 2.0);
    assert_eq!((slack.force, slack.stiffness, cable.energy(1.9, 2.0)), (0.0, 0.0, 0.0));
    assert!((cable.eval(2.2, 2.0).force - 2e5 * 0.1).abs() < 1e-9);
}

#[test]
fn ogden_matches_reference_table() {
    // notes.md: F and dF/dλ in MPa for the paper's α, μ (eqs 6–7).
    let table = [
        (0.5, -1.658416, 8.643669),
        (0.8, -0.330932, 2.213650),
        (1.0, 0.0, 1.244947),
        (1.2, 0.204145, 0.854911),
        (1.5, 0.429458, 0.707239),
        (2.0, 0.841383, 1.036236),
        (2.5, 1.555953, 1.914590),
        (3.0, 2.856414, 3.397448),
    ];
    let terms = OgdenCord::paper_terms();
    for (lambda, f, df) in table {
        let (fc, dfc) = ogden_nominal_stress(&terms, lambda);
        // The table has 6 decimals in MPa: agreement to 1e-6 MPa (its rounding).
        assert!((fc / 1e6 - f).abs() <= 1e-6, "F({lambda}) = {} MPa, table {f}", fc / 1e6);
        assert!((dfc / 1e6 - df).abs() <= 1e-6, "F'({lambda}) = {} MPa, table {df}", dfc / 1e6);
    }
}

#[test]
fn ogden_cord_derivatives_both_branches() {
    for junction in [1.0, 0.9] {
        let cord = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, junction, 0.1);
        check_derivatives(&cord, 2.0, &[0.3, 1.0, 1.7, 1.99, 2.01, 2.5, 4.0, 6.0]);
    }
}

#[test]
fn ogden_compression_branch_is_c1_and_softening() {
    for (junction, r) in [(1.0, 0.1), (0.9, 0.3), (1.0, 0.5)] {
        let cord = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, junction, r);
        let (f_ogden, df_ogden) = ogden_nominal_stress(&cord.terms, junction);
        // Just below the junction the branch must meet the Ogden value and slope: the gap
        // is O(δ·F'') for δ = 1e-9, far below 1e-6 relative.
        let (f_b, df_b) = cord.nominal_stress(junction - 1e-9);
        assert!(
            (f_b - f_ogden).abs() <= 1e-6 * df_ogden,
            "F jump {} at λj={junction}",
            f_b - f_ogden
        );
        assert!(
            (df_b - df_ogden).abs() <= 1e-6 * df_ogden,
            "F' jump {} at λj={junction}",
            df_b - df_ogden
        );
        // Softening: slope decreases monotonically as λ falls, down to r·F'_j at λ = 0.
        let mut prev = df_b;
        for i in 1..=100 {
            let lambda = junction * (1.0 - i as f64 / 100.0);
            let (_, df) = cord.nominal_stress(lambda);
            assert!(df < prev && df > 0.0, "not softening at λ={lambda}");
            prev = df;
        }
        assert!(
            (prev / df_ogden - r).abs() < 1e-9,
            "slope ratio at λ=0 is {} not {r}",
            prev / df_ogden
        );
        // And it stays far softer than the Ogden curve, which stiffens in compression.
        let (f_half, _) = cord.nominal_stress(0.5 * junction);
        let (f_half_ogden, _) = ogden_nominal_stress(&cord.terms, 0.5 * junction);
        assert!(f_half > f_half_ogden);
    }
}

/// The tension-only cord: the Ogden curve above λ = 1, bit for bit the cord with the
/// compression branch there, and nothing below (N = 0, dN/dl = 0, no energy, and no
/// change with l0 either: the derivatives checked across both sides).
#[test]
fn ogden_cord_tension_only_is_slack_below_its_rest_length() {
    let with_branch = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1);
    let mut cord = with_branch.clone();
    cord.tension_only = true;
    assert!(cord.tension_only() && !with_branch.tension_only());
    check_derivatives(&cord, 2.0, &[0.3, 1.0, 1.7, 1.99, 2.01, 2.5, 4.0, 6.0]);
    for l in [2.0, 2.01, 2.5, 4.0] {
        assert_eq!(cord.eval(l, 2.0), with_branch.eval(l, 2.0), "l = {l}");
        assert_eq!(cord.energy(l, 2.0), with_branch.energy(l, 2.0), "l = {l}");
        assert_eq!(cord.d_energy_d_rest(l, 2.0), with_branch.d_energy_d_rest(l, 2.0), "l = {l}");
        assert!(!cord.slack(l, 2.0));
    }
    for l in [0.3, 1.0, 1.99] {
        let e = cord.eval(l, 2.0);
        assert!(cord.slack(l, 2.0) && with_branch.eval(l, 2.0).force < 0.0);
        assert_eq!((e.force, e.stiffness, e.curvature), (0.0, 0.0, 0.0), "l = {l}");
        assert_eq!(
            (cord.energy(l, 2.0), cord.d_force_d_rest(l, 2.0), cord.d_energy_d_rest(l, 2.0)),
            (0.0, 0.0, 0.0)
        );
    }
}
