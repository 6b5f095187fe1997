//! `softbody diagnose SCENE --observations OBS.csv [--out DIR] [--json]`: fits the model as
//! given, shows where it fails and which effect is missing (`adjoint::diagnosis`).
//!
//! The report folder gets `diagnosis.json` (interface.md fields plus `verdict`, `per_camera`,
//! `direction`, `fitted`, `files`) and the pictures of `diagnose_report`. Every run is appended
//! to the scene's history file (`SCENE.history.jsonl`), whose rms over the user's successive
//! models is plotted.

use crate::problem_args::{Loaded, ProblemArgs};
use crate::progress;
use adjoint::cost::Robust;
use adjoint::diagnosis::history::{self, Entry};
use adjoint::diagnosis::{diagnose, DiagnoseParams, Diagnosis, Setup};
use adjoint::fit::CostKind;
use adjoint::observations::Observations;
use adjoint::observe::DepthCamera;
use adjoint::params::ParamSet;
use cutfem::fem::collision::GroundPush;
use cutfem::scene::Scene;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub problem: ProblemArgs,
    /// Report folder (default: out/<scene>-diagnose).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Gauss-Newton iterations of the fit as given.
    #[arg(long, default_value_t = 12)]
    pub iterations: usize,
    /// Candidates confirmed by a short refit.
    #[arg(long, default_value_t = 4)]
    pub refits: usize,
    /// Skip the discretisation check (the fitted model again at twice and half the
    /// resolution, `adjoint::refine`).
    #[arg(long)]
    pub no_refine_check: bool,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// A diagnosis to run and report.
pub struct Job<'a> {
    /// the scene (the model as given)
    pub scene: &'a Scene,
    /// its file (the history file lies beside it)
    pub scene_path: &'a Path,
    /// the observations
    pub observations: &'a Observations,
    /// camera eyes
    pub eyes: &'a [[f64; 3]],
    /// cameras with intrinsics
    pub cameras: &'a [DepthCamera],
    /// fitted parameters of the model as given
    pub params: ParamSet,
    /// settings
    pub settings: DiagnoseParams,
    /// report folder (transactional: written into its temporary folder)
    pub out: &'a crate::out_dir::OutDir,
    /// no progress bar
    pub quiet: bool,
    /// history entry's command
    pub command: &'a str,
    /// estimate the discretisation share of the rms (`adjoint::refine`)
    pub refine_check: bool,
}

