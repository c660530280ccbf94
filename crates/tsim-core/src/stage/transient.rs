//! A time-stepping stage (free vibration, deployment): Newmark from a given state (with
//! initial displacements and velocities added) under the structure's constant load, nodal
//! loads with time functions and ground motion, every converged step recorded, with the
//! figures the checks need.

use super::frames::{non_finite, FrameBuilder, Motion};
use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::EquilibriumSummary;
use super::{record_error, solve_error, Analysis, Settings};
use crate::dynamics::{
    Actuator, AutoStep, AxialForces, Damping, DampingTangent, Energy, FreeLoads, Integrator, Loads, Newmark, NewmarkParams, Rayleigh,
    RestSchedule,
};
use crate::error::{Error, Result};
use crate::model::{shape_error, MemberKind, Model};
use crate::record::{Recorder, Stage, StageLayout};
use crate::solve::NewtonReport;
use crate::structure::{State, Structure};
use crate::tsm::DofMap;
use nalgebra::Vector3;

/// A transient stage.
#[derive(Clone, Debug)]
pub struct Transient {
    /// Kind and name, for the recorder.
    pub stage: Stage,
    /// β, γ, Δt and step cuts.
    pub params: NewmarkParams,
    /// Duration [s].
    pub duration: f64,
    /// Rayleigh damping C = αM + βK (zero: undamped), the pipeline's to set from the
    /// eigen stage the config names.
    pub rayleigh: Rayleigh,
    /// Which K the βK damping term uses.
    pub tangent: DampingTangent,
    /// Nodal loads and ground motion (the structure's constant load acts besides).
    pub loads: Loads,
    /// Members whose rest lengths change over the stage (from those of the state it starts
    /// from); empty for none.
    pub actuators: Vec<Actuator>,
    /// What is added to the state the stage starts from.
    pub initial: Initial,
}

/// A transient as a stage of the sequence, with what it takes from earlier stages.
#[derive(Clone, Debug)]
pub struct PlannedTransient {
    /// The stage (undamped: `rayleigh_from` gives its damping).
    pub stage: Transient,
    /// The list index of the eigen stage whose Rayleigh α, β damp this one.
    pub rayleigh_from: Option<usize>,
    /// The state index whose shape this stage's is compared with.
    pub compare_to: Option<usize>,
}

impl SequenceStage for PlannedTransient {
    fn stage(&self) -> &Stage {
        &self.stage.stage
    }

    fn layout(&self, model: &Model) -> StageLayout {
        let plain = StageLayout::plain(model, self.stage.stage.clone());
        StageLayout {
            actuated: plain.actuated || !self.stage.actuators.is_empty(),
            ..plain
        }
    }

    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        let rayleigh = self.rayleigh_from.and_then(|k| match &run.earlier[k] {
            StageSummary::Eigen(e) => Some(e.rayleigh()),
            _ => None,
        });
        let stage = Transient {
            rayleigh: rayleigh.unwrap_or_default(),
            ..self.stage.clone()
        };
        // The shape error at every step, for the time it comes within 1 % of the compared shape.
        let compared = self.compare_to.map(|k| &run.reached[k].state);
        let towards = compared.map(|s| &s.positions[..]);
        let (end, transient) = stage.run_towards(run.structure, start.state.clone(), run.settings, recorder, towards)?;
        let figures = TransientStageSummary::new(transient, &end, compared);
        Ok((start.under_same_loads(end), StageSummary::Transient(Box::new(figures))))
    }
}

/// A transient's figures and, with `compare_to` (deployment: the pre-fold equilibrium),
/// how far it ended from that shape.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TransientStageSummary {
    /// The time stepping's figures.
    #[serde(flatten)]
    pub transient: TransientSummary,
    /// RMS over nodes of the distance to the compared shape, over the tower height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape_error: Option<f64>,
    /// The same against the mirror image z → −z of the compared shape: small when the
    /// tower deployed downwards (inverted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mirror_shape_error: Option<f64>,
    /// Node positions at the end [m].
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
}

