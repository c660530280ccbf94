//! The distance between two segments as a function of their four ends, with its gradient
//! and Hessian: what a strut–strut contact's force and tangent are made of.
//!
//! With x = (a0, a1, b0, b1) and the closest points at parameters σ = (s, t),
//! w(x, σ) = (1 − t) b0 + t b1 − (1 − s) a0 − s a1 and the distance d = √f,
//! f(x) = min_σ |w|². By the envelope theorem ∇f = 2 c ⊗ w with
//! c = (−(1 − s), −s, 1 − t, t); where some σ are free (strictly inside (0, 1)), the
//! stationarity ∂|w|²/∂σ_F = 0 moves them with x, and the Hessian is the Schur complement
//! ∇²f = G_xx − G_xF G_FF⁻¹ G_Fx of G = ∂²|w|²/∂(x, σ)² (a clamped σ stays at its end).
//! For skew segments crossing inside both, this is the distance of their lines, whose
//! Hessian it reproduces; for an end against a segment, a point–segment distance.

use crate::model::clearance::{Closest, Segment};
use nalgebra::{SMatrix, SVector};

/// 12 coordinates: a0, a1, b0, b1.
pub type Vec12 = SVector<f64, 12>;
/// 12 × 12 in the same order.
pub type Mat12 = SMatrix<f64, 12, 12>;

/// The distance of two segments and its derivatives in their ends' coordinates.
#[derive(Clone, Copy, Debug)]
pub struct SegmentDistance {
    /// The closest points and their distance d [m] (> 0 where used: strut axes in contact
    /// are at least their radii apart).
    pub closest: Closest,
    /// ∂d/∂x.
    pub gradient: Vec12,
}

/// Closest points closer than this fraction inside an end count as at the end: there the
/// closest-point map has a kink, and the side the round-off puts σ on does not matter.
const INSIDE: f64 = 1e-12;

impl SegmentDistance {
    /// d and ∂d/∂x of segments `a` and `b`.
    pub fn new(a: &Segment, b: &Segment) -> Self {
        let c = a.closest(b);
        let w = c.on_b - c.on_a;
        let coeff = weights(c.s, c.t);
        let mut gradient = Vec12::zeros();
        for (k, ck) in coeff.iter().enumerate() {
            gradient.fixed_rows_mut::<3>(3 * k).copy_from(&(w * (ck / c.distance)));
        }
        SegmentDistance { closest: c, gradient }
    }

    /// ∂²d/∂x² of segments `a`, `b` (those this was made from).
    pub fn hessian(&self, a: &Segment, b: &Segment) -> Mat12 {
        let Closest { s, t, distance: d, .. } = self.closest;
        let w = self.closest.on_b - self.closest.on_a;
        let (ea, eb) = (a.q - a.p, b.q - b.p);
        let c = weights(s, t);
        // G_xx = 2 (c cᵀ ⊗ I).
        let mut hf = Mat12::zeros();
        for i in 0..4 {
            for j in 0..4 {
                for k in 0..3 {
                    hf[(3 * i + k, 3 * j + k)] = 2.0 * c[i] * c[j];
                }
            }
        }
        // G_xσ columns: ∂(2 c ⊗ w)/∂s = 2 ((1, −1, 0, 0) ⊗ w + c ⊗ (−e_a)), likewise t with
        // (0, 0, −1, 1) and +e_b; G_σσ = 2 [[|e_a|², −e_a·e_b], [−e_a·e_b, |e_b|²]].
        let free: Vec<usize> = [s, t]
            .iter()
            .enumerate()
            .filter(|(_, &p)| p > INSIDE && p < 1.0 - INSIDE)
            .map(|(k, _)| k)
            .collect();
        if !free.is_empty() {
            let column = |k: usize| {
                let (dc, dw) = if k == 0 {
                    ([1.0, -1.0, 0.0, 0.0], -ea)
                } else {
                    ([0.0, 0.0, -1.0, 1.0], eb)
                };
                let mut g = Vec12::zeros();
                for i in 0..4 {
                    g.fixed_rows_mut::<3>(3 * i).copy_from(&((w * dc[i] + dw * c[i]) * 2.0));
                }
                g
            };
            let gss = [
                [2.0 * ea.norm_squared(), -2.0 * ea.dot(&eb)],
                [-2.0 * ea.dot(&eb), 2.0 * eb.norm_squared()],
            ];
            if let [k] = free[..] {
                let g = column(k);
                hf -= g * g.transpose() / gss[k][k];
            } else {
                let (g0, g1) = (column(0), column(1));
                let det = gss[0][0] * gss[1][1] - gss[0][1] * gss[1][0];
                // Free both only where the segments are not parallel (`Segment::closest` fixes
                // s there): det > 0.
                let inv = [[gss[1][1] / det, -gss[0][1] / det], [-gss[1][0] / det, gss[0][0] / det]];
                let gs = [g0, g1];
                for i in 0..2 {
                    for j in 0..2 {
                        hf -= gs[i] * gs[j].transpose() * inv[i][j];
                    }
                }
            }
        }
        // d = √f: ∇²d = ∇²f/(2d) − ∇f ∇fᵀ/(4d³), with ∇f = 2 d ∇d.
        hf / (2.0 * d) - self.gradient * self.gradient.transpose() / d
    }
}

