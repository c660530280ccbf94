use super::backoff::Backoff;
use super::bisect::StepFailure;
use super::krylov::KrylovEffort;
use super::linear::{dof_text, ratio_text, DenseSolver, LinearError, SparseSolver, Sparsity, TangentSink, TangentSolver};
use super::low_rank::LowRank;

/// Convergence settings of the Newton-Raphson driver (one struct for every stage).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonSettings {
    /// Iteration cap; beyond it the solve fails (stages may then cut the step). Default
    /// 50 in time and load steps, where Newton converges in under 10 iterations when it
    /// converges at all, and 2000 in form-finding, a minimization from the nominal shape
    /// that the energy line search globalizes: every iteration lowers the potential, so
    /// the cap is only a safety net, and a tall tower needs hundreds (a 5-strut tower:
    /// 132 for 100 stages, 543 for 200, 666 for 300; bench/formfinding.md).
    pub max_iterations: Option<usize>,
    /// Residual tolerance relative to the force scale (largest member or applied force),
    /// plus a round-off floor. Default 1e-10. 0: iterate until the residual stops falling,
    /// to what round-off leaves (a conserving scheme's drift is that residual's).
    pub force_tolerance: f64,
    /// Tolerance on the last increment, relative to the model size. Default 1e-10.
    pub displacement_tolerance: f64,
    /// Largest increment of one iteration, relative to the model size, for problems
    /// without a potential (time steps); a longer Newton step is scaled down to it, and
    /// then halved where it does not lower ‖r‖₂ (a line search on the residual).
    /// Static stages (form-finding, folding) have a potential and are globalized by the
    /// energy line search instead (see [`newton`]), which needs no such knob. Default 0.05.
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
/// rebuilt and factored at the current iterate, which is then a full Newton iteration —
/// or, with the sparse solver, where the held factorization is off because a few bar
/// elements switched (cables slack or taut), corrected for those elements by rank-one
/// updates (`low_rank.rs`), the cheaper of the two.
/// A solve whose held factorization failed so makes the next ones start fresh for a while
/// (`NewtonWorkspace::held`, an exponential back-off).
/// The converged point meets the same tolerances either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TangentUpdate {
    /// `reuse` in time-stepping stages, `full` in static ones (form-finding and folding
    /// steps are strongly nonlinear, and their solves are few).
    #[default]
    Auto,
    /// Factor at every iteration (full Newton).
    Full,
    /// Keep a factorization while it contracts the residual (modified Newton).
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolverChoice {
    /// Dense Cholesky (LU fallback) up to [`DENSE_LIMIT`] free DOFs, where a dense
    /// factorization beats sparse bookkeeping; sparse Cholesky above.
    #[default]
    Auto,
    /// Dense Cholesky (LU fallback) at any size.
    Dense,
    /// Sparse Cholesky (LDLᵀ, then LU fallback) at any size; an unsymmetric matrix by
    /// GMRES on its symmetric part's Cholesky factor before LU.
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
    /// Seek a minimum of the potential: where the tangent is not positive definite, the
    /// Newton direction comes from K + τI, the smallest τ = 10^k·τ0 that factors by
    /// Cholesky (see [`shifted_cholesky`]). Off by default: folding follows its
    /// equilibrium path through unstable states on purpose.
    pub minimize: bool,
    /// The last shift τ [N/m] (0: none was needed), where the next search starts.
    shift: f64,
    /// The solver holds a factorization of the tangent at an earlier iterate.
    factored: bool,
    /// Whether a solve starts with the factorization held from the previous one.
    ///
    /// Why a back-off: a held factorization that turns out stale costs a wasted iteration
    /// (a residual and a solve) before the refactorization; one that holds saves a
    /// factorization. Which is likelier depends on the problem: the paper's tower keeps
    /// it for most steps, while a grid whose cables go slack and taut outdates it every
    /// step (a 47 × 47 grid: the held factor's second iteration contracts only 0.4–0.8,
    /// so every step ran 4 iterations with one refactorization, where a fresh start takes
    /// 3).
    held: Backoff,
    /// max|r| at each evaluation of the last solve, the first at the starting point [N].
    pub history: Vec<f64>,
    /// The potential at the start and after each iteration of the last solve, for
    /// problems that have one [J].
    pub energies: Vec<f64>,
    /// Factorizations of the last solve, so far (a failed solve's too: [`Self::last_effort`]).
    factorizations: usize,
    /// Rank-one corrections of the held factorization for elements that switched since
    /// (see `low_rank.rs`): with a sparse solver that reuses factorizations only. Dense
    /// models (≤ 600 DOF) keep the plain path: their factorization costs little more than
    /// the assembly pass a correction needs first, and the paper deployment's figures
    /// (cross-checked against OpenSees) stay as they were.
    low_rank: Option<LowRank>,
    /// The Newton direction, a trial point of the line search and its correction.
    d: Vec<f64>,
    trial: Vec<f64>,
    correction: Vec<f64>,
}

impl NewtonWorkspace {
    /// `sparsity` gives the tangent's shape to the sparse solver, which calls it only if it
    /// is the one used; `settings` pick the linear solver and, with `transient` (a time-stepping
    /// stage), whether factorizations are reused ([`TangentUpdate::reuses`]).
    pub fn new<P: IntoIterator<Item = (usize, usize)>>(
        n: usize,
        settings: &NewtonSettings,
        transient: bool,
        sparsity: impl FnOnce() -> Sparsity<P>,
    ) -> Self {
        let dense = match settings.linear_solver {
            LinearSolverChoice::Dense => true,
            LinearSolverChoice::Auto => n <= DENSE_LIMIT,
            LinearSolverChoice::Sparse => false,
        };
        let reuse = settings.tangent.reuses(transient);
        let mut low_rank = None;
        let solver: Box<dyn TangentSolver> = if dense {
            Box::new(DenseSolver::new(n))
        } else {
            let sparse = SparseSolver::new(n, sparsity());
            low_rank = reuse.then(|| LowRank::new(n, sparse.factor_nonzeros()));
            Box::new(sparse)
        };
        NewtonWorkspace {
            r: vec![0.0; n],
            solver,
            reuse,
            minimize: false,
            shift: 0.0,
            factored: false,
            held: Backoff::default(),
            history: Vec::with_capacity(64),
            energies: Vec::with_capacity(64),
            factorizations: 0,
            low_rank,
            d: vec![0.0; n],
            trial: vec![0.0; n],
            correction: vec![0.0; n],
        }
    }

