use super::linear::{DenseSolver, LinearError, SparseSolver, TangentSink, TangentSolver};

/// Convergence settings of the Newton-Raphson driver (one struct for every stage).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonSettings {
    /// Iteration cap; beyond it the solve fails (stages may then cut the step). Default 50:
    /// Newton on these problems converges in under 10 iterations when it converges at all.
    pub max_iterations: usize,
    /// Residual tolerance relative to the force scale (largest member or applied force).
    /// Default 1e-10.
    pub force_tolerance: f64,
    /// Tolerance on the last increment, relative to the model size. Default 1e-10.
    pub displacement_tolerance: f64,
    /// Largest increment of one iteration, relative to the model size; a longer Newton
    /// step is scaled down to it (damped Newton). Stiff struts next to soft cables make
    /// the first linearised steps overshoot wildly from a far start; capping them keeps
    /// form-finding on the equilibrium nearest its start. Default 0.05.
    pub max_step: f64,
    /// Linear solver: `auto` (dense up to 600 free DOFs, sparse above), `dense` or `sparse`.
    pub linear_solver: LinearSolverChoice,
    /// When the tangent is rebuilt and factored: `auto` (reuse in time stepping, every
    /// iteration in static solves), `full` or `reuse`.
    pub tangent: TangentUpdate,
}

/// When Newton rebuilds and factors its tangent.
///
/// Full Newton factors at every iteration. Within a time step, and from one step to the
/// next, the step matrix M/(βΔt²) + γ/(βΔt)·C + K_T changes little, so its factorization
/// stays a good approximate inverse: reusing it (modified Newton) turns most iterations
/// into a residual evaluation and two triangular solves. The reuse is guarded: as soon as
/// an iteration reduces the residual less than [`REUSE_CONTRACTION`]-fold, the tangent is
/// rebuilt and factored at the current iterate, which is then a full Newton iteration.
/// The converged point meets the same tolerances either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TangentUpdate {
    /// `reuse` in time-stepping stages, `full` in static ones (form-finding and folding
    /// steps are strongly nonlinear, and their solves are few).
    #[default]
    Auto,
    Full,
    Reuse,
}

impl TangentUpdate {
    /// Whether a stage (`transient`: time stepping) reuses factorizations.
    pub fn reuses(self, transient: bool) -> bool {
        match self {
            TangentUpdate::Auto => transient,
            TangentUpdate::Full => false,
            TangentUpdate::Reuse => true,
        }
    }
}

/// Residual reduction per iteration that a reused factorization must achieve to be kept.
/// On the benchmark deployment (configs/bench_elastic.yaml) any value from 0.03 to 0.7
/// gave the same wall time within this machine's noise (3 100–6 100 factorizations for
/// 22 400–25 400 iterations); 0.1 keeps the iteration closest to full Newton.
pub const REUSE_CONTRACTION: f64 = 0.1;

/// Which linear solver Newton uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolverChoice {
    /// Dense Cholesky (LU fallback) up to [`DENSE_LIMIT`] free DOFs, where a dense
    /// factorization beats sparse bookkeeping; sparse Cholesky above.
    #[default]
    Auto,
    Dense,
    Sparse,
}

/// Largest model (free DOFs) that `auto` solves densely.
pub const DENSE_LIMIT: usize = 600;

/// Buffers of the Newton driver: the residual, the tangent solver (holding the last
/// factorization), the residual history. Built once per stage; a Newton iteration then
/// allocates nothing.
pub struct NewtonWorkspace {
    r: Vec<f64>,
    solver: Box<dyn TangentSolver>,
    /// Whether iterations may reuse the held factorization (see [`TangentUpdate`]).
    reuse: bool,
    /// The solver holds a factorization of the tangent at an earlier iterate.
    factored: bool,
    /// max|r| at each evaluation of the last solve, the first at the starting point [N].
    pub history: Vec<f64>,
}

