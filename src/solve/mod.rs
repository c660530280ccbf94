//! Numerical machinery that knows matrices and residuals but no mechanics: the one
//! Newton-Raphson driver every stage uses, and the linear solves inside it.

mod bisect;
mod linear;
mod newton;
pub mod small_solve;

pub use bisect::bisect;
pub use linear::{DenseSolver, LinearError, SparseSolver, TangentSink, TangentSolver};
pub use newton::{
    newton, LinearSolverChoice, NewtonReport, NewtonSettings, NewtonWorkspace, Residual, Scale, SolveError, TangentUpdate, DENSE_LIMIT,
    REUSE_CONTRACTION,
};