impl TransientStageSummary {
    /// The stage's figures and how far it ended from the `compared` state.
    fn new(transient: TransientSummary, end: &State, compared: Option<&State>) -> Self {
        let errors = compared.map(|c| shape_error(&end.positions, &c.positions));
        TransientStageSummary {
            transient,
            shape_error: errors.map(|e| e.0),
            mirror_shape_error: errors.map(|e| e.1),
            final_positions: end.positions.clone(),
        }
    }
}

/// Initial conditions on top of the state a transient starts from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Initial {
    /// Displacement added to a node's position [m] (entries on one node add up).
    pub displacement: Vec<(usize, Vector3<f64>)>,
    /// Velocity set on a node [m/s] (a later entry on the same node wins).
    pub velocity: Vec<(usize, Vector3<f64>)>,
    /// Start with a = 0 instead of the acceleration consistent with the loads.
    pub zero_acceleration: bool,
}

impl Initial {
    /// `state` with the displacements added and the velocities set; a non-zero value on
    /// a supported direction is an error naming the node and direction.
    pub fn apply(&self, model: &Model, mut state: State) -> std::result::Result<State, String> {
        for (what, entries) in [("displacement", &self.displacement), ("velocity", &self.velocity)] {
            for (n, value) in entries {
                if let Some(a) = (0..3).find(|&a| model.nodes[*n].support[a] && value[a] != 0.0) {
                    return Err(format!(
                        "initial {what} {} on node `{}` direction {}, which is supported",
                        value[a],
                        model.nodes[*n].id,
                        ["x", "y", "z"][a]
                    ));
                }
            }
        }
        for (n, d) in &self.displacement {
            state.positions[*n] += d;
        }
        for (n, v) in &self.velocity {
            state.velocities[*n] = *v;
        }
        Ok(state)
    }
}

/// Figures of a finished transient stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TransientSummary {
    /// Time steps taken: duration/Δt rounded, or those `dt: auto` took (each counted
    /// once, however it was cut or stopped inside).
    pub steps: usize,
    /// The smallest step taken [s] (Δt with a fixed step).
    #[serde(default)]
    pub smallest_step: f64,
    /// The largest step taken [s].
    #[serde(default)]
    pub largest_step: f64,
    /// `dt: auto`: steps whose error estimate was above the tolerance, taken again shorter
    /// (their work is in `failed_iterations`, `failed_factorizations`).
    #[serde(default)]
    pub rejected_steps: usize,
    /// `dt: auto`: steps taken at the smallest size `dt_min` with their error above the
    /// tolerance (0 where the tolerance was met everywhere).
    #[serde(default)]
    pub over_tolerance_steps: usize,
    /// Newton iterations of the converged steps and sub-steps.
    pub newton_iterations: usize,
    /// Tangent factorizations (fewer than iterations where they are reused).
    pub factorizations: usize,
    /// Steps cut in halves because a Newton solve failed; `failed_iterations` and
    /// `failed_factorizations` are the failed attempts' work, which `newton_iterations`
    /// and `factorizations` (the converged sub-steps') leave out.
    #[serde(default)]
    pub cut_steps: usize,
    /// Newton iterations of the failed attempts.
    #[serde(default)]
    pub failed_iterations: usize,
    /// Tangent factorizations of the failed attempts.
    #[serde(default)]
    pub failed_factorizations: usize,
    /// Linear solves by GMRES: the sparse solver's unsymmetric step matrices (objective
    /// damping's Jacobian), preconditioned by their symmetric part's Cholesky factor;
    /// failed attempts' included. 0 on the dense path and where every step matrix was
    /// symmetric.
    #[serde(default)]
    pub gmres_solves: usize,
    /// Their iterations (each a product with the step matrix and a solve with the factor).
    #[serde(default)]
    pub gmres_iterations: usize,
    /// GMRES solves that did not converge within `KRYLOV_ITERATIONS` (40) and were
    /// solved by an LU factorization instead (counted in `factorizations`).
    #[serde(default)]
    pub gmres_fallbacks: usize,
    /// Largest kinetic energy over the steps [J].
    pub max_kinetic: f64,
    /// Kinetic energy at the last step [J].
    pub final_kinetic: f64,
    /// max over steps of |KE + SE + D − W − E0| [J].
    pub max_balance_error: f64,
    /// max over steps of max(KE, SE) [J], the scale of the balance error.
    pub max_energy: f64,
    /// Largest rise of KE + SE from one step to the next once the loads have stopped
    /// changing [J] (less the external work W when a load stays on, e.g. gravity; damped:
    /// never positive beyond round-off).
    pub max_mechanical_rise: f64,
    /// Largest cable stretch l/l0 over the stage.
    pub max_cable_stretch: f64,
    /// Largest strut compression over the stage [N] (positive number).
    pub max_strut_compression: f64,
    /// Largest strut tension over the stage [N] (0 where no strut pulls).
    #[serde(default)]
    pub max_strut_tension: f64,
    /// Largest member tension over the stage, every step [N].
    #[serde(default)]
    pub max_tension: f64,
    /// Largest member compression over the stage, every step [N] (positive number).
    #[serde(default)]
    pub max_compression: f64,
    /// With a reference shape (deployment: the pre-fold equilibrium): the first stage time
    /// from which the shape error (RMS distance to the reference over its height, every
    /// step) stays ≤ 1 % to the stage's end [s]; `None` when it ends above 1 %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_time: Option<f64>,
    /// The member whose stiffness-proportional damping is fastest against the stage's
    /// largest step ([`FastestDashpot`]); `None` without β damping.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fastest_dashpot: Option<FastestDashpot>,
    /// Wall time of the stage, recording included [s].
    pub wall_seconds: f64,
    /// Largest out-of-balance over the recorded steps.
    #[serde(flatten)]
    pub equilibrium: EquilibriumSummary,
}

