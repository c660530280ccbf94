//! Helpers shared by the integration tests.

// Each test binary compiles this module and uses a part of it.
#![allow(dead_code)]

use nalgebra::Vector3;
use tsim::dynamics::{DampingTangent, Loads, NewmarkParams, Rayleigh};
use tsim::model::Model;
use tsim::record::NoRecorder;
use tsim::record::{Stage, StageKind};
use tsim::solve::NewtonSettings;
use tsim::stage::formfind::SelfEquilibrium;
use tsim::stage::transient::{Initial, Transient};
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

/// The largest gap between the recorded `reactions` of a frame and what the members'
/// recorded forces put into the supports less the load applied there: at each constrained
/// direction −Σ N e − f, e the unit vector from the support's node to the member's other
/// end (`ends`: each member's nodes). Where the supports do not move, no inertia enters,
/// and with objective damping a member's whole damping force is along it, so this is
/// round-off when `forces` are the totals the step's equation balanced.
pub fn reaction_gap(
    ends: &[[usize; 2]],
    constraints: &tsim::record::Constraints,
    (positions, forces): (&[Vector3<f64>], &[f64]),
    (applied, reactions): (&[Vector3<f64>], &[f64]),
) -> f64 {
    let mut worst: f64 = 0.0;
    for (c, r) in constraints.0.iter().zip(reactions) {
        let mut from_members = 0.0;
        for (m, &[a, b]) in ends.iter().enumerate() {
            let other = match c.node {
                n if n == a => b,
                n if n == b => a,
                _ => continue,
            };
            let e = (positions[other] - positions[c.node]).normalize();
            from_members -= forces[m] * e[c.axis];
        }
        worst = worst.max((r - (from_members - applied[c.node][c.axis])).abs());
    }
    worst
}

/// An undamped Newmark (average acceleration) transient `name` of `steps` steps of `dt`,
/// never cut, with `loads` and `initial` conditions.
pub fn transient(name: &str, dt: f64, steps: usize, loads: Loads, initial: Initial) -> Transient {
    Transient {
        stage: Stage::new(StageKind::Transient, name),
        params: NewmarkParams {
            dt,
            max_cuts: 0,
            ..Default::default()
        },
        duration: dt * steps as f64,
        rayleigh: Rayleigh::default(),
        tangent: DampingTangent::Objective,
        loads,
        actuators: Vec::new(),
        initial,
    }
}
