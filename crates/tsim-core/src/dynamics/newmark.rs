use super::actuation::Actuation;
use super::ledger::{trapezoidal_work, Ledger};
use super::midpoint_ends::MidpointEnds;
use super::step_control::{AutoStep, ErrorEstimate};
use super::viscous::{SnapRule, Viscous};
use super::{Energy, Rayleigh, RestSchedule};
use crate::solve::{
    bisect, newton, KrylovEffort, NewtonReport, NewtonSettings, NewtonWorkspace, Residual, Scale, ScaledSink, SolveError, TangentSink,
};
use crate::tsm::{tangent_sparsity, Assembly, EnergyMomentum};
use nalgebra::Vector3;

/// Newmark-β integration parameters; the defaults of every transient stage's config.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewmarkParams {
    /// β = 1/4 with γ = 1/2 is the average-acceleration rule: unconditionally stable, no
    /// numerical damping, energy-conserving on linear problems.
    pub beta: f64,
    /// γ; above 1/2 it adds numerical damping.
    pub gamma: f64,
    /// Time step Δt [s] (paper: 0.001).
    pub dt: f64,
    /// A step whose Newton solve fails is halved, up to this many times (2^cuts sub-steps),
    /// before the stage fails.
    pub max_cuts: u32,
    /// `dt: auto`: steps sized by a local error estimate ([`Newmark::advance_auto`]), `dt`
    /// unused; `None`: steps of `dt`.
    pub auto: Option<AutoStep>,
    /// Where a step's equation of motion holds: at its end (Newmark) or at its midpoint.
    pub scheme: Scheme,
}

/// Where each step imposes the equation of motion.
///
/// `Newmark` (the paper's, the default): at the step's end, M a_{n+1} = f_{n+1} − f_d − p(x_{n+1}),
/// with β and γ. With β = 1/4, γ = 1/2 (the trapezoidal rule) the members' central forces
/// are taken at the step's two ends, and Σ x̄ × (f_n + f_{n+1}) over the mean positions is
/// not zero: angular momentum drifts at O(Δt²) (Simo & Tarnow 1992).
///
/// `Midpoint`: the implicit midpoint rule, M (v_{n+1} − v_n)/Δt = ½ (f_n + f_{n+1})
/// − f_d − p at x_{n+½} = ½ (x_n + x_{n+1}) and v_{n+½} = (x_{n+1} − x_n)/Δt, with
/// x_{n+1} − x_n = Δt v_{n+½}. Every member force, elastic and viscous, is central at
/// x_{n+½}, so Σ x_{n+½} × (Δt forces) = 0 and angular momentum is conserved exactly
/// (to Newton's residual: `newton.force_tolerance: 0` takes it to round-off), as linear
/// momentum is by both. Second order, symplectic,
/// and on a linear structure the same steps as the trapezoidal rule; β and γ do not apply.
/// Its step matrix is half the trapezoidal one at the midpoint (one factorization a step,
/// as Newmark's). Not for stiff members that rotate fast: the end state
/// x_{n+1} = 2 x_{n+½} − x_n lengthens a member turning at ω by l ω²Δt²/8 (the chord of
/// an arc), which its EA turns into a recorded force (76 kN in a strut of the paper
/// deployment at Δt = 2 ms; docs/dt_auto.md).
///
/// `EnergyMomentum`: the midpoint rule with each member's elastic force S d_{n+½}, S the
/// strain energy's change over the step per Δ(l²/2) (Simo & Tarnow 1992; Gonzalez 1996;
/// `tsm::EnergyMomentum`): still central at x_{n+½}, so angular momentum is kept, and its
/// work over a step is the energy's change, so the energy ledger closes to Newton's
/// residual (undamped: energy conserved). The force comes from the end lengths, so a
/// rotating strut has no chord error. Its step matrix is not symmetric (LU).
///
/// Both midpoint schemes balance nothing at the step's end: with objective damping the
/// viscous forces they record there are extrapolated from the midpoints' ([`MidpointEnds`]),
/// and they take fixed steps (the config refuses `dt: auto`, whose estimate judges the
/// end state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Newmark-β: the equation of motion at the step's end.
    #[default]
    Newmark,
    /// The implicit midpoint rule: the equation at the step's midpoint, angular momentum
    /// conserved.
    Midpoint,
    /// The midpoint rule with each member's force in energy–momentum form: angular
    /// momentum and, undamped, energy conserved; no chord error on rotating members.
    EnergyMomentum,
}

impl Scheme {
    /// Whether the step's equation holds at its midpoint.
    fn at_midpoint(self) -> bool {
        self != Scheme::Newmark
    }
}

impl Default for NewmarkParams {
    fn default() -> Self {
        NewmarkParams {
            beta: 0.25,
            gamma: 0.5,
            dt: 0.001,
            max_cuts: 6,
            auto: None,
            scheme: Scheme::Newmark,
        }
    }
}

impl NewmarkParams {
    /// β and γ of the step's kinematics, a = (u − base)/(βΔt²) and
    /// v_{n+1} = v_n + Δt((1 − γ) a_n + γ a): the midpoint rule is β = ½, γ = 1 with
    /// a = (v_{n+1} − v_n)/Δt, the acceleration at the midpoint.
    fn kinematics(&self) -> (f64, f64) {
        match self.scheme {
            Scheme::Newmark => (self.beta, self.gamma),
            Scheme::Midpoint | Scheme::EnergyMomentum => (0.5, 1.0),
        }
    }

    /// The fraction of a step at which its equation of motion holds (its rest lengths and
    /// their rate are taken there): 1 for Newmark, ½ for the midpoint rule.
    fn equation_at(&self) -> f64 {
        match self.scheme {
            Scheme::Newmark => 1.0,
            Scheme::Midpoint | Scheme::EnergyMomentum => 0.5,
        }
    }

    /// C of the local position error C Δt³ x''' a step makes (Zienkiewicz & Xie 1991):
    /// β − 1/6 for Newmark; 1/12 for the midpoint rule (x_{n+1} = x_n + Δt v_n +
    /// ½Δt² a(t_{n+½}) against the Taylor series' ½Δt² a_n + Δt³/6 ȧ: Δt³ (¼ − 1/6) ȧ),
    /// that of the trapezoidal rule.
    fn error_constant(&self) -> f64 {
        match self.scheme {
            Scheme::Newmark => self.beta - 1.0 / 6.0,
            Scheme::Midpoint | Scheme::EnergyMomentum => 1.0 / 12.0,
        }
    }
}

/// Rayleigh damping and the stiffness its βK term is evaluated with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Damping {
    /// C = αM + βK coefficients.
    pub rayleigh: Rayleigh,
    /// Which K the βK term uses.
    pub tangent: DampingTangent,
}

/// Everything a Newmark integrator is set up with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Integrator {
    /// β, γ, Δt and step cuts.
    pub params: NewmarkParams,
    /// Rayleigh damping and its βK variant.
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
/// member cannot push: its damping force is held where its total force would be
/// compression, so that it goes slack with a continuous force and the step equation has
/// no jump there; a member slack at a step's start is undamped until the step ends
/// (`tsm::DampingModulus`). Its Jacobian in the Newmark step is exact and not symmetric,
/// so steps are solved as unsymmetric (dense: LU; sparse: GMRES on the Cholesky factor of
/// the symmetric part, LU where that fails), or by Cholesky on its symmetric part alone
/// where the skew part is small against the mass term.
///
/// The other three apply β K_T(x)·v with K_T at some state, as the paper does. None is
/// objective: a rigidly rotating member gets an apparent axial rate (from the lagged or
/// frozen direction) and a lateral force from K_G, so the path depends on Δt (measured on
/// the paper's deployment: docs/validation.md). They are kept to reproduce the paper.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DampingTangent {
    /// β (dN/dl) l̇ along each member's current direction: rigid motions are not damped.
    #[default]
    Objective,
    /// K_T of the stage's initial state, frozen (misdirects damping across large motion).
    Initial,
    /// K_T of the last converged step: constant within a step, so the Jacobian is exact.
    LastConverged,
    /// K_T of the current iterate; the Jacobian omits ∂K_T/∂x · v (it is not symmetric).
    Current,
}

