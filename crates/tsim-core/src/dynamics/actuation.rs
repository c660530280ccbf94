//! Members whose rest length changes in time within a stage: winches, motors, cables
//! reeled in or paid out. The rest length is element state, not a load: the member's
//! force law is evaluated with l0(t), and the energy ledger counts the work ∫ ∂U/∂l0 dl0
//! the change does on the members.

use super::TimeFunction;

/// One actuator: the rest lengths of `members` scaled in time,
/// l0(t) = l0(0) · (1 + (scale − 1) f(t)), l0(0) the rest length at the stage's start.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuator {
    /// Member indices (each in at most one actuator of a stage).
    pub members: Vec<usize>,
    /// Rest length where f = 1, over that at the stage's start.
    pub scale: f64,
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