/// How far a stage's step is from resolving the members' stiffness-proportional damping:
/// the largest over the members of Δt/τ = β k Δt/m, τ = m/(β k) the time a member's
/// dashpot (β k, k = dN/dl, a slack cable's taut branch) takes to stop the relative motion
/// of its ends (m: their reduced mass; a node fixed in every direction counts as
/// immovable). Above 1/(1 − γ) (2 for Newmark's trapezoidal rule and the midpoint schemes)
/// the scheme turns the member's extension rate over each step wherever a fast motion
/// along it is excited (a snap, an impact): its motion stays damped and its work
/// dissipative, but its recorded viscous force β k l̇ alternates at the step's scale and
/// converges as Δt halves only for Δt below 2τ (bench/pipeline.md: a 6 × 6 grid with the
/// Rayleigh β of a 105 × 105 one, up to 917 at 1 ms). Where nothing excites it the force
/// is smooth (the paper deployment's struts: 4 342 at 0.5 ms, their viscous forces up to
/// 640 N of 666 N, changing from one step to the next by at most 2.7 % of the largest).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FastestDashpot {
    /// The member's id.
    pub member: String,
    /// Δt/τ at the stage's largest step.
    pub steps_per_dashpot_time: f64,
    /// τ [s]: the steps resolve the member's viscous force below 2τ.
    pub dashpot_time: f64,
}

