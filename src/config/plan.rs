//! From a case config to what the pipeline runs: settings, real materials per member and
//! the stages. Every lookup by name (materials, node groups) happens here, on a config
//! that `validate` has accepted.

use super::schema::{CaseConfig, FoldTarget, LoadSpec, RayleighSpec, TransientSpec};
use crate::dynamics::{NodalLoad, Rayleigh};
use crate::error::{Error, Result};
use crate::model::{MemberKind, Model};
use crate::record::Stage;
use crate::stage::eigen::{DampingFrom, Eigen};
use crate::stage::fold::{Folding, Prescription, Target};
use crate::stage::substitute::Materials;
use crate::stage::transient::Transient;
use crate::stage::Settings;
use nalgebra::Vector3;

impl CaseConfig {
    pub fn settings(&self) -> Settings {
        Settings {
            newton: self.newton,
            every: self.outputs.every,
        }
    }

    /// The real law and linear density of every member: the strut material for struts,
    /// the cable material for cables. An unknown name is an error here too, for a config
    /// built in code that `validate` has not seen.
    pub fn materials(&self, model: &Model) -> Result<Materials> {
        let lib = self.material_library();
        let find = |name: &String| {
            lib.get(name).ok_or_else(|| Error::Stage {
                stage: "substitution",
                reason: format!("unknown material `{name}`"),
            })
        };
        let (strut, cable) = (find(&self.substitution.strut)?, find(&self.substitution.cable)?);
        let [strut_law, cable_law] = [strut, cable].map(|m| m.law());
        let factor = self.masses.factor();
        let (laws, linear_density) = model
            .members
            .iter()
            .map(|m| match m.kind {
                MemberKind::Strut => (strut_law.clone(), strut.density * factor * strut.area),
                MemberKind::Cable => (cable_law.clone(), cable.density * factor * cable.area),
            })
            .unzip();
        Ok(Materials { laws, linear_density })
    }

    /// The rest lengths given with the members (a model without form-finding).
    pub fn rest_lengths(&self) -> Vec<f64> {
        self.model.members.iter().map(|m| m.rest_length.unwrap_or_default()).collect()
    }

    pub fn eigen_stage(&self) -> Option<Eigen> {
        let damping = match self.eigen.as_ref()?.rayleigh {
            RayleighSpec::Given { alpha, beta } => DampingFrom::Given(Rayleigh { alpha, beta }),
            RayleighSpec::Modes { modes, ratios } => DampingFrom::Modes { modes, ratios },
            RayleighSpec::AutoModes { axis, ratios } => DampingFrom::AutoModes {
                axis: axis.index(),
                ratios,
            },
        };
        Some(Eigen { damping })
    }

    /// The transient stage `spec` describes, named `stage`.
    pub fn transient(&self, spec: &TransientSpec, stage: Stage, model: &Model) -> Result<Transient> {
        Ok(Transient {
            stage,
            params: spec.newmark(),
            duration: spec.duration,
            damped: spec.damped,
            tangent: spec.damping_tangent,
            load: spec.load.as_ref().map(|l| nodal_load(model, l)).transpose()?,
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
        }))
    }
}

fn nodal_load(model: &Model, spec: &LoadSpec) -> Result<NodalLoad> {
    let mut nodes = Vec::new();
    for g in &spec.groups {
        nodes.extend_from_slice(model.group(g)?);
    }
    nodes.sort_unstable();
    nodes.dedup();
    Ok(NodalLoad {
        nodes,
        force: Vector3::from(spec.force),
        duration: spec.duration,
        profile: spec.profile,
    })
}