    /// Drops the held factorization: the next solve starts from a fresh tangent (call when
    /// the problem changes beyond what reuse can absorb, e.g. a new time step size).
    pub fn invalidate(&mut self) {
        self.factored = false;
    }

    /// Iterations and factorizations of the last solve, a failed one's included: the work a
    /// step cut in halves spent before it was cut, which no converged report shows.
    pub fn last_effort(&self) -> (usize, usize) {
        (self.history.len().saturating_sub(1), self.factorizations)
    }

    /// The GMRES work of every solve so far, failed attempts' included.
    pub fn krylov_effort(&self) -> KrylovEffort {
        self.solver.krylov_effort()
    }
}

/// The iteration cap of a step (time or load) when the config sets none.
pub const STEP_MAX_ITERATIONS: usize = 50;
/// The iteration cap of form-finding's minimization when the config sets none.
pub const MINIMIZE_MAX_ITERATIONS: usize = 2000;

impl NewtonSettings {
    /// The iteration cap: the configured one, else the default of a step or of a
    /// minimization.
    pub fn iteration_cap(&self, minimize: bool) -> usize {
        self.max_iterations
            .unwrap_or(if minimize { MINIMIZE_MAX_ITERATIONS } else { STEP_MAX_ITERATIONS })
    }
}

impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            max_iterations: None,
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
    /// Force level [N]: the relative force tolerance is taken of it.
    pub force: f64,
    /// Round-off floor of the residual [N], added to the tolerance.
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
    /// Whether the tangent last assembled is symmetric (then Cholesky may factor it).
    fn symmetric(&self) -> bool {
        true
    }
    /// The size of an increment `d` in metres, where some unknown is not a coordinate
    /// (displacement control's load factor): the step limit and the increment test
    /// measure lengths only. `None`: max |d_i|.
    fn length_of(&self, _d: &[f64]) -> Option<f64> {
        None
    }
    /// The potential whose gradient is −r, at `u`, for a problem that has one (a static
    /// equilibrium minimises its total potential energy); `None` otherwise.
    fn energy(&mut self, _u: &[f64]) -> Option<f64> {
        None
    }
    /// The largest fraction of the increment `d` from the point of the last `residual`
    /// call that the iterate may take: where bodies are in contact, the one that keeps them
    /// apart ([`crate::contact::ContactSet::admissible`]). Newton takes no more of an
    /// increment, and its line search starts there.
    fn admissible(&mut self, _u: &[f64], _d: &[f64]) -> f64 {
        1.0
    }
}

/// How a converged Newton solve went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NewtonReport {
    /// Newton iterations taken (0: the start point already met the tolerances).
    pub iterations: usize,
    /// Tangent factorizations (equal to `iterations` for full Newton).
    pub factorizations: usize,
    /// max |r| at the converged point [N].
    pub residual: f64,
}

/// Why a Newton solve failed; every DOF is a free-DOF index (`tsm::DofMap` names it).
#[derive(Debug, PartialEq)]
pub enum SolveError {
    /// The iteration cap was reached. Both criteria are kept: the force residual max|r|
    /// against `tolerance` [N], the last increment max|Δu| against `increment_tolerance`
    /// [m]; `worst_dof` has the largest residual.
    NotConverged {
        /// Iterations taken (the cap).
        iterations: usize,
        /// max |r| at the last iterate [N].
        residual: f64,
        /// The force tolerance it had to meet [N].
        tolerance: f64,
        /// max |Δu| of the last increment [m].
        increment: f64,
        /// The increment tolerance it had to meet [m].
        increment_tolerance: f64,
        /// The free DOF of the largest |r|.
        worst_dof: usize,
    },
    /// No part of a Newton step from a tangent built at the iterate, down to 1/256 of it,
    /// lowers ‖r‖₂ by the Armijo fraction ([`backtrack`]): the residual jumps or has no
    /// root along it, so iterating on cannot help.
    NoDescent {
        /// The iteration whose step found no descent.
        iterations: usize,
        /// max |r| at its iterate [N].
        residual: f64,
        /// The free DOF of the largest |r| there.
        worst_dof: usize,
    },
    /// The residual (or the increment) became inf/NaN; `dof`: its first non-finite entry.
    NonFinite {
        /// The iteration it happened in.
        iteration: usize,
        /// The first non-finite entry's free DOF, if found.
        dof: Option<usize>,
    },
    /// The tangent is singular at free DOF `dof` (see [`LinearError::Singular`]).
    Singular {
        /// The free DOF of the failed pivot, if the factorization names one.
        dof: Option<usize>,
        /// |pivot| / largest |pivot|, if measured.
        ratio: Option<f64>,
    },
    /// The tangent's sparse LU or GMRES solve could not allocate its memory (see
    /// [`LinearError::OutOfMemory`]): an environment's limit, not the equation's; a
    /// smaller step is not tried ([`StepFailure`]).
    OutOfMemory {
        /// The tangent's order (free DOFs).
        dofs: usize,
        /// What needed the memory (see [`LinearError::OutOfMemory`]).
        what: &'static str,
    },
}

impl SolveError {
    /// The free DOF the error is about (worst residual, non-finite entry, or singular
    /// pivot), for a caller that knows the model to name.
    pub fn dof(&self) -> Option<usize> {
        match *self {
            SolveError::NotConverged { worst_dof, .. } | SolveError::NoDescent { worst_dof, .. } => Some(worst_dof),
            SolveError::NonFinite { dof, .. } | SolveError::Singular { dof, .. } => dof,
            SolveError::OutOfMemory { .. } => None,
        }
    }
}

