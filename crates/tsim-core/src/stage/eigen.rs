//! Eigenvalue analysis at an equilibrium (paper §4.1, Table 2): K_T φ = ω² M φ on the
//! free DOFs, K_T with its geometric part (a cable's lateral stiffness is pure K_G), M
//! lumped. With diagonal M the symmetric-definite problem reduces to the standard one:
//! C = M^-½ K M^-½ = Y Λ Yᵀ, Φ = M^-½ Y, which is M-orthonormal.
//!
//! Dense, that costs O(n³) time and a few n × n matrices: 2 000 free DOF take seconds,
//! 20 000 take hours and GBs. Above [`DENSE_EIGEN_LIMIT`] free DOF (or when asked) the
//! lowest k modes come instead from the partial solver (`solve::partial_eigen`,
//! shift-invert Lanczos on the sparse K_T), and so does the stability checks' lowest
//! eigenvalue. Below it every path is the dense one it always was, bit for bit.

use super::sequence::{Reached, Run, SequenceStage, StageSummary};
use super::{record_error, Analysis, Settings};
use crate::dynamics::Rayleigh;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::record::{EigenRecord, Recorder, Stage};
use crate::solve::{krylov_dimension, lowest_eigen, partial_eigen, symmetric_eigen, Diagonal, Shift, TangentSink};
use crate::structure::{State, Structure};
use crate::tsm::{tangent_sparsity, Assembly, DofMap};
use faer::Mat;
use nalgebra::Vector3;

/// Where Rayleigh damping comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DampingFrom {
    /// No damping: the eigen analysis on its own.
    None,
    /// α, β given.
    Given(Rayleigh),
    /// Damping ratios at two modes (1-based), eqs 13–14.
    Modes {
        /// The two 1-based mode numbers.
        modes: [usize; 2],
        /// Damping ratio ζ at each.
        ratios: [f64; 2],
    },
    /// Damping ratios at the two modes of largest effective modal mass along an axis
    /// (0, 1, 2 for x, y, z).
    AutoModes {
        /// 0, 1, 2 for x, y, z.
        axis: usize,
        /// Damping ratio ζ at each of the two modes, in mode order.
        ratios: [f64; 2],
    },
}

/// Eigen analysis at the state it is given, and the Rayleigh damping it implies.
#[derive(Clone, Debug, PartialEq)]
pub struct Eigen {
    /// Where the Rayleigh damping comes from.
    pub damping: DampingFrom,
    /// Kind and name, for the recorder.
    pub stage: Stage,
    /// Dense or partial, and how many modes.
    pub solver: ModeSolver,
}

/// Largest model (free DOF) whose modes `auto` computes densely (all of them). Measured on
/// this project's towers (bench/eigen.md): at 2 000 free DOF the dense decomposition takes
/// seconds and 200 MB, the partial one (20 modes) a fraction of a second.
pub const DENSE_EIGEN_LIMIT: usize = 1500;

/// Modes the partial solver computes unless told otherwise: enough for Rayleigh damping
/// from the low modes and for the effective-mass choice of `auto_modes` among them.
pub const DEFAULT_PARTIAL_MODES: usize = 20;

/// Dense or partial eigen analysis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum EigenSolverChoice {
    /// Dense up to [`DENSE_EIGEN_LIMIT`] free DOF, partial above.
    #[default]
    Auto,
    /// Every mode, by a dense decomposition.
    Dense,
    /// The lowest `modes` (or those nearest `shift`), by shift-invert Lanczos.
    Partial,
}

/// Which modes an analysis computes and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeSolver {
    /// Dense, partial, or by size.
    pub choice: EigenSolverChoice,
    /// Modes of the partial solver.
    pub modes: usize,
    /// The partial solver's modes are those nearest this ω² [rad²/s²] (`None`: the lowest).
    pub shift: Option<f64>,
}

impl Default for ModeSolver {
    fn default() -> Self {
        ModeSolver::lowest(DEFAULT_PARTIAL_MODES)
    }
}

impl ModeSolver {
    /// At least the lowest `modes`, dense or partial by size.
    pub fn lowest(modes: usize) -> Self {
        ModeSolver {
            choice: EigenSolverChoice::Auto,
            modes,
            shift: None,
        }
    }

    /// Whether `n` free DOF are solved by the partial solver: as chosen, or by size under
    /// `auto`; never when the Krylov space would not be smaller than the matrix.
    pub fn partial(&self, n: usize) -> bool {
        let fits = n > krylov_dimension(self.modes);
        match self.choice {
            EigenSolverChoice::Dense => false,
            EigenSolverChoice::Partial => fits,
            EigenSolverChoice::Auto => n > DENSE_EIGEN_LIMIT && fits,
        }
    }
}

