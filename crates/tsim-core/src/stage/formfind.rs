//! Form-finding (paper §3.1, Figure 2): from the user's unbalanced shape to a
//! self-equilibrium, with whatever force laws the members carry — measure potentials in
//! the paper, but the common scheme takes any law (a model given with real rest lengths
//! is brought to its equilibrium the same way).

use super::eigen::lowest_stiffness;
use super::{solve_error, Analysis, Settings, StaticEquilibrium};
use crate::error::{Error, Result};
use crate::model::{height, Model};
use crate::record::Recorder;
use crate::solve::{newton, NewtonWorkspace};
use crate::structure::{State, Structure};
use crate::tsm::{tangent_sparsity, Assembly, DofMap};

/// Static equilibrium without load from a state's positions; `name` names the stage in
/// errors.
#[derive(Clone, Copy, Debug)]
pub struct SelfEquilibrium {
    /// The stage's name in errors (`form-finding` or `equilibrium`).
    pub name: &'static str,
    /// Newton seeks a minimum of the potential ([`NewtonWorkspace::minimize`]).
    pub minimize: bool,
}

impl SelfEquilibrium {
    /// Form-finding with virtual measure-potential elements.
    pub const FORM_FINDING: SelfEquilibrium = SelfEquilibrium {
        name: "form-finding",
        minimize: true,
    };
    /// The equilibrium of a model given with real rest lengths (its Newton path kept as
    /// it was: these models start at or next to their equilibrium).
    pub const GIVEN: SelfEquilibrium = SelfEquilibrium {
        name: "equilibrium",
        minimize: false,
    };
}

/// What an equilibrium solve found, besides the state.
#[derive(Clone, Debug)]
pub struct Equilibrium {
    /// Member axial forces N at equilibrium [N], tension positive, under the laws solved
    /// with (the measure potentials in form-finding).
    pub forces: Vec<f64>,
    /// Member lengths at equilibrium [m].
    pub lengths: Vec<f64>,
    /// max|r| at each Newton iteration, the first at the start [N].
    pub residuals: Vec<f64>,
    /// Total potential at the start and after each iteration [J]: never rises.
    pub energies: Vec<f64>,
    /// Largest support reaction [N]: zero for a true self-equilibrium.
    pub max_reaction: f64,
    /// Lowest eigenvalue of K_T on the free DOFs [N/m] and where it acts: > 0 is a stable
    /// equilibrium (a minimum of the potential); see [`LowestStiffness`](super::eigen::LowestStiffness).
    pub lowest_stiffness: f64,
    /// The direction its eigenvector moves most ("node `t3` direction z").
    pub lowest_stiffness_at: String,
    /// The band ± this about zero in which round-off decides that eigenvalue's sign [N/m].
    pub stiffness_roundoff: f64,
}

impl Analysis for SelfEquilibrium {
    type Summary = Equilibrium;

    fn run(&self, structure: &Structure, state: State, settings: &Settings, _recorder: &mut dyn Recorder) -> Result<(State, Equilibrium)> {
        let model = &structure.model;
        // Where the supports leave rigid-body motion free (a free-floating structure), the
        // gauge holds it: the self-stress is balanced, so the equilibrium is the same.
        let dofs = DofMap::new(model, &model.gauge());
        let asm = Assembly::new(model, &structure.elements, &dofs, state.positions);
        let mut u = asm.free_coordinates();
        let mut ws = NewtonWorkspace::new(dofs.len(), &settings.newton, false, || tangent_sparsity(model, &dofs));
        ws.minimize = self.minimize;
        let mut problem = StaticEquilibrium {
            asm,
            load: vec![0.0; dofs.len()],
        };
        newton(&mut problem, &mut u, &settings.newton, model.size(), &mut ws)
            .map_err(solve_error(self.name, None, None, structure, &dofs))?;
        problem.asm.set_free(&u);
        let asm = problem.asm;
        let max_reaction = (0..model.node_count() * 3)
            .filter(|&i| dofs.free(i / 3, i % 3).is_none())
            .map(|i| asm.p[i].abs())
            .fold(0.0, f64::max);
        let lowest = lowest_stiffness(&asm)?;
        let found = Equilibrium {
            forces: asm.states.iter().map(|s| s.force).collect(),
            lengths: asm.states.iter().map(|s| s.length).collect(),
            residuals: ws.history,
            energies: ws.energies,
            max_reaction,
            lowest_stiffness: lowest.value,
            lowest_stiffness_at: lowest.at,
            stiffness_roundoff: lowest.band,
        };
        Ok((State::at_rest(asm.x), found))
    }
}