impl From<LinearError> for SolveError {
    fn from(error: LinearError) -> Self {
        match error {
            LinearError::Singular { dof, ratio } => SolveError::Singular { dof, ratio },
            LinearError::OutOfMemory { dofs, what } => SolveError::OutOfMemory { dofs, what },
        }
    }
}

/// A step halved where it failed may succeed: not where the failure was the machine's
/// memory. (A smaller Δt can make the step matrix positive definite, so Cholesky would
/// take it without the LU's memory, but that trades an environment's limit for steps
/// nobody asked for, each paying a failed LU first; the user's fix is memory.)
impl StepFailure for SolveError {
    fn smaller_step_may_help(&self) -> bool {
        !matches!(self, SolveError::OutOfMemory { .. })
    }
}

impl std::error::Error for SolveError {}

impl std::fmt::Display for SolveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe(None))
    }
}

impl SolveError {
    /// The message, with the DOF it is about called `label` ("node `t3` direction z")
    /// where the caller knows the model, else "free DOF 7".
    pub fn describe(&self, label: Option<&str>) -> String {
        let at = |dof: Option<usize>| label.map_or_else(|| dof_text(dof), str::to_string);
        match *self {
            SolveError::NotConverged {
                iterations,
                residual,
                tolerance,
                increment,
                increment_tolerance,
                worst_dof,
            } => {
                let force = |verb| format!("force residual {residual:.3e} N {verb} its tolerance {tolerance:.3e} N");
                let disp = |verb| format!("displacement increment {increment:.3e} m {verb} its tolerance {increment_tolerance:.3e} m");
                let (what, setting) = match (residual > tolerance, increment > increment_tolerance) {
                    (true, false) => (format!("{} ({})", force("exceeds"), disp("met")), "`newton.force_tolerance`"),
                    (false, true) => (format!("{} ({})", disp("exceeds"), force("met")), "`newton.displacement_tolerance`"),
                    // Both met is convergence, not an error.
                    _ => (
                        format!("{} and {}", force("exceeds"), disp("exceeds")),
                        "`newton.force_tolerance`, `newton.displacement_tolerance`",
                    ),
                };
                format!(
                    "Newton did not converge in {iterations} iteration{}: {what}; largest residual at {}; \
                     raise {setting} or `newton.max_iterations`",
                    if iterations == 1 { "" } else { "s" },
                    at(Some(worst_dof))
                )
            }
            SolveError::NoDescent {
                iterations,
                residual,
                worst_dof,
            } => format!(
                "Newton's step from iteration {iterations} (max|r| {residual:.3e} N) lowers the residual at no length down to \
                 1/256 of it: the equation jumps there, e.g. a cable going slack or taut; largest residual at {}",
                at(Some(worst_dof))
            ),
            SolveError::NonFinite { iteration, dof } => {
                format!(
                    "residual or increment became non-finite at {} in iteration {iteration} (diverged)",
                    at(dof)
                )
            }
            SolveError::Singular { dof, ratio } => format!(
                "singular tangent stiffness at {}{}: a mechanism or instability there",
                at(dof),
                ratio_text(ratio)
            ),
            SolveError::OutOfMemory { dofs, what } => format!(
                "{}: give the case more memory (fewer cases at once, `--jobs`; a higher limit, `ulimit -v`); \
                 `tsim check` estimates each case's memory",
                LinearError::OutOfMemory { dofs, what }
            ),
        }
    }
}

/// The Newton-Raphson driver: solves r(u) = 0 from the given `u` (updated in place).
/// Converged when max|r| ≤ tol_f·force + roundoff and the last increment max|Δu| ≤
/// tol_u·`length` (a start already in balance needs no increment). With reuse on, the
/// factorization held in `ws` (possibly from an earlier solve) is used while the residual
/// keeps falling [`REUSE_CONTRACTION`]-fold per iteration. On success the last
/// [`Residual::residual`] call was at the returned `u`, so the problem's state is the
/// converged one (a caller may commit it without evaluating again). Errors name a free
/// DOF by index ([`SolveError::dof`]); the caller knows the model that labels it.
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

/// max|v| and where it is, or `Err` with the first non-finite entry. (`f64::max` skips
/// NaN, so a fold with it reads an all-NaN vector as 0, i.e. converged.)
fn max_abs(v: &[f64]) -> Result<(f64, usize), usize> {
    let mut worst = (0.0, 0);
    for (i, &x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(i);
        }
        if x.abs() > worst.0 {
            worst = (x.abs(), i);
        }
    }
    Ok(worst)
}

/// Where a Newton solve has got to between iterations.
struct Progress {
    /// The last increment's length (max-norm, or the problem's [`Residual::length_of`]).
    increment: f64,
    /// The energy at the iterate, for a minimization; `None` otherwise.
    energy: Option<f64>,
    /// A minimization's last step lowered the energy by no more than its round-off and
    /// moved at least half as far as the one before.
    stalled: bool,
    /// How far the previous iteration moved (∞ before the first).
    last_moved: f64,
}

