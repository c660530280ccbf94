//! Prestress stability and super stability of a stressed state.
//!
//! Prestress stability (Connelly & Whiteley 1996, "Second-order rigidity and prestress
//! stability for tensegrity frameworks", SIAM J. Discrete Math. 9(3)): the geometric
//! stiffness K_G of the stress (tsm's member block with N/l and no material part) is
//! positive definite on the internal mechanisms M, Q = Mᵀ K_G M ≻ 0. On a mechanism every
//! member keeps its length to first order, so the (N/l) J Jᵀ part of K_G drops out and
//! Q = Mᵀ (Ω ⊗ I₃) M with Ω the stress matrix. Rigid-body motions are excluded (Ω ⊗ I₃
//! vanishes on them for a self-stress). The stress must be proper as well (struts
//! compressed, cables tensioned): cables cannot push, so a tensegrity without a proper
//! stress is not stable even where its bar framework is rigid (Roth & Whiteley 1981,
//! "Tensegrity frameworks", Trans. AMS 265). With a proper stress and no internal
//! mechanism the state is first-order rigid, hence prestress stable.
//!
//! Super stability (Connelly 1982, "Rigidity and energy", Invent. Math. 66; the
//! sufficient condition of Connelly & Guest 2022, "Frameworks, Tensegrities, and
//! Symmetry", Thm 5.14.1), for the framework on all its nodes, supports not counted:
//! (i) the stress is proper (struts compressed, cables tensioned); (ii) Ω is positive
//! semidefinite; (iii) its nullity is d + 1, d the dimension of the nodes' affine span
//! (4 for a 3-D structure); (iv) the member directions do not lie on a conic at infinity
//! (no symmetric d × d S ≠ 0 with Jᵀ S J = 0 for every member). Such a structure is stable
//! for any positive multiple of its stress and any material stiffness.

use super::{null_space, proper, rank_tolerance};
use crate::model::Model;
use crate::solve::symmetric_eigen;
use crate::tsm::{assemble_tangent, DofMap, MemberState};
use faer::Mat;
use nalgebra::Vector3;

/// Relative threshold for a positive eigenvalue of Q: Q is resolved to ~n ε ‖K_G‖ in
/// floating point, and a state balanced to the solver's tolerance (1e-10 relative) shifts
/// it by about that much times ‖K_G‖; an eigenvalue below 1e-8 max|N/l| is no stiffness one
/// can rely on (a second-order, not a prestress, stiffness).
const POSITIVE: f64 = 1e-8;

/// The stability of a stressed state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stability {
    /// Eigenvalues of Q = Mᵀ K_G M on the internal mechanisms, ascending [N/m].
    pub mechanism_stiffness: Vec<f64>,
    /// Q's eigenvalues above it count as positive [N/m].
    pub tolerance: f64,
    /// Proper stress and Q ≻ 0 on the internal mechanisms (Connelly & Whiteley).
    pub prestress_stable: bool,
    /// The four sufficient conditions of super stability all hold (module doc).
    pub super_stable: bool,
    /// Which super-stability condition fails, or that all hold.
    pub super_stability: String,
}

/// The test with member forces `stress` [N] (none: no stress, K_G = 0) on the orthonormal
/// internal mechanisms `internal`; returns the mechanisms rotated to Q's eigenvectors
/// (ascending stiffness).
pub(super) fn test(model: &Model, dofs: &DofMap, x: &[Vector3<f64>], stress: Option<&[f64]>, internal: Mat<f64>) -> (Stability, Mat<f64>) {
    let zero = vec![0.0; model.members.len()];
    let t = stress.unwrap_or(&zero);
    let states = member_states(model, x, t);
    let density = states.iter().fold(0.0_f64, |a, s| a.max((s.force / s.length).abs()));
    let tolerance = POSITIVE * density;
    let mut kg = Mat::zeros(dofs.len(), dofs.len());
    assemble_tangent(model, &states, dofs, 1.0, &mut kg);
    let q = internal.transpose() * &kg * &internal;
    let (stiffness, mechanisms) = if q.nrows() == 0 {
        (Vec::new(), internal)
    } else {
        let (values, vectors) = symmetric_eigen(q.as_ref()).expect("symmetric eigen of Q");
        (values, &internal * vectors)
    };
    // A tensegrity needs a proper stress to be stable at all (Roth & Whiteley 1981: cables
    // cannot push), then Q ≻ 0 on the internal mechanisms (none: first-order rigid).
    let proper = stress.map_or(Err("no self-stress".to_string()), |t| proper::check(model, t));
    let prestress_stable = proper.is_ok() && stiffness.first().is_none_or(|&l| l > tolerance);
    let super_stability = match stress {
        Some(t) => super_stable(model, x, t, &states),
        None => Err("no self-stress".to_string()),
    };
    let stability = Stability {
        mechanism_stiffness: stiffness,
        tolerance,
        prestress_stable,
        super_stable: super_stability.is_ok(),
        super_stability: super_stability.unwrap_or_else(|why| why),
    };
    (stability, mechanisms)
}