impl FastestDashpot {
    /// At `nm`'s state, β its Rayleigh β and `dt` the largest step; `None` where β = 0.
    fn of(nm: &Newmark, masses: &[f64], dt: f64) -> Option<Self> {
        let beta = nm.rayleigh().beta;
        if beta == 0.0 {
            return None;
        }
        let asm = &nm.asm;
        let movable = |n: usize| (0..3).any(|ax| asm.dofs.free(n, ax).is_some());
        let inverse_mass = |n: usize| if movable(n) { 1.0 / masses[n] } else { 0.0 };
        let (laws, rest) = (&asm.elements.laws, &asm.rest);
        let tau = |e: usize| {
            let (s, [a, b]) = (&asm.states[e], asm.model.members[e].nodes);
            let k = if laws[e].slack(s.length, rest[e]) {
                laws[e].eval(rest[e], rest[e]).stiffness
            } else {
                s.stiffness
            };
            1.0 / (beta * k.abs() * (inverse_mass(a) + inverse_mass(b)))
        };
        // A massless node (a member of zero density) has no dashpot time: left out.
        let times = (0..asm.states.len())
            .map(|e| (e, tau(e)))
            .filter(|(_, t)| t.is_finite() && *t > 0.0);
        let (e, tau) = times.min_by(|x, y| x.1.total_cmp(&y.1))?;
        Some(FastestDashpot {
            member: asm.model.members[e].id.clone(),
            steps_per_dashpot_time: dt / tau,
            dashpot_time: tau,
        })
    }
}

impl TransientSummary {
    /// Counts a converged step's Newton work; `cut`: it was cut in parts.
    fn add_effort(&mut self, report: &NewtonReport, cut: bool) {
        self.newton_iterations += report.iterations;
        self.factorizations += report.factorizations;
        self.cut_steps += usize::from(cut);
    }

    /// Takes in one converged step at stage time `time`, its members' axial forces
    /// (elastic + viscous) `axial`, found for it; `load_end` is when the loads stop changing;
    /// `loaded` whether some load stays on after that (then the mechanical energy counted
    /// is KE + SE − W, which a constant load leaves conserved).
    fn add_step(&mut self, nm: &Newmark, axial: &AxialForces, time: f64, (load_end, loaded): (f64, bool), dt: f64, mechanical: &mut f64) {
        let forces = &axial.total;
        let e = nm.energy();
        self.max_kinetic = self.max_kinetic.max(e.kinetic);
        self.max_energy = self.max_energy.max(e.kinetic.max(e.strain));
        self.max_balance_error = self.max_balance_error.max(nm.balance_error());
        let now = mechanical_energy(&e, loaded);
        if time - dt > load_end {
            self.max_mechanical_rise = self.max_mechanical_rise.max(now - *mechanical);
        }
        *mechanical = now;
        let asm = &nm.asm;
        for (((mem, st), l0), &force) in asm.model.members.iter().zip(&asm.states).zip(&asm.rest).zip(forces) {
            self.max_tension = self.max_tension.max(force);
            self.max_compression = self.max_compression.max(-force);
            match mem.kind {
                MemberKind::Cable => self.max_cable_stretch = self.max_cable_stretch.max(st.length / l0),
                MemberKind::Strut => {
                    self.max_strut_compression = self.max_strut_compression.max(-force);
                    self.max_strut_tension = self.max_strut_tension.max(force);
                }
            }
        }
    }
}

impl Transient {
    fn integrator(&self, settings: &Settings) -> Integrator {
        Integrator {
            params: self.params,
            damping: Damping {
                rayleigh: self.rayleigh,
                tangent: self.tangent,
            },
            newton: settings.newton,
        }
    }
}

impl Analysis for Transient {
    type Summary = TransientSummary;

    /// Runs from `state`'s positions and velocities with the initial conditions applied,
    /// with the acceleration consistent with the loads at t = 0 (or zero).
    fn run(
        &self,
        structure: &Structure,
        state: State,
        settings: &Settings,
        recorder: &mut dyn Recorder,
    ) -> Result<(State, TransientSummary)> {
        self.run_towards(structure, state, settings, recorder, None)
    }
}

/// Shape error at or below which a deployment counts as in shape (1 %).
pub const SETTLE_TOLERANCE: f64 = 0.01;

