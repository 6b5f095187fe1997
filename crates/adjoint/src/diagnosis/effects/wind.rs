//! `wind`, reconstruction half: a uniform traction `w` (force per unit surface area, 3
//! parameters) on the body's surface. The tutorial effect of `docs/effects-tutorial.md`. Its
//! physics (the consistent nodal forces `f_i = A_i w`, a [`cutfem::fem::ExternalForce`] with 3
//! basis fields) and its `[wind]` section are the forward half,
//! [`cutfem::scene::effects::wind`]; the adjoint (`dJ/dw_d = dt sum_t lam_t . F_d`),
//! tangent-linear and parameter (`external_force`) code is generic. This file adds what a
//! reconstruction needs: the parameters, the neutral value `w = 0` at which a diagnosis would
//! probe it by a score test, writing a fitted traction back into the scene and the suggestion.
//!
//! Unlike gravity (`M g`, proportional to the mass of each node), the wind pulls on the
//! surface only: on a homogeneous body the two differ only in how the force is distributed,
//! which is why `wind` is in [`super::extended_catalogue`] and not probed by a diagnosis.

use super::{add_effect, toml_vec, DataContext, Effect, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::effects::wind::{traction, WindSection};
use cutfem::scene::Scene;

/// A uniform surface traction.
#[derive(Clone, Copy, Debug, Default)]
pub struct Wind;

impl Effect for Wind {
    fn name(&self) -> &'static str {
        "wind"
    }
    fn describe(&self) -> &'static str {
        "a uniform traction (force per unit area) on the surface"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::EXTERNAL_FORCE]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        WindSection { traction: [0.0; 3] }.set(scene);
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        if let Some(traction) = traction(model) {
            WindSection { traction }.set(scene);
        }
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[wind]\ntraction = {}",
            toml_vec(traction(model).unwrap_or_default())
        )
    }
}
