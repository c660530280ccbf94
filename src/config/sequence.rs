//! From the config's stages to the planned list ([`crate::stage::sequence`]): the
//! `stages` entries as written, or the paper's sections in the paper's order (their
//! shorthand). Each stage kind's settings become its stage object here.

use super::loading::{InitialAcceleration, NodalVectorSpec, StartFrom, StaticSpec, TimeFunctionSpec};
use super::schema::{CaseConfig, EigenSpec, FoldSpec, FoldTarget, LoadSpec, RayleighSpec, StageEntry, TransientSpec};
use crate::dynamics::{Actuator, GroundMotion, Loads, NodalLoad, Rayleigh, TimeFunction};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::eigen::{DampingFrom, Eigen};
use crate::stage::fold::{Folding, Prescription, Target};
use crate::stage::sequence::{Planned, PlannedStage};
use crate::stage::static_load::{Control, StaticLoad};
use crate::stage::transient::{Initial, Transient};
use nalgebra::Vector3;

/// The settings of a `stages` entry, by its one kind key.
#[derive(Clone, Copy, Debug)]
pub enum StageEntrySpec<'a> {
    Static(&'a StaticSpec),
    Eigen(&'a EigenSpec),
    Transient(&'a TransientSpec),
    Folding(&'a FoldSpec),
}

impl StageEntry {
    /// The entry's kind and settings; Err when it gives no kind key or more than one.
    pub fn spec(&self) -> std::result::Result<StageEntrySpec<'_>, String> {
        let given: Vec<StageEntrySpec> = [
            self.statics.as_ref().map(StageEntrySpec::Static),
            self.eigen.as_ref().map(StageEntrySpec::Eigen),
            self.transient.as_ref().map(StageEntrySpec::Transient),
            self.folding.as_ref().map(StageEntrySpec::Folding),
        ]
        .into_iter()
        .flatten()
        .collect();
        match given[..] {
            [one] => Ok(one),
            _ => Err(format!(
                "stage `{}` gives {} kinds; give exactly one of `static`, `eigen`, `transient`, `folding`",
                self.name,
                given.len()
            )),
        }
    }
}

/// A stage section of the config: its field path (`deployment`, `stages[2].transient`),
/// the stage's name and its settings.
pub type Section<'a> = (String, &'a str, StageEntrySpec<'a>);

impl CaseConfig {
    /// Every stage section the config gives: the paper's (`static` as written, not the
    /// gravity-only default) or the `stages` entries, in order. Checks, limits and table
    /// reading iterate this, one loop for both forms.
    pub fn stage_sections(&self) -> Vec<Section<'_>> {
        let paper = [
            ("static", self.statics.as_ref().map(StageEntrySpec::Static)),
            ("eigen", self.eigen.as_ref().map(StageEntrySpec::Eigen)),
            ("free_vibration", self.free_vibration.as_ref().map(StageEntrySpec::Transient)),
            ("folding", self.folding.as_ref().map(StageEntrySpec::Folding)),
            ("deployment", self.deployment.as_ref().map(StageEntrySpec::Transient)),
        ];
        let mut out: Vec<Section> = paper
            .into_iter()
            .filter_map(|(name, spec)| spec.map(|spec| (name.to_string(), name, spec)))
            .collect();
        for (k, entry) in self.stages.iter().enumerate() {
            if let Ok(spec) = entry.spec() {
                let kind = match spec {
                    StageEntrySpec::Static(_) => "static",
                    StageEntrySpec::Eigen(_) => "eigen",
                    StageEntrySpec::Transient(_) => "transient",
                    StageEntrySpec::Folding(_) => "folding",
                };
                out.push((format!("stages[{k}].{kind}"), &entry.name, spec));
            }
        }
        out
    }

    /// Every transient section with its field path, to change in place (tables read in).
    pub fn transients_mut(&mut self) -> Vec<(String, &mut TransientSpec)> {
        let mut out: Vec<(String, &mut TransientSpec)> = Vec::new();
        for (name, t) in [("free_vibration", &mut self.free_vibration), ("deployment", &mut self.deployment)] {
            out.extend(t.as_mut().map(|t| (name.to_string(), t)));
        }
        for (k, entry) in self.stages.iter_mut().enumerate() {
            out.extend(entry.transient.as_mut().map(|t| (format!("stages[{k}].transient"), t)));
        }
        out
    }

    /// The name of the state every case starts with: `formfinding`, or `equilibrium` for a
    /// model given with rest lengths.
    pub fn shape_name(&self) -> &'static str {
        if self.formfinding.is_some() {
            StageKind::FormFinding.name()
        } else {
            StageKind::Equilibrium.name()
        }
    }

    /// The stages after the shape: the `stages` list, or the paper's sections.
    pub fn stage_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        if self.stages.is_empty() {
            self.paper_plan(model)
        } else {
            self.listed_plan(model)
        }
    }

    /// The paper's sequence: `static` (or gravity alone with its defaults) from the shape;
    /// `eigen` at the equilibrium it reached, whose damping the `damped` transients use;
    /// free vibration from that equilibrium (or as `initial.from` says); folding from the
    /// equilibrium; deployment from the folded state (or as `initial.from` says), its
    /// shape compared with the equilibrium's.
    fn paper_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        let mut plan = Vec::new();
        let statics = match (&self.statics, self.gravity) {
            (Some(spec), _) => Some(spec.clone()),
            (None, Some(_)) => Some(StaticSpec::default()),
            (None, None) => None,
        };
        if let Some(spec) = statics {
            let stage = static_stage(&spec, Stage::of(StageKind::Static), false, model)?;
            plan.push(PlannedStage {
                from: 0,
                analysis: Planned::Static(stage),
            });
        }
        let equilibrium = plan.len();
        let eigen = self.eigen.as_ref().map(|spec| {
            plan.push(PlannedStage {
                from: equilibrium,
                analysis: Planned::Eigen(eigen_stage(spec, Stage::of(StageKind::Eigen))),
            });
            plan.len() - 1
        });
        let mut folded = equilibrium;
        let start = |spec: &TransientSpec, default, folded, previous| match spec.initial.as_ref().and_then(|i| i.from).unwrap_or(default) {
            StartFrom::Equilibrium => equilibrium,
            StartFrom::Folded => folded,
            StartFrom::Previous => previous,
        };
        let paper_transient = |spec: &TransientSpec, name: &str, from: usize, compare_to: Option<usize>| -> Result<PlannedStage> {
            Ok(PlannedStage {
                from,
                analysis: Planned::Transient {
                    stage: transient(spec, Stage::new(StageKind::Transient, name), model)?,
                    rayleigh_from: eigen.filter(|_| spec.damped),
                    compare_to,
                },
            })
        };
        if let Some(spec) = &self.free_vibration {
            let from = start(spec, StartFrom::Equilibrium, folded, plan.len());
            plan.push(paper_transient(spec, "free_vibration", from, None)?);
        }
        if let Some(spec) = &self.folding {
            plan.push(PlannedStage {
                from: equilibrium,
                analysis: Planned::Folding(folding(spec, Stage::of(StageKind::Folding), model)?),
            });
            folded = plan.len();
        }
        if let Some(spec) = &self.deployment {
            let from = start(spec, StartFrom::Folded, folded, plan.len());
            plan.push(paper_transient(spec, "deployment", from, Some(equilibrium))?);
        }
        Ok(plan)
    }

    /// The `stages` entries in order; names are looked up among the earlier ones (an
    /// unknown one is an error here too, for a config `validate` has not seen).
    fn listed_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        let mut names = vec![self.shape_name()];
        let mut plan: Vec<PlannedStage> = Vec::new();
        for (k, entry) in self.stages.iter().enumerate() {
            let error = |reason: String| Error::Stage {
                stage: entry.name.as_str().into(),
                reason,
            };
            let find = |name: &str| {
                names
                    .iter()
                    .position(|n| *n == name)
                    .ok_or_else(|| error(format!("no earlier stage is named `{name}`")))
            };
            let from = entry.from.as_deref().map_or(Ok(k), find)?;
            let stage = |kind| Stage::new(kind, &entry.name);
            let analysis = match entry.spec().map_err(error)? {
                StageEntrySpec::Static(spec) => Planned::Static(static_stage(spec, stage(StageKind::Static), from != 0, model)?),
                StageEntrySpec::Eigen(spec) => Planned::Eigen(eigen_stage(spec, stage(StageKind::Eigen))),
                StageEntrySpec::Folding(spec) => Planned::Folding(folding(spec, stage(StageKind::Folding), model)?),
                StageEntrySpec::Transient(spec) => {
                    let rayleigh_from = match spec.rayleigh_from.as_deref() {
                        None => None,
                        Some(name) => match find(name)?.checked_sub(1).map(|i| (i, &plan[i].analysis)) {
                            Some((i, Planned::Eigen(_))) => Some(i),
                            _ => return Err(error(format!("`rayleigh_from: {name}` is not an eigen stage"))),
                        },
                    };
                    Planned::Transient {
                        stage: transient(spec, stage(StageKind::Transient), model)?,
                        rayleigh_from,
                        compare_to: spec.compare_to.as_deref().map(find).transpose()?,
                    }
                }
            };
            plan.push(PlannedStage { from, analysis });
            names.push(&entry.name);
        }
        Ok(plan)
    }
}