impl Transient {
    /// [`Analysis::run`], and with a `reference` shape the time from which the shape
    /// error stays within [`SETTLE_TOLERANCE`] (`TransientSummary::settle_time`), checked
    /// at every step (one pass over the nodes per step).
    pub fn run_towards(
        &self,
        structure: &Structure,
        state: State,
        settings: &Settings,
        recorder: &mut dyn Recorder,
        reference: Option<&[Vector3<f64>]>,
    ) -> Result<(State, TransientSummary)> {
        let name = self.stage.name();
        let model = &structure.model;
        super::whole_cables(model, &self.actuators, name)?;
        if let Some(reason) = self.cluster_limit(model) {
            return Err(Error::Stage {
                stage: name.into(),
                reason,
            });
        }
        let dofs = DofMap::new(model, &[]);
        let state = self.initial.apply(model, state).map_err(|reason| Error::Stage {
            stage: name.into(),
            reason,
        })?;
        let masses = structure.free_masses(&dofs);
        let constant = structure.constant_load();
        let loads = FreeLoads::new(&self.loads, &constant, &masses, &dofs);
        let started = std::time::Instant::now();
        let mut f0 = vec![0.0; dofs.len()];
        loads.at(0.0, false, &dofs, &mut f0);
        let rest_lengths = state.rest_lengths.clone();
        let mut nm = self.start(structure, &dofs, state, (masses, f0), settings);
        super::require_apart(&nm.asm, name)?;
        let mut run = Stepping::new(self, structure, &dofs, constant, reference);
        run.begin(&nm, recorder)?;
        match self.params.auto {
            None => self.fixed_steps(&mut nm, &loads, &mut run, settings.every, recorder)?,
            Some(auto) => self.auto_steps(&mut nm, (&loads, auto), &mut run, settings.every, recorder)?,
        }
        recorder.end_stage(&self.stage).map_err(record_error(name))?;
        let mut summary = run.finish(&nm);
        summary.wall_seconds = started.elapsed().as_secs_f64();
        Ok((final_state(&nm, &dofs, rest_lengths), summary))
    }

    /// Why this stage cannot run `model`'s clustered cables, if it cannot: the
    /// energy–momentum form is not written for them (`tsm::cluster`); with pulley friction
    /// (`tsm::friction`), whose slip is committed at a step's end, only Newmark's
    /// end-of-step equation, and no stiffness-proportional damping (a member's elastic
    /// rate would need the slip's rate).
    fn cluster_limit(&self, model: &Model) -> Option<String> {
        use crate::dynamics::Scheme;
        let cluster = &model.clusters.first()?.id;
        let friction = model.clusters.iter().find(|c| c.friction > 0.0).map(|c| &c.id);
        match (self.params.scheme, friction) {
            (Scheme::EnergyMomentum, _) => Some(format!(
                "the clustered cable `{cluster}` has no energy–momentum form yet; use `scheme: midpoint` or `newmark`"
            )),
            (Scheme::Midpoint, Some(c)) => Some(format!(
                "the clustered cable `{c}` has pulley friction, which the midpoint rule does not take yet; use `scheme: newmark` (or friction 0)"
            )),
            (_, Some(c)) if self.rayleigh.beta != 0.0 => Some(format!(
                "the clustered cable `{c}` has pulley friction, and stiffness-proportional (β) damping is not written for it yet (a member's elastic rate needs the slip's rate); damp with α only (rayleigh beta 0), or give the cable friction 0"
            )),
            _ => None,
        }
    }

    /// Steps of `params.dt`, duration/dt of them (rounded), their times on that grid.
    fn fixed_steps(
        &self,
        nm: &mut Newmark,
        loads: &FreeLoads,
        run: &mut Stepping,
        every: usize,
        recorder: &mut dyn Recorder,
    ) -> Result<()> {
        let dt = self.params.dt;
        let steps = (self.duration / dt).round() as usize;
        run.summary.steps = steps;
        let load = |t: f64, f: &mut [f64]| loads.at(t, false, run.dofs, f);
        for step in 1..=steps {
            let time = step as f64 * dt;
            let failed_before = nm.retried.attempts;
            let report = nm
                .advance(dt, &load)
                .map_err(solve_error(self.stage.name(), Some(step), Some(time), run.structure, run.dofs))?;
            let load_time = nm.time;
            // Re-anchor time to the step grid so that long runs do not drift.
            nm.time = time;
            let taken = Taken {
                index: step,
                dt,
                cut: nm.retried.attempts > failed_before,
                record: step % every == 0 || step == steps,
                load_time,
            };
            run.take(nm, &report, taken, recorder)?;
        }
        Ok(())
    }

