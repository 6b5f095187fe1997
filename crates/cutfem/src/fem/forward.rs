//! The forward run of a scene as `softbody simulate` reports it: frames of
//! [`Simulation::step`], each followed by the level-set update of thesis sec. 4.4.5 (the
//! displacements diffused into the empty band around the body, then the SDF advected, eq.
//! 4.4.19-4.4.21), with the totals a report needs (seconds per stage, CG iterations per frame,
//! the largest residual, fallbacks, Newton iterations of the penalty contact).

use super::advect::{advect, Diffusion, DIFFUSION_DISTANCE};
use super::{Simulation, StepInfo};
use crate::error::Error;
use crate::sdf::SdfGrid;
use std::time::Instant;

/// What the frames so far did.
#[derive(Clone, Debug, Default)]
pub struct RunTotals {
    /// the frames' step infos summed ([`StepInfo::then`]: the largest residual, the last
    /// contact count)
    pub info: StepInfo,
    /// CG iterations per frame
    pub iterations: Vec<usize>,
    /// frames whose linear solve fell back to the direct solver
    pub fallbacks: usize,
    /// frames where block-Jacobi stood in for the chosen preconditioner
    pub substituted: usize,
    /// seconds in diffusion and advection
    pub advection_s: f64,
}

/// A forward run that advects the level set after every frame.
#[derive(Debug)]
pub struct ForwardRun {
    /// the empty band around the body and its diffusion system
    pub band: Diffusion,
    /// the advected SDF of the last frame (`None` before the first)
    pub advected: Option<SdfGrid>,
    /// the totals so far
    pub totals: RunTotals,
}

impl ForwardRun {
    /// The band of `sim`'s grid ([`DIFFUSION_DISTANCE`], the scene's `[numerics].diffusion`).
    pub fn new(sim: &Simulation, extension: super::advect::DisplacementExtension) -> Result<Self, Error> {
        Ok(Self {
            band: Diffusion::with_distance(&sim.grid, DIFFUSION_DISTANCE, extension)?,
            advected: None,
            totals: RunTotals::default(),
        })
    }

    /// Frame `f`: one [`Simulation::step`], the finiteness check, then diffusion and
    /// advection. Errors name the frame (`step f: ...`).
    pub fn frame(&mut self, sim: &mut Simulation, f: usize) -> Result<(), Error> {
        let at = |what: &str, e: Error| Error::Invalid(format!("step {f}: {what}{e}"));
        let info = sim.step().map_err(|e| at("", e))?;
        self.totals.iterations.push(info.iterations);
        self.totals.fallbacks += info.fallback as usize;
        self.totals.substituted += info.substituted as usize;
        self.totals.info.then(info);
        sim.check_finite().map_err(|e| at("", e))?;
        let t = Instant::now();
        let u_band = self.band.diffuse(&sim.u).map_err(|e| at("diffusion: ", e))?;
        self.advected = Some(advect(&sim.grid, &self.band, &u_band).map_err(|e| at("advection: ", e))?);
        self.totals.advection_s += t.elapsed().as_secs_f64();
        Ok(())
    }
}
