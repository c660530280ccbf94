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
    /// The supports leave a rigid-body motion of the whole model unrestrained.
    #[error("the supports leave rigid-body motion free ({motion}); support more directions, e.g. fix x and y of one base node and one more in-plane direction of another")]
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
        self.check_rigid_body_supports()
    }

    /// Every rigid-body motion (translations, rotations about the centroid) that moves a
    /// node must move at least one supported direction. A motion that moves no node (the
    /// rotation about the line of collinear nodes) is no motion of the structure and is not
    /// asked for: a string between two pins, its nodes on the x axis, was refused for a free
    /// rotation about x (issue 30). Works on the Gram matrices of the motions over every
    /// direction (A) and over the supported ones (S): a free motion is a near-zero
    /// eigenvalue of S restricted to A's range (the motions that move some node, in an
    /// orthonormal basis), named by its largest component.
    fn check_rigid_body_supports(&self) -> Result<(), ModelError> {
        let n = self.nodes.len().max(1) as f64;
        let centroid = self.nodes.iter().fold(Vector3::zeros(), |s, nd| s + nd.xyz) / n;
        let scale = self.size().max(1e-12);
        let (mut all, mut supported) = (Matrix6::<f64>::zeros(), Matrix6::<f64>::zeros());
        for nd in &self.nodes {
            let r = (nd.xyz - centroid) / scale;
            for (d, &fixed) in nd.support.iter().enumerate() {
                // Component d of each rigid motion at this node: translations e_k, rotations ω_k × r.
                let mut row = Vector6::zeros();
                row[d] = 1.0;
                for k in 0..3 {
                    let mut w = Vector3::zeros();
                    w[k] = 1.0;
                    row[3 + k] = w.cross(&r)[d];
                }
                let outer = row * row.transpose();
                all += outer;
                if fixed {
                    supported += outer;
                }
            }
        }
        // The motions that move some node: A's range. Rotation columns are scaled by
        // r/size ≤ 1, so a motion that moves a node has an eigenvalue of order (r/size)²,
        // far above 1e-10 for any sensible geometry; one that moves none, zero.
        let moving = all.symmetric_eigen();
        let basis: Vec<Vector6<f64>> = (0..6)
            .filter(|&k| moving.eigenvalues[k] > 1e-10)
            .map(|k| moving.eigenvectors.column(k).into_owned())
            .collect();
        let m = basis.len();
        if m == 0 {
            return Ok(()); // no nodes: nothing to move
        }
        let projected = nalgebra::DMatrix::from_fn(m, m, |a, b| basis[a].dot(&(supported * basis[b])));
        let eig = projected.symmetric_eigen();
        let names = [
            "translation along x",
            "translation along y",
            "translation along z",
            "rotation about x",
            "rotation about y",
            "rotation about z",
        ];
        // As for A: a supported motion has an eigenvalue of order (r/size)² over its supported
        // directions, far above 1e-10 for any sensible geometry; a free one, zero.
        let free: Vec<&str> = (0..m)
            .filter(|&k| eig.eigenvalues[k] < 1e-10)
            .map(|k| {
                let w = eig.eigenvectors.column(k);
                let v: Vector6<f64> = (0..m).map(|a| basis[a] * w[a]).sum();
                let i = (0..6).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
                names[i]
            })
            .collect();
        if free.is_empty() {
            Ok(())
        } else {
            Err(ModelError::RigidBodyFree { motion: free.join(", ") })
        }
    }
}
