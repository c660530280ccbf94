//! One case, start to end (paper Figure 1): form-finding → substitution → eigen analysis
//! (→ Rayleigh α, β) → free vibration → folding → deployment. Each stage hands the next a
//! converged state and pushes its converged steps to the recorder; nothing reaches back.

use crate::config::{Axis, CaseConfig, FoldTarget, LoadSpec, RayleighSpec, TransientSpec};
use crate::dynamics::{NewmarkParams, NodalLoad, Rayleigh};
use crate::error::{Error, Result};
use crate::law::ForceLaw;
use crate::model::{height, MemberKind, Model};
use crate::record::{EigenRecord, FormFindRecord, ModelRecord, Recorder, Stage};
use crate::stage::eigen::{free_masses, lowest_stiffness, modes, tangent_matrix};
use crate::stage::fold::{FoldSummary, Folding, Prescribed};
use crate::stage::formfind::form_find;
use crate::stage::substitute::{balanced_forces, substitute};
use crate::stage::transient::{Transient, TransientSummary};
use crate::tsm::{Assembly, DofMap, Elements};
use nalgebra::Vector3;
use std::sync::Arc;

/// Key figures of every stage that ran.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct CaseSummary {
    pub formfinding: Option<FormFindSummary>,
    pub substitution: SubstitutionSummary,
    pub eigen: Option<EigenSummary>,
    pub free_vibration: Option<TransientSummary>,
    pub folding: Option<FoldSummary>,
    pub deployment: Option<DeploymentSummary>,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FormFindSummary {
    pub iterations: usize,
    pub residuals: Vec<f64>,
    /// Largest support reaction [N] (zero for a self-equilibrium).
    pub max_reaction: f64,
    pub height: f64,
    pub min_force: f64,
    pub max_force: f64,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SubstitutionSummary {
    /// Out-of-balance of the real-material structure at the form-found shape [N].
    pub residual: f64,
    pub max_force: f64,
    /// Cable stretch λ = l/l0 range after substitution.
    pub cable_stretch: [f64; 2],
    /// Lowest eigenvalue of K_T (free DOFs) [N/m] and where it acts: > 0 is stable.
    pub lowest_stiffness: f64,
    pub lowest_stiffness_at: String,
    pub total_mass: f64,
}

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

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct DeploymentSummary {
    #[serde(flatten)]
    pub transient: TransientSummary,
    /// RMS over nodes of the distance to the pre-fold equilibrium, over the tower height.
    pub shape_error: f64,
    /// The same against the mirror image z → −z of the pre-fold shape: small when the
    /// tower deployed downwards (inverted).
    pub mirror_shape_error: f64,
}

fn rec_err(stage: &'static str) -> impl Fn(Box<dyn std::error::Error + Send + Sync>) -> Error {
    move |e| Error::Stage {
        stage,
        reason: format!("recording failed: {e}"),
    }
}

/// Lumped masses: each member's density × area × rest length, half to each end.
pub fn lumped_masses(model: &Model, rest: &[f64], linear_density: &[f64]) -> Vec<f64> {
    let mut m = vec![0.0; model.node_count()];
    for (k, mem) in model.members.iter().enumerate() {
        let half = 0.5 * linear_density[k] * rest[k];
        m[mem.nodes[0]] += half;
        m[mem.nodes[1]] += half;
    }
    m
}

fn nodal_load(model: &Model, spec: &LoadSpec) -> Result<NodalLoad> {
    let mut nodes = Vec::new();
    for g in &spec.groups {
        nodes.extend_from_slice(model.group(g)?);
    }
    nodes.sort_unstable();
    nodes.dedup();
    Ok(NodalLoad {
        nodes,
        force: Vector3::from(spec.force),
        duration: spec.duration,
        profile: spec.profile,
    })
}

fn params(t: &TransientSpec) -> NewmarkParams {
    NewmarkParams {
        beta: t.newmark_beta,
        gamma: t.newmark_gamma,
        dt: t.dt,
        duration: t.duration,
        max_cuts: t.max_cuts,
    }
}

/// Runs every configured stage of one case.
pub fn run_case(cfg: &CaseConfig, recorder: &mut dyn Recorder) -> Result<CaseSummary> {
    let model = cfg.model.build()?;
    let mut summary = CaseSummary::default();
    let lib = cfg.material_library();
    let material = |kind: MemberKind| {
        let name = if kind == MemberKind::Strut {
            &cfg.substitution.strut
        } else {
            &cfg.substitution.cable
        };
        lib[name].clone()
    };
    let (strut_mat, cable_mat) = (material(MemberKind::Strut), material(MemberKind::Cable));
    let (strut_law, cable_law) = (strut_mat.law(), cable_mat.law());
    let real_laws: Vec<Arc<dyn ForceLaw>> = model
        .members
        .iter()
        .map(|m| {
            if m.kind == MemberKind::Strut {
                strut_law.clone()
            } else {
                cable_law.clone()
            }
        })
        .collect();

    // Form-finding, then substitution; or the given rest lengths directly. Its record
    // waits for the model record, which needs the real rest lengths and masses.
    let mut formfound = None;
    let (positions, elements) = match &cfg.formfinding {
        Some(ff) => {
            let virtual_elements = ff.measure.elements(&model)?;
            let eq = form_find(&model, &virtual_elements, &cfg.newton)?;
            let forces = balanced_forces(&model, &eq.positions, &eq.forces);
            summary.formfinding = Some(FormFindSummary {
                iterations: eq.residuals.len() - 1,
                residuals: eq.residuals.clone(),
                max_reaction: eq.max_reaction,
                height: height(&eq.positions),
                min_force: forces.iter().copied().fold(f64::INFINITY, f64::min),
                max_force: forces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            });
            let sub = substitute(&model, &eq.positions, &forces, real_laws, cfg.substitution.prestress_scale)?;
            summary.substitution.residual = sub.residual;
            summary.substitution.max_force = sub.max_force;
            formfound = Some((eq.residuals, forces));
            (eq.positions, sub.elements)
        }
        None => {
            let rest = cfg.model.members.iter().map(|m| m.rest_length.unwrap_or_default()).collect();
            let elements = Elements { laws: real_laws, rest };
            let eq = form_find(&model, &elements, &cfg.newton)?;
            summary.substitution.residual = eq.residuals.last().copied().unwrap_or_default();
            summary.substitution.max_force = eq.forces.iter().map(|f| f.abs()).fold(0.0, f64::max);
            (eq.positions, elements)
        }
    };

    let dofs = DofMap::new(&model, &[]);
    let asm = Assembly::new(&model, &elements, &dofs, positions.clone());
    let stretch = model
        .members
        .iter()
        .enumerate()
        .filter(|(_, m)| m.kind == MemberKind::Cable)
        .map(|(k, _)| asm.states[k].length / elements.rest[k]);
    summary.substitution.cable_stretch = stretch.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], l| [lo.min(l), hi.max(l)]);
    let k = tangent_matrix(&asm);
    let (lowest, at) = lowest_stiffness(&k, &dofs, &model)?;
    summary.substitution.lowest_stiffness = lowest;
    summary.substitution.lowest_stiffness_at = at;

    let factor = cfg.masses.factor();
    let linear_density: Vec<f64> = model
        .members
        .iter()
        .map(|m| {
            let mat = if m.kind == MemberKind::Strut { &strut_mat } else { &cable_mat };
            mat.density * factor * mat.area
        })
        .collect();
    let node_mass = lumped_masses(&model, &elements.rest, &linear_density);
    summary.substitution.total_mass = node_mass.iter().sum();
    recorder
        .model(&ModelRecord {
            model: &model,
            rest_lengths: &elements.rest,
            masses: &node_mass,
        })
        .map_err(rec_err("model"))?;
    if let Some((residuals, forces)) = &formfound {
        recorder
            .formfinding(&FormFindRecord {
                residuals,
                positions: &positions,
                forces,
            })
            .map_err(rec_err("form-finding"))?;
    }

    let mut rayleigh = Rayleigh::default();
    if let Some(spec) = &cfg.eigen {
        let mass = free_masses(&dofs, &node_mass);
        let m = modes(&k, &mass, &dofs, &model)?;
        let r = &spec.rayleigh;
        let from_modes = |[i, j]: [usize; 2], ratios: [f64; 2]| {
            let w = |k: usize| m.omega2[k - 1].sqrt();
            (Rayleigh::from_modes(w(i), w(j), ratios[0], ratios[1]), vec![i, j], ratios.to_vec())
        };
        let (chosen, ratios);
        (rayleigh, chosen, ratios) = match *r {
            RayleighSpec::Given { alpha, beta } => (Rayleigh { alpha, beta }, vec![], vec![]),
            RayleighSpec::Modes { modes, ratios } => from_modes(modes, ratios),
            RayleighSpec::AutoModes { axis, ratios } => from_modes(auto_modes(&m, &mass, &dofs, axis), ratios),
        };
        let shapes = m.node_shapes(&model, &dofs);
        recorder
            .eigen(&EigenRecord {
                omega2: &m.omega2,
                mode_shapes: &shapes,
                rayleigh_alpha: rayleigh.alpha,
                rayleigh_beta: rayleigh.beta,
                damping_modes: &chosen,
                damping_ratio: &ratios,
            })
            .map_err(rec_err("eigen"))?;
        summary.eigen = Some(EigenSummary {
            frequency_hz: m.frequency_hz(),
            omega2: m.omega2,
            damping_modes: chosen,
            damping_ratio: ratios,
            rayleigh_alpha: rayleigh.alpha,
            rayleigh_beta: rayleigh.beta,
        });
    }

    let transient = |spec: &TransientSpec, stage: Stage, x0: Vec<Vector3<f64>>, recorder: &mut dyn Recorder| -> Result<TransientSummary> {
        let load = spec.load.as_ref().map(|l| nodal_load(&model, l)).transpose()?;
        Transient {
            stage,
            params: params(spec),
            rayleigh: if spec.damped { rayleigh } else { Rayleigh::default() },
            tangent: spec.damping_tangent,
            load: load.as_ref(),
            newton: cfg.newton,
            every: cfg.outputs.every,
        }
        .run(&model, &elements, x0, &node_mass, recorder)
    };

    if let Some(spec) = &cfg.free_vibration {
        summary.free_vibration = Some(transient(spec, Stage::FreeVibration, positions.clone(), recorder)?);
    }

    let mut start = positions.clone();
    if let Some(spec) = &cfg.folding {
        let prescribed = prescribed_dofs(&model, &positions, spec)?;
        let folded = Folding {
            steps: spec.steps,
            max_cuts: spec.max_cuts,
            newton: cfg.newton,
        }
        .run(&model, &elements, positions.clone(), &prescribed, recorder)?;
        start = folded.final_positions.clone();
        summary.folding = Some(folded);
    }

    if let Some(spec) = &cfg.deployment {
        let t = transient(spec, Stage::Deployment, start, recorder)?;
        let h = height(&positions);
        let rms = |target: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
            (t.final_positions
                .iter()
                .zip(&positions)
                .map(|(x, p)| (x - target(p)).norm_squared())
                .sum::<f64>()
                / positions.len() as f64)
                .sqrt()
                / h
        };
        let base_z = positions.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        summary.deployment = Some(DeploymentSummary {
            shape_error: rms(&|p| *p),
            mirror_shape_error: rms(&|p| Vector3::new(p.x, p.y, 2.0 * base_z - p.z)),
            transient: t,
        });
    }
    Ok(summary)
}

