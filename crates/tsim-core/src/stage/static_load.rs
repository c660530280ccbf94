//! The static-load stage (after substitution): gravity and nodal loads applied to the
//! unloaded equilibrium in load steps, or a nodal load pattern whose factor λ follows the
//! displacement of one node direction (displacement control), which passes limit points
//! where load control stops. Both are the common Newton driver on the TSM residual
//! r = f_ext − p(u); what the stage applies stays on in every later stage.

use super::frames::{non_finite, FrameBuilder};
use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::{name_free_motion, record_error, solve_error, Analysis, EquilibriumSummary, Settings, StaticEquilibrium};
use crate::dynamics::Energy;
use crate::error::{Error, Result};
use crate::record::{Recorder, Stage};
use crate::solve::{bisect, newton, NewtonSettings, NewtonWorkspace, Residual, Scale, SolveError, Sparsity, TangentSink};
use crate::structure::{free_values, State, Structure};
use crate::tsm::{tangent_sparsity, Assembly, DofMap};
use nalgebra::Vector3;

/// The static-load stage.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticLoad {
    /// Kind and name, for the recorder.
    pub stage: Stage,
    /// Nodal load pattern this stage adds [N per node] (empty: gravity only).
    pub loads: Vec<Vector3<f64>>,
    /// Load (or displacement) steps.
    pub steps: usize,
    /// A failed step is halved up to this many times.
    pub max_cuts: u32,
    /// Displacement control; `None`: load control (λ = 1 at the last step).
    pub control: Option<Control>,
    /// The start is under the structure's constant load (weight, dead loads) already, so
    /// only the pattern is stepped; otherwise (the unloaded shape) the constant load is
    /// stepped with it.
    pub start_loaded: bool,
}

/// Displacement control: the free direction `axis` of `node` moves by `displacement` [m].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Control {
    /// Index of the controlled node.
    pub node: usize,
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Its total displacement over the stage [m].
    pub displacement: f64,
}

/// Key figures of a static-load stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct StaticSummary {
    /// Load (or displacement) steps.
    pub steps: usize,
    /// Newton iterations over all steps and sub-steps.
    pub newton_iterations: usize,
    /// Steps that needed sub-stepping.
    pub cut_steps: usize,
    /// Factor λ on the `loads` pattern at the end (1 under load control).
    pub load_factor: f64,
    /// Largest node displacement from the unloaded equilibrium [m].
    pub max_displacement: f64,
    /// Lowest eigenvalue of K_T at the loaded equilibrium [N/m] (< 0: unstable) — the
    /// state every later stage starts from.
    pub lowest_stiffness: f64,
    /// Σ reactions + Σ loads at every step.
    #[serde(flatten)]
    pub equilibrium: EquilibriumSummary,
}

impl StaticLoad {
    /// The loads that stay on after the stage ended at load factor `lambda`: those of
    /// its start (`before`, empty for none) and its pattern × λ.
    pub fn dead_load(&self, before: &[Vector3<f64>], lambda: f64) -> Vec<Vector3<f64>> {
        let pattern = self.loads.iter().map(|f| f * lambda);
        if before.is_empty() {
            return pattern.collect();
        }
        if self.loads.is_empty() {
            return before.to_vec();
        }
        before.iter().zip(pattern).map(|(b, p)| b + p).collect()
    }
}

/// Static equilibrium with the load pattern's factor λ as the unknown in place of the
/// controlled coordinate (held at `coordinate`): r = f_c + λ f_p − p(u). Its tangent is
/// K_T with the controlled column replaced by −f_p: not symmetric, no potential.
struct PatternControl<'a> {
    asm: Assembly<'a>,
    constant: Vec<f64>,
    pattern: Vec<f64>,
    /// The controlled free DOF, whose slot in the unknowns holds λ.
    dof: usize,
    coordinate: f64,
    /// The unknowns with the controlled coordinate in place of λ.
    coordinates: Vec<f64>,
}

impl PatternControl<'_> {
    fn load(&self, lambda: f64) -> impl Iterator<Item = f64> + '_ {
        self.constant.iter().zip(&self.pattern).map(move |(c, p)| c + lambda * p)
    }
}

