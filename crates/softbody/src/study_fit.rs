//! `softbody fit STUDY.toml`: one joint fit of several recordings (`adjoint::study`, the file
//! format in `docs/study.md`). Each recording is read and checked as `fit` reads a scene and
//! its observations ([`ProblemArgs::load`]); the shared parameters are fitted to all of them at
//! once, each recording's own parameters to it alone. The report folder gets `fit.json` (the
//! joint parameters, their standard errors and the correlations of the shared ones, the rms of
//! every recording before and after) and `recordings.png` (that rms as bars). With `--starts K`
//! (also for one scene, a study of one recording) the fit runs from K starting points
//! (`adjoint::study::starts`) and the report lists every optimum and whether they agree.

use crate::fit::{per_frame_json, values_json, Args};
use crate::plot::{palette, BarChart, Figure};
use crate::problem_args::ProblemArgs;
use crate::progress;
use adjoint::cost::Robust;
use adjoint::fit::{check_frames, check_reach, scene_problem};
use adjoint::optim::{minimize, OptimParams, Optimizer};
use adjoint::params::ParamSet;
use adjoint::statistics::Uncertainty;
use adjoint::study::ensemble::{agree, Ensemble};
use adjoint::study::joint::{JointEvaluation, JointObjective, JointProblem};
use adjoint::study::starts::{disagreement, latin_hypercube, DISAGREE_Z};
use adjoint::study::{Recording, Study};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

/// True when `path` holds a study file rather than a scene (unreadable files are left to the
/// scene reader's error).
pub fn is_study_file(path: &Path) -> bool {
    cutfem::input::read_string(path, cutfem::input::MAX_CONFIG_BYTES)
        .is_ok_and(|t| adjoint::study::is_study(&t))
}

/// The flags that name one scene's problem are refused for a study (its file names them per
/// recording), as is `--resume` (not available for studies); `fit` and `diagnose` alike.
pub fn refuse_scene_flags(p: &ProblemArgs, resume: bool) -> Result<(), String> {
    let given = [
        ("--observations", p.observations.is_some()),
        ("--params", p.params.is_some()),
        ("--steps", p.steps.is_some()),
        ("--cameras", p.cameras.is_some()),
        ("--resume", resume),
    ];
    match given.iter().find(|(_, on)| *on) {
        Some((flag, _)) => Err(format!(
            "{flag}: {} is a study file, which names each recording's observations, parameters, steps and cameras ({flag} is for one scene{})",
            p.scene.display(),
            if *flag == "--resume" { "; studies cannot resume yet" } else { "" }
        )),
        None => Ok(()),
    }
}

/// What recording `rec` of `study` names, as one scene's problem: its scene, observations,
/// steps and cameras, the study's parameters (shared, then its own) and cost (else `cost`).
pub fn recording_problem(study: &Study, rec: &Recording, cost: &str) -> ProblemArgs {
    ProblemArgs {
        scene: rec.scene.clone(),
        observations: Some(rec.observations.clone()),
        params: Some(study.recording_params().join(",")),
        steps: rec.steps,
        cost: study.cost.clone().unwrap_or_else(|| cost.to_string()),
        cameras: rec.cameras.clone(),
    }
}

/// `{name, scene, observations, points, rms{initial,final}, per_frame{final}}` per recording.
fn recordings_json(study: &Study, first: &JointEvaluation, last: &JointEvaluation) -> Value {
    Value::Array(
        study
            .recordings
            .iter()
            .enumerate()
            .map(|(r, rec)| {
                let (e0, e1) = (&first.recordings[r], &last.recordings[r]);
                json!({
                    "name": rec.name,
                    "scene": rec.scene,
                    "observations": rec.observations,
                    "points": e1.frames.iter().map(|f| f.count).sum::<usize>(),
                    "rms": {"initial": e0.rms(), "final": e1.rms()},
                    "per_frame": {"final": per_frame_json(e1)},
                })
            })
            .collect(),
    )
}

/// Runs `fit` on a study file.
pub fn run(args: &Args) -> Result<(), String> {
    refuse_scene_flags(&args.problem, args.resume)?;
    let study = Study::load(&args.problem.scene).map_err(|e| e.to_string())?;
    fit_study(args, &study)
}

