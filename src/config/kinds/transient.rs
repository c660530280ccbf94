//! `transient`: Newmark time stepping under loads, ground motion and rest lengths that
//! change in time ([`crate::stage::transient`]).

use super::{EntryCheck, EntryPlan, StageSpec, Steps};
use crate::config::loading::{ActuationSpec, InitialAcceleration, NodalVectorSpec, TimeFunctionSpec};
use crate::config::schema::{LoadSpec, TransientSpec};
use crate::config::validate::{check_cuts, check_steps, unknown_stage, Problems};
use crate::dynamics::{Actuator, DampingTangent, GroundMotion, Loads, NewmarkParams, NodalLoad, Rayleigh, Scheme, TimeFunction};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::sequence::{PlannedTransient, SequenceStage};
use crate::stage::transient::{Initial, Transient};
use nalgebra::Vector3;

impl StageSpec for TransientSpec {
    fn kind(&self) -> StageKind {
        StageKind::Transient
    }

    /// In a list the start is the entry's `from` and damping is named (`rayleigh_from`),
    /// both by stage name.
    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems) {
        let names = entry.names;
        if self.damped {
            p.add(
                format!("{at}.damped"),
                "in a `stages` entry name the eigen stage whose damping to use: `rayleigh_from: <name>`",
            );
        }
        if self.initial.as_ref().is_some_and(|i| i.from.is_some()) {
            p.add(
                format!("{at}.initial.from"),
                "in a `stages` entry the start is the entry's `from: <stage name>`",
            );
        }
        if let Some(r) = self.rayleigh_from.as_deref().filter(|r| !entry.damping.contains(r)) {
            let why = if names.contains(&r) {
                "is not an eigen stage with `rayleigh`".to_string()
            } else {
                unknown_stage(r, names)
            };
            p.add(
                format!("{at}.rayleigh_from"),
                format!("`{r}` {why}; name an earlier eigen stage that gives `rayleigh`"),
            );
        }
        if let Some(c) = &self.compare_to {
            if !names.contains(&c.as_str()) {
                p.add(format!("{at}.compare_to"), unknown_stage(c, names));
            }
        }
        check_transient(at, self, entry.model, entry.contact, p);
        check_transient_loading(at, self, entry.supported, entry.model, p);
    }

    fn plan(&self, stage: Stage, entry: &EntryPlan) -> Result<Box<dyn SequenceStage>> {
        let error = |reason: String| Error::Stage {
            stage: stage.name.clone(),
            reason,
        };
        let rayleigh_from = self
            .rayleigh_from
            .as_deref()
            .map(|name| entry.eigen(name))
            .transpose()
            .map_err(error)?;
        let compare_to = self.compare_to.as_deref().map(|name| entry.find(name)).transpose().map_err(error)?;
        Ok(Box::new(PlannedTransient {
            stage: transient(self, stage, entry.model)?,
            rayleigh_from,
            compare_to,
        }))
    }

    fn steps(&self, every: usize) -> Option<Steps> {
        let (steps, how) = match self.fixed_dt() {
            Some(dt) => {
                let steps = (self.duration / dt).round();
                (
                    steps,
                    format!("duration {} s / dt {dt} s = {steps} steps, every {every}", self.duration),
                )
            }
            // Not known before the run: at least duration/dt_max.
            None => {
                let max = self.auto_step().max;
                let steps = (self.duration / max).ceil();
                (
                    steps,
                    format!(
                        "dt: auto, at least duration {} s / dt_max {max} s = {steps} steps, every {every}",
                        self.duration
                    ),
                )
            }
        };
        Some(Steps {
            steps,
            key: "duration",
            how,
            dynamic: true,
        })
    }

    /// Objective damping's Jacobian is unsymmetric (taken by Cholesky on its symmetric
    /// part only while the skew part is small), and so is the energy–momentum scheme's.
    fn unsymmetric_steps(&self) -> bool {
        let damped = self.damped || self.rayleigh_from.is_some();
        (damped && self.damping_tangent == DampingTangent::Objective) || self.scheme == Scheme::EnergyMomentum
    }
}

