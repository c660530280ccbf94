//! One case, start to end (paper Figure 1): form-finding (or the given model's
//! equilibrium) and substitution, then the planned stages ([`crate::stage::sequence`]) in
//! order — the paper's eigen analysis (→ Rayleigh α, β), free vibration, folding and
//! deployment, or a `stages` list. Every stage takes the structure and a converged state
//! and returns the state it ends in; what a later stage takes from an earlier one (its
//! start, its damping, a shape to compare with) is named in the plan, never written into
//! the structure.

use crate::config::CaseConfig;
use crate::error::{Error, Result};
use crate::model::clearance::Tracker;
use crate::model::Model;
use crate::record::{
    ClearanceLog, ClearanceSummary, ClusterLog, ClusterSummary, FormFindRecord, FrameClearance, ModelRecord, Observed, Recorder,
    RigidityRecord, Stage, StageKind, StageLayout,
};
use crate::rigidity::{self, Rigidity, RigidityError};
use crate::stage::eigen::EigenSummary;
use crate::stage::fold::FoldSummary;
use crate::stage::formfind::{explain_failure, FormFindSummary, SelfEquilibrium};
use crate::stage::sequence::{PlannedStage, Reached, Run};
pub use crate::stage::sequence::{StageSummary, TransientStageSummary};
use crate::stage::static_load::StaticSummary;
use crate::stage::substitute::{balanced_forces, SubstitutionSummary};
use crate::stage::{Analysis, Settings};
use crate::structure::{State, Structure};
use std::collections::BTreeMap;
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
    /// The figures of each stage after the shape, by stage name (the paper's sequence:
    /// `static`, `eigen`, `free_vibration`, `folding`, `deployment`), each with its `kind`.
    #[serde(flatten)]
    pub stages: BTreeMap<String, StageSummary>,
    /// Wall time of each stage that ran, recording included [s], by stage name
    /// (`formfinding` or `equilibrium` with substitution, then the stages').
    #[serde(default)]
    pub stage_seconds: BTreeMap<String, f64>,
    /// The smallest strut clearance over every recorded step and the touch and
    /// pass-through events (absent with `outputs.clearance: false`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<ClearanceSummary>,
    /// Each clustered cable's largest tension and slide (none without clusters).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clusters: Vec<ClusterSummary>,
}

impl CaseSummary {
    pub fn stage(&self, name: &str) -> Option<&StageSummary> {
        self.stages.get(name)
    }

    /// The static stage `name`'s figures (the paper's: `static`).
    pub fn statics(&self, name: &str) -> Option<&StaticSummary> {
        match self.stage(name)? {
            StageSummary::Static(s) => Some(s),
            _ => None,
        }
    }

    /// The eigen stage `name`'s figures (the paper's: `eigen`).
    pub fn eigen(&self, name: &str) -> Option<&EigenSummary> {
        match self.stage(name)? {
            StageSummary::Eigen(s) => Some(s),
            _ => None,
        }
    }

    /// The transient `name`'s figures (the paper's: `free_vibration`, `deployment`).
    pub fn transient(&self, name: &str) -> Option<&TransientStageSummary> {
        match self.stage(name)? {
            StageSummary::Transient(s) => Some(s.as_ref()),
            _ => None,
        }
    }

    /// The folding stage `name`'s figures (the paper's: `folding`).
    pub fn folding(&self, name: &str) -> Option<&FoldSummary> {
        match self.stage(name)? {
            StageSummary::Folding(s) => Some(s),
            _ => None,
        }
    }
}

/// Runs every configured stage of one case.
pub fn run_case(cfg: &CaseConfig, recorder: &mut dyn Recorder) -> Result<CaseSummary> {
    let mut log = Observed::new(recorder, (ClearanceLog::default(), ClusterLog::default()));
    let mut summary = run_stages(cfg, &mut log)?;
    let (clearance, clusters) = &log.observer;
    summary.clearance = clearance.summary();
    summary.clusters = clusters.summary();
    Ok(summary)
}

/// [`run_case`] without the clearance summary, which its recorder keeps.
fn run_stages(cfg: &CaseConfig, recorder: &mut dyn Recorder) -> Result<CaseSummary> {
    let model = cfg.model.build()?;
    let settings = cfg.settings();
    let mut summary = CaseSummary::default();
    let mut clock = Instant::now();
    // Wall time since the previous lap, as the stage's.
    let mut lap = |summary: &mut CaseSummary, stage: &str| {
        summary.stage_seconds.insert(stage.into(), clock.elapsed().as_secs_f64());
        clock = Instant::now();
    };
    // Form-finding and substitution by real materials (or the given rest lengths).
    let (mut structure, unloaded, found) = shape(cfg, &model, &settings, recorder)?;
    if !cfg.outputs.clearance {
        structure.struts = None;
    }
    summary.substitution = SubstitutionSummary::new(&structure, &unloaded)?;
    let plan = cfg.stage_plan(&model)?;
    let analysis = analyse(&structure, &unloaded);
    summary.structure_analysis = rigidity::Summary::new(&analysis);
    let layouts = layouts(&structure.model, &plan, cfg.stages.is_empty());
    record_structure(recorder, &structure, &unloaded, &found, cfg.masses.as_str(), &layouts)?;
    let skipped = analysis.as_ref().map_err(ToString::to_string);
    let record = RigidityRecord {
        analysis: skipped.as_ref().map_err(String::as_str).copied(),
    };
    recorder.rigidity(&record).map_err(|source| Error::Record {
        stage: "structure_analysis".into(),
        source,
    })?;
    // Refused after the records: the found shape a user must change stays in result.h5.
    (summary.substitution).require_stable(cfg.substitution.allow_unstable, cfg.formfinding.is_some())?;
    lap(&mut summary, found.stage.name());
    match found.stage.kind {
        StageKind::FormFinding => summary.formfinding = Some(found.summary),
        _ => summary.equilibrium = Some(found.summary),
    }
    // Gravity acts in every stage after the shape (a static stage steps it on).
    structure.gravity = cfg.gravity();
    structure.contact = cfg.contact(&structure, &unloaded, &cfg.materials(&model)?.radius)?;
    let mut reached = vec![Reached {
        state: unloaded,
        dead_load: Vec::new(),
    }];
    let mut figures: Vec<StageSummary> = Vec::with_capacity(plan.len());
    for planned in &plan {
        structure.dead_load.clone_from(&reached[planned.from].dead_load);
        let run = Run {
            structure: &structure,
            reached: &reached,
            earlier: &figures,
            settings: &settings,
        };
        let (end, stage_figures) = planned.run(&run, recorder)?;
        figures.push(stage_figures);
        lap(&mut summary, planned.stage().name());
        reached.push(end);
    }
    for (planned, stage_figures) in plan.iter().zip(figures) {
        summary.stages.insert(planned.stage().name().into(), stage_figures);
    }
    Ok(summary)
}

