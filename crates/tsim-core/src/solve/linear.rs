//! The linear solves inside Newton: a dense Cholesky (LU fallback) for small models, a
//! sparse Cholesky (LU fallback) with its symbolic analysis done once for large ones. Both
//! factor in place into buffers allocated when the solver is built, so a Newton iteration
//! allocates nothing, and keep the factorization until the next one, so Newton may solve
//! with it again.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::linalg::cholesky::llt::factor::LltError;
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::cholesky::llt::{factor as llt_factor, solve as llt_solve};
use faer::linalg::lu::partial_pivoting::{factor as lu_factor, solve as lu_solve};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LdltRef, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::linalg::LuError;
use faer::sparse::{FaerError, SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};

use super::backoff::Backoff;
use super::krylov::{Gmres, KrylovEffort};
use super::low_rank::MOST_NEW;
use super::small_solve::{cholesky_in_place, cholesky_solve_in_place, SMALL_FACTOR, SMALL_SOLVE};

/// Why a factorization or solve failed.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum LinearError {
    /// The matrix is singular (or, for the sparse path, not factorizable) at free DOF
    /// `dof`, an index in the caller's numbering (the matrix's row/column). `ratio`: the
    /// pivot relative to the largest one, where the factorization measures it (dense LU).
    #[error("singular tangent at {}{}", dof_text(*.dof), ratio_text(*.ratio))]
    Singular {
        /// The free DOF (row) at which it failed, if the factorization names one.
        dof: Option<usize>,
        /// |pivot| / largest |pivot|, if measured.
        ratio: Option<f64>,
    },
    /// The sparse LU (the fallback for a matrix Cholesky and LDLᵀ cannot take) could not
    /// allocate its factor — its fill is decided while it factors, so no earlier step can
    /// reserve it — or GMRES its basis.
    #[error("{what} of the {dofs}-DOF matrix could not allocate its memory")]
    OutOfMemory {
        /// The matrix's order (free DOFs).
        dofs: usize,
        /// What needed the memory: [`SPARSE_LU`] or [`KRYLOV_SOLVE`].
        what: &'static str,
    },
}

/// [`LinearError::OutOfMemory`]'s `what` for the sparse LU.
pub const SPARSE_LU: &str = "the sparse LU factorization";
/// [`LinearError::OutOfMemory`]'s `what` for GMRES on the symmetric part's factor.
pub const KRYLOV_SOLVE: &str = "the GMRES solve (its basis and the symmetric part)";

/// "free DOF 3" for error messages (the caller that knows the model adds its name).
pub(super) fn dof_text(dof: Option<usize>) -> String {
    dof.map_or_else(|| "an unidentified free DOF".to_string(), |d| format!("free DOF {d}"))
}

/// " (pivot ratio 1.0e-16)", or nothing where no ratio was measured.
pub(super) fn ratio_text(ratio: Option<f64>) -> String {
    ratio.map_or_else(String::new, |r| format!(" (pivot ratio {r:.1e})"))
}

/// Receives matrix entries (row, column, value), added to what is there.
pub trait TangentSink {
    /// Adds `value` to entry (`row`, `col`), both free-DOF indices.
    fn add(&mut self, row: usize, col: usize, value: f64);

    /// Whether entry (`row`, `col`) can be added to: a sparse sink holds only its pattern's
    /// (the members'), which a contact between two struts' nodes may fall outside.
    fn holds(&self, _row: usize, _col: usize) -> bool {
        true
    }

    /// Adds a 6×6 element block on the DOFs `free` (`None`: not a free DOF). Element `e`
    /// must always come with the same DOFs, so a sink may cache where its entries go.
    fn add_element(&mut self, _e: usize, free: &[Option<usize>; 6], block: &[[f64; 6]; 6]) {
        for (r, row) in free.iter().enumerate() {
            let Some(row) = *row else { continue };
            for (c, col) in free.iter().enumerate() {
                if let Some(col) = *col {
                    self.add(row, col, block[r][c]);
                }
            }
        }
    }
    /// Adds a two-node element's 6×6 block [[k, −k], [−k, k]] on the DOFs `free` (as
    /// [`TangentSink::add_element`], `k` by rows): what a bar element gives. The default
    /// expands the block; a sink may add ±k without forming it.
    fn add_pair(&mut self, e: usize, free: &[Option<usize>; 6], k: &[[f64; 3]; 3]) {
        let block = std::array::from_fn(|r| std::array::from_fn(|c| if (r < 3) == (c < 3) { k[r % 3][c % 3] } else { -k[r % 3][c % 3] }));
        self.add_element(e, free, &block);
    }
}

/// Adds `by` times what it is given to `sink` (element blocks kept as blocks, so the
/// sink's caching of where they go still holds).
pub struct ScaledSink<'k> {
    /// Where the scaled entries go.
    pub sink: &'k mut dyn TangentSink,
    /// The factor.
    pub by: f64,
}

impl TangentSink for ScaledSink<'_> {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        self.sink.add(row, col, self.by * value);
    }

    fn holds(&self, row: usize, col: usize) -> bool {
        self.sink.holds(row, col)
    }

    fn add_element(&mut self, e: usize, free: &[Option<usize>; 6], block: &[[f64; 6]; 6]) {
        self.sink.add_element(e, free, &block.map(|row| row.map(|x| self.by * x)));
    }

    fn add_pair(&mut self, e: usize, free: &[Option<usize>; 6], k: &[[f64; 3]; 3]) {
        self.sink.add_pair(e, free, &k.map(|row| row.map(|x| self.by * x)));
    }
}

impl TangentSink for Mat<f64> {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        self[(row, col)] += value;
    }
}

