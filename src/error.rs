//! Library errors. Each says what failed and where: the stage and step, the member or the
//! node and direction, and what to change.

use crate::model::ModelError;
use crate::record::RecordError;
use crate::solve::SolveError;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("model: {0}")]
    Model(#[from] ModelError),
    /// A Newton solve failed; `at` names the free DOF the error is about ("node `t3`
    /// direction z"), labelled by the stage, which knows the model (a `Box<str>`, not a
    /// `String`: it keeps `Error` small enough to return by value everywhere).
    #[error("{stage}{}: {}", step_text(*.step, *.time), source.describe(at.as_deref()))]
    Solve {
        stage: &'static str,
        step: Option<usize>,
        time: Option<f64>,
        source: SolveError,
        at: Option<Box<str>>,
    },
    #[error("substitution: member `{member}`: {reason}")]
    Substitution { member: String, reason: String },
    #[error("{stage}: {reason}")]
    Stage { stage: &'static str, reason: String },
    #[error("{stage}: recording failed: {source}")]
    Record {
        stage: &'static str,
        #[source]
        source: RecordError,
    },
}

fn step_text(step: Option<usize>, time: Option<f64>) -> String {
    match (step, time) {
        (Some(s), Some(t)) => format!(", step {s} (t = {t:.4} s)"),
        (Some(s), None) => format!(", step {s}"),
        _ => String::new(),
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
