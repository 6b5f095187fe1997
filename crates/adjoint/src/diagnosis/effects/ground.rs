//! `ground`: a soft ground plane `{n . x >= height}` with springs at the surface crossings of
//! the cells' edges (sec. 2.8, Alg. 5.5). Its adjoint is the contact adjoint of
//! [`crate::local`]. A plane far away touches nothing and has zero gradient, so a diagnosis
//! starts it from the data: the normal opposes gravity (or is `+y` without gravity) and the
//! plane passes through the lowest observed points (the 0.2% quantile of `n . p`, robust to a
//! few noisy points), or through the body's lowest reference point when that is lower (cameras
//! may not see the bottom; a plane must not cut the body at rest).

use super::{add_effect, short, toml_vec, DataContext, Effect, Judgement, Motion, Probe};
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{GroundSection, Scene};

/// Soft ground contact.
#[derive(Clone, Copy, Debug, Default)]
pub struct GroundContact;

/// Quantile of the observed heights the initial plane passes through.
const LOW_QUANTILE: f64 = 0.002;

impl Effect for GroundContact {
    fn name(&self) -> &'static str {
        "ground"
    }
    fn describe(&self) -> &'static str {
        "a soft ground plane the body cannot pass"
    }
    fn params(&self) -> Vec<Param> {
        vec![Param::Ground]
    }
    fn probe(&self) -> Probe {
        Probe::Initialized
    }
    fn switch_on(&self, scene: &mut Scene, data: &DataContext) -> Result<(), Error> {
        let g = if scene.effect_on("gravity") {
            scene.gravity.as_ref().map(|g| g.acceleration)
        } else {
            None
        };
        let normal = match g {
            Some(g) if g.iter().map(|x| x * x).sum::<f64>() > 0.0 => {
                let n = g.iter().map(|x| x * x).sum::<f64>().sqrt();
                g.map(|x| -x / n)
            }
            _ => [0.0, 1.0, 0.0],
        };
        let mut heights: Vec<f64> = data
            .observations
            .frames()
            .flat_map(|(_, pts)| pts.iter())
            .map(|p| (0..3).map(|d| p.position[d] * normal[d]).sum::<f64>())
            .collect();
        if heights.is_empty() {
            return Err(Error::invalid("ground: no observed points to place the plane"));
        }
        heights.sort_by(f64::total_cmp);
        let k = ((heights.len() as f64 * LOW_QUANTILE) as usize).min(heights.len() - 1);
        let body_low = data
            .reference
            .iter()
            .map(|p| (0..3).map(|d| p[d] * normal[d]).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        let old = scene.ground.clone();
        scene.ground = Some(GroundSection {
            normal,
            height: heights[k].min(body_low),
            stiffness: old.as_ref().and_then(|g| g.stiffness),
            softness: old.as_ref().and_then(|g| g.softness),
            scheme: old.map(|g| g.scheme).unwrap_or_default(),
        });
        add_effect(scene, self.name());
        Ok(())
    }
    fn write_back(&self, scene: &mut Scene, model: &Model) {
        if let (Some(s), Some(g)) = (scene.ground.as_mut(), model.ground.as_ref()) {
            s.normal = g.normal.to_array();
            s.height = g.height;
        }
    }
    fn suggestion(&self, model: &Model) -> String {
        match &model.ground {
            Some(g) => format!(
                "[ground]\nnormal = {}\nheight = {}",
                toml_vec(g.normal.to_array()),
                short(g.height)
            ),
            None => "[ground]".into(),
        }
    }
    fn judge(&self, model: &Model, motion: &Motion) -> Option<Judgement> {
        let g = model.ground.as_ref()?;
        let n = [g.normal.x, g.normal.y, g.normal.z];
        Some(super::super::plausible::plane(n, g.height, motion))
    }
}
