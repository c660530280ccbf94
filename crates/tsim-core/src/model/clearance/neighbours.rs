//! The grid search along a stage's steps: the candidate pairs found once and reused while
//! the struts stay near where they were (a Verlet neighbour list, as molecular dynamics
//! keeps one per atom).
//!
//! A point of an axis moves by a convex combination of its ends' displacements, so two
//! axes' distance changes by at most twice the largest node displacement D since the list
//! was built: a list of every non-adjacent pair whose axes were within `reach` then holds
//! every pair within reach − 2D now. A step needs the pairs within
//! - the nearest pair's clearance (or 0, for the touching ones) plus both radii, and
//! - twice the step's largest displacement: a pair whose axes crossed during the step is
//!   that close at its end (the tracker's pass-throughs).
//!
//! While the list covers both, a step tests the listed pairs alone, without the grid and
//! its sort (a 105 × 105 grid's 22 000 struts: 0.12 s per step by the grid). Otherwise
//! the grid rebuilds it at twice the reach needed: the slack for the steps to come. The
//! result is the one the grid gives at every step, exactly.

use super::bound::MARGIN;
use super::{best, Aabb, Nearest, PairClearance, Struts, Workspace};
use nalgebra::Vector3;

/// The listed pairs and the positions they were listed at.
#[derive(Clone, Debug, Default)]
pub struct Neighbours {
    /// Node positions at the last build (empty before the first).
    at: Vec<Vector3<f64>>,
    /// Every non-adjacent pair whose computed axis distance was ≤ `reach` at `at`, sorted.
    pairs: Vec<(u32, u32)>,
    reach: f64,
    /// Round-off allowance of computed axis distances ([`MARGIN`] of two longest struts),
    /// taken once at the build and once at the step.
    margin: f64,
    /// Each listed pair's axis distance at the last step [m].
    distance: Vec<f64>,
    ws: Workspace,
}

impl Neighbours {
    /// The nearest pair at positions `x`, which moved at most `travel` [m] per node since
    /// the previous step; `near` is left holding every pair within max(nearest, 0) of
    /// clearance (every touching pair). Afterwards [`Neighbours::within`] lists every pair
    /// within 2 `travel` of axis distance.
    pub fn nearest(&mut self, struts: &Struts, x: &[Vector3<f64>], travel: f64, near: &mut Vec<PairClearance>) -> Option<Nearest> {
        let diagonal = diagonal(struts, x);
        if !diagonal.is_finite() {
            // Non-finite positions: no list to keep; the stage reports them.
            self.at.clear();
            self.pairs.clear();
            self.distance.clear();
            return struts.nearest(x, &mut self.ws, near);
        }
        let two_r = 2.0 * struts.r_max;
        // Above the margins (≤ 4e-6 of the longest strut, so of the diagonal), so that a
        // list built at twice a reach covers that reach.
        let floor = 1e-5 * diagonal;
        loop {
            let crossing = 2.0 * travel + self.margin;
            // The axis distance within which the list holds every pair now.
            let covered = self.reach - 2.0 * self.moved(struts, x) - 2.0 * self.margin;
            if covered >= crossing.max(two_r) {
                match self.test(struts, x, near) {
                    // A list grown fourfold at a time may reach far beyond the pairs
                    // needed, and then each step tests many more: it is built again.
                    // (A rebuild lands within: `needed` below is at most twice the need.)
                    Some(c) if covered >= c.max(0.0) + two_r && self.reach <= 4.0 * (c.max(0.0) + two_r).max(crossing).max(floor) => {
                        near.retain(|p| p.clearance <= c.max(0.0));
                        return Some(struts.describe(best(near)?.struts, x));
                    }
                    // No pair within the reach; beyond the diagonal none exists.
                    None if self.reach >= diagonal => return None,
                    _ => {}
                }
            }
            let needed = match self.distance.iter().copied().reduce(f64::min) {
                // The nearest's clearance is at most any listed pair's axis distance.
                Some(axes) => axes.max(0.0) + two_r,
                // None within the reach (or no list yet): grow it fourfold.
                None => 4.0 * self.reach,
            };
            self.build(struts, x, 2.0 * needed.max(crossing).max(two_r).max(floor));
        }
    }

