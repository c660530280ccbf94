//! The lowest eigenpairs (or those nearest a shift σ) of K φ = λ M φ, K sparse symmetric
//! and M diagonal positive, without a dense matrix: shift-invert through one sparse
//! factorization of K − σM, and faer's Krylov–Schur (thick-restart Lanczos, full
//! reorthogonalization, locking) on the symmetric operator
//! A = M^½ (K − σM)^-1 M^½, whose eigenvalues θ = 1/(λ − σ) are largest in magnitude for
//! the λ nearest σ; then λ = σ + 1/θ and φ = M^-½ y, M-orthonormal because the Lanczos
//! vectors y are orthonormal. Knows no mechanics: K comes from a caller's assembly.
//!
//! Below the spectrum (the default shift) K − σM is positive definite and Cholesky is
//! safe however singular K is (rigid-body modes, mechanisms held by prestress only); at a
//! shift inside the spectrum the factorization is an LU.
//!
//! faer's routine locks a Ritz pair once its Lanczos residual |β qₘ| is below an
//! *absolute* tolerance, and its vectors span the wanted invariant subspace only as far as
//! the start vector reaches it: an eigenvalue of multiplicity > 1 (a symmetric structure)
//! is found through round-off. So the tolerance is scaled by an estimate of ‖A‖, and a
//! second, deflated run from another start vector checks that no eigenvalue between
//! the found ones was missed. For the lowest eigenvalue alone (a stability check) one
//! Cholesky factorization just below it proves the same (Sylvester), for a fraction of a
//! Lanczos run.
//!
//! A stability check needs λ₁ only as finely as its meaning goes: within the band about
//! zero where round-off on K decides λ₁'s sign, to a fraction of that band
//! ([`lowest_eigen`]). There a near-mechanism's lowest eigenvalues crowd (a plate's measure
//! structure: thousands within 1e-6 of the band), θ's gaps vanish, and resolving λ₁ to the
//! operator's round-off took Lanczos 576 products at 100k DOF and did not finish in an
//! hour at 1M (bench/pipeline.md).

use super::linear::{LinearError, SparseSolver, Sparsity, TangentSink, TangentSolver};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::matrix_free::eigen::{partial_self_adjoint_eigen, partial_self_adjoint_eigen_scratch, PartialEigenParams};
use faer::matrix_free::LinOp;
use faer::{Col, Mat, MatMut, MatRef, Par};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Where the wanted eigenvalues lie.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shift {
    /// The lowest ones: σ below the whole spectrum (see [`partial_eigen`]).
    Lowest,
    /// The ones nearest σ.
    Nearest(f64),
}

/// Why a partial eigensolve failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EigenError {
    /// K − σM cannot be factored: σ is (numerically) an eigenvalue.
    #[error("K − σM is singular at the shift σ = {shift:e} (σ is an eigenvalue); move the shift: {source}")]
    Singular {
        /// The shift σ, in the units of λ.
        shift: f64,
        /// The factorization's failure.
        source: LinearError,
    },
    /// K − σM's factorization could not allocate its memory.
    #[error("{0}")]
    OutOfMemory(LinearError),
    /// Fewer eigenpairs converged than asked for.
    #[error("the Lanczos iteration converged {found} of {wanted} eigenpairs")]
    NotConverged {
        /// Eigenpairs converged.
        found: usize,
        /// Eigenpairs asked for.
        wanted: usize,
    },
    /// The partial solver needs more unknowns than its Krylov subspace.
    #[error("{wanted} eigenpairs of {n} unknowns: too few unknowns for the partial solver (needs more than {needed}); use the dense one")]
    TooSmall {
        /// Order of the matrix (free DOFs).
        n: usize,
        /// Eigenpairs asked for.
        wanted: usize,
        /// The Krylov dimension `n` must exceed ([`krylov_dimension`]).
        needed: usize,
    },
}

