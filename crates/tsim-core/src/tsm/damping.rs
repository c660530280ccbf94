//! The stiffness-proportional term β·K of Rayleigh damping on members: the objective form
//! β (dN/dl) l̇ e with its exact Newmark Jacobian, and the paper's β K_T v by member blocks.

use super::{add_member_block, cluster, member_block, DofMap, MemberState};
use crate::law::ForceLaw;
use crate::model::{Cluster, Model};
use crate::solve::TangentSink;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// What objective damping scales a member's elastic extension rate r by: dN/dl and
/// d²N/dl² at its current length, and whether the member can push.
///
/// A tension-only member ([`ForceLaw::tension_only`]: a cable) is a Kelvin–Voigt cord that
/// cannot push: its total force N + d is max(0, N + β k r) while taut and 0 while slack,
/// so its damping force is d = max(β k r, −N) taut and 0 slack. Going slack is then
/// continuous: shortening fast, the total reaches 0 before l reaches l0 and stays 0
/// through it, so the Newmark step's residual has a kink there, not a jump. (The
/// undamped-at-l0 alternative, d = β (dN/dl) r with the current dN/dl, jumps by
/// β (EA/l0) r at l0: on a 47 × 47 steel-cable grid's deployment Newton then cycled
/// between two sides for 50 iterations, until the step was cut.) Held at −N, a member
/// dissipates −N r ≥ 0 (r < 0 there), so dissipation is never negative.
///
/// Snapping taut is the other way round: a Kelvin–Voigt cord's force jumps from 0 to
/// β k r > 0 as it reaches l0 stretching, and a step residual with that jump may have no
/// root near it, while leaving the member undamped for the step in which it snaps loses
/// the jump's impulse, an O(Δt) velocity error per snap (first order). A member slack at a
/// step's start is therefore damped within the step at the rate of its [`SnapRate`]: the
/// one whose impulse over the step is the cord's exact β k (l − l0) at the step's end, zero
/// while it stays slack and rising continuously from zero as it snaps. No event is located
/// and no step stopped; the next step starts from the damping force and acceleration just
/// after the jump (`dynamics::Newmark`).
///
/// Holding at −N is a condition on the step's impulse where the scheme weighs the
/// step's start: Newmark's velocity update takes the damping force as (1 − γ) d_n + γ d_{n+1}.
/// A cord pulling at the start (N_n + d_n > 0) and held at the end would then keep
/// (1 − γ) Δt (N_n + d_n) of pull over a step in which it shortens: negative work. Where
/// the cord's dashpot is faster than the step (β k Δt/m ≫ 1/(1 − γ)) the trapezoidal rule
/// turns its extension rate over each step, and that pull throws it back slack faster than
/// it came, step after step (a 105 × 105 grid's deployment gained 36 kJ in four steps;
/// bench/pipeline.md). So the step's equation may hold it lower, down to −N − `allowance`
/// with `allowance` = ((1 − γ)/γ)(N_n + d_n): the step's mean force (1 − γ)(N_n + d_n) +
/// γ (N + d) then never pushes, and where it is held the member shortens over the step
/// (its mean rate is negative), so its work is dissipative. Such a member is damped by
/// its dashpot through the whole step, also where it is slack at the step's end (with its
/// taut branch's modulus; N = 0 there), so that its force has no jump at l0. A step that
/// ends below −N (or pulling while slack) has carried the pull's impulse; the member's
/// own force, −N (or 0), is recorded and the next step starts from it (`dynamics::Newmark`
/// restarts the acceleration, as after a snap). Measured: tests/loads.rs
/// `a_stiffly_damped_grid_dissipates_over_every_step`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DampingModulus {
    /// dN/dl [N/m]; zero for a member slack now, unless it was at the step's start too
    /// (`snap`) or is in a Newmark step it started taut (`allowance`).
    pub stiffness: f64,
    /// d²N/dl² [N/m²].
    pub curvature: f64,
    /// The member cannot push: its damping force is held at no less than −N.
    pub tension_only: bool,
    /// Slack at the step's start: damped at this rate instead of r (`stiffness` is then its
    /// taut branch's, at l0 where it is slack now).
    pub snap: Option<SnapRate>,
    /// How far below −N the step's equation may hold the damping force [N] (≥ 0; zero
    /// but in a Newmark step whose member pulled at its start).
    pub allowance: f64,
}

