//! Rayleigh damping within a Newmark stage: the αM term and the βK term, each way of
//! evaluating βK with the state it keeps between steps and iterates.

use super::{DampingTangent, Rayleigh};
use crate::solve::{TangentSink, REUSE_CONTRACTION};
use crate::tsm::{
    assemble_tangents, block_product, damping_moduli, member_axial_damping, member_damping_all, scaled_blocks, taut_members, Assembly,
    DampingModulus, EndSlots, MemberDamping, MemberState, ObjectiveDamping,
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

/// Members whose snapping taut falls within this fraction of a step of the first are taken
/// as snapping with it: the step stops once for all of them (within 1e-6 of a step, the
/// time each is undamped too long, or damped too early, is immaterial).
const SNAP_TOGETHER: f64 = 1e-6;

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

/// β (dN/dl) r e per member, r its elastic extension rate ([`ObjectiveDamping`]).
pub(super) struct Objective {
    /// Per member, whether it was taut at the step's start (a member slack then is
    /// undamped for the step), and its damping modulus at the current states
    /// ([`DampingModulus`]).
    taut: Vec<bool>,
    /// The flags of the step before, to see which members start to be damped.
    was_taut: Vec<bool>,
    /// Per member, l − l0 at the step's start [m] (negative where slack): where a slack
    /// member snaps taut within the step ([`Viscous::snap_fraction`]).
    start_gap: Vec<f64>,
    /// Members a step stopped at as they snapped taut, damped from the next step's start
    /// ([`Viscous::damp_from_next_step`]), and those of the current step.
    damp_next: Vec<usize>,
    snapping: Vec<usize>,
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
                start_gap: vec![0.0; members],
                damp_next: Vec::new(),
                snapping: Vec::new(),
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

    /// At the start of a step, `asm` at the last converged state: `LastConverged` takes its
    /// K_T, objective damping notes which members are slack (undamped for the step). Taken
    /// here, not at the end of the previous step, so that between steps the term is still
    /// the one the last converged equation used ([`Self::member_force`]). Whether some
    /// member is damped now that the last equation left undamped (a cable that snapped
    /// taut): the damping force jumps at the step's start, and the step should start from
    /// the acceleration just after the jump.
    pub(super) fn start_step(&mut self, asm: &Assembly) -> bool {
        match &mut self.term {
            StiffnessTerm::Objective(o) => o.keep_taut(asm) && self.rayleigh.beta != 0.0,
            StiffnessTerm::Tangent(t) if t.which == DampingTangent::LastConverged => {
                t.states.copy_from_slice(&asm.states);
                t.form_blocks(self.rayleigh.beta, asm);
                false
            }
            StiffnessTerm::Tangent(_) => false,
        }
    }

    /// Damps `members` from the next step's start on its taut branch, though a round-off may
    /// leave them short of l0 there: the members a step was stopped at as they snapped taut.
    pub(super) fn damp_from_next_step(&mut self, members: Vec<usize>) {
        if let StiffnessTerm::Objective(o) = &mut self.term {
            o.damp_next = members;
        }
    }

    /// A step has been committed: the members a stopped step handed on were damped in it.
    pub(super) fn step_committed(&mut self) {
        if let StiffnessTerm::Objective(o) = &mut self.term {
            o.damp_next.clear();
        }
    }

    /// Where in the step just solved, to `asm`'s state, the first tension-only member slack
    /// at its start snaps taut, as a fraction of the step (l − l0 interpolated linearly in
    /// time); `None` where none does, or where the β term does not see it (the paper's
    /// variants, β = 0).
    ///
    /// Why: such a member is undamped for the whole step ([`DampingModulus`]), while a
    /// Kelvin–Voigt cord's damping force jumps from 0 to β k r as it reaches l0. Over a fixed
    /// step that is an O(Δt) error in the velocity at each event, and the scheme is first
    /// order once cables snap taut (tests/slack.rs measured it). Stopping the step at the
    /// event puts the jump on a step boundary; the crossing's time is then off by the linear
    /// interpolation's O(Δt²), and second order is kept.
    /// With the fraction, the members that snap there (within [`SNAP_TOGETHER`] of it).
    pub(super) fn snap_fraction(&self, asm: &Assembly) -> Option<(f64, Vec<usize>)> {
        let StiffnessTerm::Objective(o) = &self.term else { return None };
        if self.rayleigh.beta == 0.0 {
            return None;
        }
        let laws = &asm.elements.laws;
        let snaps: Vec<(usize, f64)> = (0..o.taut.len())
            .filter(|&e| !o.taut[e] && laws[e].tension_only() && !laws[e].slack(asm.states[e].length, asm.rest[e]))
            .map(|e| {
                let (before, after) = (o.start_gap[e], asm.states[e].length - asm.rest[e]);
                (e, before / (before - after))
            })
            .collect();
        let first = snaps.iter().map(|s| s.1).min_by(f64::total_cmp)?;
        Some((first, snaps.iter().filter(|s| s.1 <= first + SNAP_TOGETHER).map(|s| s.0).collect()))
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
    /// Notes which members are taut at the current states, the ones damped until the next
    /// call, at the start of a step ([`DampingModulus`]), with those a stopped step handed
    /// on; whether one is damped that was not at the last call.
    fn keep_taut(&mut self, asm: &Assembly) -> bool {
        self.was_taut.copy_from_slice(&self.taut);
        taut_members(&asm.elements.laws, &asm.rest, &asm.states, &mut self.taut);
        // Copied, not taken: a step tried again from the same start damps them too.
        self.snapping.clone_from(&self.damp_next);
        for &e in &self.snapping {
            self.taut[e] = true;
        }
        for ((gap, s), l0) in self.start_gap.iter_mut().zip(&asm.states).zip(&asm.rest) {
            *gap = s.length - l0;
        }
        self.update_moduli(asm);
        self.taut.iter().zip(&self.was_taut).any(|(&now, &before)| now && !before)
    }

    /// The members' damping moduli at the current states; a member snapping taut at the
    /// step's start a round-off short of l0 is damped on its taut branch, at l0.
    fn update_moduli(&mut self, asm: &Assembly) {
        damping_moduli(&asm.elements.laws, &asm.rest, &asm.states, &self.taut, &mut self.moduli);
        for &e in &self.snapping {
            let (law, l0) = (&asm.elements.laws[e], asm.rest[e]);
            if law.slack(asm.states[e].length, l0) {
                let taut = law.eval(l0, l0);
                (self.moduli[e].stiffness, self.moduli[e].curvature) = (taut.stiffness, taut.curvature);
            }
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
