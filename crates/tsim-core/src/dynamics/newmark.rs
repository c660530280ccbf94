use super::{Rayleigh, RestSchedule};
use crate::solve::{
    bisect, newton, NewtonReport, NewtonSettings, NewtonWorkspace, Residual, Scale, SolveError, TangentSink, REUSE_CONTRACTION,
};
use crate::tsm::{
    assemble_tangents, block_product, damping_moduli, member_damping_all, scaled_blocks, tangent_sparsity, taut_members, Assembly,
    DampingModulus, EndSlots, MemberDamping, MemberState, ObjectiveDamping,
};
use nalgebra::{Matrix3, Vector3};

/// The energy ledger of one converged step [J].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Energy {
    pub kinetic: f64,
    pub strain: f64,
    /// Dissipated by damping since the stage began.
    pub damping: f64,
    /// Work of external loads (and, in folding, of prescribed displacements) since the stage began.
    pub external: f64,
    /// Work done on the members by changing their rest lengths since the stage began,
    /// ∫ Σ ∂U/∂l0 dl0 (actuators; zero where no rest length changes).
    pub actuation: f64,
}

/// Newmark-β integration parameters; the defaults of every transient stage's config.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewmarkParams {
    /// β = 1/4 with γ = 1/2 is the average-acceleration rule: unconditionally stable, no
    /// numerical damping, energy-conserving on linear problems.
    pub beta: f64,
    pub gamma: f64,
    /// Time step Δt [s] (paper: 0.001).
    pub dt: f64,
    /// A step whose Newton solve fails is halved, up to this many times (2^cuts sub-steps),
    /// before the stage fails.
    pub max_cuts: u32,
}

impl Default for NewmarkParams {
    fn default() -> Self {
        NewmarkParams {
            beta: 0.25,
            gamma: 0.5,
            dt: 0.001,
            max_cuts: 6,
        }
    }
}

/// Rayleigh damping and the stiffness its βK term is evaluated with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Damping {
    pub rayleigh: Rayleigh,
    pub tangent: DampingTangent,
}

/// Everything a Newmark integrator is set up with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Integrator {
    pub params: NewmarkParams,
    pub damping: Damping,
    /// Newton settings of every step (tolerances, linear solver, tangent reuse).
    pub newton: NewtonSettings,
}

/// How the stiffness-proportional term β·K of Rayleigh damping acts.
///
/// The paper writes C = αM + βK with K the tangent stiffness; for large motion it leaves
/// open which K. `Objective` (the default) damps each member's extension rate along its
/// current direction, scaled by its material tangent: f = β (dN/dl) l̇ e. A rigid-body
/// motion gets no damping force, the dissipated power β (dN/dl) l̇² is never negative, and
/// about a fixed state it is β K_0 v (K_T without its geometric part). A tension-only
/// member keeps the branch (taut or slack) of the step's start for dN/dl, so that the step
/// equation stays continuous where it goes slack (`tsm::DampingModulus`). Its Jacobian in
/// the Newmark step is exact and not symmetric, so steps are factored by LU, or by
/// Cholesky on its symmetric part where the skew part is small against the mass term.
///
/// The other three apply β K_T(x)·v with K_T at some state, as the paper does. None is
/// objective: a rigidly rotating member gets an apparent axial rate (from the lagged or
/// frozen direction) and a lateral force from K_G, so the path depends on Δt (measured on
/// the paper's deployment: docs/validation.md). They are kept to reproduce the paper.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DampingTangent {
    #[default]
    Objective,
    /// K_T of the stage's initial state, frozen (misdirects damping across large motion).
    Initial,
    /// K_T of the last converged step: constant within a step, so the Jacobian is exact.
    LastConverged,
    /// K_T of the current iterate; the Jacobian omits ∂K_T/∂x · v (it is not symmetric).
    Current,
}

/// The work of step attempts whose Newton solve failed, so that the step was cut in
/// halves: no converged report counts it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Retried {
    pub attempts: usize,
    pub iterations: usize,
    pub factorizations: usize,
}

/// Largest estimated contraction per Newton iteration, ‖S‖/λ_min, for which a step with
/// objective damping is solved with the symmetric part of its Jacobian (Cholesky) instead of
/// the whole (LU); S is the skew part ([`ObjectiveDamping::skew_bound`], a Gershgorin bound) and
/// λ_min ≥ min m (1/(βΔt²) + α γ/(βΔt)), the step matrix's mass term (K_T's part taken as
/// non-negative). The same contraction a held factorization must show to be kept
/// ([`REUSE_CONTRACTION`]): an iteration matrix that is at least that close to the Jacobian
/// is as good as a reused one. The residual is exact, so converged states meet the same
/// tolerances; where the iteration converges more slowly than estimated (a step through an
/// unstable state), a step that fails is cut, which shrinks the estimate 4-fold per halving.
/// Measured (bench/pipeline.md): a 47 × 47 steel-cable grid deploying estimates 0.7–1.2e-2
/// and takes the same 202 Newton iterations for 50 steps either way, in 4.8 s instead of
/// 11.5 s; the paper's deployment, 36 512 iterations instead of 36 925.
const SYMMETRIC_CONTRACTION: f64 = REUSE_CONTRACTION;