/// Why a transient with contact takes `energy_momentum` (measured: a 2 kg bar dropped
/// 0.1 m onto the ground, Δt = 1 ms, tests/contact.rs).
const SCHEME_WITH_CONTACT: &str = "a transient with `contact` needs `scheme: energy_momentum`, whose contact forces give back \
     the energy an impact takes (a bar dropped 0.1 m rebounds to 0.1 m); Newmark's trapezoidal work of a barrier that \
     stiffens a thousandfold within one step does not (it rebounded to 0.54 m), and the midpoint rule cannot keep the \
     step's end clear: set `scheme: energy_momentum`, or remove `contact`";

/// The checks of transient `t` at `name`, on `model` where it builds, in a case with
/// `contact` or without.
pub(in crate::config) fn check_transient(name: &str, t: &TransientSpec, model: Option<&Model>, contact: bool, p: &mut Problems) {
    p.positive(&format!("{name}.duration"), t.duration);
    match t.fixed_dt() {
        Some(dt) => check_fixed_dt(name, dt, t.duration, p),
        None => check_auto_dt(name, t, p),
    }
    check_cuts(&format!("{name}.max_cuts"), t.max_cuts, p);
    match t.scheme {
        Scheme::Newmark => {
            p.within(&format!("{name}.newmark_gamma"), t.newmark_gamma, 0.0, 1.0, "(0, 1)");
            p.within(&format!("{name}.newmark_beta"), t.newmark_beta, 0.0, 0.5 + 1e-12, "(0, 0.5]");
        }
        Scheme::Midpoint | Scheme::EnergyMomentum => check_midpoint(name, t, p),
    }
    if contact && t.scheme != Scheme::EnergyMomentum {
        p.add(format!("{name}.scheme"), SCHEME_WITH_CONTACT);
    }
    if let Some(l) = &t.load {
        p.positive(&format!("{name}.load.duration"), l.duration);
        if let Some(model) = model {
            for e in l.groups.iter().filter_map(|g| model.group(g).err()) {
                p.add(format!("{name}.load.groups"), e.to_string());
            }
        }
    }
}

/// `scheme: midpoint` has no β, γ and no acceleration of its own to start from, and takes
/// fixed steps: `dt: auto`'s estimate judges a step by its end state, which the midpoint
/// schemes do not balance (on the paper deployment, `energy_momentum` at `dt: auto` 1e-4
/// took 3.7 million steps to a largest strut force 0.8 % off, where a fixed 2 ms is within
/// 0.014 %: docs/dt_auto.md).
fn check_midpoint(name: &str, t: &TransientSpec, p: &mut Problems) {
    if t.fixed_dt().is_none() {
        p.add(
            format!("{name}.dt"),
            "`auto` applies to `scheme: newmark`: its error estimate judges a step by its end state, which the midpoint schemes do not balance; give a fixed dt (the paper deployment by `energy_momentum`: 2 ms within 0.014 % of the limit), or set `scheme: newmark`".to_string(),
        );
    }
    let newmark = NewmarkParams::default();
    for (key, value, default) in [
        ("newmark_beta", t.newmark_beta, newmark.beta),
        ("newmark_gamma", t.newmark_gamma, newmark.gamma),
    ] {
        if value != default {
            p.add(
                format!("{name}.{key}"),
                format!("applies to `scheme: newmark`; the midpoint rule has no β or γ: remove `{key}`, or set `scheme: newmark`"),
            );
        }
    }
    if t.initial.as_ref().is_some_and(|i| i.acceleration == InitialAcceleration::Zero) {
        p.add(
            format!("{name}.initial.acceleration"),
            "`zero` is a Newmark start (the equation at t = 0 with a = 0); the midpoint rule imposes no equation at t = 0: remove it, or set `scheme: newmark`".to_string(),
        );
    }
}

/// A fixed Δt: positive, shorter than the stage, not too many steps.
fn check_fixed_dt(name: &str, dt: f64, duration: f64, p: &mut Problems) {
    p.positive(&format!("{name}.dt"), dt);
    check_steps(
        &format!("{name}.duration"),
        duration / dt,
        &format!("{duration:e} s at Δt = {dt:e} s is"),
        p,
    );
    if dt > duration {
        p.add(
            format!("{name}.dt"),
            format!("{dt} s is longer than the duration {duration} s: the stage would take no step"),
        );
    }
}

