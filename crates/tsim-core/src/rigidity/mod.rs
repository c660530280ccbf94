//! Equilibrium-matrix analysis (Pellegrino & Calladine 1986): for a model at any
//! positions, the equilibrium matrix A (free DOFs × members; column j is member j's unit
//! direction, −J at its first node and +J at its second, so that A t are the nodal
//! forces of member forces t), its SVD, the rank r, the number of independent
//! self-stress states s = b − r (null space of A) and of infinitesimal mechanisms
//! m = n_f − r (null space of Aᵀ: motions that stretch no member to first order), the
//! self-stress compatible with the member kinds, and the prestress stability of the
//! mechanisms ([`stability`]).
//!
//! Dense: A is n_f × b and its full SVD costs O(n³); [`MAX_DENSE`] bounds the larger
//! dimension (the paper's tower: 52 × 50).

mod proper;
mod stability;

pub use stability::Stability;

use crate::model::{MemberKind, Model};
use crate::tsm::DofMap;
use faer::Mat;
use nalgebra::Vector3;

/// Largest number of free DOFs or members analysed. The full SVD (both factors: the
/// self-stress and mechanism bases need them) is O(n³): a 12-strut tower of 1425 free DOFs
/// takes 7 s, one of 1929 21 s on the shared 2-core machine (bench/rigidity.md); above
/// 1500 the analysis is skipped with this reason rather than stalling a case.
pub const MAX_DENSE: usize = 1500;

/// Why the analysis could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RigidityError {
    /// A model above [`MAX_DENSE`] free DOFs or members.
    #[error(
        "equilibrium-matrix analysis: {dofs} free DOFs × {members} members exceeds the dense limit of {MAX_DENSE} \
         in either dimension; the analysis is skipped for models this large"
    )]
    TooLarge {
        /// Free DOFs n_f.
        dofs: usize,
        /// Members b.
        members: usize,
    },
    /// The SVD of A failed (faer's error, as text).
    #[error("equilibrium-matrix analysis: the SVD did not converge ({0})")]
    Svd(String),
    /// A member (by id) has coincident ends at the analysed positions.
    #[error("equilibrium-matrix analysis: member `{0}` has zero length")]
    ZeroLength(String),
}

/// The analysis of one state.
#[derive(Clone, Debug)]
pub struct Rigidity {
    /// Singular values of A, descending (min(n_f, b) of them).
    pub singular_values: Vec<f64>,
    /// Singular values at or below it count as zero (see [`rank_tolerance`]).
    pub tolerance: f64,
    /// Rank r of A.
    pub rank: usize,
    /// Independent self-stress states, s = b − r (b: independent tensions, a clustered
    /// cable one).
    pub s: usize,
    /// Infinitesimal mechanisms, m = n_f − r, rigid-body motions the supports allow included.
    pub m: usize,
    /// Rigid-body motions the supports allow (6 for an unsupported 3-D model).
    pub rigid_body_modes: usize,
    /// Orthonormal self-stress basis, b × s (member forces up to scale).
    pub self_stress: Mat<f64>,
    /// (node, axis) of each free DOF: the rows of A and of the mechanisms.
    pub dofs: Vec<(usize, usize)>,
    /// Orthonormal basis of the internal mechanisms, n_f × (m − rigid_body_modes): the
    /// mechanisms orthogonal to the rigid-body motions, ordered by prestress stiffness.
    pub mechanisms: Mat<f64>,
    /// The self-stress compatible with the member kinds (struts compressed, cables
    /// tensioned), scaled to max |t| = 1, if one was found ([`proper`]).
    pub proper_self_stress: Option<Vec<f64>>,
    /// How the proper self-stress was found, or why none was. The stability test uses the
    /// state's prestress when it has one, else the proper self-stress.
    pub self_stress_source: String,
    /// ‖A t‖/‖t‖ of the prestress the state was given with (0 without one).
    pub prestress_residual: f64,
    /// Prestress and super stability of the state.
    pub stability: Stability,
}

