//! adjoint: exact gradients through the whole soft-body simulation and parameter
//! reconstruction from observed surface points (thesis ch. 5).
//!
//! The layers, from the bottom:
//!
//! * [`local`]: the adjoints of the per-cell and per-crossing stages (polar decomposition
//!   eq. 4.4.9 / 5.5.4, the corotated elastic term and the Lame parameters 5.5.5, contact
//!   Alg. 5.5), each checked against central differences in `tests/local.rs`;
//! * [`backward`]: the backward twin of `cutfem::fem::Simulation::step` (Alg. 5.3, sec.
//!   5.5.3-5.5.6): one adjoint solve with the same symmetric Newmark matrix per step, and the
//!   derivatives of `lam^T (b - A u')`;
//! * [`cost`] (displacements eq. 5.4.1, the thesis' level-set point-cloud cost 5.4.4 with
//!   Alg. 5.2 and the adjoint of the diffusion 5.5.2, Huber) and [`cost_mesh`] (distance to
//!   the simulated surface mesh);
//! * [`params`]: the interface's parameter vocabulary in unconstrained coordinates (log,
//!   logistic, tilt angles, a coarse trilinear stiffness field); a `ParamSet` is checked
//!   against its model once into a [`params::Layout`], the one map between `x` and a model;
//! * [`problem`]: forward pass storing `u, v` per step, backward pass recomputing `K`, `A`
//!   and the contact forces (sec. 5.7); [`tangent`]: tangent-linear sensitivities and the
//!   Gauss-Newton matrix;
//! * [`optim`]: Barzilai-Borwein gradient descent, L-BFGS, Levenberg-Marquardt, all
//!   tolerant of diverging evaluations;
//! * [`observe`] and [`observations`]: virtual RGB-D cameras and the observation CSV;
//!   [`camera_file`]: the camera file beside a CSV, checked against it;
//! * [`fit`]: a scene's reconstruction problem (on the simulation that
//!   `cutfem::scene::Scene::build_simulation` builds), the optimizer objective, the fit log;
//!   [`gradcheck`]: the adjoint gradient against finite differences over a sweep of steps with
//!   the Taylor remainder test of [`taylor`];
//! * [`statistics`]: standard errors of a fit, weighted consistently;
//! * [`refine`]: the discretisation share of the error (the same state at `r/2`, `r`, `2r`);
//! * [`diagnosis`]: the reconstruction half of the effects (their parameters, probes and
//!   write-back; the forward half is `cutfem::scene::effects`); where a fitted model fails
//!   and which effect is missing (score tests, short refits, BIC);
//! * [`error`]: the one error type, [`Error`].

pub mod backward;
pub mod camera_file;
pub mod cost;
pub mod cost_mesh;
pub mod diagnosis;
pub mod error;
pub mod fit;
pub mod gradcheck;
pub mod local;
pub mod observations;
pub mod observe;
pub mod optim;
pub mod params;
pub mod problem;
pub mod refine;
pub mod statistics;
pub mod study;
pub mod tangent;
pub mod taylor;

pub use error::Error;