/// A tangent matrix that is assembled, factored, then solved with as often as Newton likes.
pub trait TangentSolver: TangentSink + Send {
    /// Zeroes the matrix for the next assembly.
    fn clear(&mut self);
    /// Factors the assembled matrix, replacing the previous factorization; the assembled
    /// matrix is consumed (clear before the next assembly). A `symmetric` matrix is tried
    /// with Cholesky first (which reads one triangle only); any other goes to LU (the
    /// sparse solver: to GMRES on its symmetric part's Cholesky first).
    fn factor(&mut self, symmetric: bool) -> Result<(), LinearError>;
    /// Factors the assembled (symmetric) matrix by Cholesky only: `false` where it is not
    /// positive definite, and then nothing is factored and the assembled matrix is kept
    /// (entries may still be added, e.g. a diagonal shift, and the factorization retried).
    fn cholesky(&mut self) -> bool;
    /// Solves K x = rhs in place (rhs becomes x) with the last factorization.
    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError>;
    /// Factorizations solves made since the last call (a sparse solve whose GMRES did not
    /// converge factors the matrix by LU), for Newton to count.
    fn take_late_factorizations(&mut self) -> usize {
        0
    }
    /// The GMRES solves made so far and their iterations (none but for the sparse
    /// solver's unsymmetric matrices).
    fn krylov_effort(&self) -> KrylovEffort {
        KrylovEffort::default()
    }
    /// Solves for several right-hand sides at once, `rhs` holding them one after another
    /// (n entries each). A solver may solve them as a block, which reads its factors once.
    fn solve_columns(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        let n = self.size();
        rhs.chunks_mut(n).try_for_each(|column| self.solve(column))
    }
    /// The matrix's order.
    fn size(&self) -> usize;
}

/// Which factorization a solver holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Factored {
    None,
    Cholesky,
    /// Sparse LDLᵀ without pivoting (an indefinite symmetric matrix; [`LDLT_CHECK`]).
    Ldlt,
    /// Sparse Cholesky of an unsymmetric matrix's symmetric part, the matrix solved by
    /// GMRES with it ([`super::krylov`]), and by LU where that does not converge.
    SymmetricPart,
    Lu,
}

/// Relative pivot size below which a matrix is taken as singular: about 1e3 × machine ε,
/// far below any pivot of a stable structure (struts/cables stiffness ratio ~1e9 still
/// leaves pivots ~1e-9 relative).
const SINGULAR_PIVOT: f64 = 1e-13;

/// Dense solver: Cholesky first (the Newmark step matrix and a stable structure's K_T are
/// symmetric positive definite, and Cholesky costs half an LU; up to [`SMALL_FACTOR`]
/// rows factored and up to [`SMALL_SOLVE`] solved by the plain loops of `small_solve.rs`), partial-pivoting LU when
/// Cholesky fails (an indefinite static state). With row pivoting only, U's j-th pivot
/// belongs to column j, i.e. to free DOF j, which is what a singularity report names.
pub struct DenseSolver {
    n: usize,
    /// The assembled matrix in the leading n × n block of an (n + 1) × (n + 1) one: row and
    /// column n take the terms of fixed directions, so that an element adds its block
    /// without asking entry by entry which of its directions are free ([`Self::add_pair`]).
    k: Mat<f64>,
    /// Factor storage; `k` is kept for the LU fallback.
    work: Mat<f64>,
    /// 1 / L[j, j] of the Cholesky factor, for the small solves (empty above
    /// [`SMALL_SOLVE`] rows).
    inv_diag: Vec<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    mem: MemBuffer,
    factored: Factored,
}

impl DenseSolver {
    /// A solver for n × n matrices, its buffers allocated.
    pub fn new(n: usize) -> Self {
        let req = StackReq::any_of(&[
            llt_factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()),
            llt_solve::solve_in_place_scratch::<f64>(n, 1, Par::Seq),
            lu_factor::lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default()),
            lu_solve::solve_in_place_scratch::<usize, f64>(n, 1, Par::Seq),
        ]);
        DenseSolver {
            n,
            k: Mat::zeros(n + 1, n + 1),
            work: Mat::zeros(n, n),
            inv_diag: if n <= SMALL_SOLVE { vec![0.0; n] } else { Vec::new() },
            perm: vec![0; n],
            perm_inv: vec![0; n],
            mem: MemBuffer::new(req),
            factored: Factored::None,
        }
    }
}

impl TangentSink for DenseSolver {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        self.k[(row, col)] += value;
    }

    /// ±k straight into the matrix's columns, fixed directions into the spare row and
    /// column (each free entry receives the one addition it would from the expanded block,
    /// so the sum is the same to the last bit).
    fn add_pair(&mut self, _e: usize, free: &[Option<usize>; 6], k: &[[f64; 3]; 3]) {
        let (n, stride) = (self.n, self.k.col_stride() as usize);
        let at = free.map(|f| f.unwrap_or(n));
        let storage = self.k.as_mut();
        for (c, &col) in at.iter().enumerate() {
            // SAFETY: `col` ≤ n is a column of the (n + 1) × (n + 1) matrix, whose column
            // `col` is the n + 1 entries from col · stride of its storage.
            let column = unsafe { std::slice::from_raw_parts_mut(storage.as_ptr_mut().add(col * stride), n + 1) };
            for (r, &row) in at.iter().enumerate() {
                let value = k[r % 3][c % 3];
                if (r < 3) == (c < 3) {
                    column[row] += value;
                } else {
                    column[row] -= value;
                }
            }
        }
    }
}

impl TangentSolver for DenseSolver {
    fn clear(&mut self) {
        self.k.fill(0.0);
    }

    fn size(&self) -> usize {
        self.n
    }