impl Rigidity {
    /// Internal mechanisms, m less the rigid-body motions.
    pub fn internal_mechanisms(&self) -> usize {
        self.m - self.rigid_body_modes
    }
}

/// The key figures of an analysis for a case summary, or why it was skipped.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Rank r of the equilibrium matrix.
    pub rank: usize,
    /// Independent self-stress states, b − r.
    pub s: usize,
    /// Infinitesimal mechanisms, n_f − r, rigid-body motions included.
    pub m: usize,
    /// Rigid-body motions the supports allow.
    pub rigid_body_modes: usize,
    /// Internal mechanisms, m less the rigid-body motions.
    pub m_internal: usize,
    /// Whether the state is prestress stable ([`Stability::prestress_stable`]).
    pub prestress_stable: bool,
    /// Whether the state is super stable ([`Stability::super_stable`]).
    pub super_stable: bool,
    /// Why there is no analysis (a model above the dense limit); the figures are then 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
}

impl Summary {
    /// The figures of `analysis`, or zeros and the reason it failed.
    pub fn new(analysis: &Result<Rigidity, RigidityError>) -> Self {
        match analysis {
            Ok(r) => Summary {
                rank: r.rank,
                s: r.s,
                m: r.m,
                rigid_body_modes: r.rigid_body_modes,
                m_internal: r.internal_mechanisms(),
                prestress_stable: r.stability.prestress_stable,
                super_stable: r.stability.super_stable,
                skipped: None,
            },
            Err(e) => Summary {
                skipped: Some(e.to_string()),
                ..Summary::default()
            },
        }
    }
}

/// Analyses `model` at positions `x`. `prestress`: the member forces the state carries
/// [N], a self-equilibrium to the solver's tolerance (it sets the rank tolerance and is the
/// stress of the stability test); without it the proper self-stress is used.
pub fn analyse(model: &Model, x: &[Vector3<f64>], prestress: Option<&[f64]>) -> Result<Rigidity, RigidityError> {
    let dofs = DofMap::new(model, &[]);
    let (n, b) = (dofs.len(), model.members.len());
    if n.max(b) > MAX_DENSE {
        return Err(RigidityError::TooLarge { dofs: n, members: b });
    }
    let a = equilibrium_matrix(model, &dofs, x)?;
    let prestress_residual = prestress.map_or(0.0, |t| relative_residual(&a, t));
    // A clustered cable has one tension: its members' columns act as one.
    let tensions = Tensions::of(model);
    let a = tensions.columns(&a);
    let b = a.ncols();
    let svd = a.svd().map_err(|e| RigidityError::Svd(format!("{e:?}")))?;
    let singular_values: Vec<f64> = (0..n.min(b)).map(|i| svd.S()[i]).collect();
    let tolerance = rank_tolerance(&singular_values, n, b, prestress_residual);
    let rank = singular_values.iter().take_while(|&&sv| sv > tolerance).count();
    let self_stress = tensions.member_basis(svd.V().subcols(rank, b - rank).to_owned());
    let all_mechanisms = svd.U().subcols(rank, n - rank).to_owned();
    let rigid = rigid_motions(model, &dofs, x);
    let internal = complement(&all_mechanisms, &rigid);
    let (proper_self_stress, self_stress_source) = proper::self_stress(model, x, &self_stress, prestress);
    // The stability test takes the stress the state carries, else the proper self-stress.
    let stress = prestress.or(proper_self_stress.as_deref());
    let (stability, mechanisms) = stability::test(model, &dofs, x, stress, internal);
    Ok(Rigidity {
        singular_values,
        tolerance,
        rank,
        s: b - rank,
        m: n - rank,
        rigid_body_modes: rigid.ncols(),
        self_stress,
        dofs: (0..n).map(|i| dofs.owner(i)).collect(),
        mechanisms,
        proper_self_stress,
        self_stress_source,
        prestress_residual,
        stability,
    })
}

