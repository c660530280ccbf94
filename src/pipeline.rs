//! One case, start to end (paper Figure 1): form-finding → substitution → eigen analysis
//! (→ Rayleigh α, β) → free vibration → folding → deployment. Every stage takes the
//! structure and a converged state and returns the state it ends in; nothing reaches back.

use crate::config::{CaseConfig, StartFrom, TransientSpec};
use crate::error::{Error, Result};
use crate::model::clearance::Tracker;
use crate::model::{shape_error, Model};
use crate::record::{
    ClearanceLog, ClearanceSummary, Constraints, FormFindRecord, FrameClearance, ModelRecord, Recorder, RigidityRecord, Stage,
};
use crate::rigidity::{self, Rigidity, RigidityError};
use crate::stage::eigen::EigenSummary;
use crate::stage::fold::{FoldSummary, Folding};
use crate::stage::formfind::{explain_failure, FormFindSummary, SelfEquilibrium};
use crate::stage::static_load::StaticSummary;
use crate::stage::substitute::{balanced_forces, SubstitutionSummary};
use crate::stage::transient::TransientSummary;
use crate::stage::{Analysis, Settings};
use crate::structure::{State, Structure};
use nalgebra::Vector3;
use std::time::Instant;

/// Key figures of every stage that ran.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct CaseSummary {
    pub formfinding: Option<FormFindSummary>,
    /// The equilibrium of a model given with rest lengths (instead of form-finding).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub equilibrium: Option<FormFindSummary>,
    pub substitution: SubstitutionSummary,
    /// The equilibrium-matrix analysis of the equilibrium (s, m, stability).
    #[serde(default)]
    pub structure_analysis: rigidity::Summary,
    /// Gravity and static loads.
    #[serde(default, rename = "static", skip_serializing_if = "Option::is_none")]
    pub statics: Option<StaticSummary>,
    pub eigen: Option<EigenSummary>,
    pub free_vibration: Option<TransientSummary>,
    pub folding: Option<FoldSummary>,
    pub deployment: Option<DeploymentSummary>,
    /// Wall time of each stage that ran, recording included [s], by stage name
    /// (`formfinding` or `equilibrium` with substitution, `static`, `eigen`,
    /// `free_vibration`, `folding`, `deployment`).
    #[serde(default)]
    pub stage_seconds: std::collections::BTreeMap<String, f64>,
    /// The smallest strut clearance over every recorded step and the touch and
    /// pass-through events (absent with `outputs.clearance: false`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<ClearanceSummary>,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct DeploymentSummary {
    #[serde(flatten)]
    pub transient: TransientSummary,
    /// RMS over nodes of the distance to the pre-fold equilibrium, over the tower height.
    pub shape_error: f64,
    /// The same against the mirror image z → −z of the pre-fold shape: small when the
    /// tower deployed downwards (inverted).
    pub mirror_shape_error: f64,
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
}

/// Runs every configured stage of one case.
pub fn run_case(cfg: &CaseConfig, recorder: &mut dyn Recorder) -> Result<CaseSummary> {
    let mut log = ClearanceLog::new(recorder);
    let mut summary = run_stages(cfg, &mut log)?;
    summary.clearance = log.summary();
    Ok(summary)
}

