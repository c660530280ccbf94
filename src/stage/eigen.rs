//! Eigenvalue analysis at an equilibrium (paper §4.1, Table 2): K_T φ = ω² M φ on the
//! free DOFs, K_T with its geometric part (a cable's lateral stiffness is pure K_G), M
//! lumped. With diagonal M the symmetric-definite problem reduces to the standard one:
//! C = M^-½ K M^-½ = Y Λ Yᵀ, Φ = M^-½ Y, which is M-orthonormal.

use super::{record_error, Analysis, Settings};
use crate::dynamics::Rayleigh;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{EigenRecord, Recorder};
use crate::structure::{State, Structure};
use crate::tsm::{Assembly, DofMap};
use faer::{Mat, Side};
use nalgebra::Vector3;

/// Where Rayleigh damping comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DampingFrom {
    /// No damping: the eigen analysis on its own.
    None,
    /// α, β given.
    Given(Rayleigh),
    /// Damping ratios at two modes (1-based), eqs 13–14.
    Modes { modes: [usize; 2], ratios: [f64; 2] },
    /// Damping ratios at the two modes of largest effective modal mass along an axis
    /// (0, 1, 2 for x, y, z).
    AutoModes { axis: usize, ratios: [f64; 2] },
}

/// Eigen analysis at the state it is given, and the Rayleigh damping it implies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Eigen {
    pub damping: DampingFrom,
}

/// Key figures of the eigen analysis.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct EigenSummary {
    pub omega2: Vec<f64>,
    pub frequency_hz: Vec<f64>,
    /// 1-based modes the damping came from (empty when α, β were given).
    pub damping_modes: Vec<usize>,
    pub damping_ratio: Vec<f64>,
    pub rayleigh_alpha: f64,
    pub rayleigh_beta: f64,
}

impl EigenSummary {
    /// The Rayleigh damping the analysis chose.
    pub fn rayleigh(&self) -> Rayleigh {
        Rayleigh {
            alpha: self.rayleigh_alpha,
            beta: self.rayleigh_beta,
        }
    }
}

impl Analysis for Eigen {
    type Summary = EigenSummary;

    fn run(&self, structure: &Structure, state: State, _settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, EigenSummary)> {
        let model = &structure.model;
        let dofs = DofMap::new(model, &[]);
        let asm = Assembly::new(model, &structure.elements, &dofs, state.positions.clone());
        let mass = structure.free_masses(&dofs);
        let m = modes(&tangent_matrix(&asm), &mass, &dofs, model)?;
        let (rayleigh, chosen, ratios) = match self.damping {
            DampingFrom::None => (Rayleigh::default(), vec![], vec![]),
            DampingFrom::Given(r) => (r, vec![], vec![]),
            DampingFrom::Modes { modes, ratios } => (m.rayleigh(modes, ratios), modes.to_vec(), ratios.to_vec()),
            DampingFrom::AutoModes { axis, ratios } => {
                let modes = m.auto_modes(&mass, &dofs, axis);
                (m.rayleigh(modes, ratios), modes.to_vec(), ratios.to_vec())
            }
        };
        recorder
            .eigen(&EigenRecord {
                omega2: &m.omega2,
                mode_shapes: &m.node_shapes(model, &dofs),
                rayleigh_alpha: rayleigh.alpha,
                rayleigh_beta: rayleigh.beta,
                damping_modes: &chosen,
                damping_ratio: &ratios,
            })
            .map_err(record_error("eigen"))?;
        let summary = EigenSummary {
            frequency_hz: m.frequency_hz(),
            omega2: m.omega2,
            damping_modes: chosen,
            damping_ratio: ratios,
            rayleigh_alpha: rayleigh.alpha,
            rayleigh_beta: rayleigh.beta,
        };
        Ok((state, summary))
    }
}

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

    /// Rayleigh damping with damping `ratios` at the 1-based `modes` (eqs 13–14).
    fn rayleigh(&self, modes: [usize; 2], ratios: [f64; 2]) -> Rayleigh {
        let w = |k: usize| self.omega2[k - 1].sqrt();
        Rayleigh::from_modes(w(modes[0]), w(modes[1]), ratios[0], ratios[1])
    }

    /// The two modes with the largest effective modal mass along `axis`:
    /// m_eff = (φᵀ M r)² for mass-normalised φ and r the unit rigid translation.
    /// Returned 1-based, in ascending mode order.
    fn auto_modes(&self, mass: &[f64], dofs: &DofMap, axis: usize) -> [usize; 2] {
        let n = mass.len();
        let mut eff: Vec<(usize, f64)> = (0..n)
            .map(|k| {
                let g: f64 = (0..n)
                    .filter(|&i| dofs.owner(i).1 == axis)
                    .map(|i| self.shapes[(i, k)] * mass[i])
                    .sum();
                (k + 1, g * g)
            })
            .collect();
        eff.sort_by(|a, b| b.1.total_cmp(&a.1));
        let (a, b) = (eff[0].0, eff[1].0);
        [a.min(b), a.max(b)]
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
