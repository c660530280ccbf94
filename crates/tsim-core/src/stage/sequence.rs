//! A case's stages as data: the list the pipeline runs after form-finding and
//! substitution, each stage with the state it starts from and what it takes from earlier
//! stages, by index, never through the structure. The config's `stages` list and the
//! paper's sections (its shorthand) both plan into this.

use super::eigen::EigenSummary;
use super::fold::FoldSummary;
use super::hold::HoldSummary;
use super::static_load::StaticSummary;
pub use super::transient::{PlannedTransient, TransientStageSummary};
use super::Settings;
use crate::error::Result;
use crate::model::Model;
use crate::record::{Recorder, Stage, StageLayout};
use crate::structure::{State, Structure};
use nalgebra::Vector3;

/// One planned stage.
#[derive(Debug)]
pub struct PlannedStage {
    /// Index of the state it starts from: 0 the shape (form-finding's or the given
    /// model's equilibrium, unloaded), k the end of stage k − 1 of the list.
    pub from: usize,
    /// The stage and what it takes from earlier ones.
    pub analysis: Box<dyn SequenceStage>,
}

/// A stage as the sequence runs it: every kind implements this in its own file, so that
/// nothing here dispatches on kinds. The kinds are registered in [`StageSummary`] (and
/// [`crate::record::StageKind`], which names them).
pub trait SequenceStage: std::fmt::Debug + Send + Sync {
    /// The stage's kind and name.
    fn stage(&self) -> &Stage;

    /// What the outputs are told of this stage's series before any stage runs.
    fn layout(&self, model: &Model) -> StageLayout {
        StageLayout::plain(model, self.stage().clone())
    }

    /// Runs the stage from `start` (with the loads that hold it; the structure's dead load
    /// is set to them); `run`: the structure and what the stages before reached. The state
    /// it ends in, with the loads that hold it, and its figures.
    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)>;
}

/// What a stage of the sequence runs on: the structure, the settings and what the stages
/// before it reached.
#[derive(Clone, Copy)]
pub struct Run<'a> {
    /// The structure, its dead load that of the stage's start.
    pub structure: &'a Structure,
    /// The states reached so far (0: the shape).
    pub reached: &'a [Reached],
    /// The figures of the stages before, by plan index (an eigen stage's damping).
    pub earlier: &'a [StageSummary],
    /// Settings every stage of the case shares.
    pub settings: &'a Settings,
}

/// The figures of one stage, by its kind.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StageSummary {
    /// A static-load stage's.
    Static(StaticSummary),
    /// An eigen stage's.
    Eigen(EigenSummary),
    /// A transient's (boxed: the largest by far).
    Transient(Box<TransientStageSummary>),
    /// A folding stage's.
    Folding(FoldSummary),
    /// A hold stage's.
    Hold(HoldSummary),
}

/// A state the stages have reached, with the loads that hold it.
#[derive(Clone, Debug)]
pub struct Reached {
    /// The converged state.
    pub state: State,
    /// The dead loads on from the static stages before it [N per node]; empty for none.
    pub dead_load: Vec<Vector3<f64>>,
}

impl Reached {
    /// `state`, reached from this one under the same loads.
    pub fn under_same_loads(&self, state: State) -> Reached {
        Reached {
            state,
            dead_load: self.dead_load.clone(),
        }
    }
}

impl PlannedStage {
    /// The stage's kind and name.
    pub fn stage(&self) -> &Stage {
        self.analysis.stage()
    }

    /// What the outputs are told of this stage's series before any stage runs.
    pub fn layout(&self, model: &Model) -> StageLayout {
        self.analysis.layout(model)
    }

    /// Runs the stage from its start among `run.reached`.
    pub fn run(&self, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        self.analysis.run_from(&run.reached[self.from], run, recorder)
    }
}