/// Eigenpairs of K φ = λ M φ, λ ascending, φ M-orthonormal.
#[derive(Clone, Debug)]
pub struct EigenPairs {
    /// Eigenvalues λ, ascending (for K in N/m and M in kg: ω² in rad²/s²).
    pub values: Vec<f64>,
    /// One column per eigenvalue.
    pub vectors: Mat<f64>,
    /// The shift σ the factorization used.
    pub shift: f64,
    /// Products with the shift-inverted operator (a pair of triangular solves each), the
    /// norm estimate's included: the cost beyond the factorizations.
    pub products: usize,
}

/// Krylov subspace kept after a restart and grown before the next one: faer's defaults
/// (32, and 64 or twice the wanted count). A larger space converges in fewer restarts
/// but each costs O(n · dim²) in reorthogonalization.
const MIN_DIM: usize = 32;

/// Krylov subspace the partial solver needs for `wanted` eigenpairs; the matrix must be
/// larger than this.
pub fn krylov_dimension(wanted: usize) -> usize {
    (2 * MIN_DIM).max(2 * wanted)
}

/// Lanczos residual (relative to the estimate of ‖A‖) below which a Ritz pair is locked.
/// A locked θ is then accurate to ~residual²/gap (Rayleigh–Ritz on a symmetric operator)
/// and its vector to residual/gap; 1e-13 leaves a factor ~500 above the round-off floor
/// of one application of A (~ε‖A‖ times a few), so the iteration can reach it.
const LOCK_TOLERANCE: f64 = 1e-13;

/// The lowest shift tried is this fraction of the largest K_ii/m_ii below zero: ~450
/// times the round-off of a zero eigenvalue (~ε‖M^-½KM^-½‖ ≈ 2e-16 of that scale), so
/// K − σM is positive definite for positive semi-definite K (rigid-body modes and
/// mechanisms included), and close enough to zero that the lowest modes keep their
/// separation in θ = 1/(λ − σ) (shift-invert converges with the gaps of θ). At 1e-10 the
/// lowest stiffness of a 20k-DOF grid's measure structure, whose low eigenvalues lie
/// within 1e-16 of its largest, took 64 s of Lanczos; at 1e-13 under 3 s
/// (bench/pipeline.md).
const FIRST_SHIFT: f64 = 1e-13;
/// Each failed Cholesky moves σ down by this factor; from 1e-13 to 1e6 times the scale
/// covers every eigenvalue (|λ| ≤ ‖M^-½KM^-½‖ ≤ row count × the largest diagonal entry
/// for the matrices here, which have at most a few dozen entries per row).
const SHIFT_STEP: f64 = 10.0;
const SHIFT_TRIES: usize = 20;

/// Power iterations for the estimate of ‖A‖ that scales the lock tolerance; an
/// underestimate by 2× only makes the tolerance twice as strict.
const NORM_ITERATIONS: usize = 12;

/// The `wanted` eigenpairs of K φ = λ M φ nearest `shift` (or lowest), K assembled by
/// `assemble` into a sparse matrix with entries at `pattern` (both triangles), M = diag
/// `mass` (all positive).
///
/// [`Shift::Lowest`]: σ starts at −1e-13 × max K_ii/m_ii and steps down tenfold until
/// K − σM has a Cholesky factorization, which proves every λ > σ (Sylvester), so the
/// eigenvalues largest in θ are the lowest, negative ones (an unstable state) included.
pub fn partial_eigen(
    mass: &[f64],
    sparsity: Sparsity<impl IntoIterator<Item = (usize, usize)>>,
    assemble: &dyn Fn(&mut dyn TangentSink),
    wanted: usize,
    shift: Shift,
) -> Result<EigenPairs, EigenError> {
    let pencil = Pencil { mass, assemble };
    let (op, sigma, norm) = pencil.shift_invert(sparsity, wanted, shift)?;
    let first = lanczos(&op, wanted, &start_vector(mass.len(), 1), LOCK_TOLERANCE * norm)?;
    let pairs = if shift == Shift::Lowest && wanted == 1 {
        pencil.proven_lowest(&op, first, sigma, pencil.margin())?
    } else {
        op.complete(first, wanted)?
    };
    op.failure(sigma)?;
    Ok(op.eigenpairs(pairs, sigma))
}