/// Form-finding's `error` with what the equilibrium-matrix analysis of `model` at its
/// nominal shape says, when that explains it: s = 0 (no self-stress exists there) or no
/// self-stress with struts compressed and cables tensioned. A layout with a proper
/// self-stress gets the error as it is. (Form-finding moves the shape, so the nominal
/// shape's analysis is a diagnosis, not a proof: a prism built at the wrong twist has s = 0
/// and still form-finds.)
pub fn explain_failure(model: &Model, error: Error) -> Error {
    let Ok(r) = crate::rigidity::analyse(model, &model.positions(), None) else {
        return error;
    };
    let counts = format!(
        "(equilibrium matrix of {} free DOFs × {} members, rank {})",
        r.dofs.len(),
        model.members.len(),
        r.rank
    );
    let note = match (r.s, &r.proper_self_stress) {
        (_, Some(_)) => return error,
        (0, None) => format!(
            "this layout has s = 0 at its nominal shape: no self-stress exists there {counts}, so form-finding must move it far; \
             check the members' connectivity and kinds, or start from a shape nearer a self-stressed one"
        ),
        (s, None) => format!(
            "this layout has s = {s} at its nominal shape {counts} but no self-stress with struts compressed and cables tensioned \
             ({}); check the member kinds",
            r.self_stress_source
        ),
    };
    Error::Explained {
        source: Box::new(error),
        note,
    }
}

/// Key figures of form-finding.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FormFindSummary {
    /// Newton iterations.
    pub iterations: usize,
    /// max|r| at each Newton iteration, the first at the start [N].
    pub residuals: Vec<f64>,
    /// Total measure potential at the start and after each iteration [J].
    pub energies: Vec<f64>,
    /// Largest support reaction [N] (zero for a self-equilibrium).
    pub max_reaction: f64,
    /// Which equilibrium was found: its height [m] and its stability (the lowest
    /// eigenvalue of the measure structure's K_T [N/m], > 0: stable, and where it acts).
    pub height: f64,
    /// Lowest eigenvalue of the measure structure's K_T [N/m].
    pub lowest_stiffness: f64,
    /// The direction its eigenvector moves most ("node `t3` direction z").
    pub lowest_stiffness_at: String,
    /// The band ± this about zero in which round-off decides that eigenvalue's sign [N/m]
    /// (within it, the value is an upper bound, see `stage::eigen::LowestStiffness`).
    #[serde(default)]
    pub stiffness_roundoff: f64,
    /// Most compressive balanced member force [N] (tension positive).
    pub min_force: f64,
    /// Most tensile balanced member force [N].
    pub max_force: f64,
}

impl FormFindSummary {
    /// From the equilibrium found at `state` and its balanced member `forces`.
    pub fn new(found: &Equilibrium, state: &State, forces: &[f64]) -> Self {
        FormFindSummary {
            iterations: found.residuals.len() - 1,
            residuals: found.residuals.clone(),
            energies: found.energies.clone(),
            max_reaction: found.max_reaction,
            height: height(&state.positions),
            lowest_stiffness: found.lowest_stiffness,
            lowest_stiffness_at: found.lowest_stiffness_at.clone(),
            stiffness_roundoff: found.stiffness_roundoff,
            min_force: forces.iter().copied().fold(f64::INFINITY, f64::min),
            max_force: forces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::generate::TowerSpec;
    use crate::model::{Member, MemberKind, Node};
    use nalgebra::Vector3;

    fn failure() -> Error {
        Error::Stage {
            stage: "form-finding".into(),
            reason: "did not converge".into(),
        }
    }

    /// A triangle of a strut and two cables has no self-stress (s = 0): said so.
    #[test]
    fn a_layout_without_self_stress_is_named() {
        let node = |id: &str, x: f64, y: f64| Node {
            id: id.into(),
            xyz: Vector3::new(x, y, 0.0),
            support: [false; 3],
        };
        let member = |id: &str, nodes, kind| Member {
            id: id.into(),
            nodes,
            kind,
            groups: vec![],
        };
        let model = Model {
            nodes: vec![node("a", 0.0, 0.0), node("b", 1.0, 0.0), node("c", 0.0, 1.0)],
            members: vec![
                member("ab", [0, 1], MemberKind::Strut),
                member("bc", [1, 2], MemberKind::Cable),
                member("ca", [2, 0], MemberKind::Cable),
            ],
            node_groups: Default::default(),
            clusters: Vec::new(),
        };
        let text = explain_failure(&model, failure()).to_string();
        assert!(text.starts_with("form-finding: did not converge; this layout has s = 0"), "{text}");
    }

    /// A prism at its self-stressed twist has a proper self-stress: the error is left as it is.
    #[test]
    fn a_layout_with_a_proper_self_stress_keeps_its_error() {
        let model = TowerSpec {
            struts: 4,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        assert_eq!(explain_failure(&model, failure()).to_string(), failure().to_string());
    }
}
