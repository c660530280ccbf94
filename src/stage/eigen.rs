//! Eigenvalue analysis at an equilibrium (paper §4.1, Table 2): K_T φ = ω² M φ on the
//! free DOFs, K_T with its geometric part (a cable's lateral stiffness is pure K_G), M
//! lumped. With diagonal M the symmetric-definite problem reduces to the standard one:
//! C = M^-½ K M^-½ = Y Λ Yᵀ, Φ = M^-½ Y, which is M-orthonormal.

use crate::error::{Error, Result};
use crate::model::Model;
use crate::tsm::{Assembly, DofMap};
use faer::{Mat, Side};
use nalgebra::Vector3;

#[derive(Clone, Debug)]
pub struct Modes {
    /// ω² ascending [rad²/s²].
    pub omega2: Vec<f64>,
    /// Mass-normalised shapes on the free DOFs, one column per mode.
    pub shapes: Mat<f64>,
}

impl Modes {
    /// Frequency f = ω/2π [Hz] (NaN for a negative ω², an unstable mode).
    pub fn frequency_hz(&self) -> Vec<f64> {
        self.omega2.iter().map(|w2| w2.sqrt() / (2.0 * std::f64::consts::PI)).collect()
    }

    /// Mode shapes expanded to every node ([mode][node]), zero at supported directions.
    pub fn node_shapes(&self, model: &Model, dofs: &DofMap) -> Vec<Vec<Vector3<f64>>> {
        (0..self.omega2.len())
            .map(|k| {
                let mut v = vec![Vector3::zeros(); model.node_count()];
                for i in 0..dofs.len() {
                    let (n, a) = dofs.owner(i);
                    v[n][a] = self.shapes[(i, k)];
                }
                v
            })
            .collect()
    }
}

/// Dense K_T on the free DOFs at the assembly's state.
pub fn tangent_matrix(asm: &Assembly) -> Mat<f64> {
    let n = asm.dofs.len();
    let mut k = Mat::zeros(n, n);
    asm.add_tangent(1.0, &mut k);
    k
}

/// Lumped mass on each free DOF from nodal masses.
pub fn free_masses(dofs: &DofMap, node_mass: &[f64]) -> Vec<f64> {
    (0..dofs.len()).map(|i| node_mass[dofs.owner(i).0]).collect()
}

/// All modes of K φ = ω² M φ; every free DOF must carry mass.
pub fn modes(k: &Mat<f64>, mass: &[f64], dofs: &DofMap, model: &Model) -> Result<Modes> {
    if let Some(i) = mass.iter().position(|&m| !(m > 0.0)) {
        return Err(Error::Stage {
            stage: "eigen",
            reason: format!("{} has no mass; give its members a density", dofs.label(model, i)),
        });
    }
    let inv_sqrt: Vec<f64> = mass.iter().map(|m| 1.0 / m.sqrt()).collect();
    let n = mass.len();
    let c = Mat::from_fn(n, n, |i, j| k[(i, j)] * inv_sqrt[i] * inv_sqrt[j]);
    let evd = c.self_adjoint_eigen(Side::Lower).map_err(|e| Error::Stage {
        stage: "eigen",
        reason: format!("eigen solver failed: {e:?}"),
    })?;
    let omega2: Vec<f64> = (0..n).map(|i| evd.S()[i]).collect();
    let y = evd.U();
    let shapes = Mat::from_fn(n, n, |i, j| y[(i, j)] * inv_sqrt[i]);
    Ok(Modes { omega2, shapes })
}

/// Stability of an equilibrium: the lowest eigenvalue of K_T on the free DOFs and the DOF
/// its eigenvector moves most. K_T positive definite ⇔ stable.
pub fn lowest_stiffness(k: &Mat<f64>, dofs: &DofMap, model: &Model) -> Result<(f64, String)> {
    let evd = k.self_adjoint_eigen(Side::Lower).map_err(|e| Error::Stage {
        stage: "stability",
        reason: format!("eigen solver failed: {e:?}"),
    })?;
    let u = evd.U();
    let i = (0..k.nrows())
        .max_by(|&a, &b| u[(a, 0)].abs().total_cmp(&u[(b, 0)].abs()))
        .unwrap_or(0);
    Ok((evd.S()[0], dofs.label(model, i)))
}