/// The static-load stage `spec` describes, named `stage`; `start_loaded`: it starts
/// from a state under the structure's constant load (any but the shape), so that only
/// its own pattern is stepped.
fn static_stage(spec: &StaticSpec, stage: Stage, start_loaded: bool, model: &Model) -> Result<StaticLoad> {
    let mut loads = Vec::new();
    if !spec.loads.is_empty() {
        loads = vec![Vector3::zeros(); model.node_count()];
        for l in &spec.loads {
            for n in model.node_set(&l.nodes, &l.groups)? {
                loads[n] += Vector3::from(l.force);
            }
        }
    }
    let control = match &spec.control {
        Some(c) => Some(Control {
            node: model.node_set(std::slice::from_ref(&c.node), &[])?[0],
            axis: c.axis.index(),
            displacement: c.displacement,
        }),
        None => None,
    };
    Ok(StaticLoad {
        stage,
        loads,
        steps: spec.steps,
        max_cuts: spec.max_cuts,
        control,
        start_loaded,
    })
}

fn eigen_stage(spec: &EigenSpec, stage: Stage) -> Eigen {
    let damping = match spec.rayleigh {
        None => DampingFrom::None,
        Some(RayleighSpec::Given { alpha, beta }) => DampingFrom::Given(Rayleigh { alpha, beta }),
        Some(RayleighSpec::Modes { modes, ratios }) => DampingFrom::Modes { modes, ratios },
        Some(RayleighSpec::AutoModes { axis, ratios }) => DampingFrom::AutoModes {
            axis: axis.index(),
            ratios,
        },
    };
    Eigen {
        damping,
        stage,
        solver: spec.mode_solver(),
    }
}

