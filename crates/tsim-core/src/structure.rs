//! The hand-off between stages: a [`Structure`] (what is simulated: topology, supports,
//! laws and rest lengths, masses, damping) and a [`State`] (where it is: positions,
//! velocities, accelerations, time). Every stage takes a structure and a converged state
//! and returns the converged state it ends in.

use crate::contact::Contact;
use crate::model::clearance::Struts;
use crate::model::Model;
use crate::tsm::{Assembly, DofMap, Elements};
use nalgebra::Vector3;
use std::sync::Arc;

/// A structure as every stage sees it.
#[derive(Clone, Debug)]
pub struct Structure {
    /// Nodes, members, supports and groups.
    pub model: Model,
    /// Force law and rest length of every member.
    pub elements: Elements,
    /// Lumped mass of every node [kg]; empty for a structure that never moves
    /// dynamically (form-finding's virtual one).
    pub masses: Vec<f64>,
    /// Acceleration of gravity [m/s²]: the weight m g of every node's mass is a load in
    /// every stage (zero for none).
    pub gravity: Vector3<f64>,
    /// Nodal loads that stay on once the static stage has applied them [N per node];
    /// empty for none.
    pub dead_load: Vec<Vector3<f64>>,
    /// The struts and their radii whose clearance the stages follow (`None`: not followed).
    pub struts: Option<Arc<Struts>>,
    /// What touches what (struts, the ground) in every stage (`None`: bodies pass
    /// through each other).
    pub contact: Option<Arc<Contact>>,
}

impl Structure {
    /// A structure without mass or damping: form-finding's virtual elements.
    pub fn massless(model: Model, elements: Elements) -> Self {
        Structure {
            model,
            elements,
            masses: Vec::new(),
            gravity: Vector3::zeros(),
            dead_load: Vec::new(),
            struts: None,
            contact: None,
        }
    }

    /// Masses lumped from the members: `linear_density[m]` [kg/m] × rest length, half to
    /// each end, plus the `point_masses` of each node [kg].
    pub fn with_lumped_masses(model: Model, elements: Elements, linear_density: &[f64], point_masses: &[f64]) -> Self {
        let mut masses = lumped_masses(&model, &elements.rest, linear_density);
        masses.iter_mut().zip(point_masses).for_each(|(m, p)| *m += p);
        Structure {
            masses,
            ..Structure::massless(model, elements)
        }
    }

    /// The structure evaluated at positions `x` with rest lengths `rest` on the free DOFs of
    /// `dofs`, its contacts included: what every stage after the shape solves with.
    pub fn assembly<'a>(&'a self, dofs: &'a DofMap, x: Vec<Vector3<f64>>, rest: &[f64]) -> Assembly<'a> {
        Assembly::with_rest_lengths(&self.model, &self.elements, dofs, x, rest).with_contact(self.contact.as_ref())
    }

    /// The constant load on every node: the dead loads and the weight m g [N].
    pub fn constant_load(&self) -> Vec<Vector3<f64>> {
        let mut f = vec![Vector3::zeros(); self.model.node_count()];
        for (n, fi) in f.iter_mut().enumerate() {
            *fi = self.masses.get(n).map_or(Vector3::zeros(), |&m| self.gravity * m) + self.dead_load.get(n).copied().unwrap_or_default();
        }
        f
    }

    /// The constant load on each free DOF of `dofs` [N].
    pub fn free_load(&self, dofs: &DofMap) -> Vec<f64> {
        free_values(dofs, &self.constant_load())
    }

    /// Lumped mass on each free DOF of `dofs`.
    pub fn free_masses(&self, dofs: &DofMap) -> Vec<f64> {
        free_masses(dofs, &self.masses)
    }

    /// Strain energy of all members at positions `x` [J].
    pub fn strain_energy(&self, x: &[Vector3<f64>]) -> f64 {
        self.elements.strain_energy(&self.model, x)
    }

    /// Axial force of every member at positions `x` [N], tension positive.
    pub fn member_forces(&self, x: &[Vector3<f64>]) -> Vec<f64> {
        let mut states = Vec::new();
        crate::tsm::member_states(&self.model, &self.elements, x, &mut states);
        states.iter().map(|s| s.force).collect()
    }
}

/// Lumped masses: each member's linear density × rest length, half to each end.
pub fn lumped_masses(model: &Model, rest: &[f64], linear_density: &[f64]) -> Vec<f64> {
    let mut m = vec![0.0; model.node_count()];
    for (k, mem) in model.members.iter().enumerate() {
        let half = 0.5 * linear_density[k] * rest[k];
        m[mem.nodes[0]] += half;
        m[mem.nodes[1]] += half;
    }
    m
}

/// The free-DOF components of a per-node vector (zero for nodes past its end).
pub fn free_values(dofs: &DofMap, f: &[Vector3<f64>]) -> Vec<f64> {
    (0..dofs.len())
        .map(|i| {
            let (n, a) = dofs.owner(i);
            f.get(n).map_or(0.0, |v| v[a])
        })
        .collect()
}

/// Lumped mass on each free DOF from nodal masses.
pub fn free_masses(dofs: &DofMap, node_mass: &[f64]) -> Vec<f64> {
    (0..dofs.len()).map(|i| node_mass[dofs.owner(i).0]).collect()
}

/// A converged state of a structure, over every node (supported directions included).
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Time within the stage that produced it [s]; 0 for a static state.
    pub time: f64,
    /// Node positions [m], global frame.
    pub positions: Vec<Vector3<f64>>,
    /// Node velocities [m/s]; zero for a static state.
    pub velocities: Vec<Vector3<f64>>,
    /// Accelerations [m/s²]: informative; a transient starting from this state recomputes
    /// the acceleration consistent with its own loads and damping.
    pub accelerations: Vec<Vector3<f64>>,
    /// The members' rest lengths where a stage changed them in time (actuation) [m];
    /// `None`: the structure's own. A stage that starts from this state starts from these.
    pub rest_lengths: Option<Vec<f64>>,
}

impl State {
    /// At rest at `positions`, time 0.
    pub fn at_rest(positions: Vec<Vector3<f64>>) -> Self {
        let zeros = vec![Vector3::zeros(); positions.len()];
        State {
            time: 0.0,
            velocities: zeros.clone(),
            accelerations: zeros,
            positions,
            rest_lengths: None,
        }
    }

    /// The rest lengths a stage starting here evaluates `structure`'s members with [m].
    pub fn rest_of<'s>(&'s self, structure: &'s Structure) -> &'s [f64] {
        self.rest_lengths.as_deref().unwrap_or(&structure.elements.rest)
    }

    /// The velocity components on the free DOFs of `dofs`.
    pub fn free_velocities(&self, dofs: &DofMap) -> Vec<f64> {
        (0..dofs.len())
            .map(|i| {
                let (n, a) = dofs.owner(i);
                self.velocities[n][a]
            })
            .collect()
    }
}
