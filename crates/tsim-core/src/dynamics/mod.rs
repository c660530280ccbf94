//! Time integration: Newmark-β with Rayleigh damping on the TSM internal force, every step
//! a Newton solve by the common driver, and the energy ledger that checks it.

mod actuation;
mod ledger;
mod load;
mod midpoint_ends;
mod newmark;
mod rayleigh;
mod step_control;
mod viscous;

pub use actuation::{Actuator, RestSchedule};
pub use ledger::Energy;
pub use load::{FreeLoads, GroundMotion, LoadProfile, Loads, NodalLoad, TimeFunction};
pub use newmark::{AxialForces, Damping, DampingTangent, Integrator, Newmark, NewmarkParams, Scheme};
pub use rayleigh::Rayleigh;
pub use step_control::AutoStep;