/// [`newton`]'s loop. At the residual's round-off floor a minimization also ends when it
/// has stalled ([`Progress::stalled`]). Newton's increments shrink quadratically on the way
/// to a minimum (a 4-strut prism's last ones lower the energy by less than its round-off
/// too); increments that stop shrinking there are noise through a direction softer than
/// K's round-off (a tall tower's measure structure, lowest eigenvalue ~1e-17 of its
/// largest).
fn iterate(
    problem: &mut impl Residual,
    u: &mut [f64],
    settings: &NewtonSettings,
    length: f64,
    ws: &mut NewtonWorkspace,
) -> Result<NewtonReport, SolveError> {
    ws.factorizations = 0;
    // max|r| before the last increment (∞ at the start: a held factorization gets a try).
    let mut previous = f64::INFINITY;
    let increment_tolerance = settings.displacement_tolerance * length;
    ws.history.clear();
    ws.energies.clear();
    let mut progress = Progress {
        increment: 0.0,
        energy: problem.energy(u),
        stalled: false,
        last_moved: f64::INFINITY,
    };
    ws.energies.extend(progress.energy);
    let cap = settings.iteration_cap(ws.minimize);
    // Whether this solve starts with the held factorization, until it is replaced.
    let mut on_held = ws.reuse && ws.factored && ws.held.attempt();
    if ws.reuse && !on_held {
        ws.factored = false;
    }
    // The residual's scale where the line search left r(u) in `ws.trial` ([`backtrack`]).
    let mut evaluated = None;
    for iteration in 0..=cap {
        let (scale, res, worst_dof) = evaluate(problem, u, ws, evaluated.take(), iteration)?;
        let tolerance = settings.force_tolerance * scale.force + scale.roundoff;
        let increment = progress.increment;
        let converged = res <= tolerance
            && settled(settings, res, previous, iteration == cap)
            && (iteration == 0 || increment <= increment_tolerance || progress.stalled);
        if converged || (iteration > 0 && res <= tolerance && frozen(increment, u)) {
            if on_held && iteration > 0 {
                ws.held.record(true);
            }
            return Ok(NewtonReport {
                iterations: iteration,
                factorizations: ws.factorizations,
                residual: res,
            });
        }
        if iteration == cap {
            return Err(SolveError::NotConverged {
                iterations: iteration,
                residual: res,
                tolerance,
                increment,
                increment_tolerance,
                worst_dof,
            });
        }
        let contracting = ws.reuse && ws.factored && res <= REUSE_CONTRACTION * previous;
        if !contracting && !correct_held(problem, ws) {
            if std::mem::take(&mut on_held) {
                ws.held.record(false);
            }
            factor_tangent(problem, ws, scale.force / length, progress.energy.is_some())?;
        }
        previous = res;
        // A tangent built at this iterate (not a held one that still contracts) gives a
        // direction along which the residual falls: the line search may shorten it.
        // Within the tolerance (`force_tolerance: 0`, iterating to round-off) there is
        // nothing for it to find.
        let fresh = !contracting && res > tolerance;
        evaluated = step(problem, u, settings.max_step * length, ws, &mut progress, (iteration, fresh))?;
    }
    unreachable!("the loop returns at its last iteration")
}

/// The residual at `u` into `ws.r` (or the one the line search left in `ws.trial`, where
/// `evaluated` gives its scale), recorded in the history: its scale, max-norm and where.
fn evaluate(
    problem: &mut impl Residual,
    u: &[f64],
    ws: &mut NewtonWorkspace,
    evaluated: Option<Scale>,
    iteration: usize,
) -> Result<(Scale, f64, usize), SolveError> {
    let scale = match evaluated {
        Some(scale) => {
            std::mem::swap(&mut ws.r, &mut ws.trial);
            scale
        }
        None => problem.residual(u, &mut ws.r),
    };
    let (res, worst_dof) = max_abs(&ws.r).map_err(|dof| {
        ws.history.push(ws.r[dof].abs());
        SolveError::NonFinite { iteration, dof: Some(dof) }
    })?;
    ws.history.push(res);
    Ok((scale, res, worst_dof))
}

/// Assembles the tangent at the iterate the last residual was evaluated at and factors
/// it: by a shifted Cholesky for a minimization (`minimizing`, the problem symmetric),
/// whose shift is relative to `stiffness` (the force scale over the model length).
fn factor_tangent(problem: &mut impl Residual, ws: &mut NewtonWorkspace, stiffness: f64, minimizing: bool) -> Result<(), SolveError> {
    ws.factored = false;
    assemble_tangent(problem, ws);
    if ws.minimize && problem.symmetric() && minimizing {
        ws.factorizations += shifted_cholesky(ws, stiffness)?;
    } else {
        ws.factorizations += 1;
        ws.solver.factor(problem.symmetric())?;
    }
    ws.factored = true;
    Ok(())
}

/// Assembles the tangent at the iterate the last residual was evaluated at into the
/// cleared solver, for a factorization that carries no low-rank correction yet.
fn assemble_tangent(problem: &mut impl Residual, ws: &mut NewtonWorkspace) {
    ws.solver.clear();
    match &mut ws.low_rank {
        Some(low_rank) => low_rank.assemble_factored(&mut *ws.solver, |k| problem.tangent(k)),
        None => problem.tangent(&mut *ws.solver),
    }
}

/// Where the held factorization has stopped contracting, corrects it for the elements
/// whose tangent blocks switched since it was factored (`low_rank.rs`); `false` where
/// there is none to correct, or a factorization is cheaper.
fn correct_held(problem: &mut impl Residual, ws: &mut NewtonWorkspace) -> bool {
    match &mut ws.low_rank {
        Some(low_rank) if ws.factored => low_rank.update(&mut *ws.solver, |k| problem.tangent(k)),
        _ => false,
    }
}

/// Solves for the increment from the residual in `ws.r` and moves `u` along it: by the
/// energy line search for a minimization, else by the whole increment, or the part of it
/// that moves no coordinate further than `max_step` [m], shortened by the residual's line
/// search ([`backtrack`]) where the tangent is `fresh`. Returns the residual's scale where
/// that search left the residual at the new `u` in `ws.trial`.
fn step(
    problem: &mut impl Residual,
    u: &mut [f64],
    max_step: f64,
    ws: &mut NewtonWorkspace,
    progress: &mut Progress,
    (iteration, fresh): (usize, bool),
) -> Result<Option<Scale>, SolveError> {
    ws.d.copy_from_slice(&ws.r);
    ws.solver.solve(&mut ws.d)?;
    ws.factorizations += ws.solver.take_late_factorizations();
    if let Some(low_rank) = &mut ws.low_rank {
        low_rank.correct(&mut ws.d);
    }
    let (increment, _) = max_abs(&ws.d).map_err(|dof| SolveError::NonFinite { iteration, dof: Some(dof) })?;
    progress.increment = problem.length_of(&ws.d).unwrap_or(increment);
    match progress.energy {
        Some(e0) => {
            let (moved, e, corrections) = line_search(problem, u, e0, ws)?;
            progress.stalled = e0 - e <= ENERGY_ROUNDOFF * e0.abs() && moved >= 0.5 * progress.last_moved;
            (progress.increment, progress.last_moved) = (moved, moved);
            ws.factorizations += corrections;
            progress.energy = Some(e);
            ws.energies.push(e);
        }
        None => {
            let damping = (max_step / progress.increment).min(1.0) * problem.admissible(u, &ws.d);
            axpy(u, damping, &ws.d);
            if fresh {
                return match backtrack(problem, u, ws, damping) {
                    Search::Accepted(scale) => Ok(Some(scale)),
                    Search::NotFinite => Ok(None),
                    Search::NoDescent => {
                        let (residual, worst_dof) = max_abs(&ws.r).unwrap_or((f64::NAN, 0));
                        Err(SolveError::NoDescent {
                            iterations: iteration,
                            residual,
                            worst_dof,
                        })
                    }
                };
            }
        }
    }
    Ok(None)
}

