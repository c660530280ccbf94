//! Contact: struts that cannot pass through each other or the ground.
//!
//! A strut is a capsule, its axis plus a radius (the section's, or one given for tubes and
//! joints); the ground a half-space, a plane and its outward normal, against which every
//! node not supported in all directions is a ball of its struts' largest radius (a capsule's point
//! nearest a plane is always an end, so this is the capsule against the plane). A gap g
//! is the distance between surfaces.
//!
//! The formulation is Incremental Potential Contact's (Li et al. 2020): every gap below
//! the activation distance ĝ adds the barrier b(g) ([`barrier`]) to the structure's
//! potential, so contact is one more element of the common scheme, with a force
//! (∂b/∂x = b′ ∇g, added to the internal force) and a tangent (b″ ∇g ∇gᵀ + b′ ∇²g, added
//! to K_T) in every stage, static or dynamic, and an energy in the ledger. Bodies stay
//! apart by construction, not by a stiffness guess: the barrier is infinite at g = 0, and
//! no Newton iterate may get there, each increment being cut to the fraction that keeps
//! every gap above [`KEEP`] of its value ([`ContactSet::admissible`], a conservative
//! advancement of the segments along the increment: a continuous collision check, so a
//! strut cannot jump through another within one increment either).

pub mod barrier;
pub mod discrete;
pub mod distance;

pub use barrier::{Barrier, BarrierValue};
pub use discrete::StepContact;
pub use distance::{Mat12, SegmentDistance, Vec12};

use crate::model::clearance::{Closest, PairClearance, Segment, Struts, Workspace};
use crate::model::Model;
use crate::solve::TangentSink;
use nalgebra::Vector3;
use std::sync::Arc;

/// The numbering of the free DOFs contact forces and tangents go to (the tsm's `DofMap`).
pub trait Dofs {
    /// The free DOF of node `n`'s axis `a`, if free.
    fn free(&self, n: usize, a: usize) -> Option<usize>;
    /// The node and axis of free DOF `i`.
    fn owner(&self, i: usize) -> (usize, usize);
}

/// No increment closes more than 1 − KEEP of a gap: the iterate stays clear of the
/// barrier's singularity, and Newton (whose increments shrink quadratically) is not slowed
/// near a solution. IPC's continuous collision check keeps a similar fraction.
pub const KEEP: f64 = 0.1;

/// The ground: a half-space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// A point of its surface [m].
    pub point: Vector3<f64>,
    /// Unit outward normal (into the space the structure is in).
    pub normal: Vector3<f64>,
}

/// What can touch: the struts as capsules and the ground, with the barrier between them.
#[derive(Clone, Debug)]
pub struct Contact {
    /// The struts with their contact radii (`None`: struts pass through each other).
    pub struts: Option<Arc<Struts>>,
    /// The ground (`None`: none).
    pub ground: Option<Ground>,
    /// Each node's radius against the ground [m] (its struts' largest; 0 for a node of
    /// cables only), and `None` for a node supported in every direction, which is attached
    /// to the ground (one held in some directions only still bears on it).
    pub node_radius: Vec<Option<f64>>,
    /// The barrier.
    pub barrier: Barrier,
}

/// The two things in contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Touch {
    /// Two struts, by member index (the lower first).
    Struts([usize; 2]),
    /// A node and the ground.
    Ground(usize),
}

/// One contact within the activation distance at the current positions.
#[derive(Clone, Copy, Debug)]
pub struct Active {
    /// What touches.
    pub touch: Touch,
    /// The gap between the surfaces [m] (> 0).
    pub gap: f64,
    /// The force pressing them apart, −b′(g) [N] (≥ 0).
    pub force: f64,
    /// Where: the midpoint of the axes' closest points, or the node's foot on the ground [m].
    pub point: Vector3<f64>,
    /// Unit normal along which the force acts on the second body (the first struts'
    /// member gets −force · normal; a node on the ground gets +force · normal).
    pub normal: Vector3<f64>,
    /// The nodes whose coordinates the gap depends on: a0, a1, b0, b1 of a strut pair
    /// (in the order of the struts' search), or the node four times for the ground.
    nodes: [usize; 4],
    barrier: BarrierValue,
    /// ∂g/∂x of the nodes (ground: the normal, then zeros).
    gradient: Vec12,
    /// A strut pair's closest points (for ∇²g); `None` for the ground, where g is linear.
    closest: Option<Closest>,
}

