//! Rayleigh damping within a Newmark stage: the αM term and the βK term, each way of
//! evaluating βK with the state it keeps between steps and iterates.

use super::{DampingTangent, Rayleigh};
use crate::solve::{TangentSink, REUSE_CONTRACTION};
use crate::tsm::{
    assemble_tangents, block_product, damping_moduli, member_axial_damping, member_damping_all, scaled_blocks, taut_members, Assembly,
    DampingModulus, EndSlots, MemberDamping, MemberState, ObjectiveDamping, SnapRate,
};
use nalgebra::{Matrix3, Vector3};

/// Largest estimated contraction per Newton iteration, ‖S‖/λ_min, for which a step with
/// objective damping is solved with the symmetric part of its Jacobian (Cholesky) instead of
/// the whole (LU); S is the skew part ([`ObjectiveDamping::skew_bound`], a Gershgorin bound) and
/// λ_min ≥ min m (1/(βΔt²) + α γ/(βΔt)), the step matrix's mass term (K_T's part taken as
/// non-negative). The same contraction a held factorization must show to be kept
/// ([`REUSE_CONTRACTION`]): an iteration matrix that is at least that close to the Jacobian
/// is as good as a reused one. The residual is exact, so converged states meet the same
/// tolerances; where the iteration converges more slowly than estimated (a step through an
/// unstable state), a step that fails is cut, which shrinks the estimate 4-fold per halving.
/// (Measured gains: bench/pipeline.md.)
pub(super) const SYMMETRIC_CONTRACTION: f64 = REUSE_CONTRACTION;

/// Rayleigh damping C v = α M v + (the β term) of one stage.
pub(super) struct Viscous {
    pub(super) rayleigh: Rayleigh,
    pub(super) term: StiffnessTerm,
}

/// The β term, by [`DampingTangent`].
pub(super) enum StiffnessTerm {
    Objective(Objective),
    Tangent(TangentTerm),
}

/// How a step's equation damps a member snapping taut within it ([`SnapRate`]), by the
/// scheme: where its equation holds and how its velocity update weighs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum SnapRule {
    /// Newmark, the equation at the step's end weighed by γ: R = (l − l0)/(γΔt); a held
    /// member's allowance is `carry` = (1 − γ)/γ times its total force at the step's start
    /// ([`DampingModulus`]).
    AtEnd { gamma_dt: f64, carry: f64 },
    /// A midpoint scheme: R = r + (l_n − l0_n)/Δt.
    AtMidpoint { dt: f64 },
}

impl SnapRule {
    /// The rate of a member of rest length `rest` (at the equation's time) whose l − l0 was
    /// `start_gap` at the step's start.
    fn rate(self, rest: f64, start_gap: f64) -> SnapRate {
        match self {
            SnapRule::AtEnd { gamma_dt, .. } => SnapRate {
                per_length: 1.0 / gamma_dt,
                per_rate: 0.0,
                constant: -rest / gamma_dt,
            },
            SnapRule::AtMidpoint { dt } => SnapRate {
                per_length: 0.0,
                per_rate: 1.0,
                constant: start_gap / dt,
            },
        }
    }
}

/// β (dN/dl) r e per member, r its elastic extension rate ([`ObjectiveDamping`]).
pub(super) struct Objective {
    /// Per member, whether it was taut at the step's start (a tension-only member slack
    /// then is damped at its [`SnapRate`] in the step), and its damping modulus at the
    /// current states ([`DampingModulus`]).
    taut: Vec<bool>,
    /// The flags of the step before, to see which members start to be damped on their
    /// taut branch at this step's start, and those members ([`Viscous::newly_taut`];
    /// room for all, so that no step allocates).
    was_taut: Vec<bool>,
    newly_taut: Vec<usize>,
    /// Per member, l − l0 at the step's start [m] (negative where slack).
    start_gap: Vec<f64>,
    /// Per member, how far below −N the step may hold its damping force
    /// ([`DampingModulus`]), and two buffers of the members' damping forces.
    allowance: Vec<f64>,
    axial: [Vec<f64>; 2],
    /// Whether members taut at the step's start are damped through it as taut, with their
    /// allowance (a Newmark step, until [`Viscous::release`]).
    through: bool,
    /// The step's [`SnapRule`]; `None` until a step starts.
    snap: Option<SnapRule>,
    pub(super) moduli: Vec<DampingModulus>,
    /// Whether the step matrix last assembled is the Jacobian's symmetric part, the
    /// largest estimated contraction for which it may be ([`SYMMETRIC_CONTRACTION`]), and
    /// a per-node buffer of the estimate.
    symmetric_step: bool,
    pub(super) symmetric_below: f64,
    node_skew: Vec<f64>,
}

