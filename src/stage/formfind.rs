//! Form-finding (paper §3.1, Figure 2): from the user's unbalanced shape to a
//! self-equilibrium, with whatever force laws the members carry — measure potentials in
//! the paper, but the common scheme takes any law (a model given with real rest lengths
//! is brought to its equilibrium the same way).

use super::stability::stability;
use super::{solve_error, Analysis, Settings, StaticEquilibrium};
use crate::error::Result;
use crate::model::height;
use crate::record::Recorder;
use crate::solve::{newton, NewtonWorkspace};
use crate::structure::{State, Structure};
use crate::tsm::{tangent_pattern, Assembly, DofMap};

/// Static equilibrium without load from a state's positions; `name` names the stage in
/// errors.
#[derive(Clone, Copy, Debug)]
pub struct SelfEquilibrium {
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
    pub forces: Vec<f64>,
    pub lengths: Vec<f64>,
    /// max|r| at each Newton iteration, the first at the start [N].
    pub residuals: Vec<f64>,
    /// Total potential at the start and after each iteration [J]: never rises.
    pub energies: Vec<f64>,
    /// Largest support reaction [N]: zero for a true self-equilibrium.
    pub max_reaction: f64,
    /// Lowest eigenvalue of K_T on the free DOFs [N/m] and where it acts: > 0 is a stable
    /// equilibrium (a minimum of the potential).
    pub lowest_stiffness: f64,
    pub lowest_stiffness_at: String,
}

impl Analysis for SelfEquilibrium {
    type Summary = Equilibrium;

    fn run(&self, structure: &Structure, state: State, settings: &Settings, _recorder: &mut dyn Recorder) -> Result<(State, Equilibrium)> {
        let model = &structure.model;
        let dofs = DofMap::new(model, &[]);
        let asm = Assembly::new(model, &structure.elements, &dofs, state.positions);
        let mut u = asm.free_coordinates();
        let mut ws = NewtonWorkspace::new(dofs.len(), &settings.newton, false, || tangent_pattern(model, &dofs));
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
        let stable = stability(&asm, &dofs, model)?;
        let found = Equilibrium {
            forces: asm.states.iter().map(|s| s.force).collect(),
            lengths: asm.states.iter().map(|s| s.length).collect(),
            residuals: ws.history,
            energies: ws.energies,
            max_reaction,
            lowest_stiffness: stable.lowest,
            lowest_stiffness_at: stable.at,
        };
        Ok((State::at_rest(asm.x), found))
    }
}

/// Key figures of form-finding.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FormFindSummary {
    pub iterations: usize,
    pub residuals: Vec<f64>,
    /// Total measure potential at the start and after each iteration [J].
    pub energies: Vec<f64>,
    /// Largest support reaction [N] (zero for a self-equilibrium).
    pub max_reaction: f64,
    /// Which equilibrium was found: its height [m] and its stability (the lowest
    /// eigenvalue of the measure structure's K_T [N/m], > 0: stable, and where it acts).
    pub height: f64,
    pub lowest_stiffness: f64,
    pub lowest_stiffness_at: String,
    pub min_force: f64,
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
            min_force: forces.iter().copied().fold(f64::INFINITY, f64::min),
            max_force: forces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}
