//! The external force of a transient stage: nodal loads scaled by time functions, a
//! uniform ground acceleration, and the structure's constant load (dead loads, weight).

use crate::tsm::DofMap;
use nalgebra::Vector3;

/// Time profile of the paper's launch load (the config's `load.profile`): kept as the
/// spelling of that key; at run time it is a [`TimeFunction`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LoadProfile {
    /// Full force for 0 ≤ t < duration, then none.
    Step,
    /// sin(π t / duration) for 0 ≤ t ≤ duration, then none: a smooth pulse.
    HalfSine,
}

/// A factor f(t) of stage time t [s] (the config's `TimeFunctionSpec`, with a table's
/// file already read into its points).
#[derive(Clone, Debug, PartialEq)]
pub enum TimeFunction {
    /// 1 at every t.
    Constant,
    /// 1 for 0 ≤ t < duration, then 0.
    Step {
        /// End of the step [s].
        duration: f64,
    },
    /// t/duration up to `duration`, then 1.
    Ramp {
        /// Rise time [s].
        duration: f64,
    },
    /// sin(π t/duration) for 0 ≤ t ≤ duration, then 0.
    HalfSine {
        /// Pulse length [s].
        duration: f64,
    },
    /// sin(2π f t + φ) for 0 ≤ t < duration (for every t ≥ 0 without one).
    Harmonic {
        /// Frequency f [Hz].
        frequency: f64,
        /// Phase φ [rad].
        phase: f64,
        /// End time [s]; `None`: no end.
        duration: Option<f64>,
    },
    /// Piecewise linear through (t, f), times strictly increasing (at least two points);
    /// the first value before the first time, the last after the last. Shared: the cases
    /// of a sweep hold one copy of a table they all read (a record may have 10⁶ rows).
    Table(std::sync::Arc<[[f64; 2]]>),
}

impl TimeFunction {
    /// f(t) at stage time `t` [s].
    pub fn at(&self, t: f64) -> f64 {
        use std::f64::consts::PI;
        match *self {
            TimeFunction::Constant => 1.0,
            TimeFunction::Step { duration } => f64::from(t >= 0.0 && t < duration),
            TimeFunction::Ramp { duration } => (t / duration).clamp(0.0, 1.0),
            TimeFunction::HalfSine { duration } if (0.0..=duration).contains(&t) => (PI * t / duration).sin(),
            TimeFunction::HalfSine { .. } => 0.0,
            TimeFunction::Harmonic {
                frequency,
                phase,
                duration,
            } => {
                if t >= 0.0 && duration.is_none_or(|d| t < d) {
                    (2.0 * PI * frequency * t + phase).sin()
                } else {
                    0.0
                }
            }
            TimeFunction::Table(ref points) => table_at(points, t),
        }
    }

    /// f just before t, its left limit: differs from [`at`](Self::at) only where f jumps at t
    /// (a step's or a harmonic's end), and is the value a time step ending at t integrates
    /// with when it ends there exactly (`dt: auto` steps end on every jump).
    pub fn before(&self, t: f64) -> f64 {
        match *self {
            TimeFunction::Step { duration } => f64::from(t > 0.0 && t <= duration),
            TimeFunction::Harmonic {
                frequency,
                phase,
                duration: Some(d),
            } if t > 0.0 && t <= d => (2.0 * std::f64::consts::PI * frequency * t + phase).sin(),
            _ => self.at(t),
        }
    }

    /// The times after 0 where f has a kink or a jump, into `out` (a table: each of its
    /// points): where a step of `dt: auto` ends, so that no step straddles one.
    pub fn breakpoints(&self, out: &mut Vec<f64>) {
        match *self {
            TimeFunction::Constant => {}
            TimeFunction::Step { duration } | TimeFunction::Ramp { duration } | TimeFunction::HalfSine { duration } => out.push(duration),
            TimeFunction::Harmonic { duration, .. } => out.extend(duration),
            TimeFunction::Table(ref points) => out.extend(points.iter().map(|p| p[0])),
        }
        out.retain(|&t| t > 0.0);
    }