/// The rate R a member slack at a step's start is damped at, β k max(0, R) along it: an
/// affine function R = a l + b r + c of its length l and elastic extension rate r at the
/// state the step's equation holds at, chosen so that Δt times the force the step's
/// velocity update weighs it with is the cord's impulse β k (l − l0) over the part of the
/// step it is taut in: the whole impulse of the jump, with no need to find where in the
/// step it falls.
/// - Newmark (equation at the step's end, velocity update weighing it by γ):
///   R = (l − l0)/(γΔt), zero as the member reaches l0.
/// - Midpoint schemes (equation at the midpoint, weighing it by 1): R = r + (l_n − l0_n)/Δt,
///   the gap at the step's start closed first: Δt R = l_{n+1} − l0_{n+1} to the step's
///   O(Δt³), zero where the member ends the step at its rest length.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SnapRate {
    /// a [1/s].
    pub per_length: f64,
    /// b [1].
    pub per_rate: f64,
    /// c [m/s].
    pub constant: f64,
}

impl SnapRate {
    /// R at length `length` and elastic extension rate `rate`.
    #[inline(always)]
    fn at(&self, length: f64, rate: f64) -> f64 {
        self.per_length * length + self.per_rate * rate + self.constant
    }
}

/// Which members are on their taut branch (not slack) at `states`: the members a step
/// damps ([`DampingModulus`]).
pub fn taut_members(laws: &[Arc<dyn ForceLaw>], rest: &[f64], states: &[MemberState], taut: &mut [bool]) {
    for (((t, s), law), &l0) in taut.iter_mut().zip(states).zip(laws).zip(rest) {
        *t = !law.slack(s.length, l0);
    }
}

/// Each member's damping modulus at `states`: zero where it is slack now or was at the
/// step's start (`taut` false; the caller gives the latter their [`SnapRate`]).
pub fn damping_moduli(laws: &[Arc<dyn ForceLaw>], rest: &[f64], states: &[MemberState], taut: &[bool], moduli: &mut [DampingModulus]) {
    for (e, (m, s)) in moduli.iter_mut().zip(states).enumerate() {
        let law = &laws[e];
        let damped = taut[e] && !law.slack(s.length, rest[e]);
        *m = DampingModulus {
            stiffness: if damped { s.stiffness } else { 0.0 },
            curvature: if damped { s.curvature } else { 0.0 },
            tension_only: law.tension_only(),
            snap: None,
            allowance: 0.0,
        };
    }
}

/// The relative velocity v_b − v_a of a member's ends from free-DOF velocities `v`.
fn relative(dofs: &DofMap, v: &[f64], [a, b]: [usize; 2]) -> Vector3<f64> {
    let value = |n: usize, ax: usize| dofs.free(n, ax).map_or(0.0, |i| v[i]);
    Vector3::new(value(b, 0) - value(a, 0), value(b, 1) - value(a, 1), value(b, 2) - value(a, 2))
}

/// Adds a member force `f` (on its second node; −f on its first) to the free DOFs of `out`.
fn scatter(dofs: &DofMap, [a, b]: [usize; 2], f: &Vector3<f64>, out: &mut [f64]) {
    for ax in 0..3 {
        if let Some(i) = dofs.free(a, ax) {
            out[i] -= f[ax];
        }
        if let Some(i) = dofs.free(b, ax) {
            out[i] += f[ax];
        }
    }
}

/// Objective stiffness-proportional damping of every member at one state: an axial force
/// β k r along each member, k its [`DampingModulus`] and r = l̇ − l (l̇0/l0) its elastic
/// extension rate: l̇ = e·(v_b − v_a), less the part a rest length changing in time takes
/// up (a cable reeled in at constant stretch strains nothing, one reeled in between fixed
/// ends is stretched at the rate l l̇0/l0). A rigid motion (v_b − v_a = ω × d) of members
/// of constant rest length has r = 0 and gets no force; the power dissipated, β k r², is
/// never negative. A tension-only member's force is held at −N (less its allowance)
/// where its total would push ([`DampingModulus`]); one slack at the step's start is
/// damped at its [`SnapRate`] R, positive only where it lengthens through l0 in the step
/// (a rigid motion leaves it slack and undamped), so that it too dissipates over the step. For small motions about
/// a state it is β K_0 v: K_T's geometric part is left out, which is what makes it
/// objective.
pub struct ObjectiveDamping<'a> {
    /// Topology: each member's end nodes.
    pub model: &'a Model,
    /// Numbering of the free DOFs of `v`.
    pub dofs: &'a DofMap,
    /// Each member at the state (length, unit vector e).
    pub states: &'a [MemberState],
    /// Each member's modulus k = dN/dl [N/m] and snap rate ([`DampingModulus`]).
    pub moduli: &'a [DampingModulus],
    /// Velocities of the free DOFs [m/s].
    pub v: &'a [f64],
    /// Rayleigh's β [s].
    pub beta: f64,
    /// l̇0/l0 of each member [1/s]; empty where no rest length changes.
    pub rest_rate: &'a [f64],
}

