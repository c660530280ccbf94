//! Sparse factorization benchmark (not a test): a matrix on the tangent pattern of an
//! n × n quadruplex grid (member blocks k e eᵀ plus a mass-like diagonal, so neither
//! factorization pivots), factored by tsim's `SparseSolver` with Cholesky and with LU.
//! Prints one JSON line per factorization kind: DOF, symbolic time, median factor and
//! solve times (one right-hand side, and 16 as one block: `solve_columns`), the
//! Cholesky factor's size (`SparseSolver::stats`), and the heap the first factorization of
//! each kind added while it ran (`factor_peak_bytes`: its storage and scratch at their
//! largest, counted by this program's allocator; for LU, the symbolic analysis on first
//! need included) and kept (`factor_kept_bytes`).
//!
//! Usage: bench_factor N [REPEATS] [--amd]  (`--amd`: faer's AMD ordering instead of
//! tsim's nested dissection)

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::Instant;
use tsim::model::grid::GridSpec;
use tsim::solve::{SparseSolver, TangentSink, TangentSolver};
use tsim::tsm::{add_member_block, tangent_sparsity, DofMap};

/// Live heap bytes and their largest value since the last [`Heap::reset_peak`].
struct Heap {
    live: AtomicUsize,
    peak: AtomicUsize,
}

impl Heap {
    fn grow(&self, bytes: usize) {
        let live = self.live.fetch_add(bytes, Relaxed) + bytes;
        self.peak.fetch_max(live, Relaxed);
    }
    fn live(&self) -> usize {
        self.live.load(Relaxed)
    }
    /// Resets the peak to the live bytes now; returns them.
    fn reset_peak(&self) -> usize {
        let live = self.live();
        self.peak.store(live, Relaxed);
        live
    }
}

unsafe impl GlobalAlloc for Heap {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.grow(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.grow(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        self.live.fetch_sub(layout.size(), Relaxed);
        self.grow(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        self.live.fetch_sub(layout.size(), Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static HEAP: Heap = Heap {
    live: AtomicUsize::new(0),
    peak: AtomicUsize::new(0),
};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .expect("usage: bench_factor N [REPEATS] [--amd]");
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let amd = args.iter().any(|a| a == "--amd");
    let spec = GridSpec {
        nx: n,
        ny: n,
        cell: 2.0,
        depth: 1.0,
        supports: Default::default(),
    };
    let model = spec.build();
    let dofs = DofMap::new(&model, &[]);
    let x = model.positions();
    let t = Instant::now();
    let mut sparsity = tangent_sparsity(&model, &dofs);
    if amd {
        sparsity.order = None;
    }
    let mut solver = SparseSolver::new(dofs.len(), sparsity);
    let symbolic = t.elapsed().as_secs_f64();
    let fill = |solver: &mut SparseSolver| {
        solver.clear();
        for (e, m) in model.members.iter().enumerate() {
            let d = (x[m.nodes[1]] - x[m.nodes[0]]).normalize();
            let k = d * d.transpose() * 1e6 + nalgebra::Matrix3::identity() * 1e3;
            add_member_block(&dofs, e, m.nodes, &k, solver);
        }
        for i in 0..dofs.len() {
            solver.add(i, i, 1e5);
        }
    };
    let mut rhs = vec![1.0; dofs.len()];
    for symmetric in [true, false] {
        let (mut factor, mut solve, mut solve16) = (Vec::new(), Vec::new(), Vec::new());
        let (mut peak, mut kept) = (0, 0);
        for repeat in 0..repeats {
            fill(&mut solver);
            let before = HEAP.reset_peak();
            let t = Instant::now();
            solver.factor(symmetric).expect("factorizable");
            factor.push(t.elapsed().as_secs_f64());
            if repeat == 0 {
                (peak, kept) = (HEAP.peak.load(Relaxed) - before, HEAP.live() - before);
            }
            rhs.fill(1.0);
            let t = Instant::now();
            solver.solve(&mut rhs).expect("solvable");
            solve.push(t.elapsed().as_secs_f64());
            let mut block = vec![1.0; dofs.len() * 16];
            let t = Instant::now();
            solver.solve_columns(&mut block).expect("solvable");
            solve16.push(t.elapsed().as_secs_f64());
        }
        let med = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        println!(
            "{{\"n\": {n}, \"dof\": {}, \"ordering\": \"{}\", \"kind\": \"{}\", \"symbolic_s\": {symbolic:.3}, \"factor_s\": {:.4}, \"solve_s\": {:.4}, \"solve_16_columns_s\": {:.4}, \"factor_peak_bytes\": {peak}, \"factor_kept_bytes\": {kept}, {}}}",
            dofs.len(),
            if amd { "amd" } else { "nested_dissection_or_amd" },
            if symmetric { "cholesky" } else { "lu" },
            med(&mut factor),
            med(&mut solve),
            med(&mut solve16),
            solver.stats()
        );
    }
}
