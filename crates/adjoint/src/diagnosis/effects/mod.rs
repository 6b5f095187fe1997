//! The effects of the model as first-class parts: what each one adds to the physics, its
//! parameters, the neutral value at which it is off, and how a diagnosis probes it when the
//! model lacks it.
//!
//! | effect | forward (cutfem) | adjoint (this crate) | parameters | neutral | probe |
//! |---|---|---|---|---|---|
//! | `gravity` | body force `M g` (eq. 2.6.2) | `backward`: `dJ/dg = dt sum_t M lam_t` | `gravity` (3) | `g = 0` | score |
//! | `damping` | Rayleigh `D = a1 M + a2 K` (sec. 2.5) | `backward`: `dJ/da1`, `dJ/da2` | `damping_mass`, `damping_stiffness` | `a1 = a2 = 0` | score |
//! | `ground` | soft springs at the cells' edge crossings (sec. 2.8, Alg. 5.5) | `local` contact adjoint | `ground` (2 tilts + height) | plane far below | initialized: lowest observed points |
//! | `corotation` | `R K (R^T x - X)` (eq. 4.4.6-4.4.9) | `local` polar-decomposition adjoint | none | linear elasticity | switch and compare |
//! | `stiffness_field` | per-cell factor on `E` | `backward`: per-cell `dJ/ds_e` | `stiffness_field` (coarse log factors) | all factors 1 | score |
//! | `initial_velocity` | `v(0) = v0 + w x (X - c)` | `backward`: `dJ/dv(0)` | `initial_velocity`, `initial_angular_velocity` | `0` | score |
//! | `drag` | traction `-c v` on the surface: damping matrix `c W`, `W = diag(A_i)` ([`drag`]) | `backward`: `dJ/dc = sum_t lam_t . W (u_t - u_t+1)` | `drag` (1) | `c = 0` | score |
//! | `clamp` | springs `-k P u`, `P_ij = int N_i N_j` over the held surface, instead of the rigid Nitsche hold ([`clamp`]) | `backward`: `dJ/dk = sum_t lam_t^T P (cu u_t - ck u_t+1)` | `clamp` (1) | `k = infinity` (rigid) | initialized: `k = (lambda + 2 mu) / h` |
//! | `friction` | tangential traction `-mu N_c P v_c` at each contact crossing, `N_c` its normal force ([`friction`]) | `local::friction_adjoint` per crossing | `friction` (1) | `mu = 0` | score (ground on only) |
//! | `wind` (extended) | external force `sum_d w_d A_i e_d` ([`wind`]) | `backward`: `dJ/dc_k = dt sum_t lam_t . F_k` | `external_force` (3) | `w = 0` | score |
//!
//! A **score** probe evaluates the gradient and the Gauss-Newton matrix of the effect's
//! parameters at the neutral value (the Lagrange-multiplier test, [`super::score`]). Effects
//! whose gradient vanishes at the neutral value get an honest alternative: the ground starts
//! from a plane through the lowest observed points (a plane far away has no contact, hence no
//! gradient), corotation (no parameter) is switched on and the cost compared.
//!
//! Adding an effect with its own scene section takes two files, one per half. The forward half
//! (its section and how it changes the model) is a [`cutfem::scene::effects::SectionEffect`]
//! in `cutfem/src/scene/effects/`, so that cutfem builds the complete model on its own
//! ([`cutfem::scene::Scene::build_model`], which also refuses sections and effect names no
//! effect claims). The reconstruction half is an [`Effect`] of the same name in a new file of
//! this folder, listed in [`catalogue`] or [`extended_catalogue`] (a test checks that the
//! extended catalogue and cutfem's effects name the same effects). An effect whose physics is
//! a nodal force linear in its parameters and independent of the state needs nothing else: its
//! forward half adds basis fields to the model's [`cutfem::fem::ExternalForce`], whose forward,
//! adjoint ([`crate::backward`]), tangent-linear and parameter (`external_force`) code is
//! generic. [`wind`] is the worked example; `docs/effects-tutorial.md` walks through it.
//!
//! [`catalogue`] holds the effects a diagnosis probes; [`extended_catalogue`] adds those it
//! does not (today `wind`: a uniform surface traction on a homogeneous body pulls almost like
//! gravity, and a probe of it would compete with gravity's). Scenes may switch on any effect
//! of the extended catalogue.

mod clamp;
mod corotation;
mod damping;
mod drag;
mod friction;
mod gravity;
mod ground;
mod initial_velocity;
mod stiffness_field;
pub mod wind;

pub use clamp::Clamp;
pub use corotation::Corotation;
pub use damping::Damping;
pub use drag::Drag;
pub use friction::Friction;
pub use gravity::Gravity;
pub use ground::GroundContact;
pub use initial_velocity::InitialVelocity;
pub use stiffness_field::StiffnessField;
pub use wind::Wind;

