//! The element force equation over a time step, in energy–momentum form (Simo & Tarnow
//! 1992; Gonzalez 1996, "Time integration and discrete Hamiltonian systems"): for a step
//! that takes member (i, j) from vector d_a = x_j − x_i to d_b, the force on node j is
//! S d_mid (on i its opposite), d_mid = ½ (d_a + d_b), with S the discrete gradient of the
//! member's strain energy in q = l²/2:
//!
//!   S = (U(l_b) − U(l_a)) / (q_b − q_a).
//!
//! Its work over the step, S d_mid · (d_b − d_a) = S (q_b − q_a), is the strain energy's
//! change exactly, and the force is central at the midpoint: a step keeps energy and
//! angular momentum both. As d_b → d_a, S → U'(q) = N/l at l, so S d_mid is the member's
//! force N e of [`super::MemberState`]: the same element force equation as every stage,
//! averaged over the step. The midpoint rule instead takes N/l at |d_mid|, which is
//! shorter than both ends by the chord's sagitta on a rotating member (l ω²Δt²/8): a stiff
//! strut's EA turns that into force (`dynamics::Scheme`).

use super::{add_member_block, Assembly, TangentSink};
use crate::contact::StepContact;
use crate::law::ForceLaw;
use nalgebra::{Matrix3, Vector3};

/// Below this |q_b − q_a| / q̄ the quotient's cancellation, ε |U| / |Δq|, would exceed
/// Simpson's rule on U'(q) over [q_a, q_b], whose error is Δq⁴ U⁽⁵⁾/2880: at 1e-3 the rule is
/// exact to ~1e-16 of S for a smooth law and the quotient's round-off is ~2e-13 of
/// |U|/q̄ above it. A step across a tension-only member's kink at l0 takes the quotient
/// at any size: it is exact there, Simpson's rule is not.
const SIMPSON_BELOW: f64 = 1e-3;

/// S of one member over a step and its derivative in q_b = l_b²/2 [N/m, N/m³].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DiscreteGradient {
    /// The force per unit of d_mid [N/m].
    pub s: f64,
    /// ∂S/∂q_b [N/m³], for the step's tangent.
    pub ds_dqb: f64,
}

impl DiscreteGradient {
    /// The member of law `law` and rest length `l0` over a step from length `la` to `lb`.
    pub fn between(law: &dyn ForceLaw, l0: f64, la: f64, lb: f64) -> Self {
        let (qa, qb) = (0.5 * la * la, 0.5 * lb * lb);
        // As a product: l_b − l_a is exact where the lengths are close, q_b − q_a is not.
        let dq = 0.5 * (lb - la) * (lb + la);
        // U'(q) = N/l and U''(q) = (dN/dl − N/l)/l², at length l.
        let derivatives = |l: f64| {
            let e = law.eval(l, l0);
            (e.force / l, (e.stiffness - e.force / l) / (l * l))
        };
        let across_kink = law.slack(la, l0) != law.slack(lb, l0);
        let (db, ddb) = derivatives(lb);
        if dq.abs() <= SIMPSON_BELOW * 0.5 * (qa + qb) && !across_kink {
            let (da, _) = derivatives(la);
            let (dm, ddm) = derivatives((qa + qb).sqrt());
            return DiscreteGradient {
                s: (da + 4.0 * dm + db) / 6.0,
                ds_dqb: (2.0 * ddm + ddb) / 6.0,
            };
        }
        let s = (law.energy(lb, l0) - law.energy(la, l0)) / dq;
        DiscreteGradient { s, ds_dqb: (db - s) / dq }
    }
}

/// The members' energy–momentum forces over the step being solved: their vectors at its
/// start, S of each at the iterate, and the internal force they give.
pub struct EnergyMomentum {
    /// d_a of each member, at the step's start [m].
    start: Vec<Vector3<f64>>,
    gradients: Vec<DiscreteGradient>,
    /// Internal (resisting) force over all 3n directions [N], as [`Assembly::p`].
    pub p: Vec<f64>,
    /// The contacts' forces in the same form, where bodies touch.
    contact: Option<StepContact>,
}

impl EnergyMomentum {
    /// Buffers for the members and nodes of `asm`.
    pub fn new(asm: &Assembly) -> Self {
        let members = asm.model.members.len();
        EnergyMomentum {
            start: vec![Vector3::zeros(); members],
            gradients: vec![DiscreteGradient::default(); members],
            p: vec![0.0; 3 * asm.model.node_count()],
            contact: asm.contact.as_ref().map(|c| StepContact::new(c.contact.clone())),
        }
    }

    /// A step starts at the state of `asm`.
    pub fn start_step(&mut self, asm: &Assembly) {
        for (d, m) in self.start.iter_mut().zip(&asm.model.members) {
            *d = asm.x[m.nodes[1]] - asm.x[m.nodes[0]];
        }
        if let Some(c) = &mut self.contact {
            c.start_step(&asm.x);
        }
    }