/// Key figures of the eigen analysis.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct EigenSummary {
    /// ω² of the modes computed, ascending [rad²/s²].
    pub omega2: Vec<f64>,
    /// Their frequencies f = ω/2π [Hz].
    pub frequency_hz: Vec<f64>,
    /// 1-based modes the damping came from (empty when α, β were given).
    pub damping_modes: Vec<usize>,
    /// Damping ratio ζ asked for at each of `damping_modes`.
    pub damping_ratio: Vec<f64>,
    /// Rayleigh α [1/s].
    pub rayleigh_alpha: f64,
    /// Rayleigh β [s].
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

impl SequenceStage for Eigen {
    fn stage(&self) -> &Stage {
        &self.stage
    }

    fn run_from(&self, start: &Reached, run: &Run, recorder: &mut dyn Recorder) -> Result<(Reached, StageSummary)> {
        let (state, eigen) = Analysis::run(self, run.structure, start.state.clone(), run.settings, recorder)?;
        Ok((start.under_same_loads(state), StageSummary::Eigen(eigen)))
    }
}

impl Analysis for Eigen {
    type Summary = EigenSummary;

    fn run(&self, structure: &Structure, state: State, _settings: &Settings, recorder: &mut dyn Recorder) -> Result<(State, EigenSummary)> {
        let model = &structure.model;
        let dofs = DofMap::new(model, &[]);
        let asm = structure.assembly(&dofs, state.positions.clone(), state.rest_of(structure));
        super::require_apart(&asm, self.stage.name())?;
        let mass = structure.free_masses(&dofs);
        let m = modes(&asm, &mass, &self.solver)?;
        let (rayleigh, chosen, ratios) = match self.damping {
            DampingFrom::None => (Rayleigh::default(), vec![], vec![]),
            DampingFrom::Given(r) => (r, vec![], vec![]),
            DampingFrom::Modes { modes, ratios } => (m.rayleigh(modes, ratios)?, modes.to_vec(), ratios.to_vec()),
            DampingFrom::AutoModes { axis, ratios } => {
                let modes = m.auto_modes(&mass, &dofs, axis);
                (m.rayleigh(modes, ratios)?, modes.to_vec(), ratios.to_vec())
            }
        };
        recorder
            .eigen(&EigenRecord {
                stage: &self.stage,
                omega2: &m.omega2,
                mode_shapes: &m.node_shapes(model, &dofs),
                rayleigh_alpha: rayleigh.alpha,
                rayleigh_beta: rayleigh.beta,
                damping_modes: &chosen,
                damping_ratio: &ratios,
            })
            .map_err(record_error(self.stage.name()))?;
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

/// Eigenpairs of K_T φ = ω² M φ at one state, on the free DOFs.
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

    /// Rayleigh damping with damping `ratios` at the 1-based `modes` (eqs 13–14); an
    /// error names `eigen.modes` when the partial solver computed fewer modes.
    fn rayleigh(&self, modes: [usize; 2], ratios: [f64; 2]) -> Result<Rayleigh> {
        let count = self.omega2.len();
        if let Some(&k) = modes.iter().find(|&&k| k > count) {
            return Err(Error::Stage {
                stage: "eigen".into(),
                reason: format!(
                    "`eigen.rayleigh.modes` asks for mode {k}, but the partial eigen solver computed {count}; raise `eigen.modes` to at least {k}"
                ),
            });
        }
        let w = |k: usize| self.omega2[k - 1].sqrt();
        Ok(Rayleigh::from_modes(w(modes[0]), w(modes[1]), ratios[0], ratios[1]))
    }

    /// The two modes with the largest effective modal mass along `axis`, among the modes
    /// computed (all of them dense, the lowest k partial):
    /// m_eff = (φᵀ M r)² for mass-normalised φ and r the unit rigid translation.
    /// Returned 1-based, in ascending mode order.
    fn auto_modes(&self, mass: &[f64], dofs: &DofMap, axis: usize) -> [usize; 2] {
        let n = mass.len();
        let mut eff: Vec<(usize, f64)> = (0..self.omega2.len())
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

/// The modes of K_T φ = ω² M φ at the state of `asm` that `solver` asks for: all of them
/// (dense) or the lowest k (or nearest a shift; partial). Every free DOF must carry mass.
pub fn modes(asm: &Assembly, mass: &[f64], solver: &ModeSolver) -> Result<Modes> {
    if let Some(i) = mass.iter().position(|&m| !(m > 0.0)) {
        return Err(Error::Stage {
            stage: "eigen".into(),
            reason: format!("{} has no mass; give its members a density", asm.dofs.label(asm.model, i)),
        });
    }
    if !solver.partial(mass.len()) {
        return dense_modes(&tangent_matrix(asm), mass);
    }
    let shift = solver.shift.map_or(Shift::Lowest, Shift::Nearest);
    let pairs = partial_eigen(
        mass,
        tangent_sparsity(asm.model, asm.dofs),
        &|k: &mut dyn TangentSink| asm.add_tangent(1.0, k),
        solver.modes,
        shift,
    )
    .map_err(|e| Error::Stage {
        stage: "eigen".into(),
        reason: format!("partial eigen solver: {e}"),
    })?;
    Ok(Modes {
        omega2: pairs.values,
        shapes: pairs.vectors,
    })
}

/// All modes of K φ = ω² M φ by a dense decomposition.
fn dense_modes(k: &Mat<f64>, mass: &[f64]) -> Result<Modes> {
    let inv_sqrt: Vec<f64> = mass.iter().map(|m| 1.0 / m.sqrt()).collect();
    let n = mass.len();
    let c = Mat::from_fn(n, n, |i, j| k[(i, j)] * inv_sqrt[i] * inv_sqrt[j]);
    let (omega2, y) = symmetric_eigen(c.as_ref()).map_err(|e| Error::Stage {
        stage: "eigen".into(),
        reason: format!("eigen solver failed: {e:?}"),
    })?;
    let shapes = Mat::from_fn(n, n, |i, j| y[(i, j)] * inv_sqrt[i]);
    Ok(Modes { omega2, shapes })
}

/// The lowest eigenvalue of K_T at an equilibrium: its stability.
#[derive(Clone, Debug, PartialEq)]
pub struct LowestStiffness {
    /// The lowest eigenvalue of K_T on the free DOFs [N/m]. Within ±`band` the partial
    /// solver gives an upper bound, a Ritz value accurate to about a tenth of the band,
    /// and proves the eigenvalue less than half the band below it ([`lowest_eigen`]);
    /// elsewhere, and by the dense solver, to the solver's precision.
    pub value: f64,
    /// The direction its eigenvector moves most ("node `t3` direction z").
    pub at: String,
    /// The band ± this about zero in which round-off decides its sign [N/m]: 1e3 ε times
    /// K_T's largest diagonal entry (an eigenvalue of a symmetric matrix is resolved to
    /// ~ε‖K‖; a prestress-stabilised mechanism of the paper's tower sits ~1e5 times above it).
    pub band: f64,
}

/// Stability of an equilibrium: the lowest eigenvalue of K_T on the free DOFs of `asm` and
/// the DOF its eigenvector moves most. K_T positive definite ⇔ stable. Dense up to
/// [`DENSE_EIGEN_LIMIT`] free DOF, partial (one eigenpair, M = I, [`lowest_eigen`]) above.
pub fn lowest_stiffness(asm: &Assembly) -> Result<LowestStiffness> {
    let (dofs, model) = (asm.dofs, asm.model);
    let n = dofs.len();
    let band = 1e3 * f64::EPSILON * largest_diagonal(asm);
    let largest = |v: faer::MatRef<f64>| (0..n).max_by(|&a, &b| v[(a, 0)].abs().total_cmp(&v[(b, 0)].abs())).unwrap_or(0);
    let (value, i) = if ModeSolver::lowest(1).partial(n) {
        let pair = lowest_eigen(
            &vec![1.0; n],
            tangent_sparsity(model, dofs),
            &|k: &mut dyn TangentSink| asm.add_tangent(1.0, k),
            band,
        )
        .map_err(|e| Error::Stage {
            stage: "stability".into(),
            reason: format!("partial eigen solver: {e}"),
        })?;
        (pair.values[0], largest(pair.vectors.as_ref()))
    } else {
        let (values, vectors) = symmetric_eigen(tangent_matrix(asm).as_ref()).map_err(|e| Error::Stage {
            stage: "stability".into(),
            reason: format!("eigen solver failed: {e:?}"),
        })?;
        (values[0], largest(vectors.as_ref()))
    };
    Ok(LowestStiffness {
        value,
        at: dofs.label(model, i),
        band,
    })
}

/// The largest diagonal entry of K_T on the free DOFs of `asm` (the scale of its
/// eigenvalues' round-off), without a dense matrix.
pub fn largest_diagonal(asm: &Assembly) -> f64 {
    let mut d = Diagonal(vec![0.0; asm.dofs.len()]);
    asm.add_tangent(1.0, &mut d);
    d.0.iter().map(|v| v.abs()).fold(0.0, f64::max)
}
