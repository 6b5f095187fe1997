//! `gravity`: the body force `M g` of a uniform field (eq. 2.6.2's `f`). Neutral: `g = 0`.
//! Its adjoint is `dJ/dg = dt sum_t sum_i m_i lam_i(t)` ([`crate::backward`]).

use super::{add_effect, toml_vec, DataContext, Effect, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{GravitySection, Scene};

/// Uniform gravity.
#[derive(Clone, Copy, Debug, Default)]
pub struct Gravity;

impl Effect for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }
    fn describe(&self) -> &'static str {
        "a uniform body force M g"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::Gravity]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        scene.gravity = Some(GravitySection {
            acceleration: [0.0; 3],
        });
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        scene.gravity = Some(GravitySection {
            acceleration: model.gravity.to_array(),
        });
    }
    fn suggestion(&self, model: &Model) -> String {
        format!("[gravity]\nacceleration = {}", toml_vec(model.gravity.to_array()))
    }
}