/// `dt: auto`: a tolerance in (0, 1), 0 < dt_min ≤ dt_max ≤ duration, and a Newmark β
/// whose error constant β − 1/6 is not zero (the estimate would be blind; the midpoint
/// rule's is 1/12).
fn check_auto_dt(name: &str, t: &TransientSpec, p: &mut Problems) {
    p.within(&format!("{name}.dt_tolerance"), t.dt_tolerance, 0.0, 1.0, "(0, 1)");
    if let Some(max) = t.dt_max {
        p.positive(&format!("{name}.dt_max"), max);
    }
    if let Some(min) = t.dt_min {
        p.positive(&format!("{name}.dt_min"), min);
    }
    let auto = t.auto_step();
    if auto.min > auto.max || auto.max > t.duration {
        p.add(
            format!("{name}.dt_max"),
            format!(
                "dt_min {} s, dt_max {} s and duration {} s must be in increasing order",
                auto.min, auto.max, t.duration
            ),
        );
    }
    if t.scheme == Scheme::Newmark && (t.newmark_beta - 1.0 / 6.0).abs() < 1e-3 {
        p.add(
            format!("{name}.newmark_beta"),
            "is 1/6, where Newmark's local error constant β − 1/6 vanishes and `dt: auto` cannot estimate the error; give a fixed dt or another β".to_string(),
        );
    }
    check_steps(
        &format!("{name}.duration"),
        t.duration / auto.max,
        &format!("{:e} s at dt_max = {:e} s is at least", t.duration, auto.max),
        p,
    );
}

/// The loads, ground motion and initial conditions of a transient: every node set names
/// known nodes and at least one; time functions have positive durations and frequencies
/// and tables increasing times; ground motion needs supports to move; an initial
/// displacement or velocity may not move a supported direction.
pub(in crate::config) fn check_transient_loading(name: &str, t: &TransientSpec, supported: bool, model: Option<&Model>, p: &mut Problems) {
    for (k, l) in t.loads.iter().enumerate() {
        check_node_set(&format!("{name}.loads[{k}]"), &l.nodes, &l.groups, model, p);
        check_time_function(&format!("{name}.loads[{k}].time"), &l.time, p);
    }
    if let Some(g) = &t.ground_motion {
        check_time_function(&format!("{name}.ground_motion.time"), &g.time, p);
        if !supported {
            p.add(
                format!("{name}.ground_motion"),
                "the model has no support for the ground to move: fix some directions (`fix` of `model.nodes`), or give the forces as `loads`",
            );
        }
    }
    check_actuation(name, &t.actuation, model, p);
    let Some(initial) = &t.initial else { return };
    for (what, entries) in [("displacement", &initial.displacement), ("velocity", &initial.velocity)] {
        for (k, e) in entries.iter().enumerate() {
            let field = format!("{name}.initial.{what}[{k}]");
            check_node_set(&field, &e.nodes, &e.groups, model, p);
            if let Some(model) = model {
                check_not_supported(&field, what, e, model, p);
            }
        }
    }
}

/// Each actuation names known members, at least one, none taken by an earlier entry; its
/// scale is positive and its rest length factor 1 + (scale − 1) f(t) stays positive over
/// the range of its time function.
fn check_actuation(name: &str, actuation: &[ActuationSpec], model: Option<&Model>, p: &mut Problems) {
    for (k, a) in actuation.iter().enumerate() {
        let field = format!("{name}.actuation[{k}]");
        check_time_function(&format!("{field}.time"), &a.time, p);
        p.positive(&format!("{field}.scale"), a.scale);
        let (low, high) = time_function_range(&a.time);
        let lowest = (1.0 + (a.scale - 1.0) * low).min(1.0 + (a.scale - 1.0) * high);
        if a.scale > 0.0 && lowest <= 0.0 {
            p.add(
                format!("{field}.scale"),
                format!(
                    "{} with a time function between {low} and {high} gives rest lengths down to {lowest} times the start's; they must stay positive",
                    a.scale
                ),
            );
        }
    }
    let sets = actuation.iter().map(|a| (&a.members[..], &a.groups[..]));
    check_member_sets(&format!("{name}.actuation"), sets, model, p);
}