/// `fit SCENE --observations OBS --starts K`: the scene as a study of one recording (its
/// parameters shared, so they keep their names; a stiffness field as the recording's own).
pub fn run_scene(args: &Args) -> Result<(), String> {
    if args.resume {
        return Err("--resume: not available with --starts, --design or mpirun (those fits run as a study, which keeps no log yet)".into());
    }
    // the scene's [fit] section and parameters; the scene and its observations are read and
    // checked once, by `build`
    let section = cutfem::scene::Scene::load(&args.problem.scene)
        .map_err(|e| e.to_string())?
        .fit
        .unwrap_or_default();
    let params = args.problem.params(&section)?;
    let names: Vec<String> = params.params.iter().map(|p| p.name().to_string()).collect();
    let (shared, own): (Vec<String>, Vec<String>) = names.into_iter().partition(|n| n != "stiffness_field");
    let scene = args.problem.scene.clone();
    let name = scene
        .file_stem()
        .map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let study = Study {
        path: scene.clone(),
        shared,
        per_recording: own,
        cost: Some(args.problem.cost.clone()),
        optimizer: section.optimizer.clone(),
        iterations: section.iterations,
        recordings: vec![Recording {
            name,
            scene,
            observations: args.problem.observations()?.to_path_buf(),
            cameras: args.problem.cameras.clone(),
            steps: args.problem.steps,
        }],
    };
    fit_study(args, &study)
}

/// The files a study reads: the study file, and per recording its scene with the scene's body
/// file, its observations and camera file (`--cameras`, else the one beside the observations):
/// no output may replace them (`crate::out_dir::refuse_inputs`). A scene that does not load
/// adds only its own path (its error comes from the run).
pub fn study_inputs(study: &Study) -> Vec<PathBuf> {
    let mut inputs = vec![study.path.clone()];
    for rec in &study.recordings {
        match cutfem::scene::Scene::load(&rec.scene) {
            Ok(scene) => inputs.extend(scene.input_files()),
            Err(_) => inputs.push(rec.scene.clone()),
        }
        inputs.push(rec.observations.clone());
        inputs.push(
            rec.cameras
                .clone()
                .unwrap_or_else(|| adjoint::fit::cameras_path(&rec.observations)),
        );
    }
    inputs
}

/// The recordings' problems joined; when `check`, each recording's observed frames are
/// checked against its steps ([`check_frames`]; the reach is checked on the first evaluation,
/// [`initial`]). The copies of a multi-start fit, built from files already checked, skip that.
fn build(study: &Study, args: &Args, robust: Robust, check: bool) -> Result<JointProblem, String> {
    let mut problems = Vec::with_capacity(study.recordings.len());
    for rec in &study.recordings {
        let at = |e: String| format!("recording `{}`: {e}", rec.name);
        let loaded = recording_problem(study, rec, &args.problem.cost)
            .load()
            .map_err(at)?;
        if loaded.observations.is_empty() {
            return Err(at(format!("{}: no observed points", rec.observations.display())));
        }
        let problem = scene_problem(
            &loaded.scene,
            &loaded.observations,
            loaded.params,
            robust,
            rec.steps,
            loaded.kind,
            &loaded.eyes,
        )
        .map_err(|e| at(e.to_string()))?;
        if check {
            check_frames(&loaded.observations, &rec.observations, problem.steps)
                .map_err(|e| at(e.to_string()))?;
        }
        problems.push(problem);
    }
    let shared = if study.shared.iter().all(|s| s.trim().is_empty()) {
        ParamSet {
            params: Vec::new(),
            field: None,
        }
    } else {
        ParamSet::parse(&study.shared).map_err(|e| e.to_string())?
    };
    let rec_names = study.recordings.iter().map(|r| r.name.clone()).collect();
    JointProblem::new(rec_names, problems, &shared).map_err(|e| e.to_string())
}

/// The joint evaluation at the start, with every recording's observations checked to lie
/// within reach of its simulated body ([`check_reach`]).
fn initial(joint: &mut JointProblem, study: &Study) -> Result<JointEvaluation, String> {
    let ev = joint
        .evaluate(&joint.x0())
        .map_err(|e| format!("the starting model: {e}"))?;
    for (rec, e) in study.recordings.iter().zip(&ev.recordings) {
        check_reach(e, &rec.observations).map_err(|e| format!("recording `{}`: {e}", rec.name))?;
    }
    Ok(ev)
}

/// One fit of the joint problem: where it started and ended.
struct Run {
    start: Vec<f64>,
    x: Vec<f64>,
    info: adjoint::optim::OptimInfo,
    ev: JointEvaluation,
    unc: Option<Uncertainty>,
    history: Vec<Value>,
}

