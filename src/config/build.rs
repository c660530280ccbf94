use super::schema::ModelSpec;
use crate::model::names::hint;
use crate::model::{Cluster, Member, Model, ModelError, Node};
use nalgebra::Vector3;

impl ModelSpec {
    /// The model this spec describes, validated.
    pub fn build(&self) -> Result<Model, ModelError> {
        let model = match (&self.tower, &self.grid) {
            (Some(tower), _) => tower.build(),
            (None, Some(grid)) => grid.build(),
            (None, None) => {
                let nodes: Vec<Node> = self
                    .nodes
                    .iter()
                    .map(|n| {
                        let mut support = [false; 3];
                        n.fix.iter().for_each(|a| support[a.index()] = true);
                        Node {
                            id: n.id.clone(),
                            xyz: Vector3::from(n.xyz),
                            support,
                        }
                    })
                    .collect();
                let index = |member: &str, id: &str| {
                    nodes.iter().position(|n| n.id == id).ok_or_else(|| ModelError::UnknownNode {
                        member: member.to_string(),
                        node: id.to_string(),
                        hint: hint(id, nodes.iter().map(|n| n.id.as_str())),
                    })
                };
                let members = self
                    .members
                    .iter()
                    .map(|m| {
                        Ok(Member {
                            id: m.id.clone(),
                            nodes: [index(&m.id, &m.nodes[0])?, index(&m.id, &m.nodes[1])?],
                            kind: m.kind,
                            groups: m.groups.clone(),
                        })
                    })
                    .collect::<Result<Vec<_>, ModelError>>()?;
                let mut node_groups = std::collections::BTreeMap::new();
                for (g, ids) in &self.groups {
                    let idx = ids
                        .iter()
                        .map(|id| {
                            nodes.iter().position(|n| &n.id == id).ok_or_else(|| ModelError::UnknownGroupNode {
                                group: g.clone(),
                                node: id.clone(),
                                hint: hint(id, nodes.iter().map(|n| n.id.as_str())),
                            })
                        })
                        .collect::<Result<Vec<_>, _>>()?;
                    node_groups.insert(g.clone(), idx);
                }
                Model {
                    nodes,
                    members,
                    node_groups,
                    clusters: Vec::new(),
                }
            }
        };
        let mut model = model;
        for spec in &self.clusters {
            let members = spec
                .members
                .iter()
                .map(|id| model.member_set(std::slice::from_ref(id), &[]))
                .collect::<Result<Vec<_>, _>>()?;
            let cluster =
                Cluster::through(&model, &spec.id, members.concat(), &model.clusters)?.with_friction(spec.friction.unwrap_or(0.0))?;
            model.clusters.push(cluster);
        }
        model.validate()?;
        Ok(model)
    }
}

impl ModelSpec {
    /// The field a model error is about, for its line: the member or node it names
    /// (`model.members[3]`; of two, the later one), a node group, or the whole `model`
    /// (a generated tower or grid, or an error about the model as a whole).
    pub fn field_of(&self, e: &ModelError) -> String {
        let member = |ids: &[&String]| {
            let last = self.members.iter().rposition(|m| ids.contains(&&m.id));
            last.map(|i| format!("model.members[{i}]"))
        };
        let node = |id: &String| {
            let last = self.nodes.iter().rposition(|n| &n.id == id);
            last.map(|i| format!("model.nodes[{i}]"))
        };
        let field = match e {
            ModelError::UnknownNode { member: m, .. } | ModelError::ZeroLength { member: m, .. } => member(&[m]),
            ModelError::DuplicateMember { member: m, other, .. } => member(&[m, other]),
            ModelError::DuplicateNode { node: n } | ModelError::UnusedNode { node: n } => node(n),
            ModelError::UnknownGroupNode { group, .. } => Some(format!("model.groups.{group}")),
            ModelError::UnknownMember { member: m, .. } => self
                .clusters
                .iter()
                .rposition(|c| c.members.contains(m))
                .map(|i| format!("model.clusters[{i}]")),
            ModelError::Cluster { cluster, .. } => self
                .clusters
                .iter()
                .rposition(|c| &c.id == cluster)
                .map(|i| format!("model.clusters[{i}]")),
            _ => None,
        };
        field.unwrap_or_else(|| "model".into())
    }
}