/// State and integrator of one time-stepping stage on the free DOFs. Every buffer a step
/// needs is allocated here, once: a step allocates nothing.
pub struct Newmark<'a> {
    pub asm: Assembly<'a>,
    pub params: NewmarkParams,
    pub rayleigh: Rayleigh,
    pub tangent: DampingTangent,
    /// Newton settings of every step (tolerances; the linear solver and tangent reuse
    /// were fixed with the workspace).
    newton: NewtonSettings,
    /// Lumped mass per free DOF [kg].
    pub mass: Vec<f64>,
    /// Free coordinates, velocities, accelerations of the last converged state.
    pub u: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    /// External force on the free DOFs at the last converged time.
    f: Vec<f64>,
    /// Damping force the last converged equation used.
    fd: Vec<f64>,
    /// Member states whose K_T the βK term uses (unused for `Current`).
    damp_states: Vec<MemberState>,
    /// β k per member of the βK term's states ([`scaled_blocks`]; unused for `Objective`):
    /// re-formed when those states change, not at every residual.
    damp_blocks: Vec<Matrix3<f64>>,
    /// The members' free end directions, for the βK product.
    ends: EndSlots,
    /// Per member, whether it was taut at the step's start, and its damping modulus at the
    /// current states on that branch (`Objective` only; [`DampingModulus`]).
    taut: Vec<bool>,
    moduli: Vec<DampingModulus>,
    /// Objective damping: whether the step matrix last assembled is the Jacobian's symmetric
    /// part ([`SYMMETRIC_CONTRACTION`]), the largest estimated contraction for which it may
    /// be, and a per-node buffer of the estimate.
    symmetric_step: bool,
    symmetric_below: f64,
    node_skew: Vec<f64>,
    /// Rest lengths that change over the stage; `None` where none does.
    actuation: Option<Actuation>,
    /// l̇0/l0 per member at the end of the step being solved (objective damping strains
    /// only what the rest length does not take up); empty without actuation.
    rest_rate: Vec<f64>,
    /// Energy ledger since the stage began.
    pub energy: Energy,
    /// Failed step attempts since the stage began.
    pub retried: Retried,
    /// KE + SE at the start of the stage: the balance is KE + SE + D − W − E0.
    pub initial_energy: f64,
    pub time: f64,
    /// The Newton workspace, taken out while a step runs.
    ws: Option<NewtonWorkspace>,
    /// Step size of the step matrix whose factorization `ws` may hold.
    ws_dt: f64,
    /// Step buffers: predictor base, trial coordinates, load, velocities and damping force.
    base: Vec<f64>,
    trial: Vec<f64>,
    f_next: Vec<f64>,
    v_next: Vec<f64>,
    fd_next: Vec<f64>,
    /// The accelerations of the two converged states before the last, for the predictor.
    history: History,
}

/// A stage's rest-length schedule and what the ledger keeps of it between steps.
struct Actuation {
    schedule: RestSchedule,
    /// Rest lengths of the last converged state [m], and those of the step being solved.
    rest: Vec<f64>,
    rest_next: Vec<f64>,
    /// ∂U/∂l0 of every member at the last converged state [N], and a buffer for the next.
    force: Vec<f64>,
    force_next: Vec<f64>,
    /// l̇0/l0 just after the last converged time (the start of the next step) [1/s].
    rate_after: Vec<f64>,
}

impl Actuation {
    /// The trapezoidal work Σ ½ (q_n + q_{n+1}) (l0_{n+1} − l0_n) of the step that converged
    /// at `asm` (q = ∂U/∂l0), which then becomes the last converged state. With the
    /// trapezoidal work of the nodal forces this is the trapezoidal rule along the step's
    /// straight path in (x, l0): the ledger closes to the rule's O(Δt²).
    fn commit(&mut self, asm: &Assembly) -> f64 {
        asm.energy_rest_derivatives(&mut self.force_next);
        let work = (self.force.iter().zip(&self.force_next))
            .zip(self.rest.iter().zip(&self.rest_next))
            .map(|((q0, q1), (l0, l1))| 0.5 * (q0 + q1) * (l1 - l0))
            .sum();
        std::mem::swap(&mut self.force, &mut self.force_next);
        std::mem::swap(&mut self.rest, &mut self.rest_next);
        work
    }
}

/// Accelerations a_{n−1} and a_{n−2} of the converged states before the last one, and how
/// many steps of size `dt` in a row led to the last ([`Newmark::predict`]).
struct History {
    previous: Vec<f64>,
    before: Vec<f64>,
    dt: f64,
    steps: usize,
}

impl History {
    /// Makes way for the acceleration of a step of size `dt` converging now: `a` (a_n)
    /// becomes a_{n−1}, a_{n−1} becomes a_{n−2}, and `a` is left with stale values for
    /// the caller to overwrite with a_{n+1}.
    fn push(&mut self, a: &mut Vec<f64>, dt: f64) {
        std::mem::swap(&mut self.before, &mut self.previous);
        std::mem::swap(&mut self.previous, a);
        self.steps = if dt == self.dt { self.steps + 1 } else { 1 };
        self.dt = dt;
    }
}

impl<'a> Newmark<'a> {
    /// Starts at the state of `asm` with velocities `v` under external force `f0`, with
    /// the consistent initial acceleration a0 = M⁻¹(f0 − C v0 − p(x0)).
    pub fn new(asm: Assembly<'a>, mass: Vec<f64>, v: Vec<f64>, f0: Vec<f64>, integrator: &Integrator) -> Self {
        Self::actuated(asm, mass, v, f0, integrator, None)
    }

    /// [`Self::new`] with rest lengths that follow `schedule` over the stage (from its
    /// value at t = 0).
    pub fn actuated(
        mut asm: Assembly<'a>,
        mass: Vec<f64>,
        v: Vec<f64>,
        f0: Vec<f64>,
        integrator: &Integrator,
        schedule: Option<RestSchedule>,
    ) -> Self {
        let members = asm.states.len();
        let actuation = schedule.map(|schedule| {
            let mut rest = vec![0.0; members];
            schedule.at(0.0, &mut rest);
            asm.set_rest(&rest);
            asm.update();
            let mut force = vec![0.0; members];
            asm.energy_rest_derivatives(&mut force);
            let mut rate_after = vec![0.0; members];
            schedule.relative_rate(0.0, false, &mut rate_after);
            Actuation {
                schedule,
                rest_next: rest.clone(),
                rest,
                force_next: force.clone(),
                force,
                rate_after,
            }
        });
        // From t = 0 on: the rate after it.
        let rest_rate = actuation.as_ref().map_or(Vec::new(), |a| a.rate_after.clone());
        let n = mass.len();
        let u = asm.free_coordinates();
        let Integrator { params, damping, newton } = *integrator;
        let ws = Some(NewtonWorkspace::new(n, &newton, true, || tangent_sparsity(asm.model, asm.dofs)));
        let mut s = Newmark {
            damp_states: asm.states.clone(),
            damp_blocks: vec![Matrix3::zeros(); asm.states.len()],
            ends: EndSlots::new(asm.model, asm.dofs),
            taut: vec![true; asm.states.len()],
            moduli: vec![DampingModulus::default(); asm.states.len()],
            symmetric_step: false,
            symmetric_below: SYMMETRIC_CONTRACTION,
            node_skew: vec![0.0; asm.model.node_count()],
            actuation,
            rest_rate,
            asm,
            params,
            rayleigh: damping.rayleigh,
            tangent: damping.tangent,
            newton,
            mass,
            u,
            v,
            a: vec![0.0; n],
            f: f0,
            fd: vec![0.0; n],
            energy: Energy::default(),
            retried: Retried::default(),
            initial_energy: 0.0,
            time: 0.0,
            ws,
            ws_dt: params.dt,
            base: vec![0.0; n],
            trial: vec![0.0; n],
            f_next: vec![0.0; n],
            v_next: vec![0.0; n],
            fd_next: vec![0.0; n],
            history: History {
                previous: vec![0.0; n],
                before: vec![0.0; n],
                dt: params.dt,
                steps: 0,
            },
        };
        s.update_damping_blocks();
        s.keep_branches();
        s.consistent_acceleration();
        s.energy = s.ledger_now(0.0, 0.0, 0.0);
        s.initial_energy = s.energy.kinetic + s.energy.strain;
        s
    }

