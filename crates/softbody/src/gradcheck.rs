//! `softbody gradcheck SCENE --observations OBS.csv [--params a,b] [--step S] [--json]`: the
//! adjoint gradient of the point-cloud cost against central differences of the whole
//! simulation, for every component of every fitted parameter, in physical units.
//!
//! Not one step but a sweep (decades 1e-1..1e-8 of each parameter's scale, plus `--step`) with
//! the Taylor remainder test (`adjoint::taylor`): per component the best agreement, the observed
//! orders of the first-order and the adjoint-corrected remainder, and whether the cost is
//! smooth at those scales. A piecewise-smooth cost (rays changing faces) is reported as not
//! smooth at a scale, not as a wrong gradient.

use crate::problem_args::{Loaded, ProblemArgs};
use adjoint::cost::Robust;
use adjoint::fit::{gradcheck, scene_problem, GradCheck};
use adjoint::taylor::{Smoothness, DECADES};
use serde_json::{json, Map, Value};

/// Arguments of `gradcheck`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub problem: ProblemArgs,
    /// A relative step added to the sweep of decades 1e-1..1e-8.
    #[arg(long)]
    pub step: Option<f64>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

fn opt(v: Option<f64>) -> Value {
    v.filter(|x| x.is_finite()).map_or(Value::Null, |x| json!(x))
}

/// The JSON of one component: interface.md's fields (at the best step) and the sweep.
fn row_json(r: &GradCheck) -> Value {
    let s = &r.sweep;
    let sweep: Vec<Value> = s
        .steps
        .iter()
        .map(|t| {
            json!({"step": t.step, "finite_difference": t.finite_difference, "rel_error": t.rel_error,
                   "remainder": t.remainder, "corrected_remainder": t.corrected_remainder,
                   "order": opt(t.order), "corrected_order": opt(t.corrected_order)})
        })
        .collect();
    json!({
        "adjoint": r.adjoint, "finite_difference": r.finite_difference, "rel_error": r.rel_error,
        "step": r.step,
        "smoothness": s.smoothness.name(),
        "verified": s.smoothness != Smoothness::NonSmooth,
        "order": opt(s.order), "corrected_order": opt(s.corrected_order),
        "smooth_range": s.smooth_range.map(|(lo, hi)| json!([lo, hi])),
        "non_smooth_from": opt(s.non_smooth_from),
        "verdict": s.summary,
        "sweep": sweep,
        "failed_steps": r.failed.iter().map(|(h, e)| json!({"step": h, "error": e})).collect::<Vec<_>>(),
    })
}

/// Runs `gradcheck`.
pub fn run(args: Args) -> Result<(), String> {
    let mut steps = DECADES.to_vec();
    if let Some(s) = args.step {
        if !(s > 0.0 && s < 0.1) {
            return Err(format!("--step: must lie in (0, 0.1), got {s}"));
        }
        steps.push(s);
        steps.sort_by(|a, b| b.total_cmp(a));
        steps.dedup();
    }
    let Loaded {
        scene,
        params,
        kind,
        observations: obs,
        eyes,
        ..
    } = args.problem.load()?;
    // the check needs the exact solve: a direct factorization instead of CG
    let mut problem = scene_problem(
        &scene,
        &obs,
        params,
        Robust::Squared,
        args.problem.steps,
        kind,
        &eyes,
    )?;
    problem.sim.solver.direct = true;
    adjoint::fit::check_observations(&mut problem, &obs, args.problem.observations()?)?;
    let rows = gradcheck(&mut problem, &steps)?;
    let worst = rows.iter().map(|r| r.rel_error).fold(0.0, f64::max);
    let non_smooth: Vec<&str> = rows
        .iter()
        .filter(|r| r.sweep.smoothness == Smoothness::NonSmooth)
        .map(|r| r.name.as_str())
        .collect();
    if args.json {
        let parameters: Map<String, Value> = rows.iter().map(|r| (r.name.clone(), row_json(r))).collect();
        crate::output::print_json(&json!({
            "parameters": parameters, "max_rel_error": worst, "solver": "sparse Cholesky",
            "steps": steps, "non_smooth": non_smooth,
        }))?;
    } else {
        crate::note!(
            "{:>28} {:>16} {:>16} {:>10} {:>8} {:>6} {:>6}  verdict",
            "parameter",
            "adjoint",
            "central diff.",
            "rel. err",
            "step",
            "order",
            "corr."
        );
        let o = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
        for r in &rows {
            crate::note!(
                "{:>28} {:>16.8e} {:>16.8e} {:>10.2e} {:>8.0e} {:>6} {:>6}  {}",
                r.name,
                r.adjoint,
                r.finite_difference,
                r.rel_error,
                r.step,
                o(r.sweep.order),
                o(r.sweep.corrected_order),
                r.sweep.summary
            );
        }
        crate::note!("largest relative error at the best step: {worst:.2e}");
        if !non_smooth.is_empty() {
            crate::note!(
                "not smooth at any step tried (the gradient is not verified there): {}",
                non_smooth.join(", ")
            );
        }
    }
    Ok(())
}
