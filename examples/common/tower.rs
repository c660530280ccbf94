//! The benchmark tower (shared by the scale and eigen benchmarks and a test): an n-strut,
//! k-stage tower at its generated (nominal) geometry with real materials, aluminium
//! struts at their nominal length and rubber cables prestressed to λ = 1.2. That shape is
//! not an equilibrium (form-finding a 1000-stage tower is a separate problem), but its
//! K_T has the TSM's structure: a soft, prestress-dominated cable net around stiff struts.

use std::sync::Arc;
use tsim::config::library;
use tsim::law::ForceLaw;
use tsim::model::generate::TowerSpec;
use tsim::model::MemberKind;
use tsim::structure::Structure;
use tsim::tsm::Elements;

/// The nominal tower of `struts` struts per stage and `stages` stages, lumped masses from
/// the materials' densities: aluminium struts and rubber cables.
#[allow(dead_code)] // the eigen test includes this file and builds towers of other materials
pub fn nominal_tower(struts: usize, stages: usize) -> Structure {
    tower_of(struts, stages, "aluminium", "rubber")
}

/// The nominal tower with struts and cables of the library materials named.
pub fn tower_of(struts: usize, stages: usize, strut: &str, cable: &str) -> Structure {
    let model = TowerSpec {
        struts,
        stages,
        radius: 3.0,
        strut_length: 7.0,
        overlap: 0.1,
    }
    .build();
    let lib = library();
    let (strut, cable) = (&lib[strut], &lib[cable]);
    let (strut_law, cable_law) = (strut.law(), cable.law());
    let x0 = model.positions();
    let mut laws: Vec<Arc<dyn ForceLaw>> = Vec::new();
    let mut rest = Vec::new();
    let mut linear_density = Vec::new();
    for mem in &model.members {
        let l = (x0[mem.nodes[1]] - x0[mem.nodes[0]]).norm();
        let (law, l0, mat) = match mem.kind {
            MemberKind::Strut => (strut_law.clone(), l, strut),
            MemberKind::Cable => (cable_law.clone(), l / 1.2, cable),
        };
        laws.push(law);
        rest.push(l0);
        linear_density.push(mat.density * 1e-3 * mat.area);
    }
    Structure::with_lumped_masses(model, Elements { laws, rest }, &linear_density, &[])
}
