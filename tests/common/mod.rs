//! Helpers shared by the integration tests.

use nalgebra::Vector3;
use tsim::model::Model;
use tsim::record::NoRecorder;
use tsim::solve::NewtonSettings;
use tsim::stage::formfind::SelfEquilibrium;
use tsim::stage::{Analysis, Settings};
use tsim::structure::{State, Structure};
use tsim::tsm::Elements;

/// A form-found shape and its members' forces.
pub struct Found {
    pub positions: Vec<Vector3<f64>>,
    pub forces: Vec<f64>,
    #[allow(dead_code)] // each test binary compiles this module; not every one reads every field
    pub lengths: Vec<f64>,
    #[allow(dead_code)] // as above
    pub max_reaction: f64,
    #[allow(dead_code)] // as above
    pub iterations: usize,
    /// The lowest eigenvalue of the measure structure's K_T at the shape [N/m].
    #[allow(dead_code)] // as above
    pub lowest_stiffness: f64,
}

/// Form-finding of `model` with `elements` from its coordinates, through the stage interface.
pub fn form_find(model: &Model, elements: &Elements, newton: &NewtonSettings) -> tsim::Result<Found> {
    let structure = Structure::massless(model.clone(), elements.clone());
    let settings = Settings {
        newton: *newton,
        ..Default::default()
    };
    let (state, eq) = SelfEquilibrium::FORM_FINDING.run(&structure, State::at_rest(model.positions()), &settings, &mut NoRecorder)?;
    Ok(Found {
        positions: state.positions,
        forces: eq.forces,
        lengths: eq.lengths,
        max_reaction: eq.max_reaction,
        iterations: eq.residuals.len() - 1,
        lowest_stiffness: eq.lowest_stiffness,
    })
}
