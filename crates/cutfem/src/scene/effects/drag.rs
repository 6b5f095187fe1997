//! `drag`: linear air drag, a traction `t = -c v` opposing the surface's velocity (one parameter,
//! `c` in force per unit area per unit velocity). The forward half; `adjoint::diagnosis::effects::
//! drag` is its reconstruction half.
//!
//! **Physics.** A body moving slowly through a viscous medium (air around a soft body at
//! the speeds of a swing or a bounce, a tissue sample in a liquid) feels a traction against its
//! velocity. Linear (Stokes-like) drag takes it proportional to the local velocity,
//! `t = -c v`. Its virtual work `-int_Gamma c v . delta_u ds` with the trilinear shape functions,
//! the velocity lumped at the nodes like the mass, gives the nodal force
//!
//! ```text
//! f_i = -c A_i v_i,      A_i = int_Gamma N_i ds = sum_{cells e of node i} w_b(e, i)
//! ```
//!
//! (the surface-area weights of [`super::wind::node_areas`], eq. 4.2.3): a damping matrix
//! `c W`, `W = diag(A_i)`, beside Rayleigh's `a1 M + a2 K` (sec. 2.5). It acts on the reference
//! surface (small deformations). Rayleigh mass damping drags every node by its mass, drag only
//! the surface, by its area: on a solid body the interior is spared, and a thin part (large area
//! per mass) is slowed more than a thick one.
//!
//! **In the Newmark step** (eq. 2.6.2) it enters like `a1 M`: `A += c W`, `b += c W u`
//! ([`crate::fem::NodalDamping`]). Neutral value: `c = 0` (a fit in log space starts at the
//! damping floor); the adjoint is `dJ/dc = sum_t lam_t . W (u_t - u_{t+1})` and `c W lam` in
//! the displacement's adjoint (`adjoint::backward`).

use super::SectionEffect;
use crate::error::Error;
use crate::fem::{Grid, Model, NodalDamping};
use crate::scene::Scene;
use std::sync::Arc;

/// `[drag]`: the effect's scene section (read by [`Scene::extension`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DragSection {
    /// traction per unit velocity (force per unit area per unit velocity, >= 0)
    pub coefficient: f64,
}

impl DragSection {
    /// The scene's `[drag]`, checked (`None`: the scene has none).
    pub fn of(scene: &Scene) -> Result<Option<DragSection>, Error> {
        let d: Option<DragSection> = scene.extension("drag")?;
        if let Some(d) = &d {
            if !(d.coefficient >= 0.0 && d.coefficient.is_finite()) {
                return Err(Error::format(
                    &scene.path,
                    format!(
                        "[drag].coefficient: must be finite and >= 0, got {}",
                        d.coefficient
                    ),
                ));
            }
        }
        Ok(d)
    }
    /// Writes it into `scene` as its `[drag]` section.
    pub fn set(self, scene: &mut Scene) {
        scene.set_section("drag", &self);
    }
}

/// Linear air drag (forward half).
#[derive(Clone, Copy, Debug, Default)]
pub struct Drag;

impl SectionEffect for Drag {
    fn name(&self) -> &'static str {
        "drag"
    }
    fn apply(&self, scene: &Scene, grid: &Grid, model: &mut Model) -> Result<(), Error> {
        let d = DragSection::of(scene)?
            .ok_or_else(|| Error::Invalid("listed in [model].effects without a [drag] section".into()))?;
        model.drag = Some(NodalDamping {
            weights: Arc::new(super::wind::node_areas(grid)),
            coefficient: d.coefficient,
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(extra: &str) -> Result<Scene, String> {
        let text = format!(
            "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 0.4 }}\nresolution = 10\n\
             [material]\nyoung = 1000.0\npoisson = 0.3\n{extra}"
        );
        Scene::parse(&text, std::path::Path::new("drag.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn the_scene_section_becomes_a_nodal_damping_with_the_surface_areas() {
        let s = scene("[drag]\ncoefficient = 0.5\n").unwrap();
        assert!(s.effect_on("drag"));
        let grid = Grid::new(s.body_sdf().unwrap()).unwrap();
        let model = s.build_model(&grid).unwrap();
        let d = model.drag.as_ref().expect("drag on");
        assert_eq!(d.coefficient, 0.5);
        assert_eq!(*d.weights, super::super::wind::node_areas(&grid));
        let off = scene("[drag]\ncoefficient = 0.5\n[model]\neffects = [\"corotation\"]\n").unwrap();
        assert!(off.build_model(&grid).unwrap().drag.is_none());
        let err = |extra: &str| {
            scene(extra).and_then(|s| s.build_model(&grid).map(|_| ()).map_err(|e| e.to_string()))
        };
        let e = err("[drag]\ncoefficient = -1.0\n").unwrap_err();
        assert!(
            e.contains("drag.toml: line 8: drag.coefficient: must be >= 0"),
            "{e}"
        );
        let e = err("[drag]\ncoef = 1.0\n").unwrap_err();
        assert!(e.contains("drag.toml") && e.contains("coef"), "{e}");
        let e = err("[model]\neffects = [\"drag\"]\n").unwrap_err();
        assert!(e.contains("drag.toml") && e.contains("[drag]"), "{e}");
    }
}