    /// The damping force at the current state and velocities, and the acceleration
    /// a = M⁻¹(f − f_d − p) that satisfies the equation of motion with it.
    fn consistent_acceleration(&mut self) {
        let (v, mut fd) = (std::mem::take(&mut self.v), std::mem::take(&mut self.fd));
        self.damping_force(&v, &mut fd);
        (self.v, self.fd) = (v, fd);
        for i in 0..self.mass.len() {
            self.a[i] = (self.f[i] - self.fd[i] - self.asm.p_free(i)) / self.mass[i];
        }
    }

    /// Sets the members' rest lengths at the end of the step to `t_next` and their rates
    /// there. Where the rate jumps at the step's start t_n (an actuator starting or
    /// stopping), the damping force jumps with it: the step then starts from the damping
    /// force and acceleration just after t_n, as the equation of motion gives them there.
    /// Carrying the values from before the jump into the step would make its error O(Δt)
    /// and the scheme first order in Δt (measured: position differences halving, not
    /// quartering, as Δt halves).
    fn actuate(&mut self, t_next: f64) {
        let Some(a) = &mut self.actuation else { return };
        a.schedule.relative_rate(self.time, false, &mut a.rate_after);
        let jumped = a.rate_after != self.rest_rate;
        if jumped {
            self.rest_rate.copy_from_slice(&a.rate_after);
        }
        a.schedule.at(t_next, &mut a.rest_next);
        if jumped {
            self.consistent_acceleration();
        }
        let Some(a) = &mut self.actuation else { return };
        a.schedule.relative_rate(t_next, true, &mut self.rest_rate);
        // From the step's first residual on (branches were kept at its start).
        self.asm.set_rest(&a.rest_next);
    }

    /// Starts from a = 0 instead of the consistent acceleration (`initial.acceleration:
    /// zero`). The equation of motion at t = 0 then holds for the force M·0 + C v0 + p(x0),
    /// not for the load f0: the first step's trapezoidal work counts that force at t = 0,
    /// as it counts every force the equations used, so the ledger keeps closing.
    pub fn start_with_zero_acceleration(&mut self) {
        self.a.fill(0.0);
        for i in 0..self.mass.len() {
            self.f[i] = self.fd[i] + self.asm.p_free(i);
        }
    }

    /// External force on the free DOFs at the last converged time [N].
    pub fn external_force(&self) -> &[f64] {
        &self.f
    }

    /// Member states the βK term uses now.
    fn damping_states(&self) -> &[MemberState] {
        match self.tangent {
            DampingTangent::Current | DampingTangent::Objective => &self.asm.states,
            DampingTangent::Initial | DampingTangent::LastConverged => &self.damp_states,
        }
    }

    /// Re-forms `damp_blocks` from the states the βK term uses now.
    fn update_damping_blocks(&mut self) {
        let states = match self.tangent {
            DampingTangent::Objective => return,
            DampingTangent::Current => &self.asm.states,
            DampingTangent::Initial | DampingTangent::LastConverged => &self.damp_states,
        };
        scaled_blocks(states, self.rayleigh.beta, &mut self.damp_blocks);
    }

    /// Objective damping: every member keeps its branch (taut or slack) of the current
    /// states until the next call, at the start of a step ([`DampingModulus`]).
    fn keep_branches(&mut self) {
        if self.tangent == DampingTangent::Objective {
            taut_members(&self.asm.elements.laws, &self.asm.rest, &self.asm.states, &mut self.taut);
            self.update_moduli();
        }
    }

    /// Objective damping: the members' damping moduli at the current states.
    fn update_moduli(&mut self) {
        if self.tangent == DampingTangent::Objective {
            damping_moduli(
                &self.asm.elements.laws,
                &self.asm.rest,
                &self.asm.states,
                &self.taut,
                &mut self.moduli,
            );
        }
    }

    /// The Rayleigh damping force α M v + the β term (per `tangent`) on the free DOFs at
    /// velocities `v` into `out`.
    fn damping_force(&mut self, v: &[f64], out: &mut [f64]) {
        for i in 0..v.len() {
            out[i] = self.rayleigh.alpha * self.mass[i] * v[i];
        }
        let asm = &self.asm;
        match self.tangent {
            DampingTangent::Objective => ObjectiveDamping {
                model: asm.model,
                dofs: asm.dofs,
                states: &asm.states,
                moduli: &self.moduli,
                v,
                beta: self.rayleigh.beta,
                rest_rate: &self.rest_rate,
            }
            .add_force(out),
            _ => block_product(&self.damp_blocks, &mut self.ends, v, out),
        }
    }

    fn ledger_now(&self, damping: f64, external: f64, actuation: f64) -> Energy {
        Energy {
            kinetic: 0.5 * self.mass.iter().zip(&self.v).map(|(m, v)| m * v * v).sum::<f64>(),
            strain: self.asm.strain_energy(),
            damping,
            external,
            actuation,
        }
    }

