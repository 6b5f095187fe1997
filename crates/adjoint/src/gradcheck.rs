//! The adjoint gradient against finite differences of the whole simulation, per component of
//! every fitted parameter in physical units, over a sweep of steps with the Taylor remainder
//! test ([`crate::taylor`]): one fixed step can land across a kink of a piecewise-smooth cost
//! and cry wolf; the sweep says whether the gradient is verified at some scale and from which
//! scale the cost is not smooth.

use crate::fit::{get_physical, set_physical};
use crate::problem::Problem;
use crate::taylor::{analyse, Sample, Sweep};
use crate::Error;

/// One parameter component of a gradient check.
#[derive(Clone, Debug, PartialEq)]
pub struct GradCheck {
    /// the physical component
    pub name: String,
    /// the adjoint derivative
    pub adjoint: f64,
    /// the central difference at the best step of the sweep
    pub finite_difference: f64,
    /// the best step (in the component's units)
    pub step: f64,
    /// `|adjoint - fd| / max(|adjoint|, |fd|)` at the best step (0 when both vanish)
    pub rel_error: f64,
    /// the whole sweep: per-step agreement, remainders, orders, the verdict
    pub sweep: Sweep,
    /// steps whose evaluation failed (e.g. a damping pushed below 0), with the reason
    pub failed: Vec<(f64, String)>,
}

/// Compares the adjoint gradient in physical units with central differences of the whole
/// simulation, one component at a time, at the relative steps `rel_steps` (e.g.
/// [`crate::taylor::DECADES`]): step `rel * max(|value|, scale)` where `scale` is 1 for a value
/// of 0; a Poisson ratio's steps stay inside (0, 0.5); the stiffness field's coefficients (log
/// factors) are stepped in the coordinate itself, not below 1e-6. A step whose evaluation fails
/// is skipped and reported; a component without any successful step is an error.
pub fn gradcheck(problem: &mut Problem, rel_steps: &[f64]) -> Result<Vec<GradCheck>, Error> {
    let x0 = problem.x0();
    let model0 = problem.model_at(&x0);
    let (ev0, _, pg) = problem.gradient(&x0)?;
    let j0 = ev0.cost;
    let adjoint = problem.params.physical(&model0, &pg);
    let mut out = Vec::new();
    let labels = problem.params.labels();
    for (name, an) in adjoint {
        let mut samples = Vec::new();
        let mut failed = Vec::new();
        if name.starts_with("stiffness_field[") {
            // a coefficient (log factor): differences in the coordinate itself
            let k = labels
                .iter()
                .position(|l| *l == name)
                .ok_or_else(|| Error::invalid("field label"))?;
            let mut at = |d: f64| -> Result<f64, Error> {
                let mut x = x0.clone();
                x[k] += d;
                problem.evaluate(&x).map(|e| e.cost)
            };
            for &rel in rel_steps {
                let step = rel.max(1e-6);
                if samples.iter().any(|s: &Sample| s.step == step) {
                    continue;
                }
                match at(step).and_then(|p| Ok((p, at(-step)?))) {
                    Ok((plus, minus)) => samples.push(Sample { step, plus, minus }),
                    Err(e) => failed.push((step, e.to_string())),
                }
            }
        } else {
            let v = get_physical(&model0, &name).ok_or_else(|| {
                Error::Invalid(format!(
                    "--params: `{name}` cannot be stepped by the gradient check"
                ))
            })?;
            let mut cost_at = |val: f64| -> Result<f64, Error> {
                let mut m = model0.clone();
                set_physical(&mut m, &name, val);
                problem.evaluate_model(m).map(|e| e.cost)
            };
            for &rel in rel_steps {
                let mut step = rel * v.abs().max(if v.abs() > 0.0 { 0.0 } else { 1.0 });
                if name == "poisson" {
                    step = step.min(0.5 * (0.5 - v)).min(0.5 * v);
                }
                if samples.iter().any(|s: &Sample| s.step == step) {
                    continue;
                }
                match cost_at(v + step).and_then(|p| Ok((p, cost_at(v - step)?))) {
                    Ok((plus, minus)) => samples.push(Sample { step, plus, minus }),
                    Err(e) => failed.push((step, e.to_string())),
                }
            }
        }
        let sweep = analyse(j0, an, &samples).ok_or_else(|| {
            let why = failed
                .first()
                .map_or("no step".to_string(), |(h, e)| format!("step {h:e}: {e}"));
            Error::invalid(format!(
                "{name}: no step of the gradient check could be evaluated ({why})"
            ))
        })?;
        let best = &sweep.steps[sweep.best];
        out.push(GradCheck {
            name,
            adjoint: an,
            finite_difference: best.finite_difference,
            step: best.step,
            rel_error: best.rel_error,
            failed,
            sweep,
        });
    }
    Ok(out)
}
