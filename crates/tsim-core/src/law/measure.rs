use super::{ForceLaw, LawEval};

/// Virtual "measure potential" element of form-finding (paper eqs 2–3):
/// N = C (l − l0)^n, from the potential P = C/(n+1) (l − l0)^(n+1).
///
/// For l < l0 the law is extended as an odd function, N = −C |l − l0|^n: a strut
/// shortened below l0 pushes back, a cable potential with l0 > l compresses. For odd
/// integer n (the paper's n = 1 and n = 3) this is the plain power, so the paper's law is
/// unchanged; for other n it keeps N real and the potential convex.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasurePotential {
    /// Coefficient C [N/m^n].
    pub c: f64,
    /// Multiplier n ≥ 1.
    pub n: f64,
}

impl ForceLaw for MeasurePotential {
    fn eval(&self, l: f64, l0: f64) -> LawEval {
        let d = l - l0;
        let a = d.abs();
        LawEval {
            force: self.c * d.signum() * a.powf(self.n),
            stiffness: self.n * self.c * a.powf(self.n - 1.0),
            // Zero for n = 1, where a^(n − 2) would be 1/0 at l = l0.
            curvature: if self.n == 1.0 {
                0.0
            } else {
                self.n * (self.n - 1.0) * self.c * d.signum() * a.powf(self.n - 2.0)
            },
        }
    }

    fn energy(&self, l: f64, l0: f64) -> f64 {
        self.c * (l - l0).abs().powf(self.n + 1.0) / (self.n + 1.0)
    }

    fn d_force_d_rest(&self, l: f64, l0: f64) -> f64 {
        -self.eval(l, l0).stiffness
    }

    /// U depends on l − l0 only: ∂U/∂l0 = −N.
    fn d_energy_d_rest(&self, l: f64, l0: f64) -> f64 {
        -self.eval(l, l0).force
    }

    fn name(&self) -> &'static str {
        "measure_potential"
    }
}
