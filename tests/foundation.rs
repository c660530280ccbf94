//! Issue 2's validation: closed-form prisms, K_T against finite differences, rest-length
//! substitution, the paper's tower, and bad-model errors.

mod common;

use common::form_find;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;
use tsim::law::{ForceLaw, LinearElastic, OgdenCord};
use tsim::model::generate::TowerSpec;
use tsim::model::{MemberKind, Model, ModelError};
use tsim::solve::NewtonSettings;
use tsim::stage::eigen::{lowest_stiffness, tangent_matrix};
use tsim::stage::measure::{CableCoefficients, MeasureSpec};
use tsim::stage::substitute::{balanced_forces, rest_length, substitute};
use tsim::tsm::{Assembly, DofMap, Elements};

/// Deterministic pseudo-random perturbation in [-1, 1] (no RNG dependency).
fn noise(seed: usize) -> f64 {
    let x = ((seed as f64 + 1.0) * 12.9898).sin() * 43758.5453;
    2.0 * (x - x.floor()) - 1.0
}

fn perturb(model: &mut Model, amplitude: f64) {
    for (i, n) in model.nodes.iter_mut().enumerate() {
        for a in 0..3 {
            if !n.support[a] {
                n.xyz[a] += amplitude * noise(3 * i + a);
            }
        }
    }
}

fn real_laws(model: &Model) -> Vec<Arc<dyn ForceLaw>> {
    let strut: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
        ea: 68e9 * 0.01,
        tension_only: false,
    });
    let cable: Arc<dyn ForceLaw> = Arc::new(OgdenCord::new(OgdenCord::paper_terms(), 50e-6, 1.0, 0.1));
    model
        .members
        .iter()
        .map(|m| {
            if m.kind == MemberKind::Strut {
                strut.clone()
            } else {
                cable.clone()
            }
        })
        .collect()
}

/// Regular prisms (notes.md, Tibert & Pellegrino 2003): started 0.15 rad off the
/// equilibrium twist and perturbed, form-finding must land on the closed form. The cable
/// Cs (ring 1, side 0.5) are arbitrary: they set the prism's proportions, not its twist
/// or its force-density ratios, which is what is checked. The start has the proportions
/// these Cs give (q = C l², q_side = 2 sin(π/n) q_ring ⇒ h²/r² = 8 sin³(π/n)/0.5 −
/// 2(1 − sin(π/n))), so that Newton starts near the regular equilibrium rather than
/// near one of the irregular prisms that also balance.
#[test]
fn regular_prisms_reach_closed_form() {
    for n in [3, 4, 5, 6] {
        let s = (PI / n as f64).sin();
        let h2_r2 = 8.0 * s.powi(3) / 0.5 - 2.0 * (1.0 - s);
        let mut spec = TowerSpec {
            struts: n,
            stages: 1,
            ..TowerSpec::paper()
        };
        spec.radius = 7.0 / (2.0 + 2.0 * s + h2_r2).sqrt();
        let mut model = spec.build();
        // Twist the top ring away from equilibrium, then add noise.
        for node in model.nodes.iter_mut().filter(|nd| nd.id.starts_with('t')) {
            let (r, a) = (node.xyz.xy().norm(), node.xyz.y.atan2(node.xyz.x) + 0.15);
            node.xyz = Vector3::new(r * a.cos(), r * a.sin(), node.xyz.z);
        }
        perturb(&mut model, 0.05);
        let c = BTreeMap::from([
            ("ring_base".to_string(), 1.0),
            ("ring_top".to_string(), 1.0),
            ("side0".to_string(), 0.5),
        ]);
        let measure = MeasureSpec {
            strut_rest_length: Some(7.0),
            cable_c: CableCoefficients::PerGroup(c),
            ..Default::default()
        };
        let elements = measure.elements(&model).unwrap();
        let eq = form_find(&model, &elements, &NewtonSettings::default()).unwrap();
        let x = &eq.positions;
        let theta = TowerSpec::span_angle(n);
        for i in 0..n {
            let (b, t) = (x[i], x[n + i]);
            let span = (t.y.atan2(t.x) - b.y.atan2(b.x)).rem_euclid(2.0 * PI) - 2.0 * PI;
            let err = (span - theta + PI).rem_euclid(2.0 * PI) - PI;
            assert!(err.abs() < 1e-6, "n={n} strut {i}: span {span} vs closed form {theta}");
        }
        let q = |prefix: &str| -> Vec<f64> {
            model
                .members
                .iter()
                .enumerate()
                .filter(|(_, m)| m.id.starts_with(prefix))
                .map(|(k, _)| eq.forces[k] / eq.lengths[k])
                .collect()
        };
        let q_ring = q("ring_base")[0];
        for (group, expected) in [("ring", 1.0), ("side", 2.0 * s), ("strut", -2.0 * s)] {
            for v in q(group) {
                assert!(
                    (v / q_ring - expected).abs() < 1e-6 * expected.abs(),
                    "n={n} {group}: q ratio {} vs {expected}",
                    v / q_ring
                );
            }
        }
    }
}

