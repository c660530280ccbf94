//! Stability of an equilibrium: the lowest eigenvalue of K_T on the free DOFs, where it
//! acts, and the largest diagonal entry it is judged against.
//!
//! Up to [`DENSE_STABILITY_LIMIT`] free DOFs it is the dense eigen decomposition of
//! `eigen.rs` (exact to round-off, every eigenvalue). Above, a dense matrix would not fit
//! (20k DOF: 3.2 GB and hours), so inverse iteration runs on the sparse Cholesky factor of
//! K_T + τI: τ = 0 when K_T is positive definite, else the smallest 10^k·τ0 that makes it
//! so (the same search as Newton's, `solve::newton`); the lowest eigenvalue is then the
//! converged Rayleigh quotient less τ. Inverse iteration converges to the lowest
//! eigenvalue at the rate (λ1 + τ)/(λ2 + τ) per iteration; it stops when the eigen
//! residual ‖K x − μ x‖ of the unit iterate x is below [`RESIDUAL`] × μ, which bounds the
//! distance of μ to an eigenvalue by that much, or after [`MAX_ITERATIONS`] (then μ is an
//! upper bound of λ1 that has not settled: close eigenvalues).

use super::eigen::{lowest_stiffness, tangent_matrix};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::solve::{SparseSolver, TangentSink, TangentSolver};
use crate::tsm::{tangent_pattern, Assembly, DofMap};

/// Largest model (free DOFs) checked densely: the dense check holds about 5 n² × 8 B
/// (`config/limits.rs`), 360 MB at 3000 DOF, and takes seconds; every model measured
/// before the sparse check (the paper's, the sweep's, the 60-stage towers of 2869 DOF)
/// stays on the dense path, with its results unchanged.
pub const DENSE_STABILITY_LIMIT: usize = 3000;
/// Inverse-iteration stop: μ within 1e-8 relative of an eigenvalue, far below any use of
/// the figure (its sign, and a threshold 1e3 ε × the largest diagonal).
const RESIDUAL: f64 = 1e-8;
const MAX_ITERATIONS: usize = 5000;
/// Tenfold shift increases before giving up (as in Newton's search).
const MAX_SHIFTS: u32 = 40;

/// The figures of a stability check.
#[derive(Clone, Debug, PartialEq)]
pub struct Stability {
    /// Lowest eigenvalue of K_T on the free DOFs [N/m].
    pub lowest: f64,
    /// The DOF its eigenvector moves most ("node `t3` direction z").
    pub at: String,
    /// Largest |diagonal entry| of K_T [N/m].
    pub largest_diagonal: f64,
}

/// The stability of `asm`'s configuration (see the module docs for the method by size).
pub fn stability(asm: &Assembly, dofs: &DofMap, model: &Model) -> Result<Stability> {
    stability_within(asm, dofs, model, DENSE_STABILITY_LIMIT)
}

/// [`stability`], dense up to `dense_limit` free DOFs (a test compares the two methods).
pub fn stability_within(asm: &Assembly, dofs: &DofMap, model: &Model, dense_limit: usize) -> Result<Stability> {
    if dofs.len() <= dense_limit {
        let k = tangent_matrix(asm);
        let (lowest, at) = lowest_stiffness(&k, dofs, model)?;
        let largest_diagonal = (0..dofs.len()).map(|i| k[(i, i)].abs()).fold(0.0, f64::max);
        return Ok(Stability {
            lowest,
            at,
            largest_diagonal,
        });
    }
    let n = dofs.len();
    let mut diagonal = Diagonal(vec![0.0; n]);
    asm.add_tangent(1.0, &mut diagonal);
    let largest_diagonal = diagonal.0.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
    let mut solver = SparseSolver::new(n, tangent_pattern(model, dofs));
    asm.add_tangent(1.0, &mut solver);
    let tau = positive_shift(&mut solver, n, largest_diagonal)?;
    let (mu, v) = inverse_iteration(&mut solver, n)?;
    let i = (0..n).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
    Ok(Stability {
        lowest: mu - tau,
        at: dofs.label(model, i),
        largest_diagonal,
    })
}

/// Adds τ I to the assembled matrix until Cholesky succeeds; returns τ (0: none needed).
/// τ0 = 1e-12 × the largest diagonal entry: below the round-off of an eigenvalue of K_T
/// (~ε‖K‖), so a shift that is not needed is never added.
fn positive_shift(solver: &mut SparseSolver, n: usize, largest_diagonal: f64) -> Result<f64> {
    if solver.cholesky() {
        return Ok(0.0);
    }
    let (mut tau, mut added) = (1e-12 * largest_diagonal, 0.0);
    for _ in 0..MAX_SHIFTS {
        (0..n).for_each(|i| solver.add(i, i, tau - added));
        added = tau;
        if solver.cholesky() {
            return Ok(tau);
        }
        tau *= 10.0;
    }
    Err(Error::Stage {
        stage: "stability",
        reason: "K_T + τI did not factor for any shift τ: the tangent is not finite".into(),
    })
}

/// The lowest eigenvalue of the factored (positive definite) matrix and its eigenvector,
/// by inverse iteration from a fixed start vector (the same answer on every run).
fn inverse_iteration(solver: &mut SparseSolver, n: usize) -> Result<(f64, Vec<f64>)> {
    let normalize = |v: &mut [f64]| {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
    };
    // Not orthogonal to any eigenvector in practice: entries of varying size and sign.
    let mut v: Vec<f64> = (0..n).map(|i| 1.0 + ((i * 7919) % 13) as f64 / 13.0).collect();
    normalize(&mut v);
    let mut w = v.clone();
    let mut mu = f64::NAN;
    for _ in 0..MAX_ITERATIONS {
        w.copy_from_slice(&v);
        solver.solve(&mut w).map_err(|e| Error::Stage {
            stage: "stability",
            reason: e.to_string(),
        })?;
        // Rayleigh quotient of K at w: wᵀKw / wᵀw = wᵀv / wᵀw (K w = v), and the residual
        // ‖K w − μ w‖ / ‖w‖ = ‖v − μ w‖ / ‖w‖.
        let ww = w.iter().map(|x| x * x).sum::<f64>();
        mu = w.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() / ww;
        let residual = (v.iter().zip(&w).map(|(a, b)| (a - mu * b).powi(2)).sum::<f64>() / ww).sqrt();
        std::mem::swap(&mut v, &mut w);
        normalize(&mut v);
        if residual <= RESIDUAL * mu.abs() {
            break;
        }
    }
    Ok((mu, v))
}

/// A sink that keeps only the diagonal.
struct Diagonal(Vec<f64>);

impl TangentSink for Diagonal {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        if row == col {
            self.0[row] += value;
        }
    }
}
