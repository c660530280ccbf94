//! `eigen`: natural frequencies and modes at an equilibrium, and the Rayleigh damping
//! they give a later transient ([`crate::stage::eigen`]).

use super::{EntryCheck, EntryPlan, StageSpec, Steps};
use crate::config::schema::{EigenSpec, RayleighSpec};
use crate::config::validate::Problems;
use crate::dynamics::Rayleigh;
use crate::error::Result;
use crate::model::Model;
use crate::record::{Stage, StageKind};
use crate::solve::krylov_dimension;
use crate::stage::eigen::{DampingFrom, Eigen, EigenSolverChoice};
use crate::stage::sequence::SequenceStage;

impl StageSpec for EigenSpec {
    fn kind(&self) -> StageKind {
        StageKind::Eigen
    }

    fn check(&self, at: &str, entry: &EntryCheck, p: &mut Problems) {
        check_eigen(at, self, entry.model, p);
    }

    fn gives_damping(&self) -> bool {
        self.rayleigh.is_some()
    }

    fn plan(&self, stage: Stage, _entry: &EntryPlan) -> Result<Box<dyn SequenceStage>> {
        Ok(Box::new(eigen_stage(self, stage)))
    }

    fn steps(&self, _every: usize) -> Option<Steps> {
        None
    }

    fn eigen(&self) -> Option<&EigenSpec> {
        Some(self)
    }
}

pub(in crate::config) fn eigen_stage(spec: &EigenSpec, stage: Stage) -> Eigen {
    let damping = match spec.rayleigh {
        None => DampingFrom::None,
        Some(RayleighSpec::Given { alpha, beta }) => DampingFrom::Given(Rayleigh { alpha, beta }),
        Some(RayleighSpec::Modes { modes, ratios }) => DampingFrom::Modes { modes, ratios },
        Some(RayleighSpec::AutoModes { axis, ratios }) => DampingFrom::AutoModes {
            axis: axis.index(),
            ratios,
        },
    };
    Eigen {
        damping,
        stage,
        solver: spec.mode_solver(),
    }
}

/// The partial solver's keys, and the Rayleigh modes against the modes computed.
pub(in crate::config) fn check_eigen(at: &str, e: &EigenSpec, model: Option<&Model>, p: &mut Problems) {
    if e.solver == EigenSolverChoice::Dense {
        for (field, given) in [
            (format!("{at}.modes"), e.modes.is_some()),
            (format!("{at}.shift"), e.shift.is_some()),
        ] {
            if given {
                p.add(
                    field,
                    "applies to the partial solver; `eigen.solver: dense` computes every mode (remove it or use `partial`)",
                );
            }
        }
    }
    if let Some(shift) = e.shift {
        p.within(&format!("{at}.shift"), shift, f64::NEG_INFINITY, f64::INFINITY, "(-∞, ∞)");
    }
    let solver = e.mode_solver();
    if let Some(model) = model {
        let dof_count = 3 * model.node_count() - model.support_count();
        if e.modes.is_some_and(|k| k == 0 || k >= dof_count) {
            p.add(
                format!("{at}.modes"),
                format!("is {}; must lie in 1..{dof_count} (the model's free DOF)", solver.modes),
            );
        } else if e.solver == EigenSolverChoice::Partial && !solver.partial(dof_count) {
            p.add(format!("{at}.solver"),
                format!(
                    "`partial` with {} modes needs more than {} free DOF (its Krylov space), the model has {dof_count}; use `dense` or fewer `eigen.modes`",
                    solver.modes,
                    krylov_dimension(solver.modes)
                ),
            );
        }
        if let Some(RayleighSpec::Modes { modes, .. }) = &e.rayleigh {
            for (k, m) in modes.iter().enumerate() {
                if solver.partial(dof_count) && *m > solver.modes {
                    p.add(
                        format!("{at}.rayleigh.modes[{k}]"),
                        format!(
                            "is {m}, but the partial eigen solver computes {} modes; raise `eigen.modes` to at least {m}",
                            solver.modes
                        ),
                    );
                }
            }
        }
    }
    if let Some(r) = &e.rayleigh {
        check_rayleigh(at, r, model, p);
    }
}

/// Which keys are given is settled by the type; what remains are the ranges.
fn check_rayleigh(at: &str, r: &RayleighSpec, model: Option<&Model>, p: &mut Problems) {
    match r {
        RayleighSpec::Given { alpha, beta } => {
            for (field, v) in [(format!("{at}.rayleigh.alpha"), alpha), (format!("{at}.rayleigh.beta"), beta)] {
                p.within(&field, *v, -1e-300, f64::INFINITY, "[0, ∞)");
            }
        }
        RayleighSpec::Modes { modes, ratios } => {
            if let Some(model) = model {
                let dof_count = 3 * model.node_count() - model.support_count();
                for (k, m) in modes.iter().enumerate() {
                    if *m < 1 || *m > dof_count {
                        p.add(
                            format!("{at}.rayleigh.modes[{k}]"),
                            format!("is {m}; must lie in 1..={dof_count} (the model has {dof_count} DOF)"),
                        );
                    }
                }
            }
            if modes[0] == modes[1] {
                p.add(format!("{at}.rayleigh.modes"), "the two modes must differ");
            }
            check_ratios(at, ratios, p);
        }
        RayleighSpec::AutoModes { ratios, .. } => check_ratios(at, ratios, p),
    }
}

fn check_ratios(at: &str, ratios: &[f64; 2], p: &mut Problems) {
    for (k, z) in ratios.iter().enumerate() {
        p.within(&format!("{at}.rayleigh.ratios[{k}]"), *z, -1e-300, 1.0, "[0, 1)");
    }
}
