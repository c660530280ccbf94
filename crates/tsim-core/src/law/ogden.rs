use super::{ForceLaw, LawEval};

/// One term of the Ogden series: shear modulus μ [Pa] and exponent α.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OgdenTerm {
    /// Modulus μ_i [Pa]; one term may be negative (the paper's third is).
    pub mu: f64,
    /// Exponent α_i, dimensionless and non-zero.
    pub alpha: f64,
}

/// Uniaxial nominal stress of the incompressible Ogden solid (paper eq 5) and its slope:
/// F(λ) = Σ μ_i (λ^(α_i−1) − λ^(−1−α_i/2)).
pub fn ogden_nominal_stress(terms: &[OgdenTerm], lambda: f64) -> (f64, f64) {
    let (f, df, _) = ogden_stress_derivatives(terms, lambda);
    (f, df)
}

/// F(λ), dF/dλ and d²F/dλ² of the Ogden curve.
fn ogden_stress_derivatives(terms: &[OgdenTerm], lambda: f64) -> (f64, f64, f64) {
    let ln = lambda.ln();
    terms.iter().fold((0.0, 0.0, 0.0), |(f, df, d2f), t| {
        let a = t.alpha;
        // One exp per term and one log in all (powf is a log and an exp, and dominated
        // the solver's profile): with x = λ^(α/2) = exp(α/2 · ln λ), λ^(α−1) = x²/λ and
        // λ^(−1−α/2) = 1/(λx); each derivative's powers are these over λ. The exponent's
        // round-off, |α/2 · ln λ| ε, is a few ulp for any stretch a cord reaches.
        let x = (0.5 * a * ln).exp();
        let (p, q) = (x * x / lambda, 1.0 / (lambda * x));
        let d2 = ((a - 1.0) * (a - 2.0) * p - (1.0 + a / 2.0) * (2.0 + a / 2.0) * q) / (lambda * lambda);
        (
            f + t.mu * (p - q),
            df + t.mu * ((a - 1.0) * p + (1.0 + a / 2.0) * q) / lambda,
            d2f + t.mu * d2,
        )
    })
}

/// ∫ F dλ of the Ogden curve: Σ μ_i/α_i (λ^α_i + 2 λ^(−α_i/2)).
fn ogden_energy_density(terms: &[OgdenTerm], lambda: f64) -> f64 {
    let ln = lambda.ln();
    terms
        .iter()
        .map(|t| {
            let x = (0.5 * t.alpha * ln).exp();
            t.mu / t.alpha * (x * x + 2.0 / x)
        })
        .sum()
}

/// Rubber cord: N = A0 F(λ), λ = l/l0 (paper eqs 5, 9).
///
/// The Ogden solid stiffens in compression, a cord does not: below the junction stretch
/// λ_j the curve is replaced by the softening branch of eq 8, F(λ) = −√(aλ + b) − c.
/// The paper joins the two "smoothly" without saying how; tsim fixes the three
/// coefficients by three conditions:
/// 1. F is continuous at λ_j,
/// 2. dF/dλ is continuous at λ_j (C¹ join),
/// 3. the slope at full compression is a chosen fraction r of the slope at the junction,
///    dF/dλ(0) = r · dF/dλ(λ_j), 0 < r < 1 (default 0.1).
///
/// With s = √(aλ_j + b) and F'_j the Ogden slope at λ_j these give
/// s = 2 r² F'_j λ_j / (1 − r²), a = −2 s F'_j, b = s² − a λ_j, c = −s − F(λ_j).
/// Since a < 0 the branch slope −a / (2√(aλ + b)) falls as λ falls: the cord softens.
///
/// With `tension_only` the cord is slack below λ = 1 instead (N = 0, dN/dl = 0, no
/// energy), as a cable is: the branch is then never used.
#[derive(Clone, Debug, PartialEq)]
pub struct OgdenCord {
    /// The Ogden series Σ μ_i, α_i of the rubber.
    pub terms: Vec<OgdenTerm>,
    /// Primary cross-section A0 [m²].
    pub area: f64,
    /// Junction stretch λ_j in (0, 1].
    pub junction: f64,
    /// Slack (nothing carried) below λ = 1 instead of the compression branch; `new`
    /// leaves it off.
    pub tension_only: bool,
    branch: Branch,
}