/// u += α d.
fn axpy(u: &mut [f64], alpha: f64, d: &[f64]) {
    for (ui, di) in u.iter_mut().zip(d) {
        *ui += alpha * di;
    }
}

/// The line search of a problem without a potential (a time step): `u` has moved by
/// `whole` along the Newton direction `ws.d` of a tangent built at its start, where the
/// residual was `ws.r`; the move is halved until ‖r‖₂ falls by the Armijo fraction,
/// ‖r(u + α d)‖₂ ≤ (1 − c α) ‖r(u)‖₂, at most [`MAX_BACKTRACKS`] times (Dennis &
/// Schnabel, Numerical Methods for Unconstrained Optimization and Nonlinear Equations,
/// §6.5: the Newton direction is a descent direction of ½‖r‖², and a search that finds
/// no acceptable point ends the solve). Where no length is acceptable the residual jumps
/// along the step (a cable going slack or taut) or has no root near, and the solve fails
/// ([`SolveError::NoDescent`]) for the step to be cut, where Newton would cycle across
/// the jump or creep towards it to the iteration cap.
///
/// Why: a large grid's first steps after a release switch thousands of cables slack or
/// taut per iteration, and whole Newton steps then overshoot; without it a 332 × 332
/// grid's first step wandered between max|r| 1e3 and 7e6 N to the 50-iteration cap (twice
/// in four steps: 100 failed iterations, 20 with the search; bench/pipeline.md). Where the
/// whole step lowers the residual (a converging Newton step always does), it is taken
/// unchanged: the paper's deployment is bit for bit as without the search.
fn backtrack(problem: &mut impl Residual, u: &mut [f64], ws: &mut NewtonWorkspace, whole: f64) -> Search {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let start = norm(&ws.r);
    let mut alpha = whole;
    let mut whole_finite = true;
    for k in 0..=MAX_BACKTRACKS {
        let scale = problem.residual(u, &mut ws.trial);
        let r = norm(&ws.trial);
        if r <= (1.0 - ARMIJO * alpha) * start {
            return Search::Accepted(scale);
        }
        whole_finite &= k > 0 || r.is_finite();
        alpha *= 0.5;
        axpy(u, -alpha, &ws.d);
    }
    if whole_finite {
        axpy(u, -alpha, &ws.d);
        Search::NoDescent
    } else {
        axpy(u, whole - alpha, &ws.d);
        Search::NotFinite
    }
}

/// How the residual's line search ended.
enum Search {
    /// At an acceptable length, the residual there in `ws.trial` with this scale.
    Accepted(Scale),
    /// At no acceptable length, and the whole step's residual is not finite: `u` at the
    /// whole step, where the next evaluation reports it ([`SolveError::NonFinite`]).
    NotFinite,
    /// At no acceptable length: `u` back at its start.
    NoDescent,
}

/// Halvings of the residual's line search: a direction along which ‖r‖₂ does not fall
/// within 1/256 of the step is not a descent direction there (a smooth residual's Newton
/// direction is one at every short enough length, the symmetric part of objective
/// damping's Jacobian too, its skew part being below a tenth of the mass term).
const MAX_BACKTRACKS: u32 = 8;

/// Whether a residual `res` within the tolerance may end the solve. With a force tolerance
/// the floor is all that is left, so yes. `force_tolerance: 0` asks for the residual
/// round-off leaves, which the floor only bounds (by 64 ε per term, so from above): the
/// solve goes on while an iteration still halves the residual ([`STALL`]), and ends at
/// the first that does not, at the cap, or at an exact zero. A conserving scheme's drift is
/// that residual's, step by step (`tests/free_bodies.rs`).
fn settled(settings: &NewtonSettings, res: f64, previous: f64, at_cap: bool) -> bool {
    settings.force_tolerance > 0.0 || res == 0.0 || at_cap || res > STALL * previous
}

/// An iteration that does not halve the residual has met round-off: Newton near a solution
/// cuts it far more (quadratically, or [`REUSE_CONTRACTION`]-fold on a held factorization).
const STALL: f64 = 0.5;

/// Whether an increment of max-norm `increment` at `u` moved no unknown by more than
/// [`FROZEN_ULPS`] ulps of the largest one (no iteration can change the iterate any more).
fn frozen(increment: f64, u: &[f64]) -> bool {
    let largest = u.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    increment <= FROZEN_ULPS * f64::EPSILON * largest
}

/// An ulp of the largest unknown is ε to 2ε times it; an increment of a few is the
/// round-off of the solve itself (the 105 × 105 grid's stalled steps, when a time step's
/// unknowns were its end coordinates: 1.42e-14 m at coordinates of 64 m, one ulp), where
/// a step that can still move is orders above.
const FROZEN_ULPS: f64 = 4.0;

/// Most tenfold increases of the shift τ before giving up: from τ0 = (force scale)/(model
/// size), a few N/m, 30 reach 1e30 τ0, beyond any stiffness a model has.
const MAX_SHIFTS: u32 = 30;

