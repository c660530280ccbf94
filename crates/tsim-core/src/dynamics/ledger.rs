//! The energy ledger of a time-stepping stage: what the equations put in and took out,
//! step by step, against the mechanical energy they reached.

/// The energy ledger of one converged step [J].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Energy {
    /// Kinetic energy ½ vᵀ M v (relative to the ground under ground motion).
    pub kinetic: f64,
    /// Strain energy of the members, Σ U(l, l0).
    pub strain: f64,
    /// Energy of the contacts' barriers, Σ b(g) (zero without contact).
    pub contact: f64,
    /// Dissipated by damping since the stage began.
    pub damping: f64,
    /// Work of external loads (and, in folding, of prescribed displacements) since the stage began.
    pub external: f64,
    /// Work done on the members by changing their rest lengths since the stage began,
    /// ∫ Σ ∂U/∂l0 dl0 (actuators; zero where no rest length changes).
    pub actuation: f64,
}

/// The ledger since a stage began: KE + SE + CE + D − W − W_a − E0 is zero for exact
/// integration, E0 = KE + SE + CE at the start (CE: the contacts' barrier energy).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Ledger {
    pub(super) energy: Energy,
    initial: f64,
}

impl Ledger {
    /// At the start of a stage with kinetic, strain and contact energy `kinetic`, `strain`,
    /// `contact`.
    pub(super) fn start(kinetic: f64, strain: f64, contact: f64) -> Self {
        Ledger {
            energy: Energy {
                kinetic,
                strain,
                contact,
                ..Default::default()
            },
            initial: kinetic + strain + contact,
        }
    }

    /// A converged step reached `kinetic`, `strain` and `contact` energy, the damping forces
    /// dissipated `damping`, the loads did `external` and the actuators `actuation` of work
    /// over it.
    pub(super) fn add_step(&mut self, [kinetic, strain, contact]: [f64; 3], damping: f64, external: f64, actuation: f64) {
        let e = &self.energy;
        self.energy = Energy {
            kinetic,
            strain,
            contact,
            damping: e.damping + damping,
            external: e.external + external,
            actuation: e.actuation + actuation,
        };
    }

    /// |KE + SE + CE + D − W − W_a − E0|.
    pub(super) fn balance_error(&self) -> f64 {
        let e = &self.energy;
        (e.kinetic + e.strain + e.contact + e.damping - e.external - e.actuation - self.initial).abs()
    }
}

/// The trapezoidal work Σ ½ (f0 + f1)·Δu of forces f0 and f1 at a step's ends over its
/// increment Δu: with average acceleration, for the forces each equation actually used,
/// this is the scheme's discrete energy identity.
pub(super) fn trapezoidal_work(f0: &[f64], f1: &[f64], du: &[f64]) -> f64 {
    let mut w = 0.0;
    for i in 0..du.len() {
        w += 0.5 * (f0[i] + f1[i]) * du[i];
    }
    w
}
