//! Folding by compulsory displacement (paper §5, Figures 5–8): chosen node directions are
//! driven linearly to their targets in N static steps, the rest of the structure finds
//! equilibrium by the common Newton driver at every step. A step that fails is split in
//! halves (bounded); line search did not help in a prototype, sub-stepping did.

use super::eigen::{modes, ModeSolver};
use super::frames::{non_finite, FrameBuilder};
use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::EquilibriumSummary;
use super::{name_free_motion, record_error, solve_error, Analysis, Settings, StaticEquilibrium};
use crate::dynamics::Energy;
use crate::error::{Error, Result};
use crate::model::{height, Model};
use crate::record::{Constraints, Recorder, Stage, StageLayout};
use crate::solve::{bisect, newton, NewtonSettings, NewtonWorkspace, Residual, SolveError};
use crate::structure::{State, Structure};
use crate::tsm::{tangent_sparsity, Assembly, DofMap};
use nalgebra::Vector3;

/// Where one group's prescribed direction goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// Onto the mean coordinate of these nodes (e.g. the base ring) along the axis.
    LevelOf(Vec<usize>),
    /// By this displacement [m].
    Displacement(f64),
}

/// One prescribed direction of a set of nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Prescription {
    /// Indices of the driven nodes.
    pub nodes: Vec<usize>,
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Where the direction is driven to at the last step.
    pub target: Target,
}

/// The folding stage.
#[derive(Clone, Debug)]
pub struct Folding {
    /// Kind and name, for the recorder.
    pub stage: Stage,
    /// Static steps N, each driving the prescriptions by 1/N of the way.
    pub steps: usize,
    /// A failed step is halved up to this many times.
    pub max_cuts: u32,
    /// Applied in order; a later prescription of the same node direction wins.
    pub prescribe: Vec<Prescription>,
    /// The lowest this many eigenvalues at every step (0: none), with the prescribed
    /// directions held: where along the path the structure softens.
    pub modes: usize,
}

/// Key figures of a folding stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FoldSummary {
    /// Static steps N.
    pub steps: usize,
    /// Newton iterations over all steps and sub-steps.
    pub newton_iterations: usize,
    /// Steps that needed sub-stepping.
    pub cut_steps: usize,
    /// Final height over initial height (max z − min z).
    pub height_ratio: f64,
    /// Largest out-of-balance over the recorded steps.
    #[serde(flatten)]
    pub equilibrium: EquilibriumSummary,
    /// The lowest eigenvalues at every step, when asked for (`folding.eigen`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub modes: Vec<PathModes>,
    /// With contact: where the fold stopped short of its target, the struts in the way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped_by_contact: Option<StoppedByContact>,
}

/// A fold that contact stopped.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct StoppedByContact {
    /// The fraction of the prescribed displacement reached (the last converged step).
    pub fraction: f64,
    /// Why the next step could not be taken.
    pub reason: String,
}

/// The lowest eigenvalues of K_T φ = ω² M φ at one folding step, prescribed directions
/// held.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PathModes {
    /// The folding step (0: the start).
    pub step: usize,
    /// ω² ascending [rad²/s²]; negative: unstable.
    pub omega2: Vec<f64>,
    /// The direction the lowest mode moves most (node and axis).
    pub lowest_at: String,
}

/// (node, axis, start value, target value) of every prescribed direction [m].
type Prescribed = Vec<(usize, usize, f64, f64)>;

impl Folding {
    /// The directions this stage constrains: the supports and the prescribed directions.
    pub fn constraints(&self, model: &Model) -> Constraints {
        let prescribed: Vec<(usize, usize)> = self.prescribe.iter().flat_map(|p| p.nodes.iter().map(|&n| (n, p.axis))).collect();
        Constraints::new(model, &prescribed)
    }

    /// Start and target of every prescribed direction from positions `x`.
    /// A direction prescribed twice takes the later prescription, in the later place.
    fn resolve(&self, x: &[Vector3<f64>]) -> Prescribed {
        let mut all: Prescribed = Vec::new();
        for p in &self.prescribe {
            let a = p.axis;
            let level = match &p.target {
                Target::LevelOf(level) => level.iter().map(|&m| x[m][a]).sum::<f64>() / level.len() as f64,
                Target::Displacement(_) => 0.0,
            };
            for &n in &p.nodes {
                let target = match &p.target {
                    Target::Displacement(d) => x[n][a] + d,
                    Target::LevelOf(_) => level,
                };
                all.push((n, a, x[n][a], target));
            }
        }
        // By a table of last places, not a search per push: a grid's top layer is
        // thousands of directions.
        let mut last = vec![usize::MAX; 3 * x.len()];
        all.iter().enumerate().for_each(|(k, &(n, a, _, _))| last[3 * n + a] = k);
        all.into_iter()
            .enumerate()
            .filter(|&(k, (n, a, _, _))| last[3 * n + a] == k)
            .map(|(_, d)| d)
            .collect()
    }
}

