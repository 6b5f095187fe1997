//! `softbody gradcheck SCENE --observations OBS.csv [--params a,b] [--step S] [--json]`: the
//! adjoint gradient of the point-cloud cost against central differences of the whole
//! simulation, for every component of every fitted parameter, in physical units.

use adjoint::cost::Robust;
use adjoint::fit::{gradcheck, scene_problem};
use adjoint::observations::Observations;
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use serde_json::{json, Map, Value};
use std::path::PathBuf;

/// Arguments of `gradcheck`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Observed surface points (CSV).
    #[arg(long)]
    pub observations: PathBuf,
    /// Parameters, comma separated (default: [fit].parameters, else young,poisson).
    #[arg(long)]
    pub params: Option<String>,
    /// Relative step of the central differences.
    #[arg(long, default_value_t = 1e-4)]
    pub step: f64,
    /// Override `[time].steps`.
    #[arg(long)]
    pub steps: Option<usize>,
    /// surface (distance to the simulated surface mesh, along the viewing rays when the cameras
    /// are known) | levelset (the thesis' phi(t)(x), eq. 5.4.4).
    #[arg(long, default_value = "surface")]
    pub cost: String,
    /// Camera eyes (JSON written by `observe` beside the CSV; default: OBS.cameras.json if it
    /// exists). Residuals are then measured along each point's viewing ray.
    #[arg(long)]
    pub cameras: Option<PathBuf>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `gradcheck`.
pub fn run(args: Args) -> Result<(), String> {
    if !(args.step > 0.0 && args.step < 0.1) {
        return Err(format!("--step: must lie in (0, 0.1), got {}", args.step));
    }
    let scene = Scene::load(&args.scene).map_err(|e| e.to_string())?;
    let section = crate::fit::fit_section(&scene)?;
    let names: Vec<String> = match (&args.params, &section.parameters) {
        (Some(p), _) => vec![p.clone()],
        (None, Some(p)) => p.clone(),
        (None, None) => vec!["young,poisson".into()],
    };
    let params = ParamSet::parse(&names).map_err(|e| format!("--params: {e}"))?;
    let kind: adjoint::fit::CostKind = args.cost.parse().map_err(|e| format!("--cost: {e}"))?;
    let obs = Observations::read_csv(&args.observations).map_err(|e| e.to_string())?;
    adjoint::fit::check_frames(&obs, &args.observations, args.steps.unwrap_or(scene.time.steps))?;
    let eyes = match &args.cameras {
        Some(p) => adjoint::fit::read_camera_eyes(p)?,
        None => {
            let p = adjoint::fit::cameras_path(&args.observations);
            if p.exists() {
                adjoint::fit::read_camera_eyes(&p)?
            } else {
                Vec::new()
            }
        }
    };
    // the check needs the exact solve: a direct factorization instead of CG
    let mut problem = scene_problem(&scene, &obs, params, Robust::Squared, args.steps, kind, &eyes)?;
    problem.sim.solver.direct = true;
    adjoint::fit::check_observations(&mut problem, &obs, &args.observations)?;
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
        println!(
            "{}",
            json!({"parameters": parameters, "max_rel_error": worst, "solver": "sparse Cholesky"})
        );
    } else {
        eprintln!(
            "{:>28} {:>16} {:>16} {:>10}",
            "parameter", "adjoint", "central diff.", "rel. err"
        );
        for r in &rows {
            eprintln!(
                "{:>28} {:>16.8e} {:>16.8e} {:>10.2e}",
                r.name, r.adjoint, r.finite_difference, r.rel_error
            );
        }
        eprintln!("largest relative error: {worst:.2e}");
    }
    Ok(())
}