/// The work of step attempts not kept: those whose Newton solve failed, so that the step
/// was cut in halves, and (`dt: auto`) those taken again shorter. No converged report
/// counts it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Retried {
    /// Step attempts that failed and were cut.
    pub attempts: usize,
    /// `dt: auto`: steps that converged with an error estimate above the tolerance and
    /// were taken again shorter.
    pub rejected: usize,
    /// `dt: auto`: steps taken at the smallest size with their error above the tolerance.
    pub over_tolerance: usize,
    /// Newton iterations those attempts took.
    pub iterations: usize,
    /// Tangent factorizations those attempts took.
    pub factorizations: usize,
}

/// State and integrator of one time-stepping stage on the free DOFs. Every buffer a step
/// needs is allocated here, once: a step allocates nothing.
pub struct Newmark<'a> {
    /// The structure at the current iterate (after a step: the converged state).
    pub asm: Assembly<'a>,
    /// β, γ, Δt and step cuts.
    pub params: NewmarkParams,
    /// Rayleigh damping, with the state its βK variant keeps.
    viscous: Viscous,
    /// Newton settings of every step (tolerances; the linear solver and tangent reuse
    /// were fixed with the workspace).
    newton: NewtonSettings,
    /// Lumped mass per free DOF [kg].
    pub mass: Vec<f64>,
    /// Free coordinates of the last converged state [m] (relative to the ground under
    /// ground motion).
    pub u: Vec<f64>,
    /// Free velocities of the last converged state [m/s].
    pub v: Vec<f64>,
    /// Free accelerations of the last converged state [m/s²].
    pub a: Vec<f64>,
    /// External force on the free DOFs at the last converged time.
    f: Vec<f64>,
    /// Damping force the last converged equation used.
    fd: Vec<f64>,
    /// Rest lengths that change over the stage; `None` where none does.
    actuation: Option<Actuation>,
    ledger: Ledger,
    /// Failed step attempts since the stage began.
    pub retried: Retried,
    /// Stage time of the last converged state [s].
    pub time: f64,
    /// The Newton workspace, taken out while a step runs.
    ws: Option<NewtonWorkspace>,
    /// Step size of the step matrix whose factorization `ws` may hold.
    ws_dt: f64,
    /// The step being solved: its predictor base and trial coordinates, load, velocities
    /// and damping force.
    next: Next,
    /// The accelerations of the two converged states before the last, for the predictor.
    history: History,
    /// `dt: auto`'s error estimate; `None` with a fixed step.
    estimate: Option<ErrorEstimate>,
    /// The members' forces over the step with `scheme: energy_momentum`.
    energy_momentum: Option<EnergyMomentum>,
    /// The members' viscous forces at step ends with a midpoint scheme and objective
    /// damping ([`MidpointEnds`]).
    midpoint_ends: Option<MidpointEnds>,
}

/// The free velocities `v` on every node of `out` (zero at fixed directions).
pub(super) fn node_velocities(asm: &Assembly, v: &[f64], out: &mut [Vector3<f64>]) {
    out.fill(Vector3::zeros());
    for (i, &vi) in v.iter().enumerate() {
        let (n, a) = asm.dofs.owner(i);
        out[n][a] = vi;
    }
}

/// Each member's total axial force (elastic + viscous) at `asm`'s state and free
/// velocities `v`, into `e.forces`, with its round-off into `e.noise` for a step whose
/// velocity coefficient is `c_v` = γ/(βΔt): 4 ε of the force, and the viscous part's, β_R (dN/dl)
/// times the velocity's round-off c_v · 4 ε · (model size) (coordinates carry ε of the
/// model's size; the velocity differences them over Δt). A midpoint scheme's are the end
/// state's, not the ones it records ([`MidpointEnds`]): these carry its stiff members'
/// spurious axial rate, which steps must resolve where they change size (extrapolated,
/// steps grew to 8 ms on the paper deployment, and where they then fell to 8e-8 s the
/// struts' undamped end-state error rang out as an 18.9 kN transient).
fn total_forces(asm: &Assembly, viscous: &Viscous, rest_rate: &[f64], (v, c_v): (&[f64], f64), e: &mut ErrorEstimate) {
    node_velocities(asm, v, &mut e.velocities);
    viscous.member_axial(asm, rest_rate, &e.velocities, &mut e.forces);
    let velocity_noise = c_v * 4.0 * f64::EPSILON * e.length;
    for ((f, noise), st) in e.forces.iter_mut().zip(&mut e.noise).zip(&asm.states) {
        *f += st.force;
        *noise = 4.0 * f64::EPSILON * f.abs() + viscous.rayleigh.beta.abs() * st.stiffness.abs() * velocity_noise;
    }
}

/// The step being solved, on the free DOFs. Its unknown is the increment Δu = u_{n+1} − u_n
/// (`trial`), not the end coordinates: the inertia term m (Δu − `base`)/(βΔt²) and the
/// velocity then difference increments, whose round-off is ε|Δu|, not ε|u| — in absolute
/// coordinates the residual's floor m ε |u|/(βΔt²) grows as 1/Δt², and a step accepted
/// within it leaves a velocity error of ε|u|/Δt that adds up over 1/Δt steps (the
/// twisted prism's Δt study stopped converging at 1/32 ms). `at`: the end coordinates
/// u_n + Δu of the iterate; `v` the velocities at its end, and with the midpoint rule `mid`
/// and `v_mid` the coordinates and velocities its equation is taken at.
struct Next {
    base: Vec<f64>,
    trial: Vec<f64>,
    at: Vec<f64>,
    f: Vec<f64>,
    v: Vec<f64>,
    fd: Vec<f64>,
    mid: Vec<f64>,
    v_mid: Vec<f64>,
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

/// Each member's axial force at a converged step [N], tension positive: `total` is the
/// elastic N plus `viscous`, the member's damping force along it. The force a member
/// carries, and the one an engineer reads: a rotating stiff strut gets from Newmark a
/// spurious axial rate of order Δt², which its elastic force alone shows as a large
/// Δt-dependent swing and the total does not (issue 30).
#[derive(Clone, Debug, Default)]
pub struct AxialForces {
    /// The node velocities of the step (zero at fixed directions) [m/s].
    pub velocities: Vec<Vector3<f64>>,
    /// Elastic + viscous, per member [N].
    pub total: Vec<f64>,
    /// The viscous part, per member [N].
    pub viscous: Vec<f64>,
}

impl AxialForces {
    /// The forces of `nm`'s last converged step.
    pub fn update(&mut self, nm: &Newmark) {
        let asm = &nm.asm;
        self.velocities.resize(asm.model.node_count(), Vector3::zeros());
        node_velocities(asm, &nm.v, &mut self.velocities);
        self.viscous.resize(asm.states.len(), 0.0);
        nm.member_viscous_forces(&self.velocities, &mut self.viscous);
        self.total.clear();
        self.total.extend(asm.states.iter().zip(&self.viscous).map(|(s, d)| s.force + d));
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
        let actuation = schedule.map(|schedule| Actuation::start(schedule, &mut asm));
        let n = mass.len();
        let u = asm.free_coordinates();
        let Integrator { params, damping, newton } = *integrator;
        let ws = Some(NewtonWorkspace::new(n, &newton, true, || tangent_sparsity(asm.model, asm.dofs)));
        let (members, nodes) = (asm.model.members.len(), asm.model.node_count());
        let estimate = params.auto.map(|auto| ErrorEstimate::new(auto, asm.model.size(), members, nodes));
        let energy_momentum = (params.scheme == Scheme::EnergyMomentum).then(|| EnergyMomentum::new(&asm));
        let mut s = Newmark {
            viscous: Viscous::new(damping.rayleigh, damping.tangent, &asm),
            actuation,
            asm,
            params,
            newton,
            mass,
            u,
            v,
            a: vec![0.0; n],
            f: f0,
            fd: vec![0.0; n],
            ledger: Ledger::default(),
            retried: Retried::default(),
            time: 0.0,
            ws,
            ws_dt: params.dt,
            next: Next {
                base: vec![0.0; n],
                trial: vec![0.0; n],
                at: vec![0.0; n],
                f: vec![0.0; n],
                v: vec![0.0; n],
                fd: vec![0.0; n],
                mid: vec![0.0; n],
                v_mid: vec![0.0; n],
            },
            history: History {
                previous: vec![0.0; n],
                before: vec![0.0; n],
                dt: params.dt,
                steps: 0,
            },
            estimate,
            energy_momentum,
            midpoint_ends: None,
        };
        if params.scheme.at_midpoint() && damping.tangent == DampingTangent::Objective {
            s.midpoint_ends = Some(MidpointEnds::new(&s.asm, &s.viscous, s.rest_rate(), &s.v));
        }
        s.consistent_acceleration();
        s.restart_estimate(true);
        s.ledger = Ledger::start(s.kinetic_energy(), s.asm.strain_energy(), s.asm.contact_energy());
        s
    }

