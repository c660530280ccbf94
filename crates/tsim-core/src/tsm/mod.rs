//! The common scheme of the paper: one element force equation per member
//! ([`crate::law::ForceLaw`]) and one tangent stiffness, K_T = K_G + K_0 (eqs 4, 10),
//! evaluated the same way by every stage.
//!
//! For member (i, j) with unit vector J = (x_j − x_i)/l, the internal (resisting) force is
//! p_i = −N J, p_j = +N J, and its derivative is the 6×6 block
//! [[k, −k], [−k, k]] with k = (N/l)(e − J Jᵀ) + (dN/dl) J Jᵀ:
//! the geometric part K_G keeps rigid-body rotations exact; the material part K_0 carries
//! the law's stiffness.

mod assembly;
pub mod cluster;
mod damping;
mod dofs;
mod energy_momentum;
pub mod friction;

pub use assembly::Assembly;
pub use damping::{
    block_product, damping_moduli, held_at_no_compression, member_axial_damping, member_damping_all, scaled_blocks, taut_members,
    DampingModulus, EndSlots, MemberDamping, ObjectiveDamping, SnapRate,
};
pub use dofs::DofMap;
pub use energy_momentum::{DiscreteGradient, EnergyMomentum};

use crate::law::ForceLaw;
use crate::model::Model;
use crate::solve::ordering::nested_dissection;
use crate::solve::Sparsity;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// Per-member constitutive data: the law and the non-stressed length it is evaluated with.
#[derive(Clone, Debug)]
pub struct Elements {
    /// Constitutive law of each member, in member order (shared between members).
    pub laws: Vec<Arc<dyn ForceLaw>>,
    /// Rest (non-stressed) length l0 of each member [m].
    pub rest: Vec<f64>,
}

impl Elements {
    /// Strain energy of all members at positions `x` [J].
    pub fn strain_energy(&self, model: &Model, x: &[Vector3<f64>]) -> f64 {
        let rest = self.rest_at(model, x);
        model
            .members
            .iter()
            .enumerate()
            .map(|(m, mem)| self.laws[m].energy((x[mem.nodes[1]] - x[mem.nodes[0]]).norm(), rest[m]))
            .sum()
    }

    /// The rest length each member is evaluated with at positions `x`: its own, but shared
    /// out over each clustered cable's members ([`cluster::distribute`]).
    pub fn rest_at(&self, model: &Model, x: &[Vector3<f64>]) -> std::borrow::Cow<'_, [f64]> {
        if model.clusters.is_empty() {
            return std::borrow::Cow::Borrowed(&self.rest);
        }
        let mut rest = self.rest.clone();
        cluster::distribute(model, x, &mut rest);
        std::borrow::Cow::Owned(rest)
    }
}

/// A member's state at one configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MemberState {
    /// Current length l [m].
    pub length: f64,
    /// Unit vector from the first to the second node.
    pub dir: Vector3<f64>,
    /// Axial force N [N], tension positive.
    pub force: f64,
    /// dN/dl [N/m].
    pub stiffness: f64,
    /// d²N/dl² [N/m²].
    pub curvature: f64,
}

pub use crate::solve::TangentSink;

/// Evaluates every member at positions `x` into `states` (reused buffer).
pub fn member_states(model: &Model, elements: &Elements, x: &[Vector3<f64>], states: &mut Vec<MemberState>) {
    let rest = elements.rest_at(model, x);
    states.clear();
    states.extend(model.members.iter().enumerate().map(|(m, mem)| {
        let [a, b] = mem.nodes;
        MemberState::between(x[a], x[b], &*elements.laws[m], rest[m])
    }));
}

impl MemberState {
    /// A member from `a` to `b` with force law `law` and rest length `l0`.
    #[inline(always)]
    pub fn between(a: Vector3<f64>, b: Vector3<f64>, law: &dyn ForceLaw, l0: f64) -> Self {
        let d = b - a;
        let length = d.norm();
        let e = law.eval(length, l0);
        MemberState {
            length,
            dir: d / length,
            force: e.force,
            stiffness: e.stiffness,
            curvature: e.curvature,
        }
    }
}

/// The 3×3 member block k = (N/l)(e − J Jᵀ) + (dN/dl) J Jᵀ.
pub fn member_block(s: &MemberState) -> Matrix3<f64> {
    let jj = s.dir * s.dir.transpose();
    (Matrix3::identity() - jj) * (s.force / s.length) + jj * s.stiffness
}

/// Adds K_T = K_G + K_0 over all members, on the free DOFs of `dofs`, scaled by `factor`.
pub fn assemble_tangent(model: &Model, states: &[MemberState], dofs: &DofMap, factor: f64, sink: &mut (impl TangentSink + ?Sized)) {
    assemble_tangents(model, dofs, &[(states, factor)], sink);
}

/// Adds Σ factor_t · K_T(states_t) in one pass over the members (Newmark adds the
/// current tangent and the βK damping tangent of another state together).
pub fn assemble_tangents(model: &Model, dofs: &DofMap, terms: &[(&[MemberState], f64)], sink: &mut (impl TangentSink + ?Sized)) {
    for (e, mem) in model.members.iter().enumerate() {
        let k = terms
            .iter()
            .fold(Matrix3::zeros(), |k, (states, factor)| k + member_block(&states[e]) * *factor);
        add_member_block(dofs, e, mem.nodes, &k, sink);
    }
    cluster::add_sliding(model, dofs, terms, sink);
}

/// Adds member `e`'s 6×6 block [[k, −k], [−k, k]] (k the block on its relative position)
/// on the free DOFs of its nodes.
pub fn add_member_block(dofs: &DofMap, e: usize, [a, b]: [usize; 2], k: &Matrix3<f64>, sink: &mut (impl TangentSink + ?Sized)) {
    sink.add_pair(e, &dofs.ends([a, b]), &std::array::from_fn(|r| std::array::from_fn(|c| k[(r, c)])));
}

/// K_T's shape for the sparse solver: every (row, column) of free DOFs it can fill (the
/// DOFs of each member's two nodes, pairwise, and of every two nodes of a clustered cable), eliminated node by node in a nested
/// dissection of the model's nominal geometry ([`nested_dissection`]).
pub fn tangent_sparsity<'a>(model: &'a Model, dofs: &'a DofMap) -> Sparsity<impl Iterator<Item = (usize, usize)> + 'a> {
    let free = move |n: usize| (0..3).filter_map(move |a| dofs.free(n, a));
    let pairs = move || model.members.iter().map(|m| m.nodes).chain(cluster::coupled_nodes(model));
    let entries = pairs().flat_map(move |nodes| {
        let free: Vec<usize> = nodes.iter().flat_map(|&n| free(n)).collect();
        free.iter().flat_map(|&r| free.iter().map(move |&c| (r, c))).collect::<Vec<_>>()
    });
    // The matrix's graph at node level: a node without free DOFs couples nothing.
    let mut neighbours = vec![Vec::new(); model.node_count()];
    for [a, b] in pairs() {
        if a != b && free(a).next().is_some() && free(b).next().is_some() {
            neighbours[a].push(b);
            neighbours[b].push(a);
        }
    }
    let nodes = nested_dissection(&model.positions(), &neighbours);
    Sparsity {
        entries,
        order: Some(nodes.into_iter().flat_map(free).collect()),
    }
}
