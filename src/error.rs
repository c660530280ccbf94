//! Library errors. Each says what failed and where: the stage and step, the member or the
//! node and direction, and what to change.

use crate::model::ModelError;
use crate::solve::SolveError;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("model: {0}")]
    Model(#[from] ModelError),
    #[error("{stage}{}: {source}", step_text(*.step, *.time))]
    Solve {
        stage: &'static str,
        step: Option<usize>,
        time: Option<f64>,
        source: SolveError,
    },
    #[error("substitution: member `{member}`: {reason}")]
    Substitution { member: String, reason: String },
    #[error("{stage}: {reason}")]
    Stage { stage: &'static str, reason: String },
}

fn step_text(step: Option<usize>, time: Option<f64>) -> String {
    match (step, time) {
        (Some(s), Some(t)) => format!(", step {s} (t = {t:.4} s)"),
        (Some(s), None) => format!(", step {s}"),
        _ => String::new(),
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
