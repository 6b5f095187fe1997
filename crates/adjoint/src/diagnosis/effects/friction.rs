//! `friction`, reconstruction half: ground friction, a tangential traction `-mu N v_t` at the
//! contact, proportional to the normal force (one parameter `mu`, fitted in log space). Its
//! physics and its `[friction]` section are the forward half,
//! [`cutfem::scene::effects::friction`]; the adjoint per crossing is
//! [`crate::local::friction_adjoint`]. Neutral: `mu = 0`; like the drag, the log coordinate
//! starts at [`crate::params::DAMPING_FLOOR`] and a diagnosis probes it by a score test there.
//! It applies only to scenes with the ground on (a diagnosis names a missing ground first).
//!
//! Friction and damping both take energy out of a bouncing body; friction only while it touches
//! the ground and only along it: a body that lands sliding slows its sliding and starts to roll,
//! where mass damping or drag slow every motion all the time.

use super::{add_effect, short, DataContext, Effect, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::effects::friction::FrictionSection;
use cutfem::scene::Scene;

/// Ground friction.
#[derive(Clone, Copy, Debug, Default)]
pub struct Friction;

impl Effect for Friction {
    fn name(&self) -> &'static str {
        "friction"
    }
    fn describe(&self) -> &'static str {
        "ground friction: a tangential traction against the sliding, proportional to the contact force"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::Friction]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn applies(&self, scene: &Scene) -> bool {
        scene.effect_on("ground")
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        FrictionSection { coefficient: 0.0 }.set(scene);
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        if let Some(coefficient) = model.friction {
            FrictionSection { coefficient }.set(scene);
        }
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[friction]\ncoefficient = {}",
            short(model.friction.unwrap_or(0.0))
        )
    }
}
