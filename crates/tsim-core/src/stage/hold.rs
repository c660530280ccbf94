//! The hold stage: the loads of its start held while members' rest lengths change, in
//! static steps — the quasi-static counterpart of a transient's actuation (a winch reeled
//! in slowly enough for inertia not to matter). Each step sets the rest lengths of its
//! fraction s and solves r = f − p(u; l0(s)) = 0 by the common Newton driver on the TSM
//! residual, halving a failing step.

use super::frames::{non_finite, FrameBuilder};
use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::{name_free_motion, record_error, solve_error, Analysis, EquilibriumSummary, Settings, StaticEquilibrium};
use crate::dynamics::{Actuator, Energy, RestSchedule};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{Recorder, Stage, StageLayout};
use crate::solve::{bisect, newton, NewtonWorkspace};
use crate::structure::{free_values, State, Structure};
use crate::tsm::{tangent_sparsity, Assembly, DofMap};
use nalgebra::Vector3;

/// The hold stage.
#[derive(Clone, Debug)]
pub struct Hold {
    /// Kind and name, for the recorder.
    pub stage: Stage,
    /// The rest-length changes; each one's time function is of the stage's fraction
    /// s ∈ [0, 1] (a ramp over 1: a linear change in `steps` equal steps).
    pub actuators: Vec<Actuator>,
    /// Static steps.
    pub steps: usize,
    /// A failed step is halved up to this many times.
    pub max_cuts: u32,
    /// The start is under the structure's constant load already; otherwise (the unloaded
    /// shape) the constant load is stepped with the change.
    pub start_loaded: bool,
}

/// Key figures of a hold stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct HoldSummary {
    /// Static steps.
    pub steps: usize,
    /// Newton iterations over all steps and sub-steps.
    pub newton_iterations: usize,
    /// Steps that needed sub-stepping.
    pub cut_steps: usize,
    /// Largest node displacement from the start [m].
    pub max_displacement: f64,
    /// Work the changing rest lengths did on the structure, Σ ∫ ∂U/∂l0 dl0 [J].
    pub actuator_work: f64,
    /// The energy balance at the end, |ΔU − W − W_a| [J] (W: the loads' work; trapezoidal
    /// in the steps, so it falls as 1/steps²).
    pub energy_balance_error: f64,
    /// Lowest eigenvalue of K_T at the end [N/m] (< 0: unstable).
    pub lowest_stiffness: f64,
    /// Σ reactions + Σ loads at every step.
    #[serde(flatten)]
    pub equilibrium: EquilibriumSummary,
}

/// The energy ledger of the steps: the work of the loads and of the rest lengths.
struct Ledger {
    strain0: f64,
    contact0: f64,
    external: f64,
    actuation: f64,
    /// Energy pulley friction dissipated [J] ([`crate::tsm::Assembly::commit`]): taken
    /// in, and in the sub-steps since the last step taken in.
    dissipated: f64,
    pending: f64,
    /// ∂U/∂l0 of every member at the last converged step [N].
    force: Vec<f64>,
    force_next: Vec<f64>,
    rest: Vec<f64>,
}

impl Ledger {
    fn new(asm: &Assembly) -> Self {
        let mut force = vec![0.0; asm.rest.len()];
        asm.energy_rest_derivatives(&mut force);
        Ledger {
            strain0: asm.strain_energy(),
            contact0: asm.contact_energy(),
            external: 0.0,
            actuation: 0.0,
            dissipated: 0.0,
            pending: 0.0,
            force_next: force.clone(),
            force,
            rest: asm.rest.clone(),
        }
    }

    /// Takes in a converged step from `previous` to `asm`'s positions, the load going
    /// from `before` to `after` (trapezoidal rule on both works), pulley friction having
    /// dissipated `pending`: the rest lengths' work Σ q̄ Δl0 counts the slip over the
    /// pulleys too (−`pending`), which is not the actuators'.
    fn advance(&mut self, asm: &Assembly, previous: &[Vector3<f64>], before: &[Vector3<f64>], after: &[Vector3<f64>]) {
        let dissipated = std::mem::take(&mut self.pending);
        for n in 0..previous.len() {
            self.external += 0.5 * (before[n] + after[n]).dot(&(asm.x[n] - previous[n]));
        }
        asm.energy_rest_derivatives(&mut self.force_next);
        for m in 0..self.rest.len() {
            self.actuation += 0.5 * (self.force[m] + self.force_next[m]) * (asm.rest[m] - self.rest[m]);
        }
        self.actuation += dissipated;
        self.dissipated += dissipated;
        std::mem::swap(&mut self.force, &mut self.force_next);
        self.rest.copy_from_slice(&asm.rest);
    }

    fn energy(&self, asm: &Assembly) -> Energy {
        Energy {
            kinetic: 0.0,
            strain: asm.strain_energy() - self.strain0,
            contact: asm.contact_energy() - self.contact0,
            damping: self.dissipated,
            external: self.external,
            actuation: self.actuation,
        }
    }
}

/// What the stage records: its frames and the energy ledger behind them.
struct Recording<'a> {
    stage: &'a Stage,
    frames: FrameBuilder,
    ledger: Ledger,
}