/// Targets of the prescribed directions (start and end value per node direction).
fn prescribed_dofs(model: &Model, x: &[Vector3<f64>], spec: &crate::config::FoldSpec) -> Result<Prescribed> {
    let mut dofs = Vec::new();
    for p in &spec.prescribe {
        let a = p.axis.index();
        let base_level = if p.target == FoldTarget::ToBase {
            let base = model.group("base")?;
            base.iter().map(|&n| x[n][a]).sum::<f64>() / base.len() as f64
        } else {
            0.0
        };
        for &n in model.group(&p.group)? {
            let target = match p.target {
                FoldTarget::Displacement(d) => x[n][a] + d,
                FoldTarget::ToBase => base_level,
            };
            dofs.retain(|&(m, b, _, _)| !(m == n && b == a));
            dofs.push((n, a, x[n][a], target));
        }
    }
    Ok(Prescribed { dofs })
}

/// The two modes with the largest effective modal mass along `axis`:
/// m_eff = (φᵀ M r)² for mass-normalised φ and r the unit rigid translation.
/// Returned 1-based, in ascending mode order.
fn auto_modes(m: &crate::stage::eigen::Modes, mass: &[f64], dofs: &DofMap, axis: Axis) -> [usize; 2] {
    let n = mass.len();
    let mut eff: Vec<(usize, f64)> = (0..n)
        .map(|k| {
            let g: f64 = (0..n)
                .filter(|&i| dofs.owner(i).1 == axis.index())
                .map(|i| m.shapes[(i, k)] * mass[i])
                .sum();
            (k + 1, g * g)
        })
        .collect();
    eff.sort_by(|a, b| b.1.total_cmp(&a.1));
    let (a, b) = (eff[0].0, eff[1].0);
    [a.min(b), a.max(b)]
}