    /// l̇0/l0 per member the current equation uses; empty where no rest length changes.
    fn rest_rate(&self) -> &[f64] {
        self.actuation.as_ref().map_or(&[], |a| &a.rate)
    }

    /// The damping force at the current state and velocities (a midpoint scheme's: its
    /// extrapolated end forces), and the acceleration a = M⁻¹(f − f_d − p) that satisfies
    /// the equation of motion with it.
    fn consistent_acceleration(&mut self) {
        let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        match &mut self.midpoint_ends {
            Some(ends) => ends.damping_force(&self.asm, (self.viscous.rayleigh.alpha, &self.mass, &self.v), &mut self.fd),
            None => self.viscous.force(&self.asm, &self.mass, &self.v, rest_rate, &mut self.fd),
        }
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
        if a.jumps_at(self.time) {
            if let Some(ends) = &mut self.midpoint_ends {
                ends.restart();
            }
            self.consistent_acceleration();
        }
        if let Some(a) = &mut self.actuation {
            a.step_to(t_next, &mut self.asm);
        }
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

    /// Rayleigh's α, β of the stage.
    pub fn rayleigh(&self) -> Rayleigh {
        self.viscous.rayleigh
    }

    fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass.iter().zip(&self.v).map(|(m, v)| m * v * v).sum::<f64>()
    }

    /// The energy ledger since the stage began, at the last converged step.
    pub fn energy(&self) -> Energy {
        self.ledger.energy
    }

    /// The stiffness-proportional (β) damping force of the last converged step on all 3n
    /// node directions into `out`, as its equation had it (member states, moduli or βK
    /// blocks; a midpoint scheme's extrapolated end forces, [`MidpointEnds`]): on the free
    /// directions it is the β part of the damping force the step balanced, on the
    /// supported ones what the members' damping forces put into the supports. The αM part acts on the free directions only (a support does not move
    /// relative to the base). Summed over `members` only (model order): a direction gets its
    /// whole force where all its node's members are among them. `velocities`: the step's
    /// velocities `v` on the nodes (zero at fixed directions).
    pub fn member_damping_force(&self, members: &[usize], velocities: &[Vector3<f64>], out: &mut [f64]) {
        out.fill(0.0);
        match &self.midpoint_ends {
            Some(ends) => ends.member_forces(&self.asm, members, out),
            None => self.viscous.member_force(&self.asm, members, self.rest_rate(), velocities, out),
        }
    }

    /// The members' viscous axial forces at the last converged step into `out` [N], at node
    /// `velocities` (the step's `v`, zero at fixed directions), as the step's equation had
    /// them ([`member_axial_damping`](crate::tsm::member_axial_damping)), or a midpoint
    /// scheme's extrapolated ones ([`MidpointEnds`]).
    pub fn member_viscous_forces(&self, velocities: &[Vector3<f64>], out: &mut [f64]) {
        match &self.midpoint_ends {
            Some(ends) => out.copy_from_slice(&ends.end),
            None => self.viscous.member_axial(&self.asm, self.rest_rate(), velocities, out),
        }
    }

    /// |KE + SE + D − W − W_a − E0| (W_a: the actuators' work, E0: KE + SE at the start):
    /// zero for exact integration of the ledger.
    pub fn balance_error(&self) -> f64 {
        self.ledger.balance_error()
    }

    /// Every member's rest length now [m] (the elements' own where none changes).
    pub fn rest_lengths(&self) -> &[f64] {
        &self.asm.rest
    }