/// c = (−(1 − s), −s, 1 − t, t): w = Σ c_k x_k.
fn weights(s: f64, t: f64) -> [f64; 4] {
    [-(1.0 - s), -s, 1.0 - t, t]
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn segments(x: &Vec12) -> (Segment, Segment) {
        let p = |k: usize| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
        (Segment::new(p(0), p(1)), Segment::new(p(2), p(3)))
    }

    /// Gradient and Hessian against central differences of d and of the gradient, in the
    /// three regimes: crossing inside both (both σ free), an end against the other's
    /// inside (one free), end to end (none free). Step 1e-6 m on coordinates of order 1:
    /// truncation ~1e-12 d‴, round-off ~1e-16/1e-6 = 1e-10; 1e-6 absolute on entries of
    /// order 1 leaves a wide margin and still catches any missing term (all are O(1)).
    #[test]
    fn derivatives_match_finite_differences() {
        let cases: [[f64; 12]; 3] = [
            [-1.0, 0.1, 0.0, 1.2, -0.2, 0.1, 0.3, -1.0, 0.7, -0.1, 1.1, 0.5],
            [-1.0, 0.0, 0.0, 1.0, 0.1, 0.0, 0.2, -0.5, 0.6, 0.9, -2.0, 1.7],
            [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.5, 0.3, 0.2, 2.5, 1.0, 0.4],
        ];
        let expect_free = [2, 1, 0];
        let h = 1e-6;
        for (case, free) in cases.iter().zip(expect_free) {
            let x = Vec12::from_row_slice(case);
            let (a, b) = segments(&x);
            let sd = SegmentDistance::new(&a, &b);
            let inside = [sd.closest.s, sd.closest.t]
                .iter()
                .filter(|p| **p > INSIDE && **p < 1.0 - INSIDE)
                .count();
            assert_eq!(inside, free, "{case:?}");
            let hess = sd.hessian(&a, &b);
            for i in 0..12 {
                let mut xp = x;
                let mut xm = x;
                xp[i] += h;
                xm[i] -= h;
                let (ap, bp) = segments(&xp);
                let (am, bm) = segments(&xm);
                let (dp, dm) = (SegmentDistance::new(&ap, &bp), SegmentDistance::new(&am, &bm));
                let slope = (dp.closest.distance - dm.closest.distance) / (2.0 * h);
                assert!((slope - sd.gradient[i]).abs() < 1e-6, "case {case:?} d/dx{i}");
                let column = (dp.gradient - dm.gradient) / (2.0 * h);
                for j in 0..12 {
                    assert!(
                        (column[j] - hess[(j, i)]).abs() < 1e-6,
                        "case {case:?} H[{j},{i}] {} vs {}",
                        hess[(j, i)],
                        column[j]
                    );
                }
            }
        }
    }
}