/// Factors the assembled K, or where it is not positive definite K + τI (Nocedal & Wright,
/// Numerical Optimization, §3.4, Cholesky with added multiple of the identity): τ starts
/// at a tenth of the last shift that was needed (or at `tau0`) and grows tenfold until
/// Cholesky succeeds. Returns the factorizations made.
///
/// Why: far from equilibrium K_T of form-finding is indefinite (the struts' compression
/// softens them sideways), and there the Newton direction may point uphill or towards a
/// saddle; reversing it (the line search's fallback) gives a poor descent direction, and
/// Newton may converge to a saddle, an unstable equilibrium (a 100-stage tower did both:
/// 303 iterations to a shape with K_T's lowest eigenvalue −8.5e3 N/m). The shifted
/// direction is a descent direction that moves little along the negative curvature; near
/// a minimum K is positive definite and the step is Newton's again.
fn shifted_cholesky(ws: &mut NewtonWorkspace, tau0: f64) -> Result<usize, SolveError> {
    if ws.solver.cholesky() {
        ws.shift = 0.0;
        return Ok(1);
    }
    let n = ws.r.len();
    let (mut tau, mut added) = (if ws.shift > 0.0 { ws.shift / 10.0 } else { tau0 }, 0.0);
    for tries in 1..=MAX_SHIFTS as usize {
        (0..n).for_each(|i| ws.solver.add(i, i, tau - added));
        added = tau;
        if ws.solver.cholesky() {
            ws.shift = tau;
            return Ok(1 + tries);
        }
        tau *= 10.0;
    }
    Err(SolveError::Singular { dof: None, ratio: None })
}

/// Sufficient decrease of the Armijo condition E(u + α d) ≤ E(u) + c α E'(0): the usual
/// small c (Nocedal & Wright, Numerical Optimization, §3.1: 1e-4), so that any step that
/// lowers the energy appreciably is taken whole.
const ARMIJO: f64 = 1e-4;
/// Halvings before the line search gives up looking for a decrease: 2^-40 ≈ 1e-12 of the
/// Newton step, below which only round-off is left to find.
const MAX_HALVINGS: u32 = 40;
/// Round-off of a potential summed over members, relative to its size: each term carries
/// a few ε and there are up to ~1e5 members; 1e-12 ≈ 4500 ε.
const ENERGY_ROUNDOFF: f64 = 1e-12;

/// Backtracking line search on the potential along the Newton direction `ws.d` from `u`
/// (updated to the accepted point), each trial with a Newton correction; returns the
/// largest coordinate change, the energy there and the factorizations the corrections
/// made.
///
/// Why: form-finding from an unbalanced shape, with struts ~1e9 times stiffer than the
/// cables, makes early Newton steps overshoot wildly; a fixed cap on the step length
/// (the earlier remedy) stalled on Table 1's uniform C. The potential decreases along
/// the Newton direction wherever the tangent is positive definite (E'(0) = −r·d < 0);
/// where it is not, Newton may point uphill and the direction is reversed, which is
/// downhill. The energy falls at every iteration, so the solve ends in a minimum of the
/// potential: a stable equilibrium. Near convergence the decrease is below the energy's
/// round-off, and the full Newton step is accepted within it.
///
/// The correction: a stiff strut is nearly a length constraint, and a straight step that
/// turns it lengthens it to second order, which its stiffness turns into a large energy
/// (the Maratos effect of constrained optimization): a plain Armijo search then accepts
/// only steps of ~1/64 of Newton's. So a trial point t = u + α d that does not lower the
/// energy enough is corrected by one Newton iteration from t, t + K(t)⁻¹ r(t) (a second
/// factorization, at t's geometry, so that the struts' directions are the new ones),
/// which restores the struts' lengths; the corrected point must pass the same test
/// (Nocedal & Wright, Numerical Optimization, §15.6, second-order correction).
fn line_search(problem: &mut impl Residual, u: &mut [f64], e0: f64, ws: &mut NewtonWorkspace) -> Result<(f64, f64, usize), SolveError> {
    let mut slope: f64 = -ws.r.iter().zip(&ws.d).map(|(r, d)| r * d).sum::<f64>();
    if slope > 0.0 {
        ws.d.iter_mut().for_each(|d| *d = -*d);
        slope = -slope;
    }
    let floor = ENERGY_ROUNDOFF * e0.abs();
    let (mut alpha, mut factorizations) = (problem.admissible(u, &ws.d), 0);
    for _ in 0..MAX_HALVINGS {
        let enough = e0 + ARMIJO * alpha * slope + floor;
        for ((t, ui), di) in ws.trial.iter_mut().zip(u.iter()).zip(&ws.d) {
            *t = ui + alpha * di;
        }
        let mut e = problem.energy(&ws.trial).unwrap_or(f64::NAN);
        if !(e <= enough) {
            factorizations += 1;
            e = corrected(problem, ws).unwrap_or(f64::NAN);
        }
        if e <= enough {
            let moved = ws.trial.iter().zip(u.iter()).fold(0.0_f64, |m, (t, ui)| m.max((t - ui).abs()));
            u.copy_from_slice(&ws.trial);
            return Ok((moved, e, factorizations));
        }
        alpha *= 0.5;
    }
    // No decrease at any length: stay (the next residual shows whether that converged).
    Ok((0.0, e0, factorizations))
}