/// Where a contact is and how its gap moves with the nodes.
struct Geometry {
    nodes: [usize; 4],
    gradient: Vec12,
    closest: Option<Closest>,
    point: Vector3<f64>,
    normal: Vector3<f64>,
}

/// The contacts of a structure at its current positions, with the buffers the searches
/// reuse: what an [`Assembly`](crate::tsm::Assembly) carries to add contact to its forces,
/// tangent and energy.
#[derive(Clone, Debug)]
pub struct ContactSet {
    /// The geometry and barrier.
    pub contact: Arc<Contact>,
    /// Contacts within the activation distance at the last evaluation.
    pub active: Vec<Active>,
    /// Σ b over them [J] (∞ where some surfaces overlap).
    pub energy: f64,
    /// The most overlapping pair or node at the last evaluation (gap ≤ 0), which no
    /// admissible step reaches: a stage that starts from such a state reports it.
    pub overlap: Option<(Touch, f64)>,
    /// Verlet list: every non-adjacent strut pair within `reach` of clearance at `listed_at`.
    listed_at: Vec<Vector3<f64>>,
    listed: Vec<(u32, u32)>,
    reach: f64,
    ws: Workspace,
    near: Vec<PairClearance>,
    /// Node displacements of an increment ([`Self::admissible`]).
    dx: Vec<Vector3<f64>>,
    /// Positions an increment starts from, where not the evaluated ones
    /// ([`crate::tsm::Assembly::admissible_at`]).
    pub at: Vec<Vector3<f64>>,
}

impl Contact {
    /// Contact of `model`'s struts (capsules of radius `radius[m]` for member m; `None`:
    /// no strut contact) and of its unsupported nodes with `ground`, through `barrier`.
    pub fn new(model: &Model, struts: Option<Arc<Struts>>, radius: &[f64], ground: Option<Ground>, barrier: Barrier) -> Self {
        let mut node_radius: Vec<Option<f64>> = model.nodes.iter().map(|n| (!n.support.iter().all(|&s| s)).then_some(0.0)).collect();
        for (m, member) in model.members.iter().enumerate() {
            if member.kind == crate::model::MemberKind::Strut {
                for &n in &member.nodes {
                    if let Some(r) = &mut node_radius[n] {
                        *r = r.max(radius[m]);
                    }
                }
            }
        }
        Contact {
            struts,
            ground,
            node_radius,
            barrier,
        }
    }

    /// The gap of node `n` (radius `r`) above the ground at `x`.
    fn ground_gap(ground: &Ground, r: f64, x: Vector3<f64>) -> f64 {
        ground.normal.dot(&(x - ground.point)) - r
    }
}

impl ContactSet {
    /// The contacts of `contact`, not yet evaluated.
    pub fn new(contact: Arc<Contact>) -> Self {
        ContactSet {
            contact,
            active: Vec::new(),
            energy: 0.0,
            overlap: None,
            listed_at: Vec::new(),
            listed: Vec::new(),
            reach: 0.0,
            ws: Workspace::default(),
            near: Vec::new(),
            dx: Vec::new(),
            at: Vec::new(),
        }
    }