impl Residual for PatternControl<'_> {
    fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
        self.coordinates.copy_from_slice(u);
        self.coordinates[self.dof] = self.coordinate;
        self.asm.set_free(&self.coordinates);
        let lambda = u[self.dof];
        let mut applied = 0.0_f64;
        for (i, f) in self.load(lambda).enumerate() {
            r[i] = f - self.asm.p_free(i);
            applied = applied.max(f.abs());
        }
        self.asm.scale(applied)
    }

    fn tangent(&mut self, k: &mut dyn TangentSink) {
        self.asm.add_tangent(1.0, &mut WithoutColumn { sink: k, col: self.dof });
        for (i, &p) in self.pattern.iter().enumerate() {
            if p != 0.0 {
                k.add(i, self.dof, -p);
            }
        }
    }

    fn symmetric(&self) -> bool {
        false
    }

    /// λ is a load factor, not a length: the step limit and the increment test leave it out
    /// (limited like a length, λ moved by at most max_step × model size per iteration).
    fn length_of(&self, d: &[f64]) -> Option<f64> {
        let coordinates = d.iter().enumerate().filter(|&(i, _)| i != self.dof);
        Some(coordinates.fold(0.0, |m, (_, v)| m.max(v.abs())))
    }

    /// The coordinates' part of `d` (λ's slot is the controlled coordinate, which stays).
    fn admissible(&mut self, _u: &[f64], d: &[f64]) -> f64 {
        if self.asm.contact.is_none() {
            return 1.0;
        }
        let mut moved = d.to_vec();
        moved[self.dof] = 0.0;
        self.asm.admissible(&moved, 1.0)
    }
}

/// A sink that drops one column (the controlled coordinate's, replaced by λ's).
struct WithoutColumn<'s> {
    sink: &'s mut dyn TangentSink,
    col: usize,
}

impl TangentSink for WithoutColumn<'_> {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        if col != self.col {
            self.sink.add(row, col, value);
        }
    }

    fn holds(&self, row: usize, col: usize) -> bool {
        self.sink.holds(row, col)
    }
}

/// The positions a phase reached, and the rest lengths it carries on (`None`: the stage's).
type PhaseEnd = (Vec<Vector3<f64>>, Option<Vec<f64>>);

/// What the stage carries from step to step.
struct Steps<'a> {
    stage: &'a Stage,
    structure: &'a Structure,
    dofs: &'a DofMap,
    newton: NewtonSettings,
    /// The load on every node at the current point [N].
    applied: Vec<Vector3<f64>>,
    /// Work of the applied loads so far (trapezoidal) [J].
    work: f64,
    /// Energy pulley friction dissipated so far [J].
    dissipated: f64,
    start: Vec<Vector3<f64>>,
    strain0: f64,
    contact0: f64,
    summary: StaticSummary,
    frames: FrameBuilder,
    recorded: usize,
}