/// Fits `joint` from `x0` (`tag` names the start on the progress bar).
fn fit_from(
    joint: &mut JointProblem,
    x0: &[f64],
    optimizer: Optimizer,
    oparams: &OptimParams,
    bar: &indicatif::ProgressBar,
    tag: &str,
) -> Result<Run, String> {
    let mut objective = JointObjective::new(joint);
    let mut records = Vec::new();
    let result = minimize(optimizer, &mut objective, x0, oparams, &mut |rec| {
        bar.inc(1);
        bar.set_message(format!("{tag} {:.3e}", rec.cost));
        records.push(rec.clone());
        ControlFlow::Continue(())
    });
    let (x, info) = result.map_err(|e| format!("fit: {e}"))?;
    let history: Vec<Value> = records
        .iter()
        .map(|rec| {
            let rms = objective.evaluation_at(&rec.x).map(JointEvaluation::rms);
            json!({"iteration": rec.iteration, "cost": rec.cost, "rms": rms,
                   "parameters": values_json(&objective.joint.values(&rec.x))})
        })
        .collect();
    let ev = match objective.evaluation_at(&x) {
        Some(e) => e.clone(),
        None => objective
            .joint
            .evaluate(&x)
            .map_err(|e| format!("the fitted model: {e}"))?,
    };
    let unc = if x.len() <= 30 {
        joint.uncertainty(&x, &ev).map_err(|e| e.to_string())?
    } else {
        None
    };
    Ok(Run {
        start: x0.to_vec(),
        x,
        info,
        ev,
        unc,
        history,
    })
}

/// The standard errors of a run's reported values (NaN where unknown: not 0, which would
/// claim an exact value).
fn std_errors(run: &Run, n: usize) -> Vec<f64> {
    run.unc
        .as_ref()
        .map_or_else(|| vec![f64::NAN; n], |u| u.std_errors.clone())
}

/// The joint fit of `study` (from `--starts` starting points), its report and output. Under
/// `mpirun` (feature `mpi`) every rank runs this; rank 0 alone shows progress and writes, and
/// the other ranks end quietly on a failure (rank 0 names it).
fn fit_study(args: &Args, study: &Study) -> Result<(), String> {
    let ensemble = crate::ensemble::join()?;
    let lead = ensemble.as_ref().map_or(true, |e| e.rank() == 0);
    let result = fit_study_on(args, study, ensemble.clone());
    let Some(ranks) = &ensemble else {
        return result;
    };
    // the end, on every rank whatever happened (failures in the shared part are the same on
    // every rank; rank 0 may also fail alone, writing the report): rank 0 says its failure
    // first, then every rank learns whether any failed; no rank ends before rank 0 has spoken
    // (a rank that exits with a failure makes mpirun stop the others at once)
    if lead {
        match &result {
            Err(e) if e != crate::output::STDOUT_CLOSED => {
                crate::note!("error: {}", crate::output::error_line(e));
            }
            _ => {}
        }
    }
    let failed = ranks
        .all_gather(&[u8::from(result.is_err())])
        .iter()
        .any(|b| b.first() != Some(&0));
    if failed {
        Err(crate::ensemble::QUIET_FAILURE.into())
    } else {
        Ok(())
    }
}

/// A step every rank takes: with an ensemble, its outcome on every rank (the first failure).
fn agreed<T>(ensemble: &Option<Rc<dyn Ensemble>>, step: Result<T, String>) -> Result<T, String> {
    match ensemble {
        None => step,
        Some(e) => match agree(e.as_ref(), step.as_ref().map(|_| ()).map_err(Clone::clone)) {
            Ok(()) => step,
            Err(first) => Err(first),
        },
    }
}

