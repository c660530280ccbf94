//! Form-finding (paper §3.1, Figure 2): from the user's unbalanced shape to a
//! self-equilibrium, with whatever force laws the members carry — measure potentials in
//! the paper, but the common scheme takes any law.

use super::StaticEquilibrium;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::solve::{newton, NewtonSettings};
use crate::tsm::{Assembly, DofMap, Elements};
use nalgebra::Vector3;

#[derive(Clone, Debug)]
pub struct Equilibrium {
    pub positions: Vec<Vector3<f64>>,
    pub forces: Vec<f64>,
    pub lengths: Vec<f64>,
    /// max|r| at each Newton iteration, the first at the start [N].
    pub residuals: Vec<f64>,
    /// Largest support reaction [N]: zero for a true self-equilibrium.
    pub max_reaction: f64,
}

/// Solves nodal equilibrium without load from the model's initial coordinates.
pub fn form_find(model: &Model, elements: &Elements, settings: &NewtonSettings) -> Result<Equilibrium> {
    let dofs = DofMap::new(model, &[]);
    let asm = Assembly::new(model, elements, &dofs, model.positions());
    let mut u = asm.free_coordinates();
    let mut ws = asm.workspace(settings, false);
    let mut problem = StaticEquilibrium {
        asm,
        load: vec![0.0; dofs.len()],
    };
    newton(&mut problem, &mut u, settings, model.size(), &|d| dofs.label(model, d), &mut ws).map_err(|source| Error::Solve {
        stage: "form-finding",
        step: None,
        time: None,
        source,
    })?;
    problem.asm.set_free(&u);
    let asm = problem.asm;
    let max_reaction = (0..model.node_count() * 3)
        .filter(|&i| dofs.free(i / 3, i % 3).is_none())
        .map(|i| asm.p[i].abs())
        .fold(0.0, f64::max);
    Ok(Equilibrium {
        forces: asm.states.iter().map(|s| s.force).collect(),
        lengths: asm.states.iter().map(|s| s.length).collect(),
        positions: asm.x,
        residuals: ws.history,
        max_reaction,
    })
}
