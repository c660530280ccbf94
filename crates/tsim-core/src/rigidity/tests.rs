//! The analysis against closed forms: Maxwell's rule with Calladine's correction,
//! 3j − b − 6 = m − s for a free 3-D structure (2j − b − 3 in the plane), the known
//! counts of the regular prism (s = 1, m = 2n − 5 internal) and of Snelson's X-module
//! (s = 1, m = 0 in the plane), and the null spaces checked against A itself.

use super::*;
use crate::model::generate::TowerSpec;
use crate::model::{Member, Node};

/// The regular n-strut prism (generated at the self-stressed twist), supports removed.
fn free_prism(n: usize) -> Model {
    let mut model = TowerSpec {
        struts: n,
        stages: 1,
        ..TowerSpec::paper()
    }
    .build();
    model.nodes.iter_mut().for_each(|node| node.support = [false; 3]);
    model
}

/// The prism's top ring turned by `angle` about the axis: away from the self-stressed twist.
fn twisted(model: &Model, angle: f64) -> Vec<Vector3<f64>> {
    let rotation = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    let top = model.group("top").unwrap();
    (0..model.node_count())
        .map(|i| {
            if top.contains(&i) {
                rotation * model.nodes[i].xyz
            } else {
                model.nodes[i].xyz
            }
        })
        .collect()
}

/// Snelson's X-module: a unit square of cables with its diagonals as struts, in z = 0
/// with every z held (the planar problem).
fn x_module() -> Model {
    let corner = |id: &str, x: f64, y: f64| Node {
        id: id.into(),
        xyz: Vector3::new(x, y, 0.0),
        support: [false, false, true],
    };
    let member = |id: &str, nodes, kind| Member {
        id: id.into(),
        nodes,
        kind,
        groups: vec![],
    };
    Model {
        nodes: vec![
            corner("a", 0.0, 0.0),
            corner("b", 1.0, 0.0),
            corner("c", 1.0, 1.0),
            corner("d", 0.0, 1.0),
        ],
        members: vec![
            member("ab", [0, 1], MemberKind::Cable),
            member("bc", [1, 2], MemberKind::Cable),
            member("cd", [2, 3], MemberKind::Cable),
            member("da", [3, 0], MemberKind::Cable),
            member("ac", [0, 2], MemberKind::Strut),
            member("bd", [1, 3], MemberKind::Strut),
        ],
        node_groups: Default::default(),
        clusters: Vec::new(),
    }
}

/// |A t| for each self-stress state and |Aᵀ u| for each mechanism, relative: both ~ε.
fn null_space_errors(model: &Model, x: &[Vector3<f64>], r: &Rigidity) -> (f64, f64) {
    let a = equilibrium_matrix(model, &DofMap::new(model, &[]), x).unwrap();
    ((&a * &r.self_stress).norm_max(), (a.transpose() * &r.mechanisms).norm_max())
}

#[test]
fn prisms_have_one_self_stress_and_2n_minus_5_mechanisms() {
    for n in 3..=8 {
        let model = free_prism(n);
        let x = model.positions();
        let r = analyse(&model, &x, None).unwrap();
        let (j, b) = (model.node_count() as i64, model.members.len() as i64);
        assert_eq!((j, b), (2 * n as i64, 4 * n as i64));
        assert_eq!((r.s, r.internal_mechanisms(), r.rigid_body_modes), (1, 2 * n - 5, 6), "n = {n}");
        // Maxwell–Calladine for a free 3-D structure.
        assert_eq!(3 * j - b - 6, r.internal_mechanisms() as i64 - r.s as i64);
        // The self-stress gap: the rank is clear-cut (the smallest nonzero σ is O(0.1)).
        assert!(
            r.singular_values[r.rank - 1] > 1e-3 && r.singular_values[r.rank] < 1e-12,
            "{:?}",
            r.singular_values
        );
        let (stress, motion) = null_space_errors(&model, &x, &r);
        // Null vectors of a matrix of direction cosines: residuals of a few ε.
        assert!(stress < 1e-13 && motion < 1e-13, "{stress:e} {motion:e}");
        let t = r.proper_self_stress.as_ref().expect(&r.self_stress_source);
        assert!(t
            .iter()
            .zip(&model.members)
            .all(|(t, m)| (m.kind == MemberKind::Strut) == (*t < 0.0)));
        assert!(
            r.stability.prestress_stable && r.stability.super_stable,
            "n = {n}: {:?}",
            r.stability
        );
    }
}

/// Away from the twist π/2 − π/n no self-stress exists: s = 0, the 2n − 6 internal
/// mechanisms Maxwell's rule leaves, and no stability (no stress to stiffen them; for n = 3
/// the bar framework is rigid, but cables cannot push without a proper stress).
#[test]
fn prisms_away_from_their_twist_have_no_self_stress_and_are_not_stable() {
    for n in [3, 4, 6] {
        let model = free_prism(n);
        let x = twisted(&model, 10f64.to_radians());
        let r = analyse(&model, &x, None).unwrap();
        assert_eq!((r.s, r.internal_mechanisms()), (0, 2 * n - 6), "n = {n}");
        assert!(r.proper_self_stress.is_none() && r.self_stress_source.contains("s = 0"));
        assert!(!r.stability.prestress_stable && !r.stability.super_stable);
    }
}

