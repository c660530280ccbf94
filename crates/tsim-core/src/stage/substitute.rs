//! Substitution by real materials (paper §3.1, end): each member gets the rest length at
//! which its real law carries the form-found force at the form-found length, so the real
//! structure is in equilibrium in the same shape.

use super::eigen::lowest_stiffness;
use crate::error::{Error, Result};
use crate::law::ForceLaw;
use crate::model::clearance::{Search, Struts};
use crate::model::{MemberKind, Model};
use crate::solve::{SparseSolver, Sparsity, TangentSink, TangentSolver};
use crate::structure::{State, Structure};
use crate::tsm::{Assembly, DofMap, Elements};
use faer::linalg::solvers::Solve;
use faer::Mat;
use nalgebra::Vector3;
use std::sync::Arc;

/// The real materials of every member.
#[derive(Clone, Debug)]
pub struct Materials {
    /// Real constitutive law of each member, in member order.
    pub laws: Vec<Arc<dyn ForceLaw>>,
    /// Mass per unit rest length [kg/m] (density × area, in the chosen mass reading).
    pub linear_density: Vec<f64>,
    /// Point mass of every node [kg] (empty: none).
    pub point_masses: Vec<f64>,
    /// Radius of every member as a solid round bar of its cross-section, √(A/π) [m]: what
    /// strut clearance is measured with.
    pub radius: Vec<f64>,
}

impl Materials {
    /// The real structure with `rest` lengths, masses lumped from the members, its
    /// struts' clearance followed; an error where a clustered cable's members differ in
    /// material or have a law that cannot share one tension ([`check_clusters`]).
    pub fn structure(&self, model: &Model, rest: Vec<f64>) -> Result<Structure> {
        check_clusters(model, &self.laws)?;
        let elements = Elements {
            laws: self.laws.clone(),
            rest,
        };
        Ok(Structure {
            struts: Some(Arc::new(Struts::new(model, &self.radius, Search::Auto))),
            ..Structure::with_lumped_masses(model.clone(), elements, &self.linear_density, &self.point_masses)
        })
    }

    /// Substitution: the real structure that carries `scale` × the form-found `forces`
    /// (balanced, see [`balanced_forces`]) in the form-found shape `found`.
    pub fn substitute(&self, model: &Model, found: &State, forces: &[f64], scale: f64) -> Result<Structure> {
        let forces = cluster_tensions(model, forces)?;
        let sub = substitute(model, &found.positions, &forces, self.laws.clone(), scale)?;
        self.structure(model, sub.elements.rest)
    }
}

/// A clustered cable's members must have one material, of a law of the stretch alone
/// (`tsm::cluster`): the error names the member that does not.
pub fn check_clusters(model: &Model, laws: &[Arc<dyn ForceLaw>]) -> Result<()> {
    for c in &model.clusters {
        let first = &laws[c.members[0]];
        for &m in &c.members {
            let reason = if !Arc::ptr_eq(&laws[m], first) {
                format!(
                    "in cluster `{}` it has another material than `{}`; one cable is one material, assign the same to all its members",
                    c.id, model.members[c.members[0]].id
                )
            } else if !laws[m].of_stretch() {
                format!("in cluster `{}` its {} law is not a law of the stretch l/l0, so the cable's members cannot share one tension; use an elastic or Ogden material", c.id, laws[m].name())
            } else {
                continue;
            };
            return Err(Error::Substitution {
                member: model.members[m].id.clone(),
                reason,
            });
        }
    }
    Ok(())
}

/// The form-found `forces` with each clustered cable's members given their mean, or the
/// error where they differ by more than 1e-6 of the largest: a cable that slides freely
/// carries one tension, so a layout whose form-found members in it do not is not in
/// equilibrium clustered (a converged form-finding's forces are balanced to ~1e-10 of the
/// force level, far inside this).
pub fn cluster_tensions(model: &Model, forces: &[f64]) -> Result<Vec<f64>> {
    let mut out = forces.to_vec();
    for c in &model.clusters {
        let of = |m: &usize| forces[*m];
        let (lo, hi) = c
            .members
            .iter()
            .map(of)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), f| (a.min(f), b.max(f)));
        if hi - lo > 1e-6 * lo.abs().max(hi.abs()) {
            let at = |f: f64| {
                c.members
                    .iter()
                    .find(|m| of(m) == f)
                    .map_or(String::new(), |&m| model.members[m].id.clone())
            };
            return Err(Error::Substitution {
                member: at(lo),
                reason: format!(
                    "cluster `{}` slides freely, so all its members carry one tension, but the form-found forces differ ({lo:.6e} N here, {hi:.6e} N in `{}`); cluster only cables of one form-found force (one member group of a symmetric layout), or leave them separate",
                    c.id,
                    at(hi)
                ),
            });
        }
        let mean = c.members.iter().map(of).sum::<f64>() / c.members.len() as f64;
        c.members.iter().for_each(|&m| out[m] = mean);
    }
    Ok(out)
}

