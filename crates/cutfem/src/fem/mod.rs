//! The finite-element core: grid, element, assembly, contact, time integration.

pub mod advect;
pub mod assembly;
pub mod collision;
pub mod device_solve;
pub mod element;
pub mod forward;
pub mod grid;
pub mod model;
pub mod plausible;
pub mod sim;
pub mod solver;
mod step_info;
pub mod tet;

pub use assembly::{Assembler, Material};
pub use collision::Ground;
pub use device_solve::ComputeBackend;
pub use grid::{Cell, Grid};
pub use model::{
    Aabb, ExternalForce, MassMatrix, Model, NewmarkCoefficients, NitschePenalty, NitscheQuadrature,
    NodalDamping, DEFAULT_NITSCHE_GAMMA,
};
pub use sim::{NitscheFace, Simulation, StepInfo};
pub use solver::{LinearSolver, Preconditioner, SolveInfo, SolverSettings};