/// Runs a diagnosis, writes its report and history entry; returns it and its JSON.
pub fn run_job(job: Job) -> Result<(Diagnosis, Value), String> {
    let t0 = Instant::now();
    let out = job.out.path();
    let setup = Setup {
        observations: job.observations,
        eyes: job.eyes,
        cameras: job.cameras,
        robust: Robust::Squared,
        steps: None,
        reach: None,
    };
    let bar = progress::bar(1, "diagnose", job.quiet);
    // wall seconds per stage: each progress message starts a stage
    let mut stages: Vec<(String, Instant)> = Vec::new();
    let mut d = diagnose(
        job.scene,
        &setup,
        job.params,
        &job.settings,
        &mut |stage, done, total| {
            stages.push((stage.to_string(), Instant::now()));
            bar.set_length(total as u64);
            bar.set_position(done as u64);
            bar.set_message(stage.to_string());
        },
    )?;
    bar.finish_and_clear();

    let sim = job.scene.build_simulation().map_err(|e| e.to_string())?;
    let mut discretisation = None;
    if job.refine_check {
        // the model's own error: the discretisation share of the rms (`adjoint::refine`)
        let params = adjoint::refine::RefineParams {
            frames: Some(job.observations.frame_numbers()),
            ..Default::default()
        };
        stages.push(("discretisation check".into(), Instant::now()));
        // the refine check's 2r run of the model as given also serves the persistence check
        // below: its residuals against the observations are gathered as it runs
        let fine_setup = Setup { reach: None, ..setup };
        let steps = job.scene.time.steps;
        let share = d.missing_effect.is_some() && d.fitted_scene.time.steps == steps;
        let mut finer = adjoint::diagnosis::FinerRun::new(&fine_setup);
        let mut v = crate::refine_check::run_observed(
            job.scene,
            &sim.grid,
            &d.model,
            &params,
            d.noise_floor,
            job.quiet,
            &mut |s, t| {
                if share {
                    finer.observe(s, t)
                }
            },
        );
        // discretisation is not missing physics: the named effect's improvement must persist
        // on the grid of twice the resolution (`adjoint::diagnosis::discretisation`)
        if d.missing_effect.is_some() {
            stages.push(("persistence at 2r".into(), Instant::now()));
            let fine = 2.0 * d.fitted_scene.resolution().map_err(|e| e.to_string())?;
            let given = finer.rms(steps);
            match adjoint::diagnosis::persistence(&fine_setup, &d, &sim.grid, fine, &job.settings, given) {
                Ok(Some(p)) => {
                    let withdrew = adjoint::diagnosis::weigh_discretisation(&mut d, &p);
                    crate::note!(
                        "at resolution {fine}: {} rms {:.4e} -> {:.4e} (Delta BIC {:.1}){}",
                        p.effect,
                        p.rms,
                        p.rms_after,
                        p.delta_bic,
                        if withdrew {
                            ": withdrawn, the improvement does not persist"
                        } else {
                            ""
                        }
                    );
                    v["persistence"] = p.to_json();
                    v["withdrew"] = serde_json::Value::from(withdrew);
                }
                // the guard fails closed: a named effect it could not weigh is unverified
                Ok(None) => {
                    let reason = "the named effect has no refitted model to carry to the finer grid";
                    adjoint::diagnosis::mark_unverified(&mut d, fine, reason);
                    v["persistence"] = json!({ "error": reason });
                }
                Err(e) => {
                    crate::note!("persistence check failed: {e}");
                    adjoint::diagnosis::mark_unverified(&mut d, fine, &e.to_string());
                    v["persistence"] = json!({ "error": e.to_string() });
                }
            }
        }
        discretisation = Some(v);
    }
    stages.push(("report".into(), Instant::now()));
    let hist_path = history::history_path(job.scene_path);
    let mut entry = Entry::now(job.command, d.effects.clone(), d.fitted.clone(), d.rms);
    entry.noise_floor = d.noise_floor;
    entry.missing_effect = d.missing_effect.clone();
    entry.observations = Some(job.observations.fingerprint());
    let recorded = history::record(&hist_path, &entry);
    crate::output::warn_all(&recorded.warnings);
    let entries = recorded.entries;

    // pictures
    let mut sim = sim;
    let (reference, worst) =
        adjoint::diagnosis::residuals::surfaces_at(&mut sim, d.model.clone(), d.worst_frame)?;
    let gravity = job
        .scene
        .effect_on("gravity")
        .then(|| d.model.gravity.to_array())
        .filter(|g| g.iter().any(|v| *v != 0.0));
    let inputs = crate::diagnose_report::PictureInputs {
        reference: &reference,
        worst: &worst,
        gravity,
        history: &entries,
    };
    let pictures = crate::diagnose_report::write_pictures(out, &d, &inputs)?;
    let hist = recorded.written.then_some(hist_path.as_path());
    let mut summary = summary_json(&d, &pictures, hist, t0.elapsed().as_secs_f64());
    summary["stage_seconds"] = stage_seconds(&stages, Instant::now());
    if let Some(v) = discretisation {
        summary["discretisation"] = v;
    }
    job.out.publish(&mut summary);
    let path = out.join("diagnosis.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary).expect("json"))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((d, summary))
}

/// A candidate's row of the printed table; one whose probe or refit failed shows its error in
/// place of the numbers it has not got.
pub fn candidate_row(c: &adjoint::diagnosis::score::Candidate) -> String {
    if let Some(e) = &c.error {
        return format!("{:<18} could not be checked: {e}", c.effect);
    }
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4e}"));
    format!(
        "{:<18} {:>12.4e} {:>12} {:>12} {:>12}",
        c.effect,
        c.score,
        opt(Some(c.predicted_rms).filter(|p| p.is_finite())),
        opt(c.rms_after),
        c.delta_bic.map_or("-".to_string(), |v| format!("{v:.1}"))
    )
}

