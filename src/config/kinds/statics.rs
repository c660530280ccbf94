//! `static`: gravity and nodal loads in load steps, or a load pattern under displacement
//! control ([`crate::stage::static_load`]).

use super::{EntryCheck, EntryPlan, StageSpec, Steps};
use crate::config::loading::StaticSpec;
use crate::config::validate::{check_cuts, check_steps, Problems};
use crate::error::Result;
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::sequence::SequenceStage;
use crate::stage::static_load::{Control, StaticLoad};
use nalgebra::Vector3;

impl StageSpec for StaticSpec {
    fn kind(&self) -> StageKind {
        StageKind::Static
    }

    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems) {
        check_static(at, self, entry.gravity, entry.model, p);
    }

    /// From any state but the shape, it starts under the structure's constant load.
    fn plan(&self, stage: Stage, entry: &EntryPlan) -> Result<Box<dyn SequenceStage>> {
        Ok(Box::new(static_stage(self, stage, entry.from != 0, entry.model)?))
    }

    fn steps(&self, _every: usize) -> Option<Steps> {
        // Under displacement control gravity takes its own `steps` first.
        Some(Steps::fixed(self.steps as f64 * if self.control.is_some() { 2.0 } else { 1.0 }))
    }
}

pub(in crate::config) fn check_static(at: &str, s: &StaticSpec, gravity: bool, model: Option<&Model>, p: &mut Problems) {
    if s.steps == 0 {
        p.add(format!("{at}.steps"), "is 0; must be ≥ 1");
    }
    check_steps(&format!("{at}.steps"), s.steps as f64, "is", p);
    check_cuts(&format!("{at}.max_cuts"), s.max_cuts, p);
    if s.loads.is_empty() && !gravity {
        p.add(at, "nothing to apply: give `loads` or `gravity`");
    }
    if s.control.is_some() && s.loads.is_empty() {
        p.add(
            format!("{at}.control"),
            "displacement control scales the `loads` pattern: give `loads`",
        );
    }
    if let Some(c) = &s.control {
        if !(c.displacement != 0.0 && c.displacement.is_finite()) {
            p.add(
                format!("{at}.control.displacement"),
                format!("is {}; must be a finite number ≠ 0", c.displacement),
            );
        }
    }
    let Some(model) = model else { return };
    for (k, l) in s.loads.iter().enumerate() {
        if let Err(e) = model.node_set(&l.nodes, &l.groups) {
            p.add(format!("{at}.loads[{k}]"), e.to_string());
        }
    }
    if let Some(c) = &s.control {
        match model.nodes.iter().find(|n| n.id == c.node) {
            None => p.add(format!("{at}.control.node"), model.unknown_node(&c.node).to_string()),
            Some(n) if n.support[c.axis.index()] => p.add(
                format!("{at}.control.axis"),
                format!(
                    "node `{}` is supported in {}: control a free direction",
                    n.id,
                    crate::model::AXES[c.axis.index()]
                ),
            ),
            Some(_) => {}
        }
    }
}

/// The static-load stage `spec` describes, named `stage`; `start_loaded`: it starts
/// from a state under the structure's constant load (any but the shape), so that only
/// its own pattern is stepped.
pub(in crate::config) fn static_stage(spec: &StaticSpec, stage: Stage, start_loaded: bool, model: &Model) -> Result<StaticLoad> {
    let mut loads = Vec::new();
    if !spec.loads.is_empty() {
        loads = vec![Vector3::zeros(); model.node_count()];
        for l in &spec.loads {
            for n in model.node_set(&l.nodes, &l.groups)? {
                loads[n] += Vector3::from(l.force);
            }
        }
    }
    let control = match &spec.control {
        Some(c) => Some(Control {
            node: model.node_set(std::slice::from_ref(&c.node), &[])?[0],
            axis: c.axis.index(),
            displacement: c.displacement,
        }),
        None => None,
    };
    Ok(StaticLoad {
        stage,
        loads,
        steps: spec.steps,
        max_cuts: spec.max_cuts,
        control,
        start_loaded,
    })
}
