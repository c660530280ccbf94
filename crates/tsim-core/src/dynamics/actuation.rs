//! Members whose rest length changes in time within a stage: winches, motors, cables
//! reeled in or paid out. The rest length is element state, not a load: the member's
//! force law is evaluated with l0(t), and the energy ledger counts the work ∫ ∂U/∂l0 dl0
//! the change does on the members.

use super::TimeFunction;
use crate::tsm::Assembly;

/// One actuator: the rest lengths of `members` scaled in time,
/// l0(t) = l0(0) · (1 + (scale − 1) f(t)), l0(0) the rest length at the stage's start.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuator {
    /// Member indices (each in at most one actuator of a stage).
    pub members: Vec<usize>,
    /// Rest length where f = 1, over that at the stage's start.
    pub scale: f64,
    /// f(t), the fraction of the change made at stage time t.
    pub time: TimeFunction,
}

/// The rest lengths of every member over a stage, from those at its start.
#[derive(Clone, Debug)]
pub struct RestSchedule {
    start: Vec<f64>,
    actuators: Vec<Actuator>,
}

impl RestSchedule {
    /// `start`: every member's rest length at the stage's start [m].
    pub fn new(start: Vec<f64>, actuators: Vec<Actuator>) -> Self {
        RestSchedule { start, actuators }
    }

    /// Every member's rest length at stage time `t` into `rest` [m].
    pub fn at(&self, t: f64, rest: &mut [f64]) {
        rest.copy_from_slice(&self.start);
        for a in &self.actuators {
            let factor = 1.0 + (a.scale - 1.0) * a.time.at(t);
            a.members.iter().for_each(|&m| rest[m] = self.start[m] * factor);
        }
    }

    /// l̇0/l0 of every member at stage time `t` into `rate` [1/s]; where a time function
    /// has a kink, the rate just `before` t (that of a step ending at t) or just after.
    pub fn relative_rate(&self, t: f64, before: bool, rate: &mut [f64]) {
        rate.fill(0.0);
        for a in &self.actuators {
            let factor = 1.0 + (a.scale - 1.0) * a.time.at(t);
            let df = if before { a.time.rate_before(t) } else { a.time.rate_after(t) };
            let relative = (a.scale - 1.0) * df / factor;
            a.members.iter().for_each(|&m| rate[m] = relative);
        }
    }

    /// The time from which every rest length is constant.
    pub fn end(&self) -> f64 {
        self.actuators.iter().map(|a| a.time.end()).fold(0.0, f64::max)
    }
}

/// A stage's rest-length schedule as a Newmark stage runs it, and what the ledger keeps of
/// it between steps.
pub(super) struct Actuation {
    schedule: RestSchedule,
    /// Rest lengths of the last converged state [m], and those of the step being solved.
    rest: Vec<f64>,
    rest_next: Vec<f64>,
    /// ∂U/∂l0 of every member at the last converged state [N], and a buffer for the next.
    force: Vec<f64>,
    force_next: Vec<f64>,
    /// l̇0/l0 just after the last converged time (the start of the next step) [1/s].
    rate_after: Vec<f64>,
    /// l̇0/l0 the step's equation uses: at the end of the step being solved (objective
    /// damping strains only what the rest length does not take up) [1/s].
    pub(super) rate: Vec<f64>,
}

impl Actuation {
    /// Sets `asm` to the schedule's rest lengths at t = 0.
    pub(super) fn start(schedule: RestSchedule, asm: &mut Assembly) -> Self {
        let members = asm.states.len();
        let mut rest = vec![0.0; members];
        schedule.at(0.0, &mut rest);
        asm.set_rest(&rest);
        asm.update();
        let mut force = vec![0.0; members];
        asm.energy_rest_derivatives(&mut force);
        let mut rate_after = vec![0.0; members];
        schedule.relative_rate(0.0, false, &mut rate_after);
        Actuation {
            schedule,
            rest_next: rest.clone(),
            rest,
            force_next: force.clone(),
            force,
            // From t = 0 on: the rate after it.
            rate: rate_after.clone(),
            rate_after,
        }
    }

