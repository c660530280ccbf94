//! Clearance along a stage: the nearest pair at every step observed, and the events
//! between steps.
//!
//! - **touch**: a pair's clearance is ≤ 0 at a step and was not at the step before (or this
//!   is the first step observed): reported once when it begins, not at every step it lasts.
//! - **pass_through**: the orientation of two struts' axes (the sign of the triple product
//!   (p_b − p_a) · (u_a × u_b), the side of one axis the other is on) is +1 at one step
//!   and −1 at the next, and at the moment it is 0 (each end moving on a straight line
//!   between the steps; found by bisection) the axes meet inside both segments. Both
//!   steps may be clear: two struts can pass through each other within one step. A pair
//!   coplanar at either step (orientation 0, e.g. a flat folded state) has no side to swap
//!   from; if its axes cross there, it is a touch (a swap of sides *through* a coplanar
//!   state is therefore seen as that touch only). Two flips within one step, and parallel
//!   axes sliding through each other, are not seen: the check samples the steps it is given.

use super::bound::Bounds;
use super::neighbours::Neighbours;
use super::{Aabb, Nearest, PairClearance, Segment, Struts};
use nalgebra::Vector3;
use std::sync::Arc;

/// What happened between two struts (the module doc defines both).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventKind {
    /// Their clearance became ≤ 0.
    Touch,
    /// One axis crossed the other between two steps.
    PassThrough,
}

impl EventKind {
    /// `touch` or `pass_through`.
    pub fn as_str(self) -> &'static str {
        match self {
            EventKind::Touch => "touch",
            EventKind::PassThrough => "pass_through",
        }
    }
}

/// A touch or pass-through of two struts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Event {
    /// Touch or pass-through.
    pub kind: EventKind,
    /// Member indices, the lower first.
    pub members: [usize; 2],
    /// The step it is seen at: where a touch begins, the step after a crossing.
    pub step: usize,
    /// A touch: the step's time; a pass-through: the moment of crossing, interpolated
    /// between the two steps.
    pub time: f64,
    /// The pair's clearance at `step` [m].
    pub clearance: f64,
}

/// Follows one stage: give it every converged step in order ([`Tracker::observe`]).
pub struct Tracker {
    struts: Arc<Struts>,
    pairs: Pairs,
    near: Vec<PairClearance>,
    /// The previous step's positions (empty before the first) and time.
    previous: Vec<Vector3<f64>>,
    previous_time: f64,
    /// Pairs touching at the previous step and at this one, sorted by strut indices.
    touching: Vec<PairClearance>,
    touching_now: Vec<PairClearance>,
    /// Events since the last [`Tracker::clear_events`].
    events: Vec<Event>,
    /// Each strut's box swept between the previous step and this one (empty until a step
    /// needs them).
    boxes: Vec<Aabb>,
}

/// How a step finds the pairs it tests.
enum Pairs {
    /// All pairs, with clearance bounds that let a step skip most of them.
    All(Bounds),
    /// The grid's pairs, listed while the struts stay near.
    Listed(Box<Neighbours>),
}

/// Bisection steps for the moment of crossing: 2^-60 of a step is below f64 resolution.
const BISECTIONS: usize = 60;
/// The axes meet at the moment of crossing if their distance there is below this fraction
/// of their lengths: at the bisected root it is round-off (~1e-15 relative) when they
/// cross, and the gap beside an end (at least the strut radius to matter) when they do not.
const MEET: f64 = 1e-9;

impl Tracker {
    /// A tracker of `struts` that has observed no step yet.
    pub fn new(struts: Arc<Struts>) -> Self {
        // Room for every pair touching and crossing at once (all pairs), or eight per strut
        // (grid): a step then allocates only in an extreme case.
        let room = if struts.grid { 8 * struts.len() } else { struts.pairs.len() };
        Tracker {
            pairs: match struts.grid {
                true => Pairs::Listed(Box::default()),
                false => Pairs::All(Bounds::new(&struts)),
            },
            near: Vec::with_capacity(room),
            previous: Vec::new(),
            previous_time: 0.0,
            touching: Vec::with_capacity(room),
            touching_now: Vec::with_capacity(room),
            events: Vec::with_capacity(2 * room),
            boxes: Vec::with_capacity(struts.len()),
            struts,
        }
    }

    /// Observes the converged positions `x` of step `step` at `time`; returns the nearest
    /// pair (`None`: fewer than two non-adjacent struts) and adds the step's events.
    pub fn observe(&mut self, x: &[Vector3<f64>], step: usize, time: f64) -> Option<Nearest> {
        // The largest displacement of a strut's end since the previous step.
        let travel = match self.previous.is_empty() {
            true => 0.0,
            false => (self.struts.ends.iter().flatten())
                .map(|&n| (x[n] - self.previous[n]).norm())
                .fold(0.0, f64::max),
        };
        let nearest = match &mut self.pairs {
            Pairs::All(bounds) => bounds.nearest(&self.struts, x, &self.previous, &mut self.near),
            Pairs::Listed(list) => list.nearest(&self.struts, x, travel, &mut self.near),
        };
        self.touches(step, time);
        self.pass_throughs(x, step, time, travel);
        self.previous.clear();
        self.previous.extend_from_slice(x);
        self.previous_time = time;
        nearest
    }

