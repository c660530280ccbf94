//! `dt: auto`: the step size chosen from a local error estimate of each Newmark step, on
//! the node positions (Zienkiewicz & Xie 1991) and on the members' total axial forces.
//!
//! Positions. Newmark's local error in u over a step of Δt is (β − 1/6) Δt³ u''' + O(Δt⁴);
//! with u''' ≈ (a_{n+1} − a_n)/Δt it is e_u = (β − 1/6) Δt² (a_{n+1} − a_n), from the step's
//! own accelerations (Zienkiewicz, O.C. & Xie, Y.M., "A simple error estimator and
//! adaptive time stepping procedure for dynamic analysis", Earthquake Eng. Struct. Dyn.
//! 20 (1991) 871–887). Per node, |e_u| against the tolerance times the structure's size.
//!
//! Forces. A member's total force N(x, v) has a local error of the same order, Δt³ times
//! third derivatives with Newmark's constants (|β − 1/6| on u, 1/12 on v for γ = ½). It is
//! estimated from N's own history: e_N = |β − 1/6| · 6 Δt³ N[t_{n−2}, t_{n−1}, t_n, t_{n+1}]
//! (the third divided difference is N'''/6), against the tolerance times the largest
//! member force so far. Why the force's history and not e_u projected on the members: a
//! stiff strut's axial error is not its elastic force's (the viscous part cancels it,
//! docs/validation.md), and only the total shows what an engineer reads. The history is
//! restarted where the force may jump (a cable snapping taut, a load's kink or jump):
//! force control resumes three steps later.
//!
//! The step is accepted where the larger ratio e/(tolerance · scale) is ≤ 1, else tried
//! again shorter; the next step is Δt (0.9/ratio)^{1/3} (local error O(Δt³)), at most twice
//! and at least a fifth of the last, and kept where that would grow it by less than a fifth
//! (a changed Δt costs a factorization: M/(βΔt²) dominates the step matrix; a band up to
//! half made the paper's step launch at tolerance 1e-5 stall near `dt_min`, docs/dt_auto.md).

use crate::tsm::DofMap;
use nalgebra::Vector3;

/// `dt: auto`'s settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoStep {
    /// The local error a step may make: in node positions, relative to the structure's
    /// size; in member forces, relative to the largest member force of the stage so far.
    pub tolerance: f64,
    /// The smallest step [s]: a step at this size is taken whatever its error (the stage's
    /// summary counts those steps).
    pub min: f64,
    /// The largest step [s].
    pub max: f64,
    /// The first step tried [s].
    pub initial: f64,
}

impl AutoStep {
    /// The size to try after a step of `dt` whose error ratio was `ratio` (≤ 1: taken).
    pub fn next(&self, dt: f64, ratio: f64) -> f64 {
        let factor = (SAFETY / ratio.max(1e-12)).cbrt().clamp(0.2, 2.0);
        let next = if ratio <= 1.0 && (1.0..1.2).contains(&factor) {
            dt
        } else {
            dt * factor
        };
        next.clamp(self.min, self.max)
    }
}

/// The next step aims at this fraction of the tolerance, so that it is seldom rejected.
const SAFETY: f64 = 0.9;

/// What the error estimate keeps between steps; allocated once per stage.
pub(super) struct ErrorEstimate {
    pub(super) settings: AutoStep,
    /// The structure's size [m] (the position error's scale).
    pub(super) length: f64,
    /// The largest |total member force| of the stage so far [N] (the force error's scale).
    force_scale: f64,
    /// Total member forces at the last accepted steps, newest first, and their times.
    history: [Vec<f64>; 3],
    times: [f64; 3],
    /// How many of `history` hold forces since the last restart.
    known: usize,
    /// The total member forces of the step being judged (filled by the integrator) [N].
    pub(super) forces: Vec<f64>,
    /// The round-off in each of `forces` (filled with them) [N]: below it the estimate
    /// is noise ([`ErrorEstimate::force_ratio`]).
    pub(super) noise: Vec<f64>,
    /// Node velocities of the step being judged (zero at fixed directions) [m/s].
    pub(super) velocities: Vec<Vector3<f64>>,
    /// |e_u|² per node, a buffer.
    node_error: Vec<f64>,
}

impl ErrorEstimate {
    pub(super) fn new(settings: AutoStep, length: f64, members: usize, nodes: usize) -> Self {
        ErrorEstimate {
            settings,
            length,
            force_scale: 0.0,
            history: [vec![0.0; members], vec![0.0; members], vec![0.0; members]],
            times: [0.0; 3],
            known: 0,
            forces: vec![0.0; members],
            noise: vec![0.0; members],
            velocities: vec![Vector3::zeros(); nodes],
            node_error: vec![0.0; nodes],
        }
    }

