//! Checks run when a model is loaded: every error names the offending item and the fix.

use super::Model;
use nalgebra::{Matrix6, Vector3, Vector6};
use std::collections::HashMap;

/// An invalid model, or a node, member or group named for it that it does not have. Every
/// message names the offending item and the fix; a `hint` is ` (did you mean `x`?)` or empty.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    /// Two nodes share an id.
    #[error("node id `{node}` is used twice; give every node a unique id")]
    DuplicateNode {
        /// The repeated id.
        node: String,
    },
    /// A member's end is not a node of the model.
    #[error("member `{member}` refers to unknown node `{node}`{hint}; define the node or fix the id")]
    UnknownNode {
        /// The member's id.
        member: String,
        /// The end's node id, as given.
        node: String,
        /// The closest node id the model has, if any is close.
        hint: String,
    },
    /// A member's two ends coincide (same node, or within 1e-12 of the model size).
    #[error("member `{member}` has zero length (nodes `{a}` and `{b}` coincide); move a node or remove the member")]
    ZeroLength {
        /// The member's id.
        member: String,
        /// Id of its first end node.
        a: String,
        /// Id of its second end node.
        b: String,
    },
    /// Two members join the same pair of nodes.
    #[error("members `{member}` and `{other}` join the same nodes `{a}` and `{b}`; remove one of them")]
    DuplicateMember {
        /// Id of the later member.
        member: String,
        /// Id of the earlier member on the same nodes.
        other: String,
        /// Id of one shared node.
        a: String,
        /// Id of the other shared node.
        b: String,
    },
    /// A node that no member connects.
    #[error("node `{node}` has no members; connect it or remove it")]
    UnusedNode {
        /// The node's id.
        node: String,
    },
    /// A node group lists a node id the model does not have.
    #[error("node group `{group}` names unknown node `{node}`{hint}")]
    UnknownGroupNode {
        /// The node group's name.
        group: String,
        /// The unknown node id.
        node: String,
        /// The closest node id the model has, if any is close.
        hint: String,
    },
    /// A node group the model does not have.
    #[error("unknown node group `{group}`{hint}; the model has: {known}")]
    UnknownGroup {
        /// The group name, as given.
        group: String,
        /// The model's node groups, comma-separated.
        known: String,
        /// The closest group name, if any is close.
        hint: String,
    },
    /// A node id, named by a selection, that the model does not have.
    #[error("unknown node `{node}`{hint}; use a node id of `model.nodes` (or a group with `groups`)")]
    UnknownNodeId {
        /// The node id, as given.
        node: String,
        /// The closest node id the model has, if any is close.
        hint: String,
    },
    /// A member id the model does not have.
    #[error("unknown member `{member}`{hint}; use a member id of `model.members` (or a member group with `groups`)")]
    UnknownMember {
        /// The member id, as given.
        member: String,
        /// The closest member id the model has, if any is close.
        hint: String,
    },
    /// A member group no member of the model belongs to.
    #[error("unknown member group `{group}`{hint}; the model's member groups: {known}")]
    UnknownMemberGroup {
        /// The group name, as given.
        group: String,
        /// The model's member groups, comma-separated.
        known: String,
        /// The closest group name, if any is close.
        hint: String,
    },
    /// A node selection that names neither node ids nor node groups.
    #[error("names no node: give `nodes` (node ids) or `groups` (node groups)")]
    EmptyNodeSet,
    /// A member selection that names neither member ids nor member groups.
    #[error("names no member: give `members` (member ids) or `groups` (member groups)")]
    EmptyMemberSet,
    /// A clustered cable that cannot be built as given.
    #[error("cluster `{cluster}`: {reason}")]
    Cluster {
        /// The cluster's id.
        cluster: String,
        /// What is wrong and the fix.
        reason: String,
    },
    /// The supports leave a rigid-body motion of the whole model unrestrained (named where a
    /// static stage fails on it).
    #[error("the supports leave rigid-body motion free ({motion}), and a static solve has an equilibrium only where the load holds that motion (eigen and transient stages run without supports); support more directions, e.g. fix x and y of one base node and one more in-plane direction of another")]
    RigidBodyFree {
        /// The free motions, e.g. `translation along x, rotation about z`.
        motion: String,
    },
}