/// β K_T(x)·v with K_T at the states `which` names (the paper's variants).
pub(super) struct TangentTerm {
    which: DampingTangent,
    /// The member states of `Initial` and `LastConverged` (`Current` uses the iterate's).
    states: Vec<MemberState>,
    /// β k per member of those states ([`scaled_blocks`]): re-formed when the states change,
    /// not at every residual.
    pub(super) blocks: Vec<Matrix3<f64>>,
    /// The members' free end directions, for the βK product.
    ends: EndSlots,
}

impl Viscous {
    /// Damping `rayleigh` by `tangent`, starting at the state of `asm`.
    pub(super) fn new(rayleigh: Rayleigh, tangent: DampingTangent, asm: &Assembly) -> Self {
        let members = asm.states.len();
        let term = match tangent {
            DampingTangent::Objective => StiffnessTerm::Objective(Objective {
                taut: vec![true; members],
                was_taut: vec![true; members],
                newly_taut: Vec::with_capacity(members),
                start_gap: vec![0.0; members],
                allowance: vec![0.0; members],
                axial: [vec![0.0; members], vec![0.0; members]],
                through: false,
                snap: None,
                moduli: vec![DampingModulus::default(); members],
                symmetric_step: false,
                symmetric_below: SYMMETRIC_CONTRACTION,
                node_skew: vec![0.0; asm.model.node_count()],
            }),
            which => StiffnessTerm::Tangent(TangentTerm {
                which,
                states: if which == DampingTangent::Current {
                    Vec::new()
                } else {
                    asm.states.clone()
                },
                blocks: vec![Matrix3::zeros(); members],
                ends: EndSlots::new(asm.model, asm.dofs),
            }),
        };
        let mut viscous = Viscous { rayleigh, term };
        match &mut viscous.term {
            StiffnessTerm::Objective(o) => {
                o.keep_taut(asm);
            }
            StiffnessTerm::Tangent(t) => t.form_blocks(rayleigh.beta, asm),
        }
        viscous
    }

    /// At the start of a step, `asm` at the last converged state, the step's equation
    /// damping a member snapping taut within it by `snap`: `LastConverged` takes its K_T,
    /// objective damping notes which members are slack (damped at their [`SnapRate`] for
    /// the step). Taken here, not at the end of the previous step, so that between steps the
    /// term is still the one the last converged equation used ([`Self::member_force`]).
    /// Whether some member is damped on its taut branch now that the last equation damped
    /// at its snap rate ([`Self::newly_taut`]): the damping force jumps at the step's start,
    /// and the step should start from the acceleration just after the jump.
    /// A Newmark step also gives each member pulling at its start, at velocities `v`, its
    /// allowance ([`DampingModulus`]).
    pub(super) fn start_step(&mut self, asm: &Assembly, snap: SnapRule, v: &[f64], rest_rate: &[f64]) -> bool {
        let beta = self.rayleigh.beta;
        match &mut self.term {
            StiffnessTerm::Objective(o) => {
                o.snap = Some(snap);
                o.through = matches!(snap, SnapRule::AtEnd { .. });
                let jumped = o.keep_taut(asm) && beta != 0.0;
                if let SnapRule::AtEnd { carry, .. } = snap {
                    o.allow(asm, v, beta, rest_rate, carry);
                }
                jumped
            }
            StiffnessTerm::Tangent(t) if t.which == DampingTangent::LastConverged => {
                t.states.copy_from_slice(&asm.states);
                t.form_blocks(self.rayleigh.beta, asm);
                false
            }
            StiffnessTerm::Tangent(_) => false,
        }
    }

    /// At the end of a converged Newmark step, `v` its velocities: ends the members'
    /// damping through the step and their allowances, so that the member forces are the
    /// members' own (−N where the equation held one lower, zero where one taut at the
    /// step's start ended it slack: that force was the step's impulse, [`DampingModulus`]);
    /// whether one differs from the force the equation had, so that the next step should
    /// start from the members' own.
    pub(super) fn release(&mut self, asm: &Assembly, v: &[f64], rest_rate: &[f64]) -> bool {
        let beta = self.rayleigh.beta;
        let StiffnessTerm::Objective(o) = &mut self.term else {
            return false;
        };
        if !o.through {
            return false;
        }
        let [mut held, mut own] = std::mem::take(&mut o.axial);
        o.at(asm, v, beta, rest_rate).axial_forces(&mut held);
        o.through = false;
        o.allowance.fill(0.0);
        o.update_moduli(asm);
        o.at(asm, v, beta, rest_rate).axial_forces(&mut own);
        let differ = held.iter().zip(&own).any(|(a, b)| a != b);
        o.axial = [held, own];
        differ
    }