/// What the outputs are told of the stages before any runs: each planned stage, and for
/// the paper's sequence (`paper`) a placeholder for each of its stepped stages that does
/// not run, so that its files keep one layout whichever sections a case gives.
fn layouts(model: &Model, plan: &[PlannedStage], paper: bool) -> Vec<StageLayout> {
    let planned: Vec<StageLayout> = plan.iter().map(|p| p.layout(model)).collect();
    if !paper {
        return planned;
    }
    let paper_stages = [
        (StageKind::Static, "static"),
        (StageKind::Eigen, "eigen"),
        (StageKind::Transient, "free_vibration"),
        (StageKind::Folding, "folding"),
        (StageKind::Transient, "deployment"),
    ];
    paper_stages
        .into_iter()
        .filter_map(|(kind, name)| match planned.iter().find(|l| l.stage.name() == name) {
            Some(l) => Some(l.clone()),
            None => kind.is_stepped().then(|| StageLayout {
                placeholder: true,
                ..StageLayout::plain(model, Stage::new(kind, name))
            }),
        })
        .collect()
}

/// The equilibrium-matrix analysis at the equilibrium `state` with the real structure's
/// prestress there. Form-finding's measure structure has the same shape and, substitution
/// keeping the force ratios, a positive multiple of the same stress: one analysis covers
/// both.
fn analyse(structure: &Structure, state: &State) -> Result<Rigidity, RigidityError> {
    let forces = structure.member_forces(&state.positions);
    rigidity::analyse(&structure.model, &state.positions, Some(&forces))
}

/// What form-finding (or the given model's equilibrium) leaves for the records besides
/// the state.
struct FormFound {
    /// `formfinding` or `equilibrium`.
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
        let structure = materials.structure(model, cfg.rest_lengths())?;
        let (equilibrium, found) = SelfEquilibrium::GIVEN.run(&structure, start, settings, recorder)?;
        let summary = FormFindSummary::new(&found, &equilibrium, &found.forces);
        let forces = found.forces;
        let stage = Stage::of(StageKind::Equilibrium);
        return Ok((structure, equilibrium, FormFound { stage, summary, forces }));
    };
    let form_find = |recorder: &mut dyn Recorder| {
        // The measure potentials are per member: clusters slide from substitution on.
        let unclustered = Model {
            clusters: Vec::new(),
            ..model.clone()
        };
        let measure = Structure::massless(unclustered, ff.measure.elements(model)?);
        SelfEquilibrium::FORM_FINDING.run(&measure, start, settings, recorder)
    };
    let (shape, found) = form_find(recorder).map_err(|e| explain_failure(model, e))?;
    let forces = balanced_forces(model, &shape.positions, &found.forces);
    let structure = materials.substitute(model, &shape, &forces, cfg.substitution.prestress_scale)?;
    let summary = FormFindSummary::new(&found, &shape, &forces);
    let stage = Stage::of(StageKind::FormFinding);
    Ok((structure, shape, FormFound { stage, summary, forces }))
}

/// The model record (real rest lengths and masses) with the stages' layouts, then
/// form-finding's (or the given model's equilibrium), with the clearance of its struts.
fn record_structure(
    recorder: &mut dyn Recorder,
    structure: &Structure,
    shape: &State,
    found: &FormFound,
    mass_reading: &str,
    stages: &[StageLayout],
) -> Result<()> {
    let model = ModelRecord {
        model: &structure.model,
        rest_lengths: &structure.elements.rest,
        masses: &structure.masses,
        mass_reading,
        stages,
    };
    recorder.model(&model).map_err(|source| Error::Record {
        stage: "model".into(),
        source,
    })?;
    let mut tracker = structure.struts.clone().map(Tracker::new);
    let nearest = tracker.as_mut().map(|t| t.observe(&shape.positions, 0, 0.0));
    let record = FormFindRecord {
        stage: &found.stage,
        residuals: &found.summary.residuals,
        positions: &shape.positions,
        forces: &found.forces,
        clearance: tracker.as_ref().zip(nearest).map(|(t, nearest)| FrameClearance {
            nearest,
            events: t.events(),
        }),
    };
    recorder.formfinding(&record).map_err(|source| Error::Record {
        stage: found.stage.name.clone(),
        source,
    })
}