/// [`fit_study`] on this process' share of the recordings.
fn fit_study_on(args: &Args, study: &Study, ensemble: Option<Rc<dyn Ensemble>>) -> Result<(), String> {
    let t0 = Instant::now();
    let lead = ensemble.as_ref().map_or(true, |e| e.rank() == 0);
    let section = cutfem::scene::FitSection {
        parameters: None,
        optimizer: study.optimizer.clone(),
        iterations: study.iterations,
    };
    let crate::fit::Settings {
        optimizer,
        iterations,
        robust,
    } = crate::fit::Settings::new(args, &section)?;
    let mut joint = agreed(&ensemble, build(study, args, robust, true))?;
    if let Some(e) = &ensemble {
        joint.distribute(e.clone());
    }
    let ev_initial = initial(&mut joint, study)?;
    let x0 = joint.x0();
    let k = args.starts.unwrap_or(1) as usize;
    let starts = latin_hypercube(&x0, &joint.bounds(&x0), k, args.seed);

    let target = args
        .out
        .clone()
        .unwrap_or_else(|| crate::simulate::default_out(&args.problem.scene, "fit"));
    // only the lead writes; a folder it cannot make stops every rank
    let dir = agreed(
        &ensemble,
        lead.then(|| crate::out_dir::OutDir::begin(&target, &study_inputs(study)))
            .transpose(),
    )?;

    let bar = progress::bar(((iterations + 1) * k) as u64, "fit", args.json || !lead);
    let oparams = OptimParams {
        max_iterations: iterations,
        ..OptimParams::default()
    };
    // one start: this joint problem; several: each start on its own copy, in parallel (the
    // starts are independent and each fit's numbers do not depend on the threads), or one
    // after the other over the ranks of an ensemble
    let runs: Vec<Result<Run, String>> = if k == 1 {
        vec![fit_from(&mut joint, &starts[0], optimizer, &oparams, &bar, "fit")]
    } else if let Some(e) = &ensemble {
        let mut runs = Vec::with_capacity(k);
        for (j, xs) in starts.iter().enumerate() {
            let mut own = agreed(&ensemble, build(study, args, robust, false))?;
            own.distribute(e.clone());
            let tag = format!("start {}/{k}", j + 1);
            runs.push(fit_from(&mut own, xs, optimizer, &oparams, &bar, &tag));
        }
        runs
    } else {
        starts
            .par_iter()
            .enumerate()
            .map(|(j, xs)| {
                let mut own = build(study, args, robust, false)?;
                fit_from(
                    &mut own,
                    xs,
                    optimizer,
                    &oparams,
                    &bar,
                    &format!("start {}/{k}", j + 1),
                )
            })
            .collect()
    };
    bar.finish_and_clear();
    if k == 1 {
        if let Some(Err(e)) = runs.first() {
            return Err(e.clone());
        }
    }
    // the best optimum: the lowest cost (the first of equals)
    let best = runs
        .iter()
        .enumerate()
        .filter_map(|(j, r)| r.as_ref().ok().map(|r| (j, r.ev.cost)))
        .fold(None, |b: Option<(usize, f64)>, (j, c)| match b {
            Some((_, cb)) if cb <= c => b,
            _ => Some((j, c)),
        })
        .map(|(j, _)| j)
        .ok_or_else(|| {
            let first = runs
                .iter()
                .find_map(|r| r.as_ref().err())
                .cloned()
                .unwrap_or_default();
            format!("every one of the {k} starts failed; the first: {first}")
        })?;
    let run = runs[best].as_ref().expect("the best run succeeded");
    let (x, ev_final, unc) = (&run.x, &run.ev, &run.unc);
    let fitted = joint.values(x);
    let initial_values = joint.values(&x0);
    let s = joint.shared_len();
    let correlations: Vec<Value> = unc.as_ref().map_or_else(Vec::new, |u| {
        (0..s)
            .flat_map(|i| (i + 1..s).map(move |j| (i, j)))
            .map(|(i, j)| json!({"a": u.labels[i], "b": u.labels[j], "value": u.correlation(i, j)}))
            .collect()
    });
    // the design's Gauss-Newton picture (a collective when the fit's last evaluation did not
    // make the matrix)
    let gn_picture = if args.design {
        let (xb, evb) = (run.x.clone(), run.ev.clone());
        Some(match joint.picture(&xb, &evb) {
            Ok(Some(c)) => Ok(c),
            Ok(None) => {
                Err("no more observed points than fitted coordinates: no standard errors".to_string())
            }
            Err(e) => Err(e.to_string()),
        })
    } else {
        None
    };
    // the other ranks are done: rank 0 reports
    let Some(dir) = dir else { return Ok(()) };
    let out = dir.path().to_path_buf();
    let picture = out.join("recordings.png");
    BarChart {
        title: "rms per recording before and after the joint fit".into(),
        y_label: "rms (world units)".into(),
        bars: study
            .recordings
            .iter()
            .enumerate()
            .flat_map(|(r, rec)| {
                [
                    (
                        format!("{} before", rec.name),
                        ev_initial.recordings[r].rms(),
                        palette(1),
                    ),
                    (
                        format!("{} after", rec.name),
                        ev_final.recordings[r].rms(),
                        palette(0),
                    ),
                ]
            })
            .collect(),
        ..BarChart::default()
    }
    .picture()
    .save(&picture)?;
    let mut summary = json!({
        "study": args.problem.scene,
        "optimizer": optimizer.to_string(),
        "parameters": values_json(&fitted),
        "initial_parameters": values_json(&initial_values),
        "shared": study.shared,
        "per_recording": study.per_recording,
        "standard_errors": unc.as_ref().map(|u| values_json(&u.labels.iter().cloned().zip(u.std_errors.iter().copied()).collect::<Vec<_>>())),
        "correlations": correlations,
        "cost": {"initial": ev_initial.cost, "final": ev_final.cost},
        "rms": {"initial": ev_initial.rms(), "final": ev_final.rms()},
        "recordings": recordings_json(study, &ev_initial, ev_final),
        "iterations": run.history.len().saturating_sub(1),
        "evaluations": run.info.evaluations,
        "termination": run.info.termination.to_string(),
        "converged": run.info.termination.is_converged(),
        "history": run.history,
    });
    if k > 1 {
        let n = x.len();
        let (best_vals, best_se) = (fitted.iter().map(|v| v.1).collect::<Vec<_>>(), std_errors(run, n));
        let mut worst: f64 = 0.0;
        let list: Vec<Value> = runs
            .iter()
            .enumerate()
            .map(|(j, r)| match r {
                Ok(r) => {
                    let vals: Vec<f64> = joint.values(&r.x).iter().map(|v| v.1).collect();
                    let z = disagreement(&vals, &best_vals, &std_errors(r, n), &best_se);
                    if r.info.termination.is_converged() {
                        worst = worst.max(z);
                    }
                    json!({"start": j, "initial_parameters": values_json(&joint.values(&r.start)),
                           "parameters": values_json(&joint.values(&r.x)), "cost": r.ev.cost, "rms": r.ev.rms(),
                           "iterations": r.history.len().saturating_sub(1), "termination": r.info.termination.to_string(),
                           "converged": r.info.termination.is_converged(), "disagreement_with_best": z})
                }
                Err(e) => json!({"start": j, "initial_parameters": values_json(&joint.values(&starts[j])), "error": e}),
            })
            .collect();
        summary["starts"] = json!(list);
        summary["best_start"] = json!(best);
        summary["seed"] = json!(args.seed);
        summary["max_disagreement"] = json!(worst);
        summary["unique"] = json!(worst <= DISAGREE_Z);
    }
    // a design that cannot be made leaves the fit's report whole, saying why
    let mut advice = None;
    if let Some(current) = &gn_picture {
        let s = joint.shared_len();
        let values: Vec<f64> = fitted.iter().take(s).map(|v| v.1).collect();
        let made = current.as_ref().map_err(Clone::clone).and_then(|c| {
            let grid = &joint.problems[0].sim.grid;
            crate::study_design::design(study, grid, c, &x[..s], &values, &out)
        });
        let (entry, line) = match made {
            Ok(m) => m,
            Err(e) => (json!({ "error": e }), format!("experiment design: not made: {e}")),
        };
        summary["design"] = entry;
        advice = Some(line);
    }
    summary["seconds"] = json!(t0.elapsed().as_secs_f64());
    summary["out"] = json!(out);
    summary["files"] = json!({"recordings": picture});
    dir.finish(&mut summary, "fit.json")?;
    if args.json {
        crate::output::print_json(&summary)?;
    } else {
        crate::note!(
            "fit of {} recording(s): {} after {} iterations ({}); rms {:.4e} -> {:.4e}",
            study.recordings.len(),
            fitted
                .iter()
                .map(|(k, v)| format!("{k}={v:.6}"))
                .collect::<Vec<_>>()
                .join(" "),
            summary["iterations"],
            run.info.termination,
            ev_initial.rms(),
            ev_final.rms(),
        );
        if k > 1 {
            crate::note!(
                "{k} starts (seed {}): best is start {best}; {}",
                args.seed,
                if summary["unique"] == json!(true) {
                    "the converged optima agree within 3 standard errors".to_string()
                } else {
                    format!(
                        "the optima DISAGREE (up to {:.1} combined standard errors): the optimum is not unique, or a fit stopped early",
                        summary["max_disagreement"].as_f64().unwrap_or(f64::NAN)
                    )
                }
            );
        }
        if let Some(line) = &advice {
            crate::note!("{line}");
        }
        crate::note!("report: {}", target.display());
    }
    Ok(())
}
