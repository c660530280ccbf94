//! `hold`: the loads of its start held while members' rest lengths change in static steps
//! ([`crate::stage::hold`]), the quasi-static counterpart of a transient's `actuation`.

use super::transient::check_member_sets;
use super::{EntryCheck, EntryPlan, StageSpec, Steps};
use crate::config::loading::{six, ten};
use crate::config::validate::{check_cuts, check_steps, Problems};
use crate::dynamics::{Actuator, TimeFunction};
use crate::error::Result;
use crate::record::{Stage, StageKind};
use crate::stage::hold::Hold;
use crate::stage::sequence::SequenceStage;

/// Rest lengths changed under the loads held, in static steps: each step a static
/// equilibrium, the rest lengths changed linearly over the steps.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HoldSpec {
    /// The changes, each of its own members.
    pub actuation: Vec<RestChangeSpec>,
    /// Static steps (the change is linear over them).
    #[serde(default = "ten")]
    pub steps: usize,
    /// Halvings of a step whose Newton solve fails.
    #[serde(default = "six")]
    pub max_cuts: u32,
}

/// Members whose rest length ends at `scale` times the start's.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RestChangeSpec {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
    /// Member groups (`model.members[].groups`; a tower's `vertical`, `side0`, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<String>,
    /// Rest length at the end over that at the start (0.8: 20 % shorter); positive.
    pub scale: f64,
}

impl StageSpec for HoldSpec {
    fn kind(&self) -> StageKind {
        StageKind::Hold
    }

    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems) {
        if self.steps == 0 {
            p.add(format!("{at}.steps"), "is 0; must be ≥ 1");
        }
        check_steps(&format!("{at}.steps"), self.steps as f64, "is", p);
        check_cuts(&format!("{at}.max_cuts"), self.max_cuts, p);
        if self.actuation.is_empty() {
            p.add(
                format!("{at}.actuation"),
                "changes no rest length: give at least one `{members or groups, scale}`",
            );
        }
        for (k, a) in self.actuation.iter().enumerate() {
            p.positive(&format!("{at}.actuation[{k}].scale"), a.scale);
        }
        let sets = self.actuation.iter().map(|a| (&a.members[..], &a.groups[..]));
        check_member_sets(&format!("{at}.actuation"), sets, entry.model, p);
    }

    /// From any state but the shape, it starts under the structure's constant load.
    fn plan(&self, stage: Stage, entry: &EntryPlan) -> Result<Box<dyn SequenceStage>> {
        let mut actuators = Vec::new();
        for a in &self.actuation {
            actuators.push(Actuator {
                members: entry.model.member_set(&a.members, &a.groups)?,
                scale: a.scale,
                // Of the stage's fraction s: linear from 0 to 1.
                time: TimeFunction::Ramp { duration: 1.0 },
            });
        }
        Ok(Box::new(Hold {
            stage,
            actuators,
            steps: self.steps,
            max_cuts: self.max_cuts,
            start_loaded: entry.from != 0,
        }))
    }

    fn steps(&self, _every: usize) -> Option<Steps> {
        Some(Steps::fixed(self.steps as f64))
    }
}
