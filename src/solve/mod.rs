//! Numerical machinery that knows matrices and residuals but no mechanics: the one
//! Newton-Raphson driver every stage uses, and the linear solves inside it.

mod linear;
mod newton;

pub use linear::{solve_dense, LinearError};
pub use newton::{newton, NewtonReport, NewtonSettings, Residual, Scale, SolveError};
