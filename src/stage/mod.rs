//! The pipeline's stages, each a small driver on top of [`crate::tsm`] (forces and
//! tangents) and [`crate::solve`] (the Newton driver). A stage takes a converged state and
//! hands the next one a converged state.

pub mod eigen;
pub mod fold;
pub mod formfind;
pub mod measure;
mod statics;
pub mod substitute;
pub mod transient;

pub use statics::StaticEquilibrium;