impl NewtonWorkspace {
    /// `pattern` lists the (row, column) entries the tangent can have (used by the sparse
    /// solver); `transient`: a time-stepping stage ([`TangentUpdate::reuses`]).
    pub fn new<P: IntoIterator<Item = (usize, usize)>>(
        n: usize,
        settings: &NewtonSettings,
        transient: bool,
        pattern: impl FnOnce() -> P,
    ) -> Self {
        let reuse = settings.tangent.reuses(transient);
        let solver: Box<dyn TangentSolver> = match settings.linear_solver {
            LinearSolverChoice::Dense => Box::new(DenseSolver::new(n)),
            LinearSolverChoice::Auto if n <= DENSE_LIMIT => Box::new(DenseSolver::new(n)),
            _ => Box::new(SparseSolver::new(n, pattern())),
        };
        NewtonWorkspace {
            r: vec![0.0; n],
            solver,
            reuse,
            factored: false,
            history: Vec::with_capacity(64),
        }
    }

    /// Drops the held factorization: the next solve starts from a fresh tangent (call when
    /// the problem changes beyond what reuse can absorb, e.g. a new time step size).
    pub fn invalidate(&mut self) {
        self.factored = false;
    }
}

impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            max_iterations: 50,
            force_tolerance: 1e-10,
            displacement_tolerance: 1e-10,
            max_step: 0.05,
            linear_solver: LinearSolverChoice::Auto,
            tangent: TangentUpdate::Auto,
        }
    }
}

/// What makes a residual small: the force level, and the round-off floor below which no
/// residual can be resolved (stiff struts: EA·ε·l is ~1e-4 N for the form-finding struts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    pub force: f64,
    pub roundoff: f64,
}

