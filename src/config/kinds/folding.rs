//! `folding`: prescribed displacements of node groups in static steps
//! ([`crate::stage::fold`]).

use super::{EntryCheck, EntryPlan, StageSpec, Steps};
use crate::config::schema::{FoldSpec, FoldTarget};
use crate::config::validate::{check_cuts, check_steps, Problems};
use crate::error::Result;
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::fold::{Folding, Prescription, Target};
use crate::stage::sequence::SequenceStage;

impl StageSpec for FoldSpec {
    fn kind(&self) -> StageKind {
        StageKind::Folding
    }

    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems) {
        check_folding(at, self, entry.model, p);
    }

    fn plan(&self, stage: Stage, entry: &EntryPlan) -> Result<Box<dyn SequenceStage>> {
        Ok(Box::new(folding(self, stage, entry.model)?))
    }

    fn steps(&self, _every: usize) -> Option<Steps> {
        Some(Steps::fixed(self.steps as f64))
    }
}

/// The steps and cuts within limits; the prescribed groups (and `base`, for `to_base`)
/// and the path's eigenvalue count known to the model.
pub(in crate::config) fn check_folding(at: &str, f: &FoldSpec, model: Option<&Model>, p: &mut Problems) {
    if f.steps == 0 {
        p.add(format!("{at}.steps"), "is 0; must be ≥ 1");
    }
    check_steps(&format!("{at}.steps"), f.steps as f64, "is", p);
    check_cuts(&format!("{at}.max_cuts"), f.max_cuts, p);
    let Some(model) = model else { return };
    if let Some(k) = f.eigen {
        let dof_count = 3 * model.node_count() - model.support_count();
        if k == 0 || k > dof_count {
            p.add(
                format!("{at}.eigen"),
                format!("is {k}; must lie in 1..={dof_count} (the model's free DOF)"),
            );
        }
    }
    for (k, s) in f.prescribe.iter().enumerate() {
        if let Err(e) = model.group(&s.group) {
            p.add(format!("{at}.prescribe[{k}].group"), e.to_string());
        }
        if s.target == FoldTarget::ToBase {
            if let Err(e) = model.group("base") {
                p.add(format!("{at}.prescribe[{k}].to_base"), e.to_string());
            }
        }
    }
}

/// The folding stage `spec` describes, named `stage`.
pub(in crate::config) fn folding(spec: &FoldSpec, stage: Stage, model: &Model) -> Result<Folding> {
    let prescribe = spec
        .prescribe
        .iter()
        .map(|p| {
            let target = match p.target {
                FoldTarget::Displacement(d) => Target::Displacement(d),
                FoldTarget::ToBase => Target::LevelOf(model.group("base")?.to_vec()),
            };
            Ok(Prescription {
                nodes: model.group(&p.group)?.to_vec(),
                axis: p.axis.index(),
                target,
            })
        })
        .collect::<Result<_>>()?;
    Ok(Folding {
        stage,
        steps: spec.steps,
        max_cuts: spec.max_cuts,
        prescribe,
        modes: spec.eigen.unwrap_or(0),
    })
}
