//! Rank-one corrections of a held factorization (Sherman–Morrison–Woodbury) for the bar
//! elements whose tangent block changed since it was factored.
//!
//! Why: in a time step a tension-only cable going slack or taut takes its whole block out
//! of the step matrix or puts it back — with stiffness-proportional damping β c_v k several
//! times its EA/l — and the held factorization stops contracting the residual. Those are a
//! few elements among tens of thousands, each a change of rank one (its axial direction;
//! what else changes is smaller than the member's force over its stiffness). Solved as one
//! block, a correction's columns cost ~1/40 of a factorization each at 20k DOF and ~1/50
//! at 100k ([`MOST_NEW`]), so a switch of tens of elements is cheaper to correct than to
//! factor again (one solve at a time it would cost 1/7–1/9: why GMRES on the held factors
//! lost, bench/pipeline.md). Newton's contraction test still decides:
//! a corrected factorization that does not contract is replaced as before, so the converged
//! point meets the same tolerances either way.
//!
//! A = the matrix factored; an element e's block changed by Δk_e = Σ_j σ_j a_j b_jᵀ (its
//! SVD), which on its two nodes' DOFs is u vᵀ with u = σ_j [a_j; −a_j], v = [b_j; −b_j].
//! With U, V those columns and W = A⁻¹U: (A + U Vᵀ)⁻¹ r = x − W (I + Vᵀ W)⁻¹ Vᵀ x, x = A⁻¹ r.

use super::linear::{TangentSink, TangentSolver};
use nalgebra::Matrix3;

/// An element's block is taken as changed where it moved by more than this fraction of the
/// larger of its two values: a switch moves it by all of it, the geometry of one step by
/// a few per cent (which modified Newton absorbs).
const CHANGED: f64 = 0.5;
/// A correction is computed again where the element's change moved by more than this
/// fraction of itself since it was (a cable switched back, or taut at another rate).
const REFRESH: f64 = 0.25;
/// Singular values of a change below this fraction of its largest are left out: a
/// cable's sideways terms N/l are its strain (~1e-3) times its axial ones.
const RANK_CUT: f64 = 0.1;
/// Most new columns one correction may add. They are solved as one block, which reads the
/// factors once (examples/bench_factor.rs: 16 columns cost 2.5 single solves), a column
/// then costing ~1/40 of a factorization at 20k DOF and ~1/50 at 100k, so that 64 cost
/// about one. Measured (bench/pipeline.md), deployment time: a 47 × 47 grid's first 100
/// steps 16.9 s without corrections, 11.2 and 8.5 s with at most 32 and 64 new columns; a
/// 105 × 105 grid's first 10 steps 40.8 s without, 33.8, 32.5, 30.7 s with 16, 32, 64.
pub(super) const MOST_NEW: usize = 64;

/// Bar elements' 3×3 blocks k (their 6×6 block is [[k, −k], [−k, k]]) as one assembly of
/// the tangent gave them, summed over its calls, by element index, with their DOFs.
#[derive(Default)]
struct PairBlocks {
    blocks: Vec<Matrix3<f64>>,
    free: Vec<[Option<usize>; 6]>,
}

impl PairBlocks {
    fn clear(&mut self) {
        self.blocks.fill(Matrix3::zeros());
    }

    /// Room for `other`'s elements, so that recording them allocates nothing.
    fn size_as(&mut self, other: &PairBlocks) {
        self.blocks.resize(other.blocks.len(), Matrix3::zeros());
        self.free.resize(other.free.len(), [None; 6]);
    }

    fn block(&self, e: usize) -> Matrix3<f64> {
        self.blocks.get(e).copied().unwrap_or_else(Matrix3::zeros)
    }

    fn record(&mut self, e: usize, free: &[Option<usize>; 6], k: &[[f64; 3]; 3]) {
        if e >= self.blocks.len() {
            self.blocks.resize(e + 1, Matrix3::zeros());
            self.free.resize(e + 1, [None; 6]);
        }
        self.blocks[e] += Matrix3::from_fn(|r, c| k[r][c]);
        self.free[e] = *free;
    }
}