/// The fraction of `band` to which [`lowest_eigen`] resolves an eigenvalue within it.
const BAND_RESOLUTION: f64 = 0.1;

/// The lowest eigenpair of K φ = λ M φ (as [`partial_eigen`] with one pair and
/// [`Shift::Lowest`]), resolved only as finely as a stability check needs: where λ₁ lies
/// within ±`band` (the round-off band of its sign) to a fraction of the band, elsewhere
/// to the solver's precision.
///
/// A Ritz pair locked at Lanczos residual r has an eigenvalue θ within r of its θ̃
/// (symmetric A), so λ = σ + 1/θ lies within e = r/(θ̃(θ̃ − r)) of λ̃ = σ + 1/θ̃: the first
/// run locks at r = band/10 · ‖A‖² (e ≈ band/10 for θ̃ ≈ ‖A‖), a few dozen products even in
/// a crowded cluster. Its λ̃ is an upper bound on λ₁ (the largest Ritz value is below θ₁),
/// and a Cholesky factorization at λ̃ − 2e, or at the shift's own margin below λ̃ where
/// that is larger, proves the lower one (Sylvester): λ₁ ∈ (λ̃ − max(2e, margin), λ̃]; for
/// M = I and the band of [`lowest_stiffness`](crate::stage::eigen::lowest_stiffness) the
/// margin is 0.45 band. Where λ̃ falls outside the band, or the proof fails, the pair is
/// refined from the Ritz vector to the usual tolerance.
pub fn lowest_eigen(
    mass: &[f64],
    sparsity: Sparsity<impl IntoIterator<Item = (usize, usize)>>,
    assemble: &dyn Fn(&mut dyn TangentSink),
    band: f64,
) -> Result<EigenPairs, EigenError> {
    let pencil = Pencil { mass, assemble };
    let (op, sigma, norm) = pencil.shift_invert(sparsity, 1, Shift::Lowest)?;
    let strict = LOCK_TOLERANCE * norm;
    // r ≤ ‖A‖/4 keeps θ̃ − r away from zero, so that e bounds the error.
    let r = (BAND_RESOLUTION * band * norm * norm).min(0.25 * norm).max(strict);
    let first = lanczos(&op, 1, &start_vector(mass.len(), 1), r)?;
    let theta = first.theta[0];
    let error = if theta > r { r / (theta * (theta - r)) } else { f64::INFINITY };
    let margin = pencil.margin();
    let resolved = r > strict && (sigma + 1.0 / theta).abs() <= band && pencil.nothing_below(&op, theta, sigma, margin.max(2.0 * error));
    let pairs = if resolved {
        first
    } else {
        let refined = lanczos(&op, 1, &first.y.col(0).to_owned(), strict)?;
        pencil.proven_lowest(&op, refined, sigma, margin)?
    };
    op.failure(sigma)?;
    Ok(op.eigenpairs(pairs, sigma))
}

/// K − σM through the caller's assembly.
struct Pencil<'a> {
    mass: &'a [f64],
    assemble: &'a dyn Fn(&mut dyn TangentSink),
}