/// A member's elastic extension rate r = e·w − l ρ (w = v_b − v_a, ρ = l̇0/l0, zero where
/// `rest_rate` is empty).
#[inline(always)]
fn elastic_rate(s: &MemberState, w: &Vector3<f64>, rest_rate: &[f64], e: usize) -> f64 {
    s.dir.dot(w) - rest_rate.get(e).map_or(0.0, |rho| rho * s.length)
}

/// Member `e`'s elastic extension rate, the relative end velocity of any member m being
/// `w_of(m)`: its own ([`elastic_rate`]), or in a clustered cable its share (l_e/L) R of
/// the cable's rate R ([`cable_rate`]). Its modulus being dN/dl_e = (dN/dL) L/l_e at one
/// stretch, β k_e r_e is then the cable's one viscous force β (dN/dL) R on every member, and
/// a rigid motion (R = 0) damps none.
fn member_rate(model: &Model, states: &[MemberState], rest_rate: &[f64], e: usize, w_of: impl Fn(usize) -> Vector3<f64>) -> f64 {
    match model.cluster_of(e) {
        None => elastic_rate(&states[e], &w_of(e), rest_rate, e),
        Some(c) => {
            let (rate, length) = cable_rate(c, states, rest_rate, w_of);
            states[e].length / length * rate
        }
    }
}

/// A clustered cable's elastic extension rate R = L̇ − L ρ (L̇ = Σ e_i·w_i, ρ = L̇0/L0 the
/// rest rate its members share: they are actuated together, `Model::check_cluster_actuation`)
/// and its length L.
fn cable_rate(c: &Cluster, states: &[MemberState], rest_rate: &[f64], w_of: impl Fn(usize) -> Vector3<f64>) -> (f64, f64) {
    let length: f64 = c.members.iter().map(|&m| states[m].length).sum();
    let stretching: f64 = c.members.iter().map(|&m| states[m].dir.dot(&w_of(m))).sum();
    let rho = rest_rate.get(c.members[0]).copied().unwrap_or(0.0);
    (stretching - length * rho, length)
}

/// A member's axial damping force β k r at elastic extension rate `rate`, or −N where a
/// tension-only member's total N + β k r would push (−N − its allowance:
/// [`DampingModulus`]); with whether it is held there. A member snapping taut:
/// β k max(0, R), R its [`SnapRate`].
#[inline(always)]
fn axial_damping(s: &MemberState, m: &DampingModulus, beta: f64, rate: f64) -> (f64, bool) {
    if let Some(snap) = &m.snap {
        return (beta * m.stiffness * snap.at(s.length, rate).max(0.0), false);
    }
    let d = beta * m.stiffness * rate;
    if m.tension_only {
        held_at_no_compression(d, s.force + m.allowance)
    } else {
        (d, false)
    }
}

/// ∂/∂d of the axial force (N + A) e of a member held at −N − A (A its allowance, a
/// constant of the step): its tangent block ([`member_block`]) with the geometric part of
/// N + A.
fn held_block(s: &MemberState, allowance: f64) -> Matrix3<f64> {
    let p = Matrix3::identity() - s.dir * s.dir.transpose();
    member_block(s) + p * (allowance / s.length)
}

/// A tension-only member's damping force `d`, with elastic force `n`, held at −n where its
/// total n + d would push ([`DampingModulus`]); with whether it is held.
#[inline(always)]
pub fn held_at_no_compression(d: f64, n: f64) -> (f64, bool) {
    if d < -n {
        (-n, true)
    } else {
        (d, false)
    }
}