/// A sink that records the pair blocks it is given and forwards everything to `sink`
/// (`forward`), or nothing (asks it only which entries it holds).
struct Recording<'a, S: TangentSink + ?Sized> {
    sink: &'a mut S,
    forward: bool,
    blocks: &'a mut PairBlocks,
}

impl<S: TangentSink + ?Sized> TangentSink for Recording<'_, S> {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        if self.forward {
            self.sink.add(row, col, value);
        }
    }

    fn holds(&self, row: usize, col: usize) -> bool {
        self.sink.holds(row, col)
    }

    fn add_element(&mut self, e: usize, free: &[Option<usize>; 6], block: &[[f64; 6]; 6]) {
        if self.forward {
            self.sink.add_element(e, free, block);
        }
    }

    fn add_pair(&mut self, e: usize, free: &[Option<usize>; 6], k: &[[f64; 3]; 3]) {
        self.blocks.record(e, free, k);
        if self.forward {
            self.sink.add_pair(e, free, k);
        }
    }
}

/// One rank-one term u vᵀ of element `element`'s change `change`: u and v on the six
/// directions of its two nodes (`dofs`; `None`: fixed, left out).
#[derive(Clone, Copy)]
struct Term {
    element: usize,
    change: Matrix3<f64>,
    dofs: [Option<usize>; 6],
    u: [f64; 6],
    v: [f64; 6],
}

impl Term {
    fn entries(&self, of: &[f64; 6]) -> impl Iterator<Item = (usize, f64)> + '_ {
        let of = *of;
        self.dofs.iter().enumerate().filter_map(move |(r, d)| d.map(|i| (i, of[r])))
    }
}

/// The corrections a held factorization carries (see the module's doc). Its buffers are
/// sized when it is made and when it first records (W only as pages are written), so
/// that a Newton iteration allocates nothing (tests/allocation.rs).
pub(super) struct LowRank {
    n: usize,
    /// Most columns a held factorization carries: each costs every later solve n
    /// multiply-adds, where the solve itself costs about nnz(L); so at nnz(L)/n of them a
    /// solve costs twice what it did (and W takes as much memory as L).
    most_columns: usize,
    /// The pair blocks of the matrix factored.
    factored: PairBlocks,
    /// The pair blocks at the iterate of the last update (scratch).
    now: PairBlocks,
    terms: Vec<Term>,
    /// W = A⁻¹U, column j (n entries) for `terms[j]`.
    w: Vec<f64>,
    /// LU of I + Vᵀ W (s × s, row-major, s = `terms.len()`) and its row pivots.
    capacitance: Vec<f64>,
    pivots: Vec<usize>,
    /// Vᵀ x, then the capacitance solve's result (scratch).
    vx: Vec<f64>,
}

impl LowRank {
    /// For n × n matrices whose factor has `factor_nonzeros` entries.
    pub(super) fn new(n: usize, factor_nonzeros: usize) -> Self {
        let most_columns = (factor_nonzeros / n.max(1)).max(1);
        LowRank {
            n,
            most_columns,
            factored: PairBlocks::default(),
            now: PairBlocks::default(),
            terms: Vec::with_capacity(most_columns + MOST_NEW),
            w: vec![0.0; n * most_columns],
            capacitance: vec![0.0; most_columns * most_columns],
            pivots: vec![0; most_columns],
            vx: vec![0.0; most_columns],
        }
    }

    /// Assembles the tangent into `solver` (by `assemble`), recording its pair blocks as
    /// those of the factorization to come, which carries no correction yet.
    pub(super) fn assemble_factored<S: TangentSolver + ?Sized>(&mut self, solver: &mut S, assemble: impl FnOnce(&mut dyn TangentSink)) {
        self.factored.clear();
        assemble(&mut Recording {
            sink: solver,
            forward: true,
            blocks: &mut self.factored,
        });
        self.now.size_as(&self.factored);
        self.terms.clear();
    }

