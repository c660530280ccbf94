//! The stage kinds a `stages` entry can give, one file each: a kind's checks, the stage it
//! plans and the steps the output estimate counts, behind [`StageSpec`]. The registry is
//! [`StageEntry::kinds`] with [`KEYS`] (and the entry's field in `schema.rs`, where serde
//! needs it); nothing else in the config names the kinds.

mod eigen;
mod folding;
mod hold;
mod statics;
mod transient;

pub(super) use eigen::{check_eigen, eigen_stage};
pub(super) use folding::{check_folding, folding};
pub use hold::{HoldSpec, RestChangeSpec};
pub(super) use statics::{check_static, static_stage};
pub(super) use transient::{check_transient, check_transient_loading, transient};

use super::schema::{EigenSpec, StageEntry};
use super::validate::Problems;
use crate::error::Result;
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::sequence::{PlannedStage, SequenceStage};

/// The key of every kind an entry can give, in [`StageEntry::kinds`]'s order.
pub const KEYS: [&str; 5] = ["static", "eigen", "transient", "folding", "hold"];

impl StageEntry {
    /// The registry: the settings of every kind the entry gives (at most one is valid).
    fn kinds(&self) -> [Option<&dyn StageSpec>; KEYS.len()] {
        [
            self.statics.as_ref().map(|s| s as &dyn StageSpec),
            self.eigen.as_ref().map(|s| s as &dyn StageSpec),
            self.transient.as_ref().map(|s| s as &dyn StageSpec),
            self.folding.as_ref().map(|s| s as &dyn StageSpec),
            self.hold.as_ref().map(|s| s as &dyn StageSpec),
        ]
    }

    /// The entry's kind and settings; Err when it gives no kind key or more than one.
    pub(in crate::config) fn spec(&self) -> std::result::Result<&dyn StageSpec, String> {
        let given: Vec<&dyn StageSpec> = self.kinds().into_iter().flatten().collect();
        match given[..] {
            [one] => Ok(one),
            _ => Err(format!(
                "stage `{}` gives {} kinds; give exactly one of {}",
                self.name,
                given.len(),
                KEYS.map(|k| format!("`{k}`")).join(", ")
            )),
        }
    }
}

/// What the config knows of one stage kind: implemented by the kind's settings type.
pub(in crate::config) trait StageSpec: std::fmt::Debug {
    /// The stage kind it plans.
    fn kind(&self) -> StageKind;

    /// The kind's key in a `stages` entry (`static`, `eigen`, …), one of [`KEYS`].
    fn key(&self) -> &'static str {
        self.kind().name()
    }

    /// Every problem of the settings of the entry at `at` (`stages[2].transient`).
    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems);

    /// Whether a later transient may take its Rayleigh damping from this stage.
    fn gives_damping(&self) -> bool {
        false
    }

    /// The stage `stage` of the entry, planned on `entry.model`.
    fn plan(&self, stage: Stage, entry: &EntryPlan) -> Result<Box<dyn SequenceStage>>;

    /// The steps it takes and records, for the output estimate (None: it records none).
    fn steps(&self, every: usize) -> Option<Steps>;

    /// Its eigen settings, for the estimate of the modes' output and memory.
    fn eigen(&self) -> Option<&EigenSpec> {
        None
    }

    /// Whether its steps' matrices are unsymmetric, so factored by the sparse LU, for the
    /// memory estimate.
    fn unsymmetric_steps(&self) -> bool {
        false
    }
}

/// What an entry's checks may refer to.
pub(in crate::config) struct EntryCheck<'a> {
    /// The model, when it builds.
    pub model: Option<&'a Model>,
    /// The names of the states before it (the shape first).
    pub names: &'a [&'a str],
    /// The names of the earlier stages that give damping.
    pub damping: &'a [&'a str],
    /// Whether the config sets gravity.
    pub gravity: bool,
    /// Whether the case has contact.
    pub contact: bool,
    /// Whether the model has a support.
    pub supported: bool,
}

/// What planning an entry may refer to.
pub(in crate::config) struct EntryPlan<'a> {
    /// The built model.
    pub model: &'a Model,
    /// Index of the state it starts from (0: the shape).
    pub from: usize,
    /// The names of the states before it (the shape first).
    pub names: &'a [&'a str],
    /// The stages planned before it.
    pub plan: &'a [PlannedStage],
}

impl EntryPlan<'_> {
    /// The state index of the earlier stage `name`.
    pub fn find(&self, name: &str) -> std::result::Result<usize, String> {
        self.names
            .iter()
            .position(|n| *n == name)
            .ok_or_else(|| format!("no earlier stage is named `{name}`"))
    }

    /// The plan index of the earlier eigen stage `name`.
    pub fn eigen(&self, name: &str) -> std::result::Result<usize, String> {
        let state = self.find(name)?;
        match state.checked_sub(1) {
            Some(i) if self.plan[i].stage().kind == StageKind::Eigen => Ok(i),
            _ => Err(format!("`rayleigh_from: {name}` is not an eigen stage")),
        }
    }
}

/// The steps a stage takes, for its estimate.
pub(in crate::config) struct Steps {
    /// How many.
    pub steps: f64,
    /// The stage's key that sets them, where an error about its output points.
    pub key: &'static str,
    /// How they follow from the settings, for the message.
    pub how: String,
    /// Time stepping (recorded every `outputs.every`-th step), or static (every step).
    pub dynamic: bool,
}

impl Steps {
    /// `steps` static steps set by the kind's `steps`.
    fn fixed(steps: f64) -> Self {
        Steps {
            steps,
            key: "steps",
            how: format!("{steps} steps"),
            dynamic: false,
        }
    }
}