#[derive(Clone, Debug, PartialEq)]
struct Branch {
    a: f64,
    b: f64,
    c: f64,
    /// ∫_1^{λ_j} F dλ on the Ogden curve, so the energy stays continuous across λ_j.
    energy_at_junction: f64,
}

impl OgdenCord {
    /// The paper's rubber (eqs 6–7), μ converted from N/mm² to Pa.
    pub fn paper_terms() -> Vec<OgdenTerm> {
        [(0.715e6, 0.88), (0.0205e6, 5.31), (-0.091e6, -1.01)]
            .into_iter()
            .map(|(mu, alpha)| OgdenTerm { mu, alpha })
            .collect()
    }

    /// `junction` is λ_j, `softening` the ratio r of condition 3. Both must lie in (0, 1]
    /// and (0, 1); the config layer checks that before calling.
    pub fn new(terms: Vec<OgdenTerm>, area: f64, junction: f64, softening: f64) -> Self {
        let (fj, dfj) = ogden_nominal_stress(&terms, junction);
        let r2 = softening * softening;
        let s = 2.0 * r2 * dfj * junction / (1.0 - r2);
        let a = -2.0 * s * dfj;
        let b = s * s - a * junction;
        let c = -s - fj;
        let energy_at_junction = ogden_energy_density(&terms, junction) - ogden_energy_density(&terms, 1.0);
        OgdenCord {
            terms,
            area,
            junction,
            tension_only: false,
            branch: Branch {
                a,
                b,
                c,
                energy_at_junction,
            },
        }
    }

    /// Nominal stress F(λ) [Pa] and dF/dλ [Pa] including the compression branch.
    pub fn nominal_stress(&self, lambda: f64) -> (f64, f64) {
        let (f, df, _) = self.stress_derivatives(lambda);
        (f, df)
    }

    /// F(λ), dF/dλ, d²F/dλ² [Pa] including the compression branch.
    fn stress_derivatives(&self, lambda: f64) -> (f64, f64, f64) {
        if self.tension_only && lambda < 1.0 {
            return (0.0, 0.0, 0.0);
        }
        if lambda >= self.junction {
            return ogden_stress_derivatives(&self.terms, lambda);
        }
        let Branch { a, b, c, .. } = self.branch;
        // The branch is defined down to λ = 0 (b > 0); a cord never inverts, but a Newton
        // trial state may: clamp the root's argument so the trial stays finite.
        let root = (a * lambda + b).max(0.0).sqrt().max(f64::MIN_POSITIVE);
        (-root - c, -a / (2.0 * root), a * a / (4.0 * root * root * root))
    }

    /// ∫_1^λ F dλ' [Pa].
    fn energy_density(&self, lambda: f64) -> f64 {
        if self.tension_only && lambda < 1.0 {
            return 0.0;
        }
        if lambda >= self.junction {
            return ogden_energy_density(&self.terms, lambda) - ogden_energy_density(&self.terms, 1.0);
        }
        let Branch {
            a,
            b,
            c,
            energy_at_junction,
        } = self.branch;
        let primitive = |x: f64| -2.0 / (3.0 * a) * (a * x + b).max(0.0).powf(1.5) - c * x;
        energy_at_junction + primitive(lambda) - primitive(self.junction)
    }
}

impl ForceLaw for OgdenCord {
    fn eval(&self, l: f64, l0: f64) -> LawEval {
        let (f, df, d2f) = self.stress_derivatives(l / l0);
        LawEval {
            force: self.area * f,
            stiffness: self.area * df / l0,
            curvature: self.area * d2f / (l0 * l0),
        }
    }

    fn energy(&self, l: f64, l0: f64) -> f64 {
        self.area * l0 * self.energy_density(l / l0)
    }

    fn d_force_d_rest(&self, l: f64, l0: f64) -> f64 {
        -self.eval(l, l0).stiffness * l / l0
    }

    /// U = A0 l0 w(λ), λ = l/l0: ∂U/∂l0 = A0 w − λ N.
    fn d_energy_d_rest(&self, l: f64, l0: f64) -> f64 {
        let lambda = l / l0;
        self.area * self.energy_density(lambda) - lambda * self.eval(l, l0).force
    }

    fn tension_only(&self) -> bool {
        self.tension_only
    }

    /// N = A f(λ) and U = A l0 w(λ).
    fn of_stretch(&self) -> bool {
        true
    }

    fn name(&self) -> &'static str {
        if self.tension_only {
            "ogden_cord_tension_only"
        } else {
            "ogden_cord"
        }
    }
}