impl Model {
    /// Validates topology and supports. Called by every constructor of models from input.
    pub fn validate(&self) -> Result<(), ModelError> {
        let mut seen = HashMap::new();
        for n in &self.nodes {
            if seen.insert(n.id.as_str(), ()).is_some() {
                return Err(ModelError::DuplicateNode { node: n.id.clone() });
            }
        }
        let mut used = vec![false; self.nodes.len()];
        let mut pairs: HashMap<(usize, usize), &str> = HashMap::new();
        // Once, not per member: the check stays linear in the model size.
        let coincident = 1e-12 * self.size().max(1.0);
        for m in &self.members {
            let [a, b] = m.nodes;
            let (na, nb) = (&self.nodes[a], &self.nodes[b]);
            if a == b || (na.xyz - nb.xyz).norm() <= coincident {
                return Err(ModelError::ZeroLength {
                    member: m.id.clone(),
                    a: na.id.clone(),
                    b: nb.id.clone(),
                });
            }
            if let Some(other) = pairs.insert((a.min(b), a.max(b)), &m.id) {
                return Err(ModelError::DuplicateMember {
                    member: m.id.clone(),
                    other: other.to_string(),
                    a: na.id.clone(),
                    b: nb.id.clone(),
                });
            }
            used[a] = true;
            used[b] = true;
        }
        if let Some(i) = used.iter().position(|u| !u) {
            return Err(ModelError::UnusedNode {
                node: self.nodes[i].id.clone(),
            });
        }
        Ok(())
    }

    /// Every rigid-body motion (translations, rotations about the centroid) that moves a
    /// node moves at least one supported direction: what a static solve under load needs
    /// unless the load itself holds the motion (a hanging pendulum). [`Model::validate`]
    /// does not ask it, so that dynamics of free-floating structures and of mechanisms runs
    /// (issue 30); a static stage that fails names the free motion with it. A
    /// motion that moves no node (the rotation about the line of collinear nodes) is no
    /// motion of the structure and is not asked for.
    /// `prescribed` (per node, may be empty) holds directions besides the supports, as in
    /// [`DofMap::new`](crate::tsm::DofMap::new).
    pub fn require_supports(&self, prescribed: &[[bool; 3]]) -> Result<(), ModelError> {
        let mut free = self.free_rigid_motions(prescribed);
        // Two free motions can share their largest component's name: named once.
        let mut seen = std::collections::HashSet::new();
        free.retain(|name| seen.insert(*name));
        if free.is_empty() {
            Ok(())
        } else {
            Err(ModelError::RigidBodyFree { motion: free.join(", ") })
        }
    }

    /// The rigid-body motions that move some node and no supported direction, each named
    /// by its largest component ("rotation about z"). Works on the Gram matrices of the
    /// motions over every direction (A) and over the supported ones (S): a free motion is a
    /// near-zero eigenvalue of S restricted to A's range (the motions that move some node,
    /// in an orthonormal basis).
    pub fn free_rigid_motions(&self, prescribed: &[[bool; 3]]) -> Vec<&'static str> {
        let motions = RigidMotions::new(self, prescribed);
        let Some(eig) = motions.restricted(&motions.supported) else {
            return Vec::new(); // no nodes: nothing to move
        };
        let names = [
            "translation along x",
            "translation along y",
            "translation along z",
            "rotation about x",
            "rotation about y",
            "rotation about z",
        ];
        // A supported motion has an eigenvalue of order (r/size)² over its supported
        // directions, far above 1e-10 for any sensible geometry; a free one, zero.
        (0..motions.basis.len())
            .filter(|&k| eig.eigenvalues[k] < FREE)
            .map(|k| {
                let w = eig.eigenvectors.column(k);
                let v: Vector6<f64> = motions.basis.iter().zip(w.iter()).map(|(b, wa)| b * *wa).sum();
                let i = (0..6).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
                names[i]
            })
            .collect()
    }

    /// Directions to hold in a static solve without load (form-finding, a given model's
    /// equilibrium, the stability check) where the supports leave rigid-body motion free,
    /// per node (empty when they leave none): a set of free directions that together stop
    /// every free rigid motion, no more. Self-stress is balanced over the whole structure, so
    /// holding them changes no equilibrium and their reactions are zero (to round-off; the
    /// equilibrium's `max_reaction` shows it), while the tangent becomes regular. Chosen
    /// greedily over the nodes farthest from the centroid first, a direction taken where it
    /// stops a motion not yet stopped by a clear margin, so the set is well conditioned.
    pub fn gauge(&self) -> Vec<[bool; 3]> {
        let motions = RigidMotions::new(self, &[]);
        let stopped = |s: &Matrix6<f64>, tolerance: f64| {
            motions
                .restricted(s)
                .map_or(0, |e| e.eigenvalues.iter().filter(|&&l| l > tolerance).count())
        };
        let mut held = motions.supported;
        let goal = motions.basis.len();
        if stopped(&held, FREE) == goal {
            return Vec::new();
        }
        let mut order: Vec<usize> = (0..self.nodes.len()).collect();
        let far = |n: usize| (self.nodes[n].xyz - motions.centroid).norm();
        order.sort_by(|&a, &b| far(b).total_cmp(&far(a)));
        let mut gauge = vec![[false; 3]; self.nodes.len()];
        // A margin of 1e-3 on the (r/size)² scale: a direction at a tenth or more of the
        // model's size from the axis it stops; the second pass, at the freedom threshold,
        // only serves a geometry where no direction has that margin.
        for margin in [1e-3, FREE] {
            for &n in &order {
                for (d, (held_here, &supported)) in gauge[n].iter_mut().zip(&self.nodes[n].support).enumerate() {
                    if supported || *held_here {
                        continue;
                    }
                    let row = motions.row(n, d);
                    let trial = held + row * row.transpose();
                    if stopped(&trial, margin) > stopped(&held, margin) {
                        held = trial;
                        *held_here = true;
                    }
                }
                if stopped(&held, FREE) == goal {
                    return gauge;
                }
            }
        }
        gauge
    }
}