    /// The members [`Self::start_step`] found taut that were slack at the step before's.
    pub(super) fn newly_taut(&self) -> &[usize] {
        match &self.term {
            StiffnessTerm::Objective(o) => &o.newly_taut,
            StiffnessTerm::Tangent(_) => &[],
        }
    }

    /// Whether member `e` is damped at its [`SnapRate`] in the step (slack at its start).
    pub(super) fn snapping(&self, e: usize) -> bool {
        matches!(&self.term, StiffnessTerm::Objective(o) if o.moduli[e].snap.is_some())
    }

    /// Whether some member slack at the step's start is taut at `asm`'s state (the step's
    /// end): its damping force jumped inside the step.
    pub(super) fn snapped(&self, asm: &Assembly) -> bool {
        let laws = &asm.elements.laws;
        (0..asm.states.len()).any(|e| self.snapping(e) && !laws[e].slack(asm.states[e].length, asm.rest[e]))
    }

    /// At a new iterate of `asm`: `Current` re-forms its blocks, objective damping its moduli.
    pub(super) fn at_iterate(&mut self, asm: &Assembly) {
        match &mut self.term {
            StiffnessTerm::Objective(o) => o.update_moduli(asm),
            StiffnessTerm::Tangent(t) if t.which == DampingTangent::Current => t.form_blocks(self.rayleigh.beta, asm),
            StiffnessTerm::Tangent(_) => {}
        }
    }

    /// The damping force α M v + the β term on the free DOFs at velocities `v` into `out`;
    /// `rest_rate`: l̇0/l0 per member (empty where no rest length changes).
    pub(super) fn force(&mut self, asm: &Assembly, mass: &[f64], v: &[f64], rest_rate: &[f64], out: &mut [f64]) {
        for i in 0..v.len() {
            out[i] = self.rayleigh.alpha * mass[i] * v[i];
        }
        match &mut self.term {
            StiffnessTerm::Objective(o) => o.at(asm, v, self.rayleigh.beta, rest_rate).add_force(out),
            StiffnessTerm::Tangent(t) => block_product(&t.blocks, &mut t.ends, v, out),
        }
    }

    /// K_T of `asm` (unless `elastic` is false: the energy–momentum form brings its own)
    /// and the β term's derivative in the step matrix, c_v = γ/(βΔt) the velocity's
    /// derivative: β c_v K_T(damping states) for the paper's variants (for `Current` less
    /// ∂K_T/∂x · v), the exact objective block otherwise, or its symmetric part where the
    /// skew part is small against `mass_term` (the step matrix's least mass entry).
    pub(super) fn assemble_tangent(
        &mut self,
        asm: &Assembly,
        v: &[f64],
        rest_rate: &[f64],
        (c_v, mass_term): (f64, f64),
        elastic: bool,
        k: &mut dyn TangentSink,
    ) {
        let (model, dofs, beta) = (asm.model, asm.dofs, self.rayleigh.beta);
        match &mut self.term {
            StiffnessTerm::Objective(o) => {
                let damping = ObjectiveDamping {
                    model,
                    dofs,
                    states: &asm.states,
                    moduli: &o.moduli,
                    v,
                    beta,
                    rest_rate,
                };
                o.symmetric_step = damping.skew_bound(&mut o.node_skew) <= o.symmetric_below * mass_term;
                if elastic {
                    assemble_tangents(model, dofs, &[(&asm.states, 1.0)], k);
                    asm.add_friction_tangent(1.0, k);
                }
                damping.add_jacobian(c_v, o.symmetric_step, k);
            }
            StiffnessTerm::Tangent(t) => {
                let states = if t.which == DampingTangent::Current {
                    &asm.states
                } else {
                    &t.states
                };
                let terms = [(&asm.states[..], 1.0), (states, beta * c_v)];
                assemble_tangents(model, dofs, &terms[usize::from(!elastic)..], k);
                if elastic {
                    asm.add_friction_tangent(1.0, k);
                }
            }
        }
    }

    /// Whether the step matrix last assembled is symmetric: objective damping's block is not,
    /// unless it is its symmetric part ([`SYMMETRIC_CONTRACTION`]).
    pub(super) fn symmetric(&self) -> bool {
        match &self.term {
            StiffnessTerm::Objective(o) => self.rayleigh.beta == 0.0 || o.symmetric_step,
            StiffnessTerm::Tangent(_) => true,
        }
    }

    /// The β part of the damping force on all 3n node directions into `out`, summed over
    /// `members` only, at node velocities `velocities` ([`member_damping_all`]).
    pub(super) fn member_force(&self, asm: &Assembly, members: &[usize], rest_rate: &[f64], velocities: &[Vector3<f64>], out: &mut [f64]) {
        member_damping_all(asm.model, members, &asm.states, self.member_damping(rest_rate), velocities, out);
    }