    /// The stiffness-proportional (β) damping force of the last converged step on all 3n
    /// node directions into `out`, as its equation had it (member states, moduli or βK
    /// blocks): on the free directions it is the β part of the damping force the step
    /// balanced, on the supported ones what the members' damping forces put into the
    /// supports. The αM part acts on the free directions only (a support does not move
    /// relative to the base). Summed over `members` only (model order): a direction gets its
    /// whole force where all its node's members are among them. `velocities`: the step's
    /// velocities `v` on the nodes (zero at fixed directions).
    pub fn member_damping_force(&self, members: &[usize], velocities: &[Vector3<f64>], out: &mut [f64]) {
        out.fill(0.0);
        let damping = match self.tangent {
            DampingTangent::Objective => MemberDamping::Objective {
                moduli: &self.moduli,
                beta: self.rayleigh.beta,
                rest_rate: &self.rest_rate,
            },
            _ => MemberDamping::Blocks(&self.damp_blocks),
        };
        member_damping_all(self.asm.model, members, &self.asm.states, damping, velocities, out);
    }

    /// |KE + SE + D − W − W_a − E0| (W_a: the actuators' work): zero for exact
    /// integration of the ledger.
    pub fn balance_error(&self) -> f64 {
        let e = &self.energy;
        (e.kinetic + e.strain + e.damping - e.external - e.actuation - self.initial_energy).abs()
    }

    /// Every member's rest length now [m] (the elements' own where none changes).
    pub fn rest_lengths(&self) -> &[f64] {
        &self.asm.rest
    }

    /// Whether some member's rest length follows a schedule in this stage.
    pub fn is_actuated(&self) -> bool {
        self.actuation.is_some()
    }

    /// Advances by `dt`, cutting the step in halves (up to `max_cuts` halvings deep) where
    /// Newton fails. `load(t, f)` writes the external force on the free DOFs at time t.
    pub fn advance(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) -> Result<NewtonReport, SolveError> {
        let merge = |first: NewtonReport, second: NewtonReport| NewtonReport {
            iterations: first.iterations + second.iterations,
            factorizations: first.factorizations + second.factorizations,
            residual: second.residual,
        };
        let max_cuts = self.params.max_cuts;
        let mut step = |from: f64, to: f64| self.step(dt * (to - from), load);
        bisect(0.0, 1.0, max_cuts, &mut step, &merge).map(|(report, _)| report)
    }

    /// Newmark's velocity at the end of a step of size dt ending at coordinates `u`, into
    /// `v_next`: v_{n+1} = v_n + Δt((1 − γ) a_n + γ a_{n+1}), a_{n+1} = (u − base)/(βΔt²).
    fn next_velocity(&mut self, u: &[f64], dt: f64) {
        let (beta, gamma) = (self.params.beta, self.params.gamma);
        let c_a = 1.0 / (beta * dt * dt);
        let (v, a, base) = (&self.v, &self.a, &self.base);
        for (i, v_next) in self.v_next.iter_mut().enumerate() {
            *v_next = v[i] + dt * ((1.0 - gamma) * a[i] + gamma * (c_a * (u[i] - base[i])));
        }
    }

    /// Sets up the step to t + dt: the load at its end and the predictor.
    /// u_{n+1} = base + β dt² a_{n+1}, base = u_n + dt v_n + dt² (½ − β) a_n. Newton starts,
    /// in `trial`, from a_{n+1} = a_n + a_{n−1} − a_{n−2} where the last two steps were of
    /// this dt, else from a_{n+1} = a_n (constant acceleration, the usual predictor).
    ///
    /// Why: with γ = ½ the scheme maps a stiff component (ω Δt ≫ 1: a strut's axial
    /// stretching; damped or not) to an oscillation of period 2Δt, its amplification
    /// factor tending to −1, while the motion itself is smooth. The three-point guess is
    /// exact for both, a linear trend and a constant alternation (the difference two steps
    /// apart cancels the alternation), where a_n misses the alternation by twice its
    /// amplitude. The starting point changes only the iterations, never the tolerances
    /// the converged step meets. Measured on configs/bench_elastic.yaml's deployment
    /// (8000 steps): the first residual falls from 286 N to 0.35 N at t = 1 s, Newton
    /// iterations 17 945 → 10 451, factorizations 5 867 → 3 784; the paper's case
    /// (configs/paper.yaml, 19 000 steps of free vibration and deployment) 40 002 → 28 424
    /// iterations. (a_{n−1} alone, exact for the alternation only: 15 402 iterations on the
    /// benchmark, 39 765 on the paper's case.)
    fn predict(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) {
        load(self.time + dt, &mut self.f_next);
        let beta = self.params.beta;
        let history = self.history.steps >= 2 && self.history.dt == dt;
        for i in 0..self.mass.len() {
            self.base[i] = self.u[i] + dt * self.v[i] + dt * dt * (0.5 - beta) * self.a[i];
            let guess = if history {
                self.a[i] + self.history.previous[i] - self.history.before[i]
            } else {
                self.a[i]
            };
            self.trial[i] = self.base[i] + beta * dt * dt * guess;
        }
    }

