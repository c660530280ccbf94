//! The virtual elements of form-finding (paper Table 1): measure potentials
//! N = C (l − l0)^n, struts stiff and linear, cables soft and cubic.
//!
//! Table 1 gives every cable C = 0.8. One C for all cables fixes the ratios of cable
//! force densities through the lengths alone (q = C l² for n = 3, l0 = 0): for the tower
//! layout it does form-find (with an uncapped Newton), but to a stable tower about a third
//! of the nominal height, far from Fig 2b (configs/paper_literal.yaml). So C may be set
//! per member group, and by default it is derived from the layout's self-stress, which
//! keeps Fig 2b's proportions:
//! at the nominal geometry, strut force densities are fixed at −1 and the cable group
//! force densities q_g solve the equilibrium equations in the least-squares sense; then
//! C_g = q_g / l_g² (l_g² the group's mean squared nominal length), scaled so the mean C
//! over all cables is Table 1's 0.8. The nominal shape is then close to an equilibrium
//! and form-finding lands on the nearby self-equilibrium with the layout's force ratios.

use crate::error::{Error, Result};
use crate::law::{ForceLaw, MeasurePotential};
use crate::model::{MemberKind, Model};
use crate::tsm::Elements;
use faer::linalg::solvers::Solve;
use faer::Mat;
use std::collections::BTreeMap;
use std::sync::Arc;

/// How cable coefficients C are chosen.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum CableCoefficients {
    /// One C for every cable (Table 1 literally: 0.8).
    Uniform(f64),
    /// C per member group (a cable's first group); every cable group must be listed.
    PerGroup(BTreeMap<String, f64>),
    /// From the layout's least-squares self-stress, scaled to this mean C.
    SelfStress {
        /// Mean cable C [N/m^n].
        mean: f64,
    },
}

/// Table 1's measure potentials with the cable rule above.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct MeasureSpec {
    /// Strut EA in C = EA/l0 [N] (Table 1: 2e11).
    pub strut_ea: f64,
    /// Strut rest length l0 [m]; absent: each strut's nominal length (Table 1: 7.0).
    pub strut_rest_length: Option<f64>,
    /// Strut exponent n (Table 1: 1).
    pub strut_n: f64,
    /// Cable exponent n (Table 1: 3); cable l0 is 0.
    pub cable_n: f64,
    /// How each cable's C [N/m^n] is chosen.
    pub cable_c: CableCoefficients,
}

impl Default for MeasureSpec {
    fn default() -> Self {
        MeasureSpec {
            strut_ea: 2e11,
            strut_rest_length: None,
            strut_n: 1.0,
            cable_n: 3.0,
            cable_c: CableCoefficients::SelfStress { mean: 0.8 },
        }
    }
}

const STAGE: &str = "form-finding";

fn group_of(model: &Model, m: usize) -> &str {
    model.members[m]
        .groups
        .first()
        .map(String::as_str)
        .unwrap_or(model.members[m].id.as_str())
}

impl MeasureSpec {
    /// Measure-potential elements for `model` at its nominal coordinates.
    pub fn elements(&self, model: &Model) -> Result<Elements> {
        let x = model.positions();
        let len = |m: usize| (x[model.members[m].nodes[1]] - x[model.members[m].nodes[0]]).norm();
        let cable_c = self.cable_coefficients(model)?;
        let mut laws: Vec<Arc<dyn ForceLaw>> = Vec::new();
        let mut rest = Vec::new();
        for (m, mem) in model.members.iter().enumerate() {
            match mem.kind {
                MemberKind::Strut => {
                    let l0 = self.strut_rest_length.unwrap_or_else(|| len(m));
                    laws.push(Arc::new(MeasurePotential {
                        c: self.strut_ea / l0,
                        n: self.strut_n,
                    }));
                    rest.push(l0);
                }
                MemberKind::Cable => {
                    laws.push(Arc::new(MeasurePotential {
                        c: cable_c[group_of(model, m)],
                        n: self.cable_n,
                    }));
                    rest.push(0.0);
                }
            }
        }
        Ok(Elements { laws, rest })
    }

    /// C for each cable group.
    pub fn cable_coefficients(&self, model: &Model) -> Result<BTreeMap<String, f64>> {
        let groups: Vec<String> = {
            let mut g: Vec<String> = (0..model.members.len())
                .filter(|&m| model.members[m].kind == MemberKind::Cable)
                .map(|m| group_of(model, m).to_string())
                .collect();
            g.sort();
            g.dedup();
            g
        };
        match &self.cable_c {
            CableCoefficients::Uniform(c) => Ok(groups.into_iter().map(|g| (g, *c)).collect()),
            CableCoefficients::PerGroup(map) => groups
                .into_iter()
                .map(|g| match map.get(&g) {
                    Some(&c) => Ok((g, c)),
                    None => Err(Error::Stage {
                        stage: STAGE.into(),
                        reason: format!("cable group `{g}` has no C in formfinding.cable_c.per_group; add it"),
                    }),
                })
                .collect(),
            CableCoefficients::SelfStress { mean } => self_stress_coefficients(model, &groups, *mean),
        }
    }
}

/// C_g from the least-squares self-stress at the nominal geometry (see module docs).
fn self_stress_coefficients(model: &Model, groups: &[String], mean: f64) -> Result<BTreeMap<String, f64>> {
    let x = model.positions();
    let ndof = 3 * model.node_count();
    let col = |g: &str| groups.iter().position(|h| h == g);
    // B_c: one column per cable group; rhs = Σ strut columns (strut q fixed at −1).
    let mut bc = Mat::<f64>::zeros(ndof, groups.len());
    let mut rhs = Mat::<f64>::zeros(ndof, 1);
    let mut l2 = vec![(0.0, 0usize); groups.len()];
    for (m, mem) in model.members.iter().enumerate() {
        let [i, j] = mem.nodes;
        let d = x[j] - x[i];
        let c = match mem.kind {
            MemberKind::Strut => None,
            MemberKind::Cable => col(group_of(model, m)),
        };
        for a in 0..3 {
            match c {
                Some(c) => {
                    bc[(3 * i + a, c)] += d[a];
                    bc[(3 * j + a, c)] -= d[a];
                }
                None => {
                    rhs[(3 * i + a, 0)] += d[a];
                    rhs[(3 * j + a, 0)] -= d[a];
                }
            }
        }
        if let Some(c) = c {
            l2[c].0 += d.norm_squared();
            l2[c].1 += 1;
        }
    }
    let normal = bc.transpose() * &bc;
    let mut q = bc.transpose() * &rhs;
    normal.partial_piv_lu().solve_in_place(q.as_mut());
    let mut coeffs = BTreeMap::new();
    let (mut sum, mut count) = (0.0, 0usize);
    for (g, name) in groups.iter().enumerate() {
        let qg = q[(g, 0)];
        if !(qg > 0.0) {
            return Err(Error::Stage {
                stage: STAGE.into(),
                reason: format!(
                    "the layout's least-squares self-stress puts force density {qg:.3e} (not tension) in cable group `{name}`: \
                     this layout has no self-stress near its nominal shape; change the layout or give formfinding.cable_c per group"
                ),
            });
        }
        let c = qg / (l2[g].0 / l2[g].1 as f64);
        coeffs.insert(name.clone(), c);
        sum += c * l2[g].1 as f64;
        count += l2[g].1;
    }
    let factor = mean / (sum / count as f64);
    coeffs.values_mut().for_each(|c| *c *= factor);
    Ok(coeffs)
}