/// The transient stage `spec` describes, named `stage`: the paper's `load` first, then
/// `loads` in order, the ground motion and the initial conditions (where the stage
/// starts and its damping are the plan's). Undamped.
fn transient(spec: &TransientSpec, stage: Stage, model: &Model) -> Result<Transient> {
    let error = |reason: String| Error::Stage {
        stage: stage.name.clone(),
        reason,
    };
    let mut nodal: Vec<NodalLoad> = spec.load.iter().map(|l| launch_load(model, l)).collect::<Result<_>>()?;
    for l in &spec.loads {
        nodal.push(NodalLoad {
            nodes: model.node_set(&l.nodes, &l.groups)?,
            force: Vector3::from(l.force),
            time: time_function(&l.time).map_err(error)?,
        });
    }
    let ground = match &spec.ground_motion {
        Some(g) => Some(GroundMotion {
            acceleration: Vector3::from(g.acceleration),
            time: time_function(&g.time).map_err(error)?,
        }),
        None => None,
    };
    let mut actuators = Vec::new();
    for a in &spec.actuation {
        actuators.push(Actuator {
            members: model.member_set(&a.members, &a.groups)?,
            scale: a.scale,
            time: time_function(&a.time).map_err(error)?,
        });
    }
    let initial = spec.initial.clone().unwrap_or_default();
    let field = |entries: &[NodalVectorSpec]| -> Result<Vec<(usize, Vector3<f64>)>> {
        let mut out = Vec::new();
        for e in entries {
            let nodes = model.node_set(&e.nodes, &e.groups)?;
            out.extend(nodes.into_iter().map(|n| (n, Vector3::from(e.value))));
        }
        Ok(out)
    };
    Ok(Transient {
        stage,
        params: spec.newmark(),
        duration: spec.duration,
        rayleigh: Rayleigh::default(),
        tangent: spec.damping_tangent,
        loads: Loads { nodal, ground },
        actuators,
        initial: Initial {
            displacement: field(&initial.displacement)?,
            velocity: field(&initial.velocity)?,
            zero_acceleration: initial.acceleration == InitialAcceleration::Zero,
        },
    })
}