impl ObjectiveDamping<'_> {
    /// Per member: its nodes, state, damping modulus, relative velocity w = v_b − v_a and
    /// elastic extension rate ([`member_rate`]).
    fn members(&self) -> impl Iterator<Item = (usize, [usize; 2], &MemberState, &DampingModulus, Vector3<f64>, f64)> + '_ {
        let clustered = !self.model.clusters.is_empty();
        (self.model.members.iter().zip(self.states).zip(self.moduli))
            .enumerate()
            .map(move |(e, ((mem, s), m))| {
                let w = relative(self.dofs, self.v, mem.nodes);
                let rate = if clustered {
                    member_rate(self.model, self.states, self.rest_rate, e, |k| self.relative(k))
                } else {
                    elastic_rate(s, &w, self.rest_rate, e)
                };
                (e, mem.nodes, s, m, w, rate)
            })
    }

    /// Member `k`'s relative end velocity.
    fn relative(&self, k: usize) -> Vector3<f64> {
        relative(self.dofs, self.v, self.model.members[k].nodes)
    }

    /// Each member's axial damping force [N] into `out` ([`axial_damping`]).
    pub fn axial_forces(&self, out: &mut [f64]) {
        for (e, _, s, m, _, rate) in self.members() {
            out[e] = axial_damping(s, m, self.beta, rate).0;
        }
    }

    /// out += the damping force on the free DOFs.
    pub fn add_force(&self, out: &mut [f64]) {
        for (_, nodes, s, m, _, rate) in self.members() {
            let (d, _) = axial_damping(s, m, self.beta, rate);
            scatter(self.dofs, nodes, &(s.dir * d), out);
        }
    }

    /// Adds ∂/∂u of the damping force when the velocities follow the coordinates as
    /// v = c_v u + const (Newmark: c_v = γ/(βΔt)). Per member, with d = x_b − x_a, e = d/l,
    /// P = I − e eᵀ, r = e·w − l ρ its elastic extension rate and k its modulus, the block
    /// on d is β [(c_v k + (dk/dl) r − k ρ) e eᵀ + k (e (P w)ᵀ + r P)/l]: not symmetric (the
    /// e (P w)ᵀ term), so the step matrix needs a general (LU) factorization. With
    /// `symmetric` that term is replaced by its symmetric part, ½ (e (P w)ᵀ + P w eᵀ): the
    /// symmetric part of the Jacobian, which Cholesky factors (see [`Self::skew_bound`] for
    /// when it serves). A tension-only member held at d = −(N + A) e (A its allowance) has
    /// the block −k_T − A P/l ([`held_block`]), symmetric, free of v.
    /// A member snapping taut at rate R = a l + b r + c ([`SnapRate`]) has, with dR =
    /// a e + b dr, the block β [(a k + b (c_v k − k ρ) + (dk/dl) R) e eᵀ + k (b e (P w)ᵀ +
    /// R P)/l] where R > 0, none where its force is zero.
    pub fn add_jacobian(&self, c_v: f64, symmetric: bool, sink: &mut (impl TangentSink + ?Sized)) {
        for c in &self.model.clusters {
            self.add_cable_jacobian(c, c_v, symmetric, sink);
        }
        for (e, nodes, s, m, w, rate) in self.members() {
            if !self.model.clusters.is_empty() && self.model.cluster_of(e).is_some() {
                continue;
            }
            if axial_damping(s, m, self.beta, rate).1 {
                add_member_block(self.dofs, e, nodes, &-held_block(s, m.allowance), sink);
                continue;
            }
            let rho = self.rest_rate.get(e).copied().unwrap_or(0.0);
            let (damped, axial, per_rate) = match &m.snap {
                None => (rate, c_v * m.stiffness + m.curvature * rate - m.stiffness * rho, 1.0),
                Some(snap) => {
                    let damped = snap.at(s.length, rate);
                    if damped <= 0.0 {
                        continue;
                    }
                    let axial = snap.per_length * m.stiffness + snap.per_rate * (c_v - rho) * m.stiffness + m.curvature * damped;
                    (damped, axial, snap.per_rate)
                }
            };
            let ee = s.dir * s.dir.transpose();
            let p = Matrix3::identity() - ee;
            let mut turning = s.dir * (p * w).transpose();
            if symmetric {
                turning = (turning + turning.transpose()) * 0.5;
            }
            let k = (ee * (axial * self.beta)) + (turning * per_rate + p * damped) * (self.beta * m.stiffness / s.length);
            add_member_block(self.dofs, e, nodes, &k, sink);
        }
    }

    /// An upper bound of the norm of the Jacobian's skew part, β k (e (P w)ᵀ − P w eᵀ)/(2l)
    /// per member (none for a tension-only member held at −N): each member's 6 × 6 block
    /// has norm β k |P w|/l, and a row of the global matrix meets the blocks of its node's
    /// members, so max over nodes of their sum bounds it (Gershgorin). `node_sum`: a
    /// buffer, one entry per node.
    ///
    /// Why: the skew part comes from the members' turning rates |P w|/l, and against the
    /// step matrix's mass term M/(βΔt²) it is usually small (a 47 × 47 grid deploying: the
    /// bound is ~1e-2 of it); Newton with the symmetric part instead of the Jacobian then
    /// contracts by at most about bound/λ_min per iteration, and a Cholesky costs a quarter
    /// of an LU (47 × 47: 0.05 s against 0.17 s; 105 × 105: 0.44 s against 1.75 s,
    /// examples/bench_factor.rs).
    pub fn skew_bound(&self, node_sum: &mut [f64]) -> f64 {
        node_sum.fill(0.0);
        for c in &self.model.clusters {
            // The cable's skew part β k_c b (g hᵀ − h gᵀ)/2 ([`Self::add_cable_jacobian`]):
            // norm at most β k_c b |g| |h|, on every row of its nodes.
            if let Ok(cable) = self.cable(c) {
                let norm = |v: &[(usize, Vector3<f64>)]| v.iter().map(|(_, x)| x.norm_squared()).sum::<f64>().sqrt();
                let bound = (self.beta * cable.modulus * cable.per_rate).abs() * norm(&cable.g) * norm(&cable.h);
                cable.g.iter().for_each(|&(n, _)| node_sum[n] += bound);
            }
        }
        for (e, nodes, s, m, w, rate) in self.members() {
            if axial_damping(s, m, self.beta, rate).1 || (!self.model.clusters.is_empty() && self.model.cluster_of(e).is_some()) {
                continue;
            }
            let per_rate = m.snap.map_or(1.0, |snap| snap.per_rate);
            let turning = (w - s.dir * s.dir.dot(&w)).norm();
            let norm = (self.beta * m.stiffness * per_rate * turning / s.length).abs();
            for n in nodes {
                node_sum[n] += norm;
            }
        }
        node_sum.iter().fold(0.0, |a, &b| a.max(b))
    }
}

