//! A time-stepping stage (free vibration, deployment): Newmark from a given state (with
//! initial displacements and velocities added) under the structure's constant load, nodal
//! loads with time functions and ground motion, every converged step recorded, with the
//! figures the checks need.

use super::frames::{non_finite, FrameBuilder, Motion};
use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::EquilibriumSummary;
use super::{record_error, solve_error, Analysis, Settings};
use crate::dynamics::{
    Actuator, AxialForces, Damping, DampingTangent, Energy, FreeLoads, Integrator, Loads, Newmark, NewmarkParams, Rayleigh, RestSchedule,
};
use crate::error::{Error, Result};
use crate::model::{shape_error, MemberKind, Model};
use crate::record::{Recorder, Stage, StageLayout};
use crate::solve::NewtonReport;
use crate::structure::{State, Structure};
use crate::tsm::{Assembly, DofMap};
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
        StageLayout {
            actuated: !self.stage.actuators.is_empty(),
            ..StageLayout::plain(model, self.stage.stage.clone())
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
        Ok((start.under_same_loads(end), StageSummary::Transient(figures)))
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
    /// Time steps of Δt, duration/Δt rounded.
    pub steps: usize,
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
    /// Wall time of the stage, recording included [s].
    pub wall_seconds: f64,
    /// Largest out-of-balance over the recorded steps.
    #[serde(flatten)]
    pub equilibrium: EquilibriumSummary,
}

impl TransientSummary {
    /// Counts a converged step's Newton work; `cut`: it was cut in parts.
    fn add_effort(&mut self, report: &NewtonReport, cut: bool) {
        self.newton_iterations += report.iterations;
        self.factorizations += report.factorizations;
        self.cut_steps += usize::from(cut);
    }

    /// Takes in one converged step at stage time `time`, its members' axial forces
    /// (elastic + viscous) found into `axial`; `load_end` is when the loads stop changing;
    /// `loaded` whether some load stays on after that (then the mechanical energy counted
    /// is KE + SE − W, which a constant load leaves conserved).
    fn add_step(
        &mut self,
        nm: &Newmark,
        axial: &mut AxialForces,
        time: f64,
        (load_end, loaded): (f64, bool),
        dt: f64,
        mechanical: &mut f64,
    ) {
        axial.update(nm);
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
                MemberKind::Strut => self.max_strut_compression = self.max_strut_compression.max(-force),
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
        let dofs = DofMap::new(model, &[]);
        let state = self.initial.apply(model, state).map_err(|reason| Error::Stage {
            stage: name.into(),
            reason,
        })?;
        let masses = structure.free_masses(&dofs);
        let constant = structure.constant_load();
        let loads = FreeLoads::new(&self.loads, &constant, &masses, &dofs);
        let load_free = |t: f64, f: &mut [f64]| loads.at(t, &dofs, f);
        let started = std::time::Instant::now();
        let mut f0 = vec![0.0; dofs.len()];
        load_free(0.0, &mut f0);
        let rest_lengths = state.rest_lengths.clone();
        let mut nm = self.start(structure, &dofs, state, (masses, f0), settings);
        let dt = self.params.dt;
        let steps = (self.duration / dt).round() as usize;
        let load_end = self.load_end(&constant);
        let mut summary = TransientSummary {
            steps,
            ..Default::default()
        };
        let mut frames = FrameBuilder::new(structure, &dofs);
        frames.begin(recorder, &self.stage).map_err(record_error(name))?;
        let mut applied = constant.clone();
        let mut record = |frames: &mut FrameBuilder, nm: &Newmark, step: usize, load_time: f64, recorder: &mut dyn Recorder| {
            self.applied_load(structure, &dofs, &constant, load_time, &mut applied);
            let ground = self.loads.ground_acceleration(load_time);
            let motion = Motion {
                newmark: nm,
                support_acceleration: ground,
            };
            frames.record_motion(recorder, motion, step, &applied).map_err(record_error(name))
        };
        record(&mut frames, &nm, 0, 0.0, recorder)?;
        let mut settle = Settle { reference, since: None };
        settle.track(&nm.asm.x, 0.0);
        let (mut mechanical, mut axial) = (mechanical_energy(&nm.energy(), load_end.1), AxialForces::default());
        for step in 1..=steps {
            let time = step as f64 * dt;
            let failed_before = nm.retried.attempts;
            let report = nm
                .advance(dt, &load_free)
                .map_err(solve_error(name, Some(step), Some(time), structure, &dofs))?;
            let load_time = nm.time;
            // Re-anchor time to the step grid so that long runs do not drift.
            nm.time = time;
            if let Some(what) = non_finite(&nm.asm, Some(&nm.v), &nm.energy()) {
                let reason = format!("step {step} (t = {time:.4} s): {what} is not finite");
                return Err(Error::Stage {
                    stage: name.into(),
                    reason,
                });
            }
            summary.add_effort(&report, nm.retried.attempts > failed_before);
            summary.add_step(&nm, &mut axial, time, load_end, dt, &mut mechanical);
            settle.track(&nm.asm.x, time);
            if step % settings.every == 0 || step == steps {
                record(&mut frames, &nm, step, load_time, recorder)?;
            } else {
                frames.observe(&nm.asm.x, step, time);
            }
        }
        recorder.end_stage(&self.stage).map_err(record_error(name))?;
        summary.equilibrium = frames.check.into();
        summary.final_kinetic = nm.energy().kinetic;
        (summary.failed_iterations, summary.failed_factorizations) = (nm.retried.iterations, nm.retried.factorizations);
        summary.settle_time = settle.since;
        summary.wall_seconds = started.elapsed().as_secs_f64();
        Ok((final_state(&nm, &dofs, rest_lengths), summary))
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
        let asm = Assembly::with_rest_lengths(&structure.model, &structure.elements, dofs, state.positions, rest);
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
        self.loads.add_nodal(load_time, applied);
        let ground = self.loads.ground_acceleration(load_time);
        if ground != Vector3::zeros() {
            for i in 0..dofs.len() {
                let (n, a) = dofs.owner(i);
                applied[n][a] -= structure.masses[n] * ground[a];
            }
        }
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
