//! Strut clearance: how close struts come to each other, pure geometry on a model's
//! members and a set of node positions (no mechanics).
//!
//! A strut is a solid round bar of radius r (A = π r², from its material's cross-section:
//! a tube of the same area would be wider, so this is the thinnest bar the area allows).
//! The *clearance* of two struts is the distance between their axes (segments) less
//! r_a + r_b: the gap between their surfaces, ≤ 0 when they touch or overlap. Only
//! non-adjacent pairs (no shared node) count: struts meeting at a node touch by design.
//!
//! Below [`GRID_FROM`] struts the searches test every non-adjacent pair; from there on a
//! uniform grid ([`grid`]) finds the candidate pairs in near-linear time.
//! [`Tracker`] follows a stage's steps and reports the events: a touch (clearance ≤ 0)
//! and a pass-through (one axis crossing the other between two steps).

mod bound;
mod grid;
mod neighbours;
mod segment;
mod track;

pub use grid::{overlapping_all, Aabb, Grid};
pub use segment::{Closest, Segment};
pub use track::{Event, EventKind, Tracker};

use super::{MemberKind, Model};
use nalgebra::Vector3;

/// From this many struts on, [`Search::Auto`] uses the grid (below, testing every pair is
/// about as fast and simpler; bench/clearance.md measures both).
pub const GRID_FROM: usize = 64;

/// How candidate pairs are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// All pairs below [`GRID_FROM`] struts, the grid from there on.
    Auto,
    /// Every non-adjacent pair, whatever the number of struts.
    AllPairs,
    /// The uniform grid, whatever the number of struts.
    Grid,
}

/// The struts of a model with their radii: what every clearance search works on.
#[derive(Clone, Debug)]
pub struct Struts {
    /// Member index of each strut.
    members: Vec<usize>,
    /// End nodes of each strut.
    ends: Vec<[usize; 2]>,
    /// Radius of each strut [m].
    radius: Vec<f64>,
    r_max: f64,
    /// Every non-adjacent pair (i < j, strut indices) when testing all pairs; empty with
    /// the grid.
    pairs: Vec<(u32, u32)>,
    grid: bool,
}

/// The clearance of one non-adjacent pair of struts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairClearance {
    /// Strut indices (into [`Struts`]), i < j.
    pub struts: (u32, u32),
    /// Surface gap [m]: axis distance − r_i − r_j.
    pub clearance: f64,
}

/// The closest non-adjacent pair of a configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Surface gap [m] (≤ 0: touching).
    pub clearance: f64,
    /// Member indices, the lower first.
    pub members: [usize; 2],
    /// The closest points of the two axes [m].
    pub points: [Vector3<f64>; 2],
    /// The larger radius of the two [m].
    pub radius: f64,
}

/// Buffers of a search, reused from call to call.
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    grid: Grid,
    boxes: Vec<Aabb>,
    candidates: Vec<(u32, u32)>,
}

impl Struts {
    /// The struts of `model` with `radius[m]` the radius of member m [m] (cables' entries
    /// are not read).
    pub fn new(model: &Model, radius: &[f64], search: Search) -> Self {
        let struts: Vec<usize> = (0..model.members.len())
            .filter(|&m| model.members[m].kind == MemberKind::Strut)
            .collect();
        let ends: Vec<[usize; 2]> = struts.iter().map(|&m| model.members[m].nodes).collect();
        let radius: Vec<f64> = struts.iter().map(|&m| radius[m]).collect();
        let grid = match search {
            Search::Auto => struts.len() >= GRID_FROM,
            Search::AllPairs => false,
            Search::Grid => true,
        };
        let mut this = Struts {
            members: struts,
            ends,
            r_max: radius.iter().copied().fold(0.0, f64::max),
            radius,
            pairs: Vec::new(),
            grid,
        };
        if !grid {
            let n = this.len() as u32;
            this.pairs = (0..n)
                .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                .filter(|&(i, j)| !this.adjacent(i, j))
                .collect();
        }
        this
    }

    /// Number of struts.
    pub fn len(&self) -> usize {
        self.members.len()
    }

    /// Whether the model has no strut.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// Whether struts `i` and `j` share a node.
    fn adjacent(&self, i: u32, j: u32) -> bool {
        let (a, b) = (self.ends[i as usize], self.ends[j as usize]);
        a.iter().any(|n| b.contains(n))
    }

    /// The axis of strut `k` at positions `x`.
    pub fn segment(&self, k: u32, x: &[Vector3<f64>]) -> Segment {
        let [p, q] = self.ends[k as usize];
        Segment::new(x[p], x[q])
    }

    /// Radius of strut `k` [m].
    pub fn radius(&self, k: u32) -> f64 {
        self.radius[k as usize]
    }

    /// End nodes of strut `k`.
    pub fn ends(&self, k: u32) -> [usize; 2] {
        self.ends[k as usize]
    }

    /// The largest radius [m].
    pub fn max_radius(&self) -> f64 {
        self.r_max
    }

