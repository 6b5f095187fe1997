//! `wind`: a uniform traction `w` (force per unit surface area, 3 parameters) on the body's
//! surface `Gamma`. The tutorial effect of `docs/effects-tutorial.md`; this file is its forward half (what
//! it adds to the model), `adjoint::diagnosis::effects::wind` its reconstruction half.
//!
//! **Physics.** A traction `t` on `Gamma` does the virtual work `int_Gamma t . delta_u ds`.
//! With the trilinear shape functions `N_i` of the grid (`u = sum_i N_i u_i`) the consistent
//! nodal force is
//!
//! ```text
//! f_i = int_Gamma N_i t ds = A_i w        (t = w uniform),
//! A_i = int_Gamma N_i ds = sum_{cells e of node i} w_b(e, i)    (eq. 4.2.3)
//! ```
//!
//! with `w_b(e, i)` the cut cell's boundary weights ([`crate::cutcell::CellIntegrals`]`::
//! boundary`, their sum over `i` is the surface area in the cell), so `sum_i A_i` is the area
//! of the surface. The traction acts on the reference surface and does not follow the motion
//! (a dead load): the force is independent of the state and linear in `w`,
//!
//! ```text
//! f = w_x F_x + w_y F_y + w_z F_z,     F_d[i] = A_i e_d,
//! ```
//!
//! which is exactly a [`crate::fem::ExternalForce`] with 3 basis fields. Its forward (added to
//! `f` every step, entering the Newmark right-hand side as `dt f`), adjoint
//! (`dJ/dw_d = dt sum_t lam_t . F_d`), tangent-linear and parameter code (`external_force`)
//! are generic: this file only builds the basis and maps its own `[wind]` section
//! ([`WindSection`], an extension section of the scene) to the model. Neutral value: `w = 0`; a diagnosis probes it by a score test there.
//!
//! Unlike gravity (`M g`, proportional to the mass of each node), the wind pulls on the
//! surface only: on a homogeneous body the two differ only in how the force is distributed,
//! which is why a diagnosis does not probe `wind`.

use super::SectionEffect;
use crate::error::Error;
use crate::fem::{ExternalForce, Grid, Model};
use crate::scene::Scene;
use gpumat::Vec3;
use std::sync::Arc;

/// The labels of the wind's coefficients in the model's external force.
pub const LABELS: [&str; 3] = ["wind.x", "wind.y", "wind.z"];

/// `[wind]`: the effect's scene section (read by [`Scene::extension`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct WindSection {
    /// force per unit surface area (world units)
    pub traction: [f64; 3],
}

impl WindSection {
    /// The scene's `[wind]`, checked (`None`: the scene has none).
    pub fn of(scene: &Scene) -> Result<Option<WindSection>, Error> {
        let w: Option<WindSection> = scene.extension("wind")?;
        if let Some(w) = &w {
            if !w.traction.iter().all(|t| t.is_finite()) {
                return Err(Error::format(&scene.path, "[wind].traction: must be finite"));
            }
        }
        Ok(w)
    }
    /// Writes it into `scene` as its `[wind]` section.
    pub fn set(self, scene: &mut Scene) {
        scene.set_section("wind", &self);
    }
}

/// Per degree of freedom, its share `A_i = sum_e w_b(e, i)` of the surface area.
pub fn node_areas(grid: &Grid) -> Vec<f64> {
    let mut area = vec![0.0; grid.dofs()];
    for c in &grid.cells {
        for (dof, wb) in c.dofs.iter().zip(c.integrals.boundary) {
            area[*dof as usize] += wb;
        }
    }
    area
}

/// The basis fields `F_d[i] = A_i e_d`, `d = x, y, z`.
pub fn basis(grid: &Grid) -> Vec<Vec<Vec3<f64>>> {
    let area = node_areas(grid);
    let axes = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    axes.iter()
        .map(|&e| area.iter().map(|&a| e * a).collect())
        .collect()
}

/// The traction of `model`'s external force (the coefficients labelled [`LABELS`]), if any.
pub fn traction(model: &Model) -> Option<[f64; 3]> {
    let e = model.external_force.as_ref()?;
    let at = |l: &str| e.labels.iter().position(|x| x == l).map(|k| e.coefficients[k]);
    Some([at(LABELS[0])?, at(LABELS[1])?, at(LABELS[2])?])
}

