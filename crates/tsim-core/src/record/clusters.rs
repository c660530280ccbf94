//! The case's clustered-cable record: an [`Observer`] that keeps, per clustered cable, its
//! largest tension and its largest slide over a pulley (where and when), for the case
//! summary.

use super::{Frame, ModelRecord, Observer, Stage, StageKind};
use crate::model::Cluster;

/// Keeps each clustered cable's extremes.
pub struct ClusterLog {
    stage: Stage,
    clusters: Vec<Cluster>,
    /// Pulley node ids per cluster, and the rest lengths slides count from.
    pulleys: Vec<Vec<String>>,
    reference: Vec<f64>,
    kept: Vec<ClusterSummary>,
    buffer: Vec<f64>,
}

/// One clustered cable's extremes over the case's recorded steps.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClusterSummary {
    /// The cluster's id.
    pub id: String,
    /// Largest tension (elastic + viscous) [N].
    pub max_tension: f64,
    /// The stage and step it was reached at.
    pub max_tension_stage: String,
    /// (see `max_tension_stage`)
    pub max_tension_step: usize,
    /// Largest |slide| over one of its pulleys [m] (`pulley_slide` in result.h5), signed.
    pub max_slide: f64,
    /// The pulley's node id.
    pub max_slide_pulley: String,
    /// The stage and step it was reached at.
    pub max_slide_stage: String,
    /// (see `max_slide_stage`)
    pub max_slide_step: usize,
}

impl Default for ClusterLog {
    fn default() -> Self {
        ClusterLog {
            stage: Stage::of(StageKind::FormFinding),
            clusters: Vec::new(),
            pulleys: Vec::new(),
            reference: Vec::new(),
            kept: Vec::new(),
            buffer: Vec::new(),
        }
    }
}

impl ClusterLog {
    /// Each cable's extremes; empty for a model without clustered cables.
    pub fn summary(&self) -> Vec<ClusterSummary> {
        self.kept.clone()
    }
}

impl Observer for ClusterLog {
    fn model(&mut self, record: &ModelRecord) {
        // Pulley labels per cluster (node ids), and the rest lengths slides count from.
        let model = record.model;
        self.clusters = model.clusters.clone();
        self.pulleys = (self.clusters.iter())
            .map(|c| c.pulleys().iter().map(|&n| model.nodes[n].id.clone()).collect())
            .collect();
        self.reference = record.rest_lengths.to_vec();
        self.kept = (self.clusters.iter())
            .map(|c| ClusterSummary {
                id: c.id.clone(),
                max_tension: f64::NEG_INFINITY,
                ..Default::default()
            })
            .collect();
    }

    fn begin_stage(&mut self, stage: &Stage) {
        self.stage = stage.clone();
    }

    fn frame(&mut self, frame: &Frame) {
        for ((c, kept), pulleys) in self.clusters.iter().zip(&mut self.kept).zip(&self.pulleys) {
            let tension = c.tension(frame.forces);
            if tension > kept.max_tension {
                (kept.max_tension, kept.max_tension_stage, kept.max_tension_step) = (tension, self.stage.name().into(), frame.step);
            }
            let Some(rest) = frame.rest_lengths else { continue };
            self.buffer.clear();
            c.slides(rest, &self.reference, &mut self.buffer);
            for (slide, pulley) in self.buffer.iter().zip(pulleys) {
                if slide.abs() > kept.max_slide.abs() {
                    kept.max_slide = *slide;
                    kept.max_slide_pulley.clone_from(pulley);
                    (kept.max_slide_stage, kept.max_slide_step) = (self.stage.name().into(), frame.step);
                }
            }
        }
    }
}