    /// Evaluates every contact at positions `x` and adds their forces b′ ∇g to the
    /// internal force `p` (3n, node-major).
    pub fn evaluate(&mut self, x: &[Vector3<f64>], p: &mut [f64]) {
        self.active.clear();
        self.energy = 0.0;
        self.overlap = None;
        let contact = Arc::clone(&self.contact);
        if let Some(struts) = &contact.struts {
            self.list(struts, x);
            for k in 0..self.listed.len() {
                let (i, j) = self.listed[k];
                self.strut_pair(struts, (i, j), x);
            }
        }
        if let Some(ground) = &contact.ground {
            for (n, r) in contact.node_radius.iter().enumerate() {
                let Some(r) = *r else { continue };
                let gap = Contact::ground_gap(ground, r, x[n]);
                let mut gradient = Vec12::zeros();
                gradient.fixed_rows_mut::<3>(0).copy_from(&ground.normal);
                let at = Geometry {
                    nodes: [n; 4],
                    gradient,
                    closest: None,
                    point: x[n] - ground.normal * (gap + r),
                    normal: ground.normal,
                };
                self.add(Touch::Ground(n), gap, at);
            }
        }
        for c in &self.active {
            let count = if c.closest.is_some() { 4 } else { 1 };
            for (k, &n) in c.nodes[..count].iter().enumerate() {
                for a in 0..3 {
                    p[3 * n + a] += c.barrier.slope * c.gradient[3 * k + a];
                }
            }
        }
    }

    /// Struts `(i, j)` at `x`: an active contact if within the activation distance.
    fn strut_pair(&mut self, struts: &Struts, (i, j): (u32, u32), x: &[Vector3<f64>]) {
        let sd = SegmentDistance::new(&struts.segment(i, x), &struts.segment(j, x));
        let c = sd.closest;
        let ([pa, qa], [pb, qb]) = (struts.ends(i), struts.ends(j));
        let (ma, mb) = (struts.member(i), struts.member(j));
        // Named by the lower member first, the normal pointing away from it.
        let normal = (c.on_b - c.on_a) / c.distance * if ma < mb { 1.0 } else { -1.0 };
        let contact = Geometry {
            nodes: [pa, qa, pb, qb],
            gradient: sd.gradient,
            closest: Some(c),
            point: 0.5 * (c.on_a + c.on_b),
            normal,
        };
        self.add(
            Touch::Struts([ma.min(mb), ma.max(mb)]),
            c.distance - struts.radius(i) - struts.radius(j),
            contact,
        );
    }

    /// Adds a contact at gap `gap` if active; a gap ≤ 0 is an overlap: infinite energy,
    /// and a NaN force on its nodes, so that no solve converges there (admissible iterates
    /// never get there; a state that starts so is refused by its stage).
    fn add(&mut self, touch: Touch, gap: f64, at: Geometry) {
        let Geometry {
            nodes,
            gradient,
            closest,
            point,
            normal,
        } = at;
        let barrier = if gap > 0.0 {
            match self.contact.barrier.at(gap) {
                Some(b) => b,
                None => return,
            }
        } else {
            if self.overlap.is_none_or(|(_, g)| gap < g) {
                self.overlap = Some((touch, gap));
            }
            BarrierValue {
                energy: f64::INFINITY,
                slope: f64::NAN,
                curvature: 0.0,
            }
        };
        self.energy += barrier.energy;
        self.active.push(Active {
            touch,
            gap,
            force: -barrier.slope,
            point,
            normal,
            nodes,
            barrier,
            gradient,
            closest,
        });
    }

    /// Keeps `listed` holding every pair within the activation distance at `x`: rebuilt
    /// (with a margin, `reach`) once some strut end moved far enough since the last build
    /// that an unlisted pair could have come within it.
    fn list(&mut self, struts: &Struts, x: &[Vector3<f64>]) {
        let activation = self.contact.barrier.distance;
        let moved = self.moved(x);
        // Two ends of a pair each moving `moved` change their gap by at most 2 `moved`.
        if activation + 2.0 * moved <= self.reach {
            return;
        }
        self.reach = 2.0 * activation + 2.0 * struts.max_radius();
        struts.near(x, self.reach, &mut self.ws, &mut self.near);
        self.listed.clear();
        self.listed.extend(self.near.iter().map(|p| p.struts));
        self.listed.sort_unstable();
        self.listed_at.clear();
        self.listed_at.extend_from_slice(x);
    }