/// A nonlinear problem on the free DOFs: r(u) = external − internal (− inertia − damping)
/// and its tangent K = −∂r/∂u.
pub trait Residual {
    /// Evaluates r(u) into `r`; the problem keeps the state for [`Residual::tangent`].
    fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale;
    /// Adds K = −∂r/∂u at the point of the last `residual` call. Newton asks for it only
    /// when it factors, so a converged or reusing iteration assembles nothing.
    fn tangent(&mut self, k: &mut dyn TangentSink);
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NewtonReport {
    pub iterations: usize,
    /// Tangent factorizations (equal to `iterations` for full Newton).
    pub factorizations: usize,
    /// max |r| at the converged point [N].
    pub residual: f64,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SolveError {
    #[error("Newton did not converge in {iterations} iterations: residual {residual:.3e} N (tolerance {tolerance:.3e} N), last increment {increment:.3e} m")]
    NotConverged {
        iterations: usize,
        residual: f64,
        tolerance: f64,
        increment: f64,
    },
    #[error("residual became non-finite at iteration {iteration} (diverged)")]
    NonFinite { iteration: usize },
    #[error("singular tangent stiffness (pivot ratio {ratio:.1e}): a mechanism or instability")]
    Singular { dof: Option<usize>, ratio: f64 },
}

impl SolveError {
    /// The free DOF the error is about, where known.
    pub fn dof(&self) -> Option<usize> {
        match self {
            SolveError::Singular { dof, .. } => *dof,
            _ => None,
        }
    }
}

/// The Newton-Raphson driver: solves r(u) = 0 from the given `u` (updated in place).
/// Converged when max|r| ≤ tol_f·force + roundoff and the last increment max|Δu| ≤
/// tol_u·`length` (a start already in balance needs no increment). With reuse on, the
/// factorization held in `ws` (possibly from an earlier solve) is used while the residual
/// keeps falling [`REUSE_CONTRACTION`]-fold per iteration.
pub fn newton(
    problem: &mut impl Residual,
    u: &mut [f64],
    settings: &NewtonSettings,
    length: f64,
    ws: &mut NewtonWorkspace,
) -> Result<NewtonReport, SolveError> {
    let result = iterate(problem, u, settings, length, ws);
    if result.is_err() {
        // A failed solve may leave a factorization that led it astray: retry fresh.
        ws.factored = false;
    }
    result
}

fn iterate(
    problem: &mut impl Residual,
    u: &mut [f64],
    settings: &NewtonSettings,
    length: f64,
    ws: &mut NewtonWorkspace,
) -> Result<NewtonReport, SolveError> {
    let mut increment = 0.0;
    let mut factorizations = 0;
    // max|r| before the last increment (∞ at the start: a held factorization gets a try).
    let mut previous = f64::INFINITY;
    let disp_tol = settings.displacement_tolerance * length;
    ws.history.clear();
    for iteration in 0..=settings.max_iterations {
        let scale = problem.residual(u, &mut ws.r);
        let res = ws.r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        ws.history.push(res);
        if !res.is_finite() {
            return Err(SolveError::NonFinite { iteration });
        }
        let tolerance = settings.force_tolerance * scale.force + scale.roundoff;
        if res <= tolerance && (iteration == 0 || increment <= disp_tol) {
            return Ok(NewtonReport {
                iterations: iteration,
                factorizations,
                residual: res,
            });
        }
        if iteration == settings.max_iterations {
            return Err(SolveError::NotConverged {
                iterations: iteration,
                residual: res,
                tolerance,
                increment,
            });
        }
        let singular = |LinearError::Singular { dof, ratio }| SolveError::Singular { dof, ratio };
        if !(ws.reuse && ws.factored && res <= REUSE_CONTRACTION * previous) {
            ws.factored = false;
            ws.solver.clear();
            problem.tangent(&mut *ws.solver);
            ws.solver.factor().map_err(singular)?;
            ws.factored = true;
            factorizations += 1;
        }
        previous = res;
        ws.solver.solve(&mut ws.r).map_err(singular)?;
        increment = ws.r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let damping = (settings.max_step * length / increment).min(1.0);
        for (ui, di) in u.iter_mut().zip(&ws.r) {
            *ui += damping * di;
        }
    }
    unreachable!("the loop returns at its last iteration")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// r(u) = a − u³: the tangent 3u² changes 25-fold between the roots 2 and 10, so a
    /// factorization held from one solve is a poor one for the next.
    struct Cubic {
        a: f64,
        u: f64,
    }

    impl Residual for Cubic {
        fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
            self.u = u[0];
            r[0] = self.a - u[0].powi(3);
            Scale {
                force: self.a,
                roundoff: 0.0,
            }
        }

        fn tangent(&mut self, k: &mut dyn TangentSink) {
            k.add(0, 0, 3.0 * self.u * self.u);
        }
    }

    fn solve(a: f64, u0: f64, tangent: TangentUpdate, ws: &mut NewtonWorkspace) -> (f64, NewtonReport) {
        let settings = NewtonSettings {
            tangent,
            max_step: 1.0,
            ..Default::default()
        };
        let mut u = [u0];
        let report = newton(&mut Cubic { a, u: u0 }, &mut u, &settings, 10.0, ws).unwrap();
        (u[0], report)
    }

    fn workspace(tangent: TangentUpdate) -> NewtonWorkspace {
        let settings = NewtonSettings {
            linear_solver: LinearSolverChoice::Dense,
            tangent,
            ..Default::default()
        };
        NewtonWorkspace::new(1, &settings, true, Vec::new)
    }

    /// Tolerance 1e-10 × a on the residual, i.e. ~1e-10/3 relative on the root; 1e-10
    /// relative asks no more than that.
    fn assert_root(u: f64, a: f64) {
        assert!((u / a.cbrt() - 1.0).abs() < 1e-10, "root {u} of u³ = {a}");
    }

    #[test]
    fn full_newton_factors_every_iteration() {
        let mut ws = workspace(TangentUpdate::Full);
        let (u, report) = solve(8.0, 1.5, TangentUpdate::Full, &mut ws);
        assert_root(u, 8.0);
        assert!(report.iterations >= 3);
        assert_eq!(report.factorizations, report.iterations);
    }

    #[test]
    fn reuse_keeps_a_good_factorization_and_drops_a_bad_one() {
        let mut ws = workspace(TangentUpdate::Reuse);
        let (u, first) = solve(8.0, 1.5, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 8.0);
        assert!(first.factorizations < first.iterations, "{first:?}");
        // A nearby root: the tangent held from u ≈ 2 (12) is within 10 % of the one at
        // the new root (12.8), so every iteration contracts > 10-fold on it.
        let (u, near) = solve(8.8, u, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 8.8);
        assert_eq!(near.factorizations, 0, "{near:?}");
        // A far root: with the held tangent alone Newton would oscillate between 2 and 12
        // (steps capped at 10); the guard refactors and converges.
        let (u, far) = solve(1000.0, u, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 1000.0);
        assert!(far.factorizations >= 1, "{far:?}");
        // After `invalidate` the held factorization is not used even where it would do.
        ws.invalidate();
        let (u, fresh) = solve(1010.0, u, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 1010.0);
        assert_eq!(fresh.factorizations, 1, "{fresh:?}");
    }
}
