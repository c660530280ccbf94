//! Helpers shared by the integration tests.

// Each test binary compiles this module and uses a part of it.
#![allow(dead_code)]

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
    pub lengths: Vec<f64>,
    pub max_reaction: f64,
    pub iterations: usize,
    /// The lowest eigenvalue of the measure structure's K_T at the shape [N/m].
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

/// Asserts that the error text `errors` has, for each (line, field, message), a line
/// `<file>:<line>: `<field>`: …` containing the message.
pub fn assert_field_errors(errors: &str, file: &str, expect: &[(usize, &str, &str)]) {
    for (line, field, message) in expect {
        let at = format!("{file}:{line}: `{field}`: ");
        assert!(
            errors.lines().any(|l| l.starts_with(&at) && l.contains(message)),
            "no `{at}…{message}` in\n{errors}"
        );
    }
}