    /// The GMRES work of the stage's solves so far ([`NewtonWorkspace::krylov_effort`]).
    pub fn krylov_effort(&self) -> KrylovEffort {
        self.ws.as_ref().map_or_else(KrylovEffort::default, NewtonWorkspace::krylov_effort)
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

    /// Newmark's velocity at the end of a step of size dt by increment `du`, into `next.v`:
    /// v_{n+1} = v_n + Δt((1 − γ) a_n + γ a_{n+1}), a_{n+1} = (Δu − base)/(βΔt²).
    fn next_velocity(&mut self, du: &[f64], dt: f64) {
        let (beta, gamma) = self.params.kinematics();
        let c_a = 1.0 / (beta * dt * dt);
        let (v, a, base) = (&self.v, &self.a, &self.next.base);
        for (i, v_next) in self.next.v.iter_mut().enumerate() {
            *v_next = v[i] + dt * ((1.0 - gamma) * a[i] + gamma * (c_a * (du[i] - base[i])));
        }
    }

    /// Sets up the step to t + dt: the load at its end and the predictor.
    /// Δu = base + β dt² a_{n+1}, base = dt v_n + dt² (½ − β) a_n. Newton starts,
    /// in `next.trial`, from a_{n+1} = a_n + a_{n−1} − a_{n−2} where the last two steps were
    /// of this dt, else from a_{n+1} = a_n (constant acceleration, the usual predictor).
    ///
    /// Why: with γ = ½ the scheme maps a stiff component (ω Δt ≫ 1: a strut's axial
    /// stretching; damped or not) to an oscillation of period 2Δt, its amplification
    /// factor tending to −1, while the motion itself is smooth. The three-point guess is
    /// exact for both, a linear trend and a constant alternation (the difference two steps
    /// apart cancels the alternation), where a_n misses the alternation by twice its
    /// amplitude. The starting point changes only the iterations, never the tolerances
    /// the converged step meets (measured iteration counts: bench/opensees.md, bench/pipeline.md).
    fn predict(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) {
        load(self.time + dt, &mut self.next.f);
        let beta = self.params.kinematics().0;
        let history = self.history.steps >= 2 && self.history.dt == dt;
        let next = &mut self.next;
        for i in 0..self.mass.len() {
            next.base[i] = dt * self.v[i] + dt * dt * (0.5 - beta) * self.a[i];
            let guess = if history {
                self.a[i] + self.history.previous[i] - self.history.before[i]
            } else {
                self.a[i]
            };
            next.trial[i] = next.base[i] + beta * dt * dt * guess;
        }
        if self.asm.contact.is_some() {
            // The predictor is an iterate too: no further than keeps bodies apart (`asm` is
            // at the step's start).
            let trial = &mut self.next.trial;
            let tau = self.asm.admissible(trial, 1.0);
            trial.iter_mut().for_each(|t| *t *= tau);
        }
    }

    /// One Newmark step of size dt. On failure the state is left as it was.
    fn step(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) -> Result<NewtonReport, SolveError> {
        let (report, trial) = self.solve(dt, load)?;
        self.commit(trial, dt);
        Ok(report)
    }

    /// One step of `dt: auto` of at most `dt` [s]: kept where its local error estimate
    /// ([`super::step_control`]) is within the tolerance, else taken again shorter, and
    /// halved where Newton fails. Returns the report of the step kept, its size, and the
    /// size the next step should try.
    pub fn advance_auto(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) -> Result<(NewtonReport, f64, f64), SolveError> {
        let auto = self.estimate.as_ref().expect("dt: auto sets up an estimate").settings;
        let mut dt = dt;
        loop {
            let (report, trial) = match self.solve(dt, load) {
                Ok(solved) => solved,
                Err(_) if dt > auto.min => {
                    dt = (0.5 * dt).max(auto.min);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let ratio = self.error_ratio(&trial, dt);
            if ratio > 1.0 && dt > auto.min {
                self.retried.rejected += 1;
                self.retried.iterations += report.iterations;
                self.retried.factorizations += report.factorizations;
                self.abandon(trial);
                dt = auto.next(dt, ratio);
                continue;
            }
            self.retried.over_tolerance += usize::from(ratio > 1.0);
            self.commit(trial, dt);
            if let Some(e) = &mut self.estimate {
                e.accept(self.time);
            }
            return Ok((report, dt, auto.next(dt, ratio)));
        }
    }

    /// The error ratio of the solved, uncommitted step of `dt` to `trial` (positions and
    /// member forces; [`super::step_control`]): `asm`, `next.v` and the damping state are
    /// the step's end (`newton` ends on a residual there).
    fn error_ratio(&mut self, trial: &[f64], dt: f64) -> f64 {
        let Some(e) = &mut self.estimate else { return 0.0 };
        let ((beta, gamma), c) = (self.params.kinematics(), self.params.error_constant());
        // a_{n+1} − a_n spans the step; the midpoint rule's a_{n+½} − a_n half of it.
        let c_positions = c / self.params.equation_at();
        let positions = e.position_ratio((beta, c_positions), dt, (trial, &self.next.base, &self.a), self.asm.dofs);
        if self.viscous.snapped(&self.asm) {
            // A cable's damping force jumped inside the step (it carries the jump's impulse:
            // `tsm::SnapRate`), which no polynomial through the steps' forces follows: the
            // step is judged by its positions, and the force history restarts after it
            // (the next step starts from the jump).
            return positions;
        }
        let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        total_forces(&self.asm, &self.viscous, rest_rate, (&self.next.v, gamma / (beta * dt)), e);
        positions.max(e.force_ratio(c, self.time + dt))
    }

    /// Restarts `dt: auto`'s force history at the current time, from the current forces
    /// where they are those the next step starts from (`now`; not where a cable is damped
    /// from here on: its force jumps). Where a load has a kink or jump, or a cable snaps.
    fn restart_estimate(&mut self, now: bool) {
        let Some(e) = &mut self.estimate else { return };
        e.restart();
        if now {
            let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
            total_forces(&self.asm, &self.viscous, rest_rate, (&self.v, 0.0), e);
            e.accept(self.time);
        }
    }

    /// Sets the external force at the current time to `load`'s there, where a load jumps
    /// at the end of the last step (which took its left limit: `dt: auto` ends steps on
    /// jumps), with the acceleration consistent with it, and restarts the error estimate's
    /// force history.
    pub fn restart_load(&mut self, load: &dyn Fn(f64, &mut [f64])) {
        load(self.time, &mut self.next.f);
        if self.next.f != self.f {
            std::mem::swap(&mut self.f, &mut self.next.f);
            self.consistent_acceleration();
        }
        self.restart_estimate(true);
    }

    /// Leaves the state as it was before the step that reached `trial`.
    fn abandon(&mut self, trial: Vec<f64>) {
        self.next.trial = trial;
        if let Some(a) = &mut self.actuation {
            a.abandon_step(&mut self.asm);
        }
        let Newmark { asm, u, .. } = self;
        asm.set_free(u);
    }

    /// Solves the step of size dt to its converged coordinates, not committed; on failure
    /// the state is left as it was.
    fn solve(&mut self, dt: f64, load: &dyn Fn(f64, &mut [f64])) -> Result<(NewtonReport, Vec<f64>), SolveError> {
        let gamma = self.params.kinematics().1;
        let snap = if self.params.scheme.at_midpoint() {
            SnapRule::AtMidpoint { dt }
        } else {
            SnapRule::AtEnd {
                gamma_dt: gamma * dt,
                carry: (1.0 - gamma) / gamma,
            }
        };
        let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        if self.viscous.start_step(&self.asm, snap, &self.v, rest_rate) {
            // A cable that snapped taut in the last step, damped on its taut branch from here
            // on: the damping force jumps at this step's start, and the step starts from the
            // acceleration just after (as at an actuator's kink).
            if let Some(ends) = &mut self.midpoint_ends {
                ends.restart_members(self.viscous.newly_taut());
            }
            self.consistent_acceleration();
            self.restart_estimate(false);
        }
        if let Some(em) = &mut self.energy_momentum {
            em.start_step(&self.asm);
        }
        self.actuate(self.time + self.params.equation_at() * dt);
        self.predict(dt, load);
        let length = self.asm.model.size();
        let mut trial = std::mem::take(&mut self.next.trial);
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
        match result {
            Ok(report) => {
                if let Some(ends) = &mut self.midpoint_ends {
                    let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
                    ends.solve(&self.asm, &self.viscous, rest_rate, &self.next.v_mid);
                }
                if self.params.scheme.at_midpoint() {
                    self.end_midpoint_step(dt);
                }
                Ok((report, trial))
            }
            Err(e) => {
                self.retried.attempts += 1;
                self.retried.iterations += iterations;
                self.retried.factorizations += factorizations;
                self.abandon(trial);
                Err(e)
            }
        }
    }

    /// A midpoint step of size dt converged to end coordinates `next.at`, its equation at
    /// the midpoint: `asm` (rest lengths, member states) and the damping moduli are set to
    /// its end, what the step commits and records; `next.fd` stays the midpoint's, the
    /// force its equation balanced.
    fn end_midpoint_step(&mut self, dt: f64) {
        if let Some(a) = &mut self.actuation {
            a.step_to(self.time + dt, &mut self.asm);
        }
        self.asm.set_free(&self.next.at);
        self.viscous.at_iterate(&self.asm);
    }

    /// Commits the converged step of size dt by increment `trial` (to `next.at`): positions,
    /// accelerations, velocities, damping force, energy ledger (with the midpoint rule,
    /// the acceleration and damping force at the step's end). The last residual was
    /// evaluated at `trial` (`newton` ends on it): `asm`, the damping state, `next.at`,
    /// `next.v` and `next.fd` hold the converged step's values.
    fn commit(&mut self, trial: Vec<f64>, dt: f64) {
        let c_a = 1.0 / (self.params.kinematics().0 * dt * dt);
        self.history.push(&mut self.a, dt);
        for (a, (du, base)) in self.a.iter_mut().zip(trial.iter().zip(&self.next.base)) {
            *a = c_a * (du - base);
        }
        let external = trapezoidal_work(&self.f, &self.next.f, &trial);
        // The damping force the step's equation balanced: at its end and start (Newmark's
        // trapezoidal work), or the midpoint's over the whole step.
        let fd_start = if self.params.scheme.at_midpoint() {
            &self.next.fd
        } else {
            &self.fd
        };
        let damping = trapezoidal_work(fd_start, &self.next.fd, &trial);
        std::mem::swap(&mut self.u, &mut self.next.at);
        std::mem::swap(&mut self.v, &mut self.next.v);
        std::mem::swap(&mut self.f, &mut self.next.f);
        std::mem::swap(&mut self.fd, &mut self.next.fd);
        self.next.trial = trial;
        self.time += dt;
        // Pulley friction's dissipation, which the rest lengths' work (Σ q̄ Δl0 over the
        // actuation's members: all) counted as negative work of the actuators.
        let dissipated = self.asm.commit();
        let actuation = self.actuation.as_mut().map_or(0.0, |a| a.commit(&self.asm) + dissipated);
        if let Some(ends) = &mut self.midpoint_ends {
            ends.commit(&self.asm, self.time - 0.5 * dt, self.time);
        }
        let rest_rate = self.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        if self.params.scheme.at_midpoint() {
            // The acceleration and damping force at the step's end, where the midpoint rule
            // has none of its own: what the records, the next step's predictor and the
            // next stage start from.
            self.consistent_acceleration();
        } else if self.viscous.release(&self.asm, &self.v, rest_rate) {
            // A cable held below −N carried its pull's impulse (`tsm::DampingModulus`): its
            // force is −N from here on, and the next step starts from the acceleration
            // with it, as after a snap.
            self.consistent_acceleration();
            self.restart_estimate(false);
        }
        let energies = [self.kinetic_energy(), self.asm.strain_energy(), self.asm.contact_energy()];
        self.ledger.add_step(energies, damping + dissipated, external, actuation);
    }
}

/// The nonlinear equation of one step in its end coordinates u: r(u) = f − M a(u) − C v − p,
/// with a = (u − base)/(β dt²), v(u) = v_n + dt((1−γ) a_n + γ a). Newmark: f, C v and p at
/// the end (u, v(u)); Jacobian K_T + M/(β dt²) + (γ/(β dt)) C (for `Current`, less
/// ∂K_T/∂u · v). Midpoint (β = ½, γ = 1 in the kinematics): f = ½ (f_n + f_{n+1}), C v and p
/// at x_{n+½} = ½ (u_n + u), v_{n+½} = ½ (v_n + v(u)), both moving at half u's rate:
/// Jacobian M/(β dt²) + α M/dt + ½ (K_T + (2/dt) C_β) at the midpoint, half the trapezoidal
/// rule's K_T + 4M/dt² + (2/dt) C there.
struct StepProblem<'s, 'a> {
    nm: &'s mut Newmark<'a>,
    dt: f64,
}

impl StepProblem<'_, '_> {
    /// c_a = 1/(βΔt²) of a = c_a (u − base), and c_v the rate at which the velocity the
    /// damping force is evaluated at moves with u: γ/(βΔt), or 1/Δt at the midpoint.
    fn coefficients(&self) -> (f64, f64) {
        let ((beta, gamma), dt) = (self.nm.params.kinematics(), self.dt);
        (1.0 / (beta * dt * dt), self.nm.params.equation_at() * gamma / (beta * dt))
    }
}

impl Residual for StepProblem<'_, '_> {
    fn residual(&mut self, du: &[f64], r: &mut [f64]) -> Scale {
        let c_a = self.coefficients().0;
        let nm = &mut *self.nm;
        nm.next_velocity(du, self.dt);
        let midpoint = nm.params.scheme.at_midpoint();
        let next = &mut nm.next;
        next.at.iter_mut().zip(&nm.u).zip(du).for_each(|((x, u), d)| *x = u + d);
        if midpoint {
            next.mid.iter_mut().zip(&nm.u).zip(du).for_each(|((m, u), d)| *m = u + 0.5 * d);
            next.v_mid
                .iter_mut()
                .zip(&nm.v)
                .zip(&next.v)
                .for_each(|((m, a), b)| *m = 0.5 * (a + b));
        }
        nm.asm.set_free(if midpoint { &next.mid } else { &next.at });
        if let Some(em) = &mut nm.energy_momentum {
            em.at_midpoint(&nm.asm);
        }
        nm.viscous.at_iterate(&nm.asm);
        let v = if midpoint { &next.v_mid } else { &next.v };
        let rest_rate = nm.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        nm.viscous.force(&nm.asm, &nm.mass, v, rest_rate, &mut next.fd);
        let (mut applied, mut inertia_floor) = (0.0_f64, 0.0_f64);
        for i in 0..du.len() {
            let m = nm.mass[i];
            let inertia = m * c_a * (du[i] - next.base[i]);
            let f = if midpoint { 0.5 * (nm.f[i] + next.f[i]) } else { next.f[i] };
            let p = nm
                .energy_momentum
                .as_ref()
                .map_or_else(|| nm.asm.p_free(i), |em| em.p_free(&nm.asm, i));
            r[i] = f - inertia - next.fd[i] - p;
            applied = applied.max(f.abs()).max(inertia.abs());
            inertia_floor = inertia_floor.max(m * c_a * du[i].abs().max(next.base[i].abs()));
        }
        // The inertia term differences increments: its round-off is m/(βΔt²)·ε·|Δu| (or of
        // the base), 64 ε as for the members. The velocity does so too, so the damping force
        // adds none beyond the members' own.
        let scale = nm.asm.scale(applied);
        Scale {
            roundoff: scale.roundoff + 64.0 * f64::EPSILON * inertia_floor,
            ..scale
        }
    }

    /// K_T + M (c_a + α_R c_v) + the β_R term's derivative ([`Viscous::assemble_tangent`]).
    /// At the midpoint x and v move at s = ½ of u's rate: the members' part is assembled
    /// with the velocity's rate c_v/s and scaled by s.
    fn tangent(&mut self, k: &mut dyn TangentSink) {
        let (c_a, c_v) = self.coefficients();
        let nm = &mut *self.nm;
        let alpha_r = nm.viscous.rayleigh.alpha;
        let mass_term = nm.mass.iter().fold(f64::INFINITY, |m, &mi| m.min(mi)) * (c_a + alpha_r * c_v);
        let rest_rate = nm.actuation.as_ref().map_or(&[][..], |a| &a.rate);
        let s = nm.params.equation_at();
        let v = if nm.params.scheme.at_midpoint() {
            &nm.next.v_mid
        } else {
            &nm.next.v
        };
        let mut scaled;
        let members: &mut dyn TangentSink = if s == 1.0 {
            &mut *k
        } else {
            scaled = ScaledSink { sink: &mut *k, by: s };
            &mut scaled
        };
        let em = nm.energy_momentum.as_ref();
        nm.viscous
            .assemble_tangent(&nm.asm, v, rest_rate, (c_v / s, mass_term / s), em.is_none(), &mut *members);
        match em {
            Some(em) => em.add_tangent(&nm.asm, k),
            None => nm.asm.add_contact_tangent(1.0, members),
        }
        for (i, m) in nm.mass.iter().enumerate() {
            k.add(i, i, m * (c_a + alpha_r * c_v));
        }
    }

    fn symmetric(&self) -> bool {
        self.nm.viscous.symmetric() && self.nm.energy_momentum.is_none() && self.nm.asm.symmetric_tangent()
    }

    /// At the midpoint the positions move at half Δu's rate, and the end ones (which the
    /// step commits, and whose gaps the energy–momentum form takes) at Δu's: both stay clear.
    fn admissible(&mut self, _du: &[f64], d: &[f64]) -> f64 {
        let rate = self.nm.params.equation_at();
        let at = self.nm.asm.admissible(d, rate);
        if rate == 1.0 {
            return at;
        }
        at.min(self.nm.asm.admissible_at(&self.nm.next.at, d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::viscous::{Objective, StiffnessTerm};
    use crate::dynamics::{Actuator, TimeFunction};
    use crate::law::{ForceLaw, LinearElastic, OgdenCord};
    use crate::model::generate::TowerSpec;
    use crate::model::MemberKind;
    use crate::solve::LinearSolverChoice;
    use crate::tsm::{block_product, member_axial_damping, scaled_blocks, DampingModulus, EndSlots, MemberDamping};
    use crate::tsm::{DofMap, Elements};
    use faer::Mat;
    use std::sync::Arc;

    /// The objective damping's state, `None` for the other tangents.
    fn objective<'n>(nm: &'n mut Newmark) -> Option<&'n mut Objective> {
        match &mut nm.viscous.term {
            StiffnessTerm::Objective(o) => Some(o),
            StiffnessTerm::Tangent(_) => None,
        }
    }

    fn moduli<'n>(nm: &'n Newmark) -> &'n [DampingModulus] {
        match &nm.viscous.term {
            StiffnessTerm::Objective(o) => &o.moduli,
            StiffnessTerm::Tangent(_) => &[],
        }
    }

    /// A 3-strut prism out of balance (struts at their nominal length, EA = 1e5 N; Ogden
    /// cables at stretch 1.2), unit nodal masses, strong Rayleigh damping, moved two steps
    /// under a sideways load so that v and a are non-zero and the tangents differ; with
    /// `actuate`, the cables' rest lengths shrink by half over 0.1 s as it moves (so that
    /// the rest-length rate enters the step's damping force and Jacobian).
    fn moving_prism(tangent: DampingTangent, actuate: bool, run: impl FnOnce(&mut Newmark)) {
        let cable = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1);
        prism_in_motion(tangent, actuate, (cable, 1.2), run);
    }

    /// [`moving_prism`] with the cables `cable` at stretch `stretch` (l/l0 in the nominal
    /// shape).
    fn prism_in_motion(tangent: DampingTangent, actuate: bool, (cable, stretch): (OgdenCord, f64), run: impl FnOnce(&mut Newmark)) {
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
        let cable: Arc<dyn ForceLaw> = Arc::new(cable);
        let (laws, rest): (Vec<_>, Vec<f64>) = model
            .members
            .iter()
            .map(|m| {
                let l = (x0[m.nodes[1]] - x0[m.nodes[0]]).norm();
                match m.kind {
                    MemberKind::Strut => (strut.clone(), l),
                    MemberKind::Cable => (cable.clone(), l / stretch),
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
                assert_eq!(nm.rest_rate().iter().any(|&r| r != 0.0), actuate);
                assert_step_jacobian(nm, tangent, symmetric_below);
            });
        }
    }

    /// The midpoint rule's step tangent (members' part at x_{n+½}, halved: [`StepProblem`])
    /// against central differences, as [`step_jacobian_matches_finite_differences`] checks
    /// Newmark's; `Current` is left out there because its omitted term is taken at the
    /// frozen end velocities, not the midpoint's.
    #[test]
    fn midpoint_step_jacobian_matches_finite_differences() {
        for (tangent, symmetric_below, actuate) in [
            (DampingTangent::Objective, 0.0, false),
            (DampingTangent::Objective, f64::INFINITY, false),
            (DampingTangent::Objective, 0.0, true),
            (DampingTangent::Initial, 0.0, false),
            (DampingTangent::LastConverged, 0.0, true),
        ] {
            moving_prism(tangent, actuate, |nm| {
                nm.params.scheme = Scheme::Midpoint;
                nm.predict(0.01, &|t, f| f.iter_mut().for_each(|fi| *fi = t));
                assert_step_jacobian(nm, tangent, symmetric_below);
            });
        }
    }

    /// The energy–momentum step tangent (its members' S d_mid block, exact and not
    /// symmetric, plus the damping's at x_{n+½}, halved) against central differences, as
    /// [`midpoint_step_jacobian_matches_finite_differences`].
    #[test]
    fn energy_momentum_step_jacobian_matches_finite_differences() {
        for (tangent, actuate) in [
            (DampingTangent::Objective, false),
            (DampingTangent::Objective, true),
            (DampingTangent::Initial, false),
            (DampingTangent::LastConverged, true),
        ] {
            moving_prism(tangent, actuate, |nm| {
                nm.params.scheme = Scheme::EnergyMomentum;
                nm.energy_momentum = Some(EnergyMomentum::new(&nm.asm));
                nm.energy_momentum.as_mut().unwrap().start_step(&nm.asm);
                nm.predict(0.01, &|t, f| f.iter_mut().for_each(|fi| *fi = t));
                assert_step_jacobian(nm, tangent, 0.0);
            });
        }
    }

    /// The objective step Jacobian where tension-only members are held at no compression
    /// ([`DampingModulus`]): the prism's cables tension-only rubber barely stretched
    /// (λ = 1.0005: N ≈ 0.03 N), so that at the trial point some shorten fast enough to be
    /// held (β k r < −N: 3 of 24), some are damped as usual (17) and some are slack (4); exact and
    /// symmetrized, against central differences as in
    /// [`step_jacobian_matches_finite_differences`]. Central differences need each member
    /// away from its switch β k r = −N by more than a step h = 1e-6 m moves it
    /// ((c_v β k + k) h ≲ (200 · 0.01 · 20 + 20) · 1e-6 ≈ 6e-5 N, k = A0 F'(1)/l0 ≲ 20 N/m
    /// here): 1e-3 N is asserted.
    #[test]
    fn step_jacobian_of_held_tension_only_members_matches_finite_differences() {
        assert_held_step_jacobian(|_| {}, held_members);
    }

    /// The prism of tension-only rubber at stretch 1.0005 in motion, `start` applied to it,
    /// at a trial point off the predictor: every count of `census` ≥ 1, and the objective
    /// step Jacobian, exact and symmetrized, against central differences.
    fn assert_held_step_jacobian(start: impl Fn(&mut Newmark), census: fn(&Newmark) -> (usize, usize, usize)) {
        let mut cable = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1);
        cable.tension_only = true;
        for symmetric_below in [0.0, f64::INFINITY] {
            prism_in_motion(DampingTangent::Objective, false, (cable.clone(), 1.0005), |nm| {
                start(nm);
                let u = off_predictor(nm);
                StepProblem { nm, dt: 0.01 }.residual(&u, &mut vec![0.0; u.len()]);
                let counts = census(nm);
                assert!(counts.0 >= 1 && counts.1 >= 1 && counts.2 >= 1, "{counts:?}");
                assert_step_jacobian(nm, DampingTangent::Objective, symmetric_below);
            });
        }
    }

