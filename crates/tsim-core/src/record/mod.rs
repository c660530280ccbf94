//! The recording port: what stages hand to their outputs. Recorders see only converged
//! states: a stage calls them after each converged step, never with a Newton trial
//! (OpenSees' commit-then-record). Each output format is one implementation of
//! [`Recorder`] (in [`crate::output`]); [`Recorders`] fans out to several. Nothing here
//! knows files or threads.

mod clearance;
mod clusters;
mod fanout;
mod observe;

pub use crate::dynamics::Energy;
pub use crate::model::clearance::{Event as ClearanceEvent, EventKind, Nearest};
pub use crate::rigidity::Rigidity;
pub use clearance::{ClearanceLog, ClearanceSummary};
pub use clusters::{ClusterLog, ClusterSummary};
pub use fanout::Recorders;
pub use observe::{Observed, Observer};

use crate::model::{Model, AXES};
use nalgebra::Vector3;

/// What a stage does; several stages of a case may be of one kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StageKind {
    /// Form-finding by the measure potential (paper §2): the self-equilibrium shape.
    FormFinding,
    /// The equilibrium of a model given with rest lengths (no form-finding).
    Equilibrium,
    /// Gravity and static loads applied in load steps.
    Static,
    /// Natural frequencies and modes at an equilibrium, and the Rayleigh damping they give.
    Eigen,
    /// Newmark time stepping (the paper's free vibration and deployment).
    Transient,
    /// Prescribed displacement in static steps.
    Folding,
    /// Rest lengths changed in static steps under the loads held.
    Hold,
}

impl StageKind {
    /// The kind as the config's `stages` entries name it.
    pub fn name(self) -> &'static str {
        match self {
            StageKind::FormFinding => "formfinding",
            StageKind::Equilibrium => "equilibrium",
            StageKind::Static => "static",
            StageKind::Eigen => "eigen",
            StageKind::Transient => "transient",
            StageKind::Folding => "folding",
            StageKind::Hold => "hold",
        }
    }

    /// A stage of static steps (no velocities; `time` is the applied fraction).
    pub fn is_static(self) -> bool {
        matches!(self, StageKind::Folding | StageKind::Static | StageKind::Hold)
    }

    /// What the fraction of a static stage's step is (None: not a static stage).
    pub fn fraction(self) -> Option<&'static str> {
        match self {
            StageKind::Folding => Some("applied fraction of the prescribed displacement"),
            StageKind::Static => {
                Some("load factor: applied fraction of the total load (under displacement control: the factor on the `loads` pattern)")
            }
            StageKind::Hold => Some("applied fraction of the rest-length change (the loads held)"),
            _ => None,
        }
    }

    /// A stage that records a series of steps (a group with a `time` dimension).
    pub fn is_stepped(self) -> bool {
        matches!(
            self,
            StageKind::Static | StageKind::Transient | StageKind::Folding | StageKind::Hold
        )
    }
}

/// One stage of a case as outputs name it: its kind and its name, unique in the case
/// (the HDF5 group, the replay's stage topic, the summary key). The paper's sequence
/// names its stages `formfinding` (or `equilibrium`), `static`, `eigen`,
/// `free_vibration`, `folding`, `deployment`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stage {
    /// What the stage does.
    pub kind: StageKind,
    /// Its name in the case, unique.
    pub name: std::sync::Arc<str>,
}

impl Stage {
    /// A stage of `kind` named `name`.
    pub fn new(kind: StageKind, name: &str) -> Self {
        Stage { kind, name: name.into() }
    }

    /// A stage named after its kind.
    pub fn of(kind: StageKind) -> Self {
        Stage::new(kind, kind.name())
    }

    /// Its name in the case.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether its kind is static ([`StageKind::is_static`]).
    pub fn is_static(&self) -> bool {
        self.kind.is_static()
    }
}

