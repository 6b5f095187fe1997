//! `softbody demo [--out DIR] [--json]`: the whole story on a built-in case, no files needed.
//!
//! A torus is thrown onto the ground. The "truth" scene has the ground; the model the user
//! starts with does not. The demo
//! 1. generates observations of the truth with 4 virtual depth cameras and sensor noise,
//! 2. fits the incomplete model (Young's modulus and Poisson ratio): the body falls through
//!    the floor, the error stays high,
//! 3. diagnoses: where the model fails and which effect is missing,
//! 4. adds the effect the diagnosis names, with its suggested values, and refits,
//! 5. prints the before/after table and writes the report (pictures, JSON, the scene files and
//!    their history, whose rms falls).

use crate::diagnose::{print_text, run_job, Job};
use adjoint::camera_file::CameraFile;
use adjoint::cost::Robust;
use adjoint::diagnosis::effects::write_back_all;
use adjoint::diagnosis::history::{self, Entry};
use adjoint::diagnosis::{add_and_refit, DiagnoseParams, Setup};
use adjoint::observe::{synthesize, RigParams};
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Report folder (default: out/demo).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print exactly one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The body and physics shared by the truth and the model.
const BODY: &str = r#"# softbody demo: a torus thrown onto the ground
[body]
shape = { kind = "torus", center = [0.0, 1.0, 0.0], axis = [0.0, 0.0, 1.0], major = 0.5, minor = 0.2 }
resolution = 10

[material]
young = 2000.0
poisson = 0.3
density = 1.0

[gravity]
acceleration = [0.0, -10.0, 0.0]

[initial]
velocity = [1.0, -0.5, 0.0]
angular_velocity = [0.0, 0.0, 1.0]

[time]
dt = 0.02
steps = 15
theta = 0.6
"#;

/// The truth's hidden effect.
const GROUND: &str = "\n[ground]\nnormal = [0.0, 1.0, 0.0]\nheight = 0.2\n";

/// The model's starting material (the truth: 2000, 0.3).
const START: (f64, f64) = (3000.0, 0.25);

/// The effects of the model the user starts with (the truth adds the ground).
const BASE_EFFECTS: [&str; 3] = ["gravity", "corotation", "initial_velocity"];

/// Depth noise of the cameras (world units; the torus is 1.4 wide).
const NOISE: f64 = 0.002;

fn effects_line(effects: &[&str]) -> String {
    let list: Vec<String> = effects.iter().map(|e| format!("\"{e}\"")).collect();
    format!("\n[model]\neffects = [{}]\n", list.join(", "))
}

/// The truth's scene (the model's effects and the ground), written to `out/truth.toml`.
fn truth_scene(out: &std::path::Path) -> Result<Scene, String> {
    let truth_text = format!(
        "{BODY}{GROUND}{}",
        effects_line(&[&BASE_EFFECTS[..], &["ground"]].concat())
    );
    let truth_path = out.join("truth.toml");
    std::fs::write(&truth_path, &truth_text).map_err(|e| format!("{}: {e}", truth_path.display()))?;
    Scene::parse(&truth_text, &truth_path).map_err(|e| e.to_string())
}

/// The before / after / truth rows of the demo's table.
fn table(
    d: &adjoint::diagnosis::Diagnosis,
    rms_after: f64,
    after_model: &cutfem::fem::Model,
    truth_model: &cutfem::fem::Model,
) -> Vec<(String, String, String, String)> {
    let g = truth_model.ground.as_ref().expect("truth has a ground");
    vec![
        (
            "rms".to_string(),
            format!("{:.3e}", d.rms),
            format!("{:.3e}", rms_after),
            d.noise_floor
                .map_or("noise floor: none".into(), |f| format!("noise floor {f:.3e}")),
        ),
        (
            "young".into(),
            format!("{:.1}", d.model.young),
            format!("{:.1}", after_model.young),
            "2000".into(),
        ),
        (
            "poisson".into(),
            format!("{:.4}", d.model.poisson),
            format!("{:.4}", after_model.poisson),
            "0.3".into(),
        ),
        (
            "ground.height".into(),
            "-".into(),
            after_model
                .ground
                .as_ref()
                .map_or("-".into(), |g| format!("{:.4}", g.height)),
            format!("{}", g.height),
        ),
    ]
}

