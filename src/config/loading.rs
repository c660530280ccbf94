//! The config's loads, masses and material assignments: what a structural engineer needs to
//! write an ordinary pin-jointed model (gravity, nodal loads with time functions, ground
//! acceleration, initial conditions, point masses, materials per member group).
//! Every key that targets nodes takes `nodes` (node ids) and/or `groups` (node groups); the
//! union is used, each node once.

use super::materials::MaterialSpec;
use super::schema::Axis;
use std::sync::Arc;

/// A force on each node of a set, scaled in time by `time` (static loads ignore `time`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NodalForceSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nodes: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    /// Force on each node [N].
    pub force: [f64; 3],
    /// Time function the force is multiplied by; `constant` by default.
    #[serde(default)]
    pub time: TimeFunctionSpec,
}

/// Members whose rest length changes over a transient (a winch, a motor, a cable reeled
/// in): l0(t) = l0(0) · (1 + (scale − 1) f(t)), l0(0) the rest length the stage starts
/// with, f the time function (e.g. `ramp` to reach `scale` and hold it). The members
/// are `members` (ids) and those of `groups` (member groups), each in one actuation only.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ActuationSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
    /// Member groups (`model.members[].groups`; a tower's `vertical`, `side0`, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    /// Rest length where f = 1 over the rest length at the stage's start (0.8: 20 %
    /// shorter); must be positive.
    pub scale: f64,
    /// The time function f; e.g. `{ramp: {duration: 2.0}}`.
    pub time: TimeFunctionSpec,
}

/// A factor f(t) of time within a stage.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TimeFunctionSpec {
    /// 1 at every t.
    #[default]
    Constant,
    /// 1 for 0 ≤ t < duration, then 0.
    Step { duration: f64 },
    /// t/duration up to `duration`, then 1.
    Ramp { duration: f64 },
    /// sin(π t/duration) for 0 ≤ t ≤ duration, then 0: a smooth pulse.
    HalfSine { duration: f64 },
    /// sin(2π f t + φ) [f in Hz, φ in rad], for 0 ≤ t < duration (always when absent).
    Harmonic {
        frequency: f64,
        #[serde(default)]
        phase: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        duration: Option<f64>,
    },
    /// Piecewise linear through (t, f) points, times strictly increasing; before the
    /// first point the first value, after the last the last value. `file`: a CSV of two
    /// columns (t, f; a header line is allowed), relative to the config file; its rows
    /// are read into `points` when the config is loaded, so the case's resolved config
    /// holds the values it ran with.
    Table {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        file: Option<String>,
        // Shared: every case of a sweep holds the one copy read (`CaseConfig::share_tables`).
        #[serde(default, skip_serializing_if = "no_points")]
        points: TablePoints,
        /// For points read from a file: the name of the run's copy (`tables/`), which
        /// `case.yaml` names instead of holding the rows (`CaseConfig::recorded`).
        #[serde(skip)]
        kept_as: Option<Arc<str>>,
    },
}

/// A table's (t, f) points, shared by the cases of a sweep that hold them.
pub type TablePoints = Arc<[[f64; 2]]>;

impl TimeFunctionSpec {
    /// A table of `points` given inline.
    pub fn table(points: impl Into<TablePoints>) -> Self {
        TimeFunctionSpec::Table {
            file: None,
            points: points.into(),
            kept_as: None,
        }
    }
}

fn no_points(points: &TablePoints) -> bool {
    points.is_empty()
}

/// Uniform base (ground) acceleration a_g(t) = `acceleration` · f(t) [m/s²] of every
/// support. The motion is solved relative to the moving base: each free DOF gets the
/// inertia load −m a_g; positions and velocities are relative, reactions absolute.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GroundMotionSpec {
    /// Peak or scale vector [m/s²].
    pub acceleration: [f64; 3],
    pub time: TimeFunctionSpec,
}

/// Where a transient starts, and what is added to that state.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// The state taken: `equilibrium` (free vibration's default), `folded` (deployment's
    /// default: the end of folding, or the equilibrium without it), `previous` (the end
    /// of the stage run just before).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<StartFrom>,
    /// Displacements added to the positions [m].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub displacement: Vec<NodalVectorSpec>,
    /// Velocities set on the nodes [m/s] (others keep the state's).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub velocity: Vec<NodalVectorSpec>,
    /// `consistent` (default): the acceleration that satisfies the equation of motion at
    /// t = 0; `zero`: start with a = 0 (as some codes do; out of balance when loaded).
    #[serde(default)]
    pub acceleration: InitialAcceleration,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum StartFrom {
    Equilibrium,
    Folded,
    Previous,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum InitialAcceleration {
    #[default]
    Consistent,
    Zero,
}

/// A vector on each node of a set.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NodalVectorSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nodes: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    pub value: [f64; 3],
}

/// A point mass on each node of a set [kg], added to the members' lumped masses.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PointMassSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nodes: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    pub mass: f64,
}

/// A material for some members, by member id and/or member group; later entries
/// override earlier ones, and all override `substitution.strut`/`.cable`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AssignSpec {
    /// Member ids.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
    /// Member groups (`model.members[].groups`; a tower's `ring_base`, `side0`, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    /// A material name (library or `materials`)...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
    /// ... or a material defined here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub define: Option<MaterialSpec>,
    /// Cross-section [m²] replacing the material's (its law's EA or A0 follows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area: Option<f64>,
    /// The members carry no mass (their stiffness stays).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub massless: bool,
}

/// A static-load stage after substitution: nodal loads and gravity applied in load steps
/// (or, with `control`, followed by the displacement of one node direction past limit
/// points). The loads stay on in every later stage.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StaticSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<NodalForceSpec>,
    /// Load (or displacement) steps.
    #[serde(default = "ten")]
    pub steps: usize,
    /// Halvings of a step whose Newton solve fails.
    #[serde(default = "six")]
    pub max_cuts: u32,
    /// Displacement control of the `loads` pattern: its factor λ follows from this node
    /// direction moving by `displacement` in `steps` equal steps (gravity, if any, is
    /// applied first by load control).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control: Option<ControlSpec>,
}

impl Default for StaticSpec {
    fn default() -> Self {
        StaticSpec {
            loads: Vec::new(),
            steps: ten(),
            max_cuts: six(),
            control: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ControlSpec {
    pub node: String,
    pub axis: Axis,
    /// Total displacement [m].
    pub displacement: f64,
}

pub(in crate::config) fn ten() -> usize {
    10
}
pub(in crate::config) fn six() -> u32 {
    6
}
