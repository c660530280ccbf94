use crate::tsm::DofMap;
use nalgebra::Vector3;

/// Time profile of a load: the factor applied to its force at time t.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoadProfile {
    /// Full force for 0 ≤ t < duration, then none.
    Step,
    /// sin(π t / duration) for 0 ≤ t ≤ duration, then none: a smooth pulse.
    HalfSine,
}

/// The same force on each of a set of nodes (the paper's launch load).
#[derive(Clone, Debug, PartialEq)]
pub struct NodalLoad {
    pub nodes: Vec<usize>,
    /// Force per node [N].
    pub force: Vector3<f64>,
    /// Duration of the load [s].
    pub duration: f64,
    pub profile: LoadProfile,
}

impl NodalLoad {
    pub fn factor(&self, t: f64) -> f64 {
        match self.profile {
            LoadProfile::Step => f64::from(t >= 0.0 && t < self.duration),
            LoadProfile::HalfSine if (0.0..=self.duration).contains(&t) => (std::f64::consts::PI * t / self.duration).sin(),
            LoadProfile::HalfSine => 0.0,
        }
    }

    /// Adds the load at time t to a force vector on the free DOFs of `dofs`.
    pub fn add_free(&self, t: f64, dofs: &DofMap, f: &mut [f64]) {
        let s = self.factor(t);
        if s == 0.0 {
            return;
        }
        for &n in &self.nodes {
            for a in 0..3 {
                if let Some(i) = dofs.free(n, a) {
                    f[i] += s * self.force[a];
                }
            }
        }
    }
}