    /// Adds `factor` × the contacts' tangent, b″ ∇g ∇gᵀ + b′ ∇²g at the last evaluation
    /// (positions `x`), on the free DOFs of `dofs`. Entries the sink does not hold (a
    /// sparse pattern made from the members, which couples no two struts' nodes) are left
    /// out: Newton then iterates on an approximate tangent, and converges to the same
    /// point (the residual is exact).
    pub fn add_tangent(&self, x: &[Vector3<f64>], dofs: &dyn Dofs, factor: f64, k: &mut (impl TangentSink + ?Sized)) {
        for c in &self.active {
            let (count, hessian) = match c.closest {
                Some(closest) => {
                    let seg = |a: usize, b: usize| Segment::new(x[c.nodes[a]], x[c.nodes[b]]);
                    let sd = SegmentDistance {
                        closest,
                        gradient: c.gradient,
                    };
                    (4, sd.hessian(&seg(0, 1), &seg(2, 3)) * c.barrier.slope)
                }
                None => (1, Mat12::zeros()),
            };
            let h = (c.gradient * c.gradient.transpose() * c.barrier.curvature + hessian) * factor;
            add_block(dofs, &c.nodes[..count], &h, k);
        }
    }

    /// The largest fraction τ ∈ (0, 1] of the increment `dx` (node displacements) from
    /// positions `x` along which every gap stays above [`KEEP`] of its value at `x`.
    pub fn admissible(&mut self, x: &[Vector3<f64>], dx: &[Vector3<f64>]) -> f64 {
        let contact = Arc::clone(&self.contact);
        let mut tau: f64 = 1.0;
        if let Some(ground) = &contact.ground {
            for (n, r) in contact.node_radius.iter().enumerate() {
                let Some(r) = *r else { continue };
                let approach = -ground.normal.dot(&dx[n]);
                let gap = Contact::ground_gap(ground, r, x[n]);
                if approach > 0.0 && gap > 0.0 {
                    tau = tau.min((1.0 - KEEP) * gap / approach);
                }
            }
        }
        if let Some(struts) = &contact.struts {
            let largest = dx.iter().map(|d| d.norm()).fold(0.0, f64::max);
            // Only a pair within 2 max|dx| / (1 − KEEP) can lose 1 − KEEP of its gap.
            let within = 2.0 * largest / (1.0 - KEEP);
            if within + 2.0 * self.moved(x) <= self.reach {
                // Every such pair is on the Verlet list: no search.
                for k in 0..self.listed.len() {
                    tau = tau.min(advance(struts, self.listed[k], x, dx));
                }
            } else {
                struts.near(x, within, &mut self.ws, &mut self.near);
                for p in &self.near {
                    tau = tau.min(advance(struts, p.struts, x, dx));
                }
            }
        }
        tau
    }

