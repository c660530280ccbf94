use super::friction::Friction;
use super::{assemble_tangent, DofMap, Elements, MemberState};
use crate::contact::{Contact, ContactSet};
use crate::model::Model;
use crate::solve::{Scale, TangentSink};
use nalgebra::Vector3;
use std::sync::Arc;

/// A structure evaluated at one configuration: positions of every node (supported and
/// prescribed ones hold their imposed values), member states and internal forces.
/// Stages update the free coordinates from a Newton iterate and read forces and tangents;
/// the buffers are reused across iterations and steps.
pub struct Assembly<'a> {
    /// Topology and supports.
    pub model: &'a Model,
    /// Each member's law (and own rest length, unless `rest` replaces it).
    pub elements: &'a Elements,
    /// Numbering of the free DOFs that Newton's iterate and tangent use.
    pub dofs: &'a DofMap,
    /// The rest length each member is evaluated with [m]: the elements' own, or those a
    /// stage sets as it changes them in time ([`Self::set_rest`]); over a clustered cable's
    /// members, shared out at `x` ([`super::cluster::distribute`]).
    pub rest: Vec<f64>,
    /// Positions of every node [m], global frame.
    pub x: Vec<Vector3<f64>>,
    /// Each member evaluated at `x` with `rest`.
    pub states: Vec<MemberState>,
    /// Internal (resisting) force over all 3n directions [N], flat 3n (node-major).
    pub p: Vec<f64>,
    /// Per node, its largest |coordinate|: what a length's round-off grows with ([`Self::scale`]).
    reach: Vec<f64>,
    /// Over the members and contacts: the largest |N|, and the largest |dN/dl|·(reach) + |N|
    /// ([`Self::scale`]).
    largest: (f64, f64),
    /// The contacts, where bodies may touch: their forces are in `p`, their tangent in
    /// [`Self::add_tangent`], their energy in [`Self::contact_energy`].
    pub contact: Option<ContactSet>,
    /// The clustered cables with friction: the rest lengths their pulleys hold from (those
    /// of the last [`Self::commit`]) and which pulleys slip at `x`.
    pub friction: Option<Friction>,
}

impl<'a> Assembly<'a> {
    /// The structure at positions `x` [m], every member at its elements' rest length.
    pub fn new(model: &'a Model, elements: &'a Elements, dofs: &'a DofMap, x: Vec<Vector3<f64>>) -> Self {
        Self::with_rest_lengths(model, elements, dofs, x, &elements.rest)
    }

    /// [`Self::new`] with the members' rest lengths `rest` in place of the elements' own
    /// (those a state carries after a stage changed them).
    pub fn with_rest_lengths(model: &'a Model, elements: &'a Elements, dofs: &'a DofMap, x: Vec<Vector3<f64>>, rest: &[f64]) -> Self {
        let friction = Friction::new(model, elements, &x, rest);
        let mut a = Assembly {
            model,
            elements,
            dofs,
            rest: rest.to_vec(),
            x,
            states: Vec::new(),
            p: vec![0.0; 3 * model.node_count()],
            reach: vec![0.0; model.node_count()],
            largest: (0.0, 0.0),
            contact: None,
            friction,
        };
        a.update();
        a
    }

    /// With `contact` between its bodies (`None`: none), evaluated at the current `x`.
    pub fn with_contact(mut self, contact: Option<&Arc<Contact>>) -> Self {
        self.contact = contact.map(|c| ContactSet::new(Arc::clone(c)));
        self.update();
        self
    }

    /// Sets the members' rest lengths (not re-evaluated: the next [`Self::set_free`] or
    /// [`Self::update`] does that).
    pub fn set_rest(&mut self, rest: &[f64]) {
        self.rest.copy_from_slice(rest);
    }

    /// ∂U/∂l0 of every member at the current `x` and rest lengths, into `out` [N]
    /// ([`crate::law::ForceLaw::d_energy_d_rest`]).
    pub fn energy_rest_derivatives(&self, out: &mut [f64]) {
        for (((q, s), law), &l0) in out.iter_mut().zip(&self.states).zip(&self.elements.laws).zip(&self.rest) {
            *q = law.d_energy_d_rest(s.length, l0);
        }
    }

    /// Re-evaluates member states, internal forces (over all 3n node directions, supported
    /// ones included: there it is the support reaction needed) and the members' share of
    /// [`Self::scale`] at the current `x`, in one pass over the members.
    pub fn update(&mut self) {
        for (r, x) in self.reach.iter_mut().zip(&self.x) {
            *r = x.amax();
        }
        self.p.fill(0.0);
        super::cluster::distribute(self.model, &self.x, &mut self.rest);
        if let Some(f) = &mut self.friction {
            f.slip(self.model, self.elements, &self.x, &mut self.rest);
        }
        let members = &self.model.members;
        self.states.resize(members.len(), MemberState::default());
        let (mut force, mut stiff) = (0.0_f64, 0.0_f64);
        let laws = self.elements.laws.iter().zip(&self.rest);
        for ((s, mem), (law, &l0)) in self.states.iter_mut().zip(members).zip(laws) {
            let [a, b] = mem.nodes;
            *s = MemberState::between(self.x[a], self.x[b], &**law, l0);
            let f = s.force * s.dir;
            for k in 0..3 {
                self.p[3 * a + k] -= f[k];
                self.p[3 * b + k] += f[k];
            }
            let reach = self.reach[a].max(self.reach[b]).max(s.length);
            force = force.max(s.force.abs());
            stiff = stiff.max(s.stiffness.abs() * reach + s.force.abs());
        }
        if let Some(c) = &mut self.contact {
            c.evaluate(&self.x, &mut self.p);
            let (f, s) = c.scale(&self.x);
            (force, stiff) = (force.max(f), stiff.max(s));
        }
        self.largest = (force, stiff);
    }

