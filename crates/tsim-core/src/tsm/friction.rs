//! Capstan friction on a clustered cable's pulleys ([`crate::model::Cluster::friction`]).
//! A pulley j (between the cable's members j and j + 1, the cable turning through θ_j there)
//! holds the cable while its tensions stay in the capstan cone
//! e^{−μθ_j} ≤ N_{j+1}/N_j ≤ e^{μθ_j}, and lets it slip towards the higher tension at the
//! cone's edge. Friction makes the cable's rest-length distribution history: the one of the
//! last converged step ([`Friction::commit`]) is held, and a trial state (any positions)
//! is found from it by a return map ([`Friction::slip`]): the pulleys that slip, and by how
//! much, so that every stuck pulley is in its cone and every slipping one on its edge,
//! slipping the way its tensions pull. The frictionless cable (`tsm::cluster`) is μ = 0.
//!
//! A run of members joined by slipping pulleys (a group) keeps its total rest length and
//! satisfies N_{j+1} = c_j N_j, c_j = e^{s_j μ θ_j} (s_j = ±1 the way it slips). Its
//! consistent tangent follows from those equations: δl0 = M⁻¹ E δy, y the members' lengths
//! and the pulleys' angles, so δp gains Σ_i (∂N_i/∂l0_i) (∂l_i/∂x) δl0_i — not symmetric,
//! since θ's gradient and the ratios c_j enter on one side only.

use super::cluster::{add_outer, gathered};
use super::{DofMap, Elements, MemberState, TangentSink};
use crate::model::{Cluster, Model};
use nalgebra::{DMatrix, DVector, Vector3};

/// Relative size of a tension-ratio violation (of the cable's largest tension) below which
/// a pulley counts as in its cone: a few thousand ulps, so that a state solved on the
/// cone's edge (to round-off) is not taken as past it, while 1e-12 of a tension is far
/// below any force tolerance Newton is run to.
const CONE_TOLERANCE: f64 = 1e-12;

/// The friction state of a structure's clustered cables with μ > 0.
#[derive(Clone, Debug)]
pub struct Friction {
    /// The rest lengths of the last converged step (the members of cables with friction
    /// are the ones read) [m].
    committed: Vec<f64>,
    /// ∂U/∂l0 of every member there [N] (the cables with friction's are read).
    q: Vec<f64>,
    /// Per cluster (empty for frictionless ones), per pulley: 0 stuck, ±1 slipping so that
    /// rest length runs into the next member (+1) or the previous one (−1).
    pub slip: Vec<Vec<i8>>,
}

impl Friction {
    /// The friction state of `model` committed at positions `x` and rest lengths `rest`;
    /// `None` if no cable has friction.
    pub fn new(model: &Model, elements: &Elements, x: &[Vector3<f64>], rest: &[f64]) -> Option<Self> {
        model.clusters.iter().any(|c| c.friction > 0.0).then(|| Friction {
            committed: rest.to_vec(),
            q: energy_rest_derivatives(model, elements, x, rest),
            slip: model
                .clusters
                .iter()
                .map(|c| {
                    if c.friction > 0.0 {
                        vec![0; c.members.len() - 1]
                    } else {
                        Vec::new()
                    }
                })
                .collect(),
        })
    }

    /// Takes the rest lengths `rest` at positions `x` (a converged step's) as the ones
    /// pulleys hold from. Returns the energy the pulleys' friction dissipated since the last
    /// commit [J]: −Σ q̄_i (Δl0_i − l0_i ΔL0/L0) over the cables' members, the work of the
    /// rest length the cable moved over its pulleys (q̄ the trapezoidal mean of ∂U/∂l0; the
    /// share of a winch's change of the total L0 is uniform, the winch's work).
    pub fn commit(&mut self, model: &Model, elements: &Elements, x: &[Vector3<f64>], rest: &[f64]) -> f64 {
        let q = energy_rest_derivatives(model, elements, x, rest);
        let mut dissipated = 0.0;
        for c in model.clusters.iter().filter(|c| c.friction > 0.0) {
            let total = |r: &[f64]| c.members.iter().map(|&m| r[m]).sum::<f64>();
            let reeled = total(rest) / total(&self.committed) - 1.0;
            for &m in &c.members {
                let slid = rest[m] - self.committed[m] * (1.0 + reeled);
                dissipated -= 0.5 * (self.q[m] + q[m]) * slid;
            }
        }
        self.committed.copy_from_slice(rest);
        self.q = q;
        dissipated
    }

