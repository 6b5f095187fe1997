//! `softbody fit SCENE --observations OBS.csv [--params a,b] [--optimizer X] [--iterations N]
//! [--out DIR] [--resume] [--json]`: parameter reconstruction with adjoint gradients.
//!
//! Every iteration is appended to `fit.log` (one JSON object per line) as soon as it
//! completes, so an interrupted fit loses nothing; `--resume` continues from the log's last
//! iteration. The report is written transactionally (`crate::out_dir`): while the fit runs the
//! log is in `DIR.tmp-<pid>`, which `--resume` reads when the run was killed. The report folder gets `fit.json` and PNG plots of the cost and the parameters per
//! iteration and of the rms per frame before and after. Every run is appended to the scene's
//! history file (`SCENE.history.jsonl`, `adjoint::diagnosis::history`).

use crate::problem_args::{Loaded, ProblemArgs};
use crate::progress;
use adjoint::cost::Robust;
use adjoint::diagnosis::history::{history_path, record, Entry};
use adjoint::fit::{check_observations, scene_problem};
use adjoint::optim::Optimizer;
use adjoint::problem::Evaluation;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `fit`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub problem: ProblemArgs,
    /// lbfgs | gd | gauss-newton (default: [fit].optimizer, else lbfgs).
    #[arg(long)]
    pub optimizer: Option<String>,
    /// Maximum iterations (default: [fit].iterations, else 30).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Report folder (default: out/<scene>-fit).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue the fit logged in the report folder.
    #[arg(long)]
    pub resume: bool,
    /// Huber loss threshold (world units) against outliers (default: squared distances).
    #[arg(long)]
    pub huber: Option<f64>,
    /// Skip the discretisation check (the fitted model again at twice and half the
    /// resolution, `adjoint::refine`).
    #[arg(long)]
    pub no_refine_check: bool,
    /// Fit K times: from the scene's start and from K - 1 seeded Latin-hypercube starts in the
    /// parameters' plausible box; reports every optimum and whether they agree (docs/study.md).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub starts: Option<u64>,
    /// Seed of the starts (`--starts`).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// After the fit, say which additional recording (dropped, squeezed, thrown, struck) would
    /// shrink the largest relative standard error most (docs/study.md).
    #[arg(long)]
    pub design: bool,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub use adjoint::fit::session::values_json;
use adjoint::fit::session::{run_logged, FitLog, LoggedFit};

/// `[{frame, rms, points, outside}]` of an evaluation.
pub fn per_frame_json(ev: &Evaluation) -> Value {
    Value::Array(
        ev.frames
            .iter()
            .map(|f| json!({"frame": f.frame, "rms": f.rms(), "points": f.count, "outside": f.outside}))
            .collect(),
    )
}

/// The fit's settings: flags over `[fit]` (or a study's `[study]`) over the defaults.
pub(crate) struct Settings {
    pub(crate) optimizer: Optimizer,
    pub(crate) iterations: usize,
    pub(crate) robust: Robust,
}

impl Settings {
    pub(crate) fn new(args: &Args, section: &cutfem::scene::FitSection) -> Result<Self, String> {
        let optimizer: Optimizer = args
            .optimizer
            .clone()
            .or(section.optimizer.clone())
            .unwrap_or_else(|| "lbfgs".into())
            .parse()
            .map_err(|e| format!("--optimizer: {e}"))?;
        let robust = match args.huber {
            Some(d) if d > 0.0 && d.is_finite() => Robust::Huber(d),
            Some(d) => return Err(format!("--huber: the threshold must be positive, got {d}")),
            None => Robust::Squared,
        };
        Ok(Self {
            optimizer,
            iterations: args.iterations.or(section.iterations).unwrap_or(30),
            robust,
        })
    }
}

/// What a fit found, for its report.
struct Outcome<'a> {
    args: &'a Args,
    optimizer: Optimizer,
    initial: &'a [(String, f64)],
    fitted: &'a [(String, f64)],
    std_errors: Option<Vec<(String, f64)>>,
    /// why there are none, when there are none
    std_errors_reason: Option<String>,
    ev_initial: &'a Evaluation,
    ev_final: &'a Evaluation,
    history: &'a [Value],
    info: &'a adjoint::optim::OptimInfo,
}