    /// Corrects the held factorization in `solver` for the elements whose blocks at the
    /// current iterate (`assemble` adds the tangent there) differ from the factored ones.
    /// `false` where that changes nothing, needs more than [`MOST_NEW`] new columns or
    /// more than `most_columns` in all, or makes a singular matrix: then the caller
    /// factors instead.
    pub(super) fn update<S: TangentSolver + ?Sized>(&mut self, solver: &mut S, assemble: impl FnOnce(&mut dyn TangentSink)) -> bool {
        self.now.clear();
        assemble(&mut Recording {
            sink: solver,
            forward: false,
            blocks: &mut self.now,
        });
        let before = self.terms.len();
        let kept = self.retain_current();
        for e in 0..self.now.blocks.len() {
            let Some(change) = self.change(e) else { continue };
            if self.terms[..kept].iter().any(|t| t.element == e) {
                continue;
            }
            if !push_rank_one_terms(&mut self.terms, e, change, &self.now.free[e]) || self.terms.len() > self.most_columns {
                return false;
            }
            if self.terms.len() - kept > MOST_NEW {
                return false;
            }
        }
        if self.terms.len() == kept && kept == before {
            return false;
        }
        let n = self.n;
        let fresh = &mut self.w[kept * n..self.terms.len() * n];
        fresh.fill(0.0);
        for (t, column) in self.terms[kept..].iter().zip(fresh.chunks_mut(n)) {
            t.entries(&t.u).for_each(|(i, x)| column[i] = x);
        }
        solver.solve_columns(fresh).is_ok() && self.factor_capacitance()
    }

    /// Element `e`'s change since the factorization where it counts as changed.
    fn change(&self, e: usize) -> Option<Matrix3<f64>> {
        let (a, b) = (self.factored.block(e), self.now.block(e));
        let change = b - a;
        (change.norm() > CHANGED * a.norm().max(b.norm())).then_some(change)
    }

    /// Keeps the terms whose element's change is still about the one they correct (their
    /// W columns moved up with them); returns how many.
    fn retain_current(&mut self) -> usize {
        let n = self.n;
        let mut kept = 0;
        for j in 0..self.terms.len() {
            let t = self.terms[j];
            if self.change(t.element).is_some_and(|c| (c - t.change).norm() <= REFRESH * c.norm()) {
                self.w.copy_within(j * n..(j + 1) * n, kept * n);
                self.terms[kept] = t;
                kept += 1;
            }
        }
        self.terms.truncate(kept);
        kept
    }

    /// LU (partial pivoting) of I + Vᵀ W in place; `false` where it is singular (the
    /// corrected matrix is).
    fn factor_capacitance(&mut self) -> bool {
        let (s, n) = (self.terms.len(), self.n);
        let c = &mut self.capacitance[..s * s];
        for (i, t) in self.terms.iter().enumerate() {
            for j in 0..s {
                let w = &self.w[j * n..(j + 1) * n];
                c[i * s + j] = t.entries(&t.v).map(|(k, x)| x * w[k]).sum::<f64>() + if i == j { 1.0 } else { 0.0 };
            }
        }
        lu_in_place(c, s, &mut self.pivots[..s])
    }

    /// Turns x = A⁻¹ r (in place) into (A + U Vᵀ)⁻¹ r.
    pub(super) fn correct(&mut self, x: &mut [f64]) {
        let (s, n) = (self.terms.len(), self.n);
        if s == 0 {
            return;
        }
        let z = &mut self.vx[..s];
        for (zi, t) in z.iter_mut().zip(&self.terms) {
            *zi = t.entries(&t.v).map(|(k, v)| v * x[k]).sum();
        }
        lu_solve(&self.capacitance[..s * s], s, &self.pivots[..s], z);
        for (zj, w) in z.iter().zip(self.w.chunks(n)) {
            x.iter_mut().zip(w).for_each(|(xi, wi)| *xi -= zj * wi);
        }
    }
}

/// Pushes element `e`'s change `change` on its DOFs `dofs` as rank-one terms
/// σ [a; −a] [b; −b]ᵀ, one per singular value above [`RANK_CUT`] of the largest; `false`
/// where the SVD failed.
fn push_rank_one_terms(terms: &mut Vec<Term>, e: usize, change: Matrix3<f64>, dofs: &[Option<usize>; 6]) -> bool {
    let svd = change.svd(true, true);
    let (Some(a), Some(bt)) = (svd.u, svd.v_t) else { return false };
    let largest = svd.singular_values.max();
    let spread = |x: [f64; 3]| -> [f64; 6] { std::array::from_fn(|r| if r < 3 { x[r] } else { -x[r - 3] }) };
    for j in (0..3).filter(|&j| svd.singular_values[j] > RANK_CUT * largest) {
        let sigma = svd.singular_values[j];
        terms.push(Term {
            element: e,
            change,
            dofs: *dofs,
            u: spread(std::array::from_fn(|r| sigma * a[(r, j)])),
            v: spread(std::array::from_fn(|r| bt[(j, r)])),
        });
    }
    true
}