/// The state folding carries from step to step.
struct Fold<'a> {
    problem: StaticEquilibrium<'a>,
    prescribed: &'a Prescribed,
    newton: NewtonSettings,
    u: Vec<f64>,
    fraction: f64,
    /// Work done by the prescribed displacements (trapezoidal in the reactions).
    work: f64,
    /// Energy pulley friction dissipated so far [J].
    dissipated: f64,
    ws: NewtonWorkspace,
    /// du/d(fraction) over the last step that converged: the path's secant (empty before
    /// the first).
    secant: Vec<f64>,
}

impl<'a> Fold<'a> {
    /// At the start (fraction 0) of `asm`, under the constant `load` on its free DOFs.
    fn new(asm: Assembly<'a>, load: Vec<f64>, prescribed: &'a Prescribed, settings: &Settings) -> Self {
        let (model, dofs) = (asm.model, asm.dofs);
        Fold {
            u: asm.free_coordinates(),
            ws: NewtonWorkspace::new(dofs.len(), &settings.newton, false, || tangent_sparsity(model, dofs)),
            problem: StaticEquilibrium { load, asm },
            prescribed,
            newton: settings.newton,
            fraction: 0.0,
            work: 0.0,
            dissipated: 0.0,
            secant: Vec::new(),
        }
    }

    /// Moves the prescribed directions from fraction `from` (the current one) to `to`, or
    /// with contact as far towards it as keeps the bodies apart, and solves; on failure
    /// restores the state. Returns the Newton iterations (`fraction`: where it got to).
    fn step(&mut self, _from: f64, mut to: f64) -> Result<usize, SolveError> {
        // Where the fold is (a sub-step before this one may have stopped short at contact).
        let from = self.fraction;
        let (u_old, x_old) = (self.u.clone(), self.problem.asm.x.clone());
        let reaction = |asm: &Assembly, n: usize, a: usize| asm.p[3 * n + a];
        let before: Vec<f64> = self
            .prescribed
            .iter()
            .map(|&(n, a, _, _)| reaction(&self.problem.asm, n, a))
            .collect();
        if let Some(contact) = &mut self.problem.asm.contact {
            let mut dx = vec![Vector3::zeros(); x_old.len()];
            for &(n, a, start, end) in self.prescribed {
                dx[n][a] = (to - from) * (end - start);
            }
            to = from + contact.admissible(&x_old, &dx) * (to - from);
        }
        for &(n, a, start, end) in self.prescribed {
            self.problem.asm.x[n][a] = start + to * (end - start);
        }
        self.predict(to - from);
        let length = self.problem.asm.model.size();
        match newton(&mut self.problem, &mut self.u, &self.newton, length, &mut self.ws) {
            Ok(report) => {
                self.problem.asm.set_free(&self.u);
                self.dissipated += self.problem.asm.commit();
                self.secant.clear();
                self.secant.extend(self.u.iter().zip(&u_old).map(|(u, u0)| (u - u0) / (to - from)));
                for (k, &(n, a, start, end)) in self.prescribed.iter().enumerate() {
                    let dx = (to - from) * (end - start);
                    self.work += 0.5 * (before[k] + reaction(&self.problem.asm, n, a)) * dx;
                }
                // The constant loads' work on the free DOFs (on the prescribed ones it is
                // part of the reactions' p).
                self.work += self
                    .problem
                    .load
                    .iter()
                    .zip(&self.u)
                    .zip(&u_old)
                    .map(|((f, u), u0)| f * (u - u0))
                    .sum::<f64>();
                self.fraction = to;
                Ok(report.iterations)
            }
            Err(e) => {
                self.u = u_old;
                self.problem.asm.x = x_old;
                self.problem.asm.update();
                Err(e)
            }
        }
    }
}

/// A fold step's admissible part below which contact has stopped the fold: the struts
/// are about to touch (the step would close more than 90 % of a gap in a tenth of its
/// travel). Pushing further on would press them together under displacement control,
/// which is infinitely stiff: the barrier's force would grow without bound as the gap
/// closed (a fold taken to 1e-6 of a step left 2.6e12 N on two struts and a start no
/// transient could leave), so the fold stops before, and a force on the structure, not a
/// displacement, is what presses bodies together (tests/contact.rs).
const STALLED: f64 = 0.1;

