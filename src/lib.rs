//! tsim: tensegrity simulation by the tangent stiffness method (TSM).
//!
//! The mechanics are the `tsim-core` crate, re-exported here under the same module names
//! ([`law`], [`tsm`], [`stage`], ...): one element force equation and one tangent stiffness
//! serve every stage. This crate adds what a batch runner needs around them: the YAML
//! config and its stage plan ([`config`]), one case as a sequence of stages
//! ([`pipeline`]), the HDF5 and MCAP writers ([`output`]), the runner ([`run`]) and the
//! command line ([`cli`]), shared by the `tsim` binary and the Python package.

// `!(x > 0.0)` is how tsim writes "not positive, or NaN" (a NaN input must fail the
// check, which `x <= 0.0` would let through); clippy's suggested `partial_cmp` form hides
// that intent rather than showing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cli;
pub mod config;
pub mod output;
pub mod pipeline;
pub mod run;

pub use tsim_core::{contact, dynamics, error, law, model, record, rigidity, solve, stage, structure, tsm};
pub use tsim_core::{Error, Result};