    /// How far a strut end has moved from where the Verlet list was made (∞ without a
    /// list): a pair not on it is at least `reach` − 2 × that apart.
    fn moved(&self, x: &[Vector3<f64>]) -> f64 {
        if self.listed_at.len() != x.len() {
            return f64::INFINITY;
        }
        x.iter().zip(&self.listed_at).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max)
    }

    /// [`Self::admissible`] for an increment of the free coordinates `d` scaled by `rate`.
    pub fn admissible_free(&mut self, x: &[Vector3<f64>], dofs: &dyn Dofs, d: &[f64], rate: f64) -> f64 {
        let mut dx = std::mem::take(&mut self.dx);
        dx.clear();
        dx.resize(x.len(), Vector3::zeros());
        for (i, di) in d.iter().enumerate() {
            let (n, a) = dofs.owner(i);
            dx[n][a] = rate * di;
        }
        let tau = self.admissible(x, &dx);
        self.dx = dx;
        tau
    }

    /// What overlaps at the last evaluation, in words with the remedy (`None`: nothing).
    pub fn overlap_text(&self, model: &Model) -> Option<String> {
        let (touch, gap) = self.overlap?;
        Some(match touch {
            Touch::Struts([a, b]) => format!(
                "struts `{}` and `{}` overlap by {:.3e} m at the stage's start: contact cannot begin from overlapping bodies; \
                 give them smaller capsules (`contact.radius`), or start from a shape where they are apart",
                model.members[a].id, model.members[b].id, -gap
            ),
            Touch::Ground(n) => format!(
                "node `{}` is {:.3e} m inside the ground at the stage's start (its struts' radius included): \
                 move `contact.ground.point` below the structure, or support the node",
                model.nodes[n].id, -gap
            ),
        })
    }

    /// The largest force of the active contacts [N] and b″ times the largest coordinate
    /// of their nodes plus that force: their share of the residual's scale and round-off.
    pub fn scale(&self, x: &[Vector3<f64>]) -> (f64, f64) {
        self.active.iter().fold((0.0_f64, 0.0_f64), |(f, s), c| {
            let reach = c.nodes.iter().map(|&n| x[n].amax()).fold(0.0, f64::max);
            (f.max(c.force), s.max(c.barrier.curvature * reach + c.force))
        })
    }

    /// The ground's force on the structure, summed [N].
    pub fn ground_force(&self) -> Vector3<f64> {
        self.active
            .iter()
            .filter(|c| matches!(c.touch, Touch::Ground(_)))
            .map(|c| c.normal * c.force)
            .sum()
    }
}

/// Adds the block `h` over the coordinates of `nodes` (3 per node, in order) on their free
/// DOFs, where the sink holds the entry (see [`ContactSet::add_tangent`]).
fn add_block(dofs: &dyn Dofs, nodes: &[usize], h: &Mat12, k: &mut (impl TangentSink + ?Sized)) {
    let free: [Option<usize>; 12] = std::array::from_fn(|r| nodes.get(r / 3).and_then(|&n| dofs.free(n, r % 3)));
    for (r, row) in free.iter().enumerate() {
        let Some(row) = *row else { continue };
        for (c, col) in free.iter().enumerate() {
            if let Some(col) = *col {
                if k.holds(row, col) {
                    k.add(row, col, h[(r, c)]);
                }
            }
        }
    }
}

/// Conservative advancement (Mirtich 1996) of strut pair `(i, j)` along `dx`: the gap's
/// rate is at most L = max over a's ends of |dx| + the same over b's (a point of an axis
/// moves by a convex combination of its ends' displacements), so the pair may advance by
/// (g(τ) − KEEP g(0))/L, and again from there, until that is within a thousandth of the
/// gap kept or τ reaches 1.
fn advance(struts: &Struts, (i, j): (u32, u32), x: &[Vector3<f64>], dx: &[Vector3<f64>]) -> f64 {
    let ([pa, qa], [pb, qb]) = (struts.ends(i), struts.ends(j));
    let rate = dx[pa].norm().max(dx[qa].norm()) + dx[pb].norm().max(dx[qb].norm());
    let radii = struts.radius(i) + struts.radius(j);
    let gap_at = |tau: f64| {
        let at = |n: usize| x[n] + dx[n] * tau;
        Segment::new(at(pa), at(qa)).closest(&Segment::new(at(pb), at(qb))).distance - radii
    };
    let g0 = gap_at(0.0);
    if rate == 0.0 || !(g0 > 0.0) {
        return 1.0;
    }
    let kept = KEEP * g0;
    let mut tau = 0.0;
    let mut g = g0;
    for _ in 0..ADVANCES {
        let step = (g - kept) / rate;
        if tau + step >= 1.0 {
            return 1.0;
        }
        tau += step;
        g = gap_at(tau);
        if g - kept <= 1e-3 * (g0 - kept) {
            break;
        }
    }
    tau
}

