use super::{ForceLaw, LawEval};

/// Linear elastic bar, N = EA (l − l0)/l0 (engineering strain), as OpenSees' corotational
/// truss uses. With `tension_only` a slack member (l < l0) carries nothing and has no
/// material stiffness: a steel or nylon cable.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearElastic {
    /// Axial rigidity EA [N].
    pub ea: f64,
    /// A cable: slack (N = 0, dN/dl = 0) below its rest length instead of compressed.
    pub tension_only: bool,
}

impl ForceLaw for LinearElastic {
    fn eval(&self, l: f64, l0: f64) -> LawEval {
        if self.slack(l, l0) {
            return LawEval {
                force: 0.0,
                stiffness: 0.0,
                curvature: 0.0,
            };
        }
        LawEval {
            force: self.ea * (l - l0) / l0,
            stiffness: self.ea / l0,
            curvature: 0.0,
        }
    }

    fn tension_only(&self) -> bool {
        self.tension_only
    }

    /// N = EA (λ − 1) and U = l0 EA (λ − 1)²/2.
    fn of_stretch(&self) -> bool {
        true
    }

    fn energy(&self, l: f64, l0: f64) -> f64 {
        if self.slack(l, l0) {
            return 0.0;
        }
        0.5 * self.ea * (l - l0).powi(2) / l0
    }

    fn d_force_d_rest(&self, l: f64, l0: f64) -> f64 {
        if self.slack(l, l0) {
            return 0.0;
        }
        -self.ea * l / (l0 * l0)
    }

    /// U = EA (l − l0)²/(2 l0): ∂U/∂l0 = −N − N²/(2 EA).
    fn d_energy_d_rest(&self, l: f64, l0: f64) -> f64 {
        if self.slack(l, l0) {
            return 0.0;
        }
        let strain = (l - l0) / l0;
        -self.ea * strain * (1.0 + 0.5 * strain)
    }

    fn name(&self) -> &'static str {
        if self.tension_only {
            "elastic_tension_only"
        } else {
            "elastic"
        }
    }
}
