//! The partial eigensolver (shift-invert Lanczos on the sparse K_T) against a dense
//! reference, and the size threshold that picks one or the other.
//!
//! The reference is nalgebra's dense symmetric eigenvalues of C = M^-½ K M^-½, an
//! implementation independent of faer's. (faer 0.24.4's `self_adjoint_eigen` is not
//! backward stable on these matrices: its divide and conquer returned residuals up to
//! 1e-5 ‖C‖ and negative ω² for positive-definite towers; the dense path therefore uses
//! faer's QR algorithm, `tsim::solve::symmetric_eigen`, checked below.)

#[path = "../examples/common/tower.rs"]
mod tower;

use faer::Mat;
use tsim::stage::eigen::{lowest_stiffness, modes, tangent_matrix, EigenSolverChoice, ModeSolver, Modes, DENSE_EIGEN_LIMIT};
use tsim::structure::Structure;
use tsim::tsm::{Assembly, DofMap};

/// Modes of `structure` at its nominal positions, with its dense K_T and free masses.
fn solve(structure: &Structure, solver: ModeSolver) -> (Modes, Mat<f64>, Vec<f64>) {
    let dofs = DofMap::new(&structure.model, &[]);
    let asm = Assembly::new(&structure.model, &structure.elements, &dofs, structure.model.positions());
    let mass = structure.free_masses(&dofs);
    (modes(&asm, &mass, &solver).unwrap(), tangent_matrix(&asm), mass)
}

/// Eigenvalues of K φ = λ M φ, ascending, by nalgebra's dense symmetric solver.
fn reference(k: &Mat<f64>, mass: &[f64]) -> Vec<f64> {
    let n = mass.len();
    let c = nalgebra::DMatrix::from_fn(n, n, |i, j| k[(i, j)] / (mass[i] * mass[j]).sqrt());
    let mut e: Vec<f64> = c.symmetric_eigenvalues().iter().copied().collect();
    e.sort_by(f64::total_cmp);
    e
}

fn partial(modes: usize, shift: Option<f64>) -> ModeSolver {
    ModeSolver {
        choice: EigenSolverChoice::Partial,
        modes,
        shift,
    }
}

/// The 12-strut, 28-stage tower (2 001 free DOF) of steel struts and prestressed steel
/// cables: ‖C‖ ≈ 9.5e9 s⁻² and ω₁² ≈ 3.0e5 s⁻², so a backward-stable dense solver's
/// eigenvalue error ε‖C‖ ≈ 2e-6 s⁻² is 7e-12 of ω₁²: 1e-10 relative leaves a factor 14
/// for either solver's round-off. (The aluminium/rubber benchmark tower has ‖C‖/ω₁² ≈ 3e10,
/// where no solver resolves ω₁² to better than ~1e-5.)
#[test]
fn the_lowest_20_modes_match_the_dense_ones_on_a_2k_dof_tower() {
    let tower = tower::tower_of(12, 28, "steel", "steel");
    let (m, k, mass) = solve(&tower, partial(20, None));
    assert_eq!(mass.len(), 2001);
    let exact = reference(&k, &mass);
    assert_eq!(m.omega2.len(), 20);
    for (i, (w2, e)) in m.omega2.iter().zip(&exact).enumerate() {
        assert!((w2 - e).abs() <= 1e-10 * e.abs(), "mode {}: ω² {w2:e}, dense {e:e}", i + 1);
    }
    let phi = &m.shapes;
    let mphi = Mat::from_fn(phi.nrows(), phi.ncols(), |i, j| mass[i] * phi[(i, j)]);
    let gram = phi.transpose() * &mphi;
    // M-orthonormal to round-off: the Lanczos basis is kept orthonormal to ~ε√dim by full
    // reorthogonalization (repeated until converged); 1e-12 is ~50× that.
    for i in 0..20 {
        for j in 0..20 {
            let delta = if i == j { 1.0 } else { 0.0 };
            assert!((gram[(i, j)] - delta).abs() <= 1e-12, "φ{i}ᵀMφ{j} = {:e}", gram[(i, j)]);
        }
    }
    // Residual ‖M^-½(Kφ − ω²Mφ)‖ (φ M-normalised) bounds the eigenvalue error by itself
    // and by its square over the gap; 1e-8 ω² means shapes exact to 8 digits. Measured
    // ≤ 4e-10 ω² (the last converged modes).
    let kphi = &k * phi;
    for (j, w2) in m.omega2.iter().enumerate() {
        let r: f64 = (0..mass.len())
            .map(|i| (kphi[(i, j)] - w2 * mphi[(i, j)]).powi(2) / mass[i])
            .sum::<f64>()
            .sqrt();
        assert!(r <= 1e-8 * w2, "mode {}: residual {r:e} for ω² {w2:e}", j + 1);
    }
}