impl Steps<'_> {
    /// Records the state of `asm` under the current loads.
    fn record(&mut self, asm: &Assembly, fraction: f64, recorder: &mut dyn Recorder) -> Result<()> {
        let energy = Energy {
            kinetic: 0.0,
            strain: asm.strain_energy() - self.strain0,
            contact: asm.contact_energy() - self.contact0,
            damping: self.dissipated,
            external: self.work,
            actuation: 0.0,
        };
        if let Some(what) = non_finite(asm, None, &energy) {
            return Err(Error::Stage {
                stage: self.stage.name.clone(),
                reason: format!("step {}: {what} is not finite", self.recorded),
            });
        }
        self.frames
            .record(recorder, asm, self.recorded, fraction, energy, &self.applied)
            .map_err(record_error(self.stage.name()))?;
        self.recorded += 1;
        Ok(())
    }

    /// Takes in a converged step to positions `x` under loads `applied`.
    fn advance(&mut self, x: &[Vector3<f64>], applied: Vec<Vector3<f64>>, previous: &[Vector3<f64>]) {
        for n in 0..x.len() {
            self.work += 0.5 * (self.applied[n] + applied[n]).dot(&(x[n] - previous[n]));
            let d = (x[n] - self.start[n]).norm();
            self.summary.max_displacement = self.summary.max_displacement.max(d);
        }
        self.applied = applied;
    }

    /// Takes `phase` to its end in `steps` equal steps (each halved on failure up to
    /// `max_cuts` times), recording each; the load is `base` + factor × `pattern`.
    /// Returns the final factor.
    fn run_phase(
        &mut self,
        phase: &mut impl Phase,
        [base, pattern]: [&[Vector3<f64>]; 2],
        steps: usize,
        max_cuts: u32,
        recorder: &mut dyn Recorder,
    ) -> Result<f64> {
        let mut factor = 0.0;
        for step in 1..=steps {
            let previous = phase.asm().x.clone();
            let (from, to) = ((step - 1) as f64 / steps as f64, step as f64 / steps as f64);
            let (iterations, cut) = bisect(from, to, max_cuts, &mut |_, to| phase.solve_to(to), &|a, b| a + b).map_err(solve_error(
                self.stage.name(),
                Some(self.recorded),
                None,
                self.structure,
                self.dofs,
            ))?;
            factor = phase.factor(to);
            self.summary.newton_iterations += iterations;
            self.summary.cut_steps += usize::from(cut);
            self.dissipated += phase.dissipated();
            let applied = base.iter().zip(pattern).map(|(b, p)| b + p * factor).collect();
            self.advance(&phase.asm().x, applied, &previous);
            self.record(phase.asm(), factor, recorder)?;
        }
        Ok(factor)
    }

    /// Load control: from `asm`'s state under the current loads to the total load
    /// `target`, in proportional steps. Returns the final positions and the rest lengths
    /// to carry on where friction made them history ([`Assembly::carried_rest`]).
    fn load_control(
        &mut self,
        asm: Assembly<'_>,
        target: &[Vector3<f64>],
        steps: usize,
        max_cuts: u32,
        recorder: &mut dyn Recorder,
    ) -> Result<PhaseEnd> {
        let dofs = self.dofs;
        let base = self.applied.clone();
        let pattern: Vec<Vector3<f64>> = base.iter().zip(target).map(|(b, t)| t - b).collect();
        let model = &self.structure.model;
        let mut phase = LoadSteps {
            solver: Solver::new(asm.free_coordinates(), self.newton, dofs, model, tangent_sparsity(model, dofs)),
            base: free_values(dofs, &base),
            pattern: free_values(dofs, &pattern),
            problem: StaticEquilibrium {
                load: free_values(dofs, &base),
                asm,
            },
        };
        self.run_phase(&mut phase, [&base, &pattern], steps, max_cuts, recorder)?;
        let carried = phase.problem.asm.carried_rest(None);
        Ok((phase.problem.asm.x, carried))
    }

    /// Displacement control: the `pattern` load's factor follows `control` in `steps`
    /// equal steps, on top of the current loads. Returns where it got to (as
    /// [`Self::load_control`]) and λ.
    fn displacement_control(
        &mut self,
        asm: Assembly<'_>,
        pattern: &[Vector3<f64>],
        control: Control,
        steps: usize,
        max_cuts: u32,
        recorder: &mut dyn Recorder,
    ) -> Result<(PhaseEnd, f64)> {
        let dofs = self.dofs;
        let model = &self.structure.model;
        let dof = dofs.free(control.node, control.axis).ok_or_else(|| Error::Stage {
            stage: self.stage.name.clone(),
            reason: format!(
                "the controlled direction, node `{}` {}, is supported; control a free direction",
                model.nodes[control.node].id,
                crate::model::AXES[control.axis]
            ),
        })?;
        let base = self.applied.clone();
        let start = asm.x[control.node][control.axis];
        let pattern_free = free_values(dofs, pattern);
        let pattern_rows: Vec<(usize, usize)> = pattern_free
            .iter()
            .enumerate()
            .filter(|(_, p)| **p != 0.0)
            .map(|(i, _)| (i, dof))
            .collect();
        let mut u = asm.free_coordinates();
        u[dof] = 0.0;
        let mut phase = ControlSteps {
            solver: Solver::new(u.clone(), self.newton, dofs, model, {
                // λ takes the control DOF's place: its column gains the loaded rows.
                let Sparsity { entries, order } = tangent_sparsity(model, dofs);
                Sparsity {
                    entries: entries.chain(pattern_rows),
                    order,
                }
            }),
            start,
            displacement: control.displacement,
            problem: PatternControl {
                constant: free_values(dofs, &base),
                pattern: pattern_free,
                dof,
                coordinate: start,
                coordinates: u,
                asm,
            },
        };
        let lambda = self.run_phase(&mut phase, [&base, pattern], steps, max_cuts, recorder)?;
        let carried = phase.problem.asm.carried_rest(None);
        Ok(((phase.problem.asm.x, carried), lambda))
    }
}

