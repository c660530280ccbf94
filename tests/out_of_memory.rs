//! A sparse LU (or GMRES) that cannot allocate its memory says so: `LinearError::OutOfMemory`, a
//! Newton `SolveError::OutOfMemory` that a time step does not try to halve, and a case
//! error that tells the user to give the case memory — not "singular tangent" and a
//! string of cut steps, which is what a run under `ulimit -v` reported before.
//!
//! A fault-injecting global allocator (this test binary only) refuses the k-th allocation
//! of the current thread after it is armed; refusing each allocation of the LU's numeric
//! factorization in turn (its scratch and its factor's growth, where the memory goes: at
//! 1M DOF more than 20 GiB) covers every one of them. An allocation made infallibly would
//! abort this binary: a failing test. Not covered: the symbolic analysis before it, whose
//! column ordering (faer 0.24.4's COLAMD, sparse/linalg/colamd.rs:567-568) allocates two
//! O(n) vectors infallibly — a failure there aborts, as any `Vec`'s does; the analysis
//! needs O(nnz(A)), a fraction of what the solver already holds for Cholesky's factor.

use faer::sparse::linalg::lu::factorize_symbolic_lu;
use faer::sparse::SymbolicSparseColMatRef;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use tsim::config::parse_case;
use tsim::pipeline::run_case;
use tsim::record::{Constraints, Frame, RecordResult, Recorder, Stage};
use tsim::solve::{LinearError, LinearSolverChoice, SparseSolver, Sparsity, TangentSink, TangentSolver, KRYLOV_SOLVE, SPARSE_LU};

struct Refusing;

