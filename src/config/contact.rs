//! The `contact` section: struts that cannot pass through each other or the ground, its
//! checks, and its translation into the core's [`Contact`] once the real structure exists
//! (its defaults are taken from it).

use super::schema::CaseConfig;
use super::validate::Problems;
use crate::contact::{Barrier, Contact, Ground};
use crate::error::{Error, Result};
use crate::model::clearance::{Search, Struts};
use crate::model::{MemberKind, Model};
use crate::structure::{State, Structure};
use nalgebra::Vector3;
use std::sync::Arc;

/// Contact in every stage after substitution: struts as capsules (axis plus radius) that
/// do not pass through each other, and nodes that stay above the ground, kept apart by a
/// barrier that acts across gaps below `distance` (Incremental Potential Contact, Li et al.
/// 2020). Absent: bodies pass through each other (the paper's idealization).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Struts do not pass through each other. Default true.
    #[serde(default = "yes")]
    pub struts: bool,
    /// Capsule radii other than the section's √(A/π) [m] (a tube's outer radius, a joint's
    /// size), by member set; later entries override earlier ones.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub radius: Vec<ContactRadiusSpec>,
    /// The ground, a half-space that no node (a ball of its struts' largest radius) enters,
    /// but those supported in every direction. Absent: no ground.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground: Option<GroundSpec>,
    /// Activation distance ĝ [m]: contact forces act across gaps below it, so positions in
    /// contact are within ĝ of touching. Default: 1 % of the smallest strut radius
    /// (1e-4 of the model's size without struts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<f64>,
    /// The barrier's energy scale κ ĝ² [J]: a gap holds up to ~30 times it before it is
    /// lost in round-off, and stores about a sixth of it at half the activation distance;
    /// it sets where in (0, ĝ) a contact carries its load, not whether it holds. Default:
    /// the structure's strain energy after substitution, or the largest force on it (its
    /// weight plus the largest transient's loads) times its size where larger (1 J for
    /// neither): about what the structure's motion can bring to one contact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<f64>,
}

/// A contact radius for a set of members.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactRadiusSpec {
    /// Member ids.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
    /// Member groups.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    /// The capsule radius [m].
    pub radius: f64,
}

/// A plane and its outward normal.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GroundSpec {
    /// A point of the ground's surface [m]. Default the origin.
    #[serde(default)]
    pub point: [f64; 3],
    /// The normal pointing out of the ground, towards the structure (any length). Default
    /// [0, 0, 1].
    #[serde(default = "up")]
    pub normal: [f64; 3],
}

fn yes() -> bool {
    true
}

fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// The default activation distance relative to the smallest strut radius.
const DISTANCE_OF_RADIUS: f64 = 1e-2;
/// The default activation distance relative to the model's size, without struts.
const DISTANCE_OF_SIZE: f64 = 1e-4;

impl CaseConfig {
    /// The `contact` section's checks.
    pub(in crate::config) fn check_contact(&self, model: Option<&Model>, p: &mut Problems) {
        let Some(c) = &self.contact else { return };
        for (field, value) in [("contact.distance", c.distance), ("contact.energy", c.energy)] {
            if let Some(v) = value {
                p.positive(field, v);
            }
        }
        for (k, r) in c.radius.iter().enumerate() {
            let field = format!("contact.radius[{k}]");
            p.positive(&format!("{field}.radius"), r.radius);
            if r.members.is_empty() && r.groups.is_empty() {
                p.add(field, "names no member: give `members` (ids) or `groups` (member groups)");
            } else if let Some(Err(e)) = model.map(|m| m.member_set(&r.members, &r.groups)) {
                p.add(field, e.to_string());
            }
        }
        if let Some(g) = &c.ground {
            if !(Vector3::from(g.normal).norm() > 0.0) || g.normal.iter().chain(&g.point).any(|v| !v.is_finite()) {
                p.add(
                    "contact.ground.normal",
                    "must be a finite, non-zero vector (the ground's outward normal)",
                );
            }
        }
    }

    /// The contact of `structure` (`None` without a `contact` section), its defaults taken
    /// from the structure at `state`: the capsule radii are `section[m]` unless the section
    /// gives others.
    pub fn contact(&self, structure: &Structure, state: &State, section: &[f64]) -> Result<Option<Arc<Contact>>> {
        let Some(c) = &self.contact else { return Ok(None) };
        let model = &structure.model;
        let mut radius = section.to_vec();
        for r in &c.radius {
            let members = model.member_set(&r.members, &r.groups).map_err(|e| Error::Stage {
                stage: "contact".into(),
                reason: e.to_string(),
            })?;
            members.into_iter().for_each(|m| radius[m] = r.radius);
        }
        let strut_radii = (0..model.members.len())
            .filter(|&m| model.members[m].kind == MemberKind::Strut)
            .map(|m| radius[m]);
        let smallest = strut_radii.fold(f64::INFINITY, f64::min);
        let distance = c.distance.unwrap_or(if smallest.is_finite() {
            DISTANCE_OF_RADIUS * smallest
        } else {
            DISTANCE_OF_SIZE * model.size()
        });
        let weight = structure.constant_load().iter().sum::<Vector3<f64>>().norm();
        let work = (weight + self.transient_load(model)) * model.size();
        let strain = structure.strain_energy(&state.positions);
        let energy = c.energy.unwrap_or(if strain.max(work) > 0.0 { strain.max(work) } else { 1.0 });
        let struts = c.struts.then(|| Arc::new(Struts::new(model, &radius, Search::Auto)));
        let ground = c.ground.as_ref().map(|g| Ground {
            point: g.point.into(),
            normal: Vector3::from(g.normal).normalize(),
        });
        Ok(Some(Arc::new(Contact::new(
            model,
            struts,
            &radius,
            ground,
            Barrier::with_energy(distance, energy),
        ))))
    }

    /// The largest total force a transient's loads put on `model` [N]: each load's |F|
    /// times the nodes it acts on, summed over the stage (time functions taken at 1).
    fn transient_load(&self, model: &Model) -> f64 {
        let nodes = |ids: &[String], groups: &[String]| model.node_set(ids, groups).map_or(0, |n| n.len()) as f64;
        let paper = [&self.free_vibration, &self.deployment].into_iter().flatten();
        let listed = self.stages.iter().filter_map(|e| e.transient.as_ref());
        paper
            .chain(listed)
            .map(|t| {
                let launch = t
                    .load
                    .as_ref()
                    .map_or(0.0, |l| Vector3::from(l.force).norm() * nodes(&[], &l.groups));
                let nodal: f64 = t
                    .loads
                    .iter()
                    .map(|l| Vector3::from(l.force).norm() * nodes(&l.nodes, &l.groups))
                    .sum();
                launch + nodal
            })
            .fold(0.0, f64::max)
    }
}