    /// Each member's axial damping force [N] at node `velocities` ([`member_axial_damping`]).
    pub(super) fn member_axial(&self, asm: &Assembly, rest_rate: &[f64], velocities: &[Vector3<f64>], out: &mut [f64]) {
        member_axial_damping(asm.model, &asm.states, self.member_damping(rest_rate), velocities, out);
    }

    fn member_damping<'s>(&'s self, rest_rate: &'s [f64]) -> MemberDamping<'s> {
        match &self.term {
            StiffnessTerm::Objective(o) => MemberDamping::Objective {
                moduli: &o.moduli,
                beta: self.rayleigh.beta,
                rest_rate,
            },
            StiffnessTerm::Tangent(t) => MemberDamping::Blocks(&t.blocks),
        }
    }
}

impl Objective {
    /// Notes which members are taut at the current states, at the start of a step
    /// ([`DampingModulus`]); whether one is that was not at the last call.
    fn keep_taut(&mut self, asm: &Assembly) -> bool {
        self.was_taut.copy_from_slice(&self.taut);
        taut_members(&asm.elements.laws, &asm.rest, &asm.states, &mut self.taut);
        for ((gap, s), l0) in self.start_gap.iter_mut().zip(&asm.states).zip(&asm.rest) {
            *gap = s.length - l0;
        }
        self.update_moduli(asm);
        self.newly_taut.clear();
        let newly = (self.taut.iter().zip(&self.was_taut).enumerate()).filter(|(_, (&now, &before))| now && !before);
        self.newly_taut.extend(newly.map(|(e, _)| e));
        !self.newly_taut.is_empty()
    }

    /// Each tension-only member's allowance for the step: `carry` times its total force
    /// N + d at the step's start (velocities `v`), where it is taut and pulls; zero where it
    /// is held or slack ([`DampingModulus`]).
    fn allow(&mut self, asm: &Assembly, v: &[f64], beta: f64, rest_rate: &[f64], carry: f64) {
        let mut axial = std::mem::take(&mut self.axial[0]);
        self.allowance.fill(0.0);
        self.update_moduli(asm);
        self.at(asm, v, beta, rest_rate).axial_forces(&mut axial);
        for (e, (a, d)) in self.allowance.iter_mut().zip(&axial).enumerate() {
            let m = &mut self.moduli[e];
            if m.tension_only && m.snap.is_none() && m.stiffness != 0.0 {
                *a = carry * (asm.states[e].force + d).max(0.0);
                m.allowance = *a;
            }
        }
        self.axial[0] = axial;
    }

    /// The members' damping moduli at the current states; a tension-only member slack at
    /// the step's start is damped at its [`SnapRate`]; in a Newmark step, one taut at its
    /// start by its dashpot through the whole step, within its allowance, also where it
    /// is slack now (so that its force is continuous through l0: [`DampingModulus`]);
    /// either with its taut branch's modulus (at l0 while it is slack now).
    fn update_moduli(&mut self, asm: &Assembly) {
        let laws = &asm.elements.laws;
        damping_moduli(laws, &asm.rest, &asm.states, &self.taut, &mut self.moduli);
        for e in (0..self.taut.len()).filter(|&e| laws[e].tension_only()) {
            let snap = self.snap.filter(|_| !self.taut[e]);
            let allowance = self.allowance[e];
            if snap.is_none() && !(self.through && self.taut[e]) {
                continue;
            }
            let (law, l0, s) = (&laws[e], asm.rest[e], &asm.states[e]);
            let (stiffness, curvature) = if law.slack(s.length, l0) {
                (law.eval(l0, l0).stiffness, 0.0)
            } else {
                (s.stiffness, s.curvature)
            };
            self.moduli[e] = DampingModulus {
                stiffness,
                curvature,
                snap: snap.map(|rule| rule.rate(l0, self.start_gap[e])),
                allowance,
                ..self.moduli[e]
            };
        }
    }

    fn at<'a>(&'a self, asm: &'a Assembly, v: &'a [f64], beta: f64, rest_rate: &'a [f64]) -> ObjectiveDamping<'a> {
        ObjectiveDamping {
            model: asm.model,
            dofs: asm.dofs,
            states: &asm.states,
            moduli: &self.moduli,
            v,
            beta,
            rest_rate,
        }
    }
}

impl TangentTerm {
    /// Re-forms `blocks` from the states the βK term uses now.
    fn form_blocks(&mut self, beta: f64, asm: &Assembly) {
        let states = if self.which == DampingTangent::Current {
            &asm.states
        } else {
            &self.states
        };
        scaled_blocks(states, beta, &mut self.blocks);
    }
}
