use crate::dynamics::{AxialForces, Energy, Newmark};
use crate::model::clearance::Tracker;
use crate::model::{Model, AXES};
use crate::record::{Constraints, Frame, FrameClearance, FrameModes, RecordResult, Recorder, Stage};
use crate::structure::Structure;
use crate::tsm::{Assembly, DofMap};
use nalgebra::Vector3;

/// Builds the frames a stage records from its assembly, with buffers reused for every
/// recorded step (a time step allocates nothing): positions, velocities, member forces and
/// lengths, the applied load, the reactions at the stage's constrained directions and the
/// equilibrium check of the whole structure, and the struts' clearance.
///
/// Clearance. When the structure's struts are followed, every recorded step carries the
/// nearest pair and the events since the previous recorded one; a stage that skips steps
/// between records (`outputs.every`) gives them to [`FrameBuilder::observe`], so that a
/// pass-through is found between consecutive steps, not only between recorded ones.
///
/// Reactions. At a constrained direction (node n, axis a) the node's balance is
/// R + f − p − f_β − m a_s = 0, so the reaction is R = p + f_β − f + m a_s: p the internal
/// (member) force, f_β the members' stiffness-proportional damping force reaching the
/// support (dynamic stages; Rayleigh's αM part is zero there, a support not moving relative
/// to the base), f the applied load at that direction (it goes straight into the support),
/// and m a_s the support node's inertia when the base accelerates (ground motion).
///
/// Equilibrium check. Summed over every node, the member forces cancel pairwise, so
/// e = Σ R + Σ f − Σ_free (m a + α m v) − Σ_constrained m a_s is the sum of the out-of-balance
/// of the free directions: the sum of the Newton residual of the step. Its norm is the
/// frame's `equilibrium_error`; relative to max(|Σ f|, |Σ R|, max |N|) it is bounded by the
/// solver's force tolerance times the number of free directions, and in practice far below.
pub struct FrameBuilder {
    constraints: Constraints,
    /// Lumped mass of every node [kg] (zero for a massless structure).
    masses: Vec<f64>,
    /// A static frame's member forces (a dynamic one's come with its [`Motion`]).
    statics: Vec<f64>,
    lengths: Vec<f64>,
    reactions: Vec<f64>,
    /// The members' β damping force on all 3n directions (zero in static stages), summed
    /// over `constrained_members` only: the reactions read it at constrained directions.
    damping: Vec<f64>,
    /// The members with an end at a constrained direction's node, in model order.
    constrained_members: Vec<usize>,
    /// Largest equilibrium error of the recorded steps, absolute [N] and relative.
    pub check: EquilibriumCheck,
    /// The lowest modes (ω², lowest mode over every node) the next frames carry, when the
    /// stage computes them (folding with `folding.eigen`).
    pub modes: Option<(Vec<f64>, Vec<Vector3<f64>>)>,
    /// Follows the struts' clearance (`None`: not followed).
    clearance: Option<Tracker>,
    /// A static stage that changes rest lengths, or any stage of a structure with clustered
    /// cables (their slip shares the rest lengths out anew at every step): its frames
    /// carry them (a transient's carry them when its Newmark run is actuated).
    pub actuated: bool,
}

/// The largest out-of-balance of the whole structure over a stage's recorded steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EquilibriumCheck {
    /// max over steps of |Σ reactions + Σ applied − Σ inertia − Σ αM damping| [N].
    pub max_error: f64,
    /// max over steps of that error over max(|Σ applied|, |Σ reactions|, max |N|) of the
    /// same step.
    pub max_relative: f64,
}

/// The motion of a dynamic step, for the frame's velocities, reactions and check.
#[derive(Clone, Copy)]
pub struct Motion<'n, 'a> {
    pub newmark: &'n Newmark<'a>,
    /// The step's member forces and node velocities, updated by the caller (who reads them
    /// for its summary too: found once per step).
    pub axial: &'n AxialForces,
    /// Acceleration of the supports (the base) [m/s²]: zero unless the ground moves.
    pub support_acceleration: Vector3<f64>,
}