/// Moves `ws.trial` by one Newton iteration from it, K(t)⁻¹ r(t), and returns the energy
/// there; `None` where the tangent at the trial point does not factor.
fn corrected(problem: &mut impl Residual, ws: &mut NewtonWorkspace) -> Option<f64> {
    problem.residual(&ws.trial, &mut ws.correction);
    assemble_tangent(problem, ws);
    ws.factored = ws.solver.factor(problem.symmetric()).is_ok();
    if !ws.factored || ws.solver.solve(&mut ws.correction).is_err() {
        return None;
    }
    let admissible = problem.admissible(&ws.trial, &ws.correction);
    for (t, c) in ws.trial.iter_mut().zip(&ws.correction) {
        *t += admissible * c;
    }
    problem.energy(&ws.trial)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// r(u) = a − u³: the tangent 3u² changes 25-fold between the roots 2 and 10, so a
    /// factorization held from one solve is a poor one for the next.
    struct Cubic {
        a: f64,
        u: f64,
        /// The floor it reports (0: none).
        roundoff: f64,
    }

    impl Residual for Cubic {
        fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
            self.u = u[0];
            r[0] = self.a - u[0].powi(3);
            Scale {
                force: self.a,
                roundoff: self.roundoff,
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
        let report = newton(&mut Cubic { a, u: u0, roundoff: 0.0 }, &mut u, &settings, 10.0, ws).unwrap();
        (u[0], report)
    }

    fn workspace(tangent: TangentUpdate) -> NewtonWorkspace {
        let settings = NewtonSettings {
            linear_solver: LinearSolverChoice::Dense,
            tangent,
            ..Default::default()
        };
        NewtonWorkspace::new(1, &settings, true, || Sparsity::amd(Vec::new()))
    }

    /// Tolerance 1e-10 × a on the residual, i.e. ~1e-10/3 relative on the root; 1e-10
    /// relative asks no more than that.
    fn assert_root(u: f64, a: f64) {
        assert!((u / a.cbrt() - 1.0).abs() < 1e-10, "root {u} of u³ = {a}");
    }

    /// r(u) = 1 − p(u) with p = u below 0 and 3u + 2 from 0: a jump of 2 at 0 and no
    /// root. Newton from −1 steps to 1 (|r| 4), which the line search halves twice to 0
    /// (|r| 1); from 0 its step to −1/3 raises |r| at every length (1 + α/3): the solve
    /// ends there, at iteration 1, where whole Newton steps went on cycling between −1/3
    /// and 1 (and were caught only when the residuals repeated, at iteration 4).
    struct Jump {
        u: f64,
    }

    impl Residual for Jump {
        fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
            self.u = u[0];
            r[0] = 1.0 - if u[0] < 0.0 { u[0] } else { 3.0 * u[0] + 2.0 };
            Scale { force: 1.0, roundoff: 0.0 }
        }

        fn tangent(&mut self, k: &mut dyn TangentSink) {
            k.add(0, 0, if self.u < 0.0 { 1.0 } else { 3.0 });
        }
    }

    #[test]
    fn a_step_across_a_jump_finds_no_descent() {
        for tangent in [TangentUpdate::Full, TangentUpdate::Reuse] {
            let mut ws = workspace(tangent);
            let settings = NewtonSettings {
                tangent,
                max_step: 1.0,
                ..Default::default()
            };
            let mut u = [-1.0];
            let error = newton(&mut Jump { u: -1.0 }, &mut u, &settings, 10.0, &mut ws).unwrap_err();
            let SolveError::NoDescent {
                iterations,
                residual,
                worst_dof,
            } = error
            else {
                panic!("{tangent:?}: {error:?}")
            };
            assert_eq!((iterations, worst_dof), (1, 0), "{tangent:?}");
            assert!((residual - 1.0).abs() < 1e-15, "{tangent:?}: {residual}");
            assert!(error.to_string().contains("lowers the residual at no length"), "{error}");
        }
    }

    /// r(u) = −atan(u), root 0: whole Newton steps from |u| > 1.39 overshoot further and
    /// further (the textbook case, Dennis & Schnabel §6.1); the residual's line search
    /// shortens them to steps that lower |r|, and Newton converges (whole steps:
    /// 3 → −9.5 → 124 → −2.4e4 → …).
    struct Atan {
        u: f64,
    }

    impl Residual for Atan {
        fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
            self.u = u[0];
            r[0] = -u[0].atan();
            Scale { force: 1.0, roundoff: 0.0 }
        }

        fn tangent(&mut self, k: &mut dyn TangentSink) {
            k.add(0, 0, 1.0 / (1.0 + self.u * self.u));
        }
    }

    #[test]
    fn the_residual_line_search_converges_where_whole_newton_steps_diverge() {
        for tangent in [TangentUpdate::Full, TangentUpdate::Reuse] {
            let mut ws = workspace(tangent);
            let settings = NewtonSettings {
                tangent,
                max_step: 100.0,
                ..Default::default()
            };
            let mut u = [3.0];
            let report = newton(&mut Atan { u: 3.0 }, &mut u, &settings, 1.0, &mut ws).unwrap_or_else(|e| panic!("{tangent:?}: {e}"));
            // Tolerance 1e-10 on |atan u| ≈ |u|.
            assert!(u[0].abs() < 1e-10, "{tangent:?}: {u:?}");
            // Full Newton: every iterate's |r| below the one before, the search took no step
            // that raised it. (A held factorization's steps are not searched: one may raise
            // |r|, and the next iteration then builds the tangent afresh.)
            let falling = ws.history.windows(2).all(|w| w[1] < w[0] || w[1] == 0.0);
            assert!(falling || tangent == TangentUpdate::Reuse, "{tangent:?}: {:?}", ws.history);
            assert!(report.iterations < 15, "{tangent:?}: {report:?}");
        }
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

    /// A held factorization that fails at a solve's start makes the next solve start with a
    /// fresh one, even where the held one would do; the solve after tries it again.
    #[test]
    fn a_failed_held_start_makes_the_next_solve_start_fresh() {
        let mut ws = workspace(TangentUpdate::Reuse);
        let (u, _) = solve(8.0, 1.5, TangentUpdate::Reuse, &mut ws);
        let (u, far) = solve(1000.0, u, TangentUpdate::Reuse, &mut ws);
        assert!(far.factorizations >= 1, "{far:?}");
        // The tangent at u = 10 (300) is within 1 % of the one at the next root: held, it
        // would converge without a factorization.
        let (u, fresh) = solve(1010.0, u, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 1010.0);
        assert_eq!(fresh.factorizations, 1, "{fresh:?}");
        let (u, held) = solve(1020.0, u, TangentUpdate::Reuse, &mut ws);
        assert_root(u, 1020.0);
        assert_eq!(held.factorizations, 0, "{held:?}");
    }

    /// `force_tolerance: 0` goes on below a floor that overstates round-off (1e-3 N on
    /// r = 8 − u³, whose round-off is ~1e-15 N) until an iteration no longer halves the
    /// residual, where a tolerance stops at the first residual under the floor. A loose
    /// increment test (1e-3 of the length 10) leaves the force test alone to decide.
    #[test]
    fn tolerance_zero_iterates_to_round_off() {
        let run = |force_tolerance| {
            let settings = NewtonSettings {
                force_tolerance,
                displacement_tolerance: 1e-3,
                max_step: 1.0,
                linear_solver: LinearSolverChoice::Dense,
                tangent: TangentUpdate::Full,
                ..Default::default()
            };
            let mut ws = NewtonWorkspace::new(1, &settings, false, || Sparsity::amd(Vec::new()));
            let mut problem = Cubic {
                a: 8.0,
                u: 1.5,
                roundoff: 1e-3,
            };
            let report = newton(&mut problem, &mut [1.5], &settings, 10.0, &mut ws).unwrap();
            (report, ws.history.clone())
        };
        let (floored, _) = run(1e-10);
        let (exact, history) = run(0.0);
        // From 1.5 Newton's residuals are 4.6, 2.4, 0.18, 1.5e-3, ~1e-7: the floor stops
        // it at the last, which round-off does not limit.
        assert!(floored.residual > 1e-9 && floored.residual <= 1e-3, "{floored:?}");
        // 8 − u³ at the double nearest 2 is within a few ulps of 8 (ε·8 = 1.8e-15).
        assert!(exact.residual <= 1e-14, "{exact:?}, residuals {history:?}");
        let [before, last] = history[history.len() - 2..] else {
            unreachable!()
        };
        assert!(last == 0.0 || last > STALL * before, "stopped while still converging: {history:?}");
    }

    /// A residual `first` at the first evaluation and `later` after, whatever u is, but
    /// for a fall by a factor 1 − 1e-3 at each evaluation (which passes the residual's
    /// line search); tangent `stiffness`·I (a wrong one on purpose).
    struct Scripted {
        first: [f64; 2],
        later: [f64; 2],
        stiffness: f64,
        calls: usize,
    }

    impl Residual for Scripted {
        fn residual(&mut self, _u: &[f64], r: &mut [f64]) -> Scale {
            let fall = (1.0 - 1e-3_f64).powi(self.calls as i32);
            let values = if self.calls == 0 { &self.first } else { &self.later };
            r.iter_mut().zip(values).for_each(|(r, v)| *r = fall * v);
            self.calls += 1;
            Scale { force: 1.0, roundoff: 0.0 }
        }

        fn tangent(&mut self, k: &mut dyn TangentSink) {
            k.add(0, 0, self.stiffness);
            k.add(1, 1, self.stiffness);
        }
    }

    fn run(first: [f64; 2], later: [f64; 2], stiffness: f64) -> Result<NewtonReport, SolveError> {
        let settings = NewtonSettings {
            max_iterations: Some(5),
            ..Default::default()
        };
        let mut ws = NewtonWorkspace::new(2, &settings, false, || Sparsity::amd(Vec::new()));
        let mut problem = Scripted {
            first,
            later,
            stiffness,
            calls: 0,
        };
        newton(&mut problem, &mut [0.0; 2], &settings, 1.0, &mut ws)
    }

    /// Tolerances: 1e-10 N (force scale 1) and 1e-10 m (length 1).
    #[test]
    fn not_converged_names_the_failed_criterion_and_the_worst_dof() {
        // A residual of 2 N that the stiff tangent turns into 2e-20 m increments.
        let force = run([1.0, -2.0], [1.0, -2.0], 1e20).unwrap_err();
        assert!(
            matches!(
                force,
                SolveError::NotConverged {
                    iterations: 5,
                    worst_dof: 1,
                    ..
                }
            ),
            "{force:?}"
        );
        assert_eq!(force.dof(), Some(1));
        let text = force.to_string();
        assert!(
            text.contains("did not converge") && text.contains("force residual 1.990e0 N exceeds"),
            "{text}"
        );
        assert!(text.contains("displacement increment 1.992e-20 m met"), "{text}");
        assert!(
            text.contains("`newton.force_tolerance`") && !text.contains("`newton.displacement_tolerance`"),
            "{text}"
        );
        assert!(text.contains("`newton.max_iterations`") && text.contains("free DOF 1"), "{text}");

        // After the start a residual of 2e-12 N that the soft tangent turns into 2e-6 m.
        let disp = run([1.0, -2.0], [2e-12, 1e-12], 1e-6).unwrap_err();
        assert!(matches!(disp, SolveError::NotConverged { worst_dof: 0, .. }), "{disp:?}");
        let text = disp.to_string();
        assert!(
            text.contains("did not converge") && text.contains("displacement increment 1.992e-6 m exceeds"),
            "{text}"
        );
        assert!(text.contains("force residual 1.990e-12 N met"), "{text}");
        assert!(
            text.contains("`newton.displacement_tolerance`") && !text.contains("`newton.force_tolerance`"),
            "{text}"
        );

        let both = run([1.0, -2.0], [1.0, -2.0], 1.0).unwrap_err().to_string();
        assert!(
            both.contains("force residual 1.990e0 N exceeds") && both.contains("displacement increment 1.992e0 m exceeds"),
            "{both}"
        );
        assert!(both.contains("`newton.force_tolerance`, `newton.displacement_tolerance`"), "{both}");
    }

    #[test]
    fn a_nan_residual_is_non_finite_not_converged() {
        let nan = [f64::NAN; 2];
        assert_eq!(
            run(nan, nan, 1.0),
            Err(SolveError::NonFinite {
                iteration: 0,
                dof: Some(0)
            })
        );
        let err = run([1.0, -2.0], [1.0, f64::NAN], 1.0).unwrap_err();
        assert_eq!(
            err,
            SolveError::NonFinite {
                iteration: 1,
                dof: Some(1)
            }
        );
        assert_eq!(err.dof(), Some(1));
    }

    /// A tangent of 1e-300 overflows the increment of the 2e10 N residual at DOF 0 to ∞
    /// (the one of the 1e-10 N residual at DOF 1 stays finite), which must not pass for
    /// an increment (before the fix: damped to zero, then not converged).
    #[test]
    fn a_non_finite_increment_is_non_finite() {
        let r = [2e10, 1e-10];
        assert_eq!(
            run(r, r, 1e-300),
            Err(SolveError::NonFinite {
                iteration: 0,
                dof: Some(0)
            })
        );
    }
}