/// Conservative advancements per pair before the fraction reached is taken (it is safe at
/// any count; a pair sliding along another converges slowest).
const ADVANCES: usize = 64;

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::model::clearance::Search;
    use crate::model::{Member, MemberKind, Node};
    use nalgebra::Rotation3;

    /// Two skew struts within the activation distance, the upper one's axis off the lower
    /// one's middle, and node a0 within it of a tilted ground: (contact, positions).
    pub(super) fn crossing() -> (Arc<Contact>, Vec<Vector3<f64>>) {
        let node = |id: &str| Node {
            id: id.into(),
            xyz: Vector3::zeros(),
            support: [false; 3],
        };
        let strut = |id: &str, a, b| Member {
            id: id.into(),
            nodes: [a, b],
            kind: MemberKind::Strut,
            groups: vec![],
        };
        let model = Model {
            nodes: ["a0", "a1", "b0", "b1"].map(node).into(),
            members: vec![strut("a", 0, 1), strut("b", 2, 3)],
            node_groups: Default::default(),
            clusters: Vec::new(),
        };
        let r = 0.01;
        let struts = Arc::new(Struts::new(&model, &[r; 2], Search::AllPairs));
        let mut x = vec![
            Vector3::new(-1.0, 0.1, 0.05),
            Vector3::new(1.0, -0.1, -0.05),
            Vector3::new(0.3, -1.0, 2.0 * r),
            Vector3::new(-0.2, 1.0, 2.0 * r + 3e-4),
        ];
        // b lifted so that the surfaces are 5e-4 m apart, inside the 1e-3 m activation.
        let gap = Segment::new(x[0], x[1]).closest(&Segment::new(x[2], x[3])).distance - 2.0 * r;
        for p in &mut x[2..] {
            p.z += 5e-4 - gap;
        }
        // A tilted ground 5e-4 m below a0's surface (a0 a ball of radius r).
        let normal = Vector3::new(0.1, 0.0, 1.0).normalize();
        let ground = Ground {
            point: x[0] - normal * (r + 5e-4),
            normal,
        };
        let contact = Contact::new(&model, Some(struts), &[r; 2], Some(ground), Barrier::with_energy(1e-3, 1.0));
        (Arc::new(contact), x)
    }

    /// The forces of every contact and their energy at positions `x`.
    fn forces(contact: &Arc<Contact>, x: &[Vector3<f64>]) -> (Vec<Vector3<f64>>, f64, usize) {
        let mut set = ContactSet::new(Arc::clone(contact));
        let mut p = vec![0.0; 3 * x.len()];
        set.evaluate(x, &mut p);
        let f = (0..x.len()).map(|n| Vector3::new(p[3 * n], p[3 * n + 1], p[3 * n + 2])).collect();
        (f, set.energy, set.active.len())
    }

    /// A strut pair's contact forces are balanced and central (no net force or moment:
    /// a rigid motion of the pair is not resisted), and moving both struts rigidly
    /// (rotation and translation, the ground left out) keeps the gap's energy and rotates
    /// the forces with them: objective. 1e-12 relative: round-off of forces of order 1e3 N
    /// over coordinates of order 1.
    #[test]
    fn strut_contact_forces_are_balanced_and_objective() {
        let (contact, x) = crossing();
        let pair = Arc::new(Contact {
            ground: None,
            ..(*contact).clone()
        });
        let (f, energy, active) = forces(&pair, &x);
        assert_eq!(active, 1);
        let scale = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(scale > 0.0);
        let net: Vector3<f64> = f.iter().sum();
        let moment: Vector3<f64> = x.iter().zip(&f).map(|(x, f)| x.cross(f)).sum();
        assert!(net.norm() <= 1e-12 * scale && moment.norm() <= 1e-12 * scale, "{net:?} {moment:?}");
        let rotation = Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let shift = Vector3::new(2.0, -3.0, 0.5);
        let moved: Vec<Vector3<f64>> = x.iter().map(|p| rotation * p + shift).collect();
        let (g, moved_energy, _) = forces(&pair, &moved);
        assert!((moved_energy / energy - 1.0).abs() <= 1e-12, "{energy} {moved_energy}");
        for (a, b) in f.iter().zip(&g) {
            assert!((rotation * a - b).norm() <= 1e-12 * scale, "{a:?} {b:?}");
        }
    }

    /// The tangent the contacts add is the derivative of their force: against central
    /// differences of `evaluate` (step 1e-8 m, inside every gap's 1e-4 m; truncation
    /// ~h² b‴ ≈ 1e-16 · 1e12, round-off ~ε p / h ≈ 1e-5 of entries ~1e6 N/m: 1e-5 relative).
    #[test]
    fn the_contact_tangent_is_the_force_derivative() {
        let (contact, x) = crossing();
        let mut set = ContactSet::new(Arc::clone(&contact));
        let mut p = vec![0.0; 12];
        set.evaluate(&x, &mut p);
        assert_eq!(set.active.len(), 2, "a strut pair and the ground");
        let mut k = faer::Mat::<f64>::zeros(12, 12);
        set.add_tangent(&x, &AllFree, 1.0, &mut k);
        let h = 1e-8;
        let largest = (0..12)
            .flat_map(|i| (0..12).map(move |j| (i, j)))
            .map(|(i, j)| k[(i, j)].abs())
            .fold(0.0, f64::max);
        for j in 0..12 {
            let at = |s: f64| {
                let mut y = x.clone();
                y[j / 3][j % 3] += s;
                forces(&contact, &y).0
            };
            let (plus, minus) = (at(h), at(-h));
            for i in 0..12 {
                let fd = (plus[i / 3][i % 3] - minus[i / 3][i % 3]) / (2.0 * h);
                assert!((fd - k[(i, j)]).abs() <= 1e-5 * largest, "K[{i},{j}] {} vs {fd}", k[(i, j)]);
            }
        }
    }

    proptest::proptest! {
        /// Random walks of a tower's nodes (radii up to 0.5 m, so that pairs come within
        /// the list's reach; every fifth step ten times as long, which outruns the list),
        /// evaluated every fourth step (so that increments start away from where the list
        /// was kept), and increments of up to ten steps: the fraction an increment may take
        /// is the same, bit for bit, from the Verlet list as from a search.
        #[test]
        fn the_verlet_list_admits_what_a_search_admits(
            struts in 3usize..7,
            stages in 1usize..4,
            shifts in proptest::collection::vec(-1.0f64..1.0, 30..90),
            step in 0.001f64..0.3,
            radius in 0.01f64..0.5,
        ) {
            let model = crate::model::generate::TowerSpec { struts, stages, ..crate::model::generate::TowerSpec::paper() }.build();
            let radii = vec![radius; model.members.len()];
            let struts = Arc::new(Struts::new(&model, &radii, Search::Grid));
            let contact = Arc::new(Contact::new(&model, Some(struts), &radii, None, Barrier::with_energy(0.1 * radius, 1.0)));
            let mut listed = ContactSet::new(Arc::clone(&contact));
            let mut x = model.positions();
            let mut p = vec![0.0; 3 * x.len()];
            let walk = |k: usize, n: usize, scale: f64| Vector3::from_fn(|a, _| scale * shifts[(7 * k + 3 * n + a) % shifts.len()]);
            for k in 0..40 {
                let jump = if k % 5 == 0 { 10.0 } else { 1.0 };
                for (n, xn) in x.iter_mut().enumerate() {
                    *xn += walk(k, n, jump * step);
                }
                if k % 4 == 0 {
                    listed.evaluate(&x, &mut p);
                }
                let dx: Vec<Vector3<f64>> = (0..x.len()).map(|n| walk(k + 1, n, (k % 11) as f64 * step)).collect();
                let searched = ContactSet::new(Arc::clone(&contact)).admissible(&x, &dx);
                proptest::prop_assert_eq!(listed.admissible(&x, &dx), searched);
            }
        }
    }

    /// Every coordinate a free DOF, in order.
    pub(super) struct AllFree;

    impl Dofs for AllFree {
        fn free(&self, n: usize, a: usize) -> Option<usize> {
            Some(3 * n + a)
        }
        fn owner(&self, i: usize) -> (usize, usize) {
            (i / 3, i % 3)
        }
    }
}
