//! The nearest pair of all pairs along a stage's steps, testing only the pairs that can
//! be it.
//!
//! A point of an axis moves by a convex combination of its ends' displacements, so by at
//! most the larger of the two: a pair's clearance changes by at most the sum of its
//! struts' larger end displacements. Summed over the steps since a pair was last tested
//! (each strut's `travel`), that gives a lower bound of its clearance now. A pair whose
//! bound exceeds the smallest clearance tested so far in the step, and zero, is neither
//! the nearest (not even tied) nor touching, and is skipped: the result is the one testing
//! every pair gives, exactly. A tower's struts move millimetres per step and their pairs lie
//! metres apart, so most pairs wait hundreds of steps between tests.

use super::{best, Nearest, PairClearance, Struts};
use nalgebra::Vector3;

/// What the computed clearance may differ from the exact distance of the axes less the
/// radii, relative to the two struts' lengths. Round-off is ~1e-15 of the coordinates; the
/// closest points of axes within 1e-7 rad of parallel (`segment::PARALLEL`) are taken at an
/// end, which may overstate the distance by the angle times a length, ≤ 1e-7 of it. A bound
/// lowered by 1e-6 of the lengths is therefore below the clearance the search would compute.
pub(super) const MARGIN: f64 = 1e-6;

/// Lower bounds of every pair's clearance (in the order of `Struts::pairs`).
#[derive(Clone, Debug)]
pub struct Bounds {
    /// Per strut, the sum over the steps so far of its larger end displacement [m].
    travel: Vec<f64>,
    /// Per pair, its clearance at its last test less the margin, plus both struts' travel
    /// then: the bound now is this less both struts' travel now (−∞: never tested).
    base: Vec<f64>,
    /// The nearest pair of the previous step, tested first so that the others are held
    /// against a small clearance from the start.
    last: Option<usize>,
}

impl Bounds {
    pub fn new(struts: &Struts) -> Self {
        Bounds {
            travel: vec![0.0; struts.len()],
            base: vec![f64::NEG_INFINITY; struts.pairs.len()],
            last: None,
        }
    }

    /// The nearest pair at positions `x`, which follow `previous` (empty at the first
    /// step); `near` is left holding every pair tested, which includes every touching one.
    pub fn nearest(
        &mut self,
        struts: &Struts,
        x: &[Vector3<f64>],
        previous: &[Vector3<f64>],
        near: &mut Vec<PairClearance>,
    ) -> Option<Nearest> {
        if !previous.is_empty() {
            for (travel, [p, q]) in self.travel.iter_mut().zip(&struts.ends) {
                *travel += (x[*p] - previous[*p]).norm().max((x[*q] - previous[*q]).norm());
            }
        }
        near.clear();
        let mut smallest = f64::INFINITY;
        let last = self.last;
        let order = last.into_iter().chain((0..struts.pairs.len()).filter(|&k| Some(k) != last));
        for k in order {
            if self.may_be_within(struts, k, smallest.max(0.0)) {
                let tested = self.test(struts, k, x);
                smallest = smallest.min(tested.clearance);
                near.push(tested);
            }
        }
        let pair = best(near)?.struts;
        // `pairs` is sorted (built in order of i, then j).
        self.last = struts.pairs.binary_search(&pair).ok();
        Some(struts.describe(pair, x))
    }

    /// Whether pair `k`'s clearance may be ≤ `clearance` now: its bound does not rule it out.
    pub fn may_be_within(&self, struts: &Struts, k: usize, clearance: f64) -> bool {
        let (i, j) = struts.pairs[k];
        let bound = self.base[k] - self.travel[i as usize] - self.travel[j as usize];
        !(bound > clearance)
    }

    /// Pair `k`'s clearance at `x`, from which its bound starts again.
    fn test(&mut self, struts: &Struts, k: usize, x: &[Vector3<f64>]) -> PairClearance {
        let (i, j) = struts.pairs[k];
        let clearance = struts.pair((i, j), x).0;
        let length = |s: u32| {
            let axis = struts.segment(s, x);
            (axis.q - axis.p).norm()
        };
        let travel = self.travel[i as usize] + self.travel[j as usize];
        self.base[k] = clearance - MARGIN * (length(i) + length(j)) + travel;
        PairClearance { struts: (i, j), clearance }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::clearance::{Search, Workspace};
    use crate::model::generate::TowerSpec;
    use proptest::prelude::*;

    /// The paper's tower moving 1 mm per step: after the first step, which tests all 45
    /// pairs, a step tests only the nearest pair and those within millimetres of it.
    #[test]
    fn small_steps_skip_most_pairs() {
        let model = TowerSpec::paper().build();
        let struts = Struts::new(&model, &vec![0.05; model.members.len()], Search::AllPairs);
        let mut bounds = Bounds::new(&struts);
        let (mut near, mut x) = (Vec::new(), model.positions());
        bounds.nearest(&struts, &x, &[], &mut near);
        assert_eq!(near.len(), 45);
        for _ in 0..10 {
            let previous = x.clone();
            x.iter_mut().for_each(|p| p.z += 1e-3);
            bounds.nearest(&struts, &x, &previous, &mut near);
            assert!(near.len() < 10, "{} pairs tested", near.len());
        }
    }

    proptest! {
        /// Random walks of a tower's nodes (steps up to `step` m per coordinate, every
        /// fifth a jump ten times as long; radii large enough for pairs to touch): at every
        /// step the bounded search gives the nearest pair testing all pairs gives, bit for
        /// bit, and every touching pair.
        #[test]
        fn skipping_pairs_changes_nothing(
            struts in 3usize..7,
            stages in 1usize..4,
            shifts in prop::collection::vec(-1.0f64..1.0, 30..90),
            step in 0.001f64..0.3,
            radius in 0.05f64..1.0,
        ) {
            let model = TowerSpec { struts, stages, ..TowerSpec::paper() }.build();
            let all = Struts::new(&model, &vec![radius; model.members.len()], Search::AllPairs);
            let mut bounds = Bounds::new(&all);
            let (mut ws, mut near, mut want) = (Workspace::default(), Vec::new(), Vec::new());
            let mut x = model.positions();
            let mut previous = Vec::new();
            for k in 0..40 {
                if k > 0 {
                    let jump = if k % 5 == 0 { 10.0 } else { 1.0 };
                    for (n, p) in x.iter_mut().enumerate() {
                        *p += Vector3::from_fn(|a, _| jump * step * shifts[(7 * k + 3 * n + a) % shifts.len()]);
                    }
                }
                let got = bounds.nearest(&all, &x, &previous, &mut near);
                prop_assert_eq!(got, all.nearest(&x, &mut ws, &mut want));
                let touching = |pairs: &[PairClearance]| {
                    let mut t: Vec<_> = pairs.iter().filter(|p| p.clearance <= 0.0).copied().collect();
                    t.sort_by_key(|p| p.struts);
                    t
                };
                prop_assert_eq!(touching(&near), touching(&want));
                previous.clone_from(&x);
            }
        }
    }
}