    /// Takes the current state as converged: the rest lengths cables with friction hold
    /// from in later evaluations. Stages call it once per converged step (a rejected trial
    /// leaves nothing behind). Returns the energy friction dissipated in the step
    /// ([`Friction::commit`]; 0 without) [J].
    pub fn commit(&mut self) -> f64 {
        match &mut self.friction {
            Some(f) => f.commit(self.model, self.elements, &self.x, &self.rest),
            None => 0.0,
        }
    }

    /// The rest lengths a stage's end state carries: the current ones where friction made
    /// them history, else `started` (those it began with, or changed by its own actuators).
    pub fn carried_rest(&self, started: Option<Vec<f64>>) -> Option<Vec<f64>> {
        match self.friction {
            Some(_) => Some(self.rest.clone()),
            None => started,
        }
    }

    /// Whether [`Self::add_tangent`] is symmetric: not where a pulley slips.
    pub fn symmetric_tangent(&self) -> bool {
        !self.friction.as_ref().is_some_and(Friction::slipping)
    }

    /// Writes the free coordinates `u` into `x` and re-evaluates.
    pub fn set_free(&mut self, u: &[f64]) {
        for (i, &v) in u.iter().enumerate() {
            let (n, a) = self.dofs.owner(i);
            self.x[n][a] = v;
        }
        self.update();
    }

    /// The contacts' barrier energy at the current `x` [J] (0 without contact; ∞ where
    /// bodies overlap).
    pub fn contact_energy(&self) -> f64 {
        self.contact.as_ref().map_or(0.0, |c| c.energy)
    }

    /// Strain energy of all members at the current `x` [J].
    pub fn strain_energy(&self) -> f64 {
        self.states
            .iter()
            .zip(&self.elements.laws)
            .zip(&self.rest)
            .map(|((s, law), &l0)| law.energy(s.length, l0))
            .sum()
    }

    /// Free coordinates of the current `x`.
    pub fn free_coordinates(&self) -> Vec<f64> {
        (0..self.dofs.len())
            .map(|i| {
                let (n, a) = self.dofs.owner(i);
                self.x[n][a]
            })
            .collect()
    }

    /// Adds `factor`·K_T on the free DOFs, the contacts' and slipping pulleys' included.
    pub fn add_tangent(&self, factor: f64, k: &mut (impl TangentSink + ?Sized)) {
        assemble_tangent(self.model, &self.states, self.dofs, factor, k);
        self.add_contact_tangent(factor, k);
        self.add_friction_tangent(factor, k);
    }

    /// Adds `factor` × what slipping pulleys add to the members' K_T (nothing without):
    /// for a stage that assembles the members' K_T its own way.
    pub fn add_friction_tangent(&self, factor: f64, k: &mut (impl TangentSink + ?Sized)) {
        if let Some(f) = &self.friction {
            f.add_tangent((self.model, self.elements, self.dofs), &self.x, &self.rest, &self.states, factor, k);
        }
    }

    /// Adds `factor` × the contacts' tangent on the free DOFs (none without contact): for
    /// a stage that assembles the members' K_T its own way (time steps, with damping).
    pub fn add_contact_tangent(&self, factor: f64, k: &mut (impl TangentSink + ?Sized)) {
        if let Some(c) = &self.contact {
            c.add_tangent(&self.x, self.dofs, factor, k);
        }
    }

    /// The largest fraction of the increment `d` of the free coordinates, moved at `rate`
    /// times it, that keeps every contact gap open ([`ContactSet::admissible`]); 1 without
    /// contact.
    pub fn admissible(&mut self, d: &[f64], rate: f64) -> f64 {
        match &mut self.contact {
            Some(c) => c.admissible_free(&self.x, self.dofs, d, rate),
            None => 1.0,
        }
    }

    /// [`Self::admissible`] from the positions whose free coordinates are `u` (the others
    /// as in `x`), at u's rate: a midpoint step's end.
    pub fn admissible_at(&mut self, u: &[f64], d: &[f64]) -> f64 {
        let Some(c) = &mut self.contact else { return 1.0 };
        let mut at = std::mem::take(&mut c.at);
        at.clone_from(&self.x);
        for (i, &ui) in u.iter().enumerate() {
            let (n, a) = self.dofs.owner(i);
            at[n][a] = ui;
        }
        let tau = c.admissible_free(&at, self.dofs, d, 1.0);
        c.at = at;
        tau
    }

    /// Internal force on free DOF `i`.
    pub fn p_free(&self, i: usize) -> f64 {
        let (n, a) = self.dofs.owner(i);
        self.p[3 * n + a]
    }

    /// Force level and round-off floor of the current state. The floor is what one ulp
    /// of a coordinate does through the stiffest member: a length is a difference of
    /// coordinates, so its round-off is ε·max(|x_i|, |x_j|, l), not ε·l (it grows with
    /// the distance from the origin, e.g. up a tall tower). 64 ε (|dN/dl|·that + |N|),
    /// 64 leaving room for the summation over a node's members.
    pub fn scale(&self, applied: f64) -> Scale {
        let (force, stiff) = self.largest;
        Scale {
            force: applied.max(force),
            roundoff: 64.0 * f64::EPSILON * stiff,
        }
    }

    /// Largest |internal force| on the free DOFs: the out-of-balance of a self-stressed
    /// structure with no load.
    pub fn max_free_residual(&self) -> f64 {
        (0..self.dofs.len()).map(|i| self.p_free(i).abs()).fold(0.0, f64::max)
    }
}