/// How the real structure stands in its equilibrium shape.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SubstitutionSummary {
    /// Out-of-balance of the real-material structure at the form-found shape [N].
    pub residual: f64,
    /// Largest |member force| [N].
    pub max_force: f64,
    /// Cable stretch λ = l/l0 range after substitution.
    pub cable_stretch: [f64; 2],
    /// Lowest eigenvalue of K_T (free DOFs) [N/m] and where it acts.
    pub lowest_stiffness: f64,
    /// The direction its eigenvector moves most ("node `t3` direction z").
    pub lowest_stiffness_at: String,
    /// K_T positive definite beyond round-off (`stability` is `stable`).
    pub stable: bool,
    /// Whether K_T is positive definite, as far as round-off can tell ([`Verdict`]).
    #[serde(default)]
    pub stability: Verdict,
    /// The band about zero in which round-off decides the lowest eigenvalue's sign, ± this
    /// [N/m] ([`LowestStiffness::band`](super::eigen::LowestStiffness::band)).
    #[serde(default)]
    pub stiffness_roundoff: f64,
    /// Sum of the lumped nodal masses [kg].
    pub total_mass: f64,
}

impl SubstitutionSummary {
    /// Balance, forces, cable stretch, stability and mass of `structure` at `state`.
    pub fn new(structure: &Structure, state: &State) -> Result<Self> {
        let model = &structure.model;
        let dofs = DofMap::new(model, &model.gauge());
        let asm = Assembly::new(model, &structure.elements, &dofs, state.positions.clone());
        let stretch = model
            .members
            .iter()
            .zip(&asm.states)
            .zip(&structure.elements.rest)
            .filter(|((m, _), _)| m.kind == MemberKind::Cable)
            .map(|((_, s), l0)| s.length / l0);
        let lowest = lowest_stiffness(&asm)?;
        let stability = Verdict::of(lowest.value, lowest.band);
        Ok(SubstitutionSummary {
            residual: asm.max_free_residual(),
            max_force: asm.states.iter().map(|s| s.force.abs()).fold(0.0, f64::max),
            cable_stretch: stretch.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], l| [lo.min(l), hi.max(l)]),
            lowest_stiffness: lowest.value,
            lowest_stiffness_at: lowest.at,
            stable: stability == Verdict::Stable,
            stability,
            stiffness_roundoff: lowest.band,
            total_mass: structure.masses.iter().sum(),
        })
    }

    /// An error for a structure not known to be stable, unless `allowed`: the dynamic
    /// stages would run about a state that may not be an equilibrium one can stay in
    /// (eigen analysis gives imaginary frequencies and the Rayleigh α, β from them are
    /// NaN). `formfound`: the prestress came from form-finding, so `prestress_scale` raises it.
    pub fn require_stable(&self, allowed: bool, formfound: bool) -> Result<()> {
        if self.stable || allowed {
            return Ok(());
        }
        let (lowest, at, band) = (self.lowest_stiffness, &self.lowest_stiffness_at, self.stiffness_roundoff);
        let what = match self.stability {
            Verdict::Indeterminate => format!(
                "the real structure's stability is indeterminate at round-off: the lowest eigenvalue of K_T, {lowest:.3e} N/m \
                 at {at}, lies within ±{band:.1e} N/m, where round-off on K_T's largest entries decides its sign; that motion \
                 is held, if at all, by a stiffness too small to resolve"
            ),
            _ => format!("the real structure is not stable: lowest eigenvalue of K_T {lowest:.3e} N/m (round-off ±{band:.1e}), at {at}"),
        };
        let remedy = if formfound {
            "raise the prestress (`substitution.prestress_scale`: the geometric stiffness grows with it), change the materials"
        } else {
            "raise the self-stress (shorter cable rest lengths), add members or supports that hold that motion"
        };
        Err(Error::Stage {
            stage: "substitution".into(),
            reason: format!("{what}; {remedy}, or set `substitution.allow_unstable: true` to run anyway"),
        })
    }
}