/// A phase of the static stage: a problem taken to a fraction of its way and solved.
trait Phase {
    /// Moves to fraction `to` and solves; on failure restores the last converged state.
    /// Returns the Newton iterations.
    fn solve_to(&mut self, to: f64) -> Result<usize, SolveError>;
    /// The assembly at the last converged state (the last one evaluated).
    fn asm(&self) -> &Assembly<'_>;
    /// The factor on the phase's load pattern at the converged fraction `to`.
    fn factor(&self, to: f64) -> f64;
    /// The energy pulley friction dissipated since the last call [J].
    fn dissipated(&mut self) -> f64;
}

/// The unknowns of a phase and what solves them.
struct Solver {
    u: Vec<f64>,
    ws: NewtonWorkspace,
    newton: NewtonSettings,
    length: f64,
    /// What pulley friction dissipated in the steps solved since it was last taken [J].
    dissipated: f64,
}

impl Solver {
    fn new(
        u: Vec<f64>,
        newton: NewtonSettings,
        dofs: &DofMap,
        model: &crate::model::Model,
        sparsity: Sparsity<impl IntoIterator<Item = (usize, usize)>>,
    ) -> Self {
        Solver {
            ws: NewtonWorkspace::new(dofs.len(), &newton, false, || sparsity),
            u,
            newton,
            length: model.size(),
            dissipated: 0.0,
        }
    }

    /// Newton on `problem` from the current unknowns, its converged state committed
    /// (`asm` of it: [`Assembly::commit`]); restores the unknowns on failure.
    fn solve<'a, P: Residual>(&mut self, problem: &mut P, asm: impl Fn(&mut P) -> &mut Assembly<'a>) -> Result<usize, SolveError> {
        let saved = self.u.clone();
        let iterations = newton(problem, &mut self.u, &self.newton, self.length, &mut self.ws)
            .map(|r| r.iterations)
            .inspect_err(|_| self.u.clone_from(&saved))?;
        self.dissipated += asm(problem).commit();
        Ok(iterations)
    }
}

/// Load control: the load base + s × pattern at fraction s.
struct LoadSteps<'a> {
    problem: StaticEquilibrium<'a>,
    solver: Solver,
    base: Vec<f64>,
    pattern: Vec<f64>,
}

impl Phase for LoadSteps<'_> {
    fn solve_to(&mut self, to: f64) -> Result<usize, SolveError> {
        for ((f, b), p) in self.problem.load.iter_mut().zip(&self.base).zip(&self.pattern) {
            *f = b + p * to;
        }
        self.solver.solve(&mut self.problem, |p| &mut p.asm)
    }

    fn asm(&self) -> &Assembly<'_> {
        &self.problem.asm
    }

    fn factor(&self, to: f64) -> f64 {
        to
    }

    fn dissipated(&mut self) -> f64 {
        std::mem::take(&mut self.solver.dissipated)
    }
}

/// Displacement control: the controlled coordinate at start + s × displacement, λ found.
struct ControlSteps<'a> {
    problem: PatternControl<'a>,
    solver: Solver,
    start: f64,
    displacement: f64,
}