impl Outcome<'_> {
    /// `fit.json` but for the discretisation check, the timing and the files.
    fn json(&self) -> Value {
        let (ev_initial, ev_final) = (self.ev_initial, self.ev_final);
        json!({
            "scene": self.args.problem.scene,
            "observations": self.args.problem.observations,
            "optimizer": self.optimizer.to_string(),
            "parameters": values_json(self.fitted),
            "initial_parameters": values_json(self.initial),
            "standard_errors": self.std_errors.as_ref().map(|v| values_json(v)),
            "standard_errors_reason": self.std_errors_reason,
            "cost": {"initial": ev_initial.cost, "final": ev_final.cost},
            "rms": {"initial": ev_initial.rms(), "final": ev_final.rms()},
            "iterations": self.history.len().saturating_sub(1),
            "evaluations": self.info.evaluations,
            "termination": self.info.termination.to_string(),
            "converged": self.info.termination.is_converged(),
            "per_frame": {"initial": per_frame_json(ev_initial), "final": per_frame_json(ev_final)},
            "history": self.history,
        })
    }

    /// The one-line summary of the text output.
    fn line(&self) -> String {
        format!(
            "fit: {} after {} iterations ({}); rms {:.4e} -> {:.4e}",
            self.fitted
                .iter()
                .map(|(k, v)| format!("{k}={v:.6}"))
                .collect::<Vec<_>>()
                .join(" "),
            self.history.len().saturating_sub(1),
            self.info.termination,
            self.ev_initial.rms(),
            self.ev_final.rms()
        )
    }
}

/// The fitted model simulated at twice and half the resolution (`crate::refine_check`), its
/// surface differences against the observations' noise floor.
fn discretisation(
    scene: &cutfem::scene::Scene,
    problem: &adjoint::problem::Problem,
    model: &cutfem::fem::Model,
    frames: Vec<usize>,
    noise: Option<f64>,
    quiet: bool,
) -> Value {
    let params = adjoint::refine::RefineParams {
        steps: Some(problem.steps),
        frames: Some(frames),
        ..Default::default()
    };
    crate::refine_check::run(scene, &problem.sim.grid, model, &params, noise, quiet)
}

