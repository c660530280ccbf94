//! Library errors. Each says what failed and where: the stage and step, the member or the
//! node and direction, and what to change.

use crate::model::ModelError;
use crate::record::RecordError;
use crate::solve::SolveError;

/// An error of the library: what failed, in which stage and where.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The model is invalid, or a node, member or group named for it is not in it.
    #[error("model: {0}")]
    Model(#[from] ModelError),
    /// A Newton solve failed; `at` names the free DOF the error is about ("node `t3`
    /// direction z"), labelled by the stage, which knows the model (a `Box<str>`, not a
    /// `String`: it keeps `Error` small enough to return by value everywhere).
    #[error("{stage}{}: {}{}", step_text(*.step, *.time), source.describe(at.as_deref()), smaller_steps(stage, source))]
    Solve {
        /// The stage whose solve failed.
        stage: StageName,
        /// The step the solve failed in, for a stage that takes steps.
        step: Option<usize>,
        /// The time the failed step was to end at [s], for a time-stepping stage.
        time: Option<f64>,
        /// How the Newton solve failed.
        source: SolveError,
        /// The free DOF the failure is about, as node and direction, if it names one.
        at: Option<Box<str>>,
    },
    /// Substitution found no rest length at which a member's real material carries its
    /// scaled form-found force.
    #[error("substitution: member `{member}`: {reason}")]
    Substitution {
        /// The member's id.
        member: String,
        /// Why no rest length was found.
        reason: String,
    },
    /// A stage failed other than in its Newton solve or its recorder (bad input, a
    /// non-finite result, a failed eigen solve).
    #[error("{stage}: {reason}")]
    Stage {
        /// The stage that failed.
        stage: StageName,
        /// What failed.
        reason: String,
    },
    /// A failure and what the analysis of the layout says about it (form-finding of a
    /// layout without a proper self-stress).
    #[error("{source}; {note}")]
    Explained {
        /// The failure.
        source: Box<Error>,
        /// What the analysis of the layout says about it.
        note: String,
    },
    /// The recorder failed to take a step of a stage.
    #[error("{stage}: recording failed: {source}")]
    Record {
        /// The stage whose step was being recorded.
        stage: StageName,
        /// The recorder's error.
        #[source]
        source: RecordError,
    },
}

/// For a stage that takes steps and halves them when Newton fails (`max_cuts`), the
/// settings that make its steps smaller: a failure to converge or a divergence there is
/// often a step too large for the nonlinearity.
fn smaller_steps(stage: &str, source: &SolveError) -> String {
    if matches!(source, SolveError::Singular { .. } | SolveError::OutOfMemory { .. }) {
        return String::new();
    }
    let section = match stage {
        "static" | "folding" => format!("more `{stage}.steps`"),
        "free_vibration" | "deployment" => format!("a smaller `{stage}.dt`"),
        "form-finding" => return FORM_FINDING_HINT.into(),
        _ => return String::new(),
    };
    format!("; or take smaller steps: {section}, or more halvings of a failed step (`{stage}.max_cuts`)")
}

/// Form-finding takes no steps: it starts from the model's coordinates, and its measure
/// potentials set how hard each member pulls towards balance.
const FORM_FINDING_HINT: &str = "; or start closer to a balanced shape (the model's coordinates, or `model.tower.overlap`), \
     or change the measure potentials (`formfinding.measure`: `cable_c`, `cable_n`, `strut_ea`)";

fn step_text(step: Option<usize>, time: Option<f64>) -> String {
    match (step, time) {
        (Some(s), Some(t)) => format!(", step {s} (t = {t:.4} s)"),
        (Some(s), None) => format!(", step {s}"),
        _ => String::new(),
    }
}

/// The name of the stage an error is about (a stage of the config's `stages` list is
/// named by the user; `Arc`: as small as `&'static str`, cheap to clone).
pub type StageName = std::sync::Arc<str>;

/// A result whose error is, by default, the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    /// A stepped stage's failure names the settings for smaller steps; form-finding's names
    /// its start and its measure potentials instead.
    #[test]
    fn stepped_stages_suggest_smaller_steps() {
        let source = || SolveError::NotConverged {
            iterations: 20,
            residual: 1.0,
            tolerance: 1e-3,
            increment: 1e-12,
            increment_tolerance: 1e-9,
            worst_dof: 0,
        };
        let text = |stage| {
            Error::Solve {
                stage: StageName::from(stage),
                step: Some(3),
                time: None,
                source: source(),
                at: None,
            }
            .to_string()
        };
        let deployment = text("deployment");
        assert!(
            deployment.contains("force residual 1.000e0 N exceeds its tolerance")
                && deployment.contains("`newton.max_iterations`")
                && deployment.contains("a smaller `deployment.dt`")
                && deployment.contains("`deployment.max_cuts`"),
            "{deployment}"
        );
        assert!(text("folding").contains("more `folding.steps`") && text("folding").contains("`folding.max_cuts`"));
        assert!(text("static").contains("`static.max_cuts`"));
        let form_finding = text("form-finding");
        assert!(!form_finding.contains("smaller steps"), "{form_finding}");
        assert!(
            form_finding.contains("`formfinding.measure`") && form_finding.contains("`model.tower.overlap`"),
            "{form_finding}"
        );
    }
}
