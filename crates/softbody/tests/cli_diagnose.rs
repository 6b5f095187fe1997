//! `softbody diagnose` end to end on a small held bar whose model lacks gravity: the JSON has
//! the fields of interface.md, gravity is named missing, the pictures and the history file are
//! written, and bad input gives one line naming the file or flag. `softbody demo` tells its
//! story with the fields of interface.md.

use std::path::PathBuf;
mod common;
use common::*;

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

#[test]
fn diagnose_finds_missing_gravity() {
    let dir = tmp("diagnose", "gravity");
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
    // the discretisation share of the rms (the fitted model at twice and half the resolution)
    let d = &v["discretisation"];
    assert!(d["estimate"].as_f64().unwrap() >= 0.0, "{d}");
    assert_eq!(d["noise_floor"], v["noise_floor"]);
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
    let dir = tmp("diagnose", "bad");
    let model = write(&dir, "model.toml", &scene("\"corotation\""));
    let missing = dir.join("nope.csv");
    one_line_error(
        &run(&[
            "diagnose",
            model.to_str().unwrap(),
            "--observations",
            missing.to_str().unwrap(),
        ]),
        "nope.csv",
    );
    let bad = write(&dir, "bad.csv", "frame,x,y,z\n1,0.0,1.0,zero\n");
    one_line_error(
        &run(&[
            "diagnose",
            model.to_str().unwrap(),
            "--observations",
            bad.to_str().unwrap(),
        ]),
        "bad.csv: line 2",
    );
    let ok = write(&dir, "ok.csv", "frame,x,y,z\n1,0.0,1.0,0.0\n");
    one_line_error(
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