    /// The listed pairs whose axes were within `distance` [m] at the last step.
    pub fn within(&self, distance: f64) -> impl Iterator<Item = (u32, u32)> + '_ {
        let limit = distance + self.margin;
        self.pairs
            .iter()
            .zip(&self.distance)
            .filter(move |(_, &d)| d <= limit)
            .map(|(&p, _)| p)
    }

    /// The largest displacement of a strut's end since the build.
    fn moved(&self, struts: &Struts, x: &[Vector3<f64>]) -> f64 {
        if self.at.is_empty() {
            return f64::INFINITY;
        }
        struts
            .ends
            .iter()
            .flatten()
            .map(|&n| (x[n] - self.at[n]).norm())
            .fold(0.0, f64::max)
    }

    /// Tests every listed pair at `x` into `near` (cleared first); returns the smallest
    /// clearance (`None`: no pair listed).
    fn test(&mut self, struts: &Struts, x: &[Vector3<f64>], near: &mut Vec<PairClearance>) -> Option<f64> {
        near.clear();
        self.distance.clear();
        for &pair in &self.pairs {
            let clearance = struts.pair(pair, x).0;
            self.distance
                .push(clearance + struts.radius[pair.0 as usize] + struts.radius[pair.1 as usize]);
            near.push(PairClearance { struts: pair, clearance });
        }
        near.iter().map(|p| p.clearance).reduce(f64::min)
    }

    /// Lists every non-adjacent pair within `reach` of axis distance at `x`, by the grid.
    fn build(&mut self, struts: &Struts, x: &[Vector3<f64>], reach: f64) {
        let Workspace { grid, boxes, candidates } = &mut self.ws;
        boxes.clear();
        let mut longest: f64 = 0.0;
        for k in 0..struts.len() as u32 {
            let s = struts.segment(k, x);
            longest = longest.max((s.q - s.p).norm());
            // Axes within `reach` have boxes grown by half of it that overlap.
            boxes.push(Aabb::around(&[s.p, s.q], 0.5 * reach));
        }
        self.margin = 2.0 * MARGIN * longest;
        grid.overlapping(boxes, struts.cell(x).max(reach), candidates);
        self.pairs.clear();
        self.distance.clear();
        for &(i, j) in candidates.iter() {
            if struts.adjacent(i, j) {
                continue;
            }
            let distance = struts.segment(i, x).closest(&struts.segment(j, x)).distance;
            if distance <= reach {
                self.pairs.push((i, j));
            }
        }
        self.pairs.sort_unstable();
        self.at.clear();
        self.at.extend_from_slice(x);
        self.reach = reach;
    }
}

/// The diagonal of the box around every strut at `x`: no two axes are further apart.
fn diagonal(struts: &Struts, x: &[Vector3<f64>]) -> f64 {
    let (lo, hi) = (0..struts.len() as u32).map(|k| struts.segment(k, x)).fold(
        (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), s| (lo.inf(&s.p).inf(&s.q), hi.sup(&s.p).sup(&s.q)),
    );
    (hi - lo).norm()
}

#[cfg(test)]
mod tests {
    use crate::model::clearance::{Event, Search, Struts, Tracker};
    use crate::model::generate::TowerSpec;
    use nalgebra::Vector3;
    use proptest::prelude::*;
    use std::sync::Arc;

    /// A step's events in a fixed order (the searches see pass-throughs in different
    /// orders).
    fn sorted(events: &[Event]) -> Vec<Event> {
        let mut e = events.to_vec();
        e.sort_by_key(|a| (a.kind as u8, a.members));
        e
    }

    proptest! {
        /// Random walks of a tower's nodes (steps up to `step` m per coordinate, every
        /// fifth a jump ten times as long, which outruns the list; radii large enough for
        /// pairs to touch and axes to pass through each other; 238 of 256 walks had events
        /// when this was written): at every step the listed grid search gives the nearest
        /// pair and the events that testing all pairs gives, bit for bit.
        #[test]
        fn the_list_finds_what_all_pairs_find(
            struts in 3usize..7,
            stages in 1usize..4,
            shifts in prop::collection::vec(-1.0f64..1.0, 30..90),
            step in 0.001f64..0.3,
            radius in 0.01f64..0.5,
        ) {
            let model = TowerSpec { struts, stages, ..TowerSpec::paper() }.build();
            let radii = vec![radius; model.members.len()];
            let mut all = Tracker::new(Arc::new(Struts::new(&model, &radii, Search::AllPairs)));
            let mut listed = Tracker::new(Arc::new(Struts::new(&model, &radii, Search::Grid)));
            let mut x = model.positions();
            for k in 0..40 {
                if k > 0 {
                    let jump = if k % 5 == 0 { 10.0 } else { 1.0 };
                    for (n, p) in x.iter_mut().enumerate() {
                        *p += Vector3::from_fn(|a, _| jump * step * shifts[(7 * k + 3 * n + a) % shifts.len()]);
                    }
                }
                let time = 0.1 * k as f64;
                prop_assert_eq!(listed.observe(&x, k, time), all.observe(&x, k, time));
                prop_assert_eq!(sorted(listed.events()), sorted(all.events()));
                all.clear_events();
                listed.clear_events();
            }
        }
    }
}