/// The JSON of a diagnosis (interface.md fields first).
pub fn summary_json(d: &Diagnosis, pictures: &[PathBuf], history: Option<&Path>, seconds: f64) -> Value {
    let candidates: Vec<Value> = d
        .candidates
        .iter()
        .map(|c| {
            json!({
                "effect": c.effect,
                "score": finite(c.score),
                "rms_after": c.rms_after,
                "predicted_rms": finite(c.predicted_rms),
                "delta_bic": c.delta_bic,
                "probe": c.probe,
                "parameters": c.params,
                "values": crate::fit::values_json(&c.values),
                "suggestion": c.suggestion,
                "error": c.error,
                "frees": crate::fit::values_json(&c.frees),
            })
        })
        .collect();
    json!({
        "rms": d.rms,
        "noise_floor": d.noise_floor,
        "noise_floor_method": d.noise_floor_method,
        "noise_floor_std_error": d.noise_floor_std_error,
        "on_bounds": d.on_bounds.iter().map(|(p, v, side)| json!({"parameter": p, "value": v, "bound": side})).collect::<Vec<_>>(),
        "ground_push": d.ground_push.as_ref().map(|(p, hovers)| ground_push_json(p, *hovers)),
        "per_frame": d.per_frame.iter().map(|(f, r, n)| json!({"frame": f, "rms": r, "points": n})).collect::<Vec<_>>(),
        "regions": d.regions,
        "candidates": candidates,
        "missing_effect": d.missing_effect,
        "alternatives": d.alternatives,
        "separation": d.separation.as_ref().map(|s| json!({
            "effects": s.effects, "motion": s.motion, "what": s.what,
            "difference": finite(s.difference), "recorded": finite(s.recorded),
        })),
        "plausibility": d.plausibility,
        "verdict": d.verdict,
        "unverified": d.unverified,
        "unchecked": adjoint::diagnosis::failed(&d.candidates).map(|(effect, error)| json!({"effect": effect, "error": error})).collect::<Vec<_>>(),
        "effects": d.effects,
        "fitted": crate::fit::values_json(&d.fitted),
        "rms_start": d.rms_start,
        "per_camera": d.per_camera.iter().map(|(c, r, n)| json!({"camera": c, "rms": r, "points": n})).collect::<Vec<_>>(),
        "worst_frame": d.worst_frame,
        "direction": d.direction,
        "history": history,
        "files": pictures,
        "seconds": seconds,
    })
}

/// The JSON of where the ground pushed over a run (`GroundPush`): the force-weighted mean
/// distance of the push from the plane, the share of it on points above the plane, and whether
/// the contact law holds the body off the plane.
pub fn ground_push_json(push: &GroundPush, hovers: bool) -> Value {
    json!({
        "mean_distance": push.mean_distance(),
        "share_above_plane": push.share_above(),
        "hovers": hovers,
    })
}

/// The warning for a ground that holds the body off the plane.
pub fn hover_note(push: &GroundPush) -> String {
    format!(
        "the ground's contact law holds the body off the plane: its push acted {:.3e} above the \
         plane on average ({:.0}% of it on points not touching), the softmin law's push before \
         contact; `[ground] scheme = \"penalty\"` (stiffness per unit area) has none \
         (docs/simulation.md)",
        push.mean_distance().unwrap_or(0.0),
        100.0 * push.share_above()
    )
}

/// `[{"stage", "seconds"}]` from the stages' start times, the last one ending at `end`.
fn stage_seconds(stages: &[(String, Instant)], end: Instant) -> Value {
    let ends = stages.iter().skip(1).map(|s| s.1).chain(std::iter::once(end));
    Value::Array(
        stages
            .iter()
            .zip(ends)
            .map(|((name, start), stop)| json!({"stage": name, "seconds": (stop - *start).as_secs_f64()}))
            .collect(),
    )
}