/// At the right twist with the prestress reversed (struts pulled, cables pushed: the
/// members' kinds swapped) the stress is not proper and K_G is negative on every
/// mechanism; with the right sign, positive.
#[test]
fn a_reversed_prestress_is_not_stable() {
    let model = free_prism(4);
    let x = model.positions();
    let t = analyse(&model, &x, None).unwrap().proper_self_stress.unwrap();
    let right = analyse(&model, &x, Some(&t)).unwrap();
    let reversed: Vec<f64> = t.iter().map(|v| -v).collect();
    let wrong = analyse(&model, &x, Some(&reversed)).unwrap();
    assert!(right.stability.prestress_stable && !wrong.stability.prestress_stable);
    assert!(right.stability.mechanism_stiffness.iter().all(|&l| l > right.stability.tolerance));
    assert!(wrong.stability.mechanism_stiffness.iter().all(|&l| l < -wrong.stability.tolerance));
    assert!(
        wrong.stability.super_stability.contains("not proper"),
        "{}",
        wrong.stability.super_stability
    );
}

/// Q's eigenvalue on a mechanism u is the second derivative of Σ t_j l_j(x + εu): the
/// first vanishes for a self-stress, the second is uᵀ K_G u. Central differences.
#[test]
fn mechanism_stiffness_is_the_second_derivative_of_the_stress_work() {
    let model = free_prism(5);
    let x = model.positions();
    let r = analyse(&model, &x, None).unwrap();
    let t = r.proper_self_stress.as_ref().unwrap();
    let dofs = DofMap::new(&model, &[]);
    let work = |eps: f64| -> f64 {
        let mut y = x.clone();
        for i in 0..dofs.len() {
            let (node, axis) = dofs.owner(i);
            y[node][axis] += eps * r.mechanisms[(i, 0)];
        }
        model
            .members
            .iter()
            .zip(t)
            .map(|(m, t)| t * (y[m.nodes[1]] - y[m.nodes[0]]).norm())
            .sum()
    };
    let h = 1e-4;
    let second = (work(h) - 2.0 * work(0.0) + work(-h)) / (h * h);
    let lowest = r.stability.mechanism_stiffness[0];
    // O(h²) truncation and ε/h² round-off (~1e-8 of the work, which is O(10)).
    assert!((second - lowest).abs() < 1e-5 * lowest.abs().max(1.0), "{second} vs {lowest}");
}

#[test]
fn the_x_module_has_one_self_stress_and_no_internal_mechanism() {
    let model = x_module();
    let x = model.positions();
    let r = analyse(&model, &x, None).unwrap();
    // 8 free DOFs, 6 members: rank 5; the in-plane rigid motions (2 translations, 1 rotation).
    assert_eq!((r.rank, r.s, r.m, r.rigid_body_modes, r.internal_mechanisms()), (5, 1, 3, 3, 0));
    assert_eq!(2 * 4 - 6 - 3, r.internal_mechanisms() as i64 - r.s as i64);
    // Closed form: cables t, struts −√2 t (each corner balances two cables against a diagonal).
    let t = r.proper_self_stress.as_ref().unwrap();
    for (m, v) in model.members.iter().zip(t) {
        let expected = if m.kind == MemberKind::Strut { -1.0 } else { 1.0 / 2f64.sqrt() };
        assert!((v - expected).abs() < 1e-12, "{}: {v}", m.id);
    }
    assert!(r.stability.prestress_stable && r.stability.super_stable, "{:?}", r.stability);
}

/// Supports as grounded directions: the generated prism's n + 3 supports (z on every base
/// node, x, y on one, one more in-plane) leave no rigid motion; m − s = n_f − b = n − 3.
/// The prism's self-stress has no reactions and stays the only one (s = 1), so each of the
/// n − 3 supports beyond the 6 that ground it pins one of the 2n − 5 mechanisms: m = n − 2.
#[test]
fn supports_remove_rigid_motions() {
    for n in [4, 5, 6] {
        let model = TowerSpec {
            struts: n,
            stages: 1,
            ..TowerSpec::paper()
        }
        .build();
        let r = analyse(&model, &model.positions(), None).unwrap();
        let n_f = 3 * model.node_count() - model.support_count();
        assert_eq!(r.rigid_body_modes, 0);
        assert_eq!(r.m as i64 - r.s as i64, n_f as i64 - model.members.len() as i64);
        assert_eq!((r.s, r.internal_mechanisms()), (1, n - 2), "n = {n}");
        assert!(r.stability.prestress_stable, "n = {n}: {:?}", r.stability);
    }
}

#[test]
fn models_beyond_the_dense_limit_are_refused() {
    let mut model = free_prism(3);
    let template = model.members[0].clone();
    model.members = vec![template; MAX_DENSE + 1];
    let err = analyse(&model, &model.positions(), None).unwrap_err();
    assert!(matches!(err, RigidityError::TooLarge { members, .. } if members == MAX_DENSE + 1));
    assert!(err.to_string().contains("dense limit of 1500"));
}