    /// df/dt at t, from the left where f has a kink or a jump (the rate at the end of a
    /// time step that ends at t); a jump's impulse is not counted (a step function's rate
    /// is 0).
    pub fn rate_before(&self, t: f64) -> f64 {
        self.rate(t, true)
    }

    /// df/dt at t, from the right (the rate at the start of a time step from t).
    pub fn rate_after(&self, t: f64) -> f64 {
        self.rate(t, false)
    }

    /// df/dt on the side of t `before` says. A kink within [`KINK_TOLERANCE`] of t counts
    /// as at t: time stepped as t + Δt + Δt … reaches a ramp's end 0.1 s as
    /// 0.10000000000000006, and the step ending there must still see the ramp's rate.
    fn rate(&self, t: f64, before: bool) -> f64 {
        use std::f64::consts::PI;
        // Whether t lies in the span [0, end] where f changes, on that side.
        let within = |end: f64| {
            let tol = KINK_TOLERANCE * end.abs().max(t.abs());
            if before {
                t > tol && t <= end + tol
            } else {
                t >= -tol && t < end - tol
            }
        };
        match *self {
            TimeFunction::Constant | TimeFunction::Step { .. } => 0.0,
            TimeFunction::Ramp { duration } if within(duration) => 1.0 / duration,
            TimeFunction::HalfSine { duration } if within(duration) => PI / duration * (PI * t / duration).cos(),
            TimeFunction::Ramp { .. } | TimeFunction::HalfSine { .. } => 0.0,
            TimeFunction::Harmonic {
                frequency,
                phase,
                duration,
            } if within(duration.unwrap_or(f64::INFINITY)) => 2.0 * PI * frequency * (2.0 * PI * frequency * t + phase).cos(),
            TimeFunction::Harmonic { .. } => 0.0,
            TimeFunction::Table(ref points) => table_rate(points, t, before),
        }
    }

    /// The time from which f is constant (∞ for a harmonic without end).
    pub fn end(&self) -> f64 {
        match *self {
            TimeFunction::Constant => 0.0,
            TimeFunction::Step { duration } | TimeFunction::Ramp { duration } | TimeFunction::HalfSine { duration } => duration,
            TimeFunction::Harmonic { duration, .. } => duration.unwrap_or(f64::INFINITY),
            TimeFunction::Table(ref points) => points.last().map_or(0.0, |p| p[0]),
        }
    }

    /// The constant value f takes from [`end`](Self::end) on.
    pub fn final_value(&self) -> f64 {
        match self {
            TimeFunction::Constant | TimeFunction::Ramp { .. } => 1.0,
            TimeFunction::Table(points) => points.last().map_or(0.0, |p| p[1]),
            _ => 0.0,
        }
    }
}

/// Linear interpolation in `points` (sorted by time), held constant outside.
fn table_at(points: &[[f64; 2]], t: f64) -> f64 {
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return 0.0;
    };
    if t <= first[0] {
        return first[1];
    }
    if t >= last[0] {
        return last[1];
    }
    // The first point later than t; 1 ≤ k < len here.
    let k = points.partition_point(|p| p[0] <= t);
    let ([t0, f0], [t1, f1]) = (points[k - 1], points[k]);
    f0 + (f1 - f0) * (t - t0) / (t1 - t0)
}

/// Relative distance in time within which a time function's kink counts as at t: far
/// above the round-off of a time summed over millions of steps (1e-16 · steps), far below
/// any step size.
const KINK_TOLERANCE: f64 = 1e-9;

/// The slope of `points` at t: that of the segment t0 < t ≤ t1 (`before`) or
/// t0 ≤ t < t1, a point within [`KINK_TOLERANCE`] of t taken as at t; 0 outside.
fn table_rate(points: &[[f64; 2]], t: f64, before: bool) -> f64 {
    let near = |p: &[f64; 2]| (p[0] - t).abs() <= KINK_TOLERANCE * p[0].abs().max(t.abs());
    let k = points.partition_point(|p| if before { p[0] < t && !near(p) } else { p[0] <= t || near(p) });
    if k == 0 || k == points.len() {
        return 0.0;
    }
    let ([t0, f0], [t1, f1]) = (points[k - 1], points[k]);
    (f1 - f0) / (t1 - t0)
}

