//! # cutfem
//!
//! Linear elasticity of soft bodies on a regular grid whose cells are cut by a signed distance
//! function (thesis ch. 2 and 4), built on gpumat.
//!
//! Data flow: a body ([`sdf`]: thesis `.sdf` / `.npy`; [`mesh`]: triangle meshes turned into
//! SDFs; [`shapes`]: analytic solids) becomes a [`fem::Grid`] of active cells with their exact
//! partial integrals ([`cutcell`], eq. 4.2.2-4.2.3). [`fem::Simulation::step`] shows one time
//! step's stage order: rotations, stiffness and forces ([`fem::assembly`], eq. 4.4.5-4.4.17),
//! ground contact ([`fem::collision`], sec. 2.8), the Newmark system as two fused expressions
//! and its PCG solve ([`fem::sim`], sec. 4.4.3-4.4.4). [`fem::advect`] extends the
//! displacements and advects the level set (sec. 4.4.5), after every frame of a
//! [`fem::forward::ForwardRun`] (the run `softbody simulate` reports); [`fem::tet`] is the tetrahedral
//! baseline of sec. 4.6. [`surface`] (marching cubes, or dual contouring that keeps sharp edges)
//! and [`render`] turn states into PLY meshes and PNG pictures ([`render::raster`] is the one
//! z-buffer of the workspace, also behind the virtual depth cameras; [`render::font`] the
//! text, DejaVu Sans); [`scene`] reads the TOML scene
//! files of `docs/interface.md` (every section typed, `[fit]` and `[numerics]` included, each
//! checked on load) and builds from them the one simulation every command runs
//! ([`scene::Scene::build_simulation`]: grid, complete model with the forward half of every
//! effect, [`scene::effects`], and the `[numerics]` solver settings) and writes them back
//! ([`scene::Scene::write`]: a fitted scene is written from a `Scene` value, checked by reading
//! it back). The Newmark coefficients live in [`fem::NewmarkCoefficients`],
//! the `[f64; 3]` helpers in [`v3`].
//!
//! ```
//! use cutfem::fem::{Grid, Model, Simulation};
//! use cutfem::shapes::Shape;
//! let sdf = Shape::Sphere { center: [0.0, 1.0, 0.0], radius: 0.3 }.to_sdf(10.0, 2).unwrap();
//! let mut sim = Simulation::new(Grid::new(sdf).unwrap(), Model::default()).unwrap();
//! sim.v.as_mut_slice().iter_mut().for_each(|v| v.y = -1.0); // a falling ball, no forces
//! sim.step().unwrap();
//! assert!(sim.max_displacement() > 0.0);
//! ```

pub mod cutcell;
pub mod error;
pub mod fem;
pub mod input;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod sdf;
pub mod shapes;
pub mod surface;
pub mod v3;

pub use error::Error;
pub use mesh::TriMesh;
pub use sdf::{ExactSdf, SdfGrid};