/// A fold step that failed with `error` (`None`: contact stalled it): with contact, where
/// the fold stops (the prescribed nodes cannot be pushed through the struts; the state is
/// the last converged one, which the frames hold); without, the stage's error (`named`).
fn stopped_by_contact(
    error: Option<SolveError>,
    fold: &Fold,
    step: usize,
    named: impl FnOnce(SolveError) -> Error,
) -> Result<StoppedByContact> {
    if fold.problem.asm.contact.is_none() {
        return Err(named(error.expect("without contact every step reaches its target")));
    }
    let reason = error.map_or_else(
        || format!("step {step}: the struts are about to touch (a step's admissible part fell below {STALLED} of it)"),
        |e| named(e).to_string(),
    );
    Ok(StoppedByContact {
        fraction: fold.fraction,
        reason,
    })
}

/// Steps `fold` to fraction `target` (sub-stepped by `bisect` where Newton fails), over as
/// many steps as contact cuts short; the Newton iterations and whether a step was cut.
/// `Err(None)`: contact stalled the fold short of the target.
fn advance(fold: &mut Fold, target: f64, max_cuts: u32) -> std::result::Result<(usize, bool), Option<SolveError>> {
    let (mut iterations, mut cut) = (0, false);
    while fold.fraction < target {
        let from = fold.fraction;
        let (i, c) = bisect(from, target, max_cuts, &mut |a, b| fold.step(a, b), &|i, j| i + j).map_err(Some)?;
        (iterations, cut) = (iterations + i, cut || c);
        if fold.fraction - from <= STALLED * (target - from) {
            return Err(None);
        }
    }
    Ok((iterations, cut))
}

/// The lowest `count` modes of the structure at the state of `asm` (its free DOFs), dense
/// or partial by size.
/// Also returns the lowest mode over every node (zero at constrained directions), for the
/// frame.
impl Fold<'_> {
    /// Starts Newton from the path extrapolated along the last step's secant over
    /// `span`, where that lowers the potential below the start with the free directions
    /// left where they were.
    ///
    /// Why: the prescribed directions move alone at a step's start, which strains the
    /// members next to them hard (the 47 × 47 grid's first iterate: energy 2e7 J against
    /// 2e2 J converged), and Newton spends most of its iterations on that; the folding
    /// path is smooth from step to step. Either start reaches an equilibrium to the same
    /// tolerances; the energy test keeps the extrapolation from ever starting further up.
    fn predict(&mut self, span: f64) {
        if self.secant.is_empty() {
            return;
        }
        let frozen = self.problem.energy(&self.u);
        let predicted: Vec<f64> = self.u.iter().zip(&self.secant).map(|(u, v)| u + span * v).collect();
        if self.problem.energy(&predicted) < frozen {
            self.u = predicted;
        }
    }
}

fn path_modes(structure: &Structure, asm: &Assembly, step: usize, count: usize) -> Result<(PathModes, Vec<Vector3<f64>>)> {
    let dofs = asm.dofs;
    let m = modes(asm, &structure.free_masses(dofs), &ModeSolver::lowest(count))?;
    let lowest = (0..dofs.len())
        .max_by(|&a, &b| m.shapes[(a, 0)].abs().total_cmp(&m.shapes[(b, 0)].abs()))
        .unwrap_or(0);
    let mut shape = vec![Vector3::zeros(); structure.model.node_count()];
    for i in 0..dofs.len() {
        let (n, a) = dofs.owner(i);
        shape[n][a] = m.shapes[(i, 0)];
    }
    let modes = PathModes {
        step,
        omega2: m.omega2.iter().take(count).copied().collect(),
        lowest_at: dofs.label(&structure.model, lowest),
    };
    Ok((modes, shape))
}

/// The directions `prescribed` imposes, per node.
fn held(model: &Model, prescribed: &Prescribed) -> Vec<[bool; 3]> {
    let mut mask = vec![[false; 3]; model.node_count()];
    for &(n, a, _, _) in prescribed {
        mask[n][a] = true;
    }
    mask
}

impl SequenceStage for Folding {
    fn stage(&self) -> &Stage {
        &self.stage
    }

    fn layout(&self, model: &Model) -> StageLayout {
        StageLayout {
            constraints: self.constraints(model),
            path_modes: self.modes,
            ..StageLayout::plain(model, self.stage.clone())
        }
    }

    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        let model = &run.structure.model;
        let held = held(model, &self.resolve(&start.state.positions));
        let (state, fold) =
            Analysis::run(self, run.structure, start.state.clone(), run.settings, recorder).map_err(name_free_motion(model, &held))?;
        Ok((start.under_same_loads(state), StageSummary::Folding(fold)))
    }
}