impl Pencil<'_> {
    /// Assembles K − σM into `solver`.
    fn assemble_shifted(&self, solver: &mut SparseSolver, sigma: f64) {
        solver.clear();
        (self.assemble)(solver);
        for (i, m) in self.mass.iter().enumerate() {
            solver.add(i, i, -sigma * m);
        }
    }

    /// The largest K_ii/m_ii: the scale of the eigenvalues' round-off.
    fn scale(&self) -> f64 {
        let mut diagonal = Diagonal(vec![0.0; self.mass.len()]);
        (self.assemble)(&mut diagonal);
        let scale = diagonal.0.iter().zip(self.mass).map(|(k, m)| (k / m).abs()).fold(0.0, f64::max);
        scale.max(f64::MIN_POSITIVE)
    }

    /// Factors K − σM for the shift asked for; returns σ.
    fn factor_shifted(&self, solver: &mut SparseSolver, shift: Shift) -> Result<f64, EigenError> {
        match shift {
            Shift::Nearest(sigma) => {
                self.assemble_shifted(solver, sigma);
                solver.factor(true).map_err(|source| match source {
                    LinearError::OutOfMemory { .. } => EigenError::OutOfMemory(source),
                    LinearError::Singular { .. } => EigenError::Singular { shift: sigma, source },
                })?;
                Ok(sigma)
            }
            Shift::Lowest => {
                let mut sigma = -FIRST_SHIFT * self.scale();
                for _ in 0..SHIFT_TRIES {
                    self.assemble_shifted(solver, sigma);
                    if solver.cholesky() {
                        return Ok(sigma);
                    }
                    sigma *= SHIFT_STEP;
                }
                Err(EigenError::Singular {
                    shift: sigma,
                    source: LinearError::Singular { dof: None, ratio: None },
                })
            }
        }
    }

    /// The shift-inverted operator for `wanted` pairs at `shift`, the shift σ it was
    /// factored at, and an estimate of its norm.
    fn shift_invert(
        &self,
        sparsity: Sparsity<impl IntoIterator<Item = (usize, usize)>>,
        wanted: usize,
        shift: Shift,
    ) -> Result<(ShiftInvert, f64, f64), EigenError> {
        let n = self.mass.len();
        let needed = krylov_dimension(wanted);
        if n <= needed {
            return Err(EigenError::TooSmall { n, wanted, needed });
        }
        let mut solver = SparseSolver::new(n, sparsity);
        let sigma = self.factor_shifted(&mut solver, shift)?;
        let op = ShiftInvert::new(solver, self.mass);
        let norm = op.norm_estimate();
        // A singular LU shows in its first solves.
        op.failure(sigma)?;
        Ok((op, sigma, norm))
    }

    /// The shift's own margin, [`FIRST_SHIFT`] × the scale: a factorization cannot decide
    /// more finely, and it is far above a Ritz value's error at [`LOCK_TOLERANCE`] (~1e-13
    /// of λ₁ − σ).
    fn margin(&self) -> f64 {
        FIRST_SHIFT * self.scale()
    }

    /// `found`, one Ritz pair, if [`Pencil::nothing_below`] it at `margin`; else completed
    /// by the deflated runs.
    fn proven_lowest(&self, op: &ShiftInvert, found: Ritz, sigma: f64, margin: f64) -> Result<Ritz, EigenError> {
        if self.nothing_below(op, found.theta[0], sigma, margin) {
            Ok(found)
        } else {
            op.complete(found, 1)
        }
    }

    /// Whether no eigenvalue lies below the one found, λ₁ = σ + 1/θ₁ (less `margin`, at
    /// least the Ritz value's error), proven by a Cholesky factorization of K − μM at
    /// μ = λ₁ − margin (Sylvester: it exists only if every λ > μ): what the deflated run
    /// of [`ShiftInvert::complete`] checks for the lowest eigenvalue alone, for one
    /// factorization instead of a Lanczos run. Where μ ≤ σ the factorization at σ already
    /// proves it. Where the proof fails, `op`'s factorization is restored to K − σM.
    fn nothing_below(&self, op: &ShiftInvert, theta: f64, sigma: f64, margin: f64) -> bool {
        let mu = sigma + 1.0 / theta - margin;
        if mu <= sigma {
            return true;
        }
        let mut solver = op.solver.lock().expect("the solver lock is never poisoned");
        self.assemble_shifted(&mut solver, mu);
        if solver.cholesky() {
            return true;
        }
        self.assemble_shifted(&mut solver, sigma);
        // K − σM was factored by Cholesky before, and the same numbers factor the same way.
        assert!(solver.cholesky(), "K − σM factored before");
        false
    }
}

/// Only the diagonal of an assembled matrix.
pub struct Diagonal(pub Vec<f64>);

impl TangentSink for Diagonal {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        if row == col {
            self.0[row] += value;
        }
    }
}