impl Phase for ControlSteps<'_> {
    fn solve_to(&mut self, to: f64) -> Result<usize, SolveError> {
        self.problem.coordinate = self.start + to * self.displacement;
        self.solver.solve(&mut self.problem, |p| &mut p.asm)
    }

    fn asm(&self) -> &Assembly<'_> {
        &self.problem.asm
    }

    fn factor(&self, _to: f64) -> f64 {
        self.solver.u[self.problem.dof]
    }

    fn dissipated(&mut self) -> f64 {
        std::mem::take(&mut self.solver.dissipated)
    }
}

impl Analysis for StaticLoad {
    type Summary = StaticSummary;

    /// From the equilibrium `state`, applies this stage's pattern and, from the unloaded
    /// shape, the structure's constant load (weight, dead loads).
    fn run(&self, structure: &Structure, state: State, settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, StaticSummary)> {
        let model = &structure.model;
        let dofs = DofMap::new(model, &[]);
        let n = model.node_count();
        let rest = state.rest_of(structure);
        let asm = structure.assembly(&dofs, state.positions.clone(), rest);
        super::require_apart(&asm, self.stage.name())?;
        let mut steps = Steps {
            stage: &self.stage,
            structure,
            dofs: &dofs,
            newton: settings.newton,
            applied: if self.start_loaded {
                structure.constant_load()
            } else {
                vec![Vector3::zeros(); n]
            },
            work: 0.0,
            dissipated: 0.0,
            start: state.positions.clone(),
            strain0: asm.strain_energy(),
            contact0: asm.contact_energy(),
            summary: StaticSummary {
                steps: self.steps,
                load_factor: 1.0,
                ..Default::default()
            },
            frames: FrameBuilder::new(structure, &dofs),
            recorded: 0,
        };
        steps.frames.begin(recorder, &self.stage).map_err(record_error(self.stage.name()))?;
        steps.record(&asm, 0.0, recorder)?;
        let constant = structure.constant_load();
        let (x, carried) = match self.control {
            None => {
                let total: Vec<Vector3<f64>> = constant.iter().zip(self.pattern(n)).map(|(c, p)| c + p).collect();
                steps.load_control(asm, &total, self.steps, self.max_cuts, recorder)?
            }
            Some(control) => {
                let (x, carried) = if !self.start_loaded && constant.iter().any(|f| *f != Vector3::zeros()) {
                    steps.load_control(asm, &constant, self.steps, self.max_cuts, recorder)?
                } else {
                    (asm.x.clone(), None)
                };
                let asm = structure.assembly(&dofs, x, carried.as_deref().unwrap_or(rest));
                let (reached, lambda) = steps.displacement_control(asm, &self.pattern(n), control, self.steps, self.max_cuts, recorder)?;
                steps.summary.load_factor = lambda;
                reached
            }
        };
        recorder.end_stage(&self.stage).map_err(record_error(self.stage.name()))?;
        steps.summary.equilibrium = steps.frames.check.into();
        let asm = structure.assembly(&dofs, x, carried.as_deref().unwrap_or(rest));
        steps.summary.lowest_stiffness = super::eigen::lowest_stiffness(&asm)?.value;
        let end = State {
            rest_lengths: carried.or_else(|| state.rest_lengths.clone()),
            ..State::at_rest(asm.x)
        };
        Ok((end, steps.summary))
    }
}

impl SequenceStage for StaticLoad {
    fn stage(&self) -> &Stage {
        &self.stage
    }

    /// The loads of its start stay on, with its pattern at the factor it ended at.
    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        let (state, statics) = Analysis::run(self, run.structure, start.state.clone(), run.settings, recorder)
            .map_err(name_free_motion(&run.structure.model, &[]))?;
        let dead_load = self.dead_load(&start.dead_load, statics.load_factor);
        Ok((Reached { state, dead_load }, StageSummary::Static(statics)))
    }
}

impl StaticLoad {
    /// The pattern over `n` nodes (zeros when empty).
    fn pattern(&self, n: usize) -> Vec<Vector3<f64>> {
        if self.loads.is_empty() {
            vec![Vector3::zeros(); n]
        } else {
            self.loads.clone()
        }
    }
}
