//! The pipeline's stages, each a small driver on top of [`crate::tsm`] (forces and
//! tangents), [`crate::dynamics`] (time stepping) and [`crate::solve`] (the Newton
//! driver). Every stage has the shape of [`Analysis::run`]: it takes the [`Structure`] and
//! a converged [`State`], pushes its converged steps to the recorder and returns the
//! converged state it ends in with its summary.

pub mod eigen;
pub mod fold;
pub mod formfind;
mod frames;
pub mod hold;
pub mod measure;
pub mod sequence;
pub mod static_load;
mod statics;
pub mod substitute;
pub mod transient;

pub use statics::StaticEquilibrium;

use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{RecordError, Recorder};
use crate::solve::{NewtonSettings, SolveError, SparseSolver};
use crate::structure::{State, Structure};
use crate::tsm::{tangent_sparsity, DofMap};

/// Settings every stage of a case shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Newton settings of every solve (tolerances, linear solver, tangent reuse).
    pub newton: NewtonSettings,
    /// Record every `every`-th step of a time-stepping stage (and its last).
    pub every: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            newton: NewtonSettings::default(),
            every: 1,
        }
    }
}

/// Nonzeros of the sparse Cholesky factor a stage's Newton solver holds on `model` (free
/// of supports only), from its symbolic analysis alone: for a memory estimate.
pub fn planned_factor_nonzeros(model: &Model) -> usize {
    let dofs = DofMap::new(model, &[]);
    SparseSolver::planned_factor_nonzeros(dofs.len(), tangent_sparsity(model, &dofs))
}

/// The equilibrium check of a recording stage, in its summary: the largest out-of-balance
/// of the whole structure over the recorded steps, Σ reactions + Σ applied loads − Σ m a −
/// Σ α m v (a 3-vector's norm), in newtons and relative to the largest of |Σ applied|,
/// |Σ reactions| and the largest |member force| of the same step. Static steps (folding):
/// the sum of the Newton residual, ≤ 1e-10 relative.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EquilibriumSummary {
    /// [N]
    #[serde(default)]
    pub max_equilibrium_error: f64,
    /// The same, relative to the step's force scale.
    #[serde(default)]
    pub max_equilibrium_error_relative: f64,
}

impl From<frames::EquilibriumCheck> for EquilibriumSummary {
    fn from(c: frames::EquilibriumCheck) -> Self {
        EquilibriumSummary {
            max_equilibrium_error: c.max_error,
            max_equilibrium_error_relative: c.max_relative,
        }
    }
}

/// One stage of the paper's Figure 1.
pub trait Analysis {
    /// The stage's key figures, for the case summary.
    type Summary;
    /// Runs from the converged `state` of `structure`; returns the converged state the
    /// stage ends in and its key figures.
    fn run(&self, structure: &Structure, state: State, settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, Self::Summary)>;
}

/// A Newton failure as a stage error, the DOF it is about named by node and direction.
fn solve_error<'a>(
    stage: &'a str,
    step: Option<usize>,
    time: Option<f64>,
    structure: &'a Structure,
    dofs: &'a DofMap,
) -> impl FnOnce(SolveError) -> Error + 'a {
    move |source| Error::Solve {
        stage: stage.into(),
        step,
        time,
        at: source.dof().map(|d| dofs.label(&structure.model, d).into()),
        source,
    }
}

/// A static stage's failure (static, folding, hold) with the rigid-body motion the supports
/// and `prescribed` directions leave free, where they leave one
/// ([`Model::require_supports`](crate::model::Model::require_supports)). Such a stage is
/// not refused up front: a loaded structure free to move has an equilibrium where the load
/// holds it (a pendulum hangs under gravity, stiffened by its tension), none where the
/// load pushes it along the free motion; only the solve can tell.
fn name_free_motion<'a>(model: &'a Model, prescribed: &'a [[bool; 3]]) -> impl FnOnce(Error) -> Error + 'a {
    move |error| match model.require_supports(prescribed) {
        Ok(()) => error,
        Err(free) => Error::Explained {
            source: Box::new(error),
            note: free.to_string(),
        },
    }
}

/// Refuses to start `stage` from a state where bodies in contact overlap: the barrier is
/// infinite there, and no admissible step leads out.
fn require_apart(asm: &crate::tsm::Assembly, stage: &str) -> Result<()> {
    match asm.contact.as_ref().and_then(|c| c.overlap_text(asm.model)) {
        Some(reason) => Err(Error::Stage {
            stage: stage.into(),
            reason,
        }),
        None => Ok(()),
    }
}

/// Refuses `actuators` that change part of a clustered cable of `model` in `stage`
/// ([`crate::model::Model::check_cluster_actuation`]).
fn whole_cables(model: &Model, actuators: &[crate::dynamics::Actuator], stage: &str) -> Result<()> {
    model
        .check_cluster_actuation(actuators.iter().map(|a| a.members.as_slice()))
        .map_err(|reason| Error::Stage {
            stage: stage.into(),
            reason,
        })
}

/// A recorder failure as a stage error, keeping its source.
fn record_error(stage: &str) -> impl Fn(RecordError) -> Error + '_ {
    move |source| Error::Record {
        stage: stage.into(),
        source,
    }
}
