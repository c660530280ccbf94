//! From a case config to what the pipeline runs: settings and real materials per member
//! (the stages: `sequence`). Every lookup by name (materials, node groups) happens here, on a config
//! that `validate` has accepted.

use super::schema::CaseConfig;
use crate::error::{Error, Result};
use crate::law::ForceLaw;
use crate::model::{MemberKind, Model};
use crate::stage::substitute::Materials;
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
            stage: "substitution".into(),
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

    /// The rest lengths given with the members (a model without form-finding).
    pub fn rest_lengths(&self) -> Vec<f64> {
        self.model.members.iter().map(|m| m.rest_length.unwrap_or_default()).collect()
    }
}
