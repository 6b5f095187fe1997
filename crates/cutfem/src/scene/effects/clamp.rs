//! `clamp`: an imperfect clamp, an elastic support of finite stiffness on the surface the
//! `[[dirichlet]]` boxes hold, in place of their rigid hold (one parameter, `k` in traction
//! per unit displacement). The forward half; `adjoint::diagnosis::effects::clamp` is its
//! reconstruction half.
//!
//! **Physics.** A real clamp, a gripper or a glued base is not rigid: the fixture and the
//! material squeezed in it give, so the held part moves a little with the load and a clamped
//! beam swings as if it were longer and softer at the root. The Robin condition
//! `sigma n = -k u` on the held surface `G` (a layer of springs, `k` in stress per length)
//! models it. Its virtual work `-int_G k u . delta_u ds` with the trilinear shape functions
//! gives the stiffness blocks
//!
//! ```text
//! K_ij += k P_ij I,      P_ij = int_G N_i N_j ds
//! ```
//!
//! over the held part of the surface, clipped to the boxes exactly as the rigid hold's Nitsche
//! terms and integrated by the same quadrature (eq. 4.4.13-4.4.17; [`crate::fem::NitscheFace`]:
//! the springs are the Nitsche block with `k` for its penalty and without its traction terms).
//! They replace the Nitsche terms: `k -> infinity` is a penalty hold, which tends to the rigid
//! one (error `O(1/k)`), and `k -> 0` frees the body. A lumped (diagonal) `P` would not: on a
//! cut cell its springs pin every corner of the held face's cell as `k` grows, a cell deeper
//! than the face (`tests/clamp.rs` measures both limits).
//!
//! **In the Newmark step** (eq. 2.6.2) the springs are part of `K`, Rayleigh's `a2` included
//! ([`crate::fem::Model::support`]). They do not scale with the stiffness field (they are the
//! fixture's, not the material's). The adjoint is
//! `dJ/dk = sum_t lam_t^T P (cu u_t - ck u_{t+1})` (`adjoint::backward`).

use super::SectionEffect;
use crate::error::Error;
use crate::fem::{Grid, Model};
use crate::scene::Scene;

/// `[clamp]`: the effect's scene section (read by [`Scene::extension`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ClampSection {
    /// the support's traction per unit displacement (stress per length, > 0)
    pub stiffness: f64,
}

impl ClampSection {
    /// The scene's `[clamp]`, checked (`None`: the scene has none).
    pub fn of(scene: &Scene) -> Result<Option<ClampSection>, Error> {
        let c: Option<ClampSection> = scene.extension("clamp")?;
        if let Some(c) = &c {
            if !(c.stiffness > 0.0 && c.stiffness.is_finite()) {
                return Err(Error::format(
                    &scene.path,
                    format!("[clamp].stiffness: must be finite and > 0, got {}", c.stiffness),
                ));
            }
        }
        Ok(c)
    }
    /// Writes it into `scene` as its `[clamp]` section.
    pub fn set(self, scene: &mut Scene) {
        scene.set_section("clamp", &self);
    }
}

/// The imperfect clamp (forward half).
#[derive(Clone, Copy, Debug, Default)]
pub struct Clamp;

impl SectionEffect for Clamp {
    fn name(&self) -> &'static str {
        "clamp"
    }
    fn apply(&self, scene: &Scene, _grid: &Grid, model: &mut Model) -> Result<(), Error> {
        let c = ClampSection::of(scene)?
            .ok_or_else(|| Error::Invalid("listed in [model].effects without a [clamp] section".into()))?;
        if model.dirichlet.is_empty() {
            return Err(Error::Invalid(
                "[clamp]: the scene has no [[dirichlet]] box whose hold it would soften".into(),
            ));
        }
        model.support = Some(c.stiffness);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HOLD: &str = "[[dirichlet]]\nmin = [-1.0, -1.0, -1.0]\nmax = [-0.3, 1.0, 1.0]\n";

    fn scene(extra: &str) -> Result<Scene, String> {
        let text = format!(
            "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 0.4 }}\nresolution = 10\n\
             [material]\nyoung = 1000.0\npoisson = 0.3\n{extra}"
        );
        Scene::parse(&text, std::path::Path::new("clamp.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn the_scene_section_becomes_springs_on_the_held_surface() {
        let s = scene(&format!(
            "{HOLD}[clamp]\nstiffness = 5e4\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n"
        ))
        .unwrap();
        assert!(s.effect_on("clamp"));
        let grid = Grid::new(s.body_sdf().unwrap()).unwrap();
        let model = s.build_model(&grid).unwrap();
        assert_eq!(model.support, Some(5e4));
        // the simulation holds the body by the springs: the held cells' blocks change with k
        let mut sim = crate::fem::Simulation::new(grid.clone(), model.clone()).unwrap();
        sim.solve_static().unwrap();
        let soft = sim.u.clone();
        let mut stiff = crate::fem::Simulation::new(
            grid.clone(),
            crate::fem::Model {
                support: Some(5e6),
                ..model
            },
        )
        .unwrap();
        stiff.solve_static().unwrap();
        let (a, b) = (
            soft.ex().cwise_squared_norm().max(),
            stiff.u.ex().cwise_squared_norm().max(),
        );
        assert!(a > 2.0 * b && b > 0.0, "soft springs sag more: {a} vs {b}");
        let off = scene(&format!(
            "{HOLD}[clamp]\nstiffness = 5e4\n[model]\neffects = [\"corotation\"]\n"
        ))
        .unwrap();
        assert!(off.build_model(&grid).unwrap().support.is_none());
        let err = |extra: &str| {
            scene(extra).and_then(|s| s.build_model(&grid).map(|_| ()).map_err(|e| e.to_string()))
        };
        for bad in ["0.0", "-1.0", "nan"] {
            let e = err(&format!("{HOLD}[clamp]\nstiffness = {bad}\n")).unwrap_err();
            assert!(
                e.contains("clamp.toml")
                    && (e.contains("[clamp].stiffness") || e.contains("clamp.stiffness")),
                "{e}"
            );
        }
        let e = err(&format!("{HOLD}[clamp]\nstiff = 1.0\n")).unwrap_err();
        assert!(e.contains("clamp.toml") && e.contains("stiff"), "{e}");
        let e = err("[model]\neffects = [\"clamp\"]\n").unwrap_err();
        assert!(e.contains("clamp.toml") && e.contains("[clamp]"), "{e}");
        let e = err("[clamp]\nstiffness = 1.0\n").unwrap_err();
        assert!(e.contains("clamp.toml") && e.contains("[[dirichlet]]"), "{e}");
    }
}
