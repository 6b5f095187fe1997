//! `clamp`, reconstruction half: an imperfect clamp, springs of stiffness `k` (traction per unit
//! displacement) on the surface the `[[dirichlet]]` boxes hold instead of a rigid hold (one
//! parameter, fitted in log space). Its physics and its `[clamp]` section are the forward half,
//! [`cutfem::scene::effects::clamp`]; the adjoint
//! `dJ/dk = sum_t lam_t^T P (cu u_t - ck u_{t+1})` is in [`crate::backward`].
//!
//! **Neutral value and probe.** The effect is off at `k = infinity` (the rigid hold), where a
//! log coordinate cannot sit, and a stiff start does not work either: the springs' effect on
//! the motion is a sigmoid in `log k`, flat where they are much stiffer than the body, so a
//! score there is near zero whatever the data (measured: a hidden `k = 2e4` on the torus
//! scored as noise from a start 100 times stiffer). The probe starts at the springs of one
//! cell of the body's own material, `k0 = (lambda + 2 mu) / h` (a layer of thickness `h`
//! compressed by `u` pushes back `(lambda + 2 mu) u / h`), in the middle of the sigmoid, and
//! scores the gradient of `log k` there ([`Probe::Initialized`]: the candidate's cost at
//! `k0` already differs from the rigid base fit; the quadratic step goes either way). It
//! applies only to scenes with a `[[dirichlet]]` box.
//!
//! A soft clamp lets a cantilever swing lower and slower, as a softer material would; it differs
//! from a lower Young's modulus by where the compliance sits (at the root: the held part moves,
//! the deflection's shape along the body changes) and a diagnosis tells them apart by the fit
//! of that shape.

use super::{add_effect, short, DataContext, Effect, Judgement, Motion, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::effects::clamp::ClampSection;
use cutfem::scene::Scene;

/// The probe's start `k0` in units of `(lambda + 2 mu) / h` (module docs).
pub const START_FACTOR: f64 = 1.0;

/// An imperfect clamp.
#[derive(Clone, Copy, Debug, Default)]
pub struct Clamp;

impl Effect for Clamp {
    fn name(&self) -> &'static str {
        "clamp"
    }
    fn describe(&self) -> &'static str {
        "imperfect clamp: the held surface on springs of finite stiffness, not held rigidly"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::Clamp]
    }
    fn probe(&self) -> Probe {
        Probe::Initialized
    }
    fn applies(&self, scene: &Scene) -> bool {
        !scene.dirichlet.is_empty()
    }
    fn switch_on(&self, scene: &mut Scene, data: &DataContext) -> Result<(), Error> {
        let (young, nu) = (scene.material.young, scene.material.poisson);
        let p_modulus = young * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let stiffness = START_FACTOR * p_modulus / data.spacing;
        ClampSection { stiffness }.set(scene);
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        if let Some(stiffness) = model.support {
            ClampSection { stiffness }.set(scene);
        }
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[clamp]\nstiffness = {}",
            short(model.support.unwrap_or(f64::INFINITY))
        )
    }
    fn judge(&self, model: &Model, motion: &Motion) -> Option<Judgement> {
        let k = model.support?;
        let (lambda, mu) = model.lame();
        Some(super::super::plausible::held(
            &model.dirichlet,
            k,
            lambda + 2.0 * mu,
            motion,
        ))
    }
}