/// With a shift σ between the reference's 9th and 10th eigenvalues, the partial solver
/// returns the 6 eigenvalues nearest σ (through an LU of the indefinite K − σM),
/// ascending. Tolerance as above (‖C‖/ω² smaller still here).
#[test]
fn a_shift_gives_the_modes_nearest_it() {
    let tower = tower::tower_of(12, 8, "steel", "steel");
    let dense = ModeSolver {
        choice: EigenSolverChoice::Dense,
        ..ModeSolver::default()
    };
    let (_, k, mass) = solve(&tower, dense);
    let exact = reference(&k, &mass);
    let sigma = 0.5 * (exact[8] + exact[9]);
    let (m, _, _) = solve(&tower, partial(6, Some(sigma)));
    let mut nearest = exact.clone();
    nearest.sort_by(|a, b| (a - sigma).abs().total_cmp(&(b - sigma).abs()));
    nearest.truncate(6);
    nearest.sort_by(f64::total_cmp);
    for (w2, e) in m.omega2.iter().zip(&nearest) {
        assert!((w2 - e).abs() <= 1e-10 * e.abs(), "ω² {w2:e}, dense {e:e}");
    }
}

/// `auto` is dense (every mode) up to DENSE_EIGEN_LIMIT free DOF and partial (the lowest
/// k) above; the stability check's lowest eigenvalue of K_T goes the same way and, on the
/// partial side, equals the dense reference's (to 1e-10 relative, as above).
#[test]
fn the_threshold_picks_each_path() {
    let auto = ModeSolver::lowest(20);
    assert!(!auto.partial(DENSE_EIGEN_LIMIT) && auto.partial(DENSE_EIGEN_LIMIT + 1));
    // 12 struts per stage: 72 k − 15 free DOF, 1 497 for 21 stages and 1 569 for 22.
    let below = tower::tower_of(12, 21, "steel", "steel");
    let (m, _, mass) = solve(&below, auto);
    assert!(mass.len() <= DENSE_EIGEN_LIMIT);
    assert_eq!(m.omega2.len(), mass.len(), "dense: every mode");
    let above = tower::tower_of(12, 22, "steel", "steel");
    let (m, k, mass) = solve(&above, auto);
    assert!(mass.len() > DENSE_EIGEN_LIMIT);
    assert_eq!(m.omega2.len(), 20, "partial: the lowest 20");
    let dofs = DofMap::new(&above.model, &[]);
    let asm = Assembly::new(&above.model, &above.elements, &dofs, above.model.positions());
    let lowest = lowest_stiffness(&asm).unwrap().value;
    let exact = reference(&k, &vec![1.0; mass.len()])[0];
    assert!(
        (lowest - exact).abs() <= 1e-10 * exact.abs(),
        "lowest stiffness {lowest:e}, dense {exact:e}"
    );
}

/// The dense path on the 711-DOF aluminium/rubber tower (‖C‖ ≈ 2.2e10 s⁻², ω₁² ≈ 0.19
/// s⁻²), where faer's divide and conquer gave ω₁² = −17.0 s⁻² (bench/eigen.md): every one
/// of the lowest 20 pairs has a residual at round-off of ‖C‖, and each ω² equals the
/// partial solver's (shift-invert resolves the low modes far better than ε‖C‖) within
/// that residual. 1e-12 ‖C‖ ≈ 0.02 s⁻² is ~5× the n ε ‖C‖ worst case; the measured
/// differences are ~1e-6 s⁻².
#[test]
fn the_dense_path_keeps_the_low_modes_of_a_stiff_strut_tower() {
    let tower = tower::nominal_tower(6, 20);
    let dense = ModeSolver {
        choice: EigenSolverChoice::Dense,
        ..ModeSolver::default()
    };
    let (d, k, mass) = solve(&tower, dense);
    assert_eq!(mass.len(), 711);
    let (p, _, _) = solve(&tower, partial(20, None));
    let n = mass.len();
    let c = Mat::from_fn(n, n, |i, j| k[(i, j)] / (mass[i] * mass[j]).sqrt());
    let bound = 1e-12 * c.norm_l2();
    let kphi = &k * &d.shapes;
    for (j, (w2, exact)) in d.omega2.iter().zip(&p.omega2).enumerate() {
        assert!(
            *w2 > 0.0 && (w2 - exact).abs() <= bound,
            "mode {}: dense ω² {w2:e}, partial {exact:e}",
            j + 1
        );
        // ‖M^-½(Kφ − ω²Mφ)‖ for M-normalised φ is ‖Cy − ω²y‖ for the unit y = M^½φ.
        let r: f64 = (0..n)
            .map(|i| (kphi[(i, j)] - w2 * mass[i] * d.shapes[(i, j)]).powi(2) / mass[i])
            .sum::<f64>()
            .sqrt();
        assert!(r <= bound, "mode {}: residual {r:e}", j + 1);
    }
}