thread_local! {
    /// Allocations smaller than this [bytes] are neither counted nor refused.
    static SMALLEST: Cell<usize> = const { Cell::new(0) };
    /// Allocations still to pass before one is refused (`None`: disarmed); the refused
    /// one disarms, so the error's own allocations pass.
    static PASS: Cell<Option<u64>> = const { Cell::new(None) };
    /// Allocations of this thread.
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

/// The smallest allocation [bytes] refused in faer's supernodal LU. Its bookkeeping is
/// allocated infallibly (faer 0.24.4, sparse/linalg/lu.rs: the per-row and per-column
/// supernode lists grown by `push`, lines 969 and 1059, a few indices each; the copy of
/// the supernode partition, line 1321, 9.3 KB here), so a refusal there aborts; the
/// factor's values and indices, sized by its fill, are allocated fallibly, here in blocks
/// of 16 KiB to 6.4 MB.
/// They are where the memory goes (at 1M DOF over 20 GiB), so an allocation crossing a
/// limit is almost always one of them. Its simplicial LU makes every allocation fallibly.
const SUPERNODAL_SMALLEST: usize = 16 * 1024;

/// Whether an allocation of `size` bytes is to be refused (and counts it).
fn refuse(size: usize) -> bool {
    if size < SMALLEST.try_with(Cell::get).unwrap_or(usize::MAX) {
        return false;
    }
    // try_with: a thread's allocations during its TLS teardown pass.
    let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    PASS.try_with(|p| match p.get() {
        Some(0) => {
            p.set(None);
            true
        }
        Some(k) => {
            p.set(Some(k - 1));
            false
        }
        None => false,
    })
    .unwrap_or(false)
}

unsafe impl GlobalAlloc for Refusing {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if refuse(layout.size()) {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if refuse(layout.size()) {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if refuse(new_size) {
            return std::ptr::null_mut();
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Refusing = Refusing;

/// Refuses this thread's allocation after the next `pass` ones.
fn arm(pass: u64) {
    PASS.with(|p| p.set(Some(pass)));
}

fn disarm() {
    PASS.with(|p| p.set(None));
}

fn allocations() -> u64 {
    COUNT.with(Cell::get)
}

/// The m × m grid's neighbours of unknown i (left, right, below, above).
fn neighbours(m: usize, i: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % m, i / m);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < m).then(|| i + 1),
        (y > 0).then(|| i - m),
        (y + 1 < m).then(|| i + m),
    ]
    .into_iter()
    .flatten()
}

/// The grid operator's entry (i, j): a diagonally dominant Laplacian plus a skew part
/// along x (as a convection term) — unsymmetric, so not Cholesky's case. With `definite`
/// its symmetric part is positive definite (GMRES on that part's factor solves it),
/// without it the diagonal alternates in sign (the LU's case).
fn entry(definite: bool, i: usize, j: usize) -> f64 {
    match () {
        _ if i == j && (definite || i % 2 == 0) => 5.0,
        _ if i == j => -5.0,
        _ if j == i + 1 => -0.6,
        _ if j + 1 == i => -1.4,
        _ => -1.0,
    }
}

/// The grid operator's pattern, compressed by columns (rows sorted).
fn grid_pattern(m: usize) -> (Vec<usize>, Vec<usize>) {
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    for j in 0..m * m {
        let mut rows: Vec<usize> = std::iter::once(j).chain(neighbours(m, j)).collect();
        rows.sort_unstable();
        row_idx.extend(rows);
        col_ptr.push(row_idx.len());
    }
    (col_ptr, row_idx)
}

/// A sparse solver holding the m × m grid operator ([`entry`]), and its order.
fn unsymmetric_grid(m: usize, definite: bool) -> (SparseSolver, usize) {
    let n = m * m;
    let entries: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| std::iter::once(i).chain(neighbours(m, i)).map(move |j| (i, j)))
        .collect();
    let mut solver = SparseSolver::new(n, Sparsity::amd(entries));
    for i in 0..n {
        for j in std::iter::once(i).chain(neighbours(m, i)) {
            solver.add(i, j, entry(definite, i, j));
        }
    }
    (solver, n)
}

/// Whether `solver` solves the operator for a known x (x_i = i mod 7) as accurately as
/// its method promises: ‖x − x_exact‖₂ ≤ 2e-10 ‖b‖₂. The operator is diagonally dominant
/// by 1 in rows and columns (5 against 0.6 + 1.4 + 1 + 1), so ‖A⁻¹‖₂ ≤ 1 and the error is
/// at most the residual: GMRES's 1e-10 ‖b‖₂ (`KRYLOV_TOLERANCE`), LU's round-off; twice
/// that for the round-off of the residual's own recurrence.
fn solves(m: usize, definite: bool, solver: &mut SparseSolver) -> bool {
    let exact: Vec<f64> = (0..m * m).map(|i| (i % 7) as f64).collect();
    let b: Vec<f64> = (0..m * m)
        .map(|i| {
            std::iter::once(i)
                .chain(neighbours(m, i))
                .map(|j| entry(definite, i, j) * exact[j])
                .sum()
        })
        .collect();
    let mut x = b.clone();
    solver.solve(&mut x).unwrap();
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|e| e * e).sum::<f64>().sqrt();
    norm(&mut x.iter().zip(&exact).map(|(a, e)| a - e)) <= 2e-10 * norm(&mut b.iter().copied())
}

/// The allocations of the LU's symbolic analysis of the m × m grid's pattern, as the
/// solver makes it (faer's; its count depends on the pattern only), and whether it chose
/// the supernodal factorization.
fn symbolic_allocations(m: usize) -> (u64, bool) {
    let n = m * m;
    let (col_ptr, row_idx) = grid_pattern(m);
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let before = allocations();
    let symbolic = factorize_symbolic_lu(pattern, Default::default()).unwrap();
    let made = allocations() - before;
    // faer has no accessor for the kind; its Debug output names it.
    (made, format!("{symbolic:?}").contains("Supernodal"))
}

/// The allocations `factor(false)` makes on a fresh m × m operator, after one
/// factorization on this thread (the first LU on a thread also sets up the dense kernels'
/// thread-local workspace, private-gemm-x86's 4 MiB of pages, infallibly, once).
fn factor_allocations(m: usize, definite: bool) -> u64 {
    unsymmetric_grid(m, definite).0.factor(false).unwrap();
    let (mut fresh, _) = unsymmetric_grid(m, definite);
    let before = allocations();
    fresh.factor(false).unwrap();
    let made = allocations() - before;
    assert!(solves(m, definite, &mut fresh), "{m} × {m}");
    made
}

