//! `initial_velocity`: the body starts moving, `v(0) = v0 + w x (X - c)` with `c` the center
//! of mass. Neutral: `v0 = w = 0`. Adjoint: `dJ/dv(0)` at the end of the backward pass,
//! chained to `v0` and `w` ([`crate::backward::initial_velocity_adjoint`]).

use super::{add_effect, toml_vec, DataContext, Effect, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{InitialSection, Scene};

/// An initial linear and angular velocity.
#[derive(Clone, Copy, Debug, Default)]
pub struct InitialVelocity;

impl Effect for InitialVelocity {
    fn name(&self) -> &'static str {
        "initial_velocity"
    }
    fn describe(&self) -> &'static str {
        "an initial linear and angular velocity"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::InitialVelocity, Param::InitialAngularVelocity]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        scene.initial = Some(InitialSection::default());
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        scene.initial = Some(InitialSection {
            velocity: model.initial_velocity.to_array(),
            angular_velocity: model.initial_angular_velocity.to_array(),
        });
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[initial]\nvelocity = {}\nangular_velocity = {}",
            toml_vec(model.initial_velocity.to_array()),
            toml_vec(model.initial_angular_velocity.to_array())
        )
    }
}
