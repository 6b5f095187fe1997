//! The discretisation check of `simulate --refine-check`, `fit` and `diagnose`
//! (`adjoint::refine`): the same model state at resolutions `r/2`, `r` and `2r`, with a progress
//! bar, a summary line and a warning on stderr, and its JSON.

use crate::progress;
use adjoint::refine::{refine_check_observed, RefineParams};
use cutfem::fem::{Grid, Model, Simulation};
use cutfem::scene::Scene;
use serde_json::{json, Value};

/// Runs the check of `model` on `grid` and reports it on stderr; its JSON (judged against
/// `noise` when known), or `{"error": why}` when it could not run (the command goes on: the
/// check is advice, not the result).
pub fn run(
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    params: &RefineParams,
    noise: Option<f64>,
    quiet: bool,
) -> Value {
    run_observed(scene, grid, model, params, noise, quiet, &mut |_, _| {})
}

/// [`run`], with `observe_fine` called on the `2r` run's frames
/// (`adjoint::refine::refine_check_observed`).
pub fn run_observed(
    scene: &Scene,
    grid: &Grid,
    model: &Model,
    params: &RefineParams,
    noise: Option<f64>,
    quiet: bool,
    observe_fine: &mut dyn FnMut(&Simulation, usize),
) -> Value {
    let bar = progress::bar(1, "refine check", quiet);
    let mut progress = |level: &str, step: usize, steps: usize| {
        bar.set_length(steps as u64);
        bar.set_position(step as u64);
        bar.set_message(level.to_string());
    };
    let result = refine_check_observed(scene, grid, model, params, &mut progress, observe_fine);
    bar.finish_and_clear();
    match result {
        Ok(check) => {
            crate::note!("{}", check.summary(noise));
            if let Some(w) = check.warning(noise) {
                crate::note!("warning: {w}");
            }
            check.to_json(noise)
        }
        Err(e) => {
            crate::note!("refine check skipped: {e}");
            json!({ "error": e.to_string() })
        }
    }
}