    /// The forces at an iterate whose midpoint `asm` holds (positions x_{n+½}, rest
    /// lengths at the step's middle): each member's end vector is d_b = 2 d_mid − d_a.
    pub fn at_midpoint(&mut self, asm: &Assembly) {
        self.p.fill(0.0);
        let laws = asm.elements.laws.iter().zip(&asm.rest);
        let members = asm.model.members.iter().zip(&self.start).zip(&mut self.gradients);
        for (((m, da), g), (law, &l0)) in members.zip(laws) {
            let [a, b] = m.nodes;
            let mid = asm.x[b] - asm.x[a];
            *g = DiscreteGradient::between(&**law, l0, da.norm(), (2.0 * mid - da).norm());
            let f = g.s * mid;
            for k in 0..3 {
                self.p[3 * a + k] -= f[k];
                self.p[3 * b + k] += f[k];
            }
        }
        if let Some(c) = &mut self.contact {
            c.at_midpoint(&asm.x, &mut self.p);
        }
    }

    /// Internal force on free DOF `i`.
    pub fn p_free(&self, asm: &Assembly, i: usize) -> f64 {
        let (n, a) = asm.dofs.owner(i);
        self.p[3 * n + a]
    }

    /// Adds ∂(S d_mid)/∂u over the end coordinates u, at the iterate of the last
    /// [`Self::at_midpoint`]: d_mid moves at half u's rate and q_b with d_b, so the block
    /// on the member's relative position is S/2 · I + (∂S/∂q_b) d_mid d_bᵀ (not symmetric).
    pub fn add_tangent(&self, asm: &Assembly, sink: &mut (impl TangentSink + ?Sized)) {
        let members = asm.model.members.iter().zip(&self.start).zip(&self.gradients);
        for (e, ((m, da), g)) in members.enumerate() {
            let [a, b] = m.nodes;
            let mid = asm.x[b] - asm.x[a];
            let k = Matrix3::identity() * (0.5 * g.s) + mid * (2.0 * mid - da).transpose() * g.ds_dqb;
            add_member_block(asm.dofs, e, m.nodes, &k, sink);
        }
        if let Some(c) = &self.contact {
            c.add_tangent(asm.dofs, sink);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::{LinearElastic, OgdenCord};

    /// ∫ N dl from `la` to `lb` by composite Simpson's rule on 400 panels, split at l0 (a
    /// tension-only law's kink): a reference that does not use the law's energy, whose
    /// Ogden form differences W(λ) − W(1) of size Σ μ/α and so carries ~1e-14 J of round-off.
    fn work_of_force(law: &dyn ForceLaw, l0: f64, la: f64, lb: f64) -> f64 {
        let simpson = |a: f64, b: f64| {
            let n = 400;
            let h = (b - a) / n as f64;
            let weight = |i: usize| if i == 0 || i == n { 1.0 } else { [2.0, 4.0][i % 2] };
            h / 3.0 * (0..=n).map(|i| weight(i) * law.eval(a + i as f64 * h, l0).force).sum::<f64>()
        };
        if la.min(lb) < l0 && l0 < la.max(lb) {
            simpson(la, l0) + simpson(l0, lb)
        } else {
            simpson(la, lb)
        }
    }

    /// S against an independent quadrature of the force, ΔU/Δq = ∫ N dl / Δq, in both of
    /// its branches and across a tension-only kink; at a step of zero length it is N/l;
    /// ∂S/∂q_b against a central difference in q_b.
    #[test]
    fn the_discrete_gradient_is_the_energy_quotient_and_its_derivative() {
        let steel = LinearElastic {
            ea: 2.1e11 * 1e-4,
            tension_only: false,
        };
        let mut rubber = OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1);
        rubber.tension_only = true;
        let laws: [(&dyn ForceLaw, f64); 2] = [(&steel, 1.0), (&rubber, 1.0)];
        for (law, l0) in laws {
            for (la, lb) in [(1.01, 1.0100004), (1.01, 1.02), (1.2, 0.95), (1.0001, 1.00010001)] {
                let g = DiscreteGradient::between(law, l0, la, lb);
                let dq = 0.5 * (lb - la) * (lb + la);
                let reference = work_of_force(law, l0, la, lb) / dq;
                // Simpson's branch is exact to ~1e-16 of S; the quotient carries the energy's
                // round-off over Δq (≤ 1e-14 J / 5e-4 m² here); the reference's 400 panels
                // are exact to ~1e-13 of S. 1e-10 of S holds all three.
                assert!(
                    (g.s - reference).abs() <= 1e-10 * reference.abs(),
                    "{law:?} {la}→{lb}: S {:e} vs {reference:e}",
                    g.s
                );
                let h = 1e-7 * 0.5 * lb * lb;
                let at = |q: f64| DiscreteGradient::between(law, l0, la, (2.0 * q).sqrt()).s;
                let fd = (at(0.5 * lb * lb + h) - at(0.5 * lb * lb - h)) / (2.0 * h);
                // Central difference: truncation h² S''' and round-off ε S/h; 1e-4 of the
                // stiffness scale covers both (a wrong factor shows at O(1)).
                let k = law.eval(lb, l0).stiffness.abs() / (lb * lb) + g.s.abs() / (lb * lb);
                assert!(
                    (g.ds_dqb - fd).abs() <= 1e-4 * k,
                    "{law:?} {la}→{lb}: dS/dq {:e} vs {fd:e}",
                    g.ds_dqb
                );
            }
            let same = DiscreteGradient::between(law, l0, 1.05, 1.05);
            let e = law.eval(1.05, l0);
            assert!((same.s - e.force / 1.05).abs() <= 1e-14 * e.force.abs(), "{law:?}");
        }
    }
}
