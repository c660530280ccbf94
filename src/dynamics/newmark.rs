use super::Rayleigh;
use crate::record::Energy;
use crate::solve::{newton, NewtonReport, NewtonSettings, Residual, Scale, SolveError};
use crate::tsm::Assembly;
use faer::Mat;

/// Newmark-β integration parameters.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewmarkParams {
    /// β = 1/4 with γ = 1/2 is the average-acceleration rule: unconditionally stable, no
    /// numerical damping, energy-conserving on linear problems.
    pub beta: f64,
    pub gamma: f64,
    /// Time step Δt [s] (paper: 0.001).
    pub dt: f64,
    /// Duration [s] (paper: 8 s deployment, 3 s free vibration).
    pub duration: f64,
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
            duration: 8.0,
            max_cuts: 6,
        }
    }
}

/// Which stiffness the βK damping term uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DampingTangent {
    /// K_T of the stage's initial state, frozen.
    Initial,
    /// K_T of the last converged step (default): follows the geometry as the tower
    /// unfolds, yet is constant within a step so Newton's Jacobian is exact. A frozen
    /// initial tangent misdirects damping across large motion (a prototype deployed to
    /// another equilibrium), and the current tangent makes the damping force depend on
    /// ∂K/∂x, which the Jacobian omits (a peer solver diverges at the paper's β).
    #[default]
    LastConverged,
    /// K_T of the current iterate (Jacobian omits ∂K_T/∂x · v).
    Current,
}

/// State and integrator of one time-stepping stage on the free DOFs.
pub struct Newmark<'a> {
    pub asm: Assembly<'a>,
    pub params: NewmarkParams,
    pub rayleigh: Rayleigh,
    pub tangent: DampingTangent,
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
    /// Stiffness βK uses (unused for `Current`).
    k_damp: Mat<f64>,
    /// Energy ledger since the stage began.
    pub energy: Energy,
    /// KE + SE at the start of the stage: the balance is KE + SE + D − W − E0.
    pub initial_energy: f64,
    pub time: f64,
}

impl<'a> Newmark<'a> {
    /// Starts at rest-or-moving state (`asm`'s positions, velocities `v`) under external
    /// force `f0`, with the consistent initial acceleration a0 = M⁻¹(f0 − C v0 − p(x0)).
    pub fn new(
        asm: Assembly<'a>,
        mass: Vec<f64>,
        v: Vec<f64>,
        f0: Vec<f64>,
        params: NewmarkParams,
        rayleigh: Rayleigh,
        tangent: DampingTangent,
    ) -> Self {
        let n = mass.len();
        let u = asm.free_coordinates();
        let mut k_damp = Mat::zeros(n, n);
        asm.add_tangent(1.0, &mut k_damp);
        let mut s = Newmark {
            asm,
            params,
            rayleigh,
            tangent,
            mass,
            u,
            v,
            a: vec![0.0; n],
            f: f0,
            fd: vec![0.0; n],
            k_damp,
            energy: Energy::default(),
            initial_energy: 0.0,
            time: 0.0,
        };
        s.fd = s.damping_force(&s.k_damp, &s.v);
        for i in 0..n {
            s.a[i] = (s.f[i] - s.fd[i] - s.asm.p_free(i)) / s.mass[i];
        }
        s.energy = s.ledger_now(0.0, 0.0);
        s.initial_energy = s.energy.kinetic + s.energy.strain;
        s
    }

    fn damping_force(&self, k: &Mat<f64>, v: &[f64]) -> Vec<f64> {
        let n = v.len();
        (0..n)
            .map(|i| self.rayleigh.alpha * self.mass[i] * v[i] + self.rayleigh.beta * (0..n).map(|j| k[(i, j)] * v[j]).sum::<f64>())
            .collect()
    }

    /// The damping force at velocities `v` with the βK stiffness `tangent` selects, at
    /// the assembly's current state.
    fn damping_force_now(&self, v: &[f64]) -> Vec<f64> {
        match self.tangent {
            DampingTangent::Current => {
                let n = v.len();
                let mut k = Mat::zeros(n, n);
                self.asm.add_tangent(1.0, &mut k);
                self.damping_force(&k, v)
            }
            _ => self.damping_force(&self.k_damp, v),
        }
    }

    fn ledger_now(&self, damping: f64, external: f64) -> Energy {
        Energy {
            kinetic: 0.5 * self.mass.iter().zip(&self.v).map(|(m, v)| m * v * v).sum::<f64>(),
            strain: self.asm.elements.strain_energy(self.asm.model, &self.asm.x),
            damping,
            external,
        }
    }

    /// |KE + SE + D − W − E0|: zero for exact integration of the ledger.
    pub fn balance_error(&self) -> f64 {
        let e = &self.energy;
        (e.kinetic + e.strain + e.damping - e.external - self.initial_energy).abs()
    }

    /// Advances by `dt`, cutting the step in halves (recursively, `max_cuts` deep) where
    /// Newton fails. `load(t, f)` writes the external force on the free DOFs at time t.
    pub fn advance(
        &mut self,
        dt: f64,
        newton_settings: &NewtonSettings,
        load: &dyn Fn(f64, &mut [f64]),
        label: &dyn Fn(usize) -> String,
    ) -> Result<NewtonReport, SolveError> {
        self.advance_cut(dt, 0, newton_settings, load, label)
    }

