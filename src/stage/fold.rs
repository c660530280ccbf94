//! Folding by compulsory displacement (paper §5, Figures 5–8): chosen node directions are
//! driven linearly to their targets in N static steps, the rest of the structure finds
//! equilibrium by the common Newton driver at every step. A step that fails is split in
//! halves (bounded); line search did not help in a prototype, sub-stepping did.

use super::StaticEquilibrium;
use crate::error::{Error, Result};
use crate::model::{height, Model};
use crate::record::{Energy, Frame, Recorder, Stage};
use crate::solve::{newton, NewtonSettings, NewtonWorkspace, SolveError};
use crate::tsm::{Assembly, DofMap, Elements};
use nalgebra::Vector3;

/// Prescribed node directions and their targets.
#[derive(Clone, Debug, PartialEq)]
pub struct Prescribed {
    /// (node, axis, start value, target value) [m].
    pub dofs: Vec<(usize, usize, f64, f64)>,
}

/// Settings of the folding stage.
#[derive(Clone, Debug)]
pub struct Folding {
    pub steps: usize,
    /// A failed step is halved up to this many times.
    pub max_cuts: u32,
    pub newton: NewtonSettings,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FoldSummary {
    pub steps: usize,
    pub newton_iterations: usize,
    /// Steps that needed sub-stepping.
    pub cut_steps: usize,
    /// Final height over initial height (max z − min z).
    pub height_ratio: f64,
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
}

struct FoldState<'a> {
    problem: StaticEquilibrium<'a>,
    u: Vec<f64>,
    fraction: f64,
    /// Work done by the prescribed displacements (trapezoidal in the reactions).
    work: f64,
    ws: NewtonWorkspace,
}

impl Folding {
    pub fn run(
        &self,
        model: &Model,
        elements: &Elements,
        x0: Vec<Vector3<f64>>,
        prescribed: &Prescribed,
        recorder: &mut dyn Recorder,
    ) -> Result<FoldSummary> {
        let mut mask = vec![[false; 3]; model.node_count()];
        for &(n, a, _, _) in &prescribed.dofs {
            mask[n][a] = true;
        }
        let dofs = DofMap::new(model, &mask);
        let h0 = height(&x0);
        let asm = Assembly::new(model, elements, &dofs, x0);
        let u = asm.free_coordinates();
        let ws = asm.workspace(&self.newton, false);
        let mut st = FoldState {
            problem: StaticEquilibrium {
                asm,
                load: vec![0.0; dofs.len()],
            },
            u,
            fraction: 0.0,
            work: 0.0,
            ws,
        };
        let strain0 = elements.strain_energy(model, &st.problem.asm.x);
        let rec = |e: Box<dyn std::error::Error + Send + Sync>| Error::Stage {
            stage: "folding",
            reason: format!("recording failed: {e}"),
        };
        let record = |st: &FoldState, step: usize, recorder: &mut dyn Recorder| -> Result<()> {
            let asm = &st.problem.asm;
            let forces: Vec<f64> = asm.states.iter().map(|s| s.force).collect();
            let lengths: Vec<f64> = asm.states.iter().map(|s| s.length).collect();
            let energy = Energy {
                kinetic: 0.0,
                strain: elements.strain_energy(model, &asm.x) - strain0,
                damping: 0.0,
                external: st.work,
            };
            recorder
                .frame(&Frame {
                    step,
                    time: st.fraction,
                    positions: &asm.x,
                    velocities: None,
                    forces: &forces,
                    lengths: &lengths,
                    energy,
                })
                .map_err(rec)
        };
        recorder.begin_stage(Stage::Folding).map_err(rec)?;
        record(&st, 0, recorder)?;
        let mut summary = FoldSummary {
            steps: self.steps,
            ..Default::default()
        };
        let label = |d: usize| dofs.label(model, d);
        for step in 1..=self.steps {
            let target = step as f64 / self.steps as f64;
            let (iterations, cut) = self.reach(&mut st, target, 0, prescribed, &label).map_err(|source| Error::Solve {
                stage: "folding",
                step: Some(step),
                time: None,
                source,
            })?;
            summary.newton_iterations += iterations;
            summary.cut_steps += usize::from(cut);
            record(&st, step, recorder)?;
        }
        recorder.end_stage(Stage::Folding).map_err(rec)?;
        summary.height_ratio = height(&st.problem.asm.x) / h0;
        summary.final_positions = st.problem.asm.x;
        Ok(summary)
    }

    /// Moves the prescribed directions to `target` fraction and solves; on failure
    /// restores the state and tries two half-increments. Returns (iterations, was cut).
    fn reach(
        &self,
        st: &mut FoldState,
        target: f64,
        depth: u32,
        prescribed: &Prescribed,
        label: &dyn Fn(usize) -> String,
    ) -> Result<(usize, bool), SolveError> {
        let (u_old, f_old) = (st.u.clone(), st.fraction);
        let x_old = st.problem.asm.x.clone();
        let reaction = |asm: &Assembly, n: usize, a: usize| asm.p[3 * n + a];
        let before: Vec<f64> = prescribed
            .dofs
            .iter()
            .map(|&(n, a, _, _)| reaction(&st.problem.asm, n, a))
            .collect();
        for &(n, a, from, to) in &prescribed.dofs {
            st.problem.asm.x[n][a] = from + target * (to - from);
        }
        let length = st.problem.asm.model.size();
        match newton(&mut st.problem, &mut st.u, &self.newton, length, label, &mut st.ws) {
            Ok(report) => {
                st.problem.asm.set_free(&st.u);
                for (k, &(n, a, from, to)) in prescribed.dofs.iter().enumerate() {
                    let dx = (target - f_old) * (to - from);
                    st.work += 0.5 * (before[k] + reaction(&st.problem.asm, n, a)) * dx;
                }
                st.fraction = target;
                Ok((report.iterations, false))
            }
            Err(e) => {
                st.u = u_old;
                st.problem.asm.x = x_old;
                st.problem.asm.update();
                if depth >= self.max_cuts {
                    return Err(e);
                }
                let mid = 0.5 * (f_old + target);
                let (i1, _) = self.reach(st, mid, depth + 1, prescribed, label)?;
                let (i2, _) = self.reach(st, target, depth + 1, prescribed, label)?;
                Ok((i1 + i2, true))
            }
        }
    }
}
