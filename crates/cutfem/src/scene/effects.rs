//! The forward half of the effects that have their own scene section: how the section changes
//! the model. The core effects ([`super::EFFECTS`]: gravity, damping, ground, corotation,
//! stiffness field, initial velocity) are built by [`Scene::to_model`] from the core sections;
//! an effect with its own section ([`wind`], [`drag`], [`clamp`], [`friction`]) implements [`SectionEffect`] and is listed
//! in [`section_effects`]. [`Scene::build_model`] applies every one the scene switches on, so
//! every command builds the complete model without the adjoint crate.
//!
//! What an effect adds for reconstruction (its parameters, how a diagnosis probes it, how a
//! fitted value is written back into the scene) lives in `adjoint::diagnosis::effects`; an
//! effect has the same name in both places.

pub mod clamp;
pub mod drag;
pub mod friction;
pub mod wind;

use super::Scene;
use crate::error::Error;
use crate::fem::{Grid, Model};

/// An effect with its own scene section, forward half.
pub trait SectionEffect: Send + Sync {
    /// Its name in `[model].effects` and the name of its section.
    fn name(&self) -> &'static str;
    /// Adds the effect's physics, as `scene`'s section describes it, to the model on `grid`
    /// (typically basis fields of [`Model::external_force`]). Called by
    /// [`Scene::build_model`] when the scene switches the effect on; the error need not name
    /// the scene file (the caller adds it).
    fn apply(&self, scene: &Scene, grid: &Grid, model: &mut Model) -> Result<(), Error>;
}

/// The effects with their own section.
pub fn section_effects() -> Vec<Box<dyn SectionEffect>> {
    vec![
        Box::new(drag::Drag),
        Box::new(clamp::Clamp),
        Box::new(friction::Friction),
        Box::new(wind::Wind),
    ]
}

/// Every effect name the forward model knows: the core ones ([`super::EFFECTS`]), then those
/// of [`section_effects`].
pub fn effect_names() -> Vec<&'static str> {
    let mut names = super::EFFECTS.to_vec();
    names.extend(section_effects().iter().map(|e| e.name()));
    names
}

/// Checks the scene's effects: every name in `[model].effects` and every extension section
/// must belong to a known effect ([`effect_names`]). The error names the file and, for a
/// section, its line.
pub fn check_extensions(scene: &Scene) -> Result<(), Error> {
    let known = effect_names();
    if let Some(m) = &scene.model {
        if let Some(e) = m.effects.iter().find(|e| !known.contains(&e.as_str())) {
            return Err(Error::format(
                &scene.path,
                format!(
                    "model.effects: unknown effect `{e}` (known: {})",
                    known.join(", ")
                ),
            ));
        }
    }
    if let Some((name, x)) = scene
        .extensions
        .iter()
        .find(|(name, _)| !known.contains(&name.as_str()))
    {
        let own: Vec<&str> = section_effects().iter().map(|e| e.name()).collect();
        return Err(Error::format(
            &scene.path,
            format!(
                "{}unknown section [{name}] (core sections: {}; effects with their own section: {})",
                x.location(),
                super::SECTIONS.join(", "),
                own.join(", ")
            ),
        ));
    }
    Ok(())
}