/// A clustered cable's damping at one state, for its Jacobian ([`ObjectiveDamping::cable`]).
struct Cable {
    /// g = ∂L/∂x and h = Σ B_iᵀ P_i w_i / l_i over the cable's nodes.
    g: Vec<(usize, Vector3<f64>)>,
    h: Vec<(usize, Vector3<f64>)>,
    /// k_c = dN/dL [N/m].
    modulus: f64,
    /// The damped rate D (R, or a snap rate a L + b R + c) [m/s], the factor of g gᵀ in
    /// ∂d/∂u / β, and b.
    damped: f64,
    along: f64,
    per_rate: f64,
}

impl ObjectiveDamping<'_> {
    /// The cable `c`'s figures for its Jacobian, `Err(true)` where its damping force is held
    /// at −N, `Err(false)` where it is zero (a snap rate not positive). Its members share
    /// one stretch, so its first member's modulus gives the cable's: k_c = k_1 l_1/L,
    /// dk_c/dL = k_1' (l_1/L)²; `along` leaves out the c_v term (the skew bound has none).
    fn cable(&self, c: &Cluster) -> Result<Cable, bool> {
        let first = c.members[0];
        let (s, m) = (&self.states[first], &self.moduli[first]);
        let (rate, length) = cable_rate(c, self.states, self.rest_rate, |k| self.relative(k));
        let share = s.length / length;
        if axial_damping(s, m, self.beta, share * rate).1 {
            return Err(true);
        }
        let (modulus, curvature) = (m.stiffness * share, m.curvature * share * share);
        let rho = self.rest_rate.get(first).copied().unwrap_or(0.0);
        let (damped, along, per_rate) = match &m.snap {
            None => (rate, curvature * rate - modulus * rho, 1.0),
            Some(snap) => {
                // The members' snap rates summed: a L + b R + Σ c_i.
                let constant: f64 = c.members.iter().map(|&e| self.moduli[e].snap.map_or(0.0, |r| r.constant)).sum();
                let damped = snap.per_length * length + snap.per_rate * rate + constant;
                if damped <= 0.0 {
                    return Err(false);
                }
                (
                    damped,
                    snap.per_length * modulus + curvature * damped - snap.per_rate * modulus * rho,
                    snap.per_rate,
                )
            }
        };
        let turning = |e: usize| {
            let (s, w) = (&self.states[e], self.relative(e));
            (w - s.dir * s.dir.dot(&w)) / s.length
        };
        Ok(Cable {
            g: cluster::length_gradient(self.model, c, self.states),
            h: cluster::gathered(self.model, c, turning),
            modulus,
            damped,
            along,
            per_rate,
        })
    }

    /// Adds factor · P_i/l_i on each member of `c` (L's Hessian H, by member blocks).
    fn add_hessian(&self, c: &Cluster, factor: impl Fn(&MemberState) -> f64, sink: &mut (impl TangentSink + ?Sized)) {
        for &e in &c.members {
            let s = &self.states[e];
            let p = Matrix3::identity() - s.dir * s.dir.transpose();
            add_member_block(self.dofs, e, self.model.members[e].nodes, &(p * (factor(s) / s.length)), sink);
        }
    }

    /// [`Self::add_jacobian`]'s block of a clustered cable: its force d g, d = β k_c D,
    /// has ∂/∂u = β [(k_c' D + k_c (a + b (c_v − ρ))) g gᵀ + b k_c g hᵀ + k_c D H], H the
    /// members' P_i/l_i blocks (L's Hessian); held at −N − A, −((N + A) H + (dN/dL) g gᵀ).
    fn add_cable_jacobian(&self, c: &Cluster, c_v: f64, symmetric: bool, sink: &mut (impl TangentSink + ?Sized)) {
        let cable = match self.cable(c) {
            Ok(cable) => cable,
            Err(held) => {
                if held {
                    let allowance = self.moduli[c.members[0]].allowance;
                    self.add_hessian(c, |s| -(s.force + allowance), sink);
                    let g = cluster::length_gradient(self.model, c, self.states);
                    cluster::add_outer(self.dofs, &g, &g, -cluster::series_stiffness(c, self.states), sink);
                }
                return;
            }
        };
        let beta = self.beta;
        cluster::add_outer(
            self.dofs,
            &cable.g,
            &cable.g,
            beta * (cable.along + cable.per_rate * c_v * cable.modulus),
            sink,
        );
        let skew = beta * cable.per_rate * cable.modulus;
        if symmetric {
            cluster::add_outer(self.dofs, &cable.g, &cable.h, 0.5 * skew, sink);
            cluster::add_outer(self.dofs, &cable.h, &cable.g, 0.5 * skew, sink);
        } else {
            cluster::add_outer(self.dofs, &cable.g, &cable.h, skew, sink);
        }
        self.add_hessian(c, |_| beta * cable.modulus * cable.damped, sink);
    }
}

