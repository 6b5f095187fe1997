//! Determinism end to end: a whole `softbody fit` and a whole `softbody diagnose` give
//! bit-identical results with `RAYON_NUM_THREADS=1` and `=2`: the whole JSON object (every
//! parameter, rms, standard error, history entry, candidate, the verdict and the
//! discretisation check), less its timing (`seconds`) and with the run's own folder written
//! as `RUN`, and the fit log line for line. Small cases (4 steps, 3 iterations), but the fit's
//! bar (resolution 24, 1701 nodes) is large enough that the assembly's matrix (about 37k
//! blocks) crosses `gpumat::expr::PAR_THRESHOLD`: its parallel passes run, not only their
//! sequential fallbacks (the diagnosis, at resolution 16, crosses it in its discretisation
//! check at resolution 32); the per-cell and per-point passes (rotations, corotation forces,
//! the adjoint's cell terms, the cost's closest points) run on the pool at any size. About 20 s
//! of CPU time in release.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
mod common;
use common::*;

/// The tiny bar of 4 steps ([`tiny_bar`]) made larger (0.8 x 0.3 x 0.3, clamped at
/// x <= -0.3) and damped, at `resolution` with `young` and the model's `effects`, and a `[fit]`
/// of `young` and `poisson` by Gauss-Newton.
fn scene(resolution: u32, young: f64, effects: &str) -> String {
    let extra = format!(
        "[damping]\nmass = 0.1\nstiffness = 0.01\n[model]\neffects = [{effects}]\n\
         [fit]\nparameters = [\"young\", \"poisson\"]\noptimizer = \"gauss-newton\"\n\
         iterations = 3"
    );
    let resolution = format!("resolution = {resolution}");
    let young = format!("young = {young:?}");
    edited(
        &tiny_bar(4, &extra),
        &[
            ("size = [0.6, 0.2, 0.3]", "size = [0.8, 0.3, 0.3]"),
            ("max = [-0.2, 2.0, 1.0]", "max = [-0.3, 2.0, 1.0]"),
            ("resolution = 10", &resolution),
            ("young = 2000.0", &young),
        ],
    )
}

/// Observations (3 cameras of 32 x 32 pixels) of the scene with `effects` and E = 2000.
fn observe(dir: &Path, resolution: u32, effects: &str) -> PathBuf {
    let truth = scene(resolution, 2000.0, effects);
    observed(dir, &truth, &["--cameras", "3", "--pixels", "32"]).0
}

/// `json` without its timing, with the strings naming `run_dir` relative to `RUN`.
fn normalized(v: &Value, run_dir: &Path) -> Value {
    let dir = run_dir.to_str().unwrap();
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| k.as_str() != "seconds")
                .map(|(k, x)| (k.clone(), normalized(x, run_dir)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(|x| normalized(x, run_dir)).collect()),
        Value::String(s) => Value::String(s.replace(dir, "RUN")),
        other => other.clone(),
    }
}

/// The path of the first difference between `a` and `b` (numbers compared by their bits).
fn first_difference(a: &Value, b: &Value, at: &str) -> Option<String> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            if x.len() != y.len() {
                return Some(format!("{at}: keys {:?} vs {:?}", x.keys(), y.keys()));
            }
            x.iter().find_map(|(k, xv)| match y.get(k) {
                Some(yv) => first_difference(xv, yv, &format!("{at}.{k}")),
                None => Some(format!("{at}.{k}: missing")),
            })
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                return Some(format!("{at}: {} vs {} entries", x.len(), y.len()));
            }
            (x.iter().zip(y).enumerate())
                .find_map(|(i, (xv, yv))| first_difference(xv, yv, &format!("{at}[{i}]")))
        }
        (Value::Number(x), Value::Number(y)) => {
            let same = match (x.as_f64(), y.as_f64()) {
                (Some(p), Some(q)) => p.to_bits() == q.to_bits(),
                _ => x == y,
            };
            (!same).then(|| format!("{at}: {x} vs {y}"))
        }
        _ => (a != b).then(|| format!("{at}: {a} vs {b}")),
    }
}

