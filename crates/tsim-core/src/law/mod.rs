//! The element force equation (paper eqs 3, 9): every member's axial force is a function of
//! its current length `l` and its non-stressed (rest) length `l0`. Every stage of tsim —
//! form-finding, vibration, folding, deployment — sees members only through [`ForceLaw`];
//! adding a material means adding one type that implements it.

mod elastic;
mod measure;
mod ogden;

pub use elastic::LinearElastic;
pub use measure::MeasurePotential;
pub use ogden::{ogden_nominal_stress, OgdenCord, OgdenTerm};

/// Force and its first two length derivatives at one length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LawEval {
    /// Axial force N [N], tension positive.
    pub force: f64,
    /// dN/dl [N/m]: the material part K_0 of the tangent stiffness uses it.
    pub stiffness: f64,
    /// d²N/dl² [N/m²]: the Jacobian of objective damping, β (dN/dl) l̇, needs it.
    pub curvature: f64,
}

/// A member's constitutive law, stateless: all parameters live in the implementing value,
/// the rest length is passed in so that one law value serves many members.
pub trait ForceLaw: Send + Sync + std::fmt::Debug {
    /// Force and stiffness at length `l` for rest length `l0` (both in m).
    fn eval(&self, l: f64, l0: f64) -> LawEval;
    /// Strain energy ∫ N dl from the force-free length to `l` [J].
    fn energy(&self, l: f64, l0: f64) -> f64;
    /// ∂N/∂l0 at fixed `l`: rest-length substitution solves N(l, l0) = N* for l0 with it.
    fn d_force_d_rest(&self, l: f64, l0: f64) -> f64;
    /// ∂U/∂l0 at fixed `l` [N]: the energy a change of rest length puts into the member at
    /// fixed ends, per metre; an actuator that changes l0 does this work
    /// (`dynamics::Newmark`'s ledger).
    fn d_energy_d_rest(&self, l: f64, l0: f64) -> f64;
    /// Short name for errors and outputs.
    fn name(&self) -> &'static str;
    /// Whether the law cannot push: below its rest length it is slack and carries
    /// nothing, its dN/dl dropping to zero there. Its total force with damping is then held
    /// at no compression too (`tsm::ObjectiveDamping`). Default: no.
    fn tension_only(&self) -> bool {
        false
    }
    /// Whether N and U/l0 depend on the stretch l/l0 alone (both real laws; not the
    /// measure potential): what a clustered cable's members need to share its tension
    /// (`tsm::cluster`). Default: no.
    fn of_stretch(&self) -> bool {
        false
    }
    /// Whether a member of length `l` is slack: a tension-only law below its rest length.
    fn slack(&self, l: f64, l0: f64) -> bool {
        self.tension_only() && l < l0
    }
}