    /// The Newmark step Jacobian where tension-only members taut at the step's start carry
    /// their allowance ((1 − γ)/γ (N + d) at the start: [`DampingModulus`]): the prism of
    /// [`step_jacobian_of_held_tension_only_members_matches_finite_differences`] with the
    /// step started, so that at the trial point members with A > 0 are held at −N − A,
    /// damped above it, and slack now (damped through l0, or held at −A); exact and
    /// symmetrized, against central differences as there (1e-3 N from every switch).
    #[test]
    fn step_jacobian_with_allowances_matches_finite_differences() {
        let start = |nm: &mut Newmark| {
            let v = nm.v.clone();
            let snap = SnapRule::AtEnd {
                gamma_dt: 0.5 * 0.01,
                carry: 1.0,
            };
            nm.viscous.start_step(&nm.asm, snap, &v, &[]);
            nm.predict(0.01, &|_, f| f.fill(0.0));
        };
        assert_held_step_jacobian(start, allowed_members);
    }

    /// At `nm`'s current iterate, of the members with an allowance A > 0: how many are held
    /// at −N − A and how many damped by β k r above it while taut, and how many slack now;
    /// asserting that each is at least 1e-3 N away from its switch.
    fn allowed_members(nm: &Newmark) -> (usize, usize, usize) {
        let (asm, velocities) = (&nm.asm, trial_velocities(nm));
        let moduli = moduli(nm);
        let free: Vec<DampingModulus> = moduli.iter().map(|m| DampingModulus { tension_only: false, ..*m }).collect();
        let mut unheld = vec![0.0; free.len()];
        let damping = MemberDamping::Objective {
            moduli: &free,
            beta: nm.rayleigh().beta,
            rest_rate: &[],
        };
        member_axial_damping(asm.model, &asm.states, damping, &velocities, &mut unheld);
        let mut counts = (0, 0, 0);
        for (e, s) in asm.states.iter().enumerate().filter(|(e, _)| moduli[*e].allowance > 0.0) {
            let floor = -s.force - moduli[e].allowance;
            assert!(
                (unheld[e] - floor).abs() > 1e-3,
                "member {e} at its switch: {} N",
                unheld[e] - floor
            );
            if s.force == 0.0 {
                counts.2 += 1;
            } else if unheld[e] < floor {
                counts.0 += 1;
            } else {
                counts.1 += 1;
            }
        }
        counts
    }

