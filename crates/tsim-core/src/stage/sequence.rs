//! A case's stages as data: the list the pipeline runs after form-finding and
//! substitution, each stage with the state it starts from and what it takes from earlier
//! stages, by index, never through the structure. The config's `stages` list and the
//! paper's sections (its shorthand) both plan into this.

use super::eigen::{Eigen, EigenSummary};
use super::fold::{FoldSummary, Folding};
use super::static_load::{StaticLoad, StaticSummary};
use super::transient::{Transient, TransientSummary};
use super::{Analysis, Settings};
use crate::error::Result;
use crate::model::{shape_error, Model};
use crate::record::{Recorder, Stage, StageLayout};
use crate::structure::{State, Structure};
use nalgebra::Vector3;

/// One planned stage.
#[derive(Clone, Debug)]
pub struct PlannedStage {
    /// Index of the state it starts from: 0 the shape (form-finding's or the given
    /// model's equilibrium, unloaded), k the end of stage k − 1 of the list.
    pub from: usize,
    /// The stage and what it takes from earlier ones.
    pub analysis: Planned,
}

/// A stage of one kind, with what it takes from earlier ones.
#[derive(Clone, Debug)]
pub enum Planned {
    /// Static loads in load steps.
    Static(StaticLoad),
    /// Eigen analysis and the Rayleigh damping it gives.
    Eigen(Eigen),
    /// Newmark time stepping.
    Transient {
        /// The stage.
        stage: Transient,
        /// The list index of the eigen stage whose Rayleigh α, β damp this one.
        rayleigh_from: Option<usize>,
        /// The state index whose shape this stage's is compared with.
        compare_to: Option<usize>,
    },
    /// Prescribed displacements in static steps.
    Folding(Folding),
}

impl PlannedStage {
    /// The stage's kind and name.
    pub fn stage(&self) -> &Stage {
        match &self.analysis {
            Planned::Static(s) => &s.stage,
            Planned::Eigen(e) => &e.stage,
            Planned::Transient { stage, .. } => &stage.stage,
            Planned::Folding(f) => &f.stage,
        }
    }
}

/// The figures of one stage, by its kind.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StageSummary {
    /// A static-load stage's.
    Static(StaticSummary),
    /// An eigen stage's.
    Eigen(EigenSummary),
    /// A transient's.
    Transient(TransientStageSummary),
    /// A folding stage's.
    Folding(FoldSummary),
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

/// A state the stages have reached, with the loads that hold it.
#[derive(Clone, Debug)]
pub struct Reached {
    /// The converged state.
    pub state: State,
    /// The dead loads on from the static stages before it [N per node]; empty for none.
    pub dead_load: Vec<Vector3<f64>>,
}

impl PlannedStage {
    /// What the outputs are told of this stage's series before any stage runs.
    pub fn layout(&self, model: &Model) -> StageLayout {
        let plain = StageLayout::plain(model, self.stage().clone());
        match &self.analysis {
            Planned::Folding(f) => StageLayout {
                constraints: f.constraints(model),
                path_modes: f.modes,
                ..plain
            },
            Planned::Transient { stage, .. } => StageLayout {
                actuated: !stage.actuators.is_empty(),
                ..plain
            },
            _ => plain,
        }
    }

    /// Runs the stage from its start among `reached` (the states so far, 0 the shape) on
    /// `structure`, whose dead load the caller has set to that start's; `earlier`: the
    /// figures of the stages before, by plan index (an eigen stage's damping). The state
    /// it ends in, with the loads that hold it, and its figures.
    pub fn run(
        &self,
        structure: &Structure,
        reached: &[Reached],
        earlier: &[StageSummary],
        settings: &Settings,
        recorder: &mut dyn Recorder,
    ) -> Result<(Reached, StageSummary)> {
        let start = &reached[self.from];
        let state = start.state.clone();
        let mut dead_load = start.dead_load.clone();
        let (end, figures) = match &self.analysis {
            Planned::Static(stage) => {
                let (end, statics) = stage.run(structure, state, settings, recorder)?;
                dead_load = stage.dead_load(&dead_load, statics.load_factor);
                (end, StageSummary::Static(statics))
            }
            Planned::Eigen(stage) => {
                let (end, eigen) = stage.run(structure, state, settings, recorder)?;
                (end, StageSummary::Eigen(eigen))
            }
            Planned::Transient {
                stage,
                rayleigh_from,
                compare_to,
            } => {
                let rayleigh = rayleigh_from.and_then(|k| match &earlier[k] {
                    StageSummary::Eigen(e) => Some(e.rayleigh()),
                    _ => None,
                });
                let stage = Transient {
                    rayleigh: rayleigh.unwrap_or_default(),
                    ..stage.clone()
                };
                // The shape error at every step, for the time it comes within 1 % of the compared shape.
                let compared = compare_to.map(|k| &reached[k].state);
                let (end, transient) = stage.run_towards(structure, state, settings, recorder, compared.map(|s| &s.positions[..]))?;
                let figures = TransientStageSummary::new(transient, &end, compared);
                (end, StageSummary::Transient(figures))
            }
            Planned::Folding(stage) => {
                let (end, fold) = stage.run(structure, state, settings, recorder)?;
                (end, StageSummary::Folding(fold))
            }
        };
        Ok((Reached { state: end, dead_load }, figures))
    }
}