    /// One Newmark step of size dt; on failure the state is left as it was.
    fn step(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) -> Result<NewtonReport, SolveError> {
        if self.tangent == DampingTangent::LastConverged {
            // K_T of the last converged state (`asm` holds it between steps). Taken here, not
            // at the end of the previous step, so that between steps `damp_states` are still
            // those the last converged equation used (`member_damping_force`).
            self.damp_states.copy_from_slice(&self.asm.states);
            self.update_damping_blocks();
        }
        self.keep_branches();
        let n = self.mass.len();
        let t_next = self.time + dt;
        let beta = self.params.beta;
        self.actuate(t_next);
        self.predict(dt, load);
        let length = self.asm.model.size();
        let mut trial = std::mem::take(&mut self.trial);
        let mut ws = self.ws.take().expect("workspace present between steps");
        if dt != self.ws_dt {
            // M/(βΔt²) dominates the step matrix: a factorization for another Δt is no use.
            ws.invalidate();
            self.ws_dt = dt;
        }
        let settings = self.newton;
        let result = newton(&mut StepProblem { nm: self, dt }, &mut trial, &settings, length, &mut ws);
        let (iterations, factorizations) = ws.last_effort();
        self.ws = Some(ws);
        let report = match result {
            Ok(report) => report,
            Err(e) => {
                self.retried.attempts += 1;
                self.retried.iterations += iterations;
                self.retried.factorizations += factorizations;
                self.trial = trial;
                if let Some(a) = &self.actuation {
                    // The start state's rest lengths, and its rate from the step's side.
                    self.asm.set_rest(&a.rest);
                    self.rest_rate.copy_from_slice(&a.rate_after);
                }
                let Newmark { asm, u, .. } = self;
                asm.set_free(u);
                return Err(e);
            }
        };
        // Commit: positions, accelerations, velocities, damping force, energy ledger. The
        // last residual was evaluated at `trial` (`newton` ends on it): `asm`, the damping
        // moduli and blocks, `v_next` and `fd_next` hold the converged step's values.
        let c_a = 1.0 / (beta * dt * dt);
        let (mut dw, mut dd) = (0.0, 0.0);
        self.history.push(&mut self.a, dt);
        for (a, (u, base)) in self.a.iter_mut().zip(trial.iter().zip(&self.base)) {
            *a = c_a * (u - base);
        }
        let mut fd_next = std::mem::take(&mut self.fd_next);
        // Trapezoidal work of the forces each equation actually used: with average
        // acceleration this is the discrete energy identity of the scheme.
        for i in 0..n {
            let du = trial[i] - self.u[i];
            dw += 0.5 * (self.f[i] + self.f_next[i]) * du;
            dd += 0.5 * (self.fd[i] + fd_next[i]) * du;
        }
        std::mem::swap(&mut self.u, &mut trial);
        std::mem::swap(&mut self.v, &mut self.v_next);
        std::mem::swap(&mut self.f, &mut self.f_next);
        std::mem::swap(&mut self.fd, &mut fd_next);
        self.trial = trial;
        self.fd_next = fd_next;
        self.time = t_next;
        let actuated = self.actuation.as_mut().map_or(0.0, |a| a.commit(&self.asm));
        let (d, w, wa) = (
            self.energy.damping + dd,
            self.energy.external + dw,
            self.energy.actuation + actuated,
        );
        self.energy = self.ledger_now(d, w, wa);
        Ok(report)
    }
}

/// The nonlinear equation of one step: r(u) = f − M a(u) − C v(u) − p(u), with
/// a = (u − base)/(β dt²), v = v_n + dt((1−γ) a_n + γ a); Jacobian
/// K_T + M/(β dt²) + (γ/(β dt)) C (for `Current`, less ∂K_T/∂u · v).
struct StepProblem<'s, 'a> {
    nm: &'s mut Newmark<'a>,
    dt: f64,
}

impl StepProblem<'_, '_> {
    /// The Newmark coefficients c_a = 1/(βΔt²) and c_v = γ/(βΔt) of a = c_a (u − base) and
    /// the step's velocity.
    fn coefficients(&self) -> (f64, f64) {
        let (beta, gamma, dt) = (self.nm.params.beta, self.nm.params.gamma, self.dt);
        (1.0 / (beta * dt * dt), gamma / (beta * dt))
    }
}