    fn cholesky(&mut self) -> bool {
        // Column by column (contiguous slices: a memcpy each; faer's `copy_from` goes
        // entry by entry, a fifth of a 52 × 52 factorization's cost).
        let n = self.n;
        for j in 0..n {
            self.work.col_as_slice_mut(j).copy_from_slice(&self.k.col_as_slice(j)[..n]);
        }
        let llt = if n <= SMALL_FACTOR {
            cholesky_in_place(&mut self.work).map_err(|_| ())
        } else {
            llt_factor::cholesky_in_place(
                self.work.as_mut(),
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.mem),
                Default::default(),
            )
            .map(|_| ())
            .map_err(|_| ())
        };
        if llt.is_err() {
            self.factored = Factored::None;
            return false;
        }
        for (j, inv) in self.inv_diag.iter_mut().enumerate() {
            *inv = 1.0 / self.work[(j, j)];
        }
        self.factored = Factored::Cholesky;
        true
    }

    fn factor(&mut self, symmetric: bool) -> Result<(), LinearError> {
        let n = self.n;
        self.factored = Factored::None;
        if symmetric && self.cholesky() {
            return Ok(());
        }
        lu_factor::lu_in_place(
            self.k.as_mut().submatrix_mut(0, 0, n, n),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        // faer divides by an exactly zero pivot, so the pivots after it are NaN; their
        // ratios, +NaN after abs(), sort above every number, so the zero one is named.
        let max = (0..n).map(|j| self.k[(j, j)].abs()).fold(0.0, f64::max);
        if let Some((dof, ratio)) = (0..n)
            .map(|j| (j, self.k[(j, j)].abs() / max))
            .filter(|&(_, r)| r.is_nan() || r <= SINGULAR_PIVOT)
            .min_by(|a, b| a.1.total_cmp(&b.1))
        {
            return Err(LinearError::Singular {
                dof: Some(dof),
                ratio: Some(ratio),
            });
        }
        self.factored = Factored::Lu;
        Ok(())
    }

    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        let n = self.n;
        let stack = MemStack::new(&mut self.mem);
        match self.factored {
            Factored::Cholesky if !self.inv_diag.is_empty() => cholesky_solve_in_place(&self.work, &self.inv_diag, rhs),
            Factored::Cholesky => {
                let x = faer::ColMut::from_slice_mut(rhs).as_mat_mut();
                llt_solve::solve_in_place_with_conj(self.work.as_ref(), Conj::No, x, Par::Seq, stack)
            }
            Factored::Lu => {
                let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
                let x = faer::ColMut::from_slice_mut(rhs).as_mat_mut();
                let lu = self.k.as_ref().submatrix(0, 0, n, n);
                lu_solve::solve_in_place_with_conj(lu, lu, perm, Conj::No, x, Par::Seq, stack)
            }
            Factored::None | Factored::Ldlt | Factored::SymmetricPart => panic!("TangentSolver::solve before a successful factor()"),
        }
        Ok(())
    }
}

/// The shape of a sparse matrix before its values: every (row, column) that can receive an
/// entry (both triangles), and the order to eliminate its unknowns in.
pub struct Sparsity<P> {
    /// The (row, column) pairs that can be nonzero, both triangles; repeats allowed.
    pub entries: P,
    /// `order[k]`: the unknown eliminated k-th (a structure's: `tsm::tangent_sparsity`),
    /// used where its factor has fewer nonzeros than with faer's approximate minimum
    /// degree (AMD); `None`: AMD.
    pub order: Option<Vec<usize>>,
}

impl<P> Sparsity<P> {
    /// `entries`, ordered by AMD.
    pub fn amd(entries: P) -> Self {
        Sparsity { entries, order: None }
    }
}

/// Sparse Cholesky on a fixed pattern (the structure's connectivity): symbolic analysis
/// (the ordering of its [`Sparsity`], elimination tree) once, numeric factorization per iteration into
/// preallocated storage. The full symmetric pattern is stored; the Cholesky factorization
/// reads its lower triangle. The Newmark step matrix M/(βΔt²) + … + K_T is positive
/// definite unless the step is far too long, so the dynamic hot loop stays on Cholesky.
/// A symmetric matrix that is not positive definite (a static solve through an unstable
/// state, as in folding; a shift inside the spectrum) gets LDLᵀ on the same symbolic
/// factor where it passes [`LDLT_CHECK`], else a sparse LU, whose symbolic analysis is
/// likewise done once, on first need. An unsymmetric matrix (objective damping's step) is
/// solved by GMRES preconditioned with the Cholesky factor of its symmetric part, on the
/// same symbolic factor, and by LU where that part is not positive definite or GMRES does
/// not converge: the LU's fill is 8–12 times Cholesky's on a structure (bench/pipeline.md),
/// so a large model's deployment would otherwise not fit.
pub struct SparseSolver {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    mem: MemBuffer,
    lu: Option<(SymbolicLu<usize>, NumericLu<usize, f64>, MemBuffer)>,
    factored: Factored,
    /// The DOF at which the last Cholesky failed: the sparse LU names none, so an LU
    /// failure is reported there.
    failed_pivot: Option<usize>,
    /// Per element, the value slot of each of its 36 block entries (`u32::MAX`: not
    /// free), found once by binary search so that assembly is a direct scatter.
    slots: Vec<Option<[u32; 36]>>,
    /// The LDLᵀ check's vector ([`LDLT_CHECK`]).
    check: Vec<f64>,
    /// An unsymmetric matrix's symmetric part, each value slot's transposed slot, and the
    /// GMRES that solves the matrix with that part's factor ([`Factored::SymmetricPart`]);
    /// the first two empty until first needed.
    symmetric_part: Vec<f64>,
    transpose: Vec<u32>,
    gmres: Gmres,
    /// Whether an unsymmetric matrix is tried with GMRES on its symmetric part before LU
    /// (which costs 6–10 Cholesky factorizations and 8–12 times their memory on a
    /// structure: bench/pipeline.md).
    krylov_first: Backoff,
    /// LU factorizations made in a solve, where GMRES did not converge (see
    /// [`TangentSolver::take_late_factorizations`]).
    late_factorizations: usize,
    /// The GMRES work so far ([`TangentSolver::krylov_effort`]).
    krylov: KrylovEffort,
    /// Whether a symmetric matrix is tried with Cholesky before LDLᵀ.
    ///
    /// Why a back-off: a Cholesky that fails costs up to a whole factorization, and with a
    /// nested-dissection order the non-positive pivot tends to come late, in a separator.
    /// Folding pushes a grid through unstable states, where factorization after
    /// factorization is indefinite (a 75 × 75 grid: 349 LDLᵀ for 109 iterations), while a
    /// time step's matrix is positive definite throughout.
    cholesky_first: Backoff,
}

