//! The material library: real laws for substitution, with the sources of their values.

use crate::law::{ForceLaw, LinearElastic, OgdenCord, OgdenTerm};
use std::collections::BTreeMap;
use std::sync::Arc;

/// A real material's force law.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum LawSpec {
    /// N = EA (l − l0)/l0.
    Elastic {
        /// Young's modulus E [Pa].
        youngs_modulus: f64,
        /// A slack member carries nothing (cables).
        #[serde(default)]
        tension_only: bool,
    },
    /// Rubber cord N = A0 F(λ) with the softening compression branch (see `law::OgdenCord`).
    Ogden {
        /// Ogden terms, μ [Pa] and α.
        terms: Vec<OgdenTermSpec>,
        /// Junction stretch λ_j of the compression branch, in (0, 1].
        #[serde(default = "one")]
        junction: f64,
        /// Slope at λ = 0 over slope at λ_j, in (0, 1).
        #[serde(default = "softening")]
        softening: f64,
        /// Slack (N = 0) below λ = 1 instead of the compression branch, as a cable.
        #[serde(default)]
        tension_only: bool,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OgdenTermSpec {
    pub mu: f64,
    pub alpha: f64,
}

fn one() -> f64 {
    1.0
}
fn softening() -> f64 {
    0.1
}

/// A material: law, cross-section and density.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    pub law: LawSpec,
    /// Cross-section A [m²] (A0 for rubber).
    pub area: f64,
    /// Physical density [kg/m³].
    pub density: f64,
    /// Where the values come from.
    #[serde(default)]
    pub source: String,
}

impl MaterialSpec {
    /// Radius of a solid round bar of this cross-section, √(A/π) [m] (a material knows
    /// its area only; a tube of that area would be wider).
    pub fn radius(&self) -> f64 {
        (self.area / std::f64::consts::PI).sqrt()
    }

    pub fn law(&self) -> Arc<dyn ForceLaw> {
        match &self.law {
            LawSpec::Elastic {
                youngs_modulus,
                tension_only,
            } => Arc::new(LinearElastic {
                ea: youngs_modulus * self.area,
                tension_only: *tension_only,
            }),
            LawSpec::Ogden {
                terms,
                junction,
                softening,
                tension_only,
            } => {
                let terms = terms.iter().map(|t| OgdenTerm { mu: t.mu, alpha: t.alpha }).collect();
                let mut cord = OgdenCord::new(terms, self.area, *junction, *softening);
                cord.tension_only = *tension_only;
                Arc::new(cord)
            }
        }
    }
}

fn elastic(e: f64, tension_only: bool, area: f64, density: f64, source: &str) -> MaterialSpec {
    MaterialSpec {
        law: LawSpec::Elastic {
            youngs_modulus: e,
            tension_only,
        },
        area,
        density,
        source: source.into(),
    }
}

/// Built-in materials. Struts are 0.01 m² sections as in the paper; cables 50 mm².
/// A config's `materials` section adds to or overrides these by name.
pub fn library() -> BTreeMap<String, MaterialSpec> {
    let rubber_terms = OgdenCord::paper_terms()
        .into_iter()
        .map(|t| OgdenTermSpec { mu: t.mu, alpha: t.alpha })
        .collect();
    BTreeMap::from([
        ("aluminium".into(), elastic(68e9, false, 0.01, 2700.0, "paper §3.1: E = 68 GPa, A = 0.01 m²; density 2700 kg/m³ (specific gravity 2.7, Table 3)")),
        ("steel".into(), elastic(200e9, false, 0.01, 7850.0, "structural steel, EN 1993-1-1 §3.2.6: E = 210 GPa nominal, 200 GPa used; 7850 kg/m³")),
        ("cfrp".into(), elastic(135e9, false, 0.01, 1600.0, "unidirectional carbon/epoxy tube, typical axial E = 135 GPa, 1600 kg/m³ (manufacturer data sheets)")),
        (
            "rubber".into(),
            MaterialSpec {
                law: LawSpec::Ogden { terms: rubber_terms, junction: 1.0, softening: 0.1, tension_only: false },
                area: 50e-6,
                density: 1000.0,
                source: "paper eqs 5–8: Ogden K = 3, α = (0.88, 5.31, −1.01), μ = (0.715, 0.0205, −0.091) MPa; A0 = 50 mm² (tsim default, not in the paper); specific gravity 1.0".into(),
            },
        ),
        ("steel_cable".into(), elastic(160e9, true, 50e-6, 7850.0, "spiral strand, EN 1993-1-11 Table B.1: E ≈ 150–160 GPa; 50 mm²")),
        ("nylon".into(), elastic(3e9, true, 50e-6, 1140.0, "nylon 6.6 rope, E ≈ 3 GPa, 1140 kg/m³ (polymer handbooks); 50 mm²")),
    ])
}
