use crate::dynamics::Energy;
use crate::record::{Frame, RecordResult, Recorder};
use crate::tsm::Assembly;
use nalgebra::Vector3;

/// Builds the frames a stage records from its assembly, with buffers reused for every
/// recorded step (a time step allocates nothing).
pub struct FrameBuilder {
    velocities: Vec<Vector3<f64>>,
    forces: Vec<f64>,
    lengths: Vec<f64>,
}

impl FrameBuilder {
    pub fn new(nodes: usize) -> Self {
        FrameBuilder {
            velocities: vec![Vector3::zeros(); nodes],
            forces: Vec::new(),
            lengths: Vec::new(),
        }
    }

    /// Records the state of `asm` as step `step` at `time`; `velocities` on the free DOFs
    /// of `asm` (`None` for a static stage).
    pub fn record(
        &mut self,
        recorder: &mut dyn Recorder,
        asm: &Assembly,
        step: usize,
        time: f64,
        velocities: Option<&[f64]>,
        energy: Energy,
    ) -> RecordResult {
        if let Some(v) = velocities {
            for (i, &vi) in v.iter().enumerate() {
                let (n, a) = asm.dofs.owner(i);
                self.velocities[n][a] = vi;
            }
        }
        self.forces.clear();
        self.forces.extend(asm.states.iter().map(|s| s.force));
        self.lengths.clear();
        self.lengths.extend(asm.states.iter().map(|s| s.length));
        recorder.frame(&Frame {
            step,
            time,
            positions: &asm.x,
            velocities: velocities.map(|_| self.velocities.as_slice()),
            forces: &self.forces,
            lengths: &self.lengths,
            energy,
        })
    }
}

/// The first non-finite value of a converged state, named ("node `t3` position z",
/// "member `side0_1` force", "kinetic energy"): a state with one is never committed or
/// recorded (f64::max and comparisons let NaN through silently).
pub fn non_finite(asm: &Assembly, velocities: Option<&[f64]>, energy: &Energy) -> Option<String> {
    let model = asm.model;
    if let Some((n, a)) = (0..model.node_count())
        .flat_map(|n| (0..3).map(move |a| (n, a)))
        .find(|&(n, a)| !asm.x[n][a].is_finite())
    {
        return Some(format!("node `{}` position {}", model.nodes[n].id, crate::model::AXES[a]));
    }
    if let Some(i) = velocities.and_then(|v| v.iter().position(|v| !v.is_finite())) {
        return Some(format!("velocity of {}", asm.dofs.label(model, i)));
    }
    if let Some(m) = asm.states.iter().position(|s| !s.force.is_finite()) {
        return Some(format!("member `{}` force", model.members[m].id));
    }
    let Energy {
        kinetic,
        strain,
        damping,
        external,
    } = *energy;
    [
        ("kinetic", kinetic),
        ("strain", strain),
        ("damping", damping),
        ("external work", external),
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
    use crate::tsm::{DofMap, Elements};
    use std::sync::Arc;

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