/// The member sets of the entries of the list at `list` (`….actuation`): each names known
/// members, at least one, none named by an earlier entry (a member's rest length follows
/// one entry).
pub(super) fn check_member_sets<'a>(
    list: &str,
    sets: impl Iterator<Item = (&'a [String], &'a [String])>,
    model: Option<&Model>,
    p: &mut Problems,
) {
    let mut taken: Vec<Option<usize>> = model.map_or(Vec::new(), |m| vec![None; m.members.len()]);
    for (k, (members, groups)) in sets.enumerate() {
        let field = format!("{list}[{k}]");
        if members.is_empty() && groups.is_empty() {
            p.add(field, "names no member: give `members` (ids) or `groups` (member groups)");
            continue;
        }
        let Some(model) = model else { continue };
        match model.member_set(members, groups) {
            Err(e) => p.add(field, e.to_string()),
            Ok(members) => {
                for m in members {
                    if let Some(earlier) = taken[m].replace(k) {
                        p.add(
                            field.clone(),
                            format!(
                                "member `{}` is also actuated by {list}[{earlier}]; a member follows one actuation: merge them or split the groups",
                                model.members[m].id
                            ),
                        );
                    }
                }
            }
        }
    }
}

/// The least and greatest value a time function takes.
fn time_function_range(f: &TimeFunctionSpec) -> (f64, f64) {
    match f {
        TimeFunctionSpec::Constant => (1.0, 1.0),
        TimeFunctionSpec::Step { .. } | TimeFunctionSpec::Ramp { .. } | TimeFunctionSpec::HalfSine { .. } => (0.0, 1.0),
        TimeFunctionSpec::Harmonic { .. } => (-1.0, 1.0),
        TimeFunctionSpec::Table { points, .. } => points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1]))),
    }
}

/// A non-zero initial `what` on a supported direction, each node and direction named.
fn check_not_supported(field: &str, what: &str, e: &NodalVectorSpec, model: &Model, p: &mut Problems) {
    let Ok(nodes) = model.node_set(&e.nodes, &e.groups) else { return };
    for n in nodes {
        let node = &model.nodes[n];
        for a in (0..3).filter(|&a| node.support[a] && e.value[a] != 0.0) {
            p.add(
                format!("{field}.value"),
                format!(
                    "node `{}` is supported in {}: an initial {what} there ({}) would move the support; set that component to 0 or leave the node out",
                    node.id,
                    ["x", "y", "z"][a],
                    e.value[a]
                ),
            );
        }
    }
}

/// `nodes` and `groups` of the entry at `field` name known nodes, at least one.
fn check_node_set(field: &str, nodes: &[String], groups: &[String], model: Option<&Model>, p: &mut Problems) {
    if nodes.is_empty() && groups.is_empty() {
        p.add(field, crate::model::ModelError::EmptyNodeSet.to_string());
        return;
    }
    let Some(model) = model else { return };
    let before = p.0.len();
    for id in nodes.iter().filter(|id| !model.nodes.iter().any(|n| &n.id == *id)) {
        p.add(format!("{field}.nodes"), model.unknown_node(id).to_string());
    }
    for e in groups.iter().filter_map(|g| model.group(g).err()) {
        p.add(format!("{field}.groups"), e.to_string());
    }
    if p.0.len() == before {
        if let Err(e) = model.node_set(nodes, groups) {
            p.add(field, e.to_string());
        }
    }
}

/// Durations and frequencies positive, a table's points at least two with times
/// strictly increasing (a table read from a file was checked as it was read).
fn check_time_function(field: &str, f: &TimeFunctionSpec, p: &mut Problems) {
    match f {
        TimeFunctionSpec::Constant => {}
        TimeFunctionSpec::Step { duration } => p.positive(&format!("{field}.step.duration"), *duration),
        TimeFunctionSpec::Ramp { duration } => p.positive(&format!("{field}.ramp.duration"), *duration),
        TimeFunctionSpec::HalfSine { duration } => p.positive(&format!("{field}.half_sine.duration"), *duration),
        TimeFunctionSpec::Harmonic {
            frequency,
            phase,
            duration,
        } => {
            p.positive(&format!("{field}.harmonic.frequency"), *frequency);
            if !phase.is_finite() {
                p.add(format!("{field}.harmonic.phase"), format!("is {phase}; must be finite"));
            }
            if let Some(d) = duration {
                p.positive(&format!("{field}.harmonic.duration"), *d);
            }
        }
        TimeFunctionSpec::Table { file, points, .. } => {
            let field = format!("{field}.table");
            match (file, points.len()) {
                (Some(_), 0) => {}
                (Some(_), _) => p.add(field.clone(), "give `file` or `points`, not both"),
                (None, n) if n < 2 => p.add(
                    format!("{field}.points"),
                    format!("has {n} point(s); a table needs at least 2 `[time, value]` pairs"),
                ),
                (None, _) => {}
            }
            for (i, pt) in points.iter().enumerate() {
                if !(pt[0].is_finite() && pt[1].is_finite()) {
                    p.add(format!("{field}.points[{i}]"), format!("{pt:?} is not finite"));
                } else if i > 0 && pt[0] <= points[i - 1][0] {
                    p.add(
                        format!("{field}.points[{i}]"),
                        format!(
                            "time {} is not after points[{}]'s {}; times must increase strictly: sort the points and remove duplicates",
                            pt[0],
                            i - 1,
                            points[i - 1][0]
                        ),
                    );
                }
            }
        }
    }
}

