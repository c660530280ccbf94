//! From a case config to what the pipeline runs: settings, real materials per member and
//! the stages. Every lookup by name (materials, node groups) happens here, on a config
//! that `validate` has accepted.

use super::loading::{InitialAcceleration, NodalVectorSpec, StaticSpec, TimeFunctionSpec};
use super::schema::{CaseConfig, FoldTarget, LoadSpec, RayleighSpec, TransientSpec};
use crate::dynamics::{Actuator, GroundMotion, Loads, NodalLoad, Rayleigh, TimeFunction};
use crate::error::{Error, Result};
use crate::law::ForceLaw;
use crate::model::{MemberKind, Model};
use crate::record::Stage;
use crate::stage::eigen::{DampingFrom, Eigen};
use crate::stage::fold::{Folding, Prescription, Target};
use crate::stage::static_load::{Control, StaticLoad};
use crate::stage::substitute::Materials;
use crate::stage::transient::{Initial, Transient};
use crate::stage::Settings;
use nalgebra::Vector3;
use std::sync::Arc;

impl CaseConfig {
    pub fn settings(&self) -> Settings {
        Settings {
            newton: self.newton,
            every: self.outputs.every,
        }
    }

    /// The real law and linear density of every member (the strut material for struts,
    /// the cable material for cables, then `substitution.assign` in order) and the point
    /// masses of every node. An unknown name is an error here too, for a config built in
    /// code that `validate` has not seen.
    pub fn materials(&self, model: &Model) -> Result<Materials> {
        let lib = self.material_library();
        let stage_error = |reason: String| Error::Stage {
            stage: "substitution",
            reason,
        };
        let find = |name: &String| lib.get(name).ok_or_else(|| stage_error(format!("unknown material `{name}`")));
        let factor = self.masses.factor();
        // One (law, linear density, radius) per distinct material; members index into them,
        // so a large model shares its laws.
        let by_kind =
            [find(&self.substitution.strut)?, find(&self.substitution.cable)?].map(|m| (m.law(), m.density * factor * m.area, m.radius()));
        let mut table: Vec<(Arc<dyn ForceLaw>, f64, f64)> = by_kind.to_vec();
        let mut chosen: Vec<usize> = model.members.iter().map(|m| usize::from(m.kind == MemberKind::Cable)).collect();
        for (k, a) in self.substitution.assign.iter().enumerate() {
            let mut spec = match (&a.material, &a.define) {
                (Some(name), None) => find(name)?.clone(),
                (None, Some(spec)) => spec.clone(),
                _ => {
                    return Err(stage_error(format!(
                        "`substitution.assign[{k}]`: give `material` or `define`, one of them"
                    )))
                }
            };
            if let Some(area) = a.area {
                spec.area = area;
            }
            let density = if a.massless { 0.0 } else { spec.density * factor * spec.area };
            table.push((spec.law(), density, spec.radius()));
            for m in model.member_set(&a.members, &a.groups)? {
                chosen[m] = table.len() - 1;
            }
        }
        Ok(Materials {
            laws: chosen.iter().map(|&i| table[i].0.clone()).collect(),
            linear_density: chosen.iter().map(|&i| table[i].1).collect(),
            point_masses: self.point_masses(model)?,
            radius: chosen.iter().map(|&i| table[i].2).collect(),
        })
    }

    /// The point mass of every node [kg] (empty without `point_masses`).
    fn point_masses(&self, model: &Model) -> Result<Vec<f64>> {
        if self.point_masses.is_empty() {
            return Ok(Vec::new());
        }
        let mut m = vec![0.0; model.node_count()];
        for p in &self.point_masses {
            for n in model.node_set(&p.nodes, &p.groups)? {
                m[n] += p.mass;
            }
        }
        Ok(m)
    }

    /// Acceleration of gravity [m/s²] (zero without `gravity`).
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity.map_or(Vector3::zeros(), Vector3::from)
    }

    /// The static-load stage: the `static` section, or gravity alone with its defaults.
    pub fn static_stage(&self, model: &Model) -> Result<Option<StaticLoad>> {
        let spec = match (&self.statics, self.gravity) {
            (Some(spec), _) => spec.clone(),
            (None, Some(_)) => StaticSpec::default(),
            (None, None) => return Ok(None),
        };
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
        Ok(Some(StaticLoad {
            loads,
            steps: spec.steps,
            max_cuts: spec.max_cuts,
            control,
        }))
    }

    /// The rest lengths given with the members (a model without form-finding).
    pub fn rest_lengths(&self) -> Vec<f64> {
        self.model.members.iter().map(|m| m.rest_length.unwrap_or_default()).collect()
    }

    pub fn eigen_stage(&self) -> Option<Eigen> {
        let spec = self.eigen.as_ref()?;
        let damping = match spec.rayleigh {
            None => DampingFrom::None,
            Some(RayleighSpec::Given { alpha, beta }) => DampingFrom::Given(Rayleigh { alpha, beta }),
            Some(RayleighSpec::Modes { modes, ratios }) => DampingFrom::Modes { modes, ratios },
            Some(RayleighSpec::AutoModes { axis, ratios }) => DampingFrom::AutoModes {
                axis: axis.index(),
                ratios,
            },
        };
        Some(Eigen {
            damping,
            solver: spec.mode_solver(),
        })
    }

    /// The transient stages that change rest lengths in time (`actuation`).
    pub fn actuated_stages(&self) -> Vec<Stage> {
        [(Stage::FreeVibration, &self.free_vibration), (Stage::Deployment, &self.deployment)]
            .into_iter()
            .filter(|(_, spec)| spec.as_ref().is_some_and(|s| !s.actuation.is_empty()))
            .map(|(stage, _)| stage)
            .collect()
    }

    /// The transient stage `spec` describes, named `stage`: the paper's `load` first, then
    /// `loads` in order, the ground motion and the initial conditions (where the stage
    /// starts, `initial.from`, is the pipeline's choice).
    pub fn transient(&self, spec: &TransientSpec, stage: Stage, model: &Model) -> Result<Transient> {
        let error = |reason: String| Error::Stage {
            stage: stage.name(),
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
            damped: spec.damped,
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

    pub fn folding(&self, model: &Model) -> Result<Option<Folding>> {
        let Some(spec) = &self.folding else { return Ok(None) };
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
        Ok(Some(Folding {
            steps: spec.steps,
            max_cuts: spec.max_cuts,
            prescribe,
            modes: spec.eigen.unwrap_or(0),
        }))
    }
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