    /// The step Jacobian where cables slack at the step's start snap taut in it, damped at
    /// their snap rate ([`crate::tsm::SnapRate`]): the prism's tension-only rubber at
    /// stretch 0.999 (slack by ~1 mm), so that at the trial point some of those are taut
    /// (force β k R, R > 0) and some still slack (R ≤ 0, no force), for Newmark
    /// (R = (l − l0)/(γΔt)), the midpoint rule and the energy–momentum form
    /// (R = r + (l_n − l0_n)/Δt), exact and symmetrized, against central differences as in
    /// [`step_jacobian_matches_finite_differences`]. Each member must be away from its
    /// switch R = 0 by more than the step h = 1e-6 m moves R (h/Δt = 1e-4 m/s; 1e-3 m/s
    /// asserted).
    #[test]
    fn step_jacobian_of_snapping_members_matches_finite_differences() {
        let mut cable = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1);
        cable.tension_only = true;
        for (scheme, symmetric_below) in [
            (Scheme::Newmark, 0.0),
            (Scheme::Newmark, f64::INFINITY),
            (Scheme::Midpoint, 0.0),
            (Scheme::EnergyMomentum, 0.0),
        ] {
            prism_in_motion(DampingTangent::Objective, false, (cable.clone(), 0.999), |nm| {
                nm.params.scheme = scheme;
                if scheme == Scheme::EnergyMomentum {
                    nm.energy_momentum = Some(EnergyMomentum::new(&nm.asm));
                    nm.energy_momentum.as_mut().unwrap().start_step(&nm.asm);
                }
                let snap = match scheme {
                    Scheme::Newmark => SnapRule::AtEnd {
                        gamma_dt: 0.5 * 0.01,
                        carry: 1.0,
                    },
                    _ => SnapRule::AtMidpoint { dt: 0.01 },
                };
                let v = nm.v.clone();
                nm.viscous.start_step(&nm.asm, snap, &v, &[]);
                nm.predict(0.01, &|_, f| f.fill(0.0));
                let u = off_predictor(nm);
                StepProblem { nm, dt: 0.01 }.residual(&u, &mut vec![0.0; u.len()]);
                let (taut, slack) = snapping_members(nm);
                assert!(taut >= 1 && slack >= 1, "{scheme:?}: snapping taut {taut}, still slack {slack}");
                assert_step_jacobian(nm, DampingTangent::Objective, symmetric_below);
            });
        }
    }

