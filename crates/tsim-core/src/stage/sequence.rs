//! A case's stages as data: the list the pipeline runs after form-finding and
//! substitution, each stage with the state it starts from and what it takes from earlier
//! stages, by index, never through the structure. The config's `stages` list and the
//! paper's sections (its shorthand) both plan into this.

use super::eigen::Eigen;
use super::fold::Folding;
use super::static_load::StaticLoad;
use super::transient::Transient;
use crate::record::Stage;

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
