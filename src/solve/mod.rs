//! Numerical machinery that knows matrices and residuals but no mechanics: the one
//! Newton-Raphson driver every stage uses, the linear solves inside it, and the partial
//! symmetric eigensolver (shift-invert Lanczos on a sparse factorization).

mod bisect;
mod eigen;
mod linear;
mod newton;
pub mod small_solve;

pub use bisect::bisect;
pub use eigen::{krylov_dimension, partial_eigen, Diagonal, EigenError, EigenPairs, Shift};
pub use linear::{DenseSolver, LinearError, SparseSolver, TangentSink, TangentSolver};
pub use newton::{
    newton, LinearSolverChoice, NewtonReport, NewtonSettings, NewtonWorkspace, Residual, Scale, SolveError, TangentUpdate, DENSE_LIMIT,
    REUSE_CONTRACTION,
};
