//! `softbody diagnose STUDY.toml`: every recording of a study diagnosed on its own
//! (`crate::diagnose`: the model as given fitted to that recording, where it fails, which
//! effect is missing). A missing effect often shows in one motion only (the ground in a drop,
//! not in a swing), so the study's report lists the verdict of each recording side by side.
//! The recordings are fitted separately here (each its own material); a diagnosis of the
//! joint model (one material for all while looking for missing effects) is not built.
//!
//! The report folder holds `diagnosis.json` (`study`, `recordings[]`: `name`, `scene`,
//! `observations`, `verdict`, `missing_effect`, `rms`, `noise_floor`, `report`) and one
//! sub-folder per recording with that recording's full diagnosis.

use crate::diagnose::{diagnose_ready, prepare, print_text, Args};
use crate::study_fit::{recording_problem, refuse_scene_flags};
use adjoint::study::Study;
use serde_json::{json, Value};

/// The study report's own file.
const SUMMARY: &str = "diagnosis.json";

/// Runs `diagnose` on a study file.
pub fn run(args: &Args) -> Result<(), String> {
    let p = &args.problem;
    refuse_scene_flags(p, false)?;
    let study = Study::load(&p.scene).map_err(|e| e.to_string())?;
    // each recording gets a folder of its name beside the study's own file
    if let Some(rec) = study
        .recordings
        .iter()
        .find(|r| r.name.eq_ignore_ascii_case(SUMMARY))
    {
        return Err(format!(
            "{}: recording `{}`: the name is the study report's own file; rename the recording",
            p.scene.display(),
            rec.name
        ));
    }
    // the study's cost is its file's key, not a flag the user passed
    if let Some(cost) = study.cost.as_deref().filter(|c| *c != "surface") {
        return Err(format!(
            "{}: cost = \"{cost}\": diagnose measures distances to the simulated surface (cost = \"surface\")",
            p.scene.display()
        ));
    }
    // every recording read and checked (its simulation built, its observations within reach)
    // before anything is written
    let mut ready = Vec::with_capacity(study.recordings.len());
    for rec in &study.recordings {
        let problem = recording_problem(&study, rec, &p.cost);
        ready.push(prepare(&problem).map_err(|e| format!("recording `{}`: {e}", rec.name))?);
    }
    let target = args
        .out
        .clone()
        .unwrap_or_else(|| crate::simulate::default_out(&p.scene, "diagnose"));
    let out = crate::out_dir::OutDir::begin(&target, &crate::study_fit::study_inputs(&study))?;
    let mut rows = Vec::with_capacity(ready.len());
    for (rec, r) in study.recordings.iter().zip(ready) {
        let at = |e: String| format!("recording `{}`: {e}", rec.name);
        let sub = out.nested(&rec.name).map_err(at)?;
        let (d, _) = diagnose_ready(r, args, &rec.scene, &sub).map_err(at)?;
        sub.commit().map_err(at)?;
        if !args.json {
            crate::note!("recording `{}`:", rec.name);
            print_text(&d);
        }
        rows.push(json!({
            "name": rec.name,
            "scene": rec.scene,
            "observations": rec.observations,
            "verdict": d.verdict,
            "missing_effect": d.missing_effect,
            "rms": d.rms,
            "noise_floor": d.noise_floor,
            "report": out.path().join(&rec.name),
        }));
    }
    let mut summary: Value = json!({
        "study": p.scene,
        "recordings": rows,
        "joint": false,
    });
    out.finish(&mut summary, SUMMARY)?;
    if args.json {
        crate::output::print_json(&summary)?;
    } else {
        crate::note!("report: {}", target.display());
    }
    Ok(())
}