use super::plausible::{Judgement, Motion};
use crate::observations::Observations;
use crate::params::Param;
use crate::Error;
use cutfem::fem::Model;
use cutfem::scene::{ModelSection, Scene};

/// How a diagnosis scores an effect the model lacks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Probe {
    /// gradient and Gauss-Newton curvature at the neutral value (score test)
    Score,
    /// the same, at a starting value estimated from the data (the gradient vanishes at neutral)
    Initialized,
    /// no parameter: switch the effect on and compare the costs
    Switch,
}

/// What the data say, for effects that start from a data-driven value.
#[derive(Clone, Copy, Debug)]
pub struct DataContext<'a> {
    /// the observations
    pub observations: &'a Observations,
    /// the grid spacing of the body
    pub spacing: f64,
    /// the reference surface's vertices (the body before it moves)
    pub reference: &'a [[f64; 3]],
}

/// One physical effect of the model.
pub trait Effect: Send + Sync {
    /// Its name in `[model].effects`.
    fn name(&self) -> &'static str;
    /// One line of physics, for reports.
    fn describe(&self) -> &'static str;
    /// The parameters it adds to a fit when it is on (empty: none).
    fn params(&self) -> Vec<Param>;
    /// How a diagnosis probes it when the model lacks it.
    fn probe(&self) -> Probe;
    /// Whether it can be switched on in `scene` at all (the clamp needs a held region); a
    /// diagnosis probes only those that can.
    fn applies(&self, _scene: &Scene) -> bool {
        true
    }
    /// Switches the effect on in `scene` at its neutral value ([`Probe::Score`]), at a value
    /// estimated from `data` ([`Probe::Initialized`]), or simply on ([`Probe::Switch`]); writes
    /// the scene section it needs and adds it to `[model].effects`.
    fn switch_on(&self, scene: &mut Scene, data: &DataContext) -> Result<(), Error>;
    /// Writes the effect's values of `model` (e.g. after a fit) into `scene`'s section.
    fn write_back(&self, scene: &mut Scene, model: &Model);
    /// The TOML the user adds to the scene to switch it on with the values of `model`.
    fn suggestion(&self, model: &Model) -> String;
    /// What the fitted values of `model` imply physically over the fitted model's own `motion`,
    /// and why no body could do that, if so ([`super::plausible`]); `None`: nothing to judge.
    fn judge(&self, _model: &Model, _motion: &Motion) -> Option<Judgement> {
        None
    }
}

/// The effects of the vocabulary, in the interface's order.
pub fn catalogue() -> Vec<Box<dyn Effect>> {
    vec![
        Box::new(Gravity),
        Box::new(Damping),
        Box::new(GroundContact),
        Box::new(Corotation),
        Box::new(StiffnessField::default()),
        Box::new(InitialVelocity),
        Box::new(Drag),
        Box::new(Clamp),
        Box::new(Friction),
    ]
}

/// [`catalogue`] plus the effects a diagnosis does not probe: `wind` (module docs).
pub fn extended_catalogue() -> Vec<Box<dyn Effect>> {
    let mut all = catalogue();
    all.push(Box::new(Wind));
    all
}

/// The effect named `name` (of the [`extended_catalogue`]).
pub fn effect(name: &str) -> Option<Box<dyn Effect>> {
    extended_catalogue().into_iter().find(|e| e.name() == name)
}

/// Makes the scene's effect list explicit (`[model]` absent means "every section present plus
/// corotation") so that effects can be added to it.
pub fn explicit_effects(scene: &mut Scene) {
    if scene.model.is_none() {
        let effects = scene.effects();
        scene.model = Some(ModelSection {
            effects,
            stiffness_field: None,
        });
    }
}

/// Adds `name` to `[model].effects` (once).
pub fn add_effect(scene: &mut Scene, name: &str) {
    explicit_effects(scene);
    let m = scene.model.as_mut().expect("explicit");
    if !m.effects.iter().any(|e| e == name) {
        m.effects.push(name.to_string());
    }
}

/// Writes the values of every effect that is on, and the material, from `model` into `scene`.
pub fn write_back_all(scene: &mut Scene, model: &Model) {
    scene.material.young = model.young;
    scene.material.poisson = model.poisson;
    scene.material.density = model.density;
    for e in extended_catalogue() {
        if scene.effect_on(e.name()) {
            e.write_back(scene, model);
        }
    }
}

/// `[a, b, c]` with short numbers.
pub(crate) fn toml_vec(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", short(v[0]), short(v[1]), short(v[2]))
}

/// A number with 4 significant digits, without noise digits.
pub(crate) fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    if x.abs() < 1e-4 || x.abs() >= 1e6 {
        return format!("{x:.3e}");
    }
    let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    /// The reconstruction halves name exactly the effects the forward model knows.
    #[test]
    fn the_catalogue_and_the_forward_effects_name_the_same_effects() {
        let ours: Vec<&str> = super::extended_catalogue().iter().map(|e| e.name()).collect();
        assert_eq!(ours, cutfem::scene::effects::effect_names());
    }
}