/// Largest error of the LDLᵀ check: solving A x = A·1 must give every x within this of 1,
/// or the matrix goes to LU.
///
/// Why: where Cholesky fails (an indefinite K_T: folding pushes a grid through unstable
/// states), LDLᵀ on the same symbolic factor costs about a Cholesky, a quarter of an LU
/// (105 × 105 grid: 0.44 s against 1.75 s), but without pivoting a small pivot may grow
/// the error unboundedly. The check costs one product and one solve. 1e-6: a
/// backward-stable solve of a stiffness matrix (condition up to ~1e9) errs by ~1e-7 here;
/// an error of 1e-6 in Newton's direction slows it at most to a 1e-6 contraction per
/// iteration, far inside the tenfold one it must keep (`REUSE_CONTRACTION`).
const LDLT_CHECK: f64 = 1e-6;

/// GMRES's relative residual for an unsymmetric matrix ([`Factored::SymmetricPart`]):
/// Newton's increment then errs by about this fraction, as a direct solve's round-off
/// does at a condition of 1e6, far inside the tenfold contraction Newton must keep.
const KRYLOV_TOLERANCE: f64 = 1e-10;

/// Most GMRES iterations before the matrix is factored by LU after all: each costs a
/// solve with the Cholesky factor (about a tenth of a factorization, bench/pipeline.md)
/// and a product with A, and the LU 6–10 factorizations.
pub const KRYLOV_ITERATIONS: usize = 40;

impl SparseSolver {
    /// A solver for n × n matrices of the shape `sparsity` gives; the symbolic analysis
    /// is done here, once.
    pub fn new<P: IntoIterator<Item = (usize, usize)>>(n: usize, sparsity: Sparsity<P>) -> Self {
        let (col_ptr, row_idx, symbolic) = analyse(n, sparsity);
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
            // Up to a low-rank correction's new columns at once (`solve_columns`).
            symbolic.solve_in_place_scratch::<f64>(MOST_NEW, Par::Seq),
        ]);
        let l_values = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; row_idx.len()];
        SparseSolver {
            col_ptr,
            row_idx,
            values,
            symbolic,
            l_values,
            mem: MemBuffer::new(req),
            lu: None,
            factored: Factored::None,
            failed_pivot: None,
            slots: Vec::new(),
            check: vec![0.0; n],
            symmetric_part: Vec::new(),
            transpose: Vec::new(),
            gmres: Gmres::default(),
            krylov_first: Backoff::default(),
            late_factorizations: 0,
            krylov: KrylovEffort::default(),
            cholesky_first: Backoff::default(),
        }
    }

    /// Nonzeros of the Cholesky factor a solver built on `sparsity` would hold
    /// ([`SparseSolver::factor_nonzeros`]), from the symbolic analysis alone: no storage
    /// for values (a memory estimate's).
    pub fn planned_factor_nonzeros<P: IntoIterator<Item = (usize, usize)>>(n: usize, sparsity: Sparsity<P>) -> usize {
        analyse(n, sparsity).2.len_val()
    }
}

/// Cholesky of the symmetric matrix with `values` on `pattern` (column pointers, row
/// indices; its lower triangle read) into `l_values`, on the symbolic factor `symbolic`.
fn numeric_llt(
    symbolic: &SymbolicCholesky<usize>,
    (col_ptr, row_idx): (&[usize], &[usize]),
    values: &[f64],
    l_values: &mut [f64],
    mem: &mut MemBuffer,
) -> Result<(), LltError> {
    let n = col_ptr.len() - 1;
    let a = SparseColMatRef::new(SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx), values);
    symbolic
        .factorize_numeric_llt(
            l_values,
            a,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(mem),
            Default::default(),
        )
        .map(|_| ())
}

/// The pattern of n × n matrices of the shape `sparsity` gives, compressed by columns (both
/// triangles and the diagonal, rows sorted), and its symbolic Cholesky factor.
fn analyse<P: IntoIterator<Item = (usize, usize)>>(
    n: usize,
    Sparsity { entries, order }: Sparsity<P>,
) -> (Vec<usize>, Vec<usize>, SymbolicCholesky<usize>) {
    let mut cols: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (r, c) in entries {
        cols[c].push(r);
    }
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for (c, mut rows) in cols.into_iter().enumerate() {
        rows.push(c);
        rows.sort_unstable();
        rows.dedup();
        row_idx.extend(rows);
        col_ptr.push(row_idx.len());
    }
    let structure = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let analyse = |ordering| {
        factorize_symbolic_cholesky(structure, Side::Lower, ordering, Default::default()).expect("symbolic Cholesky of a valid pattern")
    };
    let amd = analyse(SymmetricOrdering::Amd);
    // The given order where its factor is smaller than AMD's (a dissection wins on a
    // plate, AMD on a long, thin tower: see `ordering.rs`).
    let symbolic = match order {
        Some(fwd) => {
            let mut inv = vec![0; n];
            for (new, &old) in fwd.iter().enumerate() {
                inv[old] = new;
            }
            let given = analyse(SymmetricOrdering::Custom(PermRef::new_checked(&fwd, &inv, n)));
            if given.len_val() < amd.len_val() {
                given
            } else {
                amd
            }
        }
        None => amd,
    };
    (col_ptr, row_idx, symbolic)
}

impl SparseSolver {
    /// Nonzeros of the Cholesky factor the symbolic analysis chose.
    pub fn factor_nonzeros(&self) -> usize {
        self.symbolic.len_val()
    }

