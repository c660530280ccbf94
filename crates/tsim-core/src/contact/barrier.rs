//! The barrier that keeps bodies apart: a potential of the gap g between two surfaces
//! that is zero from the activation distance ĝ on and grows without bound as g → 0
//! (Li et al., *Incremental Potential Contact*, SIGGRAPH 2020, eq. 6):
//!
//! b(g) = −κ (g − ĝ)² ln(g/ĝ) for 0 < g < ĝ, 0 for g ≥ ĝ.
//!
//! It is C² at ĝ (b, b′ and b″ vanish there), so Newton sees a smooth problem, and its
//! force −b′ is unbounded as g → 0, so no finite load closes a gap: with every Newton
//! increment cut short of a zero gap ([`super::ContactSet::admissible`]), bodies never
//! overlap, whatever κ, and positions in contact are within ĝ of touching (they converge
//! as ĝ → 0).
//!
//! κ sets where in (0, ĝ) a force is carried, and how much energy a gap can take: b grows
//! only as κ ĝ² ln(ĝ/g) near 0, and a gap cannot shrink below the round-off of the
//! coordinates it is a difference of (~1e-16 m per m), so a barrier holds at most
//! ~30 κ ĝ² before its gap is lost in round-off (a 2 kg bar dropped 0.1 m, 2 J, on a
//! barrier of κ ĝ² = 1e-3 J went through the floor's round-off). So κ is given by its
//! energy scale E = κ ĝ², b(ĝ/2) = E ln 2 / 4 ≈ 0.17 E: the energy an impact may store at
//! half the activation distance.

/// The barrier's activation distance ĝ [m] and stiffness κ [N/m].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Barrier {
    /// ĝ: the gap below which it acts [m].
    pub distance: f64,
    /// κ [N/m]: κ ĝ² is its energy scale.
    pub stiffness: f64,
}

/// b, b′ and b″ at one gap.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BarrierValue {
    /// b(g) [J].
    pub energy: f64,
    /// b′(g) [N] (≤ 0: it pushes the gap open).
    pub slope: f64,
    /// b″(g) [N/m] (≥ 0).
    pub curvature: f64,
}

impl Barrier {
    /// The barrier of activation `distance` ĝ and energy scale `energy` = κ ĝ².
    pub fn with_energy(distance: f64, energy: f64) -> Self {
        Barrier {
            distance,
            stiffness: energy / (distance * distance),
        }
    }

    /// b and its derivatives at gap `g` [m]; `None` at or beyond the activation distance
    /// (no contact), and for g ≤ 0, which the admissible steps never reach (infinite).
    pub fn at(&self, g: f64) -> Option<BarrierValue> {
        let (h, k) = (self.distance, self.stiffness);
        if g >= h {
            return None;
        }
        let (d, ln) = (g - h, (g / h).ln());
        Some(BarrierValue {
            energy: -k * d * d * ln,
            slope: -k * (2.0 * d * ln + d * d / g),
            curvature: -k * (2.0 * ln + 4.0 * d / g - d * d / (g * g)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// b′ and b″ against central differences of b and b′ (step 1e-7 ĝ: truncation
    /// ~1e-14 ĝ² b‴, round-off ~ε b / 1e-7 ĝ; 1e-6 relative covers both over the range),
    /// the C² join at ĝ, and the force at half the distance.
    #[test]
    fn derivatives_match_finite_differences() {
        let b = Barrier::with_energy(1e-3, 0.05);
        let h = 1e-7 * b.distance;
        for frac in [0.01, 0.1, 0.3, 0.5, 0.9, 0.99] {
            let g = frac * b.distance;
            let at = |g| b.at(g).unwrap();
            let slope = (at(g + h).energy - at(g - h).energy) / (2.0 * h);
            let curvature = (at(g + h).slope - at(g - h).slope) / (2.0 * h);
            assert!((slope / at(g).slope - 1.0).abs() < 1e-6, "b' at {frac}");
            assert!((curvature / at(g).curvature - 1.0).abs() < 1e-6, "b'' at {frac}");
            assert!(at(g).slope < 0.0 && at(g).curvature > 0.0);
        }
        let join = b.at(b.distance * (1.0 - 1e-9)).unwrap();
        assert!(join.energy.abs() < 1e-20 && join.slope.abs() < 1e-12 && join.curvature.abs() < 1e-3);
        assert!(b.at(b.distance).is_none());
        // b(ĝ/2) = κ ĝ² ln 2 / 4.
        assert!((b.at(0.5 * b.distance).unwrap().energy / (0.05 * std::f64::consts::LN_2 / 4.0) - 1.0).abs() < 1e-14);
    }
}
