//! The members' viscous forces at the step ends of the midpoint schemes.
//!
//! The midpoint rule and its energy–momentum form balance the forces at x_{n+½}, v_{n+½};
//! nothing balances their end states. The end velocity v_{n+1} = 2 v_{n+½} − v_n gives a
//! rotating stiff strut a spurious axial rate of order Δt², which objective damping's
//! β EA/l0 turns into force: on the paper deployment by `energy_momentum` at Δt = 2 ms,
//! 10.1 kN of a 10.2 kN largest strut force whose viscous part is about 115 N in the limit,
//! while the elastic part is right at every Δt (docs/dt_auto.md). The forces the steps
//! balanced are smooth, so the end's are extrapolated linearly in time from the last two
//! midpoints' (second order), the first step's from the stage's start, and where a member's
//! damping force jumps (a cable snapping taut: in the step it snaps in and the next; an
//! actuator's kink) its end force is the step's own.

use super::viscous::Viscous;
use crate::tsm::{held_at_no_compression, member_damping_all, Assembly, MemberDamping};
use nalgebra::Vector3;

/// The viscous axial forces the end of a midpoint scheme's step records and its reactions
/// and acceleration use.
pub(super) struct MidpointEnds {
    /// The step being solved: its members' viscous axial forces at its midpoint [N].
    solved: Vec<f64>,
    /// The last committed step's (or the stage start's) and its time [s].
    last: (Vec<f64>, f64),
    /// Per member, its damping force jumps in the step or at its start: its end is not
    /// extrapolated across.
    fresh: Vec<bool>,
    /// The members' viscous axial forces at the last converged step's end [N].
    pub(super) end: Vec<f64>,
    /// Node velocities and the end forces on all 3n node directions.
    velocities: Vec<Vector3<f64>>,
    nodal: Vec<f64>,
    members: Vec<usize>,
}

impl MidpointEnds {
    /// At the stage's start, `asm` and the free velocities `v` there.
    pub(super) fn new(asm: &Assembly, viscous: &Viscous, rest_rate: &[f64], v: &[f64]) -> Self {
        let (members, nodes) = (asm.model.members.len(), asm.model.node_count());
        let mut ends = MidpointEnds {
            solved: vec![0.0; members],
            last: (vec![0.0; members], 0.0),
            fresh: vec![false; members],
            end: vec![0.0; members],
            velocities: vec![Vector3::zeros(); nodes],
            nodal: vec![0.0; 3 * nodes],
            members: (0..members).collect(),
        };
        ends.solve(asm, viscous, rest_rate, v);
        std::mem::swap(&mut ends.last.0, &mut ends.solved);
        ends.end.copy_from_slice(&ends.last.0);
        ends
    }

    /// A step converged with `asm` at its midpoint and `v_mid` the velocities there. A
    /// cable damped at its snap rate ([`Viscous::snapping`]) snapped taut in it if damped.
    pub(super) fn solve(&mut self, asm: &Assembly, viscous: &Viscous, rest_rate: &[f64], v_mid: &[f64]) {
        super::newmark::node_velocities(asm, v_mid, &mut self.velocities);
        viscous.member_axial(asm, rest_rate, &self.velocities, &mut self.solved);
        for (e, fresh) in self.fresh.iter_mut().enumerate() {
            *fresh |= self.solved[e] != 0.0 && viscous.snapping(e);
        }
    }

    /// Every member's damping force jumps at the next step's start (see [`MidpointEnds::fresh`]).
    pub(super) fn restart(&mut self) {
        self.fresh.fill(true);
    }

    /// The damping force of `members` jumps at the next step's start.
    pub(super) fn restart_members(&mut self, members: &[usize]) {
        for &e in members {
            self.fresh[e] = true;
        }
    }

    /// The step solved last is committed, `asm` at its end, its midpoint at `t_mid` and its
    /// end at `t_end`: its end forces on the line through the last committed value and the
    /// step's own. A tension-only member's is then bounded as its law bounds it
    /// (`tsm::DampingModulus`): none while slack at the end, no less than −N while taut, so
    /// that the extrapolation never makes a cable push (the twisted prism of
    /// tests/slack.rs recorded −34 N on a cable of N = 102 N without).
    pub(super) fn commit(&mut self, asm: &Assembly, t_mid: f64, t_end: f64) {
        let slope = (t_end - t_mid) / (t_mid - self.last.1);
        for (((e, s), l), fresh) in self.end.iter_mut().zip(&self.solved).zip(&self.last.0).zip(&self.fresh) {
            *e = if *fresh { *s } else { s + slope * (s - l) };
        }
        let laws = &asm.elements.laws;
        for (e, end) in self.end.iter_mut().enumerate().filter(|(e, _)| laws[*e].tension_only()) {
            let s = &asm.states[e];
            *end = if laws[e].slack(s.length, asm.rest[e]) {
                0.0
            } else {
                held_at_no_compression(*end, s.force).0
            };
        }
        std::mem::swap(&mut self.last.0, &mut self.solved);
        self.last.1 = t_mid;
        self.fresh.fill(false);
    }

    /// The end's damping force on the free DOFs, α M v + the members' end forces.
    pub(super) fn damping_force(&mut self, asm: &Assembly, (alpha, mass, v): (f64, &[f64], &[f64]), out: &mut [f64]) {
        self.nodal.fill(0.0);
        let end = MemberDamping::Axial(&self.end);
        member_damping_all(asm.model, &self.members, &asm.states, end, &self.velocities, &mut self.nodal);
        for (i, f) in out.iter_mut().enumerate() {
            let (n, a) = asm.dofs.owner(i);
            *f = alpha * mass[i] * v[i] + self.nodal[3 * n + a];
        }
    }

    /// out (all 3n directions) += the end forces of `members` as pairs on their ends.
    pub(super) fn member_forces(&self, asm: &Assembly, members: &[usize], out: &mut [f64]) {
        member_damping_all(
            asm.model,
            members,
            &asm.states,
            MemberDamping::Axial(&self.end),
            &self.velocities,
            out,
        );
    }
}