    /// The symbolic Cholesky's figures as JSON fields (for benchmarks): nnz(L) and, for a
    /// supernodal factor, its supernodes' widths and the flops of one numeric factorization
    /// (per supernode of width w with r rows below: w³/3 + r w² + r² w).
    pub fn stats(&self) -> String {
        let nnz_l = self.factor_nonzeros();
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(_) => format!("\"nnz_l\": {nnz_l}, \"supernodal\": false"),
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (b, e, p) = (s.supernode_begin(), s.supernode_end(), s.col_ptr_for_row_idx());
                let mut flops = 0.0;
                let mut widths = Vec::new();
                for k in 0..s.n_supernodes() {
                    let w = (e[k] - b[k]) as f64;
                    let r = (p[k + 1] - p[k]) as f64;
                    widths.push(w as usize);
                    flops += w * w * w / 3.0 + r * w * w + r * r * w;
                }
                widths.sort_unstable();
                let mean = widths.iter().sum::<usize>() as f64 / widths.len() as f64;
                format!(
                    "\"nnz_l\": {nnz_l}, \"supernodes\": {}, \"mean_width\": {mean:.1}, \"median_width\": {}, \"max_width\": {}, \"flops\": {flops:.3e}",
                    widths.len(),
                    widths[widths.len() / 2],
                    widths.last().copied().unwrap_or(0)
                )
            }
        }
    }
}

impl SparseSolver {
    fn slot(&self, row: usize, col: usize) -> usize {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        lo + self.row_idx[lo..hi].binary_search(&row).expect("entry inside the tangent pattern")
    }

    /// The free DOF (caller's numbering) of the pivot at which the Cholesky failed.
    fn pivot_dof(&self, error: LltError) -> usize {
        // `factorize_numeric_llt` returns the dense factorization's error as is, not the
        // `sparse::linalg::LltError` wrapper of the high-level API.
        let LltError::NonPositivePivot { index } = error;
        // faer 0.24.4 counts the failed pivot from 1 in the simplicial factorization
        // (sparse/linalg/cholesky.rs:1002, `index: *k + 1`) and from 0 in the supernodal one
        // (cholesky.rs:3256, `index + s_start` over the dense 0-based index); the tests
        // `sparse_*_names_the_zero_dof` pin both.
        let permuted = match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(_) => index - 1,
            SymbolicCholeskyRaw::Supernodal(_) => index,
        };
        // The factored matrix is P A Pᵀ with new index perm_inv[old]
        // (sparse/utils.rs:225), so the old index is perm_fwd[new].
        self.symbolic.perm().map_or(permuted, |p| p.arrays().0[permuted])
    }
}

impl TangentSink for SparseSolver {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        let k = self.slot(row, col);
        self.values[k] += value;
    }

    fn holds(&self, row: usize, col: usize) -> bool {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        self.row_idx[lo..hi].binary_search(&row).is_ok()
    }

    fn add_element(&mut self, e: usize, free: &[Option<usize>; 6], block: &[[f64; 6]; 6]) {
        if e >= self.slots.len() {
            self.slots.resize(e + 1, None);
        }
        let slots = match self.slots[e] {
            Some(slots) => slots,
            None => {
                let slots = std::array::from_fn(|k| match (free[k / 6], free[k % 6]) {
                    (Some(row), Some(col)) => self.slot(row, col) as u32,
                    _ => u32::MAX,
                });
                self.slots[e] = Some(slots);
                slots
            }
        };
        for (k, &slot) in slots.iter().enumerate() {
            if slot != u32::MAX {
                self.values[slot as usize] += block[k / 6][k % 6];
            }
        }
    }
}

impl SparseSolver {
    /// Sparse LU of the assembled matrix (its symbolic analysis on first need); a failure
    /// is reported at the DOF of the last failed Cholesky pivot, as the LU names none.
    fn lu_factor(&mut self) -> Result<(), LinearError> {
        let n = self.col_ptr.len() - 1;
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(structure, &self.values);
        let singular = LinearError::Singular {
            dof: self.failed_pivot,
            ratio: None,
        };
        let out_of_memory = LinearError::OutOfMemory { dofs: n, what: SPARSE_LU };
        if self.lu.is_none() {
            let symbolic = factorize_symbolic_lu(structure, Default::default()).map_err(|e| match e {
                FaerError::OutOfMemory => out_of_memory.clone(),
                e => panic!("symbolic LU of a valid pattern: {e:?}"),
            })?;
            let req = StackReq::any_of(&[
                symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
                symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            ]);
            let mem = MemBuffer::try_new(req).map_err(|_| out_of_memory.clone())?;
            self.lu = Some((symbolic, NumericLu::new(), mem));
        }
        let (symbolic, numeric, mem) = self.lu.as_mut().expect("set up above");
        let result = symbolic
            .factorize_numeric_lu(numeric, a, Par::Seq, MemStack::new(mem), Default::default())
            .map(|_| ());
        if result.is_err() {
            // A factorization cut short leaves faer's storage inconsistent (the next one
            // panics on it): start the next from empty storage.
            *numeric = NumericLu::new();
        }
        result.map_err(|e| match e {
            LuError::Generic(FaerError::OutOfMemory) => out_of_memory,
            _ => singular,
        })?;
        self.factored = Factored::Lu;
        Ok(())
    }

