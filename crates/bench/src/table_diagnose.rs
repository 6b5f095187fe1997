//! Table D: the time of a diagnosis and of the demo (issue targets: `diagnose` on the swinging
//! torus (30 steps) under 2 minutes, `demo` under 3 minutes, on this 2-core machine).
//!
//! * `diagnose`: observations of `examples/scenes/swinging_torus.toml` (4 cameras of 48 x 48
//!   pixels, depth noise 0.002, seed 0) against the model `examples/scenes/fit/torus_material.toml`
//!   (E = 2200, nu = 0.32 to fit; nothing hidden), with the default settings of `softbody
//!   diagnose`.
//! * `diagnose bar`: the diagnosis issue's speed case. A bar 1.05 x 0.22 x 0.22 clamped at one
//!   end swings under gravity with hidden mass damping 0.8 (the truth simulated at resolution
//!   30), 80 steps, 300 points per frame drawn uniformly by area with isotropic noise 0.01
//!   ([`adjoint::observe::sample_surface`], no cameras); the model at resolution 20 without
//!   damping, fitting `young, poisson`. Timed as a user runs it: the `softbody diagnose`
//!   binary (built beside `tables`), its discretisation check included.
//! * `demo`: the `softbody demo` binary (built beside `tables`), run as a child process.

use crate::progress;
use crate::report::{col, markdown_table, Fmt};
use adjoint::cost::Robust;
use adjoint::diagnosis::{diagnose, DiagnoseParams, Setup};
use adjoint::observe::{synthesize, RigParams};
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One row.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// what ran
    pub case: String,
    /// wall seconds
    pub seconds: f64,
    /// the target (seconds)
    pub goal_s: f64,
    /// rms of the model as given
    pub rms: Option<f64>,
    /// rms after adding the missing effect (demo)
    pub rms_after: Option<f64>,
    /// the verdict's missing effect
    pub missing_effect: Option<String>,
    /// why it could not run, if so
    pub error: Option<String>,
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn diagnose_row() -> Result<Row, String> {
    let truth =
        Scene::load(&root().join("examples/scenes/swinging_torus.toml")).map_err(|e| e.to_string())?;
    let model =
        Scene::load(&root().join("examples/scenes/fit/torus_material.toml")).map_err(|e| e.to_string())?;
    let rig = RigParams {
        cameras: 4,
        pixels: 48,
        ..RigParams::default()
    };
    progress("D: observing the swinging torus");
    let (obs, cams) = synthesize(&truth, &rig, 0.002, truth.time.steps, |_, _| {})?;
    let eyes: Vec<[f64; 3]> = cams.iter().map(|c| c.camera.eye).collect();
    let setup = Setup {
        observations: &obs,
        eyes: &eyes,
        cameras: &cams,
        robust: Robust::Squared,
        steps: None,
        reach: None,
    };
    progress("D: diagnosing the torus model");
    let t = Instant::now();
    let d = diagnose(
        &model,
        &setup,
        ParamSet::parse(&["young,poisson"])?,
        &DiagnoseParams::default(),
        &mut |stage, _, _| progress(&format!("D: {stage}")),
    )?;
    Ok(Row {
        case: "diagnose: swinging torus, 30 steps (nothing hidden)".into(),
        seconds: t.elapsed().as_secs_f64(),
        goal_s: 120.0,
        rms: Some(d.rms),
        rms_after: None,
        missing_effect: d.missing_effect,
        error: None,
    })
}

/// The bar of the diagnosis issue's speed case at `resolution`, with `[model].effects` and
/// `damping` (mass) when given.
fn bar_scene(resolution: f64, damping: Option<f64>) -> String {
    let (effects, section) = match damping {
        Some(a) => (
            "\"gravity\", \"damping\"",
            format!("[damping]\nmass = {a}\nstiffness = 0.0\n"),
        ),
        None => ("\"gravity\"", String::new()),
    };
    format!(
        "[body]\nresolution = {resolution}\nshape = {{ kind = \"box\", center = [0.525, 1.0, 0.0], size = [1.05, 0.22, 0.22] }}\n\n\
         [material]\nyoung = 2400.0\npoisson = 0.35\ndensity = 1.0\n\n{section}\
         [gravity]\nacceleration = [0.0, -10.0, 0.0]\n\n\
         [[dirichlet]]\nmin = [-0.02, 0.8, -0.2]\nmax = [0.02, 1.2, 0.2]\n\n\
         [time]\ndt = 0.02\nsteps = {BAR_STEPS}\n\n[model]\neffects = [{effects}]\n"
    )
}

/// Steps of the bar case.
const BAR_STEPS: usize = 80;

