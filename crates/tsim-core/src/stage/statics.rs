use crate::solve::{Residual, Scale, TangentSink};
use crate::tsm::Assembly;

/// Static nodal equilibrium r(u) = f_ext − p(u) with tangent K_T: the problem of
/// form-finding and of every folding step. It has a potential (strain energy less the
/// load's work), so Newton on it is globalized by an energy line search.
pub struct StaticEquilibrium<'a> {
    /// The structure at the current iterate.
    pub asm: Assembly<'a>,
    /// External load on the free DOFs [N].
    pub load: Vec<f64>,
}

impl Residual for StaticEquilibrium<'_> {
    fn residual(&mut self, u: &[f64], r: &mut [f64]) -> Scale {
        self.asm.set_free(u);
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = self.load[i] - self.asm.p_free(i);
        }
        let applied = self.load.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        self.asm.scale(applied)
    }

    fn tangent(&mut self, k: &mut dyn TangentSink) {
        self.asm.add_tangent(1.0, k);
    }

    fn symmetric(&self) -> bool {
        self.asm.symmetric_tangent()
    }

    /// Strain energy (and the contacts' barrier energy) less the work of the load: its
    /// gradient is −r. None with pulley friction, which dissipates: no potential.
    fn energy(&mut self, u: &[f64]) -> Option<f64> {
        if self.asm.friction.is_some() {
            return None;
        }
        self.asm.set_free(u);
        let work: f64 = self.load.iter().zip(u).map(|(f, ui)| f * ui).sum();
        Some(self.asm.strain_energy() + self.asm.contact_energy() - work)
    }

    fn admissible(&mut self, _u: &[f64], d: &[f64]) -> f64 {
        self.asm.admissible(d, 1.0)
    }
}