    /// Whether the rate jumps at the step's start `t` (an actuator starting or stopping);
    /// if so, `rate` becomes the rate just after `t`, for the caller to re-form the state's
    /// damping force and acceleration with.
    pub(super) fn jumps_at(&mut self, t: f64) -> bool {
        self.schedule.relative_rate(t, false, &mut self.rate_after);
        let jumped = self.rate_after != self.rate;
        if jumped {
            self.rate.copy_from_slice(&self.rate_after);
        }
        jumped
    }

    /// Sets the step's end to `t_next`: its rest lengths (in `asm`, from the step's first
    /// residual on) and its rate there.
    pub(super) fn step_to(&mut self, t_next: f64, asm: &mut Assembly) {
        self.schedule.at(t_next, &mut self.rest_next);
        self.schedule.relative_rate(t_next, true, &mut self.rate);
        asm.set_rest(&self.rest_next);
    }

    /// A step failed: back to the start state's rest lengths, and its rate from the step's side.
    pub(super) fn abandon_step(&mut self, asm: &mut Assembly) {
        asm.set_rest(&self.rest);
        self.rate.copy_from_slice(&self.rate_after);
    }

    /// The trapezoidal work Σ ½ (q_n + q_{n+1}) (l0_{n+1} − l0_n) of the step that converged
    /// at `asm` (q = ∂U/∂l0), which then becomes the last converged state. With the
    /// trapezoidal work of the nodal forces this is the trapezoidal rule along the step's
    /// straight path in (x, l0): the ledger closes to the rule's O(Δt²).
    pub(super) fn commit(&mut self, asm: &Assembly) -> f64 {
        // The rest lengths reached: the schedule's, but over clustered cables shared out
        // (and with friction slipped) by the assembly.
        self.rest_next.copy_from_slice(&asm.rest);
        asm.energy_rest_derivatives(&mut self.force_next);
        let work = (self.force.iter().zip(&self.force_next))
            .zip(self.rest.iter().zip(&self.rest_next))
            .map(|((q0, q1), (l0, l1))| 0.5 * (q0 + q1) * (l1 - l0))
            .sum();
        std::mem::swap(&mut self.force, &mut self.force_next);
        std::mem::swap(&mut self.rest, &mut self.rest_next);
        work
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp to 0.8 over 2 s on members 0 and 2: the lengths follow it exactly
    /// (binary-exact fractions), member 1 keeps its length, the rate is −0.2/2 s over the
    /// current factor while the ramp runs and 0 after it.
    #[test]
    fn rest_lengths_follow_the_schedule() {
        let schedule = RestSchedule::new(
            vec![2.0, 1.0, 4.0],
            vec![Actuator {
                members: vec![0, 2],
                scale: 0.75,
                time: TimeFunction::Ramp { duration: 2.0 },
            }],
        );
        let mut rest = [0.0; 3];
        schedule.at(1.0, &mut rest);
        assert_eq!(rest, [1.75, 1.0, 3.5]);
        schedule.at(3.0, &mut rest);
        assert_eq!(rest, [1.5, 1.0, 3.0]);
        let mut rate = [9.0; 3];
        schedule.relative_rate(1.0, true, &mut rate);
        assert_eq!(rate, [-0.125 / 0.875, 0.0, -0.125 / 0.875]);
        schedule.relative_rate(3.0, true, &mut rate);
        assert_eq!(rate, [0.0; 3]);
        // At the ramp's end the rate drops: before it the ramp's, after it none.
        schedule.relative_rate(2.0, true, &mut rate);
        assert_eq!(rate, [-0.125 / 0.75, 0.0, -0.125 / 0.75]);
        schedule.relative_rate(2.0, false, &mut rate);
        assert_eq!(rate, [0.0; 3]);
        assert_eq!(schedule.end(), 2.0);
    }
}
