//! The linear solves inside Newton: a dense Cholesky (LU fallback) for small models, a
//! sparse Cholesky (LU fallback) with its symbolic analysis done once for large ones. Both
//! factor in place into buffers allocated when the solver is built, so a Newton iteration
//! allocates nothing, and keep the factorization until the next one, so Newton may solve
//! with it again.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::cholesky::llt::{factor as llt_factor, solve as llt_solve};
use faer::linalg::lu::partial_pivoting::{factor as lu_factor, solve as lu_solve};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LinearError {
    /// Pivot of free DOF `dof` vanished relative to the largest one (the sparse LU does
    /// not say which DOF: `None`, ratio 0).
    #[error("singular tangent at free DOF {dof:?} (pivot ratio {ratio:.1e})")]
    Singular { dof: Option<usize>, ratio: f64 },
}

/// Receives matrix entries (row, column, value), added to what is there.
pub trait TangentSink {
    fn add(&mut self, row: usize, col: usize, value: f64);

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
    /// matrix is consumed (clear before the next assembly).
    fn factor(&mut self) -> Result<(), LinearError>;
    /// Solves K x = rhs in place (rhs becomes x) with the last factorization.
    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError>;
}

/// Which factorization a solver holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Factored {
    None,
    Cholesky,
    Lu,
}

/// Relative pivot size below which a matrix is taken as singular: about 1e3 × machine ε,
/// far below any pivot of a stable structure (struts/cables stiffness ratio ~1e9 still
/// leaves pivots ~1e-9 relative).
const SINGULAR_PIVOT: f64 = 1e-13;

/// Dense solver: Cholesky first (the Newmark step matrix and a stable structure's K_T are
/// symmetric positive definite, and Cholesky costs half an LU), partial-pivoting LU when
/// Cholesky fails (an indefinite static state). With row pivoting only, U's j-th pivot
/// belongs to column j, i.e. to free DOF j, which is what a singularity report names.
pub struct DenseSolver {
    k: Mat<f64>,
    /// Factor storage; `k` is kept for the LU fallback.
    work: Mat<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    mem: MemBuffer,
    factored: Factored,
}

impl DenseSolver {
    pub fn new(n: usize) -> Self {
        let req = StackReq::any_of(&[
            llt_factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()),
            llt_solve::solve_in_place_scratch::<f64>(n, 1, Par::Seq),
            lu_factor::lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default()),
            lu_solve::solve_in_place_scratch::<usize, f64>(n, 1, Par::Seq),
        ]);
        DenseSolver {
            k: Mat::zeros(n, n),
            work: Mat::zeros(n, n),
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
}

impl TangentSolver for DenseSolver {
    fn clear(&mut self) {
        self.k.fill(0.0);
    }