    /// The positions' error ratio of a step of `dt` from acceleration `a` (a_n) to
    /// coordinates `u = base + β dt² a_{n+1}`, its error e_u = C dt² (a_{n+1} − a_n) (C: the
    /// scheme's error constant, β − 1/6 for Newmark): max over nodes of |e_u| / (tolerance · size).
    pub(super) fn position_ratio(&mut self, (beta, c): (f64, f64), dt: f64, (u, base, a): (&[f64], &[f64], &[f64]), dofs: &DofMap) -> f64 {
        self.node_error.fill(0.0);
        for i in 0..u.len() {
            let a_next = (u[i] - base[i]) / (beta * dt * dt);
            let e = c * dt * dt * (a_next - a[i]);
            self.node_error[dofs.owner(i).0] += e * e;
        }
        let largest = self.node_error.iter().fold(0.0_f64, |m, &e| m.max(e)).sqrt();
        largest / (self.settings.tolerance * self.length)
    }

    /// The forces' error ratio of `forces` at time `t`, for a scheme of error constant `c`
    /// (0 until three accepted steps since the last restart are known), each member's
    /// estimate less its round-off `noise`:
    /// without, a short step's viscous force, β (dN/dl) times a velocity differenced over
    /// Δt, carries round-off growing as 1/Δt that the third difference amplifies, and
    /// below some Δt no step meets the tolerance (measured: the paper deployment with a
    /// step launch at tolerance 1e-5 stuck at `dt_min` 8e-8 s after the launch).
    pub(super) fn force_ratio(&self, c: f64, t: f64) -> f64 {
        if self.known < 3 || self.force_scale == 0.0 {
            return 0.0;
        }
        let [t0, t1, t2] = self.times;
        let [h0, h1, h2] = &self.history;
        let c = 6.0 * c.abs() * (t - t0).powi(3);
        let mut largest = 0.0_f64;
        for j in 0..self.forces.len() {
            let d_new = (self.forces[j] - h0[j]) / (t - t0);
            let d0 = (h0[j] - h1[j]) / (t0 - t1);
            let d1 = (h1[j] - h2[j]) / (t1 - t2);
            let dd3 = ((d_new - d0) / (t - t1) - (d0 - d1) / (t0 - t2)) / (t - t2);
            largest = largest.max((c * dd3).abs() - self.noise[j]);
        }
        largest / (self.settings.tolerance * self.force_scale)
    }

    /// Keeps the forces of the step accepted at time `t`.
    pub(super) fn accept(&mut self, t: f64) {
        self.force_scale = self.forces.iter().fold(self.force_scale, |m, &f| m.max(f.abs()));
        self.history.rotate_right(1);
        self.history[0].copy_from_slice(&self.forces);
        self.times.rotate_right(1);
        self.times[0] = t;
        self.known = (self.known + 1).min(3);
    }

    /// Forgets the force history (their derivatives, or they themselves, may jump here).
    pub(super) fn restart(&mut self) {
        self.known = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The force estimate on a cubic N(t) = t³ is exact: N''' = 6, e_N = |β − 1/6| 6 Δt³
    /// for unequal steps too; on a quadratic it is 0 (round-off).
    #[test]
    fn force_estimate_is_exact_on_cubics() {
        let settings = AutoStep {
            tolerance: 1.0,
            min: 1e-9,
            max: 1.0,
            initial: 0.1,
        };
        let cubic: fn(f64) -> f64 = |t| t.powi(3) + 1.0;
        let quadratic: fn(f64) -> f64 = |t| 2.0 * t * t - t + 1.0;
        for (f, expected) in [(cubic, 1.0), (quadratic, 0.0)] {
            let mut e = ErrorEstimate::new(settings, 1.0, 1, 1);
            for t in [0.0, 0.1, 0.25] {
                e.forces[0] = f(t);
                e.accept(t);
            }
            let t = 0.32;
            e.forces[0] = f(t);
            let ratio = e.force_ratio(0.25 - 1.0 / 6.0, t) * e.force_scale;
            let exact = expected * 6.0 / 12.0 * (t - 0.25_f64).powi(3);
            assert!((ratio - exact).abs() < 1e-14, "{ratio} vs {exact}");
        }
    }

    /// The next size: shrinks after a rejection, grows at most 2×, stays where the change
    /// would be small, within the bounds.
    #[test]
    fn next_step_sizes() {
        let s = AutoStep {
            tolerance: 1e-4,
            min: 1e-6,
            max: 0.1,
            initial: 1e-3,
        };
        assert!((s.next(1e-3, 8.0) - 1e-3 * (0.9_f64 / 8.0).cbrt()).abs() < 1e-15);
        assert_eq!(s.next(1e-3, 1e-9), 2e-3);
        assert_eq!(s.next(1e-3, 0.7), 1e-3);
        assert!((s.next(1e-3, 0.5) - 1e-3 * 1.8_f64.cbrt()).abs() < 1e-15);
        assert_eq!(s.next(0.08, 1e-9), 0.1);
        assert_eq!(s.next(2e-6, 1e9), 1e-6);
    }
}