/// Below this eigenvalue of the supported directions' Gram matrix (on the (r/size)² scale) a
/// rigid motion is free.
const FREE: f64 = 1e-10;

/// The model's rigid-body motions (3 translations, 3 rotations about the centroid, rotation
/// components scaled by the model's size) as rows per node direction.
struct RigidMotions {
    centroid: Vector3<f64>,
    /// Orthonormal basis of the motions that move some node (the range of their Gram
    /// matrix over every direction).
    basis: Vec<Vector6<f64>>,
    /// Their Gram matrix over the supported directions.
    supported: Matrix6<f64>,
    rows: Vec<[Vector6<f64>; 3]>,
}

impl RigidMotions {
    /// The motions of `model` with its supports and the `prescribed` directions held.
    fn new(model: &Model, prescribed: &[[bool; 3]]) -> Self {
        let n = model.nodes.len().max(1) as f64;
        let centroid = model.nodes.iter().fold(Vector3::zeros(), |s, nd| s + nd.xyz) / n;
        let scale = model.size().max(1e-12);
        let mut rows = Vec::with_capacity(model.nodes.len());
        let (mut all, mut supported) = (Matrix6::<f64>::zeros(), Matrix6::<f64>::zeros());
        for (i, nd) in model.nodes.iter().enumerate() {
            let r = (nd.xyz - centroid) / scale;
            // Component d of each rigid motion at this node: translations e_k, rotations ω_k × r.
            let node_rows: [Vector6<f64>; 3] = std::array::from_fn(|d| {
                let mut row = Vector6::zeros();
                row[d] = 1.0;
                for k in 0..3 {
                    let mut w = Vector3::zeros();
                    w[k] = 1.0;
                    row[3 + k] = w.cross(&r)[d];
                }
                row
            });
            for (d, row) in node_rows.iter().enumerate() {
                let outer = row * row.transpose();
                all += outer;
                if nd.support[d] || prescribed.get(i).is_some_and(|p| p[d]) {
                    supported += outer;
                }
            }
            rows.push(node_rows);
        }
        // The motions that move some node: A's range. Rotation columns are scaled by
        // r/size ≤ 1, so a motion that moves a node has an eigenvalue of order (r/size)²,
        // far above 1e-10 for any sensible geometry; one that moves none, zero.
        let moving = all.symmetric_eigen();
        let basis = (0..6)
            .filter(|&k| moving.eigenvalues[k] > FREE)
            .map(|k| moving.eigenvectors.column(k).into_owned())
            .collect();
        RigidMotions {
            centroid,
            basis,
            supported,
            rows,
        }
    }

    /// Node `n`'s direction `d` of every motion.
    fn row(&self, n: usize, d: usize) -> Vector6<f64> {
        self.rows[n][d]
    }

    /// The eigen decomposition of Gram matrix `s` restricted to the moving motions; `None`
    /// when nothing moves (no nodes).
    fn restricted(&self, s: &Matrix6<f64>) -> Option<nalgebra::SymmetricEigen<f64, nalgebra::Dyn>> {
        let m = self.basis.len();
        (m > 0).then(|| nalgebra::DMatrix::from_fn(m, m, |a, b| self.basis[a].dot(&(s * self.basis[b]))).symmetric_eigen())
    }
}