    /// `dt: auto`: steps sized by the local error estimate ([`Newmark::advance_auto`]),
    /// each ending on every kink or jump of a load or actuator it would cross (a step
    /// ending on a jump takes the load's left limit; the next starts from its right one).
    fn auto_steps(
        &self,
        nm: &mut Newmark,
        (loads, auto): (&FreeLoads, AutoStep),
        run: &mut Stepping,
        every: usize,
        recorder: &mut dyn Recorder,
    ) -> Result<()> {
        let breaks = self.breakpoints();
        let (mut dt, mut next_break) = (auto.initial, 0);
        for step in 1.. {
            while breaks[next_break] <= nm.time {
                next_break += 1;
            }
            let target = breaks[next_break];
            // Within round-off of the breakpoint: a step sized to reach it does.
            let at_target = |t: f64| (t - target).abs() <= 1e-12 * target;
            let load = |t: f64, f: &mut [f64]| loads.at(t, at_target(t), run.dofs, f);
            let step_dt = dt.min(auto.max);
            let step_dt = if nm.time + 1.05 * step_dt >= target {
                target - nm.time
            } else {
                step_dt
            };
            let failed_before = nm.retried.attempts;
            let (report, taken, next) = nm.advance_auto(step_dt, &load).map_err(solve_error(
                self.stage.name(),
                Some(step),
                Some(nm.time + step_dt),
                run.structure,
                run.dofs,
            ))?;
            dt = next;
            let at_break = at_target(nm.time);
            if at_break {
                nm.time = target;
                nm.restart_load(&|t: f64, f: &mut [f64]| loads.at(t, false, run.dofs, f));
            }
            let last = at_break && next_break + 1 == breaks.len();
            let taken = Taken {
                index: step,
                dt: taken,
                cut: nm.retried.attempts > failed_before,
                record: step % every == 0 || last,
                load_time: nm.time,
            };
            run.take(nm, &report, taken, recorder)?;
            if last {
                run.summary.steps = step;
                return Ok(());
            }
        }
        unreachable!("the stage ends at its last breakpoint")
    }

    /// The times in (0, duration) where a load or actuator has a kink or a jump, sorted,
    /// and the duration last.
    fn breakpoints(&self) -> Vec<f64> {
        let mut breaks = self.loads.breakpoints();
        for a in &self.actuators {
            a.time.breakpoints(&mut breaks);
        }
        breaks.retain(|&t| t < self.duration);
        breaks.sort_by(f64::total_cmp);
        breaks.dedup();
        breaks.push(self.duration);
        breaks
    }