/// [`run_case`] without the clearance summary, which its recorder keeps.
fn run_stages(cfg: &CaseConfig, recorder: &mut dyn Recorder) -> Result<CaseSummary> {
    let model = cfg.model.build()?;
    let settings = cfg.settings();
    let mut summary = CaseSummary::default();
    let mut clock = Instant::now();
    // Wall time since the previous lap, as the stage's.
    let mut lap = |summary: &mut CaseSummary, stage: Stage| {
        summary.stage_seconds.insert(stage.name().into(), clock.elapsed().as_secs_f64());
        clock = Instant::now();
    };
    // 1–2. Form-finding and substitution by real materials (or the given rest lengths).
    let (mut structure, unloaded, found) = shape(cfg, &model, &settings, recorder)?;
    if !cfg.outputs.clearance {
        structure.struts = None;
    }
    summary.substitution = SubstitutionSummary::new(&structure, &unloaded)?;
    summary.substitution.require_stable(cfg.substitution.allow_unstable)?;
    let folding = cfg.folding(&model)?;
    let analysis = analyse(&structure, &unloaded);
    summary.structure_analysis = rigidity::Summary::new(&analysis);
    let actuated = cfg.actuated_stages();
    record_structure(
        recorder,
        &structure,
        &unloaded,
        &found,
        cfg.masses.as_str(),
        folding.as_ref(),
        &actuated,
    )?;
    let skipped = analysis.as_ref().map_err(ToString::to_string);
    let record = RigidityRecord {
        analysis: skipped.as_ref().map_err(String::as_str).copied(),
    };
    recorder.rigidity(&record).map_err(|source| Error::Record {
        stage: "structure_analysis",
        source,
    })?;
    lap(&mut summary, found.stage);
    match found.stage {
        Stage::FormFinding => summary.formfinding = Some(found.summary),
        _ => summary.equilibrium = Some(found.summary),
    }
    // Gravity and static loads, which stay on from here.
    structure.gravity = cfg.gravity();
    let mut equilibrium = unloaded;
    if let Some(loading) = cfg.static_stage(&model)? {
        let (state, statics) = loading.run(&structure, equilibrium, &settings, recorder)?;
        structure.dead_load = loading.dead_load(statics.load_factor);
        (equilibrium, summary.statics) = (state, Some(statics));
        lap(&mut summary, Stage::Static);
    }
    // 3. Eigen analysis at the equilibrium, and the Rayleigh damping it gives.
    if let Some(eigen) = cfg.eigen_stage() {
        let (_, eig) = eigen.run(&structure, equilibrium.clone(), &settings, recorder)?;
        structure.damping = eig.rayleigh();
        summary.eigen = Some(eig);
        lap(&mut summary, Stage::Eigen);
    }
    // 4. Free vibration about the equilibrium (or as `initial.from` says).
    let mut previous = equilibrium.clone();
    if let Some(spec) = &cfg.free_vibration {
        let stage = cfg.transient(spec, Stage::FreeVibration, &model)?;
        let start = start_state(spec, StartFrom::Equilibrium, [&equilibrium, &equilibrium, &previous]);
        let (end, transient) = stage.run(&structure, start, &settings, recorder)?;
        (previous, summary.free_vibration) = (end, Some(transient));
        lap(&mut summary, Stage::FreeVibration);
    }
    // 5. Folding from the equilibrium.
    let mut folded = equilibrium.clone();
    if let Some(folding) = folding {
        let (state, fold) = folding.run(&structure, equilibrium.clone(), &settings, recorder)?;
        (folded, previous, summary.folding) = (state.clone(), state, Some(fold));
        lap(&mut summary, Stage::Folding);
    }
    // 6. Deployment from the folded state (or as `initial.from` says).
    if let Some(spec) = &cfg.deployment {
        let stage = cfg.transient(spec, Stage::Deployment, &model)?;
        let start = start_state(spec, StartFrom::Folded, [&equilibrium, &folded, &previous]);
        // The shape error at every step, for the time it comes within 1 % of the pre-fold shape.
        let (deployed, transient) = stage.run_towards(&structure, start, &settings, recorder, Some(&equilibrium.positions))?;
        summary.deployment = Some(DeploymentSummary::new(transient, deployed, &equilibrium));
        lap(&mut summary, Stage::Deployment);
    }
    Ok(summary)
}

/// The equilibrium-matrix analysis at the equilibrium `state` with the real structure's
/// prestress there. Form-finding's measure structure has the same shape and, substitution
/// keeping the force ratios, a positive multiple of the same stress: one analysis covers
/// both.
fn analyse(structure: &Structure, state: &State) -> Result<Rigidity, RigidityError> {
    let forces = structure.member_forces(&state.positions);
    rigidity::analyse(&structure.model, &state.positions, Some(&forces))
}

/// The state a transient starts from: its `initial.from`, else `default`; the candidates
/// are [equilibrium, folded, previous] (the end of the stage run just before).
fn start_state(spec: &TransientSpec, default: StartFrom, [equilibrium, folded, previous]: [&State; 3]) -> State {
    match spec.initial.as_ref().and_then(|i| i.from).unwrap_or(default) {
        StartFrom::Equilibrium => equilibrium.clone(),
        StartFrom::Folded => folded.clone(),
        StartFrom::Previous => previous.clone(),
    }
}

