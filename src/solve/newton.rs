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
}

/// Which linear solver Newton uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolverChoice {
    /// Dense LU up to [`DENSE_LIMIT`] free DOFs (a 600×600 LU takes ~10 ms and is
    /// faster than sparse bookkeeping on small models), sparse Cholesky above.
    #[default]
    Auto,
    Dense,
    Sparse,
}

/// Largest model (free DOFs) that `auto` solves densely.
pub const DENSE_LIMIT: usize = 600;

/// Buffers of the Newton driver: the residual, the tangent solver, the residual history.
/// Built once per stage; a Newton iteration then allocates nothing.
pub struct NewtonWorkspace {
    r: Vec<f64>,
    solver: Box<dyn TangentSolver>,
    /// max|r| at each evaluation of the last solve, the first at the starting point [N].
    pub history: Vec<f64>,
}

impl NewtonWorkspace {
    /// `pattern` lists the (row, column) entries the tangent can have (used by the sparse solver).
    pub fn new<P: IntoIterator<Item = (usize, usize)>>(n: usize, choice: LinearSolverChoice, pattern: impl FnOnce() -> P) -> Self {
        let solver: Box<dyn TangentSolver> = match choice {
            LinearSolverChoice::Dense => Box::new(DenseSolver::new(n)),
            LinearSolverChoice::Auto if n <= DENSE_LIMIT => Box::new(DenseSolver::new(n)),
            _ => Box::new(SparseSolver::new(n, pattern())),
        };
        NewtonWorkspace {
            r: vec![0.0; n],
            solver,
            history: Vec::with_capacity(64),
        }
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
    fn evaluate(&mut self, u: &[f64], r: &mut [f64], k: &mut dyn TangentSink) -> Scale;
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NewtonReport {
    pub iterations: usize,
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
    #[error("singular tangent stiffness at {dof} (pivot ratio {ratio:.1e}): a mechanism or instability there")]
    Singular { dof: String, ratio: f64 },
}

/// The Newton-Raphson driver: solves r(u) = 0 from the given `u` (updated in place).
/// Converged when max|r| ≤ tol_f·force + roundoff and the last increment max|Δu| ≤
/// tol_u·`length` (a start already in balance needs no increment).
/// `label` names a free DOF for error messages.
pub fn newton(
    problem: &mut impl Residual,
    u: &mut [f64],
    settings: &NewtonSettings,
    length: f64,
    label: &dyn Fn(usize) -> String,
    ws: &mut NewtonWorkspace,
) -> Result<NewtonReport, SolveError> {
    let mut increment = 0.0;
    let disp_tol = settings.displacement_tolerance * length;
    ws.history.clear();
    for iteration in 0..=settings.max_iterations {
        ws.solver.clear();
        let scale = problem.evaluate(u, &mut ws.r, &mut *ws.solver);
        let res = ws.r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        ws.history.push(res);
        if !res.is_finite() {
            return Err(SolveError::NonFinite { iteration });
        }
        let tolerance = settings.force_tolerance * scale.force + scale.roundoff;
        if res <= tolerance && (iteration == 0 || increment <= disp_tol) {
            return Ok(NewtonReport {
                iterations: iteration,
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
        ws.solver
            .solve(&mut ws.r)
            .map_err(|LinearError::Singular { dof, ratio }| SolveError::Singular {
                dof: dof.map_or_else(|| "a DOF the sparse LU does not name".to_string(), label),
                ratio,
            })?;
        increment = ws.r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let damping = (settings.max_step * length / increment).min(1.0);
        for (ui, di) in u.iter_mut().zip(&ws.r) {
            *ui += damping * di;
        }
    }
    unreachable!("the loop returns at its last iteration")
}