/// A deterministic start vector with every component nonzero and no symmetry (a vector of
/// ones is orthogonal to every antisymmetric mode of a symmetric structure): a
/// low-discrepancy sequence in [-1, 1) seeded by `seed`.
fn start_vector(n: usize, seed: u64) -> Col<f64> {
    const GOLDEN: f64 = 0.618_033_988_749_894_9;
    Col::from_fn(n, |i| {
        let t = ((i as u64 + 1) * (2 * seed + 1)) as f64 * GOLDEN;
        2.0 * (t - t.floor()) - 1.0 + 1e-3
    })
}

/// Ritz pairs (θ, y) of the shift-inverted operator, |θ| descending.
struct Ritz {
    theta: Vec<f64>,
    y: Mat<f64>,
}

/// y ↦ M^½ (K − σM)^-1 M^½ y through the held factorization.
struct ShiftInvert {
    solver: Mutex<SparseSolver>,
    sqrt_m: Vec<f64>,
    /// A solve that failed (a non-finite result of the LU) inside faer's iteration, which
    /// cannot return an error.
    failed: Mutex<Option<LinearError>>,
    /// Vectors the operator was applied to.
    products: AtomicUsize,
}

impl std::fmt::Debug for ShiftInvert {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ShiftInvert({} unknowns)", self.sqrt_m.len())
    }
}

impl LinOp<f64> for ShiftInvert {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.sqrt_m.len()
    }
    fn ncols(&self) -> usize {
        self.sqrt_m.len()
    }
    fn apply(&self, mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, _stack: &mut MemStack) {
        self.products.fetch_add(rhs.ncols(), Ordering::Relaxed);
        let mut solver = self.solver.lock().expect("the solver lock is never poisoned");
        let mut x = vec![0.0; self.sqrt_m.len()];
        for j in 0..rhs.ncols() {
            for (i, xi) in x.iter_mut().enumerate() {
                *xi = self.sqrt_m[i] * rhs[(i, j)];
            }
            if let Err(e) = solver.solve(&mut x) {
                // faer's reorthogonalization loops forever on a NaN (its convergence test
                // is never true) and on an exact zero vector, so a failed solve gives
                // a finite, generic vector; the failure is reported after the iteration.
                *self.failed.lock().expect("never poisoned") = Some(e);
                let noise = start_vector(x.len(), 3);
                x.iter_mut().enumerate().for_each(|(i, xi)| *xi = noise[i]);
            }
            for (i, xi) in x.iter().enumerate() {
                out[(i, j)] = self.sqrt_m[i] * xi;
            }
        }
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        self.apply(out, rhs, par, stack);
    }
}

impl ShiftInvert {
    fn new(solver: SparseSolver, mass: &[f64]) -> Self {
        ShiftInvert {
            solver: Mutex::new(solver),
            sqrt_m: mass.iter().map(|m| m.sqrt()).collect(),
            failed: Mutex::new(None),
            products: AtomicUsize::new(0),
        }
    }

    /// The error of a failed solve, if any, at the shift `sigma`.
    fn failure(&self, sigma: f64) -> Result<(), EigenError> {
        match self.failed.lock().expect("never poisoned").take() {
            Some(source) => Err(EigenError::Singular { shift: sigma, source }),
            None => Ok(()),
        }
    }

    fn apply_vec(&self, v: &Col<f64>) -> Col<f64> {
        let mut out = Col::zeros(v.nrows());
        self.apply(
            out.as_mat_mut(),
            v.as_mat(),
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(StackReq::EMPTY)),
        );
        out
    }

    /// ‖A‖ = max |θ| by power iteration from a fixed vector.
    fn norm_estimate(&self) -> f64 {
        let mut v = start_vector(self.nrows(), 7);
        let mut norm = 0.0;
        for _ in 0..NORM_ITERATIONS {
            v /= v.norm_l2();
            v = self.apply_vec(&v);
            norm = v.norm_l2();
        }
        norm
    }
}