impl Residual for StepProblem<'_, '_> {
    fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
        let (c_a, c_v) = self.coefficients();
        let nm = &mut *self.nm;
        nm.asm.set_free(u);
        if nm.tangent == DampingTangent::Current {
            nm.update_damping_blocks();
        }
        nm.update_moduli();
        nm.next_velocity(u, self.dt);
        let n = u.len();
        let (v_next, mut fd) = (std::mem::take(&mut nm.v_next), std::mem::take(&mut nm.fd_next));
        nm.damping_force(&v_next, &mut fd);
        nm.v_next = v_next;
        let (mut applied, mut inertia_floor) = (0.0_f64, 0.0_f64);
        for i in 0..n {
            let m = nm.mass[i];
            let inertia = m * c_a * (u[i] - nm.base[i]);
            r[i] = nm.f_next[i] - inertia - fd[i] - nm.asm.p_free(i);
            applied = applied.max(nm.f_next[i].abs()).max(inertia.abs());
            inertia_floor = inertia_floor.max(m * c_a * u[i].abs());
        }
        nm.fd_next = fd;
        // The inertia term differences absolute coordinates: its round-off is
        // m/(βΔt²)·ε·|u|, which for small steps or far-from-origin nodes exceeds the
        // members' floor. 64 ε as for the members. The damping force does so through the
        // velocity γ/(βΔt)·(u − …): β_R γ/(βΔt) times the members' floor, α_R γ/(βΔt)
        // times m ε |u|. Those count at a frozen iterate only: a 105 × 105 grid
        // (β_R γ/(βΔt) = 42) stalled 3 % above the floor without them at 4 of 1000 steps,
        // each cut after 50 iterations, while counted everywhere they let the paper's
        // deployment stop 3 times further from full Newton's path (tests/pipeline.rs
        // `newmark_newton_floor_with_stiffness_damping`).
        let scale = nm.asm.scale(applied);
        let Rayleigh { alpha, beta } = nm.rayleigh;
        let inertia = 64.0 * f64::EPSILON * inertia_floor;
        Scale {
            roundoff: scale.roundoff + inertia,
            frozen: beta.abs() * c_v * scale.roundoff + alpha.abs() * c_v / c_a * inertia,
            ..scale
        }
    }

    /// K_T + M (c_a + α_R c_v) + the β_R term's derivative: β_R c_v K_T(damping states)
    /// for the paper-style variants, the exact objective-damping block otherwise.
    fn tangent(&mut self, k: &mut dyn TangentSink) {
        let (c_a, c_v) = self.coefficients();
        let nm = &mut *self.nm;
        let (alpha_r, beta_r) = (nm.rayleigh.alpha, nm.rayleigh.beta);
        let (model, dofs) = (nm.asm.model, nm.asm.dofs);
        if nm.tangent == DampingTangent::Objective {
            let damping = ObjectiveDamping {
                model,
                dofs,
                states: &nm.asm.states,
                moduli: &nm.moduli,
                v: &nm.v_next,
                beta: beta_r,
                rest_rate: &nm.rest_rate,
            };
            let mass_term = nm.mass.iter().fold(f64::INFINITY, |m, &mi| m.min(mi)) * (c_a + alpha_r * c_v);
            nm.symmetric_step = damping.skew_bound(&mut nm.node_skew) <= nm.symmetric_below * mass_term;
            assemble_tangents(model, dofs, &[(&nm.asm.states, 1.0)], k);
            damping.add_jacobian(c_v, nm.symmetric_step, k);
        } else {
            assemble_tangents(model, dofs, &[(&nm.asm.states, 1.0), (nm.damping_states(), beta_r * c_v)], k);
        }
        for (i, m) in nm.mass.iter().enumerate() {
            k.add(i, i, m * (c_a + alpha_r * c_v));
        }
    }

    /// Objective damping's block is not symmetric, unless the step matrix is its symmetric
    /// part ([`SYMMETRIC_CONTRACTION`]).
    fn symmetric(&self) -> bool {
        self.nm.tangent != DampingTangent::Objective || self.nm.rayleigh.beta == 0.0 || self.nm.symmetric_step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{Actuator, TimeFunction};
    use crate::law::{ForceLaw, LinearElastic, OgdenCord};
    use crate::model::generate::TowerSpec;
    use crate::model::MemberKind;
    use crate::solve::LinearSolverChoice;
    use crate::tsm::{DofMap, Elements};
    use faer::Mat;
    use std::sync::Arc;

    /// A 3-strut prism out of balance (struts at their nominal length, EA = 1e5 N; Ogden
    /// cables at stretch 1.2), unit nodal masses, strong Rayleigh damping, moved two steps
    /// under a sideways load so that v and a are non-zero and the tangents differ; with
    /// `actuate`, the cables' rest lengths shrink by half over 0.1 s as it moves (so that
    /// the rest-length rate enters the step's damping force and Jacobian).
    fn moving_prism(tangent: DampingTangent, actuate: bool, run: impl FnOnce(&mut Newmark)) {
        let model = TowerSpec {
            struts: 3,
            ..TowerSpec::paper()
        }
        .build();
        let x0 = model.positions();
        let strut: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
            ea: 1e5,
            tension_only: false,
        });
        let cable: Arc<dyn ForceLaw> = Arc::new(OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1));
        let (laws, rest): (Vec<_>, Vec<f64>) = model
            .members
            .iter()
            .map(|m| {
                let l = (x0[m.nodes[1]] - x0[m.nodes[0]]).norm();
                match m.kind {
                    MemberKind::Strut => (strut.clone(), l),
                    MemberKind::Cable => (cable.clone(), l / 1.2),
                }
            })
            .unzip();
        let schedule = actuate.then(|| {
            let cables = (0..model.members.len())
                .filter(|&m| model.members[m].kind == MemberKind::Cable)
                .collect();
            let ramp = Actuator {
                members: cables,
                scale: 0.5,
                time: TimeFunction::Ramp { duration: 0.1 },
            };
            RestSchedule::new(rest.clone(), vec![ramp])
        });
        let elements = Elements { laws, rest };
        let dofs = DofMap::new(&model, &[]);
        let asm = Assembly::new(&model, &elements, &dofs, x0);
        let n = dofs.len();
        let integrator = Integrator {
            params: NewmarkParams {
                dt: 0.01,
                ..Default::default()
            },
            damping: Damping {
                rayleigh: Rayleigh { alpha: 0.5, beta: 0.01 },
                tangent,
            },
            newton: NewtonSettings {
                linear_solver: LinearSolverChoice::Dense,
                ..Default::default()
            },
        };
        let mut nm = Newmark::actuated(asm, vec![1.0; n], vec![0.0; n], vec![0.0; n], &integrator, schedule);
        let push = |t: f64, f: &mut [f64]| {
            f.iter_mut()
                .enumerate()
                .for_each(|(i, fi)| *fi = if i % 3 == 0 { 5.0 * (1.0 + t) } else { 0.0 })
        };
        for _ in 0..2 {
            nm.advance(0.01, &push).unwrap();
        }
        nm.predict(0.01, &push);
        run(&mut nm);
    }

    /// The step tangent against the central-difference Jacobian −∂r/∂u at a trial point
    /// off the predictor, for every damping tangent. `Current` leaves out ∂K_T/∂x · v
    /// (the term is not symmetric, and the symmetric solvers would need LU for it); the
    /// test computes that term independently, by central differences of the βK product at
    /// frozen velocities, and checks that it is exactly what is missing. `Objective` is
    /// checked twice: exact (LU), and as the Jacobian's symmetric part ½ (J + Jᵀ), which
    /// it assembles where the skew part is small ([`SYMMETRIC_CONTRACTION`]); the skew part
    /// must be large enough here to tell the two apart.
    ///
    /// Tolerance: h = 1e-6 m; the truncation error h²/6 · |∂³r| is below 1e-9 N/m here,
    /// the round-off ε |r| / h with |r| ≲ 1e5 N (inertia m/(βΔt²) · u, u ~ 3 m) is ~2e-5
    /// N/m; 1e-3 N/m leaves margin and is 1e-7 of the largest entry (m/(βΔt²) = 4e4 N/m),
    /// while the omitted term of `Current` is ~10 N/m and a wrong Newmark coefficient
    /// shows at the size of the mass or damping terms.
    #[test]
    fn step_jacobian_matches_finite_differences() {
        for (tangent, symmetric_below, actuate) in [
            (DampingTangent::Objective, 0.0, false),
            (DampingTangent::Objective, f64::INFINITY, false),
            (DampingTangent::Objective, 0.0, true),
            (DampingTangent::Objective, f64::INFINITY, true),
            (DampingTangent::Initial, 0.0, false),
            (DampingTangent::LastConverged, 0.0, false),
            (DampingTangent::Current, 0.0, false),
            (DampingTangent::Current, 0.0, true),
        ] {
            moving_prism(tangent, actuate, |nm| {
                assert_eq!(nm.rest_rate.iter().any(|&r| r != 0.0), actuate);
                nm.symmetric_below = symmetric_below;
                let n = nm.mass.len();
                let dt = 0.01;
                let u: Vec<f64> = nm.trial.iter().enumerate().map(|(i, t)| t + 1e-3 * ((i * 7) % 5) as f64).collect();
                let mut problem = StepProblem { nm, dt };
                let mut r = vec![0.0; n];
                problem.residual(&u, &mut r);
                let mut k = Mat::<f64>::zeros(n, n);
                problem.tangent(&mut k);
                let symmetrized = problem.symmetric() && tangent == DampingTangent::Objective;
                assert_eq!(symmetrized, symmetric_below > 0.0, "{tangent:?}");
                let v_frozen = problem.nm.v_next.clone();
                let mut blocks = problem.nm.damp_blocks.clone();
                let mut ends = EndSlots::new(problem.nm.asm.model, problem.nm.asm.dofs);
                let h = 1e-6;
                let (mut rp, mut rm, mut gp, mut gm) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                // The expected tangent, column by column, and the largest omitted term.
                let mut expected = Mat::<f64>::zeros(n, n);
                let mut omitted_size: f64 = 0.0;
                for j in 0..n {
                    let (mut up, mut um) = (u.clone(), u.clone());
                    up[j] += h;
                    um[j] -= h;
                    problem.residual(&up, &mut rp);
                    let nm = &*problem.nm;
                    gp.fill(0.0);
                    scaled_blocks(&nm.asm.states, nm.rayleigh.beta, &mut blocks);
                    block_product(&blocks, &mut ends, &v_frozen, &mut gp);
                    problem.residual(&um, &mut rm);
                    let nm = &*problem.nm;
                    gm.fill(0.0);
                    scaled_blocks(&nm.asm.states, nm.rayleigh.beta, &mut blocks);
                    block_product(&blocks, &mut ends, &v_frozen, &mut gm);
                    for i in 0..n {
                        let exact = -(rp[i] - rm[i]) / (2.0 * h);
                        let omitted = (gp[i] - gm[i]) / (2.0 * h);
                        omitted_size = omitted_size.max(omitted.abs());
                        expected[(i, j)] = if tangent == DampingTangent::Current {
                            exact - omitted
                        } else {
                            exact
                        };
                    }
                }
                let mut skew: f64 = 0.0;
                if symmetrized {
                    let whole = expected.clone();
                    for (i, j) in (0..n).flat_map(|i| (0..n).map(move |j| (i, j))) {
                        expected[(i, j)] = 0.5 * (whole[(i, j)] + whole[(j, i)]);
                        skew = skew.max((whole[(i, j)] - expected[(i, j)]).abs());
                    }
                    assert!(skew > 1.0, "the skew part is only {skew:e} N/m");
                }
                let worst = (0..n)
                    .flat_map(|i| (0..n).map(move |j| (i, j)))
                    .fold(0.0_f64, |w, (i, j)| w.max((k[(i, j)] - expected[(i, j)]).abs()));
                assert!(worst < 1e-3, "{tangent:?}: tangent differs from −∂r/∂u by {worst:e} N/m");
                // The omitted term is large enough that the check above tells it apart.
                assert!(omitted_size > 1.0, "{tangent:?}: ∂K_T/∂x·v only {omitted_size:e} N/m");
            });
        }
    }

    /// The predictor starts from a_n + a_{n−1} − a_{n−2} after two steps of the step's
    /// size, and from a_n for a step of another size and for the first one after a size
    /// change (the accelerations recorded here, the same arithmetic: equal to the bit).
    #[test]
    fn the_predictor_extrapolates_over_steps_of_the_same_size() {
        moving_prism(DampingTangent::LastConverged, false, |nm| {
            let zero = |_: f64, f: &mut [f64]| f.fill(0.0);
            let (dt, beta) = (0.01, nm.params.beta);
            let mut a = vec![nm.a.clone()];
            for _ in 0..2 {
                nm.advance(dt, &zero).unwrap();
                a.push(nm.a.clone());
            }
            let started = |nm: &Newmark, dt: f64, guess: &dyn Fn(usize) -> f64| {
                (0..nm.a.len()).all(|i| nm.trial[i] == nm.base[i] + beta * dt * dt * guess(i))
            };
            nm.predict(dt, &zero);
            assert!(started(nm, dt, &|i| a[2][i] + a[1][i] - a[0][i]));
            nm.predict(dt / 2.0, &zero);
            assert!(started(nm, dt / 2.0, &|i| a[2][i]));
            nm.advance(dt / 2.0, &zero).unwrap();
            let a3 = nm.a.clone();
            nm.predict(dt / 2.0, &zero);
            assert!(started(nm, dt / 2.0, &|i| a3[i]));
            assert!(a3.iter().zip(&a[2]).any(|(x, y)| x != y), "the accelerations change");
        });
    }

    /// A step commits what its last residual computed instead of evaluating again: the
    /// committed member states, internal force, velocities and damping force must be
    /// exactly (bitwise) those of a fresh evaluation at the committed coordinates.
    #[test]
    fn a_step_commits_the_state_of_a_fresh_evaluation() {
        for (tangent, actuate) in [
            (DampingTangent::Objective, false),
            (DampingTangent::Objective, true),
            (DampingTangent::Initial, false),
            (DampingTangent::LastConverged, false),
            (DampingTangent::Current, false),
        ] {
            moving_prism(tangent, actuate, |nm| {
                let asm = &nm.asm;
                let fresh = Assembly::with_rest_lengths(asm.model, asm.elements, asm.dofs, asm.x.clone(), &asm.rest);
                assert_eq!((&fresh.states, &fresh.p), (&nm.asm.states, &nm.asm.p), "{tangent:?}");
                assert_eq!(nm.asm.strain_energy(), nm.energy.strain, "{tangent:?}");
                let mut fd = vec![0.0; nm.v.len()];
                nm.damping_force(&nm.v.clone(), &mut fd);
                assert_eq!(fd, nm.fd, "{tangent:?}");
            });
        }
    }

    /// The actuated prism, damped, integrated over 0.2 s (the cables' rest lengths halve
    /// over the first 0.1 s, then hold) at Δt = 4, 2, 1 ms. The ledger KE + SE + D − W −
    /// W_a − E0 is the trapezoidal rule's error along each step: it must fall about
    /// 4-fold per halving (second order; ≥ 3 allows for the pre-asymptotic range), and at
    /// 1 ms be ≤ 1e-6 of the actuators' work. The end positions' differences between
    /// successive Δt fall about 4-fold too (Richardson's ratio for a second-order scheme).
    #[test]
    fn actuated_ledger_closes_and_converges_at_second_order() {
        let run = |dt: f64| {
            let mut end = (Vec::new(), 0.0, 0.0);
            moving_prism(DampingTangent::Objective, true, |nm| {
                // The sideways load goes on: a load that stops at a step's start would make the
                // step first order (its acceleration jumps).
                let push = |t: f64, f: &mut [f64]| {
                    f.iter_mut()
                        .enumerate()
                        .for_each(|(i, fi)| *fi = if i % 3 == 0 { 5.0 * (1.0 + t) } else { 0.0 })
                };
                let balance = |e: &Energy| e.kinetic + e.strain + e.damping - e.external - e.actuation;
                // moving_prism took two 10 ms steps already (their ledger error is the same
                // for every Δt here): the ledger's change from t = 0.02 s on.
                let (start, work0) = (balance(&nm.energy), nm.energy.actuation);
                let mut worst: f64 = 0.0;
                for _ in 0..((0.18 / dt).round() as usize) {
                    nm.advance(dt, &push).unwrap();
                    worst = worst.max((balance(&nm.energy) - start).abs());
                }
                assert!(nm.energy.damping > 0.0);
                end = (nm.u.clone(), worst, nm.energy.actuation - work0);
            });
            end
        };
        let runs: Vec<_> = [4e-3, 2e-3, 1e-3].into_iter().map(run).collect();
        let ledger: Vec<f64> = runs.iter().map(|r| r.1).collect();
        let work = runs[2].2.abs();
        assert!(
            ledger[0] / ledger[1] > 3.0 && ledger[1] / ledger[2] > 3.0,
            "ledger errors {ledger:?}"
        );
        // Measured: 2.54, 0.636, 0.159 J against 1686 J of actuator work (9.4e-5 at 1 ms, the
        // cables halving in 0.1 s against stiff struts); 1e-3 says only that the error is
        // the integration's, not a term missing from the ledger (that would be O(work)).
        assert!(ledger[2] < 1e-3 * work, "ledger {:e} J against {work:e} J", ledger[2]);
        let gap = |a: &[f64], b: &[f64]| a.iter().zip(b).fold(0.0_f64, |g, (x, y)| g.max((x - y).abs()));
        let (coarse, fine) = (gap(&runs[0].0, &runs[1].0), gap(&runs[1].0, &runs[2].0));
        assert!(coarse / fine > 3.0, "position differences {coarse:e}, {fine:e}");
    }

    #[test]
    fn a_cable_snapping_taut_keeps_its_slack_branch_for_the_step() {
        snapping_cable(DampingTangent::Objective, 0, |mut nm, (ea, m, dt, v0, s)| {
            assert_eq!(nm.a, [0.0], "slack at the start: no force");
            let report = nm.advance(dt, &|_, _| ()).expect("the step converges uncut");
            let (c_a, k) = (4.0 / (dt * dt), ea);
            let base = 1.0 - s + v0 * dt;
            let expected = (m * c_a * base + k) / (m * c_a + k);
            assert!((nm.u[0] - expected).abs() < 1e-12, "x = {}, closed form {expected}", nm.u[0]);
            assert!(report.iterations <= 3, "{report:?}");
            assert_eq!(nm.moduli[0].stiffness, 0.0, "damped on the slack branch of the step's start");
            // The next step starts taut: damped by β EA/l0 again.
            nm.advance(dt, &|_, _| ()).expect("second step");
            assert!(nm.u[0] > 1.0 && nm.moduli[0].stiffness == ea, "{:?}", nm.moduli[0]);
            assert_eq!(nm.retried, Retried::default());
        });
    }

    /// The same snap with the paper's β K_T(x)·v at the current iterate, whose K_T jumps
    /// where the cable goes taut: the whole step has no root and is cut; the failed
    /// attempts' work is kept in `retried` (each ran to the iteration cap, 50).
    #[test]
    fn failed_step_attempts_are_counted() {
        snapping_cable(DampingTangent::Current, 6, |mut nm, (_, _, dt, _, _)| {
            let report = nm.advance(dt, &|_, _| ()).expect("the step converges in parts");
            let r = nm.retried;
            assert!(r.attempts >= 1, "{r:?}");
            assert!(
                r.iterations >= 50 * r.attempts && r.factorizations >= r.attempts,
                "{r:?}, {report:?}"
            );
        });
    }

    /// One free DOF: a node of mass m on a tension-only cable (k = EA/l0, l0 = 1 m) from a
    /// fixed node, starting slack at x = 1 − s and moving out at V with a = 0,
    /// s = ¾ VΔt, with β-only Rayleigh damping by `tangent`; `run` gets the integrator and
    /// (EA, m, Δt, V, s).
    fn snapping_cable(tangent: DampingTangent, max_cuts: u32, run: impl FnOnce(Newmark, (f64, f64, f64, f64, f64))) {
        use crate::model::{Member, Model, Node};
        let node = |id: &str, x: f64, support: [bool; 3]| Node {
            id: id.into(),
            xyz: nalgebra::Vector3::new(x, 0.0, 0.0),
            support,
        };
        let (ea, m, dt, v0, beta_r) = (1e4, 1.0, 0.01, 0.1, 0.1);
        let s = 0.75 * v0 * dt;
        let model = Model {
            nodes: vec![node("a", 0.0, [true; 3]), node("b", 1.0 - s, [false, true, true])],
            members: vec![Member {
                id: "c".into(),
                nodes: [0, 1],
                kind: MemberKind::Cable,
                groups: Vec::new(),
            }],
            node_groups: Default::default(),
        };
        let elements = Elements {
            laws: vec![Arc::new(LinearElastic { ea, tension_only: true })],
            rest: vec![1.0],
        };
        let dofs = DofMap::new(&model, &[]);
        let asm = Assembly::new(&model, &elements, &dofs, model.positions());
        let integrator = Integrator {
            params: NewmarkParams {
                dt,
                max_cuts,
                ..Default::default()
            },
            damping: Damping {
                rayleigh: Rayleigh { alpha: 0.0, beta: beta_r },
                tangent,
            },
            newton: NewtonSettings {
                linear_solver: LinearSolverChoice::Dense,
                ..Default::default()
            },
        };
        run(Newmark::new(asm, vec![m], vec![v0], vec![0.0], &integrator), (ea, m, dt, v0, s));
    }
}
