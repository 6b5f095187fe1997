//! `drag`, reconstruction half: linear air drag, a traction `-c v` on the surface (one
//! parameter `c`, fitted in log space). Its physics (the damping matrix `c W`, `W` the nodes'
//! surface areas) and its `[drag]` section are the forward half,
//! [`cutfem::scene::effects::drag`]; the adjoint `dJ/dc = sum_t lam_t . W (u_t - u_{t+1})` is in
//! [`crate::backward`]. Neutral: `c = 0`; like the damping coefficients, the log coordinate
//! starts at [`crate::params::DAMPING_FLOOR`] and a diagnosis probes it by a score test there.
//!
//! Drag and Rayleigh mass damping both slow the motion; mass damping weighs each node by its
//! mass, drag by its surface area. A diagnosis tells them apart by how the slowing is
//! distributed over the body (interior against surface, thin against thick parts) and, at equal
//! fit, by the BIC's count of parameters (drag: 1, damping: 2).

use super::{add_effect, short, DataContext, Effect, Judgement, Motion, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::effects::drag::DragSection;
use cutfem::scene::Scene;

/// Linear air drag.
#[derive(Clone, Copy, Debug, Default)]
pub struct Drag;

impl Effect for Drag {
    fn name(&self) -> &'static str {
        "drag"
    }
    fn describe(&self) -> &'static str {
        "linear air drag: a traction -c v against the surface's velocity"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::Drag]
    }
    fn probe(&self) -> Probe {
        Probe::Score
    }
    fn switch_on(&self, scene: &mut Scene, _: &DataContext) -> Result<(), Error> {
        DragSection { coefficient: 0.0 }.set(scene);
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        if let Some(d) = &model.drag {
            DragSection {
                coefficient: d.coefficient,
            }
            .set(scene);
        }
    }
    fn suggestion(&self, model: &Model) -> String {
        format!(
            "[drag]\ncoefficient = {}",
            short(model.drag.as_ref().map_or(0.0, |d| d.coefficient))
        )
    }
    fn judge(&self, model: &Model, motion: &Motion) -> Option<Judgement> {
        // the force per unit speed on a rigid motion: c times the surface area
        let d = model.drag.as_ref()?;
        let area: f64 = d.weights.iter().sum();
        Some(super::super::plausible::terminal(
            "drag",
            d.coefficient * area,
            motion,
        ))
    }
}