/// What form-finding (or the given model's equilibrium) leaves for the records besides
/// the state.
struct FormFound {
    /// `FormFinding` or `Equilibrium`.
    stage: Stage,
    summary: FormFindSummary,
    /// Balanced member forces of the form-found shape [N].
    forces: Vec<f64>,
}

/// The real structure and its equilibrium: form-found with measure potentials and
/// substituted by real materials, or the equilibrium of the given rest lengths.
fn shape(cfg: &CaseConfig, model: &Model, settings: &Settings, recorder: &mut dyn Recorder) -> Result<(Structure, State, FormFound)> {
    let start = State::at_rest(model.positions());
    let materials = cfg.materials(model)?;
    let Some(ff) = &cfg.formfinding else {
        let structure = materials.structure(model, cfg.rest_lengths());
        let (equilibrium, found) = SelfEquilibrium::GIVEN.run(&structure, start, settings, recorder)?;
        let summary = FormFindSummary::new(&found, &equilibrium, &found.forces);
        let forces = found.forces;
        let stage = Stage::Equilibrium;
        return Ok((structure, equilibrium, FormFound { stage, summary, forces }));
    };
    let form_find = |recorder: &mut dyn Recorder| {
        let measure = Structure::massless(model.clone(), ff.measure.elements(model)?);
        SelfEquilibrium::FORM_FINDING.run(&measure, start, settings, recorder)
    };
    let (shape, found) = form_find(recorder).map_err(|e| explain_failure(model, e))?;
    let forces = balanced_forces(model, &shape.positions, &found.forces);
    let structure = materials.substitute(model, &shape, &forces, cfg.substitution.prestress_scale)?;
    let summary = FormFindSummary::new(&found, &shape, &forces);
    let stage = Stage::FormFinding;
    Ok((structure, shape, FormFound { stage, summary, forces }))
}

/// The model record (real rest lengths and masses), then form-finding's (or the given
/// model's equilibrium), with the clearance of its struts. Folding's prescribed directions
/// (reactions too) and its modes per step are declared here: the outputs fix their layout
/// before streaming starts.
fn record_structure(
    recorder: &mut dyn Recorder,
    structure: &Structure,
    shape: &State,
    found: &FormFound,
    mass_reading: &str,
    folding: Option<&Folding>,
    actuated: &[Stage],
) -> Result<()> {
    let constraints: Vec<(Stage, Constraints)> = folding.iter().map(|f| (Stage::Folding, f.constraints(&structure.model))).collect();
    let model = ModelRecord {
        model: &structure.model,
        rest_lengths: &structure.elements.rest,
        masses: &structure.masses,
        mass_reading,
        constraints: &constraints,
        path_modes: folding.map_or(0, |f| f.modes),
        actuated,
    };
    recorder.model(&model).map_err(|source| Error::Record { stage: "model", source })?;
    let mut tracker = structure.struts.clone().map(Tracker::new);
    let nearest = tracker.as_mut().map(|t| t.observe(&shape.positions, 0, 0.0));
    let record = FormFindRecord {
        stage: found.stage,
        residuals: &found.summary.residuals,
        positions: &shape.positions,
        forces: &found.forces,
        clearance: tracker.as_ref().zip(nearest).map(|(t, nearest)| FrameClearance {
            nearest,
            events: t.events(),
        }),
    };
    recorder.formfinding(&record).map_err(|source| Error::Record {
        stage: found.stage.name(),
        source,
    })
}

impl DeploymentSummary {
    /// The stage's figures and how far it ended from the pre-fold `equilibrium`.
    fn new(transient: TransientSummary, deployed: State, equilibrium: &State) -> Self {
        let (shape_error, mirror_shape_error) = shape_error(&deployed.positions, &equilibrium.positions);
        DeploymentSummary {
            transient,
            shape_error,
            mirror_shape_error,
            final_positions: deployed.positions,
        }
    }
}