/// Runs `softbody args` (with `{run}` replaced by the run's folder, a copy of `scene` as
/// `{run}/scene.toml`) on `threads` rayon threads; its normalized JSON and fit log.
fn run_with(threads: usize, root: &Path, scene: &str, args: &[&str]) -> (Value, Option<String>) {
    let run_dir = root.join(format!("threads{threads}"));
    std::fs::create_dir_all(&run_dir).unwrap();
    write(&run_dir, "scene.toml", scene);
    let args: Vec<String> = args
        .iter()
        .map(|a| a.replace("{run}", run_dir.to_str().unwrap()))
        .collect();
    let o = Command::new(env!("CARGO_BIN_EXE_softbody"))
        .args(&args)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .unwrap();
    let v = normalized(&json(&o), &run_dir);
    let log = std::fs::read_to_string(run_dir.join("out").join("fit.log")).ok();
    (v, log)
}

/// `softbody COMMAND {run}/scene.toml --observations OBS --out {run}/out --json` ([`run_with`]):
/// the runs on 1 and 2 threads agree bit for bit.
fn assert_thread_independent(root: &Path, scene: &str, command: &str, obs: &Path) -> Value {
    let ob = obs.to_str().unwrap();
    let args = [
        command,
        "{run}/scene.toml",
        "--observations",
        ob,
        "--out",
        "{run}/out",
        "--json",
    ];
    let (one, log_one) = run_with(1, root, scene, &args);
    let (two, log_two) = run_with(2, root, scene, &args);
    if let Some(d) = first_difference(&one, &two, "") {
        panic!("{command}: 1 vs 2 threads differ at {d}");
    }
    assert_eq!(log_one, log_two, "{command}: fit.log differs");
    one
}

#[test]
fn fit_is_bit_identical_on_1_and_2_threads() {
    let dir = tmp("determinism", "fit");
    let obs = observe(&dir, 24, "\"gravity\", \"damping\", \"corotation\"");
    let start = scene(24, 2600.0, "\"gravity\", \"damping\", \"corotation\"");
    let v = assert_thread_independent(&dir, &start, "fit", &obs);
    // the run did work: parameters moved, rms fell, a log was written
    assert!(v["iterations"].as_u64().unwrap() >= 1, "{v}");
    let (e0, e) = (
        v["initial_parameters"]["young"].as_f64().unwrap(),
        v["parameters"]["young"].as_f64().unwrap(),
    );
    assert!(e != e0, "{v}");
    assert!(v["rms"]["final"].as_f64().unwrap() < v["rms"]["initial"].as_f64().unwrap());
    assert!(v["discretisation"]["difference"].is_number(), "{v}");
    assert!(v["scene"].as_str().unwrap().starts_with("RUN"), "{v}");
}

#[test]
fn diagnose_is_bit_identical_on_1_and_2_threads() {
    let dir = tmp("determinism", "diagnose");
    // resolution 16: its discretisation check's finer grid crosses the threshold
    let obs = observe(&dir, 16, "\"gravity\", \"damping\", \"corotation\"");
    // the model lacks gravity
    let model = scene(16, 2000.0, "\"damping\", \"corotation\"");
    let v = assert_thread_independent(&dir, &model, "diagnose", &obs);
    assert!(v["rms"].as_f64().unwrap() > 0.0, "{v}");
    assert!(!v["candidates"].as_array().unwrap().is_empty(), "{v}");
    assert!(v["verdict"].is_string(), "{v}");
}

/// The comparison sees a difference of one unit in the last place, and only timing is dropped.
#[test]
fn comparison_sees_one_ulp() {
    let x = 0.1f64;
    let y = f64::from_bits(x.to_bits() + 1);
    let a = serde_json::json!({"rms": {"final": x}, "seconds": 1.0, "out": "/r/out"});
    let b = serde_json::json!({"rms": {"final": y}, "seconds": 2.0, "out": "/s/out"});
    let (a, b) = (normalized(&a, Path::new("/r")), normalized(&b, Path::new("/s")));
    assert_eq!(a["out"], "RUN/out");
    assert!(a.get("seconds").is_none());
    let d = first_difference(&a, &b, "").expect("one ulp apart");
    assert!(d.starts_with(".rms.final"), "{d}");
    assert!(first_difference(&a, &a, "").is_none());
}