/// Runs the demo.
pub fn run(a: Args) -> Result<(), String> {
    let t0 = Instant::now();
    let target = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join("demo"));
    // the demo reads no file
    let dir = crate::out_dir::OutDir::begin(&target, &[])?;
    let out = dir.path().to_path_buf();
    let say = |s: String| {
        if !a.json {
            crate::note!("{s}");
        }
    };

    // 1. the truth and its observations
    let truth = truth_scene(&out)?;
    let rig = RigParams {
        cameras: 4,
        pixels: 48,
        seed: 7,
        ..RigParams::default()
    };
    say(format!(
        "1. observing the truth (hidden from the model: ground contact) with {} cameras of {}x{} pixels, noise {NOISE}",
        rig.cameras, rig.pixels, rig.pixels
    ));
    let (obs, cameras) = synthesize(&truth, &rig, NOISE, truth.time.steps, |_, _| {})?;
    let obs_path = out.join("observations.csv");
    obs.write_csv(&obs_path).map_err(|e| e.to_string())?;
    let eyes: Vec<[f64; 3]> = cameras.iter().map(|c| c.camera.eye).collect();
    let cams_path = adjoint::fit::cameras_path(&obs_path);
    std::fs::write(&cams_path, CameraFile::text(&cameras, NOISE, rig.seed))
        .map_err(|e| format!("{}: {e}", cams_path.display()))?;

    // 2-3. the incomplete model: fit and diagnose
    let model_path = out.join("model.toml");
    let mut model = Scene::parse(&format!("{BODY}{}", effects_line(&BASE_EFFECTS)), &model_path)
        .map_err(|e| e.to_string())?;
    (model.material.young, model.material.poisson) = START;
    model.write(&model_path).map_err(|e| e.to_string())?;
    let hist = history::history_path(&model_path);
    let _ = std::fs::remove_file(&hist);
    say("2. fitting the model as given (no ground) and 3. diagnosing it".into());
    let params = ParamSet::parse(&["young,poisson"])?;
    let (d, diag_json) = run_job(Job {
        scene: &model,
        scene_path: &model_path,
        observations: &obs,
        eyes: &eyes,
        cameras: &cameras,
        params: params.clone(),
        settings: DiagnoseParams::default(),
        out: &dir,
        quiet: a.json,
        command: "demo: diagnose",
        refine_check: false,
    })?;
    if !a.json {
        print_text(&d);
    }

    // 4. add the effect the diagnosis names and refit
    let Some(missing) = d.missing_effect.clone() else {
        return Err(format!("the diagnosis found nothing missing: {}", d.verdict));
    };
    say(format!("4. adding `{missing}` and refitting"));
    let setup = Setup {
        observations: &obs,
        eyes: &eyes,
        cameras: &cameras,
        robust: Robust::Squared,
        steps: None,
        reach: None,
    };
    let refined = add_and_refit(&setup, &d, &missing, 15)?;
    let ev = refined.eval.clone();
    // the user's next scene file: the effect on, with its fitted values
    let fixed_path = out.join("model_fixed.toml");
    let mut fixed = refined.scene.clone();
    write_back_all(&mut fixed, &refined.model);
    fixed.write(&fixed_path).map_err(|e| e.to_string())?;
    let after_model = refined.model.clone();
    let after_values = refined.values.clone();
    let mut effects_after: Vec<String> = d.effects.clone();
    effects_after.push(missing.clone());
    let mut entry = Entry::now("demo: refit", effects_after, after_values.clone(), ev.rms());
    entry.observations = Some(obs.fingerprint());
    // the report's history picture with the refit
    let recorded = history::record(&hist, &entry);
    crate::output::warn_all(&recorded.warnings);
    crate::diagnose_report::write_history_picture(&out.join("history.png"), &recorded.entries)?;

    // 5. the table
    let rows = table(&d, ev.rms(), &after_model, &truth.to_model());
    let fall = d.rms / ev.rms().max(f64::MIN_POSITIVE);
    let mut summary = json!({
        "before": {"rms": d.rms, "effects": d.effects, "parameters": crate::fit::values_json(&d.fitted)},
        "missing_effect": missing,
        "after": {"rms": ev.rms(), "parameters": crate::fit::values_json(&after_values)},
        "noise_floor": d.noise_floor,
        "rms_fall": fall,
        "verdict": d.verdict,
        "diagnosis": diag_json,
        "out": out,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    dir.finish(&mut summary, "demo.json")?;
    if a.json {
        crate::output::print_json(&summary)?;
    } else {
        crate::note!("5. before / after");
        crate::note!("{:<14} {:>12} {:>12} {:>22}", "", "before", "after", "truth");
        for (k, b, af, t) in rows {
            crate::note!("{k:<14} {b:>12} {af:>12} {t:>22}");
        }
        crate::note!(
            "the error fell {fall:.1}x by adding `{missing}`; report, pictures and scene files in {} ({:.0} s)",
            target.display(),
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