/// Every allocation of an unsymmetric matrix's solver set-up, refused in turn, gives
/// `OutOfMemory` naming the matrix's order and what needed the memory — and the solver
/// stays usable: factored again with memory, it solves to round-off. An operator whose
/// symmetric part is indefinite goes through GMRES's set-up (its basis, the symmetric
/// part: `KRYLOV_SOLVE`), Cholesky's failure, the LU's symbolic analysis (not refused: see
/// the module's note) and its numeric factorization (`SPARSE_LU`). A 6 × 6 grid takes
/// faer's simplicial LU (every allocation refused in turn), a 100 × 100 one its supernodal
/// LU (every one of [`SUPERNODAL_SMALLEST`] or more).
#[test]
fn each_allocation_the_solver_cannot_make_is_reported_as_out_of_memory() {
    for (m, supernodal, smallest) in [(6, false, 0), (100, true, SUPERNODAL_SMALLEST)] {
        SMALLEST.with(|s| s.set(smallest));
        // A definite symmetric part: GMRES's set-up is all that factor(false) allocates.
        let krylov = factor_allocations(m, true);
        let made = factor_allocations(m, false);
        let (symbolic, chosen) = symbolic_allocations(m);
        assert_eq!(chosen, supernodal, "{m} × {m}: the factorization to cover");
        assert!(krylov > 0 && made > krylov + symbolic, "{m} × {m}: {krylov}, {symbolic} of {made}");
        let n = m * m;
        for k in (0..krylov).chain(krylov + symbolic..made) {
            let (mut solver, _) = unsymmetric_grid(m, false);
            arm(k);
            let result = solver.factor(false);
            disarm();
            let what = if k < krylov { KRYLOV_SOLVE } else { SPARSE_LU };
            assert_eq!(
                result,
                Err(LinearError::OutOfMemory { dofs: n, what }),
                "{m} × {m}, allocation {k} of {made} refused"
            );
            solver.factor(false).unwrap();
            assert!(solves(m, false, &mut solver), "{m} × {m}, after refusing allocation {k}");
        }
        eprintln!(
            "{m} × {m}: each of the {krylov} allocations of GMRES's set-up and the {} of the numeric LU of at least {smallest} bytes \
             refused in turn (after {symbolic} symbolic ones)",
            made - krylov - symbolic
        );
    }
}

/// Arms the allocator at the deployment's second frame (after its first step, which fills
/// the solver's caches; later steps allocate nothing but the unsymmetric solve's set-up on
/// its first need: tests/allocation.rs): the next allocation of a page or more is refused.
struct ArmAfterFirstStep {
    deployment: bool,
    frames: usize,
}

impl Recorder for ArmAfterFirstStep {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &Constraints) -> RecordResult {
        self.deployment = stage.name() == "deployment";
        Ok(())
    }
    fn frame(&mut self, _frame: &Frame) -> RecordResult {
        if self.deployment {
            self.frames += 1;
            if self.frames == 2 {
                SMALLEST.with(|s| s.set(4096));
                arm(0);
            }
        }
        Ok(())
    }
}

/// The paper deployment on the sparse solver, the first allocation of its unsymmetric
/// solve's set-up refused (GMRES's basis): the case fails in that step with the memory
/// named and the remedy, not "singular tangent"; and not after cut steps, since a halved
/// step would have succeeded (the refusal is one-shot).
#[test]
fn a_deployment_out_of_memory_says_so_and_is_not_cut() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/configs/paper.yaml");
    let mut cfg = parse_case(&std::fs::read_to_string(path).unwrap(), path).unwrap();
    cfg.free_vibration = None;
    cfg.newton.linear_solver = LinearSolverChoice::Sparse;
    let mut recorder = ArmAfterFirstStep {
        deployment: false,
        frames: 0,
    };
    let result = run_case(&cfg, &mut recorder);
    disarm();
    let Err(error) = result else {
        panic!("the deployment ran through with its LU's memory refused")
    };
    let error = error.to_string();
    assert!(
        error.starts_with("deployment, step ")
            && error.contains("-DOF matrix could not allocate its memory")
            && error.contains("`--jobs`")
            && !error.contains("singular")
            && !error.contains("smaller"),
        "{error}"
    );
    eprintln!("{error}");
}
