//! A time-stepping stage (free vibration, deployment): Newmark from a given state under a
//! nodal load, every converged step recorded, with the figures the checks need.

use crate::dynamics::{DampingTangent, Newmark, NewmarkParams, NodalLoad, Rayleigh};
use crate::error::{Error, Result};
use crate::model::{MemberKind, Model};
use crate::record::{Frame, Recorder, Stage};
use crate::solve::NewtonSettings;
use crate::tsm::{Assembly, DofMap, Elements};
use nalgebra::Vector3;

/// Settings of one transient stage.
#[derive(Clone, Debug)]
pub struct Transient<'a> {
    pub stage: Stage,
    pub params: NewmarkParams,
    pub rayleigh: Rayleigh,
    pub tangent: DampingTangent,
    pub load: Option<&'a NodalLoad>,
    pub newton: NewtonSettings,
    /// Record every `every`-th step (and the last).
    pub every: usize,
}

/// Figures of a finished transient stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TransientSummary {
    pub steps: usize,
    pub newton_iterations: usize,
    /// Tangent factorizations (fewer than iterations where they are reused).
    pub factorizations: usize,
    pub max_kinetic: f64,
    pub final_kinetic: f64,
    /// max over steps of |KE + SE + D − W − E0| [J].
    pub max_balance_error: f64,
    /// max over steps of max(KE, SE) [J], the scale of the balance error.
    pub max_energy: f64,
    /// Largest rise of KE + SE from one step to the next once the load has ended [J]
    /// (damped: never positive beyond round-off).
    pub max_mechanical_rise: f64,
    /// Largest cable stretch l/l0 over the stage.
    pub max_cable_stretch: f64,
    /// Largest strut compression over the stage [N] (positive number).
    pub max_strut_compression: f64,
    /// Wall time of the stage, recording included [s].
    pub wall_seconds: f64,
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
}

impl Transient<'_> {
    /// Runs from positions `x0` at rest.
    pub fn run(
        &self,
        model: &Model,
        elements: &Elements,
        x0: Vec<Vector3<f64>>,
        node_mass: &[f64],
        recorder: &mut dyn Recorder,
    ) -> Result<TransientSummary> {
        let stage_name = self.stage.name();
        let dofs = DofMap::new(model, &[]);
        let load_free = |t: f64, f: &mut [f64]| {
            f.fill(0.0);
            if let Some(load) = self.load {
                load.add_free(t, &dofs, f);
            }
        };
        let mass = super::eigen::free_masses(&dofs, node_mass);
        let started = std::time::Instant::now();
        let n = dofs.len();
        let mut f0 = vec![0.0; n];
        load_free(0.0, &mut f0);
        let asm = Assembly::new(model, elements, &dofs, x0);
        let mut nm = Newmark::new(asm, mass, vec![0.0; n], f0, self.params, self.rayleigh, self.tangent, self.newton);
        let steps = (self.params.duration / self.params.dt).round() as usize;
        let load_end = self.load.map_or(0.0, |l| l.duration);
        let mut summary = TransientSummary {
            steps,
            ..Default::default()
        };
        let rec = |e: Box<dyn std::error::Error + Send + Sync>| Error::Stage {
            stage: stage_name,
            reason: format!("recording failed: {e}"),
        };
        recorder.begin_stage(self.stage).map_err(rec)?;
        let label = |d: usize| dofs.label(model, d);
        // Frame buffers, reused for every recorded step.
        let (mut velocities, mut forces, mut lengths) = (vec![Vector3::zeros(); model.node_count()], Vec::new(), Vec::new());
        let mut record = |nm: &Newmark, step: usize, recorder: &mut dyn Recorder| -> Result<()> {
            for (i, &v) in nm.v.iter().enumerate() {
                let (n, a) = dofs.owner(i);
                velocities[n][a] = v;
            }
            forces.clear();
            forces.extend(nm.asm.states.iter().map(|s| s.force));
            lengths.clear();
            lengths.extend(nm.asm.states.iter().map(|s| s.length));
            recorder
                .frame(&Frame {
                    step,
                    time: nm.time,
                    positions: &nm.asm.x,
                    velocities: Some(&velocities),
                    forces: &forces,
                    lengths: &lengths,
                    energy: nm.energy,
                })
                .map_err(rec)
        };
        record(&nm, 0, recorder)?;
        let mut mechanical = nm.energy.kinetic + nm.energy.strain;
        for step in 1..=steps {
            let report = nm.advance(self.params.dt, &load_free, &label).map_err(|source| Error::Solve {
                stage: stage_name,
                step: Some(step),
                time: Some(step as f64 * self.params.dt),
                source,
            })?;
            // Re-anchor time to the step grid so that long runs do not drift.
            nm.time = step as f64 * self.params.dt;
            summary.newton_iterations += report.iterations;
            summary.factorizations += report.factorizations;
            let e = nm.energy;
            summary.max_kinetic = summary.max_kinetic.max(e.kinetic);
            summary.max_energy = summary.max_energy.max(e.kinetic.max(e.strain));
            summary.max_balance_error = summary.max_balance_error.max(nm.balance_error());
            let now = e.kinetic + e.strain;
            if nm.time - self.params.dt > load_end {
                summary.max_mechanical_rise = summary.max_mechanical_rise.max(now - mechanical);
            }
            mechanical = now;
            for ((mem, st), l0) in model.members.iter().zip(&nm.asm.states).zip(&elements.rest) {
                match mem.kind {
                    MemberKind::Cable => summary.max_cable_stretch = summary.max_cable_stretch.max(st.length / l0),
                    MemberKind::Strut => summary.max_strut_compression = summary.max_strut_compression.max(-st.force),
                }
            }
            if step % self.every == 0 || step == steps {
                record(&nm, step, recorder)?;
            }
        }
        recorder.end_stage(self.stage).map_err(rec)?;
        summary.final_kinetic = nm.energy.kinetic;
        summary.wall_seconds = started.elapsed().as_secs_f64();
        summary.final_positions = nm.asm.x;
        Ok(summary)
    }
}