/// A direction a stage holds fixed, where it records a reaction: a support, or a direction
/// the stage prescribes (folding), whose reaction is the force that drives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Constraint {
    /// Node index.
    pub node: usize,
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Prescribed by the stage (not a support of the model).
    pub prescribed: bool,
}

/// The constrained directions of a stage, in DOF order (by node, then axis): the order of
/// [`Frame::reactions`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Constraints(pub Vec<Constraint>);

impl Constraints {
    /// The supports of `model` and the `prescribed` (node, axis) directions (a support
    /// that is also prescribed is listed once, as a support).
    pub fn new(model: &Model, prescribed: &[(usize, usize)]) -> Self {
        // A lookup table, not `contains`: folding a grid prescribes thousands of directions.
        let mut is_prescribed = vec![false; 3 * model.node_count()];
        prescribed.iter().for_each(|&(node, axis)| is_prescribed[3 * node + axis] = true);
        let mut list = Vec::new();
        for (node, n) in model.nodes.iter().enumerate() {
            for axis in 0..3 {
                let prescribed = !n.support[axis] && is_prescribed[3 * node + axis];
                if prescribed || n.support[axis] {
                    list.push(Constraint { node, axis, prescribed });
                }
            }
        }
        Constraints(list)
    }

    /// Number of constrained directions.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether no direction is constrained.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// "`<node id>.<axis>`" of each direction, e.g. `b0.z`.
    pub fn labels(&self, model: &Model) -> Vec<String> {
        self.0
            .iter()
            .map(|c| format!("{}.{}", model.nodes[c.node].id, AXES[c.axis]))
            .collect()
    }
}

/// One converged step of a time-stepping stage.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Step index within the stage (0 = the initial state).
    pub step: usize,
    /// Simulated time within the stage [s]; for folding, the applied fraction of the
    /// prescribed displacement (0..1).
    pub time: f64,
    /// Node positions [m], global frame (relative to the ground under ground motion).
    pub positions: &'a [Vector3<f64>],
    /// Node velocities [m/s]; `None` for static stages.
    pub velocities: Option<&'a [Vector3<f64>]>,
    /// Member axial forces [N], tension positive: in a transient stage the elastic force N
    /// plus the viscous one (the member's damping force along it), which the member carries.
    pub forces: &'a [f64],
    /// The viscous part of `forces` [N] in a transient stage (its elastic part is
    /// `forces − viscous_forces`); `None` in static stages, where there is none.
    pub viscous_forces: Option<&'a [f64]>,
    /// Member lengths [m].
    pub lengths: &'a [f64],
    /// The members' rest lengths at this step [m], in a stage that changes them in time
    /// (declared in [`StageLayout::actuated`]); `None` elsewhere.
    pub rest_lengths: Option<&'a [f64]>,
    /// The energy ledger at this step [J].
    pub energy: Energy,
    /// External load applied on every node [N]: dead loads, weight, time-varying loads
    /// (and, under ground motion, −m a_g on the free directions).
    pub applied: &'a [Vector3<f64>],
    /// Reaction at each constrained direction of the stage, in the order of the
    /// [`Constraints`] given to [`Recorder::begin_stage`] [N]: the force the support (or the
    /// prescribing device) exerts on the node.
    pub reactions: &'a [f64],
    /// |Σ reactions + Σ applied − Σ m a − Σ α m v| over the structure (a 3-vector's norm):
    /// the out-of-balance of the whole structure, zero to the solver's tolerance [N].
    pub equilibrium_error: f64,
    /// The lowest modes at this step (folding with `folding.eigen`): ω² ascending
    /// [rad²/s²] and the mass-normalised lowest mode over every node [m·kg^-1/2].
    pub modes: Option<FrameModes<'a>>,
    /// Strut clearance at this step; `None` when not tracked (`outputs.clearance: false`).
    pub clearance: Option<FrameClearance<'a>>,
    /// The contacts within the activation distance at this step (empty without contact).
    pub contacts: &'a [crate::contact::Active],
}

