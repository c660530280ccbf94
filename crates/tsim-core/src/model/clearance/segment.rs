//! Closest points of two segments (Ericson, *Real-Time Collision Detection*, §5.1.9) and
//! the orientation of two segments' lines, the sign that flips when one line passes
//! through the other.

use nalgebra::Vector3;

/// A segment from `p` to `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// First end [m].
    pub p: Vector3<f64>,
    /// Second end [m].
    pub q: Vector3<f64>,
}

/// The closest points `a.p + s (a.q − a.p)` and `b.p + t (b.q − b.p)`, s, t ∈ [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// The parameter of the point on a.
    pub s: f64,
    /// The parameter of the point on b.
    pub t: f64,
    /// The point on a [m].
    pub on_a: Vector3<f64>,
    /// The point on b [m].
    pub on_b: Vector3<f64>,
    /// |on_b − on_a| [m].
    pub distance: f64,
}

/// Relative size of a² e² − b² (the squared sine of the angle between the segments times
/// their squared lengths) below which they are treated as parallel: there s is fixed at 0
/// and the clamping below finds the right closest pair, whereas dividing by a denominator
/// made of round-off would put s anywhere. 1e-14 is a few hundred ε: an angle below 1e-7 rad.
const PARALLEL: f64 = 1e-14;

impl Segment {
    /// The segment from `p` to `q`.
    pub fn new(p: Vector3<f64>, q: Vector3<f64>) -> Self {
        Segment { p, q }
    }

    /// The segment at fraction `tau` of the way from `self` to `other` (each end moving on
    /// a straight line).
    pub fn lerp(&self, other: &Segment, tau: f64) -> Segment {
        Segment {
            p: self.p.lerp(&other.p, tau),
            q: self.q.lerp(&other.q, tau),
        }
    }