impl FrameBuilder {
    /// For a stage on `structure` whose free directions are `dofs`: every other direction
    /// is constrained (a support, or prescribed by the stage).
    pub fn new(structure: &Structure, dofs: &DofMap) -> Self {
        let model = &structure.model;
        let nodes = model.node_count();
        let prescribed: Vec<(usize, usize)> = (0..nodes)
            .flat_map(|n| (0..3).map(move |a| (n, a)))
            .filter(|&(n, a)| dofs.free(n, a).is_none() && !model.nodes[n].support[a])
            .collect();
        let constraints = Constraints::new(model, &prescribed);
        let mut constrained = vec![false; nodes];
        constraints.0.iter().for_each(|c| constrained[c.node] = true);
        let constrained_members = (0..model.members.len())
            .filter(|&m| model.members[m].nodes.iter().any(|&n| constrained[n]))
            .collect();
        FrameBuilder {
            constrained_members,
            reactions: vec![0.0; constraints.len()],
            constraints,
            masses: (0..nodes).map(|n| structure.masses.get(n).copied().unwrap_or(0.0)).collect(),
            statics: Vec::new(),
            lengths: Vec::new(),
            damping: vec![0.0; 3 * nodes],
            check: EquilibriumCheck::default(),
            modes: None,
            clearance: structure.struts.clone().map(Tracker::new),
            actuated: !structure.model.clusters.is_empty(),
        }
    }

    /// Follows the clearance through step `step` at `time` (positions `x`), which is not
    /// recorded: its events go with the next recorded frame.
    pub fn observe(&mut self, x: &[Vector3<f64>], step: usize, time: f64) {
        if let Some(tracker) = &mut self.clearance {
            tracker.observe(x, step, time);
        }
    }

    /// Tells `recorder` that `stage` begins, with its constrained directions.
    pub fn begin(&self, recorder: &mut dyn Recorder, stage: &Stage) -> RecordResult {
        recorder.begin_stage(stage, &self.constraints)
    }

    /// Records the static state of `asm` under `applied` (on every node) as step `step`
    /// at `time` (folding: the applied fraction).
    pub fn record(
        &mut self,
        recorder: &mut dyn Recorder,
        asm: &Assembly,
        step: usize,
        time: f64,
        energy: Energy,
        applied: &[Vector3<f64>],
    ) -> RecordResult {
        self.emit(recorder, asm, step, time, energy, applied, None)
    }

    /// Records the converged step of `motion.newmark` (its time and energy) under `applied`.
    pub fn record_motion(&mut self, recorder: &mut dyn Recorder, motion: Motion, step: usize, applied: &[Vector3<f64>]) -> RecordResult {
        let nm = motion.newmark;
        self.emit(recorder, &nm.asm, step, nm.time, nm.energy(), applied, Some(motion))
    }

    /// Fills the frame's buffers and hands it to `recorder`.
    #[allow(clippy::too_many_arguments)] // the private join of `record` and `record_motion`
    fn emit(
        &mut self,
        recorder: &mut dyn Recorder,
        asm: &Assembly,
        step: usize,
        time: f64,
        energy: Energy,
        applied: &[Vector3<f64>],
        motion: Option<Motion>,
    ) -> RecordResult {
        // Σ over the structure of applied + reactions − inertia − αM damping.
        let mut balance: Vector3<f64> = applied.iter().sum();
        let applied_sum = balance.norm();
        self.damping.fill(0.0);
        let mut base = Vector3::zeros();
        if let Some(Motion {
            newmark: nm,
            axial,
            support_acceleration,
        }) = motion
        {
            for (i, &vi) in nm.v.iter().enumerate() {
                let (_, a) = asm.dofs.owner(i);
                balance[a] -= nm.mass[i] * (nm.a[i] + nm.rayleigh().alpha * vi);
            }
            nm.member_damping_force(&self.constrained_members, &axial.velocities, &mut self.damping);
            base = support_acceleration;
        } else {
            self.statics.clear();
            self.statics.extend(asm.states.iter().map(|s| s.force));
        }
        let forces = motion.map_or(&self.statics[..], |m| &m.axial.total[..]);
        let mut reaction_sum = Vector3::zeros();
        for (r, c) in self.reactions.iter_mut().zip(&self.constraints.0) {
            let (i, inertia) = (3 * c.node + c.axis, self.masses[c.node] * base[c.axis]);
            *r = asm.p[i] + self.damping[i] - applied[c.node][c.axis] + inertia;
            reaction_sum[c.axis] += *r;
            balance[c.axis] -= inertia;
        }
        // The ground's contact force is a reaction too, at no constrained direction.
        balance += reaction_sum + asm.contact.as_ref().map_or(Vector3::zeros(), |c| c.ground_force());
        let error = balance.norm();
        let max_force = forces.iter().fold(0.0_f64, |m, n| m.max(n.abs()));
        let scale = applied_sum.max(reaction_sum.norm()).max(max_force);
        let relative = if scale > 0.0 { error / scale } else { error };
        self.check.max_error = self.check.max_error.max(error);
        self.check.max_relative = self.check.max_relative.max(relative);
        self.lengths.clear();
        self.lengths.extend(asm.states.iter().map(|s| s.length));
        // The state was checked before it was committed; what is derived from it here
        // (reactions, their sum) is too, so that no complete case holds a non-finite value.
        if let Some(what) = non_finite_loads(asm.model, &self.constraints, &self.reactions, applied, error) {
            return Err(format!("step {step}: {what} is not finite; the stage stops rather than record it").into());
        }
        let nearest = self.clearance.as_mut().map(|t| t.observe(&asm.x, step, time));
        let recorded = recorder.frame(&Frame {
            step,
            time,
            positions: &asm.x,
            velocities: motion.map(|m| m.axial.velocities.as_slice()),
            forces,
            viscous_forces: motion.map(|m| m.axial.viscous.as_slice()),
            lengths: &self.lengths,
            rest_lengths: (self.actuated || motion.is_some_and(|m| m.newmark.is_actuated())).then_some(&asm.rest[..]),
            energy,
            applied,
            reactions: &self.reactions,
            equilibrium_error: error,
            modes: self.modes.as_ref().map(|(omega2, lowest)| FrameModes { omega2, lowest }),
            clearance: self.clearance.as_ref().zip(nearest).map(|(t, nearest)| FrameClearance {
                nearest,
                events: t.events(),
            }),
            contacts: asm.contact.as_ref().map_or(&[][..], |c| &c.active[..]),
        });
        if let Some(tracker) = &mut self.clearance {
            tracker.clear_events();
        }
        recorded
    }
}