/// factor · k for every member (k: [`member_block`]) into `blocks`: the member blocks of
/// factor · K_T(states), formed once for as many products as the states stay fixed (the
/// βK term on the last converged tangent, within a time step).
pub fn scaled_blocks(states: &[MemberState], factor: f64, blocks: &mut [Matrix3<f64>]) {
    for (b, s) in blocks.iter_mut().zip(states) {
        *b = member_block(s) * factor;
    }
}

/// out += K·v on the free DOFs, member by member (no matrix), with K's member `blocks`
/// from [`scaled_blocks`]: the βK part of paper-style Rayleigh damping.
pub fn block_product(blocks: &[Matrix3<f64>], ends: &mut EndSlots, v: &[f64], out: &mut [f64]) {
    let n = v.len();
    ends.v[..n].copy_from_slice(v);
    ends.f[..n].copy_from_slice(out);
    let (vs, fs) = (&ends.v, &mut ends.f);
    for (s, k) in ends.slots.iter().zip(blocks) {
        let w = Vector3::new(vs[s[3]] - vs[s[0]], vs[s[4]] - vs[s[1]], vs[s[5]] - vs[s[2]]);
        let f = k * w;
        for ax in 0..3 {
            fs[s[ax]] -= f[ax];
            fs[s[3 + ax]] += f[ax];
        }
    }
    out.copy_from_slice(&fs[..n]);
}