    /// Member index of strut `k`.
    pub fn member(&self, k: u32) -> usize {
        self.members[k as usize]
    }

    /// Member indices of struts `pair`, the lower first.
    fn members_of(&self, (i, j): (u32, u32)) -> [usize; 2] {
        let (a, b) = (self.member(i), self.member(j));
        [a.min(b), a.max(b)]
    }

    /// Grid cell edge at positions `x`: the longest strut plus 2 r_max, so that a strut's
    /// box covers at most two cells along each axis.
    fn cell(&self, x: &[Vector3<f64>]) -> f64 {
        let longest = (0..self.len() as u32)
            .map(|k| {
                let s = self.segment(k, x);
                (s.q - s.p).norm()
            })
            .fold(0.0, f64::max);
        // A model of points only (every strut of zero length) still needs a cell.
        (longest + 2.0 * self.r_max).max(f64::MIN_POSITIVE)
    }

    /// The non-adjacent pairs whose `boxes` (one per strut) overlap, found by `grid` into
    /// `out`; with all pairs, every non-adjacent pair (the caller tests the boxes).
    fn candidates<'w>(&'w self, x: &[Vector3<f64>], boxes: &[Aabb], grid: &mut Grid, out: &'w mut Vec<(u32, u32)>) -> &'w [(u32, u32)] {
        if !self.grid {
            return &self.pairs;
        }
        grid.overlapping(boxes, self.cell(x), out);
        out.retain(|&(i, j)| !self.adjacent(i, j));
        out
    }

    /// The clearance of struts i, j at `x`, with their axes' closest points.
    fn pair(&self, (i, j): (u32, u32), x: &[Vector3<f64>]) -> (f64, segment::Closest) {
        let c = self.segment(i, x).closest(&self.segment(j, x));
        (c.distance - self.radius[i as usize] - self.radius[j as usize], c)
    }

    /// Every non-adjacent pair with clearance ≤ `d` [m] at positions `x`, into `out`
    /// (cleared first), in no particular order.
    pub fn near(&self, x: &[Vector3<f64>], d: f64, ws: &mut Workspace, out: &mut Vec<PairClearance>) {
        out.clear();
        if self.grid {
            // A pair within d has axes within d + r_i + r_j: its boxes grown by r + d/2 overlap.
            ws.boxes.clear();
            for k in 0..self.len() as u32 {
                let s = self.segment(k, x);
                ws.boxes.push(Aabb::around(&[s.p, s.q], self.radius[k as usize] + 0.5 * d));
            }
        }
        let Workspace { grid, boxes, candidates } = ws;
        for &pair in self.candidates(x, boxes, grid, candidates) {
            let clearance = self.pair(pair, x).0;
            if clearance <= d {
                out.push(PairClearance { struts: pair, clearance });
            }
        }
    }