/// The first non-finite value a frame derives from a finite state, named ("the reaction
/// at node `b0` direction z", "the applied load on node `t3`", "the equilibrium error").
fn non_finite_loads(model: &Model, constraints: &Constraints, reactions: &[f64], applied: &[Vector3<f64>], error: f64) -> Option<String> {
    if let Some(c) = reactions.iter().zip(&constraints.0).find(|(r, _)| !r.is_finite()).map(|(_, c)| c) {
        return Some(format!(
            "the reaction at node `{}` direction {}",
            model.nodes[c.node].id, AXES[c.axis]
        ));
    }
    if let Some(n) = applied.iter().position(|f| !f.iter().all(|x| x.is_finite())) {
        return Some(format!("the applied load on node `{}`", model.nodes[n].id));
    }
    (!error.is_finite()).then(|| "the equilibrium error".to_string())
}

/// The first non-finite value of a converged state, named ("node `t3` position z",
/// "member `side0_1` force", "kinetic energy"): a state with one is never committed or
/// recorded (f64::max and comparisons let NaN through silently).
pub fn non_finite(asm: &Assembly, velocities: Option<&[f64]>, energy: &Energy) -> Option<String> {
    // Every step's check: a sum is finite where every term is (NaN and ±∞ carry through a
    // sum; finite terms that overflow it only send it on to the search, which finds none).
    let Energy {
        kinetic,
        strain,
        contact,
        damping,
        external,
        actuation,
    } = *energy;
    let sum = asm.x.iter().map(|x| x.sum()).sum::<f64>()
        + velocities.map_or(0.0, |v| v.iter().sum())
        + asm.states.iter().map(|s| s.force).sum::<f64>()
        + (kinetic + strain + contact + damping + external + actuation);
    if sum.is_finite() {
        return None;
    }
    let model = asm.model;
    if let Some((n, a)) = (0..model.node_count())
        .flat_map(|n| (0..3).map(move |a| (n, a)))
        .find(|&(n, a)| !asm.x[n][a].is_finite())
    {
        return Some(format!("node `{}` position {}", model.nodes[n].id, AXES[a]));
    }
    if let Some(i) = velocities.and_then(|v| v.iter().position(|v| !v.is_finite())) {
        return Some(format!("velocity of {}", asm.dofs.label(model, i)));
    }
    if let Some(m) = asm.states.iter().position(|s| !s.force.is_finite()) {
        return Some(format!("member `{}` force", model.members[m].id));
    }
    [
        ("kinetic", kinetic),
        ("strain", strain),
        ("damping", damping),
        ("external work", external),
        ("actuator work", actuation),
    ]
    .into_iter()
    .find(|(_, e)| !e.is_finite())
    .map(|(name, _)| format!("{name} energy"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::{ForceLaw, LinearElastic};
    use crate::model::generate::TowerSpec;
    use crate::record::StageKind;
    use crate::tsm::{DofMap, Elements};
    use std::sync::Arc;

    /// The frame of the last `record` call: its reactions and equilibrium error.
    #[derive(Default)]
    struct LastFrame {
        constraints: Constraints,
        reactions: Vec<f64>,
        applied: Vec<Vector3<f64>>,
        equilibrium_error: f64,
    }

    impl Recorder for LastFrame {
        fn begin_stage(&mut self, _stage: &Stage, constraints: &Constraints) -> RecordResult {
            self.constraints = constraints.clone();
            Ok(())
        }
        fn frame(&mut self, frame: &Frame) -> RecordResult {
            self.reactions = frame.reactions.to_vec();
            self.applied = frame.applied.to_vec();
            self.equilibrium_error = frame.equilibrium_error;
            Ok(())
        }
    }

    /// A 3-strut prism under its weight: form-found (Table 1's measure potentials),
    /// substituted by elastic members carrying 10× the form-found forces, with masses set by
    /// hand (0.4 kg/m of member, 2 kg on the top node `t0`), gravity −9.81 m/s² along z and
    /// a 5 N sideways dead load on `t1`; its static equilibrium is solved by
    /// `StaticEquilibrium` + Newton. The reactions of its six support directions must carry
    /// the whole load: Σ reactions = −Σ (m g + dead load) per axis.
    ///
    /// Tolerance 1e-10 relative (issue 14) to the frame's scale (the largest of |Σ applied|,
    /// |Σ reactions| and max |N|): Σ R + Σ f is the sum of the Newton residual over the nine
    /// free directions, each ≤ 1e-10 of the force scale at convergence and in practice far
    /// smaller after the last quadratic step; a reaction that missed a member, the weight of
    /// a supported node or counted the load with the wrong sign is off by ≥ 1 N here.
    #[test]
    fn prism_reactions_carry_its_weight() {
        use crate::solve::{newton, NewtonWorkspace};
        use crate::stage::formfind::SelfEquilibrium;
        use crate::stage::measure::MeasureSpec;
        use crate::stage::substitute::{balanced_forces, substitute};
        use crate::stage::{Analysis, Settings, StaticEquilibrium};
        use crate::tsm::tangent_sparsity;

        let model = TowerSpec {
            struts: 3,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let settings = Settings::default();
        let measure = Structure::massless(model.clone(), MeasureSpec::default().elements(&model).unwrap());
        let start = crate::structure::State::at_rest(model.positions());
        let (shape, found) = SelfEquilibrium::FORM_FINDING
            .run(&measure, start, &settings, &mut crate::record::NoRecorder)
            .unwrap();
        let forces = balanced_forces(&model, &shape.positions, &found.forces);
        let laws: Vec<Arc<dyn ForceLaw>> = model
            .members
            .iter()
            .map(|m| -> Arc<dyn ForceLaw> {
                let ea = if m.kind == crate::model::MemberKind::Strut { 1e8 } else { 1e6 };
                Arc::new(LinearElastic { ea, tension_only: false })
            })
            .collect();
        let elements = substitute(&model, &shape.positions, &forces, laws, 10.0).unwrap().elements;
        let top = model.nodes.iter().position(|n| n.id == "t0_0").unwrap();
        let mut point = vec![0.0; model.node_count()];
        point[top] = 2.0;
        let mut structure = Structure::with_lumped_masses(model.clone(), elements, &vec![0.4; model.members.len()], &point);
        structure.gravity = Vector3::new(0.0, 0.0, -9.81);
        structure.dead_load = vec![Vector3::zeros(); model.node_count()];
        structure.dead_load[model.node_count() - 2] = Vector3::new(5.0, 0.0, 0.0);
        let applied = structure.constant_load();

        let dofs = DofMap::new(&model, &[]);
        let load: Vec<f64> = (0..dofs.len())
            .map(|i| {
                let (n, a) = dofs.owner(i);
                applied[n][a]
            })
            .collect();
        let asm = Assembly::new(&model, &structure.elements, &dofs, shape.positions);
        let mut problem = StaticEquilibrium { asm, load };
        let mut u = problem.asm.free_coordinates();
        let mut ws = NewtonWorkspace::new(dofs.len(), &settings.newton, false, || tangent_sparsity(&model, &dofs));
        newton(&mut problem, &mut u, &settings.newton, model.size(), &mut ws).unwrap();
        problem.asm.set_free(&u);

        let mut frames = FrameBuilder::new(&structure, &dofs);
        let mut last = LastFrame::default();
        frames.begin(&mut last, &Stage::of(StageKind::Folding)).unwrap();
        frames.record(&mut last, &problem.asm, 1, 1.0, Energy::default(), &applied).unwrap();
        assert_eq!(last.constraints.len(), model.support_count());
        assert!(last.constraints.0.iter().all(|c| !c.prescribed));
        let total: Vector3<f64> = applied.iter().sum();
        let mut reactions = Vector3::zeros();
        for (c, r) in last.constraints.0.iter().zip(&last.reactions) {
            reactions[c.axis] += r;
        }
        let max_force = problem.asm.states.iter().fold(0.0_f64, |m, s| m.max(s.force.abs()));
        let scale = total.norm().max(reactions.norm()).max(max_force);
        let error = (reactions + total).norm();
        eprintln!(
            "prism under gravity: Σ applied {total:?} N, Σ reactions {reactions:?} N, |Σ R + Σ f| {error:.2e} N = {:.2e} of {scale:.3e} N; frame's check {:.2e} N, summary {:?}",
            error / scale,
            last.equilibrium_error,
            frames.check
        );
        assert!(total.z < -9.81 * 2.0, "the weight includes the hub mass");
        assert!(error <= 1e-10 * scale, "Σ R + Σ f = {error:.3e} N vs scale {scale:.3e} N");
        assert!(last.equilibrium_error <= 1e-10 * scale);
        assert!(frames.check.max_relative <= 1e-10);
        // The frame records what it was given.
        assert_eq!(last.applied, applied);
    }

    /// A non-finite reaction, applied load or equilibrium error is found and named; finite
    /// ones pass.
    #[test]
    fn names_a_non_finite_reaction_or_load() {
        let model = TowerSpec {
            struts: 3,
            ..TowerSpec::paper()
        }
        .build();
        let constraints = Constraints::new(&model, &[]);
        let mut reactions = vec![1.0; constraints.len()];
        let mut applied = vec![Vector3::new(0.0, 0.0, -1.0); model.node_count()];
        assert_eq!(non_finite_loads(&model, &constraints, &reactions, &applied, 0.0), None);
        assert_eq!(
            non_finite_loads(&model, &constraints, &reactions, &applied, f64::NAN).as_deref(),
            Some("the equilibrium error")
        );
        applied[2].x = f64::INFINITY;
        assert_eq!(
            non_finite_loads(&model, &constraints, &reactions, &applied, 0.0).unwrap(),
            format!("the applied load on node `{}`", model.nodes[2].id)
        );
        reactions[1] = f64::NAN;
        let c = constraints.0[1];
        assert_eq!(
            non_finite_loads(&model, &constraints, &reactions, &applied, 0.0).unwrap(),
            format!("the reaction at node `{}` direction {}", model.nodes[c.node].id, AXES[c.axis])
        );
    }

    /// Each kind of non-finite value is found and named; a finite state passes.
    #[test]
    fn names_the_first_non_finite_value() {
        let model = TowerSpec {
            struts: 3,
            ..TowerSpec::paper()
        }
        .build();
        let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
            ea: 1e5,
            tension_only: false,
        });
        let elements = Elements {
            laws: vec![law; model.members.len()],
            rest: vec![5.0; model.members.len()],
        };
        let dofs = DofMap::new(&model, &[]);
        let mut x = model.positions();
        let asm = Assembly::new(&model, &elements, &dofs, x.clone());
        let v = vec![0.0; dofs.len()];
        assert_eq!(non_finite(&asm, Some(&v), &Energy::default()), None);
        let mut bad_v = v.clone();
        bad_v[4] = f64::INFINITY;
        assert_eq!(
            non_finite(&asm, Some(&bad_v), &Energy::default()).unwrap(),
            format!("velocity of {}", dofs.label(&model, 4))
        );
        let energy = Energy {
            kinetic: f64::NAN,
            ..Energy::default()
        };
        assert_eq!(non_finite(&asm, Some(&v), &energy).unwrap(), "kinetic energy");
        x[5].y = f64::NAN;
        let asm = Assembly::new(&model, &elements, &dofs, x);
        assert_eq!(
            non_finite(&asm, None, &Energy::default()).unwrap(),
            format!("node `{}` position y", model.nodes[5].id)
        );
    }
}