/// `count` Ritz pairs of largest |θ| of `op` from the start vector `v0`, locked at
/// `tolerance`.
fn lanczos(op: &dyn LinOp<f64>, count: usize, v0: &Col<f64>, tolerance: f64) -> Result<Ritz, EigenError> {
    let n = op.nrows();
    let params = PartialEigenParams {
        min_dim: MIN_DIM.max(count),
        max_dim: krylov_dimension(count),
        ..Default::default()
    };
    let mut mem = MemBuffer::new(partial_self_adjoint_eigen_scratch::<f64>(op, count, Par::Seq, params));
    let mut y = Mat::zeros(n, count);
    let mut theta = vec![0.0; count];
    let info = partial_self_adjoint_eigen(
        y.as_mut(),
        &mut theta,
        op,
        v0.as_ref(),
        tolerance,
        Par::Seq,
        MemStack::new(&mut mem),
        params,
    );
    if info.n_converged_eigen < count {
        return Err(EigenError::NotConverged {
            found: info.n_converged_eigen,
            wanted: count,
        });
    }
    Ok(Ritz { theta, y })
}

/// A with the span of orthonormal `y` deflated: P A P, P = I − Y Yᵀ.
#[derive(Debug)]
struct Deflated<'a> {
    op: &'a ShiftInvert,
    y: &'a Mat<f64>,
}

impl Deflated<'_> {
    fn project(&self, mut v: MatMut<'_, f64>) {
        let coefficients = self.y.transpose() * v.as_ref();
        v -= self.y * coefficients;
    }
}

impl LinOp<f64> for Deflated<'_> {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.op.nrows()
    }
    fn ncols(&self) -> usize {
        self.op.ncols()
    }
    fn apply(&self, mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        let mut p = rhs.to_owned();
        self.project(p.as_mut());
        self.op.apply(out.as_mut(), p.as_ref(), par, stack);
        self.project(out);
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        self.apply(out, rhs, par, stack);
    }
}

/// Ritz pairs each check asks the deflated operator for: a multiplicity the first run
/// missed shows up among them (a structure with n-fold symmetry has double eigenvalues).
const CHECK_COUNT: usize = 8;

impl ShiftInvert {
    /// Completes `found` by runs on the operator with the found vectors deflated, from
    /// another start vector each: while such a run finds a θ larger in magnitude than the
    /// smallest wanted one (an eigenvalue the first run missed), it joins the set.
    fn complete(&self, mut found: Ritz, wanted: usize) -> Result<Ritz, EigenError> {
        let tolerance = LOCK_TOLERANCE * found.theta[0].abs();
        for seed in 2..wanted as u64 + 3 {
            let deflated = Deflated { op: self, y: &found.y };
            let mut v0 = start_vector(self.nrows(), seed);
            deflated.project(v0.as_mat_mut());
            let extra = lanczos(&deflated, CHECK_COUNT, &v0, tolerance)?;
            let smallest = found.theta[wanted - 1].abs();
            let missed: Vec<usize> = (0..CHECK_COUNT).filter(|&j| extra.theta[j].abs() > smallest).collect();
            if missed.is_empty() {
                return Ok(found);
            }
            found = merge(&found, &extra, &missed, wanted);
        }
        // Every round adds a pair, so `wanted` + 1 rounds without settling cannot happen
        // unless the iteration is not converging to the operator's eigenpairs.
        Err(EigenError::NotConverged { found: 0, wanted })
    }

    /// Eigenpairs of the pencil from Ritz pairs of the operator at shift `sigma`.
    fn eigenpairs(&self, ritz: Ritz, sigma: f64) -> EigenPairs {
        let mut order: Vec<usize> = (0..ritz.theta.len()).collect();
        let values: Vec<f64> = ritz.theta.iter().map(|t| sigma + 1.0 / t).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        EigenPairs {
            values: order.iter().map(|&j| values[j]).collect(),
            vectors: Mat::from_fn(self.nrows(), order.len(), |i, j| ritz.y[(i, order[j])] / self.sqrt_m[i]),
            shift: sigma,
            products: self.products.load(Ordering::Relaxed),
        }
    }
}