    /// At `nm`'s current iterate, how many members damped at their snap rate have R > 0
    /// and R ≤ 0, asserting that each is at least 1e-3 m/s away from R = 0.
    fn snapping_members(nm: &Newmark) -> (usize, usize) {
        let asm = &nm.asm;
        let midpoint = nm.params.scheme.at_midpoint();
        let v = if midpoint { &nm.next.v_mid } else { &nm.next.v };
        let mut velocities = vec![Vector3::zeros(); asm.model.node_count()];
        node_velocities(asm, v, &mut velocities);
        let mut counts = (0, 0);
        for (e, m) in moduli(nm).iter().enumerate() {
            let Some(snap) = m.snap else { continue };
            let [a, b] = asm.model.members[e].nodes;
            let s = &asm.states[e];
            let rate = snap.per_length * s.length + snap.per_rate * s.dir.dot(&(velocities[b] - velocities[a])) + snap.constant;
            assert!(rate.abs() > 1e-3, "member {e} at its switch: R = {rate:e} m/s");
            if rate > 0.0 {
                counts.0 += 1;
            } else {
                counts.1 += 1;
            }
        }
        counts
    }

    /// At `nm`'s current iterate, how many tension-only members are held at −N, damped by
    /// β k r and slack, asserting that each is at least 1e-3 N away from its switch.
    fn held_members(nm: &Newmark) -> (usize, usize, usize) {
        let (asm, velocities) = (&nm.asm, trial_velocities(nm));
        let free: Vec<DampingModulus> = moduli(nm).iter().map(|m| DampingModulus { tension_only: false, ..*m }).collect();
        let beta = nm.rayleigh().beta;
        let (mut held, mut unheld) = (vec![0.0; free.len()], vec![0.0; free.len()]);
        for (moduli, out) in [(moduli(nm), &mut held), (&free[..], &mut unheld)] {
            let damping = MemberDamping::Objective {
                moduli,
                beta,
                rest_rate: &[],
            };
            member_axial_damping(asm.model, &asm.states, damping, &velocities, out);
        }
        let mut counts = (0, 0, 0);
        for (e, s) in asm.states.iter().enumerate().filter(|(e, _)| moduli(nm)[*e].tension_only) {
            if s.force == 0.0 {
                counts.2 += 1;
                continue;
            }
            assert!(
                (unheld[e] + s.force).abs() > 1e-3,
                "member {e} at its switch: {} N",
                unheld[e] + s.force
            );
            if unheld[e] > -s.force {
                assert_eq!(held[e], unheld[e]);
                counts.1 += 1;
            } else {
                // Recorded as e·(−N e): |e|² is 1 to a few ulp.
                assert!((held[e] + s.force).abs() <= 1e-14 * s.force, "{} against −{}", held[e], s.force);
                counts.0 += 1;
            }
        }
        counts
    }