/// The transient stage `spec` describes, named `stage`: the paper's `load` first, then
/// `loads` in order, the ground motion and the initial conditions (where the stage
/// starts and its damping are the plan's). Undamped.
pub(in crate::config) fn transient(spec: &TransientSpec, stage: Stage, model: &Model) -> Result<Transient> {
    let error = |reason: String| Error::Stage {
        stage: stage.name.clone(),
        reason,
    };
    let mut nodal: Vec<NodalLoad> = spec.load.iter().map(|l| launch_load(model, l)).collect::<Result<_>>()?;
    for l in &spec.loads {
        nodal.push(NodalLoad {
            nodes: model.node_set(&l.nodes, &l.groups)?,
            force: Vector3::from(l.force),
            time: time_function(&l.time).map_err(error)?,
        });
    }
    let ground = match &spec.ground_motion {
        Some(g) => Some(GroundMotion {
            acceleration: Vector3::from(g.acceleration),
            time: time_function(&g.time).map_err(error)?,
        }),
        None => None,
    };
    let mut actuators = Vec::new();
    for a in &spec.actuation {
        actuators.push(Actuator {
            members: model.member_set(&a.members, &a.groups)?,
            scale: a.scale,
            time: time_function(&a.time).map_err(error)?,
        });
    }
    let initial = spec.initial.clone().unwrap_or_default();
    let field = |entries: &[NodalVectorSpec]| -> Result<Vec<(usize, Vector3<f64>)>> {
        let mut out = Vec::new();
        for e in entries {
            let nodes = model.node_set(&e.nodes, &e.groups)?;
            out.extend(nodes.into_iter().map(|n| (n, Vector3::from(e.value))));
        }
        Ok(out)
    };
    Ok(Transient {
        stage,
        params: spec.newmark(),
        duration: spec.duration,
        rayleigh: Rayleigh::default(),
        tangent: spec.damping_tangent,
        loads: Loads { nodal, ground },
        actuators,
        initial: Initial {
            displacement: field(&initial.displacement)?,
            velocity: field(&initial.velocity)?,
            zero_acceleration: initial.acceleration == InitialAcceleration::Zero,
        },
    })
}

fn launch_load(model: &Model, spec: &LoadSpec) -> Result<NodalLoad> {
    let mut nodes = Vec::new();
    for g in &spec.groups {
        nodes.extend_from_slice(model.group(g)?);
    }
    nodes.sort_unstable();
    nodes.dedup();
    Ok(NodalLoad::launch(nodes, Vector3::from(spec.force), spec.duration, spec.profile))
}

/// The run-time function of a time function spec; a table must have its points (a file
/// is read into them when the config is loaded: `resolve_tables`).
fn time_function(spec: &TimeFunctionSpec) -> std::result::Result<TimeFunction, String> {
    Ok(match *spec {
        TimeFunctionSpec::Constant => TimeFunction::Constant,
        TimeFunctionSpec::Step { duration } => TimeFunction::Step { duration },
        TimeFunctionSpec::Ramp { duration } => TimeFunction::Ramp { duration },
        TimeFunctionSpec::HalfSine { duration } => TimeFunction::HalfSine { duration },
        TimeFunctionSpec::Harmonic {
            frequency,
            phase,
            duration,
        } => TimeFunction::Harmonic {
            frequency,
            phase,
            duration,
        },
        TimeFunctionSpec::Table { ref file, ref points, .. } => {
            if points.len() < 2 {
                let source = file.as_ref().map_or(String::new(), |f| format!(" (file `{f}` not read)"));
                return Err(format!("a time table needs at least 2 points{source}"));
            }
            TimeFunction::Table(points.clone())
        }
    })
}
