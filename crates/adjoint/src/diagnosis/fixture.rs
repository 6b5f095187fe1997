//! A refitted candidate for the tests of what is done with a refit (plausibility, separation).

use super::effects::Probe;
use super::score::Candidate;
use cutfem::fem::Model;
use cutfem::scene::Scene;

impl Candidate {
    /// A candidate refitted to `model` in `scene` (Delta BIC -50, rms 0.01), for tests of what
    /// is done with a refit.
    pub(crate) fn refitted(effect: &str, scene: Scene, model: Model) -> Candidate {
        Candidate {
            effect: effect.into(),
            probe: Probe::Score,
            params: Vec::new(),
            score: 1.0,
            predicted_rms: 0.01,
            rms_after: Some(0.01),
            delta_bic: Some(-50.0),
            values: Vec::new(),
            suggestion: String::new(),
            error: None,
            frees: Vec::new(),
            model: Some(model),
            step: Vec::new(),
            x: Vec::new(),
            scene: Some(scene),
        }
    }
}