/// Strut clearance at one step (see [`crate::model::clearance`]).
#[derive(Clone, Copy, Debug)]
pub struct FrameClearance<'a> {
    /// The closest pair of non-adjacent struts; `None` without two such struts.
    pub nearest: Option<Nearest>,
    /// The touches and pass-throughs since the previous recorded step (those between
    /// unrecorded steps included), in the order seen.
    pub events: &'a [ClearanceEvent],
}

/// The lowest modes at one step of a stage.
#[derive(Clone, Copy, Debug)]
pub struct FrameModes<'a> {
    /// ω² of the lowest modes, ascending [rad²/s²] (negative: unstable).
    pub omega2: &'a [f64],
    /// The lowest mode's shape per node, mass-normalised [m·kg^-1/2] (zero at fixed directions).
    pub lowest: &'a [Vector3<f64>],
}

/// Static description of the model written once per case.
#[derive(Clone, Copy, Debug)]
pub struct ModelRecord<'a> {
    /// Topology, initial geometry and supports.
    pub model: &'a Model,
    /// Real-material rest lengths [m].
    pub rest_lengths: &'a [f64],
    /// Lumped nodal masses [kg].
    pub masses: &'a [f64],
    /// The config's `masses` reading they follow: `physical`, or `paper` (1000× lighter).
    pub mass_reading: &'a str,
    /// Every stage the case runs after form-finding, in order, with what its outputs
    /// need to know before streaming starts (file layouts are fixed then).
    pub stages: &'a [StageLayout],
}

/// What a stage's outputs need before any stage runs.
#[derive(Clone, Debug, PartialEq)]
pub struct StageLayout {
    /// The stage's kind and name.
    pub stage: Stage,
    /// The directions the stage holds fixed: the supports, and for folding the
    /// prescribed directions.
    pub constraints: Constraints,
    /// The stage changes rest lengths in time (actuators, or the slip of clustered cables):
    /// its frames carry [`Frame::rest_lengths`], and its outputs record them and the
    /// actuators' work.
    pub actuated: bool,
    /// How many of the lowest modes the stage records at every step (0: none).
    pub path_modes: usize,
    /// Declared for the file layout only (the paper's sequence keeps a group for each of
    /// its stepped stages, run or not); it never begins.
    pub placeholder: bool,
}

impl StageLayout {
    /// A stage that holds the supports only, has no actuators and records no modes.
    pub fn plain(model: &Model, stage: Stage) -> Self {
        StageLayout {
            stage,
            constraints: Constraints::new(model, &[]),
            actuated: !model.clusters.is_empty(),
            path_modes: 0,
            placeholder: false,
        }
    }
}

/// Results of form-finding, or of the equilibrium of a model given with rest lengths.
#[derive(Clone, Copy, Debug)]
pub struct FormFindRecord<'a> {
    /// `formfinding` or `equilibrium`: the group it is written to.
    pub stage: &'a Stage,
    /// max|r| at each Newton iteration, the first at the start [N].
    pub residuals: &'a [f64],
    /// Equilibrium node positions [m].
    pub positions: &'a [Vector3<f64>],
    /// Member axial forces N at equilibrium [N], tension positive.
    pub forces: &'a [f64],
    /// Strut clearance of the equilibrium shape; `None` when not tracked.
    pub clearance: Option<FrameClearance<'a>>,
}

/// Results of the eigen analysis.
#[derive(Clone, Copy, Debug)]
pub struct EigenRecord<'a> {
    /// The eigen stage: its group.
    pub stage: &'a Stage,
    /// ω² ascending [rad²/s²].
    pub omega2: &'a [f64],
    /// Mass-normalised mode shapes, `mode_shapes[mode][node]` [m·kg^-1/2].
    pub mode_shapes: &'a [Vec<Vector3<f64>>],
    /// Rayleigh α [1/s].
    pub rayleigh_alpha: f64,
    /// Rayleigh β [s].
    pub rayleigh_beta: f64,
    /// 1-based mode numbers the damping came from (empty when α, β were given).
    pub damping_modes: &'a [usize],
    /// Damping ratio ζ asked for at each of `damping_modes`.
    pub damping_ratio: &'a [f64],
}