/// Runs `fit`.
pub fn run(args: Args) -> Result<(), String> {
    if crate::study_fit::is_study_file(&args.problem.scene) {
        return crate::study_fit::run(&args);
    }
    // several starts, the design advice, or several MPI ranks: the scene as a study of one
    // recording
    if args.starts.is_some() || args.design || crate::ensemble::launched() {
        return crate::study_fit::run_scene(&args);
    }
    let t0 = Instant::now();
    let loaded = args.problem.load()?;
    let fingerprint = loaded.fingerprint(crate::problem_args::steps(args.problem.steps, &loaded.scene)?);
    let Loaded {
        scene,
        section,
        params,
        kind,
        observations: obs,
        eyes,
        cameras: camera_file,
        inputs,
    } = loaded;
    let settings = Settings::new(&args, &section)?;
    if obs.is_empty() {
        return Err(format!(
            "{}: no observed points",
            args.problem.observations()?.display()
        ));
    }
    let target = args
        .out
        .clone()
        .unwrap_or_else(|| crate::simulate::default_out(&args.problem.scene, "fit"));
    let dir = crate::out_dir::OutDir::begin(&target, &inputs)?;
    let out = dir.path().to_path_buf();

    let mut problem = scene_problem(
        &scene,
        &obs,
        params,
        settings.robust,
        args.problem.steps,
        kind,
        &eyes,
    )?;
    // the problem's set: resolved against the model (the stiffness field's basis, the external
    // force's coefficient count), which the parsed one is not
    let params = problem.params.clone();
    let x_start = problem.x0();
    let initial_values = params.values(&problem.model_at(&x_start));

    // resume: continue from the last logged iteration (the earlier run's log: of a killed
    // run, else of the report)
    let mut x0 = x_start.clone();
    let earlier = args.resume.then(|| dir.resume_file("fit.log")).flatten();
    let mut log = FitLog::begin(
        &out.join("fit.log"),
        earlier.as_deref(),
        &initial_values.iter().map(|(k, _)| k.clone()).collect::<Vec<_>>(),
        &fingerprint,
        &mut x0,
    )?;

    // the start: rms per frame before fitting (and the observations' sanity)
    let ev_initial = check_observations(&mut problem, &obs, args.problem.observations()?)?;

    let bar = progress::bar(settings.iterations as u64 + 1, "fit", args.json);
    let fitted = run_logged(
        &mut problem,
        settings.optimizer,
        settings.iterations,
        &x0,
        &mut log,
        |iteration, cost| {
            bar.set_position(iteration as u64 + 1);
            bar.set_message(format!("fit {cost:.3e}"));
        },
    );
    bar.finish_and_clear();
    let LoggedFit {
        x: x_best,
        info,
        evaluation: ev_final,
        model,
    } = fitted.map_err(|e| match &earlier {
        // a resumed fit starts where the log ends: say which log, since that start was not
        // the scene's
        Some(log) => format!("{e} (resumed from the last entry of {})", log.display()),
        None => e.to_string(),
    })?;
    let final_values = params.values(&model);
    // uncertainty from the Gauss-Newton matrix at the result (one tangent-linear pass; not for
    // the many coefficients of a stiffness field)
    let unc = if x_best.len() <= 30 {
        adjoint::fit::uncertainty(&mut problem, &x_best, &ev_final)?
    } else {
        None
    };
    // "cannot estimate" is said with its reason, never as a number
    let std_errors_reason = unc.is_none().then(|| {
        if x_best.len() > 30 {
            format!("not computed for {} coordinates (at most 30)", x_best.len())
        } else {
            let n = ev_final.frames.iter().map(|f| f.informative).sum();
            adjoint::statistics::no_uncertainty_reason(n, x_best.len())
        }
    });
    // the noise floor at the result (as `diagnose` states it), and the discretisation share of
    // the final rms against it
    let cams = camera_file.map(|f| f.cameras()).transpose()?.unwrap_or_default();
    let (noise, method, noise_se) =
        adjoint::diagnosis::floor::floor_at(&mut problem, &model, &obs, &cams, &eyes, settings.robust)?;
    let discretisation = (!args.no_refine_check)
        .then(|| discretisation(&scene, &problem, &model, obs.frame_numbers(), noise, args.json));
    let history = log.into_history();
    let mut files = crate::fit_report::write(&out, &history, &initial_values, &ev_initial, &ev_final)?;
    if let (Some(u), 2) = (&unc, x_best.len()) {
        let path = out.join("uncertainty.png");
        crate::fit_report::uncertainty_picture(&path, u, &history)?;
        files["uncertainty"] = json!(path);
    }
    let outcome = Outcome {
        args: &args,
        optimizer: settings.optimizer,
        initial: &initial_values,
        fitted: &final_values,
        std_errors: unc.map(|u| u.labels.into_iter().zip(u.std_errors).collect()),
        std_errors_reason,
        ev_initial: &ev_initial,
        ev_final: &ev_final,
        history: &history,
        info: &info,
    };
    let mut summary = outcome.json();
    summary["discretisation"] = json!(discretisation);
    summary["noise_floor"] = json!({"value": noise, "method": method, "std_error": noise_se});
    summary["problem"] = json!(fingerprint);
    summary["seconds"] = json!(t0.elapsed().as_secs_f64());
    summary["out"] = json!(out);
    summary["files"] = files;
    // the scene's history of models (`diagnose` plots the rms over them)
    let mut entry = Entry::now("fit", scene.effects(), final_values.clone(), ev_final.rms());
    entry.observations = Some(obs.fingerprint());
    let hist = history_path(&args.problem.scene);
    let recorded = record(&hist, &entry);
    crate::output::warn_all(&recorded.warnings);
    summary["history_file"] = if recorded.written {
        json!(hist)
    } else {
        Value::Null
    };
    dir.finish(&mut summary, "fit.json")?;
    if args.json {
        crate::output::print_json(&summary)?;
    } else {
        crate::note!("{}", outcome.line());
        crate::note!("report: {}", target.display());
    }
    Ok(())
}