    /// Cholesky of the assembled unsymmetric matrix's symmetric part ½(A + Aᵀ) (A kept for
    /// GMRES's products; the transpose map and the part's storage made on first need):
    /// `Ok(false)` where that part is not positive definite.
    fn symmetric_part_cholesky(&mut self) -> Result<bool, LinearError> {
        let n = self.col_ptr.len() - 1;
        if self.transpose.is_empty() {
            let out_of_memory = |_| LinearError::OutOfMemory {
                dofs: n,
                what: KRYLOV_SOLVE,
            };
            self.gmres.reserve(n, KRYLOV_ITERATIONS).map_err(out_of_memory)?;
            let mut transpose = Vec::new();
            transpose.try_reserve_exact(self.row_idx.len()).map_err(out_of_memory)?;
            for c in 0..n {
                for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                    transpose.push(self.slot(c, self.row_idx[k]) as u32);
                }
            }
            self.symmetric_part.try_reserve_exact(self.values.len()).map_err(out_of_memory)?;
            self.symmetric_part.resize(self.values.len(), 0.0);
            self.transpose = transpose;
        }
        for (k, &t) in self.transpose.iter().enumerate() {
            self.symmetric_part[k] = 0.5 * (self.values[k] + self.values[t as usize]);
        }
        let pattern = (&self.col_ptr[..], &self.row_idx[..]);
        Ok(numeric_llt(&self.symbolic, pattern, &self.symmetric_part, &mut self.l_values, &mut self.mem).is_ok())
    }

    /// Solves A x = rhs in place by GMRES preconditioned with the symmetric part's
    /// Cholesky factor ([`Factored::SymmetricPart`]); `false` (rhs unchanged) where it did
    /// not converge in [`KRYLOV_ITERATIONS`].
    fn krylov_solve(&mut self, rhs: &mut [f64]) -> bool {
        let SparseSolver {
            col_ptr,
            row_idx,
            values,
            symbolic,
            l_values,
            mem,
            gmres,
            krylov,
            ..
        } = self;
        let multiply = |x: &[f64], out: &mut [f64]| {
            out.fill(0.0);
            for (c, &xc) in x.iter().enumerate() {
                for k in col_ptr[c]..col_ptr[c + 1] {
                    out[row_idx[k]] += values[k] * xc;
                }
            }
        };
        let precondition = |v: &mut [f64]| {
            let x = faer::ColMut::from_slice_mut(v).as_mat_mut();
            LltRef::new(symbolic, l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(mem));
        };
        let iterations = gmres.solve(rhs, KRYLOV_TOLERANCE, KRYLOV_ITERATIONS, multiply, precondition);
        krylov.solves += 1;
        krylov.iterations += iterations.unwrap_or(KRYLOV_ITERATIONS);
        krylov.unconverged += usize::from(iterations.is_none());
        iterations.is_some()
    }
}

impl SparseSolver {
    /// [`TangentSolver::cholesky`], its outcome recorded in the back-off.
    fn recorded_cholesky(&mut self) -> bool {
        let positive = self.cholesky();
        self.cholesky_first.record(positive);
        positive
    }

    /// LDLᵀ of the assembled symmetric matrix on Cholesky's symbolic factor, kept only if it
    /// passes the [`LDLT_CHECK`].
    fn ldlt(&mut self) -> bool {
        let n = self.col_ptr.len() - 1;
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(structure, &self.values);
        let ok = self
            .symbolic
            .factorize_numeric_ldlt(
                &mut self.l_values,
                a,
                Side::Lower,
                LdltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.mem),
                Default::default(),
            )
            .is_ok();
        if !ok {
            return false;
        }
        // A·1: the row sums (both triangles are stored).
        self.check.fill(0.0);
        for c in 0..n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                self.check[self.row_idx[k]] += self.values[k];
            }
        }
        let x = faer::ColMut::from_slice_mut(&mut self.check).as_mat_mut();
        LdltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut self.mem));
        self.check.iter().all(|x| (x - 1.0).abs() <= LDLT_CHECK)
    }
}

impl TangentSolver for SparseSolver {
    fn clear(&mut self) {
        self.values.fill(0.0);
    }

    fn cholesky(&mut self) -> bool {
        let pattern = (&self.col_ptr[..], &self.row_idx[..]);
        let llt = numeric_llt(&self.symbolic, pattern, &self.values, &mut self.l_values, &mut self.mem);
        (self.factored, self.failed_pivot) = match llt {
            Ok(_) => (Factored::Cholesky, None),
            Err(e) => (Factored::None, Some(self.pivot_dof(e))),
        };
        self.factored == Factored::Cholesky
    }

    fn factor(&mut self, symmetric: bool) -> Result<(), LinearError> {
        self.factored = Factored::None;
        self.failed_pivot = None;
        let tried = symmetric && self.cholesky_first.attempt();
        if tried && self.recorded_cholesky() {
            return Ok(());
        }
        if symmetric && self.ldlt() {
            self.factored = Factored::Ldlt;
            return Ok(());
        }
        // The LU names no failed pivot, so an LU failure is reported at Cholesky's: where
        // it was skipped above, it runs now (the LU costs several Cholesky factorizations).
        if symmetric && !tried && self.recorded_cholesky() {
            return Ok(());
        }
        if !symmetric && self.krylov_first.attempt() {
            if self.symmetric_part_cholesky()? {
                self.factored = Factored::SymmetricPart;
                return Ok(());
            }
            self.krylov_first.record(false);
        }
        self.lu_factor()
    }

    fn size(&self) -> usize {
        self.col_ptr.len() - 1
    }

    fn take_late_factorizations(&mut self) -> usize {
        std::mem::take(&mut self.late_factorizations)
    }

    fn krylov_effort(&self) -> KrylovEffort {
        self.krylov
    }