    /// Whether any pulley slips (then the tangent is not symmetric).
    pub fn slipping(&self) -> bool {
        self.slip.iter().flatten().any(|&s| s != 0)
    }

    /// The return map: each cable with friction's rest lengths at positions `x`, from the
    /// committed ones scaled to the total `rest` holds (an actuator may have changed it),
    /// into `rest`; which pulleys slip into [`Self::slip`].
    pub fn slip(&mut self, model: &Model, elements: &Elements, x: &[Vector3<f64>], rest: &mut [f64]) {
        for (c, slip) in model.clusters.iter().zip(&mut self.slip) {
            if c.friction == 0.0 {
                continue;
            }
            let cable = Cable::at(model, elements, c, x);
            let total: f64 = c.members.iter().map(|&m| rest[m]).sum();
            let held: f64 = c.members.iter().map(|&m| self.committed[m]).sum();
            let start: Vec<f64> = c.members.iter().map(|&m| self.committed[m] * total / held).collect();
            let l0 = cable.return_map(&start, slip);
            for (&m, l0) in c.members.iter().zip(l0) {
                rest[m] = l0;
            }
        }
    }

    /// Adds `factor` × the slipping pulleys' part of the tangent at `x` (`rest` and
    /// `states` the trial's there): what their slip adds to the members' own blocks, which
    /// stuck pulleys keep.
    #[allow(clippy::too_many_arguments)]
    pub fn add_tangent(
        &self,
        (model, elements, dofs): (&Model, &Elements, &DofMap),
        x: &[Vector3<f64>],
        rest: &[f64],
        states: &[MemberState],
        factor: f64,
        sink: &mut (impl TangentSink + ?Sized),
    ) {
        for (c, slip) in model.clusters.iter().zip(&self.slip) {
            if slip.iter().all(|&s| s == 0) {
                continue;
            }
            let cable = Cable::at(model, elements, c, x);
            let l0: Vec<f64> = c.members.iter().map(|&m| rest[m]).collect();
            for group in groups(slip).filter(|(r, t)| t > r) {
                cable.add_group_tangent(&l0, slip, group, states, dofs, factor, sink);
            }
        }
    }
}

/// ∂U/∂l0 of every member at `x` with rest lengths `rest` [N].
fn energy_rest_derivatives(model: &Model, elements: &Elements, x: &[Vector3<f64>], rest: &[f64]) -> Vec<f64> {
    (model.members.iter().zip(&elements.laws).zip(rest))
        .map(|((mem, law), &l0)| law.d_energy_d_rest((x[mem.nodes[1]] - x[mem.nodes[0]]).norm(), l0))
        .collect()
}

/// The runs of members joined by slipping pulleys, as (first, last) positions in the cable.
fn groups(slip: &[i8]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let mut r = 0;
    (0..=slip.len()).filter_map(move |j| {
        if j == slip.len() || slip[j] == 0 {
            let run = (r, j);
            r = j + 1;
            Some(run)
        } else {
            None
        }
    })
}

/// One cable with friction at given positions: its members' lengths and laws, its
/// pulleys' wrap angles.
struct Cable<'a> {
    model: &'a Model,
    elements: &'a Elements,
    cluster: &'a Cluster,
    /// Member lengths, in the cable's order [m].
    length: Vec<f64>,
    /// Wrap angle θ_j at each pulley [rad].
    theta: Vec<f64>,
    /// Each pulley's θ gradient over its three nodes (before, at, after).
    theta_gradient: Vec<[Vector3<f64>; 3]>,
}

impl<'a> Cable<'a> {
    fn at(model: &'a Model, elements: &'a Elements, cluster: &'a Cluster, x: &[Vector3<f64>]) -> Self {
        let length = cluster
            .members
            .iter()
            .map(|&m| {
                let [a, b] = model.members[m].nodes;
                (x[b] - x[a]).norm()
            })
            .collect();
        let n = &cluster.nodes;
        let (theta, theta_gradient) = (1..n.len() - 1).map(|j| wrap_angle(x[n[j - 1]], x[n[j]], x[n[j + 1]])).unzip();
        Cable {
            model,
            elements,
            cluster,
            length,
            theta,
            theta_gradient,
        }
    }

