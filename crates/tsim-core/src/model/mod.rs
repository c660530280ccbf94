//! Topology and geometry of a tensegrity: nodes, members, supports, named groups.
//! A [`Model`] knows nothing of materials; laws and rest lengths live in
//! [`crate::tsm::Elements`] so that one model serves form-finding and every real-material
//! stage of a sweep.

pub mod clearance;
mod cluster;
pub mod generate;
pub mod grid;
pub mod names;
mod validate;

use nalgebra::Vector3;
use std::collections::BTreeMap;

pub use cluster::Cluster;
pub use validate::ModelError;

/// The three coordinate directions, for DOF labels and support flags.
pub const AXES: [&str; 3] = ["x", "y", "z"];

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
/// Strut or cable: form-finding, substitution and the slack checks treat the two apart.
#[serde(rename_all = "snake_case")]
pub enum MemberKind {
    /// Compression member (brown in the paper's figures).
    Strut,
    /// Tension member (red when taut, grey when slack).
    Cable,
}

impl MemberKind {
    /// `"strut"` or `"cable"`, as in config and outputs.
    pub fn as_str(self) -> &'static str {
        match self {
            MemberKind::Strut => "strut",
            MemberKind::Cable => "cable",
        }
    }
}

/// A straight two-node bar: a strut or a cable.
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    /// Unique id, as in config and outputs.
    pub id: String,
    /// Indices into [`Model::nodes`].
    pub nodes: [usize; 2],
    /// Strut or cable.
    pub kind: MemberKind,
    /// Member groups, e.g. `ring`, `side`, `saddle`; form-finding may set C per group.
    pub groups: Vec<String>,
}

/// A pin joint: its id, initial position and supports.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Unique id, as in config and outputs.
    pub id: String,
    /// Initial coordinates [m].
    pub xyz: Vector3<f64>,
    /// Supported (fixed) directions x, y, z in the global frame.
    pub support: [bool; 3],
}

/// A tensegrity's topology and initial geometry, without materials.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Model {
    /// Nodes; node i owns DOFs 3i..3i+3 of every flat 3n vector.
    pub nodes: Vec<Node>,
    /// Members, in the order of every per-member vector (forces, rest lengths).
    pub members: Vec<Member>,
    /// Named node groups (`base`, `middle`, `top`, ...), node indices in order.
    pub node_groups: BTreeMap<String, Vec<usize>>,
    /// Clustered cables: chains of cable members that one cable runs through, sliding
    /// over the nodes between them (empty: every member on its own).
    pub clusters: Vec<Cluster>,
}

impl Model {
    /// Number of nodes n (3n DOFs before supports).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Initial node positions [m], in node order.
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        self.nodes.iter().map(|n| n.xyz).collect()
    }

    /// Number of supported directions.
    pub fn support_count(&self) -> usize {
        self.nodes.iter().map(|n| n.support.iter().filter(|&&s| s).count()).sum()
    }

    /// The error for a node id the model does not have, with the closest id it has.
    pub fn unknown_node(&self, id: &str) -> ModelError {
        ModelError::UnknownNodeId {
            node: id.to_string(),
            hint: names::hint(id, self.nodes.iter().map(|n| n.id.as_str())),
        }
    }

    /// Nodes of a group, or an error naming the group and the ones that exist.
    pub fn group(&self, name: &str) -> Result<&[usize], ModelError> {
        self.node_groups
            .get(name)
            .map(Vec::as_slice)
            .ok_or_else(|| ModelError::UnknownGroup {
                group: name.to_string(),
                known: self.node_groups.keys().cloned().collect::<Vec<_>>().join(", "),
                hint: names::hint(name, self.node_groups.keys().map(String::as_str)),
            })
    }

    /// The nodes named by id or by node group, each once, in index order; an empty set
    /// is an error (a load or mass on nothing is a mistake).
    pub fn node_set(&self, ids: &[String], groups: &[String]) -> Result<Vec<usize>, ModelError> {
        let mut set = Vec::new();
        for id in ids {
            let n = self.nodes.iter().position(|n| &n.id == id);
            set.push(n.ok_or_else(|| self.unknown_node(id))?);
        }
        for g in groups {
            set.extend_from_slice(self.group(g)?);
        }
        set.sort_unstable();
        set.dedup();
        if set.is_empty() {
            return Err(ModelError::EmptyNodeSet);
        }
        Ok(set)
    }

    /// The members named by id or by member group, each once, in index order.
    pub fn member_set(&self, ids: &[String], groups: &[String]) -> Result<Vec<usize>, ModelError> {
        let mut set = Vec::new();
        for id in ids {
            let m = self.members.iter().position(|m| &m.id == id);
            set.push(m.ok_or_else(|| ModelError::UnknownMember {
                member: id.clone(),
                hint: names::hint(id, self.members.iter().map(|m| m.id.as_str())),
            })?);
        }
        for g in groups {
            let before = set.len();
            set.extend((0..self.members.len()).filter(|&k| self.members[k].groups.contains(g)));
            if set.len() == before {
                let mut known: Vec<&str> = self.members.iter().flat_map(|m| m.groups.iter().map(String::as_str)).collect();
                known.sort_unstable();
                known.dedup();
                return Err(ModelError::UnknownMemberGroup {
                    group: g.clone(),
                    hint: names::hint(g, known.iter().copied()),
                    known: known.join(", "),
                });
            }
        }
        set.sort_unstable();
        set.dedup();
        if set.is_empty() {
            return Err(ModelError::EmptyMemberSet);
        }
        Ok(set)
    }

    /// The clustered cable member `m` belongs to, if any.
    pub fn cluster_of(&self, m: usize) -> Option<&Cluster> {
        self.clusters.iter().find(|c| c.members.contains(&m))
    }

    /// Largest distance between two nodes' bounding-box corners: the model's length scale.
    pub fn size(&self) -> f64 {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for n in &self.nodes {
            lo = lo.inf(&n.xyz);
            hi = hi.sup(&n.xyz);
        }
        (hi - lo).norm()
    }
}

/// Vertical extent max z − min z of a set of positions [m]: the tower height that folding
/// and deployment are measured against.
pub fn height(x: &[Vector3<f64>]) -> f64 {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.z), hi.max(p.z)));
    hi - lo
}

/// How far positions `x` are from a `reference` shape: the RMS over nodes of the distance
/// to it, over its height; and the same against its mirror image z → 2 z_base − z about
/// its lowest level (small when a tower ended upside down). Returns (direct, mirrored).
pub fn shape_error(x: &[Vector3<f64>], reference: &[Vector3<f64>]) -> (f64, f64) {
    let h = height(reference);
    let rms = |target: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
        (x.iter().zip(reference).map(|(x, p)| (x - target(p)).norm_squared()).sum::<f64>() / reference.len() as f64).sqrt() / h
    };
    let base_z = reference.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    (rms(&|p| *p), rms(&|p| Vector3::new(p.x, p.y, 2.0 * base_z - p.z)))
}