    /// Cholesky's and LDLᵀ's solves take the columns as one block (beyond [`MOST_NEW`]
    /// columns with a scratch allocated for them); LU's one by one.
    fn solve_columns(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        let n = self.size();
        let k = rhs.len() / n;
        let x = faer::MatMut::from_column_major_slice_mut(rhs, n, k);
        let mut wider;
        let mem = if k <= MOST_NEW {
            &mut self.mem
        } else {
            wider = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(k, Par::Seq));
            &mut wider
        };
        let stack = MemStack::new(mem);
        match self.factored {
            Factored::Cholesky => LltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, stack),
            Factored::Ldlt => LdltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, stack),
            _ => return rhs.chunks_mut(n).try_for_each(|column| self.solve(column)),
        }
        Ok(())
    }

    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        if self.factored == Factored::SymmetricPart {
            let converged = self.krylov_solve(rhs);
            self.krylov_first.record(converged);
            if converged {
                return Ok(());
            }
            // Too unsymmetric for GMRES at this cost: factor A after all.
            self.late_factorizations += 1;
            self.lu_factor()?;
        }
        let x = faer::ColMut::from_slice_mut(rhs).as_mat_mut();
        match (self.factored, &mut self.lu) {
            (Factored::Cholesky, _) => {
                LltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut self.mem));
                Ok(())
            }
            (Factored::Ldlt, _) => {
                LdltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut self.mem));
                Ok(())
            }
            (Factored::Lu, Some((symbolic, numeric, mem))) => {
                LuRef::new_unchecked(symbolic, numeric).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(mem));
                // The sparse LU does not report a vanishing pivot; it shows as inf/NaN.
                if rhs.iter().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err(LinearError::Singular {
                        dof: self.failed_pivot,
                        ratio: None,
                    })
                }
            }
            _ => panic!("TangentSolver::solve before a successful factor()"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Entries (both triangles) of a symmetric matrix with −1 between DOFs that are
    /// `neighbours` and 1 + (number of neighbours) on the diagonal: diagonally dominant,
    /// hence positive definite, so every failure below comes from the zeroed DOF.
    fn laplacian(n: usize, neighbours: impl Fn(usize, usize) -> bool) -> Vec<(usize, usize, f64)> {
        let mut entries = Vec::new();
        for i in 0..n {
            let mut degree = 0.0;
            for j in (0..n).filter(|&j| j != i && neighbours(i, j)) {
                entries.push((i, j, -1.0));
                degree += 1.0;
            }
            entries.push((i, i, degree + 1.0));
        }
        entries
    }

    /// 5-point stencil on an m × m grid.
    fn grid(m: usize) -> Vec<(usize, usize, f64)> {
        laplacian(m * m, |i, j| {
            let ((ri, ci), (rj, cj)) = ((i / m, i % m), (j / m, j % m));
            ri.abs_diff(rj) + ci.abs_diff(cj) == 1
        })
    }

    /// Every DOF coupled to the `w` on either side.
    fn band(n: usize, w: usize) -> Vec<(usize, usize, f64)> {
        laplacian(n, |i, j| i.abs_diff(j) <= w)
    }

    /// Assembles `entries` with row and column `zero` left out, factors and solves.
    fn factor_and_solve(
        solver: &mut dyn TangentSolver,
        n: usize,
        entries: &[(usize, usize, f64)],
        zero: Option<usize>,
    ) -> Result<(), LinearError> {
        solver.clear();
        for &(i, j, v) in entries.iter().filter(|&&(i, j, _)| zero != Some(i) && zero != Some(j)) {
            solver.add(i, j, v);
        }
        solver.factor(true)?;
        let mut x = vec![1.0; n];
        solver.solve(&mut x)
    }

    /// The sparse solver skips Cholesky after a failed one (its back-off), so from the
    /// second zero DOF on the name comes from the Cholesky its LU path runs instead.
    fn assert_names_zero_dofs(solver: &mut dyn TangentSolver, n: usize, entries: &[(usize, usize, f64)], ks: &[usize]) {
        factor_and_solve(solver, n, entries, None).expect("the full matrix is positive definite");
        for &k in ks {
            let err = factor_and_solve(solver, n, entries, Some(k));
            assert!(
                matches!(err, Err(LinearError::Singular { dof: Some(d), .. }) if d == k),
                "zero DOF {k}: {err:?}"
            );
        }
    }

    /// The dense solver's `add_pair` (±k straight into its columns) against the expanded
    /// 6×6 block through `add` (the trait's default, what a `Mat` receives): two pairs
    /// sharing DOFs, one end partly fixed, must give the same matrix to the last bit (the
    /// same one addition per entry and pair, in the same order).
    #[test]
    fn dense_add_pair_is_the_expanded_block() {
        let n = 5;
        let k1 = [[1.5, -0.25, 0.125], [-0.25, 2.0, 0.375], [0.125, 0.375, 3.0]];
        let k2 = [[0.1, 0.2, 0.3], [0.2, 0.7, -0.4], [0.3, -0.4, 0.9]];
        let free1 = [Some(0), Some(1), Some(2), Some(3), None, Some(4)];
        let free2 = [Some(4), Some(2), None, Some(1), Some(0), Some(3)];
        let mut dense = DenseSolver::new(n);
        let mut reference = Mat::<f64>::zeros(n, n);
        for (free, k) in [(&free1, &k1), (&free2, &k2)] {
            dense.add_pair(0, free, k);
            reference.add_pair(0, free, k);
        }
        for i in 0..n {
            for j in 0..n {
                assert_eq!(dense.k[(i, j)].to_bits(), reference[(i, j)].to_bits(), "entry ({i}, {j})");
            }
        }
        // Free DOFs 0 and 3: the two ends' x in the first pair (−k1[0][0]), the second end's
        // y and z in the second (+k2[1][2]).
        assert_eq!(reference[(0, 3)], -1.5 + k2[1][2]);
    }

    #[test]
    fn dense_names_the_zero_dof() {
        for (n, entries) in [(36, grid(6)), (300, band(300, 20))] {
            let ks = [0, 7, n / 2, n - 2, n - 1];
            assert_names_zero_dofs(&mut DenseSolver::new(n), n, &entries, &ks);
        }
    }

    /// A sparse solver on `entries`, after checking which faer factorization it uses and
    /// that AMD moves some of `ks`, in a way that tells its two directions apart.
    fn sparse(n: usize, entries: &[(usize, usize, f64)], ks: &[usize], supernodal: bool) -> SparseSolver {
        let solver = SparseSolver::new(n, Sparsity::amd(entries.iter().map(|&(i, j, _)| (i, j))));
        assert_eq!(matches!(solver.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)), supernodal);
        let (_, inv) = solver.symbolic.perm().expect("an AMD ordering").arrays();
        assert!(ks.iter().any(|&k| inv[inv[k]] != k), "AMD moves none of {ks:?} off an involution");
        solver
    }

    #[test]
    fn sparse_simplicial_names_the_zero_dof() {
        let (n, entries) = (64, grid(8));
        let ks = [0, 9, 27, 36, 63];
        assert_names_zero_dofs(&mut sparse(n, &entries, &ks, false), n, &entries, &ks);
    }

    /// A band of 2 × 100 + 1: L's columns hold ~100 entries, past faer's supernodal
    /// threshold (flops / nnz(L) > 40).
    #[test]
    fn sparse_supernodal_names_the_zero_dof() {
        let (n, entries) = (3000, band(3000, 100));
        let ks = [0, 1, 1234, 1500, 2998, 2999];
        assert_names_zero_dofs(&mut sparse(n, &entries, &ks, true), n, &entries, &ks);
    }

    /// Solves `entries` x = A·x_true with the sparse solver; returns which factorization
    /// served and the largest error of x.
    fn sparse_solve(n: usize, entries: &[(usize, usize, f64)]) -> (Factored, f64) {
        let mut solver = SparseSolver::new(n, Sparsity::amd(entries.iter().map(|&(i, j, _)| (i, j))));
        solver.clear();
        let x_true: Vec<f64> = (0..n).map(|i| 1.0 + (i % 7) as f64).collect();
        let mut rhs = vec![0.0; n];
        for &(i, j, v) in entries {
            solver.add(i, j, v);
            rhs[i] += v * x_true[j];
        }
        solver.factor(true).expect("nonsingular");
        solver.solve(&mut rhs).expect("solvable");
        let error = rhs.iter().zip(&x_true).fold(0.0_f64, |m, (x, t)| m.max((x - t).abs()));
        (solver.factored, error)
    }

    /// An indefinite symmetric matrix (an 8 × 8 grid Laplacian shifted by −2.5: eigenvalues
    /// on both sides of 0, none near it) goes to LDLᵀ, not LU, and is solved to round-off;
    /// a matrix whose first pivot is zero ([[0, 1], [1, 0]] blocks) cannot be factored
    /// without pivoting and goes to LU. Tolerance 1e-10: the condition numbers are below 100.
    #[test]
    fn sparse_indefinite_goes_to_ldlt_and_zero_pivots_to_lu() {
        let shifted: Vec<(usize, usize, f64)> = grid(8)
            .into_iter()
            .map(|(i, j, v)| (i, j, if i == j { v - 2.5 } else { v }))
            .collect();
        let (factored, error) = sparse_solve(64, &shifted);
        assert_eq!(factored, Factored::Ldlt);
        assert!(error < 1e-10, "LDLᵀ error {error:e}");
        let swaps: Vec<(usize, usize, f64)> = (0..32).flat_map(|k| [(2 * k, 2 * k + 1, 1.0), (2 * k + 1, 2 * k, 1.0)]).collect();
        let (factored, error) = sparse_solve(64, &swaps);
        assert_eq!(factored, Factored::Lu);
        assert!(error < 1e-10, "LU error {error:e}");
    }

    /// A 30 × 30 grid Laplacian plus a skew part ±`skew` on its x-neighbours, solved as
    /// unsymmetric: the factorization that served, max |x − x_true|, and the LU
    /// factorizations its solves made.
    fn unsymmetric_solve(solver: &mut SparseSolver, skew: f64) -> (Factored, f64, usize) {
        let n = 900;
        let x_true: Vec<f64> = (0..n).map(|i| 1.0 + (i % 7) as f64).collect();
        let mut rhs = vec![0.0; n];
        solver.clear();
        for (i, j, v) in grid(30) {
            let v = v + if j == i + 1 {
                skew
            } else if i == j + 1 {
                -skew
            } else {
                0.0
            };
            solver.add(i, j, v);
            rhs[i] += v * x_true[j];
        }
        solver.factor(false).expect("nonsingular");
        let factored = solver.factored;
        solver.solve(&mut rhs).expect("solvable");
        let error = rhs.iter().zip(&x_true).fold(0.0_f64, |m, (x, t)| m.max((x - t).abs()));
        (factored, error, solver.take_late_factorizations())
    }

    /// An unsymmetric matrix whose skew part is small against its symmetric part (as
    /// objective damping's against the mass term) is solved by GMRES on the symmetric
    /// part's Cholesky factor; one whose skew part dominates (±40 against a diagonal of at
    /// most 5) does not converge in `KRYLOV_ITERATIONS` and is factored by LU in the solve,
    /// counted, and the next one goes to LU directly (the back-off). Errors: GMRES's
    /// relative residual 1e-10 times the conditioning (the Laplacian's smallest eigenvalue
    /// is 1.01: ‖A⁻¹‖ ≲ 1, entries of x ≤ 7, ‖b‖ ≲ 1e3); LU's round-off.
    #[test]
    fn unsymmetric_matrices_go_to_gmres_on_their_symmetric_part_or_to_lu() {
        let mut solver = SparseSolver::new(900, Sparsity::amd(grid(30).into_iter().map(|(i, j, _)| (i, j))));
        let (factored, error, late) = unsymmetric_solve(&mut solver, 0.5);
        assert_eq!((factored, late), (Factored::SymmetricPart, 0));
        assert!(error < 1e-7, "GMRES error {error:e}");
        let first = solver.krylov_effort();
        assert_eq!((first.solves, first.unconverged), (1, 0));
        assert!((1..KRYLOV_ITERATIONS).contains(&first.iterations), "{first:?}");
        let (factored, error, late) = unsymmetric_solve(&mut solver, 40.0);
        assert_eq!((factored, solver.factored, late), (Factored::SymmetricPart, Factored::Lu, 1));
        assert!(error < 1e-10, "LU error {error:e}");
        let second = solver.krylov_effort();
        let expected = KrylovEffort {
            solves: 2,
            iterations: first.iterations + KRYLOV_ITERATIONS,
            unconverged: 1,
        };
        assert_eq!(second, expected);
        let (factored, error, late) = unsymmetric_solve(&mut solver, 40.0);
        assert_eq!((factored, late), (Factored::Lu, 0));
        assert!(error < 1e-10, "LU error {error:e}");
        assert_eq!(solver.krylov_effort(), expected, "the back-off's LU makes no GMRES solve");
    }
}