/// The same force on each of a set of nodes, scaled by a time function.
#[derive(Clone, Debug, PartialEq)]
pub struct NodalLoad {
    /// Indices of the loaded nodes.
    pub nodes: Vec<usize>,
    /// Force per node [N].
    pub force: Vector3<f64>,
    /// The force's factor f(t).
    pub time: TimeFunction,
}

impl NodalLoad {
    /// The paper's launch load: `profile` over `duration` [s].
    pub fn launch(nodes: Vec<usize>, force: Vector3<f64>, duration: f64, profile: LoadProfile) -> Self {
        let time = match profile {
            LoadProfile::Step => TimeFunction::Step { duration },
            LoadProfile::HalfSine => TimeFunction::HalfSine { duration },
        };
        NodalLoad { nodes, force, time }
    }

    /// The load's factor f(t) at stage time `t` [s]; `before`: its left limit there.
    pub fn factor(&self, t: f64, before: bool) -> f64 {
        if before {
            self.time.before(t)
        } else {
            self.time.at(t)
        }
    }

    /// Adds the load at time t (`before`: its left limit) to a force vector on the free
    /// DOFs of `dofs`.
    pub fn add_free(&self, t: f64, before: bool, dofs: &DofMap, f: &mut [f64]) {
        let s = self.factor(t, before);
        if s == 0.0 {
            return;
        }
        for &n in &self.nodes {
            for a in 0..3 {
                if let Some(i) = dofs.free(n, a) {
                    f[i] += s * self.force[a];
                }
            }
        }
    }
}

/// Uniform acceleration of the ground, a_g(t) = `acceleration` · f(t) [m/s²], moving
/// every support together.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundMotion {
    /// Peak ground acceleration vector [m/s²], global frame.
    pub acceleration: Vector3<f64>,
    /// The acceleration's factor f(t).
    pub time: TimeFunction,
}

/// The time-varying loads of a transient stage (the structure's constant load comes on
/// top, see [`FreeLoads`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Loads {
    /// Nodal loads, each with its time function.
    pub nodal: Vec<NodalLoad>,
    /// Ground acceleration, if any (the stage then works relative to the ground).
    pub ground: Option<GroundMotion>,
}

impl Loads {
    /// The time from which every load is constant (0 for none).
    pub fn end(&self) -> f64 {
        let ground = self.ground.iter().map(|g| g.time.end());
        self.nodal.iter().map(|l| l.time.end()).chain(ground).fold(0.0, f64::max)
    }

    /// Adds the nodal loads at time `t` (`before`: their left limits) to a force per node
    /// [N] (allocates nothing).
    pub fn add_nodal(&self, t: f64, before: bool, f: &mut [Vector3<f64>]) {
        for load in &self.nodal {
            let s = load.factor(t, before);
            if s != 0.0 {
                load.nodes.iter().for_each(|&n| f[n] += load.force * s);
            }
        }
    }

    /// The ground acceleration a_g(t) [m/s²] (zero without ground motion); `before`: its
    /// left limit.
    pub fn ground_acceleration(&self, t: f64, before: bool) -> Vector3<f64> {
        let factor = |f: &TimeFunction| if before { f.before(t) } else { f.at(t) };
        self.ground.as_ref().map_or(Vector3::zeros(), |g| g.acceleration * factor(&g.time))
    }

    /// Every time after 0 where a load's time function has a kink or a jump, sorted, each once.
    pub fn breakpoints(&self) -> Vec<f64> {
        let mut out = Vec::new();
        let ground = self.ground.iter().map(|g| &g.time);
        for f in self.nodal.iter().map(|l| &l.time).chain(ground) {
            f.breakpoints(&mut out);
        }
        out.sort_by(f64::total_cmp);
        out.dedup();
        out
    }

    /// Whether some load is still on after [`end`](Self::end).
    pub fn persist(&self) -> bool {
        let nodal = self
            .nodal
            .iter()
            .any(|l| l.time.final_value() != 0.0 && l.force != Vector3::zeros());
        let ground = self
            .ground
            .as_ref()
            .is_some_and(|g| g.time.final_value() != 0.0 && g.acceleration != Vector3::zeros());
        nodal || ground
    }
}

