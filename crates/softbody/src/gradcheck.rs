//! `softbody gradcheck SCENE --observations OBS.csv [--params a,b] [--step S] [--json]`: the
//! adjoint gradient of the point-cloud cost against central differences of the whole
//! simulation, for every component of every fitted parameter, in physical units.

use crate::problem_args::{Loaded, ProblemArgs};
use adjoint::cost::Robust;
use adjoint::fit::{gradcheck, scene_problem};
use serde_json::{json, Map, Value};

/// Arguments of `gradcheck`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub problem: ProblemArgs,
    /// Relative step of the central differences.
    #[arg(long, default_value_t = 1e-4)]
    pub step: f64,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `gradcheck`.
pub fn run(args: Args) -> Result<(), String> {
    if !(args.step > 0.0 && args.step < 0.1) {
        return Err(format!("--step: must lie in (0, 0.1), got {}", args.step));
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
    adjoint::fit::check_observations(&mut problem, &obs, &args.problem.observations)?;
    let rows = gradcheck(&mut problem, args.step)?;
    let worst = rows.iter().map(|r| r.rel_error).fold(0.0, f64::max);
    if args.json {
        let parameters: Map<String, Value> = rows
            .iter()
            .map(|r| {
                (
                    r.name.clone(),
                    json!({"adjoint": r.adjoint, "finite_difference": r.finite_difference,
                           "rel_error": r.rel_error, "step": r.step}),
                )
            })
            .collect();
        crate::output::print_json(
            &json!({"parameters": parameters, "max_rel_error": worst, "solver": "sparse Cholesky"}),
        )?;
    } else {
        crate::note!(
            "{:>28} {:>16} {:>16} {:>10}",
            "parameter",
            "adjoint",
            "central diff.",
            "rel. err"
        );
        for r in &rows {
            crate::note!(
                "{:>28} {:>16.8e} {:>16.8e} {:>10.2e}",
                r.name,
                r.adjoint,
                r.finite_difference,
                r.rel_error
            );
        }
        crate::note!("largest relative error: {worst:.2e}");
    }
    Ok(())
}