fn bar_row() -> Result<Row, String> {
    let bin = softbody_binary()?;
    let dir = std::env::temp_dir().join(format!("tables-bar-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let truth_path = dir.join("truth.toml");
    let model_path = dir.join("bar.toml");
    let obs_path = dir.join("bar.csv");
    let write = |p: &Path, s: String| std::fs::write(p, s).map_err(|e| format!("{}: {e}", p.display()));
    write(&truth_path, bar_scene(30.0, Some(0.8)))?;
    write(&model_path, bar_scene(20.0, None))?;
    progress("D: simulating the hidden-damping bar");
    let truth = Scene::load(&truth_path).map_err(|e| e.to_string())?;
    let mut sim = truth.build_simulation().map_err(|e| e.to_string())?;
    let surface = sim.grid.surface().map_err(|e| e.to_string())?;
    let mut obs = adjoint::observations::Observations::new();
    for f in 1..=BAR_STEPS {
        sim.step().map_err(|e| format!("truth step {f}: {e}"))?;
        let mesh = sim.grid.deformed(&surface, &sim.u);
        for p in adjoint::observe::sample_surface(&mesh, 300, 0.01, 0, f) {
            obs.push(f, adjoint::observations::ObservedPoint::new(p));
        }
    }
    obs.write_csv(&obs_path).map_err(|e| e.to_string())?;
    progress("D: softbody diagnose on the bar");
    let t = Instant::now();
    let o = std::process::Command::new(&bin)
        .arg("diagnose")
        .arg(&model_path)
        .arg("--observations")
        .arg(&obs_path)
        .args(["--json", "--out"])
        .arg(dir.join("report"))
        .output()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().to_string());
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).map_err(|e| e.to_string())?;
    Ok(Row {
        case: format!("diagnose: bar r = 20, {BAR_STEPS} steps, 300 points per frame (damping hidden)"),
        seconds,
        goal_s: 120.0,
        rms: v["rms"].as_f64(),
        rms_after: v["candidates"][0]["rms_after"].as_f64(),
        missing_effect: v["missing_effect"].as_str().map(str::to_string),
        error: None,
    })
}

/// The `softbody` binary beside this one.
pub fn softbody_binary() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let bin = exe.with_file_name(format!("softbody{}", std::env::consts::EXE_SUFFIX));
    if !bin.exists() {
        return Err(format!(
            "{} not found: build it first (cargo build --release -p softbody)",
            bin.display()
        ));
    }
    Ok(bin)
}

fn demo_row() -> Result<Row, String> {
    let bin = softbody_binary()?;
    let out = std::env::temp_dir().join(format!("tables-demo-{}", std::process::id()));
    progress("D: softbody demo");
    let t = Instant::now();
    let o = std::process::Command::new(&bin)
        .args(["demo", "--json", "--out"])
        .arg(&out)
        .output()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&out);
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().to_string());
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).map_err(|e| e.to_string())?;
    Ok(Row {
        case: "softbody demo".into(),
        seconds,
        goal_s: 180.0,
        rms: v["before"]["rms"].as_f64(),
        rms_after: v["after"]["rms"].as_f64(),
        missing_effect: v["missing_effect"].as_str().map(str::to_string),
        error: None,
    })
}

/// Runs Table D (`quick`: the demo only).
pub fn table(quick: bool) -> Vec<Row> {
    let fail = |case: &str, goal_s: f64, e: String| Row {
        case: case.into(),
        seconds: f64::NAN,
        goal_s,
        rms: None,
        rms_after: None,
        missing_effect: None,
        error: Some(e),
    };
    let mut rows = Vec::new();
    if !quick {
        rows.push(diagnose_row().unwrap_or_else(|e| fail("diagnose: swinging torus", 120.0, e)));
        rows.push(bar_row().unwrap_or_else(|e| fail("diagnose: bar", 120.0, e)));
    }
    rows.push(demo_row().unwrap_or_else(|e| fail("softbody demo", 180.0, e)));
    rows
}

/// The markdown of Table D.
pub fn markdown(rows: &[serde_json::Value]) -> String {
    markdown_table(
        "Table D: diagnosis and demo",
        "Wall time on this machine; goals from the diagnosis issue (2-core machine).",
        rows,
        &[
            col("case", "case", Fmt::Plain),
            col("seconds", "seconds", Fmt::Ratio),
            col("goal s", "goal_s", Fmt::Plain),
            col("rms", "rms", Fmt::Sci),
            col("rms after", "rms_after", Fmt::Sci),
            col("missing", "missing_effect", Fmt::Plain),
            col("error", "error", Fmt::Plain),
        ],
    )
}
