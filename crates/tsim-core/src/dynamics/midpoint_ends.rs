//! The members' viscous forces at the step ends of the midpoint schemes.
//!
//! The midpoint rule and its energy–momentum form balance the forces at x_{n+½}, v_{n+½};
//! nothing balances their end states. The end velocity v_{n+1} = 2 v_{n+½} − v_n gives a
//! rotating stiff strut a spurious axial rate of order Δt², which objective damping's
//! β EA/l0 turns into force: on the paper deployment by `energy_momentum` at Δt = 2 ms,
//! 10.1 kN of a 10.2 kN largest strut force whose viscous part is about 115 N in the limit,
//! while the elastic part is right at every Δt (docs/dt_auto.md). The forces the steps
//! balanced are smooth, so the end's are extrapolated linearly in time from the last two
//! midpoints' (second order), the first step's from the stage's start, and the first after a
//! jump of the damping force (a cable snapping taut, an actuator's kink) is the step's own.

use super::viscous::Viscous;
use crate::tsm::{member_damping_all, Assembly, MemberDamping};
use nalgebra::Vector3;

/// The viscous axial forces the end of a midpoint scheme's step records and its reactions
/// and acceleration use.
pub(super) struct MidpointEnds {
    /// The step being solved: its members' viscous axial forces at its midpoint [N].
    solved: Vec<f64>,
    /// The last committed step's (or the stage start's) and its time [s].
    last: (Vec<f64>, f64),
    /// The damping force jumps at the next step's start: its end is not extrapolated across.
    restart: bool,
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
            restart: false,
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

    /// A step converged with `asm` at its midpoint and `v_mid` the velocities there.
    pub(super) fn solve(&mut self, asm: &Assembly, viscous: &Viscous, rest_rate: &[f64], v_mid: &[f64]) {
        super::newmark::node_velocities(asm, v_mid, &mut self.velocities);
        viscous.member_axial(asm, rest_rate, &self.velocities, &mut self.solved);
    }

    /// The damping force jumps at the next step's start (see [`MidpointEnds::restart`]'s field).
    pub(super) fn restart(&mut self) {
        self.restart = true;
    }

    /// The step solved last is committed, its midpoint at `t_mid` and its end at `t_end`:
    /// its end forces on the line through the last committed value and the step's own.
    pub(super) fn commit(&mut self, t_mid: f64, t_end: f64) {
        let slope = if self.restart {
            0.0
        } else {
            (t_end - t_mid) / (t_mid - self.last.1)
        };
        for ((e, s), l) in self.end.iter_mut().zip(&self.solved).zip(&self.last.0) {
            *e = s + slope * (s - l);
        }
        std::mem::swap(&mut self.last.0, &mut self.solved);
        self.last.1 = t_mid;
        self.restart = false;
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