    /// The integrator at `state` (its rest lengths, or the elements' own), with the free
    /// DOFs' masses and external force at t = 0, and the initial acceleration the stage asks for.
    fn start<'s>(
        &self,
        structure: &'s Structure,
        dofs: &'s DofMap,
        state: State,
        (masses, f0): (Vec<f64>, Vec<f64>),
        settings: &Settings,
    ) -> Newmark<'s> {
        let v0 = state.free_velocities(dofs);
        let rest = state.rest_lengths.as_deref().unwrap_or(&structure.elements.rest);
        let schedule = (!self.actuators.is_empty()).then(|| RestSchedule::new(rest.to_vec(), self.actuators.clone()));
        let asm = structure.assembly(dofs, state.positions, rest);
        let mut nm = Newmark::actuated(asm, masses, v0, f0, &self.integrator(settings), schedule);
        if self.initial.zero_acceleration {
            nm.start_with_zero_acceleration();
        }
        nm
    }

    /// When the loads stop changing (actuators do work until their rest lengths stop
    /// changing, as loads do), and whether some load stays on after that, besides the
    /// structure's `constant` load.
    fn load_end(&self, constant: &[Vector3<f64>]) -> (f64, bool) {
        let loaded = constant.iter().any(|f| *f != Vector3::zeros()) || self.loads.persist();
        let actuation_end = self.actuators.iter().map(|a| a.time.end()).fold(0.0, f64::max);
        (self.loads.end().max(actuation_end), loaded)
    }

    /// The load on every node at `load_time` into `applied`, the time the step's equation
    /// took its load at (before time is re-anchored to the grid, which may move it by an
    /// ulp across a step load's end): the structure's `constant` load and the stage's loads
    /// on every direction (on a supported one it goes into the support), and under ground
    /// motion the inertia load −m a_g on the free ones (the supports move with the ground).
    fn applied_load(&self, structure: &Structure, dofs: &DofMap, constant: &[Vector3<f64>], load_time: f64, applied: &mut [Vector3<f64>]) {
        applied.copy_from_slice(constant);
        self.loads.add_nodal(load_time, false, applied);
        let ground = self.loads.ground_acceleration(load_time, false);
        if ground != Vector3::zeros() {
            for i in 0..dofs.len() {
                let (n, a) = dofs.owner(i);
                applied[n][a] -= structure.masses[n] * ground[a];
            }
        }
    }
}

/// A converged step as the stage takes it in.
struct Taken {
    /// Its number in the stage (from 1).
    index: usize,
    /// Its size [s].
    dt: f64,
    /// Whether it was cut because a Newton solve failed.
    cut: bool,
    /// Whether it is recorded (every `every`-th, and the last).
    record: bool,
    /// The time its equation took its load at (before the time is re-anchored to a grid).
    load_time: f64,
}

/// What a transient keeps over its steps: the recorder's frames, the summary's figures,
/// the settling check.
struct Stepping<'s, 'r> {
    stage: &'s Transient,
    structure: &'s Structure,
    dofs: &'s DofMap,
    /// The structure's constant load on every node, and the applied load of a frame [N].
    constant: Vec<Vector3<f64>>,
    applied: Vec<Vector3<f64>>,
    frames: FrameBuilder,
    summary: TransientSummary,
    settle: Settle<'r>,
    /// The mechanical energy of the last step ([`mechanical_energy`]).
    mechanical: f64,
    axial: AxialForces,
    load_end: (f64, bool),
}

impl<'s, 'r> Stepping<'s, 'r> {
    fn new(
        stage: &'s Transient,
        structure: &'s Structure,
        dofs: &'s DofMap,
        constant: Vec<Vector3<f64>>,
        reference: Option<&'r [Vector3<f64>]>,
    ) -> Self {
        Stepping {
            load_end: stage.load_end(&constant),
            stage,
            structure,
            dofs,
            applied: constant.clone(),
            constant,
            frames: FrameBuilder::new(structure, dofs),
            summary: TransientSummary {
                smallest_step: f64::INFINITY,
                ..Default::default()
            },
            settle: Settle { reference, since: None },
            mechanical: 0.0,
            axial: AxialForces::default(),
        }
    }

    /// Begins the stage on the recorder with the state at t = 0.
    fn begin(&mut self, nm: &Newmark, recorder: &mut dyn Recorder) -> Result<()> {
        let name = self.stage.stage.name();
        self.frames.begin(recorder, &self.stage.stage).map_err(record_error(name))?;
        self.axial.update(nm);
        self.record(nm, 0, 0.0, recorder)?;
        self.settle.track(&nm.asm.x, 0.0);
        self.mechanical = mechanical_energy(&nm.energy(), self.load_end.1);
        Ok(())
    }

    fn record(&mut self, nm: &Newmark, step: usize, load_time: f64, recorder: &mut dyn Recorder) -> Result<()> {
        let stage = self.stage;
        stage.applied_load(self.structure, self.dofs, &self.constant, load_time, &mut self.applied);
        let motion = Motion {
            newmark: nm,
            axial: &self.axial,
            support_acceleration: stage.loads.ground_acceleration(load_time, false),
        };
        self.frames
            .record_motion(recorder, motion, step, &self.applied)
            .map_err(record_error(stage.stage.name()))
    }