/// The equilibrium matrix on the free DOFs of `dofs` at positions `x`: column j holds
/// −J_j at member j's first node and +J_j at its second (J_j its unit vector), so that
/// A t is the internal force of member forces t and Aᵀ u the members' elongations under
/// the displacement u.
pub fn equilibrium_matrix(model: &Model, dofs: &DofMap, x: &[Vector3<f64>]) -> Result<Mat<f64>, RigidityError> {
    let mut a = Mat::zeros(dofs.len(), model.members.len());
    for (j, mem) in model.members.iter().enumerate() {
        let d = x[mem.nodes[1]] - x[mem.nodes[0]];
        let l = d.norm();
        if !(l > 0.0) {
            return Err(RigidityError::ZeroLength(mem.id.clone()));
        }
        for (node, sign) in [(mem.nodes[0], -1.0), (mem.nodes[1], 1.0)] {
            for axis in 0..3 {
                if let Some(i) = dofs.free(node, axis) {
                    a[(i, j)] += sign * d[axis] / l;
                }
            }
        }
    }
    Ok(a)
}

/// The independent tensions of a model: one per clustered cable, one per other member
/// (`tension[m]`: member m's). With clusters the equilibrium matrix is A S, S the members'
/// incidence on the tensions (Moored & Bart-Smith 2009, clustered tensegrity), so s and m
/// count the cables' sliding.
struct Tensions {
    of_member: Vec<usize>,
    count: usize,
}

impl Tensions {
    fn of(model: &Model) -> Self {
        let mut of_member = vec![usize::MAX; model.members.len()];
        for (k, c) in model.clusters.iter().enumerate() {
            c.members.iter().for_each(|&m| of_member[m] = k);
        }
        let mut count = model.clusters.len();
        for t in of_member.iter_mut().filter(|t| **t == usize::MAX) {
            *t = count;
            count += 1;
        }
        Tensions { of_member, count }
    }

    /// A S: the columns of a cluster's members summed (A itself without clusters).
    fn columns(&self, a: &Mat<f64>) -> Mat<f64> {
        if self.count == a.ncols() {
            return a.clone();
        }
        let mut out = Mat::zeros(a.nrows(), self.count);
        for (m, &t) in self.of_member.iter().enumerate() {
            for i in 0..a.nrows() {
                out[(i, t)] += a[(i, m)];
            }
        }
        out
    }

    /// An orthonormal basis of member forces S V from one `v` of tensions (`v` itself
    /// without clusters).
    fn member_basis(&self, v: Mat<f64>) -> Mat<f64> {
        if self.count == self.of_member.len() {
            return v;
        }
        range(&Mat::from_fn(self.of_member.len(), v.ncols(), |m, k| v[(self.of_member[m], k)]))
    }
}

/// ‖A t‖ / ‖t‖: how far member forces t are from a self-stress (dimensionless, A's
/// entries being direction cosines).
fn relative_residual(a: &Mat<f64>, t: &[f64]) -> f64 {
    let norm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
    let tv = Mat::from_fn(t.len(), 1, |i, _| t[i]);
    (a * &tv).norm_l2() / norm
}

/// The rank tolerance: the larger of
/// - round-off, max(n_f, b) · ε · σ_max: the error of singular values computed in floating
///   point is ~ε‖A‖₂ per operation over a dimension's worth of them (the LAPACK / NumPy
///   `matrix_rank` default);
/// - 10 ρ, ρ = ‖A t‖/‖t‖ the prestress's out-of-balance: a state in equilibrium only to
///   the solver's tolerance has its self-stress singular value at ≤ ρ, not at zero, and
///   the other near-null directions of the same inexact geometry at the same order; a
///   factor 10 of margin keeps them counted. A genuine singular value that small would be
///   miscounted, which the recorded singular values show.
pub fn rank_tolerance(singular_values: &[f64], n: usize, b: usize, prestress_residual: f64) -> f64 {
    let largest = singular_values.first().copied().unwrap_or(0.0);
    (n.max(b) as f64 * f64::EPSILON * largest).max(10.0 * prestress_residual)
}