/// Whether K_T at an equilibrium is positive definite, as far as round-off can tell.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The lowest eigenvalue is above the round-off band.
    #[default]
    Stable,
    /// It lies within the band: round-off, not the structure, decides its sign.
    Indeterminate,
    /// It lies below the band: some motion loses stiffness.
    Unstable,
}

impl Verdict {
    /// The verdict on a lowest eigenvalue `lowest` with round-off band ±`band` [N/m].
    pub fn of(lowest: f64, band: f64) -> Self {
        if lowest > band {
            Verdict::Stable
        } else if lowest >= -band {
            Verdict::Indeterminate
        } else {
            Verdict::Unstable
        }
    }
}

/// Member forces of a form-found shape, made to balance exactly.
///
/// A form-finding strut is a virtual spring of stiffness EA/l0 ≈ 3e10 N/m: one ulp of its
/// length is ~1e-4 N of force, so the forces the laws give at the converged shape leave an
/// out-of-balance of that size however far Newton iterates. The soft cables' forces are
/// exact to round-off. So the strut forces are recovered from statics: the correction δ
/// that minimises |A_s δ + r| (A_s the struts' columns of the equilibrium matrix on the
/// free DOFs, r the out-of-balance), a small normal-equations solve (one unknown per strut).
pub fn balanced_forces(model: &Model, positions: &[Vector3<f64>], forces: &[f64]) -> Vec<f64> {
    let dofs = DofMap::new(model, &model.gauge());
    let struts: Vec<usize> = (0..model.members.len())
        .filter(|&m| model.members[m].kind == MemberKind::Strut)
        .collect();
    if struts.is_empty() {
        return forces.to_vec();
    }
    if struts.len() > DENSE_BALANCE_LIMIT {
        return sparse_balanced_forces(model, &dofs, positions, forces, &struts);
    }
    // Column of member m: ∂p/∂N_m = −J at its first node, +J at its second.
    let mut a = Mat::<f64>::zeros(dofs.len(), struts.len());
    let mut r = Mat::<f64>::zeros(dofs.len(), 1);
    for (m, mem) in model.members.iter().enumerate() {
        let d = positions[mem.nodes[1]] - positions[mem.nodes[0]];
        let j = d / d.norm();
        let col = struts.iter().position(|&s| s == m);
        for (node, sign) in [(mem.nodes[0], -1.0), (mem.nodes[1], 1.0)] {
            for ax in 0..3 {
                if let Some(i) = dofs.free(node, ax) {
                    r[(i, 0)] += sign * j[ax] * forces[m];
                    if let Some(c) = col {
                        a[(i, c)] += sign * j[ax];
                    }
                }
            }
        }
    }
    let normal = a.transpose() * &a;
    let mut delta = -(a.transpose() * &r);
    normal.partial_piv_lu().solve_in_place(delta.as_mut());
    let mut out = forces.to_vec();
    for (c, &m) in struts.iter().enumerate() {
        out[m] += delta[(c, 0)];
    }
    out
}

/// Most struts whose normal equations are solved densely (a struts² matrix: 600 struts,
/// 2.9 MB); every model measured before the sparse path stays below, its results unchanged.
const DENSE_BALANCE_LIMIT: usize = 600;

/// [`balanced_forces`] for many struts: the normal matrix A_sᵀA_s couples two struts only
/// through a free DOF they share, so it is assembled per node and solved by sparse
/// Cholesky (A_s has full column rank when no strut is free to turn alone).
fn sparse_balanced_forces(model: &Model, dofs: &DofMap, positions: &[Vector3<f64>], forces: &[f64], struts: &[usize]) -> Vec<f64> {
    let mut column = vec![usize::MAX; model.members.len()];
    struts.iter().enumerate().for_each(|(c, &m)| column[m] = c);
    // Per node, the struts there with ∂p/∂N at the node (−J at the first end, +J at the second).
    let mut at_node: Vec<Vec<(usize, Vector3<f64>)>> = vec![Vec::new(); model.node_count()];
    let mut r = vec![0.0; dofs.len()];
    for (m, mem) in model.members.iter().enumerate() {
        let d = positions[mem.nodes[1]] - positions[mem.nodes[0]];
        let j = d / d.norm();
        for (node, sign) in [(mem.nodes[0], -1.0), (mem.nodes[1], 1.0)] {
            for ax in 0..3 {
                if let Some(i) = dofs.free(node, ax) {
                    r[i] += sign * j[ax] * forces[m];
                }
            }
            if column[m] != usize::MAX {
                at_node[node].push((column[m], sign * j));
            }
        }
    }
    let pattern = at_node
        .iter()
        .flat_map(|s| s.iter().flat_map(move |&(a, _)| s.iter().map(move |&(b, _)| (a, b))));
    let mut solver = SparseSolver::new(struts.len(), Sparsity::amd(pattern));
    let mut rhs = vec![0.0; struts.len()];
    for (node, incident) in at_node.iter().enumerate() {
        let free: Vec<(usize, usize)> = (0..3).filter_map(|ax| dofs.free(node, ax).map(|i| (ax, i))).collect();
        for &(a, ja) in incident {
            for &(ax, i) in &free {
                rhs[a] -= ja[ax] * r[i];
            }
            for &(b, jb) in incident {
                solver.add(a, b, free.iter().map(|&(ax, _)| ja[ax] * jb[ax]).sum());
            }
        }
    }
    let solved = solver.factor(true).and_then(|()| solver.solve(&mut rhs));
    let mut out = forces.to_vec();
    if solved.is_ok() {
        struts.iter().zip(&rhs).for_each(|(&m, delta)| out[m] += delta);
    }
    out
}

