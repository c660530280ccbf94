//! Contact over a time step in energy–momentum form, as the members' forces of
//! [`crate::tsm::EnergyMomentum`]: a contact whose gap goes from g_a at the step's start to
//! g_b at its end pushes with
//!
//!   F = B̄ ∇g(x_{n+½}),   B̄ = (b(g_b) − b(g_a)) / (g_b − g_a),
//!
//! the barrier's discrete derivative along the gap at the gap's gradient at the midpoint.
//! Its work over the step, B̄ ∇g(x_{n+½})·(x_b − x_a), is b(g_b) − b(g_a) exactly for the
//! ground (g linear in x), and to the third order of the step for two struts (∇g at the
//! midpoint integrates a gap of bounded curvature to O(Δx³)): an impact gives back the
//! energy it took, where Newmark's trapezoidal work of a barrier stiffening a thousandfold
//! within one step does not (a mass dropped 0.1 m rose 0.39 m). ∇g is balanced and
//! central (a distance between two points of the bodies), so momentum and angular momentum
//! are kept too. As g_b → g_a, B̄ → b′(g): the same force as every other stage.

use super::{Barrier, Contact, Mat12, SegmentDistance, Vec12};
use crate::model::clearance::{PairClearance, Segment, Struts, Workspace};
use crate::solve::TangentSink;
use nalgebra::Vector3;
use std::sync::Arc;

/// Below this |g_b − g_a| / min(g_a, g_b) Simpson's rule on b′ replaces the quotient
/// (whose cancellation grows as the gap change shrinks); the barrier's length scale is
/// the gap itself, so the rule's error, (Δg/g)⁴, is ~1e-12 of b′ there.
const SIMPSON_BELOW: f64 = 1e-3;

/// One contact over the step.
#[derive(Clone, Copy, Debug)]
struct Term {
    nodes: [usize; 4],
    count: usize,
    /// B̄ [N] and ∂B̄/∂g_b [N/m].
    slope: f64,
    dslope: f64,
    /// ∇g at the midpoint and at the end.
    mid: Vec12,
    end: Vec12,
    /// The struts' axes and closest points at the midpoint (for ∇²g there); `None` for
    /// the ground, where g is linear.
    pair: Option<(Segment, Segment, SegmentDistance)>,
}

/// The contacts of a structure over the step being solved.
#[derive(Clone, Debug)]
pub struct StepContact {
    contact: Arc<Contact>,
    start: Vec<Vector3<f64>>,
    end: Vec<Vector3<f64>>,
    terms: Vec<Term>,
    ws: Workspace,
    near: Vec<PairClearance>,
}

/// B̄ and ∂B̄/∂g_b of `barrier` over a gap change from `ga` to `gb`; `None` where it is zero
/// at both ends (beyond the activation distance).
pub fn discrete_slope(barrier: &Barrier, ga: f64, gb: f64) -> Option<(f64, f64)> {
    let h = barrier.distance;
    if ga >= h && gb >= h {
        return None;
    }
    let at = |g: f64| barrier.at(g).unwrap_or_default();
    let dg = gb - ga;
    if dg.abs() <= SIMPSON_BELOW * ga.min(gb) && (ga < h) == (gb < h) {
        let (a, m, b) = (at(ga), at(0.5 * (ga + gb)), at(gb));
        return Some(((a.slope + 4.0 * m.slope + b.slope) / 6.0, (2.0 * m.curvature + b.curvature) / 6.0));
    }
    let (a, b) = (at(ga), at(gb));
    let slope = (b.energy - a.energy) / dg;
    Some((slope, (b.slope - slope) / dg))
}

impl StepContact {
    /// For the contacts of `contact`.
    pub fn new(contact: Arc<Contact>) -> Self {
        StepContact {
            contact,
            start: Vec::new(),
            end: Vec::new(),
            terms: Vec::new(),
            ws: Workspace::default(),
            near: Vec::new(),
        }
    }

    /// A step starts at positions `x`.
    pub fn start_step(&mut self, x: &[Vector3<f64>]) {
        self.start.clear();
        self.start.extend_from_slice(x);
    }

    /// Adds the contacts' forces at an iterate whose midpoint is `mid` to `p` (3n): the
    /// end is 2 mid − start.
    pub fn at_midpoint(&mut self, mid: &[Vector3<f64>], p: &mut [f64]) {
        self.end.clear();
        self.end.extend(mid.iter().zip(&self.start).map(|(m, a)| 2.0 * m - a));
        self.terms.clear();
        let contact = Arc::clone(&self.contact);
        if let Some(ground) = &contact.ground {
            for (n, r) in contact.node_radius.iter().enumerate() {
                let Some(r) = *r else { continue };
                let gap = |x: &Vector3<f64>| ground.normal.dot(&(x - ground.point)) - r;
                if let Some((slope, dslope)) = discrete_slope(&contact.barrier, gap(&self.start[n]), gap(&self.end[n])) {
                    let mut g = Vec12::zeros();
                    g.fixed_rows_mut::<3>(0).copy_from(&ground.normal);
                    self.terms.push(Term {
                        nodes: [n; 4],
                        count: 1,
                        slope,
                        dslope,
                        mid: g,
                        end: g,
                        pair: None,
                    });
                }
            }
        }
        if let Some(struts) = &contact.struts {
            let travel = self.start.iter().zip(&self.end).map(|(a, b)| (b - a).norm()).fold(0.0, f64::max);
            // A pair within ĝ at either end is within ĝ + travel at the midpoint.
            struts.near(mid, contact.barrier.distance + travel, &mut self.ws, &mut self.near);
            for k in 0..self.near.len() {
                let pair = self.near[k].struts;
                self.strut_pair(struts, pair, mid);
            }
        }
        for t in &self.terms {
            for (k, &n) in t.nodes[..t.count].iter().enumerate() {
                for a in 0..3 {
                    p[3 * n + a] += t.slope * t.mid[3 * k + a];
                }
            }
        }
    }