    /// The closest points of `self` and `other`, degenerate (point) and parallel segments
    /// included.
    pub fn closest(&self, other: &Segment) -> Closest {
        let (d1, d2, r) = (self.q - self.p, other.q - other.p, self.p - other.p);
        let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
        let (s, t) = if a == 0.0 && e == 0.0 {
            (0.0, 0.0)
        } else if a == 0.0 {
            (0.0, (f / e).clamp(0.0, 1.0))
        } else {
            let c = d1.dot(&r);
            if e == 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else {
                let b = d1.dot(&d2);
                let denom = a * e - b * b;
                let s = if denom > PARALLEL * a * e {
                    ((b * f - c * e) / denom).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                // The point of `other` closest to s, then s again if t had to be clamped.
                let t = (b * s + f) / e;
                if t < 0.0 {
                    ((-c / a).clamp(0.0, 1.0), 0.0)
                } else if t > 1.0 {
                    (((b - c) / a).clamp(0.0, 1.0), 1.0)
                } else {
                    (s, t)
                }
            }
        };
        let (on_a, on_b) = (self.p + d1 * s, other.p + d2 * t);
        Closest {
            s,
            t,
            on_a,
            on_b,
            distance: (on_b - on_a).norm(),
        }
    }

    /// (other.p − self.p) · (d_self × d_other): six times the signed volume of the
    /// tetrahedron of the four ends.
    pub fn triple(&self, other: &Segment) -> f64 {
        (other.p - self.p).dot(&(self.q - self.p).cross(&(other.q - other.p)))
    }

    /// The orientation of the two segments' lines: +1 or −1 as the tetrahedron (self.p,
    /// self.q, other.p, other.q) is right- or left-handed, the sign of
    /// (other.p − self.p) · (d_self × d_other), the signed distance between the lines times
    /// |d_self × d_other|. 0 when the four points are coplanar within round-off (lines that
    /// meet, parallel lines, a flat folded state): no side to swap from.
    pub fn orientation(&self, other: &Segment) -> i8 {
        let (d1, d2, r) = (self.q - self.p, other.q - other.p, other.p - self.p);
        let triple = self.triple(other);
        // |triple| ≤ |r| |d1| |d2|; a relative 1e-10 is far above the round-off of the
        // products (~1e-15) and far below any real separation (1e-10 of a 7 m strut is
        // 0.7 nm). Compared squared, with (|r| + |d1| + |d2|)² ≤ 3 (|r|² + |d1|² + |d2|²):
        // no square root (this runs for every pair at every step).
        let (r2, a2, b2) = (r.norm_squared(), d1.norm_squared(), d2.norm_squared());
        if triple * triple <= 1e-20 * 3.0 * (r2 + a2 + b2) * a2 * b2 {
            0
        } else if triple > 0.0 {
            1
        } else {
            -1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    /// Distance from point `x` to segment `seg`, by projection (an independent closed form).
    fn point_distance(x: Vector3<f64>, seg: &Segment) -> f64 {
        let d = seg.q - seg.p;
        let t = if d.norm_squared() == 0.0 {
            0.0
        } else {
            ((x - seg.p).dot(&d) / d.norm_squared()).clamp(0.0, 1.0)
        };
        (seg.p + d * t - x).norm()
    }

    /// The segment distance by a ternary search over s of the point-to-segment distance
    /// (convex in s: the distance of a point moving on a line to a convex set).
    fn reference_distance(a: &Segment, b: &Segment) -> f64 {
        let f = |s: f64| point_distance(a.p + (a.q - a.p) * s, b);
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..200 {
            let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if f(m1) <= f(m2) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
    }

    #[test]
    fn known_configurations() {
        // Skew, closest points inside both: the unit-apart crossing of x and y axes.
        let a = Segment::new(v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
        let b = Segment::new(v(0.0, -1.0, 1.0), v(0.0, 1.0, 1.0));
        let c = a.closest(&b);
        assert_eq!((c.s, c.t, c.distance), (0.5, 0.5, 1.0));
        // Parallel, overlapping: the lines' distance.
        let b = Segment::new(v(0.5, 2.0, 0.0), v(3.0, 2.0, 0.0));
        assert!((a.closest(&b).distance - 2.0).abs() < 1e-15);
        // Parallel, disjoint along the line: end to end.
        let b = Segment::new(v(4.0, 0.0, 0.0), v(5.0, 0.0, 0.0));
        assert!((a.closest(&b).distance - 3.0).abs() < 1e-15);
        // Collinear through each other, and a point segment on the other.
        let b = Segment::new(v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0));
        assert_eq!(a.closest(&b).distance, 0.0);
        let b = Segment::new(v(0.3, 0.0, 0.0), v(0.3, 0.0, 0.0));
        // 0.3 = −1 + 2 s with s = 0.65 rounds by one ulp.
        assert!(a.closest(&b).distance <= 1e-16);
        // Two points.
        let p = Segment::new(v(0.0, 0.0, 0.0), v(0.0, 0.0, 0.0));
        let q = Segment::new(v(0.0, 3.0, 4.0), v(0.0, 3.0, 4.0));
        assert_eq!(p.closest(&q).distance, 5.0);
        // Orientation: flips when b passes to the other side of a; 0 when coplanar.
        let above = Segment::new(v(0.0, -1.0, 1.0), v(0.0, 1.0, 1.0));
        let below = Segment::new(v(0.0, -1.0, -1.0), v(0.0, 1.0, -1.0));
        let flat = Segment::new(v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0));
        assert_eq!(a.orientation(&above), -a.orientation(&below));
        assert_ne!(a.orientation(&above), 0);
        assert_eq!(a.orientation(&flat), 0);
    }

    proptest! {
        /// Random segments, including near-parallel and short ones: the closed form agrees
        /// with the ternary search to 1e-9 m (the search's own resolution after 200
        /// thirds is far finer; 1e-9 of coordinates of order 1 allows for the round-off of
        /// the near-parallel denominator), and its points are on the segments at that
        /// distance.
        #[test]
        fn matches_a_brute_force_search(
            c in prop::array::uniform12(-2.0f64..2.0),
            parallel in any::<bool>(),
            shrink in 0.0f64..1.0,
        ) {
            let a = Segment::new(v(c[0], c[1], c[2]), v(c[3], c[4], c[5]));
            let mut b = Segment::new(v(c[6], c[7], c[8]), v(c[9], c[10], c[11]));
            if parallel {
                // b along a (up to round-off), scaled and shifted.
                b.q = b.p + (a.q - a.p) * (shrink - 0.5);
            }
            let got = a.closest(&b);
            let want = reference_distance(&a, &b);
            prop_assert!((got.distance - want).abs() <= 1e-9, "{} vs {}", got.distance, want);
            prop_assert!((0.0..=1.0).contains(&got.s) && (0.0..=1.0).contains(&got.t));
            prop_assert!((point_distance(got.on_a, &a)) <= 1e-12);
            prop_assert!((point_distance(got.on_b, &b)) <= 1e-12);
        }
    }
}
