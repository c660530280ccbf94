//! Clustered cables, as topology: one continuous cable run through a chain of cable
//! members, sliding without friction over the nodes between them (pulleys). The mechanics
//! (one tension along the cable, its tangent) are in `tsm::cluster`.

use super::{MemberKind, Model, ModelError};

/// A cable through the members `members`, in the order it runs: each shares a node with the
/// next, and that node is a pulley the cable slides over.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    /// Unique id, as in config and outputs.
    pub id: String,
    /// Indices into [`Model::members`], in the cable's order.
    pub members: Vec<usize>,
    /// The nodes the cable passes, from one end to the other (`members.len() + 1` of them;
    /// first = last for a closed loop): `nodes[j + 1]` joins `members[j]` and
    /// `members[j + 1]`.
    pub nodes: Vec<usize>,
    /// Capstan friction coefficient μ over every pulley (0: it slides freely;
    /// `tsm::friction`). An open cable only: a loop with friction is refused.
    pub friction: f64,
}

impl Cluster {
    /// The cable `id` through `members` of `model` (indices, in order), or the error naming
    /// what is wrong: fewer than two members, a strut, a member in another cluster of
    /// `earlier`, or two members in a row that share no node.
    pub fn through(model: &Model, id: &str, members: Vec<usize>, earlier: &[Cluster]) -> Result<Cluster, ModelError> {
        let name = |m: usize| model.members[m].id.clone();
        let error = |reason: String| ModelError::Cluster {
            cluster: id.to_string(),
            reason,
        };
        if members.len() < 2 {
            return Err(error(
                "a clustered cable runs through at least two members; a single member is an ordinary cable".into(),
            ));
        }
        if let Some(c) = earlier.iter().find(|c| c.id == id) {
            return Err(error(format!(
                "the id is used twice (clusters `{}`); give every cluster a unique id",
                c.id
            )));
        }
        for (k, &m) in members.iter().enumerate() {
            if model.members[m].kind != MemberKind::Cable {
                return Err(error(format!("member `{}` is a strut; only cables slide over nodes", name(m))));
            }
            if members[..k].contains(&m) {
                return Err(error(format!("member `{}` is listed twice", name(m))));
            }
            if let Some(c) = earlier.iter().find(|c| c.members.contains(&m)) {
                return Err(error(format!(
                    "member `{}` is already in cluster `{}`; a member belongs to one cable",
                    name(m),
                    c.id
                )));
            }
        }
        let nodes = chain(model, &members).ok_or_else(|| {
            let k = (1..members.len()).find(|&k| shared(model, members[k - 1], members[k]).is_none());
            let k = k.unwrap_or(1);
            error(format!(
                "members `{}` and `{}` follow each other in the list but share no node (or the chain turns back on itself); list the members in the order the cable runs",
                name(members[k - 1]),
                name(members[k])
            ))
        })?;
        Ok(Cluster {
            id: id.to_string(),
            members,
            nodes,
            friction: 0.0,
        })
    }

    /// This cable with capstan friction `mu` over its pulleys, or why not: μ must be finite
    /// and not negative, and a loop (whose pulleys close on themselves) has none yet.
    pub fn with_friction(self, mu: f64) -> Result<Cluster, ModelError> {
        let error = |reason: String| ModelError::Cluster {
            cluster: self.id.clone(),
            reason,
        };
        if !(mu.is_finite() && mu >= 0.0) {
            return Err(error(format!("friction {mu} is not a coefficient: give μ ≥ 0 (0: frictionless)")));
        }
        if mu > 0.0 && self.nodes.first() == self.nodes.last() {
            return Err(error(
                "a closed loop with friction is not supported: open it at one node (end the cable there) or give friction 0".into(),
            ));
        }
        Ok(Cluster { friction: mu, ..self })
    }

    /// The slide over each of its [`Self::pulleys`], from the rest lengths `reference` to
    /// `rest` [m], into `out`: Σ_{i≤j} (l0_i − l0_i^ref · L0/L0^ref) over the members up to
    /// pulley j, the cable (as rest length) that has run over it towards the cable's first
    /// member, less a winch's uniform change of the whole.
    pub fn slides(&self, rest: &[f64], reference: &[f64], out: &mut Vec<f64>) {
        let total = |r: &[f64]| self.members.iter().map(|&m| r[m]).sum::<f64>();
        let scale = total(rest) / total(reference);
        let mut run = 0.0;
        for &m in &self.members[..self.members.len() - 1] {
            run += rest[m] - reference[m] * scale;
            out.push(run);
        }
    }

    /// The cable's tension from every member's `forces` [N]: the one its members carry
    /// (its first's) without friction; with friction, whose pulleys hold different tensions
    /// either side (up to e^{μθ} apart), the largest of its spans'.
    pub fn tension(&self, forces: &[f64]) -> f64 {
        if self.friction == 0.0 {
            forces[self.members[0]]
        } else {
            self.members.iter().map(|&m| forces[m]).fold(f64::NEG_INFINITY, f64::max)
        }
    }

    /// The pulley nodes between two of its listed members, `nodes[1..k]` (a loop's first
    /// node, between its last member and its first, is not one: a loop turning as a whole
    /// has no origin to count a slide from): where [`Self::slides`] are counted.
    pub fn pulleys(&self) -> &[usize] {
        &self.nodes[1..self.members.len()]
    }
}

impl Model {
    /// Checks that actuators changing the rest lengths of the member `sets` change each
    /// clustered cable as a whole (one set holds all its members or none): a cable's rest
    /// length is one length, which its members only share out.
    pub fn check_cluster_actuation<'a>(&self, mut sets: impl Iterator<Item = &'a [usize]>) -> Result<(), String> {
        sets.try_for_each(|set| match self.clusters.iter().find(|c| c.members.iter().any(|m| set.contains(m)) && !c.members.iter().all(|m| set.contains(m))) {
            None => Ok(()),
            Some(c) => {
                let ids: Vec<&str> = c.members.iter().map(|&m| self.members[m].id.as_str()).collect();
                Err(format!(
                    "an actuator changes part of the clustered cable `{}`; a cable has one rest length: actuate all its members together ({})",
                    c.id,
                    ids.join(", ")
                ))
            }
        })
    }
}

/// The node members `a` and `b` share, if one.
fn shared(model: &Model, a: usize, b: usize) -> Option<usize> {
    let [a0, a1] = model.members[a].nodes;
    model.members[b].nodes.into_iter().find(|&n| n == a0 || n == a1)
}

/// The nodes a cable through `members` passes in order, if each member continues from the
/// end the one before it reached.
fn chain(model: &Model, members: &[usize]) -> Option<Vec<usize>> {
    let [a, b] = model.members[members[0]].nodes;
    // Start at the end of the first member that the second one does not touch.
    let first = if shared(model, members[0], members[1]) == Some(a) { b } else { a };
    let mut nodes = vec![first];
    for &m in members {
        let [p, q] = model.members[m].nodes;
        let at = *nodes.last()?;
        nodes.push(match at {
            _ if at == p => q,
            _ if at == q => p,
            _ => return None,
        });
    }
    Some(nodes)
}