/// An orthonormal basis (n_f × k) of the rigid-body motions the supports allow, on the free
/// DOFs: the translations and the rotations about the centroid, u_i = c + ω × (x_i − x̄),
/// with (c, ω) in the null space of their values at the supported directions.
fn rigid_motions(model: &Model, dofs: &DofMap, x: &[Vector3<f64>]) -> Mat<f64> {
    let centroid = x.iter().sum::<Vector3<f64>>() / x.len().max(1) as f64;
    let scale = x.iter().map(|p| (p - centroid).norm()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    // Column k < 3: translation along k; k ≥ 3: rotation about axis k − 3 (scaled to the
    // model size so both kinds have comparable norms).
    let motion = |node: usize, axis: usize, k: usize| -> f64 {
        if k < 3 {
            f64::from(u8::from(axis == k))
        } else {
            let w = Vector3::ith(k - 3, 1.0);
            w.cross(&((x[node] - centroid) / scale))[axis]
        }
    };
    let supported: Vec<(usize, usize)> = (0..model.node_count())
        .flat_map(|i| (0..3).map(move |a| (i, a)))
        .filter(|&(i, a)| dofs.free(i, a).is_none())
        .collect();
    let rs = Mat::from_fn(supported.len(), 6, |r, k| motion(supported[r].0, supported[r].1, k));
    let allowed = null_space(&rs, 6);
    let rf = Mat::from_fn(dofs.len(), 6, |i, k| {
        let (node, axis) = dofs.owner(i);
        motion(node, axis, k)
    });
    range(&(rf * allowed))
}

/// An orthonormal basis of the null space of `a` (columns), `cols` its column count
/// (`a` may have no rows: then everything).
fn null_space(a: &Mat<f64>, cols: usize) -> Mat<f64> {
    if a.nrows() == 0 {
        return Mat::identity(cols, cols);
    }
    let svd = a.svd().expect("SVD of at most 6 columns");
    let s: Vec<f64> = (0..a.nrows().min(cols)).map(|i| svd.S()[i]).collect();
    let r = s.iter().take_while(|&&v| v > rank_tolerance(&s, a.nrows(), cols, 0.0)).count();
    svd.V().subcols(r, cols - r).to_owned()
}

/// An orthonormal basis of the column space of `a`.
fn range(a: &Mat<f64>) -> Mat<f64> {
    if a.ncols() == 0 || a.nrows() == 0 {
        return Mat::zeros(a.nrows(), 0);
    }
    let svd = a.thin_svd().expect("SVD of at most 6 columns");
    let s: Vec<f64> = (0..a.nrows().min(a.ncols())).map(|i| svd.S()[i]).collect();
    let r = s.iter().take_while(|&&v| v > rank_tolerance(&s, a.nrows(), a.ncols(), 0.0)).count();
    svd.U().subcols(0, r).to_owned()
}

/// An orthonormal basis of the part of span(`m`) orthogonal to span(`r`) (`m`
/// orthonormal, span(`r`) ⊂ span(`m`)): the internal mechanisms.
fn complement(m: &Mat<f64>, r: &Mat<f64>) -> Mat<f64> {
    if r.ncols() == 0 || m.ncols() == 0 {
        return m.clone();
    }
    let c = m.transpose() * r;
    let svd = c.svd().expect("SVD of a small matrix");
    let k = r.ncols().min(m.ncols());
    m * svd.U().subcols(k, m.ncols() - k)
}

/// The members' kinds as signs: −1 for a strut (compressed), +1 for a cable (tensioned).
fn kind_signs(model: &Model) -> Vec<f64> {
    model
        .members
        .iter()
        .map(|m| match m.kind {
            MemberKind::Strut => -1.0,
            MemberKind::Cable => 1.0,
        })
        .collect()
}

#[cfg(test)]
mod tests;