    /// Takes in the converged step `taken` of `nm`, whose Newton work `report` gives.
    fn take(&mut self, nm: &Newmark, report: &NewtonReport, taken: Taken, recorder: &mut dyn Recorder) -> Result<()> {
        let (step, time) = (taken.index, nm.time);
        if let Some(what) = non_finite(&nm.asm, Some(&nm.v), &nm.energy()) {
            let reason = format!("step {step} (t = {time:.4} s): {what} is not finite");
            return Err(Error::Stage {
                stage: self.stage.stage.name().into(),
                reason,
            });
        }
        let summary = &mut self.summary;
        summary.add_effort(report, taken.cut);
        self.axial.update(nm);
        summary.add_step(nm, &self.axial, time, self.load_end, taken.dt, &mut self.mechanical);
        summary.smallest_step = summary.smallest_step.min(taken.dt);
        summary.largest_step = summary.largest_step.max(taken.dt);
        self.settle.track(&nm.asm.x, time);
        if taken.record {
            self.record(nm, step, taken.load_time, recorder)
        } else {
            self.frames.observe(&nm.asm.x, step, time);
            Ok(())
        }
    }

    /// The stage's figures at its end (but its wall time).
    fn finish(self, nm: &Newmark) -> TransientSummary {
        let mut summary = self.summary;
        summary.equilibrium = self.frames.check.into();
        summary.final_kinetic = nm.energy().kinetic;
        (summary.failed_iterations, summary.failed_factorizations) = (nm.retried.iterations, nm.retried.factorizations);
        let krylov = nm.krylov_effort();
        (summary.gmres_solves, summary.gmres_iterations, summary.gmres_fallbacks) = (krylov.solves, krylov.iterations, krylov.unconverged);
        (summary.rejected_steps, summary.over_tolerance_steps) = (nm.retried.rejected, nm.retried.over_tolerance);
        summary.settle_time = self.settle.since;
        summary.fastest_dashpot = FastestDashpot::of(nm, &self.structure.masses, summary.largest_step);
        summary
    }
}

/// The time from which a transient's shape stays within [`SETTLE_TOLERANCE`] of a
/// reference shape, checked at every step.
struct Settle<'r> {
    reference: Option<&'r [Vector3<f64>]>,
    /// The time the shape error last came (and stayed) within the tolerance.
    since: Option<f64>,
}

impl Settle<'_> {
    fn track(&mut self, x: &[Vector3<f64>], time: f64) {
        if let Some(reference) = self.reference {
            let within = shape_error(x, reference).0 <= SETTLE_TOLERANCE;
            self.since = if within { self.since.or(Some(time)) } else { None };
        }
    }
}

/// KE + SE, less the external work W when a load stays on (KE + SE − W is then what a
/// constant load conserves; without one W no longer changes and is left out, so that the
/// figure is KE + SE exactly).
fn mechanical_energy(e: &Energy, loaded: bool) -> f64 {
    let work = if loaded { e.external } else { 0.0 };
    e.kinetic + e.strain - work
}

/// The converged end of a Newmark run as a state over every node; its rest lengths are the
/// stage's last where it changed them, else `rest_lengths` (those it started with).
fn final_state(nm: &Newmark, dofs: &DofMap, rest_lengths: Option<Vec<f64>>) -> State {
    let rest_lengths = if nm.is_actuated() {
        Some(nm.rest_lengths().to_vec())
    } else {
        rest_lengths
    };
    let n = nm.asm.x.len();
    let (mut velocities, mut accelerations) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    for i in 0..dofs.len() {
        let (node, a) = dofs.owner(i);
        velocities[node][a] = nm.v[i];
        accelerations[node][a] = nm.a[i];
    }
    State {
        time: nm.time,
        positions: nm.asm.x.clone(),
        velocities,
        accelerations,
        rest_lengths,
    }
}