/// LU with partial pivoting of the s × s row-major `a` in place (L unit lower, U upper),
/// row swaps in `pivots`; `false` at a zero pivot.
fn lu_in_place(a: &mut [f64], s: usize, pivots: &mut [usize]) -> bool {
    for k in 0..s {
        let p = (k..s)
            .max_by(|&i, &j| a[i * s + k].abs().total_cmp(&a[j * s + k].abs()))
            .unwrap_or(k);
        pivots[k] = p;
        if a[p * s + k] == 0.0 || !a[p * s + k].is_finite() {
            return false;
        }
        if p != k {
            for c in 0..s {
                a.swap(k * s + c, p * s + c);
            }
        }
        for i in k + 1..s {
            let f = a[i * s + k] / a[k * s + k];
            a[i * s + k] = f;
            for c in k + 1..s {
                a[i * s + c] -= f * a[k * s + c];
            }
        }
    }
    true
}

/// Solves with [`lu_in_place`]'s factors, `x` in place.
fn lu_solve(a: &[f64], s: usize, pivots: &[usize], x: &mut [f64]) {
    for k in 0..s {
        x.swap(k, pivots[k]);
        for i in k + 1..s {
            x[i] -= a[i * s + k] * x[k];
        }
    }
    for k in (0..s).rev() {
        x[k] /= a[k * s + k];
        for i in 0..k {
            x[i] -= a[i * s + k] * x[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{SparseSolver, Sparsity};

    /// Nodes 0…N−1 on a line, 3 DOFs each (node 0's fixed), bar elements between
    /// neighbours and between every other node.
    const NODES: usize = 16;

    fn elements() -> Vec<[usize; 2]> {
        (0..NODES - 1)
            .map(|a| [a, a + 1])
            .chain((0..NODES - 2).map(|a| [a, a + 2]))
            .collect()
    }

    fn free(node: usize) -> [Option<usize>; 3] {
        std::array::from_fn(|a| (node > 0).then(|| 3 * (node - 1) + a))
    }

    fn ends([a, b]: [usize; 2]) -> [Option<usize>; 6] {
        let (fa, fb) = (free(a), free(b));
        std::array::from_fn(|r| if r < 3 { fa[r] } else { fb[r - 3] })
    }

    /// A taut bar's block: EA/l along its direction, a fifth of it sideways (so that no
    /// singular value falls under the rank cut and the corrected matrix is the new one
    /// exactly).
    fn taut(e: usize) -> Matrix3<f64> {
        let t = e as f64;
        let dir = nalgebra::Vector3::new(1.0, 0.3 * t.sin(), 0.2 * t.cos()).normalize();
        let k = 1e3 * (1.0 + 0.1 * t);
        dir * dir.transpose() * (0.8 * k) + Matrix3::identity() * (0.2 * k)
    }

    /// The tangent: `blocks` on the elements and a mass-like diagonal (not a pair block).
    fn assemble(blocks: &[Matrix3<f64>], k: &mut dyn TangentSink) {
        for (e, nodes) in elements().into_iter().enumerate() {
            k.add_pair(
                e,
                &ends(nodes),
                &std::array::from_fn(|r| std::array::from_fn(|c| blocks[e][(r, c)])),
            );
        }
        for i in 0..3 * (NODES - 1) {
            k.add(i, i, 10.0);
        }
    }

    /// Corrections for these tests' small matrices: room for 128 columns, more than
    /// [`MOST_NEW`] (nnz(L)/n, the production cap, is a few here).
    fn low_rank() -> LowRank {
        LowRank::new(3 * (NODES - 1), 128 * 3 * (NODES - 1))
    }

    fn solver() -> SparseSolver {
        let entries = elements().into_iter().flat_map(|nodes| {
            let f: Vec<usize> = ends(nodes).into_iter().flatten().collect();
            f.iter().flat_map(|&r| f.iter().map(move |&c| (r, c))).collect::<Vec<_>>()
        });
        SparseSolver::new(3 * (NODES - 1), Sparsity::amd(entries))
    }

    fn rhs() -> Vec<f64> {
        (0..3 * (NODES - 1)).map(|i| (i as f64 * 0.7).sin() + 0.5).collect()
    }

    /// x = K(blocks)⁻¹ r by a factorization of its own (LU: `blocks` may be unsymmetric).
    fn exact(blocks: &[Matrix3<f64>]) -> Vec<f64> {
        let mut s = solver();
        assemble(blocks, &mut s);
        s.factor(false).unwrap();
        let mut x = rhs();
        s.solve(&mut x).unwrap();
        x
    }

    /// Held factors of K(`held`) corrected to K(`now`): x for [`rhs`], and whether the
    /// correction was made.
    fn corrected(held: &[Matrix3<f64>], now: &[Matrix3<f64>]) -> (Vec<f64>, bool) {
        let mut s = solver();
        let mut low_rank = low_rank();
        low_rank.assemble_factored(&mut s, |k| assemble(held, k));
        s.factor(true).unwrap();
        let made = low_rank.update(&mut s, |k| assemble(now, k));
        let mut x = rhs();
        s.solve(&mut x).unwrap();
        low_rank.correct(&mut x);
        (x, made)
    }

    fn gap(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
    }

    /// Round-off of solves with these well-conditioned matrices (diagonal 10 against
    /// blocks of ~1e3: condition ~1e3) is ~1e-13 relative (the corrected solve: 4e-15);
    /// 1e-10 leaves room for the Woodbury update's own. Uncorrected: 7e-2.
    const SOLVE_ROUNDOFF: f64 = 1e-10;

    #[test]
    fn a_corrected_solve_is_the_new_matrix_solve() {
        let held: Vec<Matrix3<f64>> = (0..elements().len())
            .map(|e| if e == 4 { Matrix3::zeros() } else { taut(e) })
            .collect();
        let mut now = held.clone();
        now[2] = Matrix3::zeros(); // went slack
        now[4] = taut(4); // snapped taut
        now[7] = Matrix3::new(900.0, 250.0, -80.0, -40.0, 700.0, 120.0, 60.0, -300.0, 800.0); // unsymmetric, rank 3
        let (x, made) = corrected(&held, &now);
        assert!(made);
        let g = gap(&x, &exact(&now));
        assert!(g <= SOLVE_ROUNDOFF, "corrected solve off by {g:e}");
        // Without the correction the held solve is far off: the test can tell.
        assert!(gap(&corrected(&held, &held).0, &exact(&now)) > 1e-3);
    }

    #[test]
    fn small_drifts_are_left_to_newton_and_many_switches_to_a_factorization() {
        let held: Vec<Matrix3<f64>> = (0..elements().len()).map(taut).collect();
        let drift: Vec<Matrix3<f64>> = held.iter().map(|k| k * 1.2).collect();
        assert!(!corrected(&held, &drift).1, "a 20 % drift is below the change threshold");
        let slack = vec![Matrix3::zeros(); held.len()];
        // Every element switched: 29 elements × 3 singular values > MOST_NEW.
        assert!(elements().len() * 3 > MOST_NEW);
        assert!(!corrected(&held, &slack).1);
    }

    #[test]
    fn a_switch_back_drops_its_correction() {
        let held: Vec<Matrix3<f64>> = (0..elements().len()).map(taut).collect();
        let mut slack = held.clone();
        slack[3] = Matrix3::zeros();
        let mut s = solver();
        let mut low_rank = low_rank();
        low_rank.assemble_factored(&mut s, |k| assemble(&held, k));
        s.factor(true).unwrap();
        assert!(low_rank.update(&mut s, |k| assemble(&slack, k)));
        assert_eq!(low_rank.terms.len(), 3);
        assert!(low_rank.update(&mut s, |k| assemble(&held, k)), "dropping the term is a change");
        assert!(low_rank.terms.is_empty());
        let mut x = rhs();
        s.solve(&mut x).unwrap();
        low_rank.correct(&mut x);
        assert!(gap(&x, &exact(&held)) <= SOLVE_ROUNDOFF);
    }
}