    /// Force, dN/dl and dN/dl0 of the cable's member `i` at rest length `l0`.
    fn law(&self, i: usize, l0: f64) -> (f64, f64, f64) {
        let law = &self.elements.laws[self.cluster.members[i]];
        let l = self.length[i];
        let e = law.eval(l, l0);
        (e.force, e.stiffness, law.d_force_d_rest(l, l0))
    }

    /// c_j = e^{s μ θ_j}: the tension ratio N_{j+1}/N_j pulley j holds at its cone's edge `s`.
    fn ratio(&self, j: usize, s: i8) -> f64 {
        (f64::from(s) * self.cluster.friction * self.theta[j]).exp()
    }

    /// The rest lengths at these positions from `start` (the held ones), and which pulleys
    /// slip (`slip`, in/out: the active set it starts from is all stuck).
    fn return_map(&self, start: &[f64], slip: &mut [i8]) -> Vec<f64> {
        slip.fill(0);
        let mut l0 = start.to_vec();
        // Each pass changes one pulley's state; a pulley leaves the active set only when its
        // slip turned back, so twice the pulleys bounds the passes of any sane state. Should
        // a state cycle past that, the last pass's distribution stands and Newton, whose
        // residual it is, does not converge on it (the step is cut).
        for _ in 0..=2 * slip.len() + 2 {
            l0.copy_from_slice(start);
            for (r, t) in groups(slip) {
                self.solve_group(&mut l0[r..=t], r, slip);
            }
            let forces: Vec<f64> = (0..l0.len()).map(|i| self.law(i, l0[i]).0).collect();
            let scale = forces.iter().fold(0.0_f64, |a, f| a.max(f.abs()));
            // A slipping pulley whose slip ran against its tensions sticks.
            let mut run = 0.0;
            let mut changed = false;
            for j in 0..slip.len() {
                run += l0[j] - start[j];
                if slip[j] != 0 && f64::from(slip[j]) * run > CONE_TOLERANCE * start[j] {
                    slip[j] = 0;
                    changed = true;
                }
            }
            if changed {
                continue;
            }
            // The stuck pulley furthest outside its cone slips.
            let outside = (0..slip.len())
                .filter(|&j| slip[j] == 0)
                .map(|j| {
                    let c = self.ratio(j, 1);
                    let (up, down) = (forces[j + 1] - c * forces[j], forces[j] - c * forces[j + 1]);
                    (j, if up >= down { (up, 1) } else { (down, -1) })
                })
                .filter(|&(_, (v, _))| v > CONE_TOLERANCE * scale)
                .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0));
            match outside {
                Some((j, (_, s))) => slip[j] = s,
                None => break,
            }
        }
        l0
    }

    /// Solves the group of members `first..first + l0.len()` (pulleys between them slipping
    /// as `slip` says) for its rest lengths `l0` (in: the start; the group's total kept):
    /// N_{j+1} = c_j N_j, by Newton on the small system.
    fn solve_group(&self, l0: &mut [f64], first: usize, slip: &[i8]) {
        let g = l0.len();
        if g == 1 {
            return;
        }
        let total: f64 = l0.iter().sum();
        // From the held distribution Newton converges quadratically in a few iterations (the
        // equations are smooth in l0); 60 is a safety net, after which the last iterate
        // stands and the global Newton, whose residual it is, sees what is left. The stop:
        // a step of a few ulps of the longest rest length.
        for _ in 0..60 {
            let (f, m) = self.group_system(l0, first, slip);
            let size = l0.iter().fold(0.0_f64, |a, &v| a.max(v));
            let Some(step) = m.lu().solve(&(-&f)) else { return };
            let mut tau = 1.0;
            // Keep every rest length positive.
            while l0.iter().zip(step.iter()).any(|(&v, &d)| v + tau * d <= 0.0) {
                tau *= 0.5;
            }
            for (v, d) in l0.iter_mut().zip(step.iter()) {
                *v += tau * d;
            }
            if step.amax() <= 4.0 * f64::EPSILON * size {
                break;
            }
        }
        // The total is the group's invariant: remove what the iterations' round-off moved.
        let drift = (l0.iter().sum::<f64>() - total) / g as f64;
        l0.iter_mut().for_each(|v| *v -= drift);
    }

    /// The group's equations at `l0` and their Jacobian in l0: rows N_{j+1} − c_j N_j for
    /// its slipping pulleys, then Σ l0 − (the total, a constant: its residual is 0).
    fn group_system(&self, l0: &[f64], first: usize, slip: &[i8]) -> (DVector<f64>, DMatrix<f64>) {
        let g = l0.len();
        let laws: Vec<(f64, f64, f64)> = (0..g).map(|k| self.law(first + k, l0[k])).collect();
        let mut f = DVector::zeros(g);
        let mut m = DMatrix::zeros(g, g);
        for k in 0..g - 1 {
            let c = self.ratio(first + k, slip[first + k]);
            f[k] = laws[k + 1].0 - c * laws[k].0;
            m[(k, k + 1)] = laws[k + 1].2;
            m[(k, k)] = -c * laws[k].2;
        }
        m.row_mut(g - 1).fill(1.0);
        (f, m)
    }

    /// Adds `factor` × the group `(r, t)`'s slip tangent: with W = M⁻¹ (M the group's
    /// Jacobian in l0) and e_k the gradient in x of row k's right-hand side
    /// −a_{k+1} ∂l_{k+1} + c_k a_k ∂l_k + c_k s_k μ N_k ∂θ_k (a = ∂N/∂l, b = ∂N/∂l0),
    /// δl0_i = Σ_k W_ik e_k·δx, and δp = Σ_i b_i (∂l_i/∂x) δl0_i.
    #[allow(clippy::too_many_arguments)]
    fn add_group_tangent(
        &self,
        rest: &[f64],
        slip: &[i8],
        (r, t): (usize, usize),
        states: &[MemberState],
        dofs: &DofMap,
        factor: f64,
        sink: &mut (impl TangentSink + ?Sized),
    ) {
        let (_, m) = self.group_system(&rest[r..=t], r, slip);
        let Some(w) = m.try_inverse() else { return };
        let position = |m: usize| self.cluster.members.iter().position(|&k| k == m).expect("a member of its cable");
        let laws: Vec<(f64, f64, f64)> = (0..rest.len()).map(|i| self.law(i, rest[i])).collect();
        let nodes = &self.cluster.nodes;
        for k in 0..t - r {
            let j = r + k;
            // u_k = Σ_i b_i W_ik ∂l_i/∂x over the group's members.
            let u = gathered(self.model, self.cluster, |m| {
                let i = position(m);
                let coef = if (r..=t).contains(&i) { laws[i].2 * w[(i - r, k)] } else { 0.0 };
                states[m].dir * coef
            });
            let c = self.ratio(j, slip[j]);
            let mut e = gathered(self.model, self.cluster, |m| {
                let i = position(m);
                let coef = match i {
                    _ if i == j + 1 => -laws[i].1,
                    _ if i == j => c * laws[i].1,
                    _ => 0.0,
                };
                states[m].dir * coef
            });
            let turn = c * f64::from(slip[j]) * self.cluster.friction * laws[j].0;
            e.extend((0..3).map(|a| (nodes[j + a], self.theta_gradient[j][a] * turn)));
            add_outer(dofs, &u, &e, factor, sink);
        }
    }
}

/// The angle θ a cable through `a`, `p`, `b` turns through at `p` [rad], and its gradient
/// over the three nodes. θ has no gradient where the cable runs straight or turns right
/// back (sin θ = 0: θ is |angle| or π − |angle| there, not differentiable); those points get
/// none, as a one-sided choice.
fn wrap_angle(a: Vector3<f64>, p: Vector3<f64>, b: Vector3<f64>) -> (f64, [Vector3<f64>; 3]) {
    let (u, w) = (p - a, b - p);
    let (lu, lw) = (u.norm(), w.norm());
    let (d1, d2) = (u / lu, w / lw);
    let (cos, sin) = (d1.dot(&d2), d1.cross(&d2).norm());
    let theta = sin.atan2(cos);
    if sin <= f64::EPSILON {
        return (theta, [Vector3::zeros(); 3]);
    }
    let du = -(d2 - d1 * cos) / (sin * lu);
    let dw = -(d1 - d2 * cos) / (sin * lw);
    (theta, [-du, du - dw, dw])
}