fn folding(spec: &FoldSpec, stage: Stage, model: &Model) -> Result<Folding> {
    let prescribe = spec
        .prescribe
        .iter()
        .map(|p| {
            let target = match p.target {
                FoldTarget::Displacement(d) => Target::Displacement(d),
                FoldTarget::ToBase => Target::LevelOf(model.group("base")?.to_vec()),
            };
            Ok(Prescription {
                nodes: model.group(&p.group)?.to_vec(),
                axis: p.axis.index(),
                target,
            })
        })
        .collect::<Result<_>>()?;
    Ok(Folding {
        stage,
        steps: spec.steps,
        max_cuts: spec.max_cuts,
        prescribe,
        modes: spec.eigen.unwrap_or(0),
    })
}

fn launch_load(model: &Model, spec: &LoadSpec) -> Result<NodalLoad> {
    let mut nodes = Vec::new();
    for g in &spec.groups {
        nodes.extend_from_slice(model.group(g)?);
    }
    nodes.sort_unstable();
    nodes.dedup();
    Ok(NodalLoad::launch(nodes, Vector3::from(spec.force), spec.duration, spec.profile))
}

/// The run-time function of a time function spec; a table must have its points (a file
/// is read into them when the config is loaded: `resolve_tables`).
fn time_function(spec: &TimeFunctionSpec) -> std::result::Result<TimeFunction, String> {
    Ok(match *spec {
        TimeFunctionSpec::Constant => TimeFunction::Constant,
        TimeFunctionSpec::Step { duration } => TimeFunction::Step { duration },
        TimeFunctionSpec::Ramp { duration } => TimeFunction::Ramp { duration },
        TimeFunctionSpec::HalfSine { duration } => TimeFunction::HalfSine { duration },
        TimeFunctionSpec::Harmonic {
            frequency,
            phase,
            duration,
        } => TimeFunction::Harmonic {
            frequency,
            phase,
            duration,
        },
        TimeFunctionSpec::Table { ref file, ref points } => {
            if points.len() < 2 {
                let source = file.as_ref().map_or(String::new(), |f| format!(" (file `{f}` not read)"));
                return Err(format!("a time table needs at least 2 points{source}"));
            }
            TimeFunction::Table(points.clone())
        }
    })
}
