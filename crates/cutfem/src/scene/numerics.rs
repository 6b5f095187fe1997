//! `[numerics]` (an extension section of the scene): solver and discretization constants.

use serde::{Deserialize, Serialize};

/// `[numerics]` (extension): solver and discretization constants.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct NumericsSection {
    /// how the Nitsche terms are integrated: "consistent" (default) or "thesis"
    /// ([`crate::fem::NitscheQuadrature`])
    #[serde(default)]
    pub nitsche: crate::fem::NitscheQuadrature,
    /// a fixed Nitsche penalty eta (the thesis: 1e8); excludes `nitsche_gamma`
    #[serde(default)]
    pub nitsche_eta: Option<f64>,
    /// the Nitsche penalty relative to the material and the cell size, `eta = gamma (lambda +
    /// 2 mu) |G_e| / |K_e|` ([`crate::fem::NitschePenalty`]); when neither is given, the
    /// default of `nitsche` ([`crate::fem::NitscheQuadrature::default_penalty`])
    #[serde(default)]
    pub nitsche_gamma: Option<f64>,
    /// relative CG tolerance
    #[serde(default = "cg_tol")]
    pub cg_tolerance: f64,
    /// CG iteration limit
    #[serde(default = "cg_max")]
    pub cg_max_iterations: usize,
    /// extension of the displacements into empty nodes before advection: "harmonic" (the
    /// thesis' Poisson diffusion) or "linear" (reproduces linear fields exactly)
    #[serde(default)]
    pub diffusion: crate::fem::advect::DisplacementExtension,
    /// CG preconditioner of the step's linear solve: "block_ic0" (default), "block_jacobi" (the
    /// thesis'), "rest_cholesky" or "multigrid" ([`crate::fem::solver`])
    #[serde(default)]
    pub preconditioner: crate::fem::Preconditioner,
    /// factor a Newmark matrix met again at a later step (a linear model without contact: the
    /// same at every step, forward, adjoint and tangent) and solve directly while it stays the same
    /// (default true; [`crate::fem::solver`])
    #[serde(default = "reuse_factor")]
    pub reuse_factor: bool,
    /// the largest such factor in megabytes (8 bytes per entry; default 200): a larger one is
    /// not made and the matrix is solved by CG at every step
    #[serde(default = "reuse_factor_mb")]
    pub reuse_factor_mb: f64,
    /// the grid element: "incompatible" (default), "trilinear" (the thesis'),
    /// "trilinear_exact", "incompatible_corner" ([`crate::fem::element::Element`])
    #[serde(default)]
    pub element: crate::fem::element::Element,
    /// the mass matrix of a grid body: "lumped" (default; the thesis' diagonal) or
    /// "consistent" (`rho int N_i N_j`; [`crate::fem::MassMatrix`])
    #[serde(default)]
    pub mass: crate::fem::MassMatrix,
    /// the observed surface is extracted from the body's SDF sampled this many times finer than
    /// the simulation grid (1: on the grid itself, as the thesis does), each vertex moved by
    /// the trilinear field of its cell ([`crate::fem::Grid::surface`]); 1..=8
    #[serde(default = "surface_subdivision")]
    pub surface_subdivision: usize,
    /// how the observed surface is extracted: "marching_cubes" (default; vertices on grid
    /// edges, sharp edges bevelled by up to a surface cell) or "dual_contouring" (one vertex
    /// per cut cell, sharp edges and corners kept; [`crate::surface::dual_contour`])
    #[serde(default)]
    pub surface_method: crate::surface::SurfaceMethod,
    /// where the step's linear solves run: "cpu" (default) or "cuda" (block-Jacobi CG on CUDA
    /// device 0; a one-line error where CUDA is not available; [`crate::fem::device_solve`])
    #[serde(default)]
    pub backend: crate::fem::ComputeBackend,
}

/// Largest `[numerics].surface_subdivision`.
pub const MAX_SURFACE_SUBDIVISION: usize = 8;

fn cg_tol() -> f64 {
    crate::fem::SolverSettings::default().cg.tolerance
}
fn cg_max() -> usize {
    crate::fem::SolverSettings::default().cg.max_iterations
}
fn reuse_factor() -> bool {
    crate::fem::SolverSettings::default().reuse_factor
}
fn reuse_factor_mb() -> f64 {
    crate::fem::SolverSettings::default().max_reused_factor as f64 * 8e-6
}
fn surface_subdivision() -> usize {
    DEFAULT_SURFACE_SUBDIVISION
}
/// Default `[numerics].surface_subdivision`: the surface from an SDF twice as fine as the grid
/// (`docs/simulation.md`, "The observed surface").
pub const DEFAULT_SURFACE_SUBDIVISION: usize = 2;
impl NumericsSection {
    /// True when every key has its default value.
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

impl Default for NumericsSection {
    fn default() -> Self {
        Self {
            nitsche: Default::default(),
            nitsche_eta: None,
            nitsche_gamma: None,
            cg_tolerance: cg_tol(),
            cg_max_iterations: cg_max(),
            diffusion: Default::default(),
            preconditioner: crate::fem::Preconditioner::default(),
            reuse_factor: reuse_factor(),
            reuse_factor_mb: reuse_factor_mb(),
            element: crate::fem::element::Element::default(),
            mass: Default::default(),
            surface_subdivision: surface_subdivision(),
            surface_method: Default::default(),
            backend: Default::default(),
        }
    }
}

impl NumericsSection {
    /// The Nitsche penalty: `nitsche_eta` (fixed) or `nitsche_gamma` (scaled), not both; else
    /// the default of `nitsche`.
    pub fn nitsche_penalty(&self) -> Result<crate::fem::NitschePenalty, String> {
        use crate::fem::NitschePenalty;
        match (self.nitsche_eta, self.nitsche_gamma) {
            (Some(_), Some(_)) => Err(
                "numerics: give nitsche_eta (a fixed penalty) or nitsche_gamma (a \
                 penalty scaled with the material and the cell size), not both"
                    .into(),
            ),
            (Some(eta), None) => Ok(NitschePenalty::Fixed(eta)),
            (None, Some(g)) => Ok(NitschePenalty::Scaled(g)),
            (None, None) => Ok(self.nitsche.default_penalty()),
        }
    }
}