/// Paper tower form-found, then substituted: a prestressed state to test K_T on.
fn paper_tower() -> (Model, Elements, Vec<Vector3<f64>>) {
    let model = TowerSpec::paper().build();
    let elements = MeasureSpec::default().elements(&model).unwrap();
    let eq = form_find(&model, &elements, &NewtonSettings::default()).unwrap();
    let sub = substitute(&model, &eq.positions, &eq.forces, real_laws(&model), 1.0).unwrap();
    (model, sub.elements, eq.positions)
}

/// K_T against the central-difference Jacobian of the internal force vector, at a
/// perturbed (not balanced) state so that both K_G and K_0 matter. The step 1e-6 m gives
/// truncation ~h²·p''' and round-off ~ε·|p|/h, both ≪ 1e-6 of the largest entry.
#[test]
fn tangent_matches_finite_differences() {
    let (mut model, elements, x) = paper_tower();
    for (node, xi) in model.nodes.iter_mut().zip(&x) {
        node.xyz = *xi;
    }
    perturb(&mut model, 0.05);
    let dofs = DofMap::new(&model, &[]);
    let asm = Assembly::new(&model, &elements, &dofs, model.positions());
    let k = tangent_matrix(&asm);
    let u0 = asm.free_coordinates();
    let n = dofs.len();
    let mut fd = vec![vec![0.0; n]; n];
    let h = 1e-6;
    let mut probe = Assembly::new(&model, &elements, &dofs, model.positions());
    for j in 0..n {
        let mut u = u0.clone();
        u[j] += h;
        probe.set_free(&u);
        let plus: Vec<f64> = (0..n).map(|i| probe.p_free(i)).collect();
        u[j] -= 2.0 * h;
        probe.set_free(&u);
        for i in 0..n {
            fd[i][j] = (plus[i] - probe.p_free(i)) / (2.0 * h);
        }
    }
    let max_k = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| k[(i, j)].abs())
        .fold(0.0, f64::max);
    let mut worst = 0.0_f64;
    for i in 0..n {
        for j in 0..n {
            worst = worst.max((k[(i, j)] - fd[i][j]).abs() / max_k);
        }
    }
    assert!(worst <= 1e-6, "K_T vs finite differences: relative error {worst:e}");
    // The soft cable entries matter too: compare them against their own size.
    let cable_block = (0..n).map(|i| k[(i, i)].abs()).fold(f64::INFINITY, f64::min);
    assert!(cable_block > 0.0);
}

#[test]
fn substitution_round_trip() {
    let model = TowerSpec::paper().build();
    let elements = MeasureSpec::default().elements(&model).unwrap();
    let eq = form_find(&model, &elements, &NewtonSettings::default()).unwrap();
    let balanced = balanced_forces(&model, &eq.positions, &eq.forces);
    let sub = substitute(&model, &eq.positions, &balanced, real_laws(&model), 1.0).unwrap();
    assert!(
        sub.residual <= 1e-8 * sub.max_force,
        "real-material residual {:e} vs max force {}",
        sub.residual,
        sub.max_force
    );
    // Linear elastic closed form: l0 = l·EA/(EA + N).
    let law = LinearElastic {
        ea: 1e6,
        tension_only: true,
    };
    for (l, n) in [(2.0, 150.0), (3.5, 1.0), (1.0, 0.0)] {
        let l0 = rest_length(&law, l, n).unwrap();
        let exact = l * 1e6 / (1e6 + n);
        assert!((l0 - exact).abs() <= 1e-13 * exact, "l0 {l0} vs {exact}");
    }
    assert!(rest_length(&law, 2.0, -5.0).unwrap_err().contains("cannot carry"));
}

