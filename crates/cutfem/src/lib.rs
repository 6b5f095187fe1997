//! # cutfem
//!
//! Linear elasticity of soft bodies on a regular grid whose cells are cut by a signed distance
//! function (thesis ch. 2 and 4). Work in progress (issue 3): the modules below are being
//! built; none of them is a complete simulation yet.

pub mod cutcell;
pub mod error;
pub mod fem;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod sdf;
pub mod shapes;
pub mod surface;

pub use error::Error;
pub use mesh::TriMesh;
pub use sdf::SdfGrid;