    /// The events since the last [`Tracker::clear_events`], in the order seen.
    pub fn events(&self) -> &[Event] {
        &self.events
    }

    /// Forgets the events seen so far (the touching pairs and the last step are kept).
    pub fn clear_events(&mut self) {
        self.events.clear();
    }

    /// Touches that begin at this step (`near` holds every touching pair).
    fn touches(&mut self, step: usize, time: f64) {
        self.touching_now.clear();
        self.touching_now.extend(self.near.iter().filter(|p| p.clearance <= 0.0));
        self.touching_now.sort_unstable_by_key(|p| p.struts);
        for p in &self.touching_now {
            if self.touching.binary_search_by_key(&p.struts, |q| q.struts).is_err() {
                let members = self.struts.members_of(p.struts);
                self.events.push(Event {
                    kind: EventKind::Touch,
                    members,
                    step,
                    time,
                    clearance: p.clearance,
                });
            }
        }
        std::mem::swap(&mut self.touching, &mut self.touching_now);
    }

    /// Pairs whose axes crossed between the previous step and `x`, whose strut ends moved
    /// at most `travel` (none at the first step).
    fn pass_throughs(&mut self, x: &[Vector3<f64>], step: usize, time: f64, travel: f64) {
        let Tracker {
            struts,
            pairs,
            previous,
            previous_time,
            events,
            boxes,
            ..
        } = self;
        if previous.is_empty() {
            return;
        }
        // Axes that cross meet inside the boxes swept by both between the steps; built
        // at the step's first swap of sides (most steps have none).
        boxes.clear();
        let mut check = |pair: (u32, u32), was: i8, side: i8| {
            if was * side >= 0 {
                return;
            }
            if boxes.is_empty() {
                boxes.extend((0..struts.len() as u32).map(|k| {
                    let (a, b) = (struts.segment(k, previous), struts.segment(k, x));
                    Aabb::around(&[a.p, a.q, b.p, b.q], 0.0)
                }));
            }
            if !boxes[pair.0 as usize].overlaps(&boxes[pair.1 as usize]) {
                return;
            }
            let after = (struts.segment(pair.0, x), struts.segment(pair.1, x));
            let before = (struts.segment(pair.0, previous), struts.segment(pair.1, previous));
            if let Some(tau) = crossing(before, after) {
                events.push(Event {
                    kind: EventKind::PassThrough,
                    members: struts.members_of(pair),
                    step,
                    time: *previous_time + tau * (time - *previous_time),
                    clearance: struts.pair(pair, x).0,
                });
            }
        };
        let side = |pair: (u32, u32), at: &[Vector3<f64>]| struts.segment(pair.0, at).orientation(&struts.segment(pair.1, at));
        // A pair whose axes crossed is within twice the travel at the step's end.
        match pairs {
            // The clearance bounds rule out most pairs (a tower's struts lie metres apart).
            Pairs::All(bounds) => {
                for (k, &pair) in struts.pairs.iter().enumerate() {
                    if bounds.may_be_within(struts, k, 2.0 * travel) {
                        check(pair, side(pair, previous), side(pair, x));
                    }
                }
            }
            Pairs::Listed(list) => {
                for pair in list.within(2.0 * travel) {
                    check(pair, side(pair, previous), side(pair, x));
                }
            }
        }
    }
}

