//! tsim: tensegrity simulation by the tangent stiffness method (TSM).
//!
//! One element force equation ([`law`]) and one tangent stiffness ([`tsm`]) serve every
//! stage ([`stage`]): form-finding, substitution by real materials, eigen analysis, free
//! vibration, folding and deployment, all solved by one Newton driver ([`solve`]).

pub mod config;
pub mod dynamics;
pub mod error;
pub mod law;
pub mod model;
pub mod output;
pub mod pipeline;
pub mod record;
pub mod run;
pub mod solve;
pub mod stage;
pub mod structure;
pub mod tsm;

pub use error::{Error, Result};
