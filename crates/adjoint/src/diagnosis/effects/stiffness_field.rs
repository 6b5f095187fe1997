//! `stiffness_field`: a heterogeneous Young's modulus, `E_e = E s_e` per cell with
//! `s_e = exp(sum_k w_ek c_k)` trilinear in log factors `c_k` on a coarse grid
//! ([`crate::params::FieldBasis`]). The forward scales each cell's element blocks, corotation
//! forces and Nitsche terms by `s_e`; the adjoint collects `dJ/ds_e` per cell
//! ([`crate::backward::PhysicalGradient::cell_scale`]). Neutral: all `c_k = 0` (homogeneous).

use super::{add_effect, DataContext, Effect, Judgement, Motion, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{ModelSection, Scene, StiffnessFieldSection};

/// A heterogeneous Young's modulus on a coarse grid of `cells` per axis.
#[derive(Clone, Copy, Debug)]
pub struct StiffnessField {
    /// coarse cells per axis when the scene does not say
    pub cells: [usize; 3],
}

impl Default for StiffnessField {
    fn default() -> Self {
        Self { cells: [2, 2, 2] }
    }
}

impl Effect for StiffnessField {
    fn name(&self) -> &'static str {
        "stiffness_field"
    }
    fn describe(&self) -> &'static str {
        "a heterogeneous Young's modulus (stiffer or softer regions)"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::StiffnessField]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        add_effect(scene, self.name());
        let m: &mut ModelSection = scene.model.as_mut().expect("explicit");
        if m.stiffness_field.is_none() {
            m.stiffness_field = Some(StiffnessFieldSection { cells: self.cells });
        }
        Ok(())
    }
    fn write_back(&self, _: &mut Scene, _: &Model) {
        // the coefficients live in the fit's result, not in the scene
    }
    fn suggestion(&self, _: &Model) -> String {
        format!(
            "[model]\nstiffness_field = {{ cells = [{}, {}, {}] }}",
            self.cells[0], self.cells[1], self.cells[2]
        )
    }
    fn judge(&self, model: &Model, _: &Motion) -> Option<Judgement> {
        Some(super::super::plausible::contrast(
            model.stiffness_scale.as_deref()?,
        ))
    }
}