/// Member states carrying forces `t` with no material stiffness: K_T = K_G.
fn member_states(model: &Model, x: &[Vector3<f64>], t: &[f64]) -> Vec<MemberState> {
    model
        .members
        .iter()
        .zip(t)
        .map(|(mem, &force)| {
            let d = x[mem.nodes[1]] - x[mem.nodes[0]];
            let length = d.norm();
            MemberState {
                length,
                dir: d / length,
                force,
                ..MemberState::default()
            }
        })
        .collect()
}

/// Conditions (i)–(iv) of the module docs; Ok with a note when all hold, else which fails.
fn super_stable(model: &Model, x: &[Vector3<f64>], t: &[f64], states: &[MemberState]) -> Result<String, String> {
    proper::check(model, t).map_err(|why| format!("the stress is not proper: {why}"))?;
    if let Some(c) = model.clusters.first() {
        // Condition (iv) is for members that keep their own rest length; a sliding cable
        // adds motions it does not see.
        return Err(format!(
            "not tested: cable `{}` is clustered (the conditions are for members of their own rest length)",
            c.id
        ));
    }
    let n = model.node_count();
    let mut omega = Mat::<f64>::zeros(n, n);
    for (mem, s) in model.members.iter().zip(states) {
        let q = s.force / s.length;
        let [i, j] = mem.nodes;
        omega[(i, i)] += q;
        omega[(j, j)] += q;
        omega[(i, j)] -= q;
        omega[(j, i)] -= q;
    }
    let (span, d) = affine_span(x);
    let (lambda, _) = symmetric_eigen(omega.as_ref()).expect("symmetric eigen of the stress matrix");
    let tol = stress_matrix_tolerance(&omega, x, &lambda);
    let nullity = lambda.iter().filter(|l| l.abs() <= tol).count();
    if lambda[0] < -tol {
        return Err(format!("the stress matrix has a negative eigenvalue {:.3e} N/m", lambda[0]));
    }
    if nullity != d + 1 {
        return Err(format!("the stress matrix has nullity {nullity}, not d + 1 = {}", d + 1));
    }
    if on_conic_at_infinity(model, x, &span) {
        return Err("the member directions lie on a conic at infinity".into());
    }
    Ok(format!(
        "stress proper, stress matrix positive semidefinite with nullity d + 1 = {}",
        d + 1
    ))
}

/// Zero-eigenvalue tolerance of Ω [N/m]: round-off n ε |λ|max, or 10× the Rayleigh
/// quotient of Ω on the affine motions (exact null vectors of Ω for an exact self-stress;
/// a state balanced to the solver's tolerance leaves them at that level).
fn stress_matrix_tolerance(omega: &Mat<f64>, x: &[Vector3<f64>], lambda: &[f64]) -> f64 {
    let n = x.len();
    let centroid = x.iter().sum::<Vector3<f64>>() / n as f64;
    let mut quotient = 0.0_f64;
    for k in 0..4 {
        let v = Mat::from_fn(n, 1, |i, _| if k == 3 { 1.0 } else { x[i][k] - centroid[k] });
        let norm2 = v.squared_norm_l2();
        if norm2 > 0.0 {
            quotient = quotient.max((v.transpose() * omega * &v)[(0, 0)].abs() / norm2);
        }
    }
    let largest = lambda.iter().fold(0.0_f64, |a, l| a.max(l.abs()));
    (n as f64 * f64::EPSILON * largest).max(10.0 * quotient)
}

/// An orthonormal basis (3 × d) of the directions the nodes span, and d.
fn affine_span(x: &[Vector3<f64>]) -> (Mat<f64>, usize) {
    let centroid = x.iter().sum::<Vector3<f64>>() / x.len() as f64;
    let centred = Mat::from_fn(x.len(), 3, |i, k| x[i][k] - centroid[k]);
    let off = null_space(&centred, 3);
    let d = 3 - off.ncols();
    let basis = null_space(&off.transpose().to_owned(), 3);
    (basis, d)
}

/// Whether a symmetric S ≠ 0 on the span has Jᵀ S J = 0 for every member direction J:
/// the linear map S ↦ (Jᵀ S J)_j has a null space.
fn on_conic_at_infinity(model: &Model, x: &[Vector3<f64>], span: &Mat<f64>) -> bool {
    let d = span.ncols();
    let entries: Vec<(usize, usize)> = (0..d).flat_map(|a| (a..d).map(move |b| (a, b))).collect();
    let dirs: Vec<Vec<f64>> = model
        .members
        .iter()
        .map(|m| {
            let v = (x[m.nodes[1]] - x[m.nodes[0]]).normalize();
            (0..d).map(|a| (0..3).map(|k| span[(k, a)] * v[k]).sum()).collect()
        })
        .collect();
    let map = Mat::from_fn(dirs.len(), entries.len(), |j, e| {
        let (a, b) = entries[e];
        let both = if a == b { 1.0 } else { 2.0 };
        both * dirs[j][a] * dirs[j][b]
    });
    let s = map.singular_values().expect("SVD of a b × 6 matrix");
    let tol = rank_tolerance(&s, map.nrows(), map.ncols(), 0.0);
    s.iter().filter(|&&v| v > tol).count() < entries.len()
}
