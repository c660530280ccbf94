//! Time integration: Newmark-β with Rayleigh damping on the TSM internal force, every step
//! a Newton solve by the common driver, and the energy ledger that checks it.

mod actuation;
mod load;
mod newmark;
mod rayleigh;

pub use actuation::{Actuator, RestSchedule};
pub use load::{FreeLoads, GroundMotion, LoadProfile, Loads, NodalLoad, TimeFunction};
pub use newmark::{Damping, DampingTangent, Energy, Integrator, Newmark, NewmarkParams};
pub use rayleigh::Rayleigh;