/// Each member's six end directions as indices into free-DOF vectors extended by one slot
/// (index n, the free DOF count): a fixed direction points at it, where the velocity reads
/// zero and what is added is dropped. A loop over members then gathers and scatters
/// without asking per direction whether it is free, and without per-node copies of the
/// vectors (8 % fewer instructions for the βK product on the benchmark tower, callgrind).
/// Each free entry receives its terms in member order, as before, to the last bit.
#[derive(Clone, Debug)]
pub struct EndSlots {
    slots: Vec<[usize; 6]>,
    /// The extended velocity and result (slot n: zero velocity, dropped result).
    v: Vec<f64>,
    f: Vec<f64>,
}

impl EndSlots {
    /// The slots of every member of `model` under the numbering `dofs`.
    pub fn new(model: &Model, dofs: &DofMap) -> Self {
        let spare = dofs.len();
        let slots = (model.members.iter())
            .map(|m| dofs.ends(m.nodes).map(|f| f.unwrap_or(spare)))
            .collect();
        EndSlots {
            slots,
            v: vec![0.0; spare + 1],
            f: vec![0.0; spare + 1],
        }
    }
}

/// How the β term of Rayleigh damping acts on each member.
#[derive(Clone, Copy, Debug)]
pub enum MemberDamping<'a> {
    /// [`ObjectiveDamping`]: β k r along the member, k its modulus, r its elastic extension
    /// rate (`rest_rate`: l̇0/l0 per member, empty where no rest length changes).
    Objective {
        /// Each member's modulus k = dN/dl [N/m] and snap rate ([`DampingModulus`]).
        moduli: &'a [DampingModulus],
        /// Rayleigh's β [s].
        beta: f64,
        /// l̇0/l0 of each member [1/s].
        rest_rate: &'a [f64],
    },
    /// [`block_product`]'s: the member's block of β K (from [`scaled_blocks`]) times its
    /// relative velocity.
    Blocks(&'a [Matrix3<f64>]),
    /// Given axial forces [N] along each member (the midpoint schemes' step ends:
    /// `dynamics::Newmark`).
    Axial(&'a [f64]),
}

/// out (over all 3n node directions, supported ones included) += the stiffness-proportional
/// damping force of the `members` listed at node `velocities` (zero at fixed directions),
/// the same member forces the step's equation had. Each member's force is a pair (+f, −f)
/// on its ends, so what reaches a supported direction is its share of the support's
/// reaction.
pub fn member_damping_all(
    model: &Model,
    members: &[usize],
    states: &[MemberState],
    damping: MemberDamping,
    velocities: &[Vector3<f64>],
    out: &mut [f64],
) {
    for &e in members {
        let [a, b] = model.members[e].nodes;
        let f = member_damping(model, e, states, damping, velocities);
        for ax in 0..3 {
            out[3 * a + ax] -= f[ax];
            out[3 * b + ax] += f[ax];
        }
    }
}

/// Each member's axial damping force [N], tension positive (the force a member's damping
/// adds to its elastic N), at node `velocities`: β k r for [`ObjectiveDamping`] (held at
/// −N for a tension-only member whose total would push), the projection on the member of
/// β k w for the βK variants. A βK variant's block also has a
/// transverse part (β N/l times the relative velocity across the member): a force on the
/// nodes, in their balance and the reactions, but no force of the member's.
pub fn member_axial_damping(model: &Model, states: &[MemberState], damping: MemberDamping, velocities: &[Vector3<f64>], out: &mut [f64]) {
    for (e, f) in out.iter_mut().enumerate() {
        *f = states[e].dir.dot(&member_damping(model, e, states, damping, velocities));
    }
}

/// Member `e`'s damping force on its second end [N] at node `velocities`.
fn member_damping(model: &Model, e: usize, states: &[MemberState], damping: MemberDamping, velocities: &[Vector3<f64>]) -> Vector3<f64> {
    let [a, b] = model.members[e].nodes;
    let w = velocities[b] - velocities[a];
    match damping {
        MemberDamping::Objective { moduli, beta, rest_rate } => {
            let s = &states[e];
            let rate = member_rate(model, states, rest_rate, e, |k| {
                let [a, b] = model.members[k].nodes;
                velocities[b] - velocities[a]
            });
            s.dir * axial_damping(s, &moduli[e], beta, rate).0
        }
        MemberDamping::Blocks(blocks) => blocks[e] * w,
        MemberDamping::Axial(forces) => states[e].dir * forces[e],
    }
}