impl Analysis for Folding {
    type Summary = FoldSummary;

    fn run(&self, structure: &Structure, state: State, settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, FoldSummary)> {
        let model = &structure.model;
        let prescribed = self.resolve(&state.positions);
        let dofs = DofMap::new(model, &held(model, &prescribed));
        let h0 = height(&state.positions);
        let rest_lengths = state.rest_lengths;
        let rest = rest_lengths.as_deref().unwrap_or(&structure.elements.rest);
        let asm = structure.assembly(&dofs, state.positions, rest);
        super::require_apart(&asm, self.stage.name())?;
        let mut fold = Fold::new(asm, structure.free_load(&dofs), &prescribed, settings);
        let (strain0, contact0) = (fold.problem.asm.strain_energy(), fold.problem.asm.contact_energy());
        let mut frames = FrameBuilder::new(structure, &dofs);
        let applied = structure.constant_load();
        let name = self.stage.name();
        frames.begin(recorder, &self.stage).map_err(record_error(name))?;
        let mut summary = FoldSummary {
            steps: self.steps,
            ..Default::default()
        };
        let mut record = |fold: &Fold, step: usize, recorder: &mut dyn Recorder| {
            if self.modes > 0 {
                let (modes, lowest) = path_modes(structure, &fold.problem.asm, step, self.modes)?;
                frames.modes = Some((modes.omega2.clone(), lowest));
                summary.modes.push(modes);
            }
            let energy = Energy {
                kinetic: 0.0,
                strain: fold.problem.asm.strain_energy() - strain0,
                contact: fold.problem.asm.contact_energy() - contact0,
                damping: fold.dissipated,
                external: fold.work,
                actuation: 0.0,
            };
            frames
                .record(recorder, &fold.problem.asm, step, fold.fraction, energy, &applied)
                .map_err(record_error(name))
        };
        record(&fold, 0, recorder)?;
        let (mut iterations_total, mut cuts_total, mut stopped_at) = (0, 0, None);
        for step in 1..=self.steps {
            let target = step as f64 / self.steps as f64;
            let (iterations, cut) = match advance(&mut fold, target, self.max_cuts) {
                Ok(done) => done,
                Err(e) => {
                    let stopped = stopped_by_contact(e, &fold, step, solve_error(name, Some(step), None, structure, &dofs))?;
                    stopped_at = Some(stopped);
                    record(&fold, step, recorder)?;
                    break;
                }
            };
            iterations_total += iterations;
            cuts_total += usize::from(cut);
            let energy = Energy {
                external: fold.work,
                ..Energy::default()
            };
            if let Some(what) = non_finite(&fold.problem.asm, None, &energy) {
                return Err(Error::Stage {
                    stage: name.into(),
                    reason: format!("step {step}: {what} is not finite"),
                });
            }
            record(&fold, step, recorder)?;
        }
        recorder.end_stage(&self.stage).map_err(record_error(name))?;
        (summary.newton_iterations, summary.cut_steps) = (iterations_total, cuts_total);
        summary.stopped_by_contact = stopped_at;
        summary.equilibrium = frames.check.into();
        summary.height_ratio = height(&fold.problem.asm.x) / h0;
        let end = State {
            rest_lengths: fold.problem.asm.carried_rest(rest_lengths),
            ..State::at_rest(fold.problem.asm.x)
        };
        Ok((end, summary))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node 1's z is prescribed twice: the later prescription wins and takes the later
    /// place; a level target is the level's mean.
    #[test]
    fn a_direction_prescribed_twice_takes_the_later_prescription() {
        let x: Vec<Vector3<f64>> = (0..4).map(|i| Vector3::new(0.0, 0.0, i as f64)).collect();
        let prescribe = |nodes: Vec<usize>, target| Prescription { nodes, axis: 2, target };
        let folding = Folding {
            stage: Stage::of(crate::record::StageKind::Folding),
            steps: 1,
            max_cuts: 0,
            prescribe: vec![
                prescribe(vec![0, 1], Target::Displacement(-0.5)),
                prescribe(vec![2], Target::Displacement(1.0)),
                prescribe(vec![1, 3], Target::LevelOf(vec![0, 2])),
            ],
            modes: 0,
        };
        assert_eq!(
            folding.resolve(&x),
            vec![(0, 2, 0.0, -0.5), (2, 2, 2.0, 3.0), (1, 2, 1.0, 1.0), (3, 2, 3.0, 1.0)]
        );
    }
}