/// The fraction τ ∈ (0, 1) of the way from `before` to `after` (a pair of axes, each end
/// moving on a straight line) at which the axes are coplanar, if they meet there inside
/// both segments; `None` when the plane is reached beside an end (a near miss) or by
/// turning parallel. The triple product changes sign between the two; bisection finds
/// one of its (odd number of) roots.
fn crossing(before: (Segment, Segment), after: (Segment, Segment)) -> Option<f64> {
    let at = |tau: f64| (before.0.lerp(&after.0, tau), before.1.lerp(&after.1, tau));
    let positive = before.0.triple(&before.1) > 0.0;
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..BISECTIONS {
        let mid = 0.5 * (lo + hi);
        let (a, b) = at(mid);
        if (a.triple(&b) > 0.0) == positive {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let tau = 0.5 * (lo + hi);
    let (a, b) = at(tau);
    let length = (a.q - a.p).norm() + (b.q - b.p).norm();
    (a.closest(&b).distance <= MEET * length).then_some(tau)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::clearance::Search;
    use crate::model::{Member, MemberKind, Model, Node};

    /// Strut `a` on the x axis from −1 to 1; strut `b` parallel to y through (bx, 0, bz)
    /// from y = −1 to 1; radius 0.01 m each.
    fn two_struts(search: Search) -> Arc<Struts> {
        let node = |id: &str| Node {
            id: id.into(),
            xyz: Vector3::zeros(),
            support: [false; 3],
        };
        let strut = |id: &str, nodes| Member {
            id: id.into(),
            nodes,
            kind: MemberKind::Strut,
            groups: vec![],
        };
        let model = Model {
            nodes: vec![node("a0"), node("a1"), node("b0"), node("b1")],
            members: vec![strut("a", [0, 1]), strut("b", [2, 3])],
            node_groups: Default::default(),
            clusters: Vec::new(),
        };
        Arc::new(Struts::new(&model, &[0.01, 0.01], search))
    }

    fn at(bx: f64, by: f64, bz: f64) -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(bx, by - 1.0, bz),
            Vector3::new(bx, by + 1.0, bz),
        ]
    }

    /// The events of observing `steps` (positions) at times 0, 0.1, 0.2, ...
    fn events(steps: &[Vec<Vector3<f64>>], search: Search) -> Vec<Event> {
        let mut tracker = Tracker::new(two_struts(search));
        let mut all = Vec::new();
        for (k, x) in steps.iter().enumerate() {
            tracker.observe(x, k, 0.1 * k as f64);
            all.extend_from_slice(tracker.events());
            tracker.clear_events();
        }
        all
    }

    /// b crosses a from 0.5 m above to 0.5 m below within one step: clearance 0.48 m at
    /// both steps, no end within 0.9 m of the other strut; detected as one pass-through
    /// at the crossing's moment (halfway: 0.05 s) and the step after it.
    #[test]
    fn crossing_between_clear_steps_is_detected() {
        for search in [Search::AllPairs, Search::Grid] {
            let found = events(&[at(0.0, 0.0, 0.5), at(0.0, 0.0, -0.5)], search);
            assert_eq!(found.len(), 1, "{search:?}: {found:?}");
            let e = found[0];
            assert_eq!((e.kind, e.members, e.step), (EventKind::PassThrough, [0, 1], 1));
            // Bisection to 2^-60 of the step: the time to round-off.
            assert!((e.time - 0.05).abs() < 1e-12, "{}", e.time);
            assert!((e.clearance - 0.48).abs() < 1e-12);
        }
    }

    /// Moving apart (0.5 m → 1.5 m above), and sliding parallel side by side 0.5 m apart
    /// (b turned along x and moved along x past a): no event.
    #[test]
    fn moving_apart_or_parallel_is_no_event() {
        for search in [Search::AllPairs, Search::Grid] {
            assert!(events(&[at(0.0, 0.0, 0.5), at(0.0, 0.0, 1.5)], search).is_empty());
            let parallel = |dx: f64| {
                let mut x = at(0.0, 0.0, 0.5);
                (x[2], x[3]) = (Vector3::new(dx - 1.0, 0.0, 0.5), Vector3::new(dx + 1.0, 0.0, 0.5));
                x
            };
            assert!(events(&[parallel(-3.0), parallel(0.0), parallel(3.0)], search).is_empty());
        }
    }

    /// b passes from above to below a just beyond a's end (x = 1.05): the axes' plane
    /// flips, but they meet outside a, 0.05 m from its end (clearance 0.03 m): no event.
    #[test]
    fn near_miss_beside_an_end_is_no_event() {
        for search in [Search::AllPairs, Search::Grid] {
            let found = events(&[at(1.05, 0.0, 0.5), at(1.05, 0.0, -0.5)], search);
            assert!(found.is_empty(), "{search:?}: {found:?}");
        }
    }

    /// b lowered onto a: a touch when the clearance first reaches ≤ 0 (step 2), none while
    /// it stays, another after it has left and comes back (step 5).
    #[test]
    fn touch_is_reported_when_it_begins() {
        for search in [Search::AllPairs, Search::Grid] {
            let zs = [0.5, 0.1, 0.015, 0.012, 0.5, 0.019];
            let steps: Vec<_> = zs.iter().map(|&z| at(0.0, 0.0, z)).collect();
            let found = events(&steps, search);
            let touches: Vec<(usize, f64)> = found.iter().map(|e| (e.step, e.clearance)).collect();
            assert!(found.iter().all(|e| e.kind == EventKind::Touch));
            assert_eq!(touches.len(), 2, "{search:?}: {found:?}");
            assert_eq!((touches[0].0, touches[1].0), (2, 5));
            assert!((touches[0].1 + 0.005).abs() < 1e-12);
        }
    }
}
