//! `damping`: Rayleigh damping `D = a1 M + a2 K` (sec. 2.5) in the Newmark matrix and
//! right-hand side. Neutral: `a1 = a2 = 0` (fits start at [`crate::params::DAMPING_FLOOR`]
//! because both are fitted in log space). Adjoint: `dJ/da1`, `dJ/da2` in [`crate::backward`].

use super::{add_effect, short, DataContext, Effect, Judgement, Motion, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{DampingSection, Scene};

/// Rayleigh damping.
#[derive(Clone, Copy, Debug, Default)]
pub struct Damping;

impl Effect for Damping {
    fn name(&self) -> &'static str {
        "damping"
    }
    fn describe(&self) -> &'static str {
        "Rayleigh damping D = a1 M + a2 K"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::DampingMass, Param::DampingStiffness]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        scene.damping = Some(DampingSection {
            mass: 0.0,
            stiffness: 0.0,
        });
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        scene.damping = Some(DampingSection {
            mass: model.damping_mass,
            stiffness: model.damping_stiffness,
        });
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[damping]\nmass = {}\nstiffness = {}",
            short(model.damping_mass),
            short(model.damping_stiffness)
        )
    }
    fn judge(&self, model: &Model, motion: &Motion) -> Option<Judgement> {
        let (a1, a2) = (model.damping_mass, model.damping_stiffness);
        // the mass term on the rigid motion: a force a1 m per unit speed (a free body's drag)
        let mut j = super::super::plausible::terminal("mass damping", a1 * motion.mass, motion);
        if let Some(w) = motion.frequency.filter(|w| *w > 0.0) {
            j.implies = format!(
                "damping ratio {} at the recorded deformation's frequency {} rad/s (period {}); {}",
                short(a1 / (2.0 * w) + a2 * w / 2.0),
                short(w),
                short(std::f64::consts::TAU / w),
                j.implies
            );
        }
        Some(j)
    }
}
