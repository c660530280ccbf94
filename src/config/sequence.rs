//! From the config's stages to the planned list ([`crate::stage::sequence`]): the
//! `stages` entries as written, or the paper's sections in the paper's order (their
//! shorthand). A listed entry is planned by its kind's `StageSpec` (`config/kinds`).

use super::kinds::{eigen_stage, folding, static_stage, transient, EntryPlan, StageSpec};
use super::loading::{StartFrom, StaticSpec};
use super::schema::{CaseConfig, TransientSpec};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::stage::sequence::{PlannedStage, PlannedTransient};

/// A stage section of the config: its field path (`deployment`, `stages[2].transient`),
/// the stage's name and its settings.
pub(super) type Section<'a> = (String, &'a str, &'a dyn StageSpec);

impl CaseConfig {
    /// Every stage section the config gives: the paper's (`static` as written, not the
    /// gravity-only default) or the `stages` entries, in order. Checks, limits and table
    /// reading iterate this, one loop for both forms.
    pub(super) fn stage_sections(&self) -> Vec<Section<'_>> {
        let paper: [(&str, Option<&dyn StageSpec>); 5] = [
            ("static", self.statics.as_ref().map(|s| s as _)),
            ("eigen", self.eigen.as_ref().map(|s| s as _)),
            ("free_vibration", self.free_vibration.as_ref().map(|s| s as _)),
            ("folding", self.folding.as_ref().map(|s| s as _)),
            ("deployment", self.deployment.as_ref().map(|s| s as _)),
        ];
        let mut out: Vec<Section> = paper
            .into_iter()
            .filter_map(|(name, spec)| spec.map(|spec| (name.to_string(), name, spec)))
            .collect();
        for (k, entry) in self.stages.iter().enumerate() {
            if let Ok(spec) = entry.spec() {
                out.push((format!("stages[{k}].{}", spec.key()), &entry.name, spec));
            }
        }
        out
    }

    /// Every transient section with its field path, to change in place (tables read in).
    pub fn transients_mut(&mut self) -> Vec<(String, &mut TransientSpec)> {
        let mut out: Vec<(String, &mut TransientSpec)> = Vec::new();
        for (name, t) in [("free_vibration", &mut self.free_vibration), ("deployment", &mut self.deployment)] {
            out.extend(t.as_mut().map(|t| (name.to_string(), t)));
        }
        for (k, entry) in self.stages.iter_mut().enumerate() {
            out.extend(entry.transient.as_mut().map(|t| (format!("stages[{k}].transient"), t)));
        }
        out
    }

    /// The name of the state every case starts with: `formfinding`, or `equilibrium` for a
    /// model given with rest lengths.
    pub fn shape_name(&self) -> &'static str {
        if self.formfinding.is_some() {
            StageKind::FormFinding.name()
        } else {
            StageKind::Equilibrium.name()
        }
    }

    /// The stages after the shape: the `stages` list, or the paper's sections.
    pub fn stage_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        if self.stages.is_empty() {
            self.paper_plan(model)
        } else {
            self.listed_plan(model)
        }
    }

    /// The paper's sequence: `static` (or gravity alone with its defaults) from the shape;
    /// `eigen` at the equilibrium it reached, whose damping the `damped` transients use;
    /// free vibration from that equilibrium (or as `initial.from` says); folding from the
    /// equilibrium; deployment from the folded state (or as `initial.from` says), its
    /// shape compared with the equilibrium's.
    fn paper_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        let mut plan = Vec::new();
        let statics = match (&self.statics, self.gravity) {
            (Some(spec), _) => Some(spec.clone()),
            (None, Some(_)) => Some(StaticSpec::default()),
            (None, None) => None,
        };
        if let Some(spec) = statics {
            let stage = static_stage(&spec, Stage::of(StageKind::Static), false, model)?;
            plan.push(PlannedStage {
                from: 0,
                analysis: Box::new(stage),
            });
        }
        let equilibrium = plan.len();
        let eigen = self.eigen.as_ref().map(|spec| {
            plan.push(PlannedStage {
                from: equilibrium,
                analysis: Box::new(eigen_stage(spec, Stage::of(StageKind::Eigen))),
            });
            plan.len() - 1
        });
        let mut folded = equilibrium;
        let start = |spec: &TransientSpec, default, folded, previous| match spec.initial.as_ref().and_then(|i| i.from).unwrap_or(default) {
            StartFrom::Equilibrium => equilibrium,
            StartFrom::Folded => folded,
            StartFrom::Previous => previous,
        };
        let paper_transient = |spec: &TransientSpec, name: &str, from: usize, compare_to: Option<usize>| -> Result<PlannedStage> {
            Ok(PlannedStage {
                from,
                analysis: Box::new(PlannedTransient {
                    stage: transient(spec, Stage::new(StageKind::Transient, name), model)?,
                    rayleigh_from: eigen.filter(|_| spec.damped),
                    compare_to,
                }),
            })
        };
        if let Some(spec) = &self.free_vibration {
            let from = start(spec, StartFrom::Equilibrium, folded, plan.len());
            plan.push(paper_transient(spec, "free_vibration", from, None)?);
        }
        if let Some(spec) = &self.folding {
            plan.push(PlannedStage {
                from: equilibrium,
                analysis: Box::new(folding(spec, Stage::of(StageKind::Folding), model)?),
            });
            folded = plan.len();
        }
        if let Some(spec) = &self.deployment {
            let from = start(spec, StartFrom::Folded, folded, plan.len());
            plan.push(paper_transient(spec, "deployment", from, Some(equilibrium))?);
        }
        Ok(plan)
    }

    /// The `stages` entries in order; names are looked up among the earlier ones (an
    /// unknown one is an error here too, for a config `validate` has not seen).
    fn listed_plan(&self, model: &Model) -> Result<Vec<PlannedStage>> {
        let mut names = vec![self.shape_name()];
        let mut plan: Vec<PlannedStage> = Vec::new();
        for (k, entry) in self.stages.iter().enumerate() {
            let error = |reason: String| Error::Stage {
                stage: entry.name.as_str().into(),
                reason,
            };
            let spec = entry.spec().map_err(error)?;
            let mut context = EntryPlan {
                model,
                from: k,
                names: &names,
                plan: &plan,
            };
            if let Some(from) = &entry.from {
                context.from = context.find(from).map_err(error)?;
            }
            let analysis = spec.plan(Stage::new(spec.kind(), &entry.name), &context)?;
            plan.push(PlannedStage {
                from: context.from,
                analysis,
            });
            names.push(&entry.name);
        }
        Ok(plan)
    }
}