    /// Struts `(i, j)` over the step, a term where the barrier acts at either end.
    fn strut_pair(&mut self, struts: &Struts, (i, j): (u32, u32), mid: &[Vector3<f64>]) {
        let radii = struts.radius(i) + struts.radius(j);
        let at = |x: &[Vector3<f64>]| (struts.segment(i, x), struts.segment(j, x));
        let distance = |(a, b): (Segment, Segment)| SegmentDistance::new(&a, &b);
        let (ga, end) = (distance(at(&self.start)).closest.distance - radii, distance(at(&self.end)));
        let Some((slope, dslope)) = discrete_slope(&self.contact.barrier, ga, end.closest.distance - radii) else {
            return;
        };
        let ([pa, qa], [pb, qb]) = (struts.ends(i), struts.ends(j));
        let (a, b) = at(mid);
        let mid = distance((a, b));
        self.terms.push(Term {
            nodes: [pa, qa, pb, qb],
            count: 4,
            slope,
            dslope,
            mid: mid.gradient,
            end: end.gradient,
            pair: Some((a, b, mid)),
        });
    }

    /// Adds ∂F/∂u over the end coordinates u at the last [`Self::at_midpoint`]:
    /// ∂B̄/∂g_b ∇g_mid ∇g_endᵀ + ½ B̄ ∇²g_mid (the midpoint moves at half u's rate; not
    /// symmetric).
    pub fn add_tangent(&self, dofs: &dyn super::Dofs, k: &mut (impl TangentSink + ?Sized)) {
        for t in &self.terms {
            let curvature = t.pair.map_or(Mat12::zeros(), |(a, b, sd)| sd.hessian(&a, &b) * (0.5 * t.slope));
            let h = t.mid * t.end.transpose() * t.dslope + curvature;
            super::add_block(dofs, &t.nodes[..t.count], &h, k);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::tests::{crossing, AllFree};

    /// The forces over a step from `start` to `end`.
    fn forces(contact: &Arc<Contact>, start: &[Vector3<f64>], end: &[Vector3<f64>]) -> (StepContact, Vec<f64>) {
        let mut step = StepContact::new(Arc::clone(contact));
        step.start_step(start);
        let mid: Vec<Vector3<f64>> = start.iter().zip(end).map(|(a, b)| 0.5 * (a + b)).collect();
        let mut p = vec![0.0; 3 * start.len()];
        step.at_midpoint(&mid, &mut p);
        (step, p)
    }

    /// A step that takes the crossing struts and the grounded node closer (by 2e-4 m):
    /// the forces' work is the barrier energy's change (exactly for the ground, to the
    /// step's third order for the pair), and the step tangent is the derivative of the
    /// forces in the end coordinates (central differences, step 1e-9 m; 1e-5 of the
    /// largest entry as in the contact set's test).
    #[test]
    fn the_step_forces_do_the_energy_s_work_and_their_tangent_is_their_derivative() {
        let (contact, start) = crossing();
        // a0 towards the ground, b (nodes 2, 3) towards a.
        let mut end = start.clone();
        for n in [0, 2, 3] {
            end[n].z -= 2e-4;
        }
        let (step, p) = forces(&contact, &start, &end);
        assert_eq!(step.terms.len(), 2, "the pair and the ground");
        let energy = |x: &[Vector3<f64>]| {
            let mut set = super::super::ContactSet::new(Arc::clone(&contact));
            set.evaluate(x, &mut vec![0.0; 3 * x.len()]);
            set.energy
        };
        let work: f64 = (0..12).map(|i| p[i] * (end[i / 3][i % 3] - start[i / 3][i % 3])).sum();
        let change = energy(&end) - energy(&start);
        println!("work {work:e} J, energy change {change:e} J");
        assert!((work - change).abs() <= 1e-6 * change.abs(), "{work} {change}");
        let mut k = faer::Mat::<f64>::zeros(12, 12);
        step.add_tangent(&AllFree, &mut k);
        let largest = (0..12)
            .flat_map(|i| (0..12).map(move |j| (i, j)))
            .map(|(i, j)| k[(i, j)].abs())
            .fold(0.0, f64::max);
        let h = 1e-9;
        for j in 0..12 {
            let at = |s: f64| {
                let mut y = end.clone();
                y[j / 3][j % 3] += s;
                forces(&contact, &start, &y).1
            };
            let (plus, minus) = (at(h), at(-h));
            for i in 0..12 {
                let fd = (plus[i] - minus[i]) / (2.0 * h);
                assert!((fd - k[(i, j)]).abs() <= 1e-5 * largest, "K[{i},{j}] {} vs {fd}", k[(i, j)]);
            }
        }
    }
}
