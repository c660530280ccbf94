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