/// The paper's 5×2 tower form-finds to a 3-D self-equilibrium and its real-material state
/// is stable.
#[test]
fn paper_tower_form_finds_and_is_stable() {
    let model = TowerSpec::paper().build();
    assert_eq!((model.node_count(), model.support_count()), (20, 8));
    assert_eq!(model.members.iter().filter(|m| m.kind == MemberKind::Strut).count(), 10);
    let elements = MeasureSpec::default().elements(&model).unwrap();
    let eq = form_find(&model, &elements, &NewtonSettings::default()).unwrap();
    let height = eq.positions.iter().map(|p| p.z).fold(0.0, f64::max);
    assert!(height > 5.0, "tower went flat: height {height}");
    for (m, mem) in model.members.iter().enumerate() {
        match mem.kind {
            MemberKind::Strut => assert!(eq.forces[m] < 0.0, "strut {} not compressed", mem.id),
            MemberKind::Cable => assert!(eq.forces[m] > 0.0, "cable {} not taut", mem.id),
        }
    }
    // Self-equilibrium: the supports carry (almost) nothing — the symmetric layout's
    // reactions vanish up to the round-off of the stiff struts (EA/l0·ε·l ≈ 1e-4 N).
    assert!(eq.max_reaction < 1e-3, "support reactions {}", eq.max_reaction);
    let sub = substitute(&model, &eq.positions, &eq.forces, real_laws(&model), 1.0).unwrap();
    let dofs = DofMap::new(&model, &[]);
    assert_eq!(dofs.len(), 52);
    let asm = Assembly::new(&model, &sub.elements, &dofs, eq.positions.clone());
    let lowest = lowest_stiffness(&asm).unwrap();
    assert!(lowest.value > 0.0, "real-material K_T not positive definite: {lowest:?}");
}

