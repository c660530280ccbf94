//! Numerical machinery that knows matrices and residuals but no mechanics: the one
//! Newton-Raphson driver every stage uses, the linear solves inside it, and the dense and
//! partial symmetric eigensolvers (shift-invert Lanczos on a sparse factorization).

mod backoff;
mod bisect;
mod dense_eigen;
mod eigen;
mod krylov;
mod linear;
mod low_rank;
mod newton;
pub mod ordering;
pub mod small_solve;

pub use bisect::{bisect, StepFailure};
pub use dense_eigen::symmetric_eigen;
pub use eigen::{krylov_dimension, lowest_eigen, partial_eigen, Diagonal, EigenError, EigenPairs, Shift};
pub use krylov::KrylovEffort;
pub use linear::{
    DenseSolver, LinearError, ScaledSink, SparseSolver, Sparsity, TangentSink, TangentSolver, KRYLOV_ITERATIONS, KRYLOV_SOLVE, SPARSE_LU,
};
pub use newton::{
    newton, LinearSolverChoice, NewtonReport, NewtonSettings, NewtonWorkspace, Residual, Scale, SolveError, TangentUpdate, DENSE_LIMIT,
    REUSE_CONTRACTION,
};