/// A uniform surface traction (forward half).
#[derive(Clone, Copy, Debug, Default)]
pub struct Wind;

impl SectionEffect for Wind {
    fn name(&self) -> &'static str {
        "wind"
    }
    fn apply(&self, scene: &Scene, grid: &Grid, model: &mut Model) -> Result<(), Error> {
        let w = WindSection::of(scene)?
            .ok_or_else(|| Error::Invalid("listed in [model].effects without a [wind] section".into()))?;
        let force = ExternalForce {
            basis: Arc::new(basis(grid)),
            coefficients: w.traction.to_vec(),
            labels: LABELS.map(String::from).to_vec(),
        };
        match &mut model.external_force {
            Some(e) => e.extend(&force),
            None => model.external_force = Some(force),
        }
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
        Scene::parse(&text, std::path::Path::new("wind.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn node_areas_sum_to_the_surface_area() {
        let grid = Grid::new(scene("").unwrap().body_sdf().unwrap()).unwrap();
        let total: f64 = node_areas(&grid).iter().sum();
        let exact = 4.0 * std::f64::consts::PI * 0.4 * 0.4;
        assert!((total / exact - 1.0).abs() < 0.02, "area {total} vs {exact}");
    }

    #[test]
    fn the_scene_section_becomes_an_external_force() {
        let s = scene("[wind]\ntraction = [1.0, 0.0, -2.0]\n").unwrap();
        assert!(s.effect_on("wind"));
        let grid = Grid::new(s.body_sdf().unwrap()).unwrap();
        let model = s.build_model(&grid).unwrap();
        let e = model.external_force.as_ref().expect("wind on");
        assert_eq!(e.labels, LABELS);
        assert_eq!(traction(&model), Some([1.0, 0.0, -2.0]));
        assert_eq!(e.basis[1][5].to_array()[1], node_areas(&grid)[5]);
        // listed but off: no force; listed without a section: an error naming the section
        let off = scene("[wind]\ntraction = [1.0, 0.0, 0.0]\n[model]\neffects = [\"corotation\"]\n").unwrap();
        assert!(off.build_model(&grid).unwrap().external_force.is_none());
        let model_err = |extra: &str| {
            let s = scene(extra).unwrap();
            s.build_model(&grid).unwrap_err().to_string()
        };
        let err = model_err("[model]\neffects = [\"wind\"]\n");
        assert!(err.contains("[wind]"), "{err}");
        // the section's keys are the effect's: a typo names the file, line and section
        let err = model_err("\n[wind]\ntractio = [1.0, 0.0, 0.0]\n");
        assert!(
            // the file said once (`dedupe_prefixes`)
            err.contains("wind.toml: wind: line 8: [wind]: unknown field `tractio`")
                && err.matches("wind.toml").count() == 1,
            "{err}"
        );
        // a non-finite number is refused with the scene, naming the key (every section alike)
        let err = scene("[wind]\ntraction = [1.0, 0.0, nan]\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("wind.toml: line 8: wind.traction[2]: not a finite number (nan)"),
            "{err}"
        );
    }

    /// A section or an effect name no effect claims is refused, naming the file and line.
    #[test]
    fn unknown_sections_and_effects_are_errors() {
        let grid = Grid::new(scene("").unwrap().body_sdf().unwrap()).unwrap();
        let model_err = |extra: &str| {
            let s = scene(extra).unwrap();
            s.build_model(&grid).unwrap_err().to_string()
        };
        let err = model_err("[gravty]\nacceleration = [0.0, -9.81, 0.0]\n");
        assert!(
            err.starts_with("wind.toml: line 7: unknown section [gravty]"),
            "{err}"
        );
        assert!(
            err.contains("effects with their own section: drag, clamp, friction, wind"),
            "{err}"
        );
        let err = model_err("[model]\neffects = [\"magic\"]\n");
        assert!(err.contains("model.effects: unknown effect `magic`"), "{err}");
        // a top-level key that is no section is refused by the scene parser itself
        let err = Scene::parse(
            "youngs = 3.0\n[body]\nresolution = 5\n",
            std::path::Path::new("w.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("line 1: unknown key `youngs`"), "{err}");
    }
}