/// Real-material elements and how well they balance at the form-found shape.
#[derive(Clone, Debug)]
pub struct Substituted {
    /// The real laws with the rest lengths found.
    pub elements: Elements,
    /// max |out-of-balance force| on the free DOFs at the form-found shape [N].
    pub residual: f64,
    /// Largest |member force| [N], the scale of `residual`.
    pub max_force: f64,
}

/// Rest lengths for `laws` so that member m carries `scale · forces[m]` at the lengths of
/// `positions`; then the equilibrium residual of the result.
pub fn substitute(
    model: &Model,
    positions: &[Vector3<f64>],
    forces: &[f64],
    laws: Vec<Arc<dyn ForceLaw>>,
    scale: f64,
) -> Result<Substituted> {
    let mut rest = Vec::with_capacity(model.members.len());
    for (m, mem) in model.members.iter().enumerate() {
        let l = (positions[mem.nodes[1]] - positions[mem.nodes[0]]).norm();
        let l0 = rest_length(laws[m].as_ref(), l, scale * forces[m]).map_err(|reason| Error::Substitution {
            member: mem.id.clone(),
            reason,
        })?;
        rest.push(l0);
    }
    let elements = Elements { laws, rest };
    let dofs = DofMap::new(model, &model.gauge());
    let asm = Assembly::new(model, &elements, &dofs, positions.to_vec());
    let residual = asm.max_free_residual();
    let max_force = asm.states.iter().map(|s| s.force.abs()).fold(0.0, f64::max);
    Ok(Substituted {
        elements,
        residual,
        max_force,
    })
}

/// Solves N(l, l0) = target for l0 by Newton safeguarded with a bracket. Every law here
/// has N decreasing in l0 (a longer rest length means less tension), so the bracket is
/// found by halving or doubling l0 from l, where N is about zero.
pub fn rest_length(law: &dyn ForceLaw, l: f64, target: f64) -> std::result::Result<f64, String> {
    let f = |l0: f64| law.eval(l, l0).force - target;
    let (mut lo, mut hi) = (l, l);
    // 200 halvings/doublings reach any l0 in (l·1e-60, l·1e60): a failure here means the
    // law cannot carry the target force at this length at all.
    let mut found = false;
    for _ in 0..200 {
        if f(lo) >= 0.0 && f(hi) <= 0.0 {
            found = true;
            break;
        }
        if f(lo) < 0.0 {
            lo *= 0.5;
        }
        if f(hi) > 0.0 {
            hi *= 2.0;
        }
    }
    if !found {
        return Err(format!(
            "the {} law cannot carry {target:.6e} N at length {l:.6} m for any rest length (a tension-only member asked for compression?)",
            law.name()
        ));
    }
    let tol = 1e-14 * target.abs().max(1e-300);
    let mut l0 = 0.5 * (lo + hi);
    for _ in 0..200 {
        let r = f(l0);
        if r.abs() <= tol || hi - lo <= 4.0 * f64::EPSILON * hi {
            return Ok(l0);
        }
        if r > 0.0 {
            lo = l0;
        } else {
            hi = l0;
        }
        let step = l0 - r / law.d_force_d_rest(l, l0);
        l0 = if step > lo && step < hi { step } else { 0.5 * (lo + hi) };
    }
    Ok(l0)
}
