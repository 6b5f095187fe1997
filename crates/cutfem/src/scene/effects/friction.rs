//! `friction`: ground friction, a tangential traction against the sliding at the contact,
//! proportional to the contact's normal force (one parameter `mu`, tangential traction per unit
//! normal traction per unit sliding speed, s/m). The forward half;
//! `adjoint::diagnosis::effects::friction` is its reconstruction half.
//!
//! **Physics.** A body that lands sliding or rolls on a surface is slowed by friction at the
//! contact. Coulomb's law `|f_t| <= mu_C |f_n|` with `f_t` against the sliding velocity is
//! non-smooth at zero sliding; its viscous regularisation `f_t = -mu_C |f_n| v_t / eps` (valid
//! while the sliding speed stays below `eps`, the regime of soft bodies that stick and roll
//! more than they skid) is smooth and linear in the velocity. With `mu = mu_C / eps`, per
//! surface crossing of a grid edge (the contact points of sec. 2.8):
//!
//! ```text
//! f_c = -mu N_c (I - n n^T) v_c,      N_c = -k S(d_c)  (the crossing's normal force)
//! ```
//!
//! **In the Newmark step** (eq. 2.6.2) the normal force is taken at the step's start (lagged)
//! and the sliding velocity over the step, `v_c = (u'_c - u_c) / dt`: `A += mu N_c w w^T (x) P`,
//! `b += mu N_c P u_c` ([`crate::fem::collision::add_friction_forces`]). Neutral value: `mu = 0`
//! (a fit in log space starts at the damping floor). The adjoint (`adjoint::local`) differentiates
//! `mu N_c(d(u_c)) lam_c . P (u_c - u'_c)` per crossing, through `N_c` also with respect to `u`
//! and the ground's plane.

use super::SectionEffect;
use crate::error::Error;
use crate::fem::{Grid, Model};
use crate::scene::Scene;

/// `[friction]`: the effect's scene section (read by [`Scene::extension`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionSection {
    /// tangential traction per unit normal traction per unit sliding speed (s/m, >= 0)
    pub coefficient: f64,
}

impl FrictionSection {
    /// The scene's `[friction]`, checked (`None`: the scene has none).
    pub fn of(scene: &Scene) -> Result<Option<FrictionSection>, Error> {
        let f: Option<FrictionSection> = scene.extension("friction")?;
        if let Some(f) = &f {
            if !(f.coefficient >= 0.0 && f.coefficient.is_finite()) {
                return Err(Error::format(
                    &scene.path,
                    format!(
                        "[friction].coefficient: must be finite and >= 0, got {}",
                        f.coefficient
                    ),
                ));
            }
        }
        Ok(f)
    }
    /// Writes it into `scene` as its `[friction]` section.
    pub fn set(self, scene: &mut Scene) {
        scene.set_section("friction", &self);
    }
}

/// Ground friction (forward half).
#[derive(Clone, Copy, Debug, Default)]
pub struct Friction;

impl SectionEffect for Friction {
    fn name(&self) -> &'static str {
        "friction"
    }
    fn apply(&self, scene: &Scene, _grid: &Grid, model: &mut Model) -> Result<(), Error> {
        let f = FrictionSection::of(scene)?
            .ok_or_else(|| Error::Invalid("listed in [model].effects without a [friction] section".into()))?;
        if model.ground.is_none() {
            return Err(Error::Invalid(
                "[friction]: ground friction needs the ground ([ground] and `ground` in [model].effects)"
                    .into(),
            ));
        }
        model.friction = Some(f.coefficient);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(extra: &str) -> Result<Scene, String> {
        let text = format!(
            "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.5, 0.0], radius = 0.4 }}\nresolution = 10\n\
             [material]\nyoung = 1000.0\npoisson = 0.3\n{extra}"
        );
        Scene::parse(&text, std::path::Path::new("friction.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn the_scene_section_becomes_the_model_s_friction() {
        let s = scene("[ground]\nheight = 0.0\n[friction]\ncoefficient = 0.5\n").unwrap();
        assert!(s.effect_on("friction"));
        let grid = Grid::new(s.body_sdf().unwrap()).unwrap();
        assert_eq!(s.build_model(&grid).unwrap().friction, Some(0.5));
        let off =
            scene("[ground]\nheight = 0.0\n[friction]\ncoefficient = 0.5\n[model]\neffects = [\"ground\"]\n")
                .unwrap();
        assert!(off.build_model(&grid).unwrap().friction.is_none());
        let err = |extra: &str| {
            scene(extra).and_then(|s| s.build_model(&grid).map(|_| ()).map_err(|e| e.to_string()))
        };
        let e = err("[ground]\nheight = 0.0\n[friction]\ncoefficient = -1.0\n").unwrap_err();
        assert!(
            e.contains("friction.toml: line 10: friction.coefficient: must be >= 0"),
            "{e}"
        );
        let e = err("[ground]\nheight = 0.0\n[friction]\ncoef = 1.0\n").unwrap_err();
        assert!(e.contains("friction.toml") && e.contains("coef"), "{e}");
        let e = err("[ground]\nheight = 0.0\n[model]\neffects = [\"friction\", \"ground\"]\n").unwrap_err();
        assert!(e.contains("friction.toml") && e.contains("[friction]"), "{e}");
        let e = err("[friction]\ncoefficient = 1.0\n").unwrap_err();
        assert!(
            e.contains("friction.toml") && e.contains("needs the ground"),
            "{e}"
        );
    }
}
