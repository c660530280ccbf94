//! tsim-core: the mechanics of tsim, the tangent stiffness method (TSM) for tensegrities.
//!
//! One element force equation ([`law`]) and one tangent stiffness ([`tsm`]) serve every
//! stage ([`stage`]): form-finding, substitution by real materials, eigen analysis, static
//! loads, free vibration, folding and deployment, all solved by one Newton driver
//! ([`solve`]) and, in time, by Newmark-β ([`dynamics`]). A stage takes a
//! [`structure::Structure`] and a converged [`structure::State`] and pushes every converged
//! step to a [`record::Recorder`]. This crate reads and writes no file and starts no
//! thread: the config, the HDF5 and MCAP writers and the batch runner are the `tsim` crate.

#![warn(missing_docs)]
// `!(x > 0.0)` is how tsim writes "not positive, or NaN" (a NaN input must fail the
// check, which `x <= 0.0` would let through); clippy's suggested `partial_cmp` form hides
// that intent rather than showing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod contact;
pub mod dynamics;
pub mod error;
pub mod law;
pub mod model;
pub mod record;
pub mod rigidity;
pub mod solve;
pub mod stage;
pub mod structure;
pub mod tsm;

pub use error::{Error, Result};
