//! `corotation`: corotated linear elasticity, `f = -R K (R^T x - X)` with the per-cell
//! rotation `R` of the iterative polar decomposition (eq. 4.4.6-4.4.9). Its adjoint is the
//! polar-decomposition adjoint of [`crate::local`]. It has no parameter, so a diagnosis
//! switches it on and compares the costs (a linear model is its neutral value).

use super::{add_effect, DataContext, Effect, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::Scene;

/// Corotated elasticity (large rotations without spurious growth).
#[derive(Clone, Copy, Debug, Default)]
pub struct Corotation;

impl Effect for Corotation {
    fn name(&self) -> &'static str {
        "corotation"
    }
    fn describe(&self) -> &'static str {
        "corotated elasticity: rotations produce no elastic force"
    }
    fn params(&self) -> Vec<Param> {
        Vec::new()
    }
    fn probe(&self) -> Probe {
        Probe::Switch
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, _: &mut Scene, _: &Model) {}
    fn suggestion(&self, _: &Model) -> String {
        "(no section: corotation has no parameter)".into()
    }
}
