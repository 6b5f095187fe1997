//! The simulation grid of a scene: the body's SDF at the scene's (or a given) resolution, and
//! the finer SDF its observed surface is extracted from (`[numerics] surface_subdivision`,
//! [`crate::surface::embed`]). Every command builds its grid here.

use super::Scene;
use crate::error::Error;
use crate::fem::Grid;

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