    /// The closest non-adjacent pair at `x` (`None` without one); `near` is left holding
    /// every pair within some d ≥ 0 of it, touching pairs included. With the grid, d starts
    /// at 2 r_max and grows fourfold until a pair is found: a search over the whole model
    /// only when struts are far apart. (Along a stage's steps, `Tracker` keeps the pairs.)
    pub fn nearest(&self, x: &[Vector3<f64>], ws: &mut Workspace, near: &mut Vec<PairClearance>) -> Option<Nearest> {
        if self.grid {
            let (lo, hi) = (0..self.len() as u32).map(|k| self.segment(k, x)).fold(
                (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
                |(lo, hi), s| (lo.inf(&s.p).inf(&s.q), hi.sup(&s.p).sup(&s.q)),
            );
            let diagonal = (hi - lo).norm();
            let mut d = (2.0 * self.r_max).max(1e-6 * diagonal);
            loop {
                self.near(x, d, ws, near);
                // Beyond the diagonal every pair is within d: none found means none exist.
                if !near.is_empty() || d > diagonal || !diagonal.is_finite() {
                    break;
                }
                d *= 4.0;
            }
        } else {
            self.near(x, f64::INFINITY, ws, near);
        }
        Some(self.describe(best(near)?.struts, x))
    }

    /// Pair `(i, j)` at `x` as the nearest pair.
    fn describe(&self, (i, j): (u32, u32), x: &[Vector3<f64>]) -> Nearest {
        let (clearance, c) = self.pair((i, j), x);
        let (mi, mj) = (self.member(i), self.member(j));
        let (members, points) = if mi < mj {
            ([mi, mj], [c.on_a, c.on_b])
        } else {
            ([mj, mi], [c.on_b, c.on_a])
        };
        Nearest {
            clearance,
            members,
            points,
            radius: self.radius[i as usize].max(self.radius[j as usize]),
        }
    }
}

/// The pair of `near` with the smallest clearance. Ties (a symmetric tower) go to the
/// lowest pair, whatever order the search found them in.
fn best(near: &[PairClearance]) -> Option<&PairClearance> {
    near.iter()
        .min_by(|a, b| a.clearance.total_cmp(&b.clearance).then(a.struts.cmp(&b.struts)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::generate::TowerSpec;
    use proptest::prelude::*;

    /// A tower's struts at its nominal positions, each node moved by up to `jitter` [m]
    /// (seeded by `shifts`): random configurations with both near and far pairs.
    fn jittered(struts: usize, stages: usize, shifts: &[f64]) -> (Model, Vec<Vector3<f64>>) {
        let model = TowerSpec {
            struts,
            stages,
            ..TowerSpec::paper()
        }
        .build();
        let x = model
            .positions()
            .iter()
            .enumerate()
            .map(|(n, p)| p + Vector3::from_fn(|k, _| shifts[(3 * n + k) % shifts.len()]))
            .collect();
        (model, x)
    }

    proptest! {
        /// Random towers (up to 12 struts per stage, 6 stages, nodes shifted by up to 2 m,
        /// radii 0.01–0.5 m) and query distances: the grid finds exactly the pairs, with
        /// the same clearances, that testing all pairs finds, and the same nearest pair.
        #[test]
        fn grid_finds_what_all_pairs_finds(
            struts in 3usize..12,
            stages in 1usize..6,
            shifts in prop::collection::vec(-2.0f64..2.0, 1..50),
            radius in 0.01f64..0.5,
            d in 0.0f64..3.0,
        ) {
            let (model, x) = jittered(struts, stages, &shifts);
            let radii: Vec<f64> = (0..model.members.len()).map(|m| radius * (1.0 + (m % 3) as f64 * 0.5)).collect();
            let all = Struts::new(&model, &radii, Search::AllPairs);
            let grid = Struts::new(&model, &radii, Search::Grid);
            let mut ws = Workspace::default();
            let (mut want, mut got) = (Vec::new(), Vec::new());
            all.near(&x, d, &mut ws, &mut want);
            grid.near(&x, d, &mut ws, &mut got);
            got.sort_by_key(|p| p.struts);
            prop_assert_eq!(&got, &want);
            let a = all.nearest(&x, &mut ws, &mut want);
            let g = grid.nearest(&x, &mut ws, &mut got);
            prop_assert_eq!(a, g);
        }
    }

    /// The paper's tower: 10 struts, none sharing a node, so all 45 pairs count; the
    /// nearest pair's clearance is its axis distance less 2 r, checked against the
    /// closest points it reports.
    #[test]
    fn counts_non_adjacent_pairs_and_subtracts_radii() {
        let model = TowerSpec::paper().build();
        let r = (0.01 / std::f64::consts::PI).sqrt();
        let struts = Struts::new(&model, &vec![r; model.members.len()], Search::Auto);
        assert_eq!((struts.len(), struts.pairs.len()), (10, 45));
        let x = model.positions();
        let (mut ws, mut near) = (Workspace::default(), Vec::new());
        let nearest = struts.nearest(&x, &mut ws, &mut near).unwrap();
        assert_eq!(near.len(), 45);
        let axis = (nearest.points[1] - nearest.points[0]).norm();
        assert!((nearest.clearance - (axis - 2.0 * r)).abs() < 1e-12);
        assert!(near.iter().all(|p| p.clearance >= nearest.clearance));
    }

    /// Two struts sharing a node are never a pair; a third crossing them is.
    #[test]
    fn adjacent_struts_are_not_pairs() {
        let node = |id: &str, x: f64, y: f64, z: f64| crate::model::Node {
            id: id.into(),
            xyz: Vector3::new(x, y, z),
            support: [false; 3],
        };
        let strut = |id: &str, a, b| crate::model::Member {
            id: id.into(),
            nodes: [a, b],
            kind: MemberKind::Strut,
            groups: vec![],
        };
        let model = Model {
            nodes: vec![
                node("a", 0.0, 0.0, 0.0),
                node("b", 1.0, 0.0, 0.0),
                node("c", 1.0, 1.0, 0.0),
                node("d", 0.5, -1.0, 0.0),
                node("e", 0.5, 1.0, 0.0),
            ],
            members: vec![strut("ab", 0, 1), strut("bc", 1, 2), strut("de", 3, 4)],
            node_groups: Default::default(),
            clusters: Vec::new(),
        };
        for search in [Search::AllPairs, Search::Grid] {
            let struts = Struts::new(&model, &[0.01; 3], search);
            let (mut ws, mut near) = (Workspace::default(), Vec::new());
            struts.near(&model.positions(), 10.0, &mut ws, &mut near);
            near.sort_by_key(|p| p.struts);
            let pairs: Vec<(u32, u32)> = near.iter().map(|p| p.struts).collect();
            assert_eq!(pairs, [(0, 2), (1, 2)], "{search:?}");
            // de crosses ab at (0.5, 0, 0): clearance −2r.
            assert!((near[0].clearance + 0.02).abs() < 1e-15);
        }
    }
}
