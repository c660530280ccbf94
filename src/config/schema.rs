use super::kinds::HoldSpec;
use super::limits::LimitSpec;
use super::loading::{six, ten, ActuationSpec, AssignSpec, GroundMotionSpec, InitialSpec, NodalForceSpec, PointMassSpec, StaticSpec};
use super::materials::MaterialSpec;
use crate::dynamics::{AutoStep, DampingTangent, LoadProfile, NewmarkParams, Scheme};
use crate::model::generate::TowerSpec;
use crate::model::grid::GridSpec;
use crate::model::MemberKind;
use crate::solve::NewtonSettings;
use crate::stage::eigen::{EigenSolverChoice, ModeSolver, DEFAULT_PARTIAL_MODES};
use crate::stage::measure::MeasureSpec;
use std::collections::BTreeMap;

/// One case: a model and the pipeline to run on it. A stage section left out is skipped.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CaseConfig {
    /// Case name (the sweep's name when the file has a `sweep`).
    pub name: String,
    pub model: ModelSpec,
    /// Materials added to (or overriding) the built-in library, by name.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialSpec>,
    /// Form-finding with measure potentials. Absent: the model's coordinates are taken
    /// as the shape and every member must give `rest_length` (no substitution).
    #[serde(default)]
    pub formfinding: Option<FormFindingSpec>,
    pub substitution: SubstitutionSpec,
    #[serde(default)]
    pub masses: MassReading,
    /// Point masses added to the members' lumped masses.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub point_masses: Vec<PointMassSpec>,
    /// Acceleration of gravity g [m/s²], acting on the lumped masses in every stage after
    /// substitution (form-finding finds a self-equilibrium, without gravity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 3]>,
    /// Struts that cannot pass through each other or the ground, in every stage after
    /// substitution. Absent: none (the paper's idealization).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<super::ContactSpec>,
    /// Static loads (and gravity) applied after substitution in load steps; with gravity
    /// and no `static` section, gravity alone is applied with its defaults.
    #[serde(rename = "static", default, skip_serializing_if = "Option::is_none")]
    pub statics: Option<StaticSpec>,
    #[serde(default)]
    pub eigen: Option<EigenSpec>,
    #[serde(default)]
    pub free_vibration: Option<TransientSpec>,
    #[serde(default)]
    pub folding: Option<FoldSpec>,
    #[serde(default)]
    pub deployment: Option<TransientSpec>,
    /// The stages after form-finding (or the given model's equilibrium) and substitution,
    /// in the order given, any kind repeated: in place of the paper's sections `static`,
    /// `eigen`, `free_vibration`, `folding`, `deployment` (which run in the paper's order
    /// and are shorthand for such a list). Never written when empty.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stages: Vec<StageEntry>,
    /// Newton settings shared by every stage.
    #[serde(default)]
    pub newton: NewtonSettings,
    #[serde(default)]
    pub outputs: OutputSpec,
    /// Sweep axes (see `config::sweep`); only in a top-level file.
    #[serde(default)]
    pub sweep: Option<SweepSpec>,
    /// Work limits raised or lowered (see `config::limits`); only in a top-level file,
    /// never written when unset.
    #[serde(default, skip_serializing_if = "LimitSpec::is_unset")]
    pub limits: LimitSpec,
    /// Directories besides the config file's own that time tables (`table.file`) may be
    /// read from: relative to the config's directory, or absolute.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub table_dirs: Vec<String>,
}

/// One stage of `stages`: its name, the stage whose end state it starts from, and one kind
/// key (`static`, `eigen`, `transient`, `folding`) holding the settings of that kind, the
/// same as the paper's section of the kind.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StageEntry {
    /// Unique in the case (letters, digits, `_`, `-`): the stage's HDF5 group, replay
    /// stage and summary key.
    pub name: String,
    /// The stage whose end state this one starts from, with the loads that hold it: an
    /// earlier entry, or `formfinding` (`equilibrium` without form-finding) for the
    /// unloaded shape. Default: the entry before (the shape for the first).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<String>,
    /// Gravity and static loads in load steps, from the loads the start carries.
    #[serde(rename = "static", default, skip_serializing_if = "Option::is_none")]
    pub statics: Option<StaticSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eigen: Option<EigenSpec>,
    /// Newmark time stepping; `rayleigh_from` names the eigen stage whose damping it uses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transient: Option<TransientSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub folding: Option<FoldSpec>,
    /// Rest lengths changed in static steps, the loads of the start held.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hold: Option<HoldSpec>,
}