    /// The node velocities at `nm`'s current iterate (zero at fixed directions).
    fn trial_velocities(nm: &Newmark) -> Vec<Vector3<f64>> {
        let mut velocities = vec![Vector3::zeros(); nm.asm.model.node_count()];
        for (i, &vi) in nm.next.v.iter().enumerate() {
            let (n, a) = nm.asm.dofs.owner(i);
            velocities[n][a] = vi;
        }
        velocities
    }

    /// A trial point off `nm`'s predictor, every coordinate moved by 0 to 4 mm.
    fn off_predictor(nm: &Newmark) -> Vec<f64> {
        (nm.next.trial.iter().enumerate())
            .map(|(i, t)| t + 1e-3 * ((i * 7) % 5) as f64)
            .collect()
    }

    /// The step tangent of `nm` (`tangent`, the objective one symmetrized where its skew
    /// part is below `symmetric_below` of the mass term) against −∂r/∂u by central
    /// differences at [`off_predictor`] (tolerances: [`step_jacobian_matches_finite_differences`]).
    fn assert_step_jacobian(nm: &mut Newmark, tangent: DampingTangent, symmetric_below: f64) {
        if let Some(o) = objective(nm) {
            o.symmetric_below = symmetric_below;
        }
        let n = nm.mass.len();
        let dt = 0.01;
        let u = off_predictor(nm);
        let mut problem = StepProblem { nm, dt };
        let mut r = vec![0.0; n];
        problem.residual(&u, &mut r);
        let mut k = Mat::<f64>::zeros(n, n);
        problem.tangent(&mut k);
        let symmetrized = problem.symmetric() && tangent == DampingTangent::Objective;
        assert_eq!(symmetrized, symmetric_below > 0.0, "{tangent:?}");
        let v_frozen = problem.nm.next.v.clone();
        let mut blocks = vec![nalgebra::Matrix3::zeros(); problem.nm.asm.states.len()];
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
            for (u, r, g) in [(&up, &mut rp, &mut gp), (&um, &mut rm, &mut gm)] {
                problem.residual(u, r);
                // β K_T(u) at the frozen velocities: what `Current` leaves out.
                let nm = &*problem.nm;
                g.fill(0.0);
                scaled_blocks(&nm.asm.states, nm.rayleigh().beta, &mut blocks);
                block_product(&blocks, &mut ends, &v_frozen, g);
            }
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
        if symmetrized {
            let skew = symmetrize(&mut expected);
            assert!(skew > 1.0, "the skew part is only {skew:e} N/m");
        }
        let worst = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .fold(0.0_f64, |w, (i, j)| w.max((k[(i, j)] - expected[(i, j)]).abs()));
        assert!(worst < 1e-3, "{tangent:?}: tangent differs from −∂r/∂u by {worst:e} N/m");
        // The omitted term is large enough that the check above tells it apart.
        assert!(omitted_size > 1.0, "{tangent:?}: ∂K_T/∂x·v only {omitted_size:e} N/m");
    }

    /// Replaces `m` by its symmetric part ½ (M + Mᵀ); returns the largest entry of the skew part.
    fn symmetrize(m: &mut Mat<f64>) -> f64 {
        let (whole, n) = (m.clone(), m.nrows());
        let mut skew: f64 = 0.0;
        for (i, j) in (0..n).flat_map(|i| (0..n).map(move |j| (i, j))) {
            m[(i, j)] = 0.5 * (whole[(i, j)] + whole[(j, i)]);
            skew = skew.max((whole[(i, j)] - m[(i, j)]).abs());
        }
        skew
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
                (0..nm.a.len()).all(|i| nm.next.trial[i] == nm.next.base[i] + beta * dt * dt * guess(i))
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
                assert_eq!(nm.asm.strain_energy(), nm.energy().strain, "{tangent:?}");
                let mut fd = vec![0.0; nm.v.len()];
                let rest_rate = nm.rest_rate().to_vec();
                nm.viscous.force(&nm.asm, &nm.mass, &nm.v, &rest_rate, &mut fd);
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
                let (start, work0) = (balance(&nm.energy()), nm.energy().actuation);
                let mut worst: f64 = 0.0;
                for _ in 0..((0.18 / dt).round() as usize) {
                    nm.advance(dt, &push).unwrap();
                    worst = worst.max((balance(&nm.energy()) - start).abs());
                }
                assert!(nm.energy().damping > 0.0);
                end = (nm.u.clone(), worst, nm.energy().actuation - work0);
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

    /// The cable reaches l0 three quarters into the step: the step is taken whole, the
    /// cable damped at its snap rate R = (l − l0)/(γΔt) (`tsm::SnapRate`), so the step's
    /// end solves m c_a (u − base) = −k (u − l0)(1 + β_R/(γΔt)) in closed form.
    #[test]
    fn a_step_in_which_a_cable_snaps_taut_carries_its_impulse() {
        snapping_cable(DampingTangent::Objective, 0, |mut nm, (ea, m, dt, v0, s)| {
            assert_eq!(nm.a, [0.0], "slack at the start: no force");
            nm.advance(dt, &|_, _| ()).expect("the step converges uncut");
            assert_eq!(nm.retried, Retried::default());
            assert!((nm.time - dt).abs() < 1e-15, "the whole step is taken: t = {}", nm.time);
            let (c_a, beta_r) = (4.0 / (dt * dt), nm.viscous.rayleigh.beta);
            let base = 1.0 - s + v0 * dt;
            let k = ea * (1.0 + beta_r / (0.5 * dt));
            let closed = (m * c_a * base + k) / (m * c_a + k);
            // The step's residual tolerance on a force of k (u − 1) ~ 1e2 N: 1e-12 m.
            assert!((nm.u[0] - closed).abs() < 1e-12, "x = {}, closed form {closed}", nm.u[0]);
            assert!(
                nm.u[0] > 1.0 && moduli(&nm)[0].snap.is_some(),
                "x = {}, {:?}",
                nm.u[0],
                moduli(&nm)[0]
            );
        });
    }

    /// A cable that stays slack through the step gets no force from its snap rate: the
    /// step ends on its predictor, uniform motion.
    #[test]
    fn a_cable_that_stays_slack_is_not_damped() {
        snapping_cable(DampingTangent::Objective, 0, |mut nm, (_, _, dt, v0, s)| {
            nm.v[0] = -v0;
            nm.advance(dt, &|_, _| ()).expect("the step converges");
            let uniform = 1.0 - s - v0 * dt;
            assert!((nm.u[0] - uniform).abs() < 1e-15, "x = {}, uniform motion {uniform}", nm.u[0]);
        });
    }

    /// The same snap with the paper's β K_T(x)·v at the current iterate, whose K_T jumps
    /// where the cable goes taut: the whole step has no root and is cut; the failed
    /// attempts' work is kept in `retried`. Newton's step towards the other side raises
    /// the residual at every length, and each attempt ends there
    /// ([`crate::solve::SolveError::NoDescent`]) where it used to run to the iteration cap
    /// of 50.
    #[test]
    fn failed_step_attempts_are_counted() {
        snapping_cable(DampingTangent::Current, 6, |mut nm, (_, _, dt, _, _)| {
            let report = nm.advance(dt, &|_, _| ()).expect("the step converges in parts");
            let r = nm.retried;
            assert!(r.attempts >= 1, "{r:?}");
            assert!(
                (3 * r.attempts..50 * r.attempts).contains(&r.iterations) && r.factorizations >= r.attempts,
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
            clusters: Vec::new(),
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