/// The external force of a transient on the free DOFs, set up once for a stage so that
/// evaluating it at a time allocates nothing:
///
/// f(t) = f_c + Σ_k F_k f_k(t) − M a_g(t),
///
/// f_c the structure's constant load (dead loads and weight m g), F_k the nodal loads with
/// their time functions, and −M a_g the inertia load of the ground acceleration on every
/// free DOF. The last term is the relative formulation: positions, velocities and
/// accelerations are those relative to the moving ground (supports stay where they are),
/// so a rigid motion of the whole structure with the ground strains nothing, and kinetic
/// energy, the energy ledger and Rayleigh damping (its αM term included) all act on the
/// relative motion; absolute motion is the relative one plus the ground's.
#[derive(Clone, Debug)]
pub struct FreeLoads {
    constant: Vec<f64>,
    nodal: Vec<NodalLoad>,
    /// −m on each free DOF times the ground acceleration's component there [N per m/s²
    /// of f(t)], with its time function; `None` without ground motion.
    ground: Option<(Vec<f64>, TimeFunction)>,
    /// Whether `constant` has any non-zero entry (no need to read it otherwise).
    has_constant: bool,
}

impl FreeLoads {
    /// `constant[n]` per node [N], `masses` per free DOF [kg].
    pub fn new(loads: &Loads, constant: &[Vector3<f64>], masses: &[f64], dofs: &DofMap) -> Self {
        let on_free = |value: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            (0..dofs.len())
                .map(|i| {
                    let (n, a) = dofs.owner(i);
                    value(n, a)
                })
                .collect()
        };
        let constant = on_free(&|n, a| constant.get(n).map_or(0.0, |f| f[a]));
        let ground = loads.ground.as_ref().map(|g| {
            let inertia: Vec<f64> = (0..dofs.len()).map(|i| -masses[i] * g.acceleration[dofs.owner(i).1]).collect();
            (inertia, g.time.clone())
        });
        FreeLoads {
            has_constant: constant.iter().any(|&c| c != 0.0),
            constant,
            nodal: loads.nodal.clone(),
            ground,
        }
    }

    /// Writes f(t) on the free DOFs of `dofs` into `f` (`before`: its left limit, where a
    /// load jumps at t); allocates nothing.
    pub fn at(&self, t: f64, before: bool, dofs: &DofMap, f: &mut [f64]) {
        if self.has_constant {
            f.copy_from_slice(&self.constant);
        } else {
            f.fill(0.0);
        }
        for load in &self.nodal {
            load.add_free(t, before, dofs, f);
        }
        if let Some((inertia, time)) = &self.ground {
            let s = if before { time.before(t) } else { time.at(t) };
            if s != 0.0 {
                for (fi, mi) in f.iter_mut().zip(inertia) {
                    *fi += s * mi;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each function at points inside, at the edges and past its end; the values are
    /// exact in floating point except the sines (1e-15: sin near π is ~1e-16 off 0).
    #[test]
    fn time_functions() {
        let near = |a: f64, b: f64| (a - b).abs() < 1e-15;
        let step = TimeFunction::Step { duration: 0.5 };
        assert_eq!((step.at(0.0), step.at(0.49), step.at(0.5), step.at(-0.1)), (1.0, 1.0, 0.0, 0.0));
        let ramp = TimeFunction::Ramp { duration: 2.0 };
        assert_eq!((ramp.at(0.0), ramp.at(1.0), ramp.at(2.0), ramp.at(5.0)), (0.0, 0.5, 1.0, 1.0));
        let pulse = TimeFunction::HalfSine { duration: 1.0 };
        assert!(near(pulse.at(0.5), 1.0) && near(pulse.at(1.0), 0.0) && pulse.at(1.5) == 0.0);
        let h = TimeFunction::Harmonic {
            frequency: 2.0,
            phase: std::f64::consts::FRAC_PI_2,
            duration: Some(1.0),
        };
        assert!(near(h.at(0.0), 1.0) && near(h.at(0.25), -1.0) && h.at(1.0) == 0.0);
        let table = TimeFunction::Table(vec![[0.0, 1.0], [1.0, 3.0], [3.0, -1.0]].into());
        assert_eq!(
            (table.at(-1.0), table.at(0.5), table.at(1.0), table.at(2.0), table.at(9.0)),
            (1.0, 2.0, 3.0, 1.0, -1.0)
        );
        assert_eq!((table.end(), table.final_value()), (3.0, -1.0));
        assert_eq!((TimeFunction::Constant.end(), TimeFunction::Constant.final_value()), (0.0, 1.0));
    }

    /// Left limits differ from the values only at jumps; breakpoints are the kinks and
    /// jumps after 0, a table's every point.
    #[test]
    fn left_limits_and_breakpoints() {
        let step = TimeFunction::Step { duration: 0.5 };
        assert_eq!(
            (step.before(0.5), step.at(0.5), step.before(0.6), step.before(0.2)),
            (1.0, 0.0, 0.0, 1.0)
        );
        let h = TimeFunction::Harmonic {
            frequency: 2.0,
            phase: std::f64::consts::FRAC_PI_2,
            duration: Some(1.0),
        };
        assert!((h.before(1.0) - 1.0).abs() < 1e-15 && h.at(1.0) == 0.0);
        let pulse = TimeFunction::HalfSine { duration: 1.0 };
        assert_eq!(pulse.before(0.3), pulse.at(0.3));
        let loads = Loads {
            nodal: [step, pulse, TimeFunction::Table(vec![[0.0, 1.0], [0.5, 3.0], [3.0, -1.0]].into())]
                .into_iter()
                .map(|time| NodalLoad {
                    nodes: vec![0],
                    force: Vector3::x(),
                    time,
                })
                .collect(),
            ground: None,
        };
        assert_eq!(loads.breakpoints(), vec![0.5, 1.0, 3.0]);
    }

    /// `rate_before` against a backward difference and `rate_after` against a forward one,
    /// at points inside, at kinks and at the ends. h = 1e-7: the differences' truncation
    /// (h f''/2 ≤ 1e-7 · 4π²·4) and round-off (ε/h ~ 2e-9) stay below 1e-5.
    #[test]
    fn time_function_rates() {
        let functions = [
            TimeFunction::Constant,
            TimeFunction::Ramp { duration: 2.0 },
            TimeFunction::HalfSine { duration: 1.0 },
            TimeFunction::Harmonic {
                frequency: 2.0,
                // sin(4π + φ) = 0 at the end: no jump there.
                phase: 0.0,
                duration: Some(1.0),
            },
            TimeFunction::Table(vec![[0.0, 1.0], [1.0, 3.0], [3.0, -1.0]].into()),
        ];
        let h = 1e-7;
        for f in &functions {
            for t in [0.0, 0.3, 0.5, 1.0, 1.7, 2.0, 2.5, 3.0, 4.0] {
                let backward = (f.at(t) - f.at(t - h)) / h;
                assert!(
                    (f.rate_before(t) - backward).abs() < 1e-5,
                    "{f:?} before {t}: {} vs {backward}",
                    f.rate_before(t)
                );
                let forward = (f.at(t + h) - f.at(t)) / h;
                assert!(
                    (f.rate_after(t) - forward).abs() < 1e-5,
                    "{f:?} after {t}: {} vs {forward}",
                    f.rate_after(t)
                );
            }
        }
        assert_eq!(
            TimeFunction::Step { duration: 0.5 }.rate_before(0.5),
            0.0,
            "a jump's impulse is not a rate"
        );
        // A kink reached by summed steps, an ulp or a few past it, is at it.
        let ramp = TimeFunction::Ramp { duration: 0.1 };
        let t = (0..25).fold(0.0, |t, _| t + 0.004);
        assert!(t > 0.1 && ramp.rate_before(t) == 10.0 && ramp.rate_after(t) == 0.0, "{t}");
        let table = TimeFunction::Table(vec![[0.0, 0.0], [0.1, 1.0], [0.2, 1.0]].into());
        assert!(table.rate_before(t) == 10.0 && table.rate_after(t) == 0.0);
    }
}
