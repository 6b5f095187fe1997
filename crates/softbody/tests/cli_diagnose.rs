//! `softbody diagnose` end to end on a small held bar whose model lacks gravity: the JSON has
//! the fields of interface.md, gravity is named missing, the pictures and the history file are
//! written, and bad input gives one line naming the file or flag. `softbody demo` tells its
//! story with the fields of interface.md.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn softbody() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softbody"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softbody-diagnose-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn scene(effects: &str) -> String {
    format!(
        r#"
[body]
shape = {{ kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }}
resolution = 10
[material]
young = 2000.0
poisson = 0.3
[gravity]
acceleration = [0.0, -10.0, 0.0]
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[time]
dt = 0.01
steps = 8
[model]
effects = [{effects}]
"#
    )
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn run(args: &[&str]) -> Output {
    softbody().args(args).output().unwrap()
}

fn json(o: &Output) -> Value {
    assert!(
        o.status.success(),
        "failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("one JSON object on stdout")
}

fn fails_with(o: &Output, needle: &str) {
    assert!(!o.status.success(), "should fail");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn diagnose_finds_missing_gravity() {
    let dir = tmp("gravity");
    let truth = write(&dir, "truth.toml", &scene("\"gravity\", \"corotation\""));
    let model = write(&dir, "model.toml", &scene("\"corotation\""));
    let obs = dir.join("obs.csv");
    let o = run(&[
        "observe",
        truth.to_str().unwrap(),
        "--out",
        obs.to_str().unwrap(),
        "--cameras",
        "3",
        "--pixels",
        "32",
        "--json",
    ]);
    json(&o);
    let out = dir.join("report");
    let args = [
        "diagnose",
        model.to_str().unwrap(),
        "--observations",
        obs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    let v = json(&run(&args));
    // interface.md fields
    assert!(v["rms"].as_f64().unwrap() > 0.0);
    assert!(v["noise_floor"].as_f64().unwrap() >= 0.0);
    let per_frame = v["per_frame"].as_array().unwrap();
    assert_eq!(per_frame.len(), 8);
    assert!(per_frame.iter().all(|f| f["frame"].is_u64() && f["rms"].is_f64()));
    assert!(!v["regions"].as_array().unwrap().is_empty());
    let c = &v["candidates"][0];
    assert_eq!(c["effect"], "gravity", "{v}");
    assert!(c["score"].as_f64().unwrap() > 0.0);
    let after = c["rms_after"].as_f64().unwrap();
    assert!(after * 5.0 < v["rms"].as_f64().unwrap(), "{v}");
    assert_eq!(v["missing_effect"], "gravity");
    assert!(v["verdict"].as_str().unwrap().starts_with("missing: gravity"));
    // pictures
    for f in v["files"].as_array().unwrap() {
        let p = PathBuf::from(f.as_str().unwrap());
        assert!(std::fs::metadata(&p).unwrap().len() > 1000, "{}", p.display());
    }
    assert!(out.join("diagnosis.json").exists());
    assert!(out.join("surface_residual.png").exists());
    // the history next to the scene grows by one line per run
    let hist = dir.join("model.history.jsonl");
    assert_eq!(std::fs::read_to_string(&hist).unwrap().lines().count(), 1);
    json(&run(&args));
    assert_eq!(std::fs::read_to_string(&hist).unwrap().lines().count(), 2);
    assert!(out.join("history.png").exists());
}

#[test]
fn diagnose_bad_input() {
    let dir = tmp("bad");
    let model = write(&dir, "model.toml", &scene("\"corotation\""));
    let missing = dir.join("nope.csv");
    fails_with(
        &run(&[
            "diagnose",
            model.to_str().unwrap(),
            "--observations",
            missing.to_str().unwrap(),
        ]),
        "nope.csv",
    );
    let bad = write(&dir, "bad.csv", "frame,x,y,z\n1,0.0,1.0,zero\n");
    fails_with(
        &run(&[
            "diagnose",
            model.to_str().unwrap(),
            "--observations",
            bad.to_str().unwrap(),
        ]),
        "bad.csv: line 2",
    );
    let ok = write(&dir, "ok.csv", "frame,x,y,z\n1,0.0,1.0,0.0\n");
    fails_with(
        &run(&[
            "diagnose",
            model.to_str().unwrap(),
            "--observations",
            ok.to_str().unwrap(),
            "--cost",
            "levelset",
        ]),
        "--cost",
    );
}