    fn advance_cut(
        &mut self,
        dt: f64,
        depth: u32,
        settings: &NewtonSettings,
        load: &dyn Fn(f64, &mut [f64]),
        label: &dyn Fn(usize) -> String,
    ) -> Result<NewtonReport, SolveError> {
        match self.step(dt, settings, load, label) {
            Ok(r) => Ok(r),
            Err(e) if depth >= self.params.max_cuts => Err(e),
            Err(_) => {
                let first = self.advance_cut(dt / 2.0, depth + 1, settings, load, label)?;
                let second = self.advance_cut(dt / 2.0, depth + 1, settings, load, label)?;
                Ok(NewtonReport {
                    iterations: first.iterations + second.iterations,
                    residuals: second.residuals,
                })
            }
        }
    }

    /// One Newmark step of size dt; on failure the state is left as it was.
    fn step(
        &mut self,
        dt: f64,
        settings: &NewtonSettings,
        load: &dyn Fn(f64, &mut [f64]),
        label: &dyn Fn(usize) -> String,
    ) -> Result<NewtonReport, SolveError> {
        let n = self.mass.len();
        let t_next = self.time + dt;
        let mut f_next = vec![0.0; n];
        load(t_next, &mut f_next);
        let (beta, gamma) = (self.params.beta, self.params.gamma);
        // Predictor: u_{n+1} = u_n + dt v_n + dt² (½ − β) a_n + β dt² a_{n+1}.
        let base: Vec<f64> = (0..n)
            .map(|i| self.u[i] + dt * self.v[i] + dt * dt * (0.5 - beta) * self.a[i])
            .collect();
        let mut u = self.u.clone();
        let length = self.asm.model.size();
        let report = {
            let mut problem = StepProblem {
                nm: self,
                dt,
                base: &base,
                f: &f_next,
            };
            let result = newton(&mut problem, &mut u, settings, length, label);
            if result.is_err() {
                let u_old = self.u.clone();
                self.asm.set_free(&u_old);
                return result;
            }
            result?
        };
        // Commit: accelerations, velocities, damping force, energy ledger.
        self.asm.set_free(&u);
        let a_next: Vec<f64> = (0..n).map(|i| (u[i] - base[i]) / (beta * dt * dt)).collect();
        let v_next: Vec<f64> = (0..n)
            .map(|i| self.v[i] + dt * ((1.0 - gamma) * self.a[i] + gamma * a_next[i]))
            .collect();
        let fd_next = self.damping_force_now(&v_next);
        // Trapezoidal work of the forces each equation actually used: with average
        // acceleration this is the discrete energy identity of the scheme.
        let (mut dw, mut dd) = (0.0, 0.0);
        for i in 0..n {
            let du = u[i] - self.u[i];
            dw += 0.5 * (self.f[i] + f_next[i]) * du;
            dd += 0.5 * (self.fd[i] + fd_next[i]) * du;
        }
        self.u = u;
        self.v = v_next;
        self.a = a_next;
        self.f = f_next;
        self.fd = fd_next;
        self.time = t_next;
        let (d, w) = (self.energy.damping + dd, self.energy.external + dw);
        self.energy = self.ledger_now(d, w);
        if self.tangent == DampingTangent::LastConverged {
            self.k_damp.fill(0.0);
            self.asm.add_tangent(1.0, &mut self.k_damp);
        }
        Ok(report)
    }
}

/// The nonlinear equation of one step: r(u) = f − M a(u) − C v(u) − p(u), with
/// a = (u − base)/(β dt²), v = v_n + dt((1−γ) a_n + γ a); Jacobian
/// K_T + M/(β dt²) + (γ/(β dt)) C.
struct StepProblem<'s, 'a> {
    nm: &'s mut Newmark<'a>,
    dt: f64,
    base: &'s [f64],
    f: &'s [f64],
}

impl Residual for StepProblem<'_, '_> {
    fn evaluate(&mut self, u: &[f64], r: &mut [f64], k: &mut Mat<f64>) -> Scale {
        let nm = &mut *self.nm;
        let (beta, gamma, dt) = (nm.params.beta, nm.params.gamma, self.dt);
        nm.asm.set_free(u);
        let n = u.len();
        let c_a = 1.0 / (beta * dt * dt);
        let c_v = gamma / (beta * dt);
        let v: Vec<f64> = (0..n)
            .map(|i| nm.v[i] + dt * ((1.0 - gamma) * nm.a[i] + gamma * c_a * (u[i] - self.base[i])))
            .collect();
        let (alpha_r, beta_r) = (nm.rayleigh.alpha, nm.rayleigh.beta);
        // Jacobian: K_T + β_R c_v K_damp, then M (c_a + α_R c_v) on the diagonal below.
        nm.asm.add_tangent(1.0, k);
        match nm.tangent {
            DampingTangent::Current => nm.asm.add_tangent(beta_r * c_v, k),
            _ => {
                for i in 0..n {
                    for j in 0..n {
                        k[(i, j)] += beta_r * c_v * nm.k_damp[(i, j)];
                    }
                }
            }
        }
        let fd = nm.damping_force_now(&v);
        let (mut applied, mut inertia_floor) = (0.0_f64, 0.0_f64);
        for i in 0..n {
            let m = nm.mass[i];
            k[(i, i)] += m * (c_a + alpha_r * c_v);
            let inertia = m * c_a * (u[i] - self.base[i]);
            r[i] = self.f[i] - inertia - fd[i] - nm.asm.p_free(i);
            applied = applied.max(self.f[i].abs()).max(inertia.abs());
            inertia_floor = inertia_floor.max(m * c_a * u[i].abs());
        }
        // The inertia term differences absolute coordinates: its round-off is
        // m/(βΔt²)·ε·|u|, which for small steps or far-from-origin nodes exceeds the
        // members' floor. 64 ε as for the members.
        let scale = nm.asm.scale(applied);
        Scale {
            roundoff: scale.roundoff + 64.0 * f64::EPSILON * inertia_floor,
            ..scale
        }
    }
}