fn small_model() -> Model {
    TowerSpec {
        struts: 3,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build()
}

#[test]
fn bad_models_are_rejected_by_name() {
    let mut m = small_model();
    m.members[0].nodes[1] = m.members[0].nodes[0];
    assert!(matches!(m.validate(), Err(ModelError::ZeroLength { ref member, .. }) if member == "strut0_0"));

    let mut m = small_model();
    let dup = m.members[3].clone();
    m.members.push(tsim::model::Member { id: "extra".into(), ..dup });
    assert!(
        matches!(m.validate(), Err(ModelError::DuplicateMember { ref member, ref other, .. }) if member == "extra" && other == "side0_0")
    );

    let mut m = small_model();
    m.nodes.push(tsim::model::Node {
        id: "lonely".into(),
        xyz: Vector3::new(9.0, 9.0, 9.0),
        support: [false; 3],
    });
    assert_eq!(m.validate(), Err(ModelError::UnusedNode { node: "lonely".into() }));

    let mut m = small_model();
    m.nodes[1].id = m.nodes[0].id.clone();
    assert!(matches!(m.validate(), Err(ModelError::DuplicateNode { .. })));

    // Free rigid motions are valid (dynamics runs them); static stages under load ask.
    let mut m = small_model();
    m.nodes[1].support = [false, false, true];
    assert_eq!(m.validate(), Ok(()));
    let err = m.require_supports(&[]).unwrap_err();
    assert!(
        matches!(err, ModelError::RigidBodyFree { ref motion } if motion.contains("rotation about z")),
        "{err}"
    );

    let mut m = small_model();
    m.nodes[0].support = [false, false, true];
    let err = m.require_supports(&[]).unwrap_err().to_string();
    assert!(err.contains("translation along x") || err.contains("translation along y"), "{err}");

    assert!(small_model().validate().is_ok());
    assert!(TowerSpec::paper().build().validate().is_ok());
}

#[test]
fn unknown_node_in_explicit_model_is_named() {
    use tsim::config::{MemberSpec, ModelSpec, NodeSpec};
    let spec = ModelSpec {
        nodes: vec![
            NodeSpec {
                id: "a".into(),
                xyz: [0.0; 3],
                fix: vec![],
            },
            NodeSpec {
                id: "b".into(),
                xyz: [1.0, 0.0, 0.0],
                fix: vec![],
            },
        ],
        members: vec![MemberSpec {
            id: "m1".into(),
            nodes: ["a".into(), "c".into()],
            kind: MemberKind::Cable,
            groups: vec![],
            rest_length: None,
        }],
        ..Default::default()
    };
    assert_eq!(
        spec.build().unwrap_err(),
        ModelError::UnknownNode {
            member: "m1".into(),
            node: "c".into(),
            hint: String::new()
        }
    );
}

/// Form-finding converges from the nominal start with default settings for Table 1
/// literally (C = 0.8 on every cable) and for C per cable group from the layout's
/// self-stress (mean 0.8, the paper case), the total measure potential never rising: the
/// energy line search with its Newton correction. Both land on stable equilibria
/// (positive definite K_T); which ones is part of the check: uniform C gives a tower
/// about a third of the nominal height, per-group C keeps the nominal proportions
/// (Fig 2b). The reference heights come from an independent computation,
/// tests/python/test_formfinding.py: the same layout and measure potentials (C per group
/// rebuilt from stage/measure.rs's rule), the struts as rigid 7 m bars and the cables'
/// potential minimised under them (SciPy SLSQP, then Newton on the KKT equations), which
/// gives 2.934971940 m and 8.933621549 m and asserts that tsim's nodes are within 1e-6 m of
/// its own (measured 5.0e-9 m and 1.6e-9 m). The tolerance here is that 1e-6 m: the
/// rigid bars leave out the struts' stretch (≤ 3.5e-9 m) and tsim's solve leaves ~1e-7 m
/// open in its softest direction (1e-10 of ~100 N over 0.09 N/m).
///
/// "Never rising" allows the energy's round-off, 1e-12 of it (ENERGY_ROUNDOFF in
/// solve/newton.rs): near convergence the line search accepts steps within it.
#[test]
fn form_finding_converges_without_tuning_for_table_1_and_per_group_c() {
    use tsim::record::NoRecorder;
    use tsim::stage::formfind::SelfEquilibrium;
    use tsim::stage::{Analysis, Settings};
    use tsim::structure::{State, Structure};
    let model = TowerSpec::paper().build();
    let nominal = model.positions().iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
    for (cable_c, reference) in [
        (CableCoefficients::Uniform(0.8), 2.934971940),
        (CableCoefficients::SelfStress { mean: 0.8 }, 8.933621549),
    ] {
        let measure = MeasureSpec {
            strut_rest_length: Some(7.0),
            cable_c: cable_c.clone(),
            ..Default::default()
        };
        let structure = Structure::massless(model.clone(), measure.elements(&model).unwrap());
        let (state, eq) = SelfEquilibrium::FORM_FINDING
            .run(&structure, State::at_rest(model.positions()), &Settings::default(), &mut NoRecorder)
            .unwrap_or_else(|e| panic!("{cable_c:?}: {e}"));
        let height = state.positions.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
        eprintln!(
            "{cable_c:?}: {} iterations, height {height:.3} m (nominal {nominal:.3}), lowest K_T eigenvalue {:.3e} N/m, energy {:?}",
            eq.residuals.len() - 1,
            eq.lowest_stiffness,
            eq.energies
        );
        assert!(eq.residuals.len() - 1 <= 20, "{cable_c:?}: {} iterations", eq.residuals.len() - 1);
        for pair in eq.energies.windows(2) {
            assert!(pair[1] <= pair[0] + 1e-12 * pair[0].abs(), "{cable_c:?}: energy rose {pair:?}");
        }
        assert!(
            eq.lowest_stiffness > 0.0,
            "{cable_c:?}: unstable ({} at {})",
            eq.lowest_stiffness,
            eq.lowest_stiffness_at
        );
        assert!(
            (height - reference).abs() <= 1e-6,
            "{cable_c:?}: height {height} m, independent reference {reference} m"
        );
    }
}

/// A string between two pins on the x axis, its inner nodes free only in y: the rotation
/// about x moves no node, so it is no free motion of the structure, and the model is valid
/// (it was refused for a free "rotation about x", issue 30). With the inner nodes free in
/// y and z and one pin released to slide along y, the string swings about the other pin:
/// a motion that moves nodes, free, and named (rotation about z).
#[test]
fn a_motion_that_moves_no_node_is_not_a_free_rigid_body_motion() {
    let node = |id: &str, x: f64, support: [bool; 3]| tsim::model::Node {
        id: id.into(),
        xyz: Vector3::new(x, 0.0, 0.0),
        support,
    };
    let member = |k: usize| tsim::model::Member {
        id: format!("s{k}"),
        nodes: [k, k + 1],
        kind: tsim::model::MemberKind::Cable,
        groups: vec![],
    };
    let string = |inner: [bool; 3], end: [bool; 3]| Model {
        nodes: vec![
            node("a", 0.0, [true; 3]),
            node("m1", 1.0, inner),
            node("m2", 2.0, inner),
            node("b", 3.0, end),
        ],
        members: (0..3).map(member).collect(),
        node_groups: Default::default(),
        clusters: Vec::new(),
    };
    assert_eq!(string([true, false, true], [true; 3]).require_supports(&[]), Ok(()));
    let err = string([true, false, false], [true, false, true]).require_supports(&[]).unwrap_err();
    assert!(
        matches!(err, ModelError::RigidBodyFree { ref motion } if motion == "rotation about z"),
        "{err}"
    );
}
