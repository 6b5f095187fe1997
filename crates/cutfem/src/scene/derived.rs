//! Scenes derived from a user's scene in code (an experiment-design candidate, a refit's scene,
//! the discretisation check's finer grid): an edit that removes a section must not leave an
//! effect that needs it, and the result goes through the same checks as a scene read from a
//! file, with errors naming the derived scene, not the user's.

use super::Scene;
use crate::error::Error;

impl Scene {
    /// The effects of `[model].effects` that need a section or a hold the scene no longer has:
    /// `ground` and `friction` without `[ground]`, `friction` without its own section, `clamp`
    /// without a `[[dirichlet]]` box, and the core effects without theirs.
    fn orphan_effects(&self) -> Vec<String> {
        let Some(m) = &self.model else {
            return Vec::new();
        };
        m.effects
            .iter()
            .filter(|e| match e.as_str() {
                "gravity" => self.gravity.is_none(),
                "damping" => self.damping.is_none(),
                "ground" => self.ground.is_none(),
                "initial_velocity" => self.initial.is_none(),
                "stiffness_field" => m.stiffness_field.is_none(),
                "friction" => self.ground.is_none() || !self.extensions.contains_key("friction"),
                "clamp" => self.dirichlet.is_empty() || !self.extensions.contains_key("clamp"),
                _ => false,
            })
            .cloned()
            .collect()
    }

    /// This scene, edited in code into `what` (e.g. "design candidate `throw`"), made
    /// consistent and checked as a scene read from a file would be: the effects whose section
    /// or hold the edit removed are switched off (with their sections: a thrown body has no
    /// clamp), then the scene's checks and the effects' own run, errors naming `what` and the
    /// scene it was derived from.
    pub fn derived(mut self, what: &str) -> Result<Scene, Error> {
        let orphans = self.orphan_effects();
        if let Some(m) = &mut self.model {
            m.effects.retain(|e| !orphans.contains(e));
        }
        for e in &orphans {
            self.extensions.remove(e);
        }
        self.checked(what)
    }

    /// This scene, edited in code into `what`, checked as a scene read from a file would be
    /// (nothing switched off: an edit that leaves it inconsistent is an error here, where it is
    /// made, naming `what` and the scene it was derived from).
    pub fn checked(self, what: &str) -> Result<Scene, Error> {
        let named = |e: Error| {
            let msg = e.to_string();
            let file = format!("{}: ", self.path.display());
            let msg = msg.strip_prefix(&file).unwrap_or(&msg).to_string();
            Error::Invalid(format!("{what} (derived from {}): {msg}", self.path.display()))
        };
        self.check(&self.path).map_err(named)?;
        super::effects::check_extensions(&self).map_err(named)?;
        Ok(self)
    }
}
