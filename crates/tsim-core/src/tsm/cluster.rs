//! Clustered cables ([`crate::model::Cluster`]) in the common scheme. A cable that slides
//! without friction over its pulley nodes has one tension N(L, L0) along its whole
//! length L = Σ l_i, L0 its rest length. Its members keep their own element force equation:
//! shared out in proportion to the members' current lengths, l0_i = L0 l_i / L, the rest
//! length gives every member the cable's stretch L/L0, so a law of the stretch alone (both
//! real laws; checked where they are assigned) gives each the cable's N, and their
//! energies l0_i w(λ) sum to the cable's. The sharing is the slip over the pulleys; the
//! total L0 is all a cluster keeps (an actuator may change it).
//!
//! The tangent is the cable's, not the members': with L's gradient g = Σ_i B_iᵀ J_i (each
//! member's unit vector J_i on its two nodes) and Hessian Σ_i B_iᵀ (e − J_i J_iᵀ)/l_i B_i,
//! K = N ∂²L/∂x² + (dN/dL) g gᵀ: the members' geometric blocks as they are, their material
//! blocks k_i J_i J_iᵀ replaced by one rank-1 term over the cable's nodes, with
//! dN/dL = 1/Σ_i (1/k_i) (the members are springs in series: 1/k_i = l0_i/(dN/dλ)).

use super::{add_member_block, DofMap, MemberState, TangentSink};
use crate::model::{Cluster, Model};
use nalgebra::{Matrix3, Vector3};

/// Shares each cluster's total rest length Σ l0_i among its members in proportion to their
/// lengths at `x` ([`self`]: the frictionless slip). Cables with friction keep theirs: a
/// state's are its own, a step's come from [`super::friction`].
pub fn distribute(model: &Model, x: &[Vector3<f64>], rest: &mut [f64]) {
    for c in model.clusters.iter().filter(|c| c.friction == 0.0) {
        let length = |m: usize| {
            let [a, b] = model.members[m].nodes;
            (x[b] - x[a]).norm()
        };
        let total_rest: f64 = c.members.iter().map(|&m| rest[m]).sum();
        let total: f64 = c.members.iter().map(|&m| length(m)).sum();
        for &m in &c.members {
            rest[m] = total_rest * length(m) / total;
        }
    }
}

/// The cable's dN/dL from its members' dN/dl_i (springs in series); zero where a member is
/// slack or unstressed-stiff (then all are: they share one stretch).
pub fn series_stiffness(c: &Cluster, states: &[MemberState]) -> f64 {
    let compliance: f64 = c.members.iter().map(|&m| 1.0 / states[m].stiffness).sum();
    if compliance.is_finite() {
        1.0 / compliance
    } else {
        0.0
    }
}

/// L's gradient over the cable's distinct nodes: Σ_i B_iᵀ J_i, as (node, 3-vector) pairs.
pub fn length_gradient(model: &Model, c: &Cluster, states: &[MemberState]) -> Vec<(usize, Vector3<f64>)> {
    gathered(model, c, |m| states[m].dir)
}

/// Σ_i B_iᵀ v_i over the cable's members (−v_i on a member's first node, +v_i on its second),
/// as (node, 3-vector) pairs over its distinct nodes.
pub fn gathered(model: &Model, c: &Cluster, v: impl Fn(usize) -> Vector3<f64>) -> Vec<(usize, Vector3<f64>)> {
    let mut g: Vec<(usize, Vector3<f64>)> = Vec::with_capacity(c.nodes.len());
    let mut add = |n: usize, v: Vector3<f64>| match g.iter_mut().find(|(k, _)| *k == n) {
        Some((_, w)) => *w += v,
        None => g.push((n, v)),
    };
    for &m in &c.members {
        let [a, b] = model.members[m].nodes;
        let vm = v(m);
        add(a, -vm);
        add(b, vm);
    }
    g
}

/// Adds Σ_pq factor · u_p w_qᵀ (both over the cable's nodes, from [`gathered`]) on the free DOFs.
pub fn add_outer(
    dofs: &DofMap,
    u: &[(usize, Vector3<f64>)],
    w: &[(usize, Vector3<f64>)],
    factor: f64,
    sink: &mut (impl TangentSink + ?Sized),
) {
    for &(p, up) in u {
        for &(q, wq) in w {
            add_node_block(dofs, [p, q], &(up * wq.transpose() * factor), sink);
        }
    }
}

/// Adds Σ_t factor_t · (the clusters' tangent less their members' own material blocks),
/// so that with every member's [`super::member_block`] already added the sink holds each
/// cable's tangent ([`self`]). A cable with friction keeps its members' blocks (pulleys
/// stuck); the [`super::friction`] state adds what its slipping pulleys change.
pub fn add_sliding(model: &Model, dofs: &DofMap, terms: &[(&[MemberState], f64)], sink: &mut (impl TangentSink + ?Sized)) {
    for c in model.clusters.iter().filter(|c| c.friction == 0.0) {
        for &(states, factor) in terms {
            for &m in &c.members {
                let s = &states[m];
                let k = s.dir * s.dir.transpose() * (-factor * s.stiffness);
                add_member_block(dofs, m, model.members[m].nodes, &k, sink);
            }
            let k = factor * series_stiffness(c, states);
            if k != 0.0 {
                let g = length_gradient(model, c, states);
                add_outer(dofs, &g, &g, k, sink);
            }
        }
    }
}

/// Adds the 3×3 block `k` at rows of node `p` and columns of node `q`, on their free DOFs.
fn add_node_block(dofs: &DofMap, [p, q]: [usize; 2], k: &Matrix3<f64>, sink: &mut (impl TangentSink + ?Sized)) {
    for r in 0..3 {
        let Some(row) = dofs.free(p, r) else { continue };
        for c in 0..3 {
            if let Some(col) = dofs.free(q, c) {
                sink.add(row, col, k[(r, c)]);
            }
        }
    }
}

/// The pairs of nodes a cluster couples beyond its members' own: every two of its nodes.
pub fn coupled_nodes(model: &Model) -> impl Iterator<Item = [usize; 2]> + '_ {
    model.clusters.iter().flat_map(|c| {
        let n = &c.nodes;
        (0..n.len()).flat_map(move |i| (i + 1..n.len()).map(move |j| [n[i], n[j]]).filter(|[p, q]| p != q))
    })
}