fn finite(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

/// Runs `diagnose`.
pub fn run(args: Args) -> Result<(), String> {
    if crate::study_fit::is_study_file(&args.problem.scene) {
        return crate::study_diagnose::run(&args);
    }
    let ready = prepare(&args.problem)?;
    let target = args
        .out
        .clone()
        .unwrap_or_else(|| crate::simulate::default_out(&args.problem.scene, "diagnose"));
    let out = crate::out_dir::OutDir::begin(&target, &ready.loaded.inputs)?;
    let (d, summary) = diagnose_ready(ready, &args, &args.problem.scene, &out)?;
    out.commit()?;
    if args.json {
        crate::output::print_json(&summary)?;
    } else {
        print_text(&d);
        crate::note!("report: {}", target.display());
    }
    Ok(())
}

/// A scene and its observations read and checked for a diagnosis, before anything is written.
pub struct Ready {
    loaded: Loaded,
    cameras: Vec<DepthCamera>,
}

/// Reads and checks what `problem` names ([`ProblemArgs::load`]; the surface cost only, at
/// least one observed point; the simulation builds and the observations are within reach,
/// [`Loaded::check_start`]): everything is checked before any work.
pub fn prepare(problem: &ProblemArgs) -> Result<Ready, String> {
    let loaded = problem.load()?;
    if loaded.kind != CostKind::Surface {
        return Err("--cost: diagnose measures distances to the simulated surface (--cost surface)".into());
    }
    if loaded.observations.is_empty() {
        return Err(format!(
            "{}: no observed points",
            problem.observations()?.display()
        ));
    }
    loaded.check_start(problem.observations()?, problem.steps)?;
    let cameras = match &loaded.cameras {
        Some(f) => f.cameras()?,
        None => Vec::new(),
    };
    Ok(Ready { loaded, cameras })
}

/// Diagnoses what [`prepare`] read (the scene file `scene_path`) into `out`.
pub fn diagnose_ready(
    ready: Ready,
    args: &Args,
    scene_path: &Path,
    out: &crate::out_dir::OutDir,
) -> Result<(Diagnosis, Value), String> {
    let settings = DiagnoseParams {
        fit_iterations: args.iterations,
        refits: args.refits,
        ..DiagnoseParams::default()
    };
    let l = ready.loaded;
    run_job(Job {
        scene: &l.scene,
        scene_path,
        observations: &l.observations,
        eyes: &l.eyes,
        cameras: &ready.cameras,
        params: l.params,
        settings,
        out,
        quiet: args.json,
        command: "diagnose",
        refine_check: !args.no_refine_check,
    })
}

/// The diagnosis for a reader, on stderr.
pub fn print_text(d: &Diagnosis) {
    crate::note!(
        "model as given ({}): rms {:.4e} (start {:.4e}), noise floor {} ({}{})",
        d.effects.join(", "),
        d.rms,
        d.rms_start,
        d.noise_floor.map_or("unknown".into(), |f| format!("{f:.4e}")),
        d.noise_floor_method,
        d.noise_floor_std_error
            .map_or(String::new(), |e| format!(", standard error {e:.1e}"))
    );
    for (p, v, side) in &d.on_bounds {
        crate::note!(
            "its fit ended with {p} = {v:.4} on the {side} bound of the plausible range: a wrong \
             model often pushes a parameter there"
        );
    }
    if let Some((push, true)) = &d.ground_push {
        crate::note!("{}", hover_note(push));
    }
    let worst = d.per_frame.iter().find(|f| f.0 == d.worst_frame);
    if let Some((f, r, _)) = worst {
        crate::note!("worst frame {f}: rms {r:.4e}");
    }
    if let Some(r) = d.regions.iter().max_by(|a, b| a.rms.total_cmp(&b.rms)) {
        crate::note!(
            "worst region {} around ({:.2}, {:.2}, {:.2}): rms {:.4e}, mean {:+.3e}",
            r.id,
            r.center[0],
            r.center[1],
            r.center[2],
            r.rms,
            r.mean
        );
    }
    let p = d.direction.principal;
    crate::note!(
        "residual direction ({:.2}, {:.2}, {:.2}) carries {:.0}% of it; a uniform shift explains {:.0}%",
        p[0],
        p[1],
        p[2],
        100.0 * d.direction.principal_share,
        100.0 * d.direction.shift_share
    );
    crate::note!(
        "{:<18} {:>12} {:>12} {:>12} {:>12}",
        "candidate",
        "score",
        "predicted",
        "rms after",
        "dBIC"
    );
    for c in &d.candidates {
        crate::note!("{}", candidate_row(c));
    }
    crate::note!("{}", d.verdict);
}
