//! `/tsim/clusters` (`cables.Cables`): per clustered cable, at every logged step of a stage
//! that records rest lengths, its tension and the slide over each of its pulleys, as in
//! result.h5's `cluster_tension` and `pulley_slide`. The topic exists only for a model with
//! clustered cables.

use super::encode::msg;
use crate::model::Cluster;
use crate::record::{ModelRecord, Stage};

/// What the replay keeps to log a model's clustered cables.
pub(super) struct CableReplay {
    pub(super) channel: u16,
    clusters: Vec<Cluster>,
    /// Pulley node ids per cluster ([`Cluster::pulleys`]).
    pulleys: Vec<Vec<String>>,
    /// The rest lengths slides count from (substitution's).
    reference: Vec<f64>,
    slides: Vec<f64>,
}

impl CableReplay {
    /// For `record`'s clustered cables, logged on `channel`.
    pub(super) fn new(record: &ModelRecord, channel: u16) -> Self {
        let model = record.model;
        CableReplay {
            channel,
            clusters: model.clusters.clone(),
            pulleys: (model.clusters.iter())
                .map(|c| c.pulleys().iter().map(|&n| model.nodes[n].id.clone()).collect())
                .collect(),
            reference: record.rest_lengths.to_vec(),
            slides: Vec::new(),
        }
    }

    /// The message of one state: its member `forces` and `rest` lengths.
    pub(super) fn message(&mut self, stage: &Stage, step: usize, forces: &[f64], rest: &[f64]) -> msg::Cables {
        let cables = (self.clusters.iter().zip(&self.pulleys))
            .map(|(c, pulleys)| {
                self.slides.clear();
                c.slides(rest, &self.reference, &mut self.slides);
                msg::Cable {
                    id: c.id.clone(),
                    tension: c.tension(forces),
                    pulleys: (pulleys.iter().zip(&self.slides))
                        .map(|(node, &slide)| msg::PulleySlide { node: node.clone(), slide })
                        .collect(),
                }
            })
            .collect();
        msg::Cables {
            stage: stage.name().into(),
            step: step as u64,
            cables,
        }
    }
}
