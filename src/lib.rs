//! tsim: tensegrity simulation by the tangent stiffness method (TSM).
//!
//! One element force equation ([`law`]) and one tangent stiffness ([`tsm`]) serve every
//! stage ([`stage`]): form-finding, substitution by real materials, eigen analysis, free
//! vibration, folding and deployment, all solved by one Newton driver ([`solve`]).

// `!(x > 0.0)` is how tsim writes "not positive, or NaN" (a NaN input must fail the
// check, which `x <= 0.0` would let through); clippy's suggested `partial_cmp` form hides
// that intent rather than showing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod config;
pub mod dynamics;
pub mod error;
pub mod law;
pub mod model;
pub mod output;
pub mod pipeline;
pub mod record;
pub mod rigidity;
pub mod run;
pub mod solve;
pub mod stage;
pub mod structure;
pub mod tsm;

pub use error::{Error, Result};
