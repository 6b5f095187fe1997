//! Scene -> grid -> model -> simulation: the one place where every command (`simulate`,
//! `observe`, `fit`, `gradcheck`, `diagnose`, the synthetic data, the benchmarks) builds the
//! simulation of a scene, `[numerics]` included.
//!
//! * the grid: the body's SDF at the scene's (or a given) resolution, and the finer SDF its
//!   observed surface is extracted from (`[numerics] surface_subdivision`,
//!   [`crate::surface::embed`]);
//! * the model: [`Scene::to_model`] (the core effects) plus what every effect with its own
//!   section adds ([`super::effects`]);
//! * the simulation: the model on the grid with the scene's solver settings.

use super::effects::{check_extensions, section_effects};
use super::Scene;
use crate::error::Error;
use crate::fem::{Grid, Model, Simulation, SolverSettings};

impl Scene {
    /// The simulation grid at the scene's resolution, with its surface SDF.
    pub fn grid(&self) -> Result<Grid, Error> {
        self.grid_at(None)
    }

    /// The simulation grid at `resolution` cells per unit (`None`: the scene's), with the
    /// body's SDF sampled `[numerics] surface_subdivision` times finer for its surface (a
    /// shape is evaluated exactly there, a mesh's SDF is computed there, an SDF file's
    /// trilinear interpolant is resampled). Errors name the scene file.
    pub fn grid_at(&self, resolution: Option<f64>) -> Result<Grid, Error> {
        let sdf = self.body_sdf_at(resolution)?;
        let r = 1.0 / sdf.spacing;
        let grid = Grid::new(sdf)
            .map_err(|e| Error::format(&self.path, e.to_string()))?
            .with_surface_method(self.numerics.surface_method);
        let s = self.numerics.surface_subdivision;
        if s <= 1 {
            return Ok(grid);
        }
        Ok(grid.with_surface_sdf(self.body_sdf_at(Some(s as f64 * r))?))
    }
}

impl Scene {
    /// The complete forward model of the scene on `grid`: [`Scene::to_model`] plus what every
    /// effect with its own section that the scene switches on adds (e.g. `wind`'s external
    /// force). Refuses effect names and sections that no effect claims
    /// ([`check_extensions`]). Errors name the scene file.
    pub fn build_model(&self, grid: &Grid) -> Result<Model, Error> {
        check_extensions(self)?;
        let mut model = self.to_model();
        for e in section_effects() {
            if self.effect_on(e.name()) {
                e.apply(self, grid, &mut model).map_err(|why| {
                    // the effect's own errors may name the file already: say it once
                    let why = why.to_string();
                    let file = format!("{}: ", self.path.display());
                    let why = why.strip_prefix(&file).unwrap_or(&why);
                    Error::format(&self.path, format!("{}: {why}", e.name()))
                })?;
            }
        }
        Ok(model)
    }

    /// The simulation of the scene: its grid, its model ([`Scene::build_model`]) and its
    /// solver settings ([`Scene::solver_settings`]). Errors name the scene file.
    pub fn build_simulation(&self) -> Result<Simulation, Error> {
        let grid = self.grid()?;
        let model = self.build_model(&grid)?;
        // a model that cannot be simulated names the scene and the key
        let mut sim = Simulation::new(grid, model).map_err(|e| Error::format(&self.path, e.to_string()))?;
        sim.solver = self.solver_settings(sim.solver);
        if self.numerics.backend == crate::fem::ComputeBackend::Cuda {
            let device = crate::fem::device_solve::cuda_device()
                .map_err(|e| Error::format(&self.path, format!("[numerics] backend = \"cuda\": {e}")))?;
            sim.set_device(Some(device));
        }
        Ok(sim)
    }

    /// `settings` with the scene's `[numerics]` solver keys (CG tolerance and iteration limit,
    /// preconditioner): every command solves a scene's steps the same way.
    pub fn solver_settings(&self, settings: SolverSettings) -> SolverSettings {
        let mut s = settings;
        s.cg.tolerance = self.numerics.cg_tolerance;
        s.cg.max_iterations = self.numerics.cg_max_iterations;
        s.preconditioner = self.numerics.preconditioner;
        s.reuse_factor = self.numerics.reuse_factor;
        // checked finite and >= 0 (`Scene::check`); megabytes of 8-byte entries
        s.max_reused_factor = (self.numerics.reuse_factor_mb * 1e6 / 8.0).min(usize::MAX as f64) as usize;
        s
    }
}