/// The equilibrium-matrix analysis ([`crate::rigidity`]) of the equilibrium form-finding
/// (or the given model's equilibrium) found, with the substituted structure's prestress;
/// or why it was skipped (a model above the dense limit).
#[derive(Clone, Copy, Debug)]
pub struct RigidityRecord<'a> {
    /// The analysis, or why it was skipped.
    pub analysis: Result<&'a Rigidity, &'a str>,
}

/// Why a recorder failed (I/O, encoding, a lost writer thread), kept whole as the source
/// of the stage error it becomes.
pub type RecordError = Box<dyn std::error::Error + Send + Sync>;
/// What every [`Recorder`] call returns.
pub type RecordResult = Result<(), RecordError>;

/// How a case ended, as the outputs' `status` records it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Every stage converged and every record was written.
    Complete,
    /// The reason: a stage error, a panic, or a recording failure.
    Failed(String),
    /// Stopped by a signal (SIGINT, SIGTERM) before the end.
    Interrupted,
}

impl Outcome {
    /// What a file records when its own writing failed with `recording` (Ok: it did not):
    /// a complete case's file is missing data, so it reads failed; any other outcome stands.
    pub fn unless_recording_failed<E: std::fmt::Display>(&self, recording: &Result<(), E>) -> Outcome {
        match (recording, self) {
            (Err(e), Outcome::Complete) => Outcome::Failed(format!("recording failed: {e}")),
            _ => self.clone(),
        }
    }
}

impl std::fmt::Display for Outcome {
    /// "complete", "failed: <reason>" or "interrupted": the `status` strings of
    /// result.h5, replay.mcap and outcome.json.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Outcome::Complete => f.write_str("complete"),
            Outcome::Failed(reason) => write!(f, "failed: {reason}"),
            Outcome::Interrupted => f.write_str("interrupted"),
        }
    }
}

/// A sink for results. Stages call, in order: `model`, `formfinding`, `rigidity`, `eigen`, then for
/// each time-stepping stage `begin_stage`, `frame`…, `end_stage`; `finish` last.
pub trait Recorder {
    /// The model, its materials and the stages to come, once per case, first.
    fn model(&mut self, _record: &ModelRecord) -> RecordResult {
        Ok(())
    }
    /// Form-finding's (or the given model's) equilibrium.
    fn formfinding(&mut self, _record: &FormFindRecord) -> RecordResult {
        Ok(())
    }
    /// The equilibrium-matrix analysis of that equilibrium.
    fn rigidity(&mut self, _record: &RigidityRecord) -> RecordResult {
        Ok(())
    }
    /// The eigen analysis.
    fn eigen(&mut self, _record: &EigenRecord) -> RecordResult {
        Ok(())
    }
    /// A time-stepping stage begins; its frames' reactions are at `constraints`.
    fn begin_stage(&mut self, _stage: &Stage, _constraints: &Constraints) -> RecordResult {
        Ok(())
    }
    /// One converged step of the stage begun last.
    fn frame(&mut self, _frame: &Frame) -> RecordResult {
        Ok(())
    }
    /// The stage begun last has taken all its steps.
    fn end_stage(&mut self, _stage: &Stage) -> RecordResult {
        Ok(())
    }
    /// The case's outcome; a recorder writes it as its `status`.
    fn finish(&mut self, _outcome: &Outcome) -> RecordResult {
        Ok(())
    }
}

/// Records nothing: a pipeline run without outputs.
pub struct NoRecorder;
impl Recorder for NoRecorder {}