/// A generated tower, a generated grid, or explicit nodes and members.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    #[serde(default)]
    pub tower: Option<TowerSpec>,
    /// Never written when unset, so that `case.yaml` of a tower or explicit model reads
    /// as before (it is compared on resume).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridSpec>,
    #[serde(default)]
    pub nodes: Vec<NodeSpec>,
    #[serde(default)]
    pub members: Vec<MemberSpec>,
    /// Node groups by name, node ids.
    #[serde(default)]
    pub groups: BTreeMap<String, Vec<String>>,
    /// Clustered cables: each one cable run through a chain of cable members, sliding
    /// without friction over the nodes between them (one tension along it). Never written
    /// when empty, so that earlier `case.yaml` files read as before.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clusters: Vec<ClusterSpec>,
}

/// One clustered cable.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ClusterSpec {
    /// Unique id, as in outputs.
    pub id: String,
    /// Member ids in the order the cable runs through them: each shares a node (a pulley)
    /// with the next; the first and last may share one (a closed loop). Cables only, of one
    /// material.
    pub members: Vec<String>,
    /// Capstan friction coefficient μ over every pulley (default 0: the cable slides
    /// freely). A pulley holds the cable while its tensions on either side stay within
    /// e^{±μθ} of each other (θ the angle the cable turns there) and lets it slip at that
    /// ratio. Open cables only; transients with friction run `scheme: newmark` and take no
    /// β damping.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    pub fn index(self) -> usize {
        self as usize
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NodeSpec {
    pub id: String,
    /// Coordinates [m].
    pub xyz: [f64; 3],
    /// Supported directions.
    #[serde(default)]
    pub fix: Vec<Axis>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MemberSpec {
    pub id: String,
    pub nodes: [String; 2],
    pub kind: MemberKind,
    #[serde(default)]
    pub groups: Vec<String>,
    /// Real-material rest length [m], needed only without form-finding.
    #[serde(default)]
    pub rest_length: Option<f64>,
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FormFindingSpec {
    #[serde(default)]
    pub measure: MeasureSpec,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SubstitutionSpec {
    /// Strut material name (library or `materials`).
    pub strut: String,
    /// Cable material name.
    pub cable: String,
    /// Factor on the form-found self-stress (the self-stress is defined up to a factor).
    #[serde(default = "one")]
    pub prestress_scale: f64,
    /// Run on when the real structure is not stable (K_T not positive definite at its
    /// equilibrium); by default the case fails there, naming the softest direction.
    /// Left out of the resolved config when false, so that earlier case.yaml files match.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_unstable: bool,
    /// Materials per member group or member, overriding `strut` and `cable`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub assign: Vec<AssignSpec>,
}

fn one() -> f64 {
    1.0
}

/// Which reading of the paper's "specific gravity" gives the masses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MassReading {
    /// Physical densities (aluminium 2700 kg/m³, rubber 1000 kg/m³).
    #[default]
    Physical,
    /// The paper's effective masses, 1000× smaller (specific gravity used as kg/m³ with
    /// forces in N): the only reading that reproduces Table 2's magnitudes.
    Paper,
}

impl MassReading {
    pub fn factor(self) -> f64 {
        match self {
            MassReading::Physical => 1.0,
            MassReading::Paper => 1e-3,
        }
    }

    /// The config spelling, recorded beside the masses in the outputs.
    pub fn as_str(self) -> &'static str {
        match self {
            MassReading::Physical => "physical",
            MassReading::Paper => "paper",
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EigenSpec {
    /// Rayleigh damping for the damped transients; absent: eigen analysis only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rayleigh: Option<RayleighSpec>,
    /// `auto` (dense up to 1500 free DOF, partial above), `dense` (every mode) or
    /// `partial` (the lowest `modes`, or those nearest `shift`). Written to case.yaml
    /// only when not `auto`, so configs from before the key resume unchanged.
    #[serde(default, skip_serializing_if = "is_auto")]
    pub solver: EigenSolverChoice,
    /// Modes the partial solver computes (default 20).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modes: Option<usize>,
    /// The partial solver's modes are those nearest this ω² [rad²/s²] (default: the lowest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shift: Option<f64>,
}

impl EigenSpec {
    /// The stage's choice of solver and modes.
    pub fn mode_solver(&self) -> ModeSolver {
        ModeSolver {
            choice: self.solver,
            modes: self.modes.unwrap_or(DEFAULT_PARTIAL_MODES),
            shift: self.shift,
        }
    }
}

fn is_auto(choice: &EigenSolverChoice) -> bool {
    *choice == EigenSolverChoice::Auto
}

/// Rayleigh damping: `alpha` and `beta` given, or from two modes (`modes`, 1-based, or
/// `auto_modes`: the two modes with the largest effective modal mass along that axis)
/// and their damping `ratios`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(try_from = "RayleighRaw", into = "RayleighRaw")]
pub enum RayleighSpec {
    Given { alpha: f64, beta: f64 },
    Modes { modes: [usize; 2], ratios: [f64; 2] },
    AutoModes { axis: Axis, ratios: [f64; 2] },
}

/// The YAML form of [`RayleighSpec`]: every key, absent ones written as `null`, so that
/// `case.yaml` (compared on resume) reads as it did before the enum.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
struct RayleighRaw {
    #[serde(default)]
    alpha: Option<f64>,
    #[serde(default)]
    beta: Option<f64>,
    #[serde(default)]
    modes: Option<[usize; 2]>,
    #[serde(default)]
    auto_modes: Option<Axis>,
    #[serde(default)]
    ratios: Option<[f64; 2]>,
}

impl TryFrom<RayleighRaw> for RayleighSpec {
    type Error = String;

    /// The parser reports the line of the section; the message names it, since a sweep
    /// value converted without the parser has no line of its own.
    fn try_from(r: RayleighRaw) -> Result<Self, String> {
        let problem = match r {
            RayleighRaw {
                alpha: Some(alpha),
                beta: Some(beta),
                modes: None,
                auto_modes: None,
                ratios: None,
            } => return Ok(RayleighSpec::Given { alpha, beta }),
            RayleighRaw {
                alpha: None,
                beta: None,
                modes: Some(modes),
                auto_modes: None,
                ratios: Some(ratios),
            } => return Ok(RayleighSpec::Modes { modes, ratios }),
            RayleighRaw {
                alpha: None,
                beta: None,
                modes: None,
                auto_modes: Some(axis),
                ratios: Some(ratios),
            } => return Ok(RayleighSpec::AutoModes { axis, ratios }),
            RayleighRaw {
                modes: Some(_),
                auto_modes: Some(_),
                ..
            } => "`modes` and `auto_modes` both given",
            RayleighRaw {
                alpha: Some(_),
                beta: None,
                ..
            } => "`alpha` without `beta`",
            RayleighRaw {
                alpha: None,
                beta: Some(_),
                ..
            } => "`beta` without `alpha`",
            RayleighRaw { alpha: Some(_), .. } => "`alpha` and `beta` exclude `modes`, `auto_modes` and `ratios`",
            RayleighRaw {
                ratios: None,
                modes: None,
                auto_modes: None,
                ..
            } => "nothing given",
            RayleighRaw { ratios: None, .. } => "`ratios` missing (the damping ratio of each mode)",
            RayleighRaw { .. } => "`ratios` without `modes` or `auto_modes`",
        };
        Err(format!(
            "`eigen.rayleigh`: {problem}; give `alpha` and `beta`, or `modes` (or `auto_modes`) with `ratios`"
        ))
    }
}

impl From<RayleighSpec> for RayleighRaw {
    fn from(r: RayleighSpec) -> Self {
        match r {
            RayleighSpec::Given { alpha, beta } => RayleighRaw {
                alpha: Some(alpha),
                beta: Some(beta),
                ..Default::default()
            },
            RayleighSpec::Modes { modes, ratios } => RayleighRaw {
                modes: Some(modes),
                ratios: Some(ratios),
                ..Default::default()
            },
            RayleighSpec::AutoModes { axis, ratios } => RayleighRaw {
                auto_modes: Some(axis),
                ratios: Some(ratios),
                ..Default::default()
            },
        }
    }
}

/// A load on node groups.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    pub groups: Vec<String>,
    /// Force on each node [N].
    pub force: [f64; 3],
    /// [s]
    pub duration: f64,
    #[serde(default = "step_profile")]
    pub profile: LoadProfile,
}

fn step_profile() -> LoadProfile {
    LoadProfile::Step
}

/// Free vibration or deployment. The Newmark keys default to [`NewmarkParams::default`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TransientSpec {
    /// Δt [s], or `auto`: each step sized by a local error estimate on positions and
    /// member forces (`dt_tolerance`, `dt_max`, `dt_min`).
    #[serde(default = "default_dt")]
    pub dt: TimeStep,
    /// With `dt: auto`: the local error a step may make, in node positions relative to
    /// the structure's size and in member forces relative to the largest so far.
    #[serde(default = "default_dt_tolerance")]
    pub dt_tolerance: f64,
    /// With `dt: auto`: the largest step [s] (default: duration/100).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt_max: Option<f64>,
    /// With `dt: auto`: the smallest step [s] (default: duration · 1e-8); a step this
    /// short is taken whatever its error, and the summary counts it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt_min: Option<f64>,
    /// [s]
    pub duration: f64,
    /// `newmark` (the paper's): the equation of motion at each step's end, with
    /// `newmark_beta` and `newmark_gamma`; `midpoint`: the implicit midpoint rule, the
    /// equation at each step's midpoint, which conserves angular momentum to Newton's
    /// residual but overstates the forces of fast-rotating stiff members (docs/config.md).
    #[serde(default)]
    pub scheme: Scheme,
    #[serde(default = "default_beta")]
    pub newmark_beta: f64,
    #[serde(default = "default_gamma")]
    pub newmark_gamma: f64,
    /// Rayleigh damping on (from `eigen.rayleigh`); free vibration is undamped by default.
    /// In a `stages` entry, `rayleigh_from` names the eigen stage instead.
    #[serde(default)]
    pub damped: bool,
    /// In a `stages` entry: the eigen stage (with `rayleigh`) whose α, β damp this one;
    /// undamped without.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rayleigh_from: Option<String>,
    /// In a `stages` entry: a stage whose end shape this one's is compared with (the
    /// summary's shape error, and the settle time: when the shape comes within 1 %), as
    /// deployment is with the pre-fold equilibrium.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compare_to: Option<String>,
    #[serde(default)]
    pub damping_tangent: DampingTangent,
    /// The paper's launch load (one force on node groups, step or half-sine).
    #[serde(default)]
    pub load: Option<LoadSpec>,
    /// Nodal loads with time functions, any number, besides `load` (and gravity).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<NodalForceSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground_motion: Option<GroundMotionSpec>,
    /// Rest lengths changed in time (winches, motors), any number of entries.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub actuation: Vec<ActuationSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<InitialSpec>,
    /// Halvings of a step whose Newton solve fails.
    #[serde(default = "default_cuts")]
    pub max_cuts: u32,
}

/// A transient's time step: a fixed Δt [s], or `auto`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum TimeStep {
    /// Steps of this size [s].
    Fixed(f64),
    /// Steps sized by the local error estimate.
    Auto(AutoWord),
}

/// A number, or the word `auto`; anything else is told what is expected (serde's untagged
/// enums say only "did not match any variant").
impl<'de> serde::Deserialize<'de> for TimeStep {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = TimeStep;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a time step in seconds (a number, e.g. 0.0005) or `auto`")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<TimeStep, E> {
                Ok(TimeStep::Fixed(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<TimeStep, E> {
                Ok(TimeStep::Fixed(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<TimeStep, E> {
                Ok(TimeStep::Fixed(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<TimeStep, E> {
                match v {
                    "auto" => Ok(TimeStep::Auto(AutoWord::Auto)),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// The word `auto`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AutoWord {
    /// `dt: auto`.
    Auto,
}

impl TransientSpec {
    /// The integrator's parameters.
    pub fn newmark(&self) -> NewmarkParams {
        let defaults = NewmarkParams::default();
        NewmarkParams {
            beta: self.newmark_beta,
            gamma: self.newmark_gamma,
            dt: self.fixed_dt().unwrap_or(defaults.dt),
            max_cuts: self.max_cuts,
            auto: self.fixed_dt().is_none().then(|| self.auto_step()),
            scheme: self.scheme,
        }
    }

    /// Δt where it is fixed.
    pub fn fixed_dt(&self) -> Option<f64> {
        match self.dt {
            TimeStep::Fixed(dt) => Some(dt),
            TimeStep::Auto(_) => None,
        }
    }

    /// `dt: auto`'s settings, with their defaults; the first step tried is the smallest
    /// times 100 (it doubles each step its error allows).
    pub fn auto_step(&self) -> AutoStep {
        let min = self.dt_min.unwrap_or(1e-8 * self.duration);
        AutoStep {
            tolerance: self.dt_tolerance,
            min,
            max: self.dt_max.unwrap_or(0.01 * self.duration),
            initial: 100.0 * min,
        }
    }
}

fn default_dt() -> TimeStep {
    TimeStep::Fixed(NewmarkParams::default().dt)
}
fn default_dt_tolerance() -> f64 {
    1e-4
}
fn default_beta() -> f64 {
    NewmarkParams::default().beta
}
fn default_gamma() -> f64 {
    NewmarkParams::default().gamma
}
fn default_cuts() -> u32 {
    NewmarkParams::default().max_cuts
}

/// Folding by prescribed displacement.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FoldSpec {
    #[serde(default = "ten")]
    pub steps: usize,
    #[serde(default = "six")]
    pub max_cuts: u32,
    pub prescribe: Vec<PrescribeSpec>,
    /// The lowest this many eigenvalues (and the lowest mode) at every folding step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eigen: Option<usize>,
}

/// One group's prescribed direction, moved to `target`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(try_from = "PrescribeRaw", into = "PrescribeRaw")]
pub struct PrescribeSpec {
    pub group: String,
    pub axis: Axis,
    pub target: FoldTarget,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FoldTarget {
    /// Each node to the mean coordinate of the `base` group along `axis`.
    ToBase,
    /// By this much [m].
    Displacement(f64),
}

/// The YAML form of [`PrescribeSpec`] (`to_base: true` or `displacement`), kept with
/// every key so that `case.yaml` reads as it did before the enum.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
struct PrescribeRaw {
    group: String,
    axis: Axis,
    #[serde(default)]
    to_base: bool,
    #[serde(default)]
    displacement: Option<f64>,
}

impl TryFrom<PrescribeRaw> for PrescribeSpec {
    type Error = String;

    fn try_from(p: PrescribeRaw) -> Result<Self, String> {
        let target = match (p.to_base, p.displacement) {
            (true, None) => FoldTarget::ToBase,
            (false, Some(d)) => FoldTarget::Displacement(d),
            (true, Some(_)) => return Err("`folding.prescribe`: `to_base: true` and `displacement` both given; give one".into()),
            (false, None) => return Err("`folding.prescribe`: give either `to_base: true` or `displacement`".into()),
        };
        Ok(PrescribeSpec {
            group: p.group,
            axis: p.axis,
            target,
        })
    }
}

impl From<PrescribeSpec> for PrescribeRaw {
    fn from(p: PrescribeSpec) -> Self {
        let (to_base, displacement) = match p.target {
            FoldTarget::ToBase => (true, None),
            FoldTarget::Displacement(d) => (false, Some(d)),
        };
        PrescribeRaw {
            group: p.group,
            axis: p.axis,
            to_base,
            displacement,
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Record every n-th step of time-stepping stages.
    #[serde(default = "one_usize")]
    pub every: usize,
    #[serde(default = "yes")]
    pub hdf5: bool,
    #[serde(default = "yes")]
    pub mcap: bool,
    /// Write each time-stepping stage as `paraview/<stage>.vtkhdf`, a transient VTKHDF
    /// grid ParaView opens directly (members as lines with their forces, nodes with their
    /// displacements and velocities, every recorded step).
    #[serde(default)]
    pub paraview: bool,
    /// Frames per second of simulated time in `replay.mcap` for time-stepping stages
    /// [Hz]: a frame is logged when at least 1/rate has passed since the last one logged,
    /// and a stage's first and last frames always are; 0 logs every recorded step.
    /// result.h5 keeps every recorded step either way. Default 250: smooth real-time
    /// playback in Foxglove (which draws at the display's rate, ~60 Hz) and 60 frames per
    /// second down to 0.25× speed; for slower study, raise it (1000: 0.1× at 100 frames
    /// per second). Encoding and compressing the replay's frames was most of the output
    /// writer's CPU: at 1000 it took 0.59 of the solver's CPU on the paper case, at 250
    /// 0.38 (bench/outputs.md).
    #[serde(default = "default_replay_rate")]
    pub replay_rate: f64,
    /// Draw the case's figures after it completes, as `tsim figures` does (or with the
    /// command in `TSIM_FIGURES`). Needs Python; a failure is noted in `outcome.json` and
    /// does not fail the case.
    #[serde(default)]
    pub figures: bool,
    /// Follow the struts' clearance at every step: the nearest pair per recorded step, and
    /// touches and pass-throughs (result.h5, replay.mcap, summary).
    #[serde(default = "yes")]
    pub clearance: bool,
}

fn one_usize() -> usize {
    1
}
fn default_replay_rate() -> f64 {
    250.0
}
fn yes() -> bool {
    true
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            every: 1,
            hdf5: true,
            mcap: true,
            paraview: false,
            replay_rate: default_replay_rate(),
            figures: false,
            clearance: true,
        }
    }
}

/// Sweep axes, expanded as a cross product in the order given (first axis slowest).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    pub axes: Vec<SweepAxis>,
}

/// One axis: a name for case ids and, per value, the settings it overrides, as dotted
/// paths into the case config (e.g. `folding.steps: 20`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SweepAxis {
    pub name: String,
    pub values: Vec<SweepValue>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SweepValue {
    /// Label in case ids (letters, digits, `-`, `.`).
    pub label: String,
    pub set: BTreeMap<String, serde_json::Value>,
}

#[cfg(test)]
mod tests {
    use super::{EigenSpec, FoldSpec, FoldTarget, RayleighSpec};

    /// `case.yaml` is compared byte for byte on resume: the enums must write what the
    /// structs of five and four keys wrote (these texts are the structs' output).
    #[test]
    fn exclusive_choices_serialize_as_before() {
        for (yaml, spec, written) in [
            (
                "rayleigh: { alpha: 1.612, beta: 0.0052 }\n",
                RayleighSpec::Given {
                    alpha: 1.612,
                    beta: 0.0052,
                },
                "rayleigh:\n  alpha: 1.612\n  beta: 0.0052\n  modes: null\n  auto_modes: null\n  ratios: null\n",
            ),
            (
                "rayleigh: { modes: [3, 20], ratios: [0.2, 0.2] }\n",
                RayleighSpec::Modes {
                    modes: [3, 20],
                    ratios: [0.2, 0.2],
                },
                "rayleigh:\n  alpha: null\n  beta: null\n  modes:\n  - 3\n  - 20\n  auto_modes: null\n  ratios:\n  - 0.2\n  - 0.2\n",
            ),
            (
                "rayleigh: { auto_modes: z, ratios: [0.05, 0.1] }\n",
                RayleighSpec::AutoModes {
                    axis: super::Axis::Z,
                    ratios: [0.05, 0.1],
                },
                "rayleigh:\n  alpha: null\n  beta: null\n  modes: null\n  auto_modes: z\n  ratios:\n  - 0.05\n  - 0.1\n",
            ),
        ] {
            let e: EigenSpec = serde_saphyr::from_str(yaml).unwrap();
            assert_eq!(e.rayleigh, Some(spec));
            assert_eq!(serde_saphyr::to_string(&e).unwrap(), written);
        }

        let f: FoldSpec = serde_saphyr::from_str(
            "prescribe: [{group: top, axis: z, to_base: true}, {group: middle, axis: x, displacement: -0.5}, \
             {group: g, axis: y, to_base: false, displacement: 0.25}]\n",
        )
        .unwrap();
        let targets: Vec<FoldTarget> = f.prescribe.iter().map(|p| p.target).collect();
        assert_eq!(
            targets,
            [FoldTarget::ToBase, FoldTarget::Displacement(-0.5), FoldTarget::Displacement(0.25)]
        );
        assert_eq!(
            serde_saphyr::to_string(&f).unwrap(),
            "steps: 10\nmax_cuts: 6\nprescribe:\n- group: top\n  axis: z\n  to_base: true\n  displacement: null\n- group: middle\n  \
             axis: x\n  to_base: false\n  displacement: -0.5\n- group: g\n  axis: \"y\"\n  to_base: false\n  displacement: 0.25\n"
        );
    }
}