    fn factor(&mut self) -> Result<(), LinearError> {
        let n = self.k.nrows();
        self.factored = Factored::None;
        self.work.copy_from(&self.k);
        let llt = llt_factor::cholesky_in_place(
            self.work.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        if llt.is_ok() {
            self.factored = Factored::Cholesky;
            return Ok(());
        }
        lu_factor::lu_in_place(
            self.k.as_mut(),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        let max = (0..n).map(|j| self.k[(j, j)].abs()).fold(0.0, f64::max);
        if let Some((dof, ratio)) = (0..n)
            .map(|j| (j, self.k[(j, j)].abs() / max))
            .filter(|&(_, r)| !(r > SINGULAR_PIVOT))
            .min_by(|a, b| a.1.total_cmp(&b.1))
        {
            return Err(LinearError::Singular { dof: Some(dof), ratio });
        }
        self.factored = Factored::Lu;
        Ok(())
    }

    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        let x = faer::ColMut::from_slice_mut(rhs).as_mat_mut();
        let stack = MemStack::new(&mut self.mem);
        match self.factored {
            Factored::Cholesky => llt_solve::solve_in_place_with_conj(self.work.as_ref(), Conj::No, x, Par::Seq, stack),
            Factored::Lu => {
                let perm = PermRef::new_checked(&self.perm, &self.perm_inv, self.k.nrows());
                lu_solve::solve_in_place_with_conj(self.k.as_ref(), self.k.as_ref(), perm, Conj::No, x, Par::Seq, stack)
            }
            Factored::None => panic!("TangentSolver::solve before a successful factor()"),
        }
        Ok(())
    }
}

/// Sparse Cholesky on a fixed pattern (the structure's connectivity): symbolic analysis
/// (AMD ordering, elimination tree) once, numeric factorization per iteration into
/// preallocated storage. The full symmetric pattern is stored; the Cholesky factorization
/// reads its lower triangle. The Newmark step matrix M/(βΔt²) + … + K_T is positive
/// definite unless the step is far too long, so the dynamic hot loop stays on Cholesky;
/// a static solve through an unstable (indefinite) state, as in folding, falls back to a
/// sparse LU whose symbolic analysis is likewise done once, on first need.
pub struct SparseSolver {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    mem: MemBuffer,
    lu: Option<(SymbolicLu<usize>, NumericLu<usize, f64>, MemBuffer)>,
    factored: Factored,
    /// Per element, the value slot of each of its 36 block entries (`u32::MAX`: not
    /// free), found once by binary search so that assembly is a direct scatter.
    slots: Vec<Option<[u32; 36]>>,
}

impl SparseSolver {
    /// `pattern`: every (row, column) that can receive an entry; both triangles.
    pub fn new(n: usize, pattern: impl IntoIterator<Item = (usize, usize)>) -> Self {
        let mut cols: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (r, c) in pattern {
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
        let symbolic = factorize_symbolic_cholesky(structure, Side::Lower, SymmetricOrdering::Amd, Default::default())
            .expect("symbolic Cholesky of a valid pattern");
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
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
            slots: Vec::new(),
        }
    }
}

impl SparseSolver {
    fn slot(&self, row: usize, col: usize) -> usize {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        lo + self.row_idx[lo..hi].binary_search(&row).expect("entry inside the tangent pattern")
    }
}

impl TangentSink for SparseSolver {
    fn add(&mut self, row: usize, col: usize, value: f64) {
        let k = self.slot(row, col);
        self.values[k] += value;
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

impl TangentSolver for SparseSolver {
    fn clear(&mut self) {
        self.values.fill(0.0);
    }

    fn factor(&mut self) -> Result<(), LinearError> {
        let n = self.col_ptr.len() - 1;
        self.factored = Factored::None;
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(structure, &self.values);
        let llt = self.symbolic.factorize_numeric_llt(
            &mut self.l_values,
            a,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        if llt.is_ok() {
            self.factored = Factored::Cholesky;
            return Ok(());
        }
        let (symbolic, numeric, mem) = self.lu.get_or_insert_with(|| {
            let symbolic = factorize_symbolic_lu(structure, Default::default()).expect("symbolic LU of a valid pattern");
            let req = StackReq::any_of(&[
                symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
                symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            ]);
            (symbolic, NumericLu::new(), MemBuffer::new(req))
        });
        symbolic
            .factorize_numeric_lu(numeric, a, Par::Seq, MemStack::new(mem), Default::default())
            .map_err(|_| LinearError::Singular { dof: None, ratio: 0.0 })?;
        self.factored = Factored::Lu;
        Ok(())
    }

    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearError> {
        let x = faer::ColMut::from_slice_mut(rhs).as_mat_mut();
        match (self.factored, &mut self.lu) {
            (Factored::Cholesky, _) => {
                LltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut self.mem));
                Ok(())
            }
            (Factored::Lu, Some((symbolic, numeric, mem))) => {
                LuRef::new_unchecked(symbolic, numeric).solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(mem));
                // The sparse LU does not report a vanishing pivot; it shows as inf/NaN.
                if rhs.iter().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err(LinearError::Singular { dof: None, ratio: 0.0 })
                }
            }
            _ => panic!("TangentSolver::solve before a successful factor()"),
        }
    }
}