impl Recording<'_> {
    /// Records the state of `asm` under `applied` as step `step` at fraction `s`.
    fn record(&mut self, asm: &Assembly, step: usize, s: f64, applied: &[Vector3<f64>], recorder: &mut dyn Recorder) -> Result<()> {
        let energy = self.ledger.energy(asm);
        if let Some(what) = non_finite(asm, None, &energy) {
            return Err(Error::Stage {
                stage: self.stage.name.clone(),
                reason: format!("step {step}: {what} is not finite"),
            });
        }
        self.frames
            .record(recorder, asm, step, s, energy, applied)
            .map_err(record_error(self.stage.name()))
    }
}

/// The load at fraction `s`: `base` + s (`target` − `base`).
fn load_at(base: &[Vector3<f64>], target: &[Vector3<f64>], s: f64) -> Vec<Vector3<f64>> {
    base.iter().zip(target).map(|(b, t)| b + (t - b) * s).collect()
}

impl Analysis for Hold {
    type Summary = HoldSummary;

    /// From the equilibrium `state`, changes the rest lengths and, from the unloaded
    /// shape, steps the structure's constant load with them.
    fn run(&self, structure: &Structure, state: State, settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, HoldSummary)> {
        let model = &structure.model;
        let name = self.stage.name();
        let dofs = DofMap::new(model, &[]);
        let target = structure.constant_load();
        let base = if self.start_loaded {
            target.clone()
        } else {
            vec![Vector3::zeros(); model.node_count()]
        };
        super::whole_cables(model, &self.actuators, name)?;
        let schedule = RestSchedule::new(state.rest_of(structure).to_vec(), self.actuators.clone());
        let asm = structure.assembly(&dofs, state.positions.clone(), state.rest_of(structure));
        super::require_apart(&asm, name)?;
        let mut frames = FrameBuilder::new(structure, &dofs);
        frames.actuated = true;
        frames.begin(recorder, &self.stage).map_err(record_error(name))?;
        let mut recording = Recording {
            stage: &self.stage,
            ledger: Ledger::new(&asm),
            frames,
        };
        recording.record(&asm, 0, 0.0, &base, recorder)?;
        let mut problem = StaticEquilibrium {
            load: free_values(&dofs, &base),
            asm,
        };
        let mut u = problem.asm.free_coordinates();
        let mut ws = NewtonWorkspace::new(dofs.len(), &settings.newton, false, || tangent_sparsity(model, &dofs));
        let mut rest = state.rest_of(structure).to_vec();
        let mut summary = HoldSummary {
            steps: self.steps,
            ..Default::default()
        };
        let mut applied = base.clone();
        for step in 1..=self.steps {
            let previous = problem.asm.x.clone();
            let (from, to) = ((step - 1) as f64 / self.steps as f64, step as f64 / self.steps as f64);
            let mut solve_to = |_, s: f64| {
                schedule.at(s, &mut rest);
                problem.asm.set_rest(&rest);
                problem.load = free_values(&dofs, &load_at(&base, &target, s));
                let saved = u.clone();
                let iterations = newton(&mut problem, &mut u, &settings.newton, model.size(), &mut ws)
                    .map(|r| r.iterations)
                    .inspect_err(|_| u.clone_from(&saved))?;
                recording.ledger.pending += problem.asm.commit();
                Ok(iterations)
            };
            let (iterations, cut) = bisect(from, to, self.max_cuts, &mut solve_to, &|a, b| a + b).map_err(solve_error(
                name,
                Some(step),
                None,
                structure,
                &dofs,
            ))?;
            summary.newton_iterations += iterations;
            summary.cut_steps += usize::from(cut);
            let now = load_at(&base, &target, to);
            recording.ledger.advance(&problem.asm, &previous, &applied, &now);
            applied = now;
            for (x, x0) in problem.asm.x.iter().zip(&state.positions) {
                summary.max_displacement = summary.max_displacement.max((x - x0).norm());
            }
            recording.record(&problem.asm, step, to, &applied, recorder)?;
        }
        recorder.end_stage(&self.stage).map_err(record_error(name))?;
        let asm = problem.asm;
        let energy = recording.ledger.energy(&asm);
        summary.actuator_work = energy.actuation;
        summary.energy_balance_error = (energy.strain + energy.damping - energy.external - energy.actuation).abs();
        summary.equilibrium = recording.frames.check.into();
        summary.lowest_stiffness = super::eigen::lowest_stiffness(&asm)?.value;
        let end = State {
            rest_lengths: Some(asm.rest.clone()),
            ..State::at_rest(asm.x)
        };
        Ok((end, summary))
    }
}

impl SequenceStage for Hold {
    fn stage(&self) -> &Stage {
        &self.stage
    }

    fn layout(&self, model: &Model) -> StageLayout {
        StageLayout {
            actuated: true,
            ..StageLayout::plain(model, self.stage.clone())
        }
    }

    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        let (state, hold) = Analysis::run(self, run.structure, start.state.clone(), run.settings, recorder)
            .map_err(name_free_motion(&run.structure.model, &[]))?;
        Ok((start.under_same_loads(state), StageSummary::Hold(hold)))
    }
}