/// The `wanted` pairs of largest |θ| among `found` and `extra`'s columns `missed`.
fn merge(found: &Ritz, extra: &Ritz, missed: &[usize], wanted: usize) -> Ritz {
    let mut all: Vec<(f64, &Ritz, usize)> = (0..found.theta.len()).map(|j| (found.theta[j], found, j)).collect();
    all.extend(missed.iter().map(|&j| (extra.theta[j], extra, j)));
    all.sort_by(|a, b| b.0.abs().total_cmp(&a.0.abs()));
    all.truncate(wanted);
    Ritz {
        theta: all.iter().map(|a| a.0).collect(),
        y: Mat::from_fn(found.y.nrows(), wanted, |i, j| all[j].1.y[(i, all[j].2)]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// K = diag(d), M = diag(m) through the solver's interface.
    fn diagonal_pencil(d: &[f64], m: &[f64], wanted: usize, shift: Shift) -> Result<EigenPairs, EigenError> {
        let assemble = |k: &mut dyn TangentSink| d.iter().enumerate().for_each(|(i, &v)| k.add(i, i, v));
        partial_eigen(m, Sparsity::amd((0..d.len()).map(|i| (i, i))), &assemble, wanted, shift)
    }

    /// Every eigenvalue double (λ = 1, 1, 2, 2, …, the masses varied so that the pencil is
    /// not the identity's): a Krylov space from one start vector holds one vector of each
    /// eigenspace, the other copy is found by the deflated check. Exact values, so the
    /// tolerance is round-off: 1e-12 relative (the operator's θ converge to 1e-13 of θ₁).
    #[test]
    fn finds_both_copies_of_double_eigenvalues() {
        let n = 300;
        let m: Vec<f64> = (0..n).map(|i| 1.0 + (i % 7) as f64).collect();
        let d: Vec<f64> = (0..n).map(|i| (1 + i / 2) as f64 * m[i]).collect();
        let pairs = diagonal_pencil(&d, &m, 10, Shift::Lowest).unwrap();
        for (j, v) in pairs.values.iter().enumerate() {
            let exact = (1 + j / 2) as f64;
            assert!((v - exact).abs() <= 1e-12 * exact, "λ{j} = {v}, expected {exact}");
        }
    }

    /// The proof that no eigenvalue lies below the lowest one found: it holds for λ₁ = 1 of
    /// diag(1, 2, …) and fails for λ = 2 (a lowest mode the Lanczos run would have missed),
    /// after which the factorization is K − σM again. (A start vector orthogonal to the
    /// lowest mode does not make a test of the whole: round-off brings the mode into the
    /// Krylov space and the first run finds it.) Exact values: the shift-inverted 1/(1 − σ)
    /// to round-off.
    #[test]
    fn only_the_lowest_eigenvalue_has_nothing_below_it() {
        let n = 200;
        let mass = vec![1.0; n];
        let assemble = |k: &mut dyn TangentSink| (0..n).for_each(|i| k.add(i, i, (i + 1) as f64));
        let pencil = Pencil {
            mass: &mass,
            assemble: &assemble,
        };
        let mut solver = SparseSolver::new(n, Sparsity::amd((0..n).map(|i| (i, i))));
        let sigma = pencil.factor_shifted(&mut solver, Shift::Lowest).unwrap();
        let op = ShiftInvert::new(solver, &mass);
        assert!(pencil.nothing_below(&op, 1.0 / (1.0 - sigma), sigma, pencil.margin()));
        assert!(!pencil.nothing_below(&op, 1.0 / (2.0 - sigma), sigma, pencil.margin()));
        let first = op.apply_vec(&Col::from_fn(n, |i| if i == 0 { 1.0 } else { 0.0 }));
        assert!((first[0] * (1.0 - sigma) - 1.0).abs() < 1e-15, "A e₀ = {}", first[0]);
    }

    /// K = diag(d) with M = I for [`lowest_eigen`] at round-off band `band`.
    fn lowest_of(d: &[f64], band: f64) -> EigenPairs {
        let assemble = |k: &mut dyn TangentSink| d.iter().enumerate().for_each(|(i, &v)| k.add(i, i, v));
        lowest_eigen(&vec![1.0; d.len()], Sparsity::amd((0..d.len()).map(|i| (i, i))), &assemble, band).unwrap()
    }

    /// A near-mechanism: 1000 eigenvalues λₖ = 1e-8 k² × the round-off band (a plate's
    /// crowded bending modes, up to a hundredth of the band; the band 1e3 ε × the largest
    /// entry, 300), the rest 1 … 300. The stability check resolves λ₁ to a tenth of the
    /// band (an upper bound, the Ritz value; 0.2 band allows for the lock's bound e) where
    /// the solver's full precision must pull λ₁ out of the crowd: measured 76 products
    /// against 2 540, asserted ≥ 10× fewer. Outside the band (λ₁ = 1) it is exact to
    /// round-off, as [`partial_eigen`].
    #[test]
    fn the_stability_check_resolves_a_crowded_lowest_eigenvalue_to_its_band() {
        let band = 1e3 * f64::EPSILON * 300.0;
        let mut d: Vec<f64> = (1..=1000).map(|k| 1e-8 * band * (k * k) as f64).collect();
        d.extend((1..=300).map(|i| i as f64));
        let loose = lowest_of(&d, band);
        let full = diagonal_pencil(&d, &vec![1.0; d.len()], 1, Shift::Lowest).unwrap();
        let lowest = loose.values[0];
        assert!(
            lowest >= d[0] - 1e-3 * band && lowest - d[0] <= 0.2 * band,
            "λ₁ = {lowest:e} ({:e} ± the band's resolution, band {band:e})",
            d[0]
        );
        assert!(
            10 * loose.products <= full.products,
            "{} products, full precision {}",
            loose.products,
            full.products
        );
        let d: Vec<f64> = (1..=400).map(|i| i as f64).collect();
        let strict = lowest_of(&d, band).values[0];
        assert!((strict - 1.0).abs() <= 1e-12, "λ₁ = {strict}, expected 1");
    }

    /// A shift inside the spectrum (an indefinite K − σM, factored by LU): the modes
    /// nearest σ = 10.3 are λ = 10, 11, 9, 12, 8 (single here), returned ascending.
    #[test]
    fn a_shift_inside_the_spectrum_gives_the_nearest_modes() {
        let n = 200;
        let d: Vec<f64> = (0..n).map(|i| (i + 1) as f64).collect();
        let pairs = diagonal_pencil(&d, &vec![1.0; n], 5, Shift::Nearest(10.3)).unwrap();
        for (v, exact) in pairs.values.iter().zip([8.0, 9.0, 10.0, 11.0, 12.0]) {
            assert!((v - exact).abs() <= 1e-12 * exact, "λ = {v}, expected {exact}");
        }
    }

    /// A shift on an eigenvalue cannot be factored, and says so.
    #[test]
    fn a_shift_on_an_eigenvalue_is_an_error() {
        let d: Vec<f64> = (0..200).map(|i| (i + 1) as f64).collect();
        let err = diagonal_pencil(&d, &vec![1.0; 200], 5, Shift::Nearest(10.0)).unwrap_err();
        assert!(matches!(err, EigenError::Singular { shift, .. } if shift == 10.0), "{err}");
    }

    /// An indefinite K (λ = −5 … ): the default shift steps below the spectrum and the
    /// lowest, negative eigenvalues come first.
    #[test]
    fn the_lowest_modes_of_an_indefinite_matrix_include_the_negative_ones() {
        let d: Vec<f64> = (0..200).map(|i| i as f64 - 5.0).collect();
        let pairs = diagonal_pencil(&d, &vec![2.0; 200], 3, Shift::Lowest).unwrap();
        assert!(pairs.shift < -2.5, "σ = {} is not below λ₁ = −2.5", pairs.shift);
        for (v, exact) in pairs.values.iter().zip([-2.5, -2.0, -1.5]) {
            assert!((v - exact).abs() <= 1e-12 * exact.abs(), "λ = {v}, expected {exact}");
        }
    }
}
