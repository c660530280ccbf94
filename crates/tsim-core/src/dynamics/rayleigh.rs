/// Rayleigh damping C = αM + βK (paper eq 12).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rayleigh {
    /// Mass-proportional coefficient α [1/s].
    pub alpha: f64,
    /// Stiffness-proportional coefficient β [s].
    pub beta: f64,
}

impl Rayleigh {
    /// α, β that give damping ratios ζ_i, ζ_j at circular frequencies ω_i, ω_j
    /// (paper eqs 13–14; with ζ_i = ζ_j they reduce to eqs 15–16).
    pub fn from_modes(omega_i: f64, omega_j: f64, zeta_i: f64, zeta_j: f64) -> Self {
        let den = omega_j * omega_j - omega_i * omega_i;
        Rayleigh {
            alpha: 2.0 * omega_i * omega_j * (zeta_i * omega_j - zeta_j * omega_i) / den,
            beta: 2.0 * (zeta_j * omega_j - zeta_i * omega_i) / den,
        }
    }

    /// Damping ratio this damping gives a mode of circular frequency ω: ζ = α/2ω + βω/2.
    pub fn ratio_at(&self, omega: f64) -> f64 {
        self.alpha / (2.0 * omega) + self.beta * omega / 2.0
    }
}
