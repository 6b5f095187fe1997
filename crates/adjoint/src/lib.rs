//! adjoint: gradients and parameter reconstruction (thesis ch. 5). Not implemented yet: see issue 4.

pub mod backward;
pub mod cost;
pub mod cost_mesh;
pub mod fit;
pub mod local;
pub mod observations;
pub mod observe;
pub mod optim;
pub mod params;
pub mod problem;
pub mod tangent;
