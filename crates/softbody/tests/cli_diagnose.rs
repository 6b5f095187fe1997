//! `softbody diagnose` end to end on a small held bar whose model lacks gravity: the JSON has
//! the fields of interface.md, gravity is named missing, the pictures and the history file are
//! written, and bad input gives one line naming the file or flag. `softbody demo` tells its
//! story with the fields of interface.md.

use std::path::{Path, PathBuf};
mod common;
use common::*;

/// The tiny bar of 8 steps ([`tiny_bar`]) with the model's `effects`.
fn scene(effects: &str) -> String {
    tiny_bar(8, &format!("[model]\neffects = [{effects}]"))
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn diagnose_finds_missing_gravity() {
    let dir = tmp("diagnose", "gravity");
    let truth = scene("\"gravity\", \"corotation\"");
    let model = write(&dir, "model.toml", &scene("\"corotation\""));
    let (obs, _) = observed(&dir, &truth, &["--cameras", "3", "--pixels", "32"]);
    let out = dir.join("report");
    let diagnose = || run_on("diagnose", &model, &obs, &out, &["--json"]);
    let v = json(&diagnose());
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
    json(&diagnose());
    assert_eq!(std::fs::read_to_string(&hist).unwrap().lines().count(), 2);
    assert!(out.join("history.png").exists());
    // the history is a by-product: a line cut short by a killed run is left out, said with
    // its line, and the next entry starts its own line
    let text = std::fs::read_to_string(&hist).unwrap();
    std::fs::write(&hist, format!("{text}{}", &text[..text.len() / 4])).unwrap();
    let o = diagnose();
    let v = json(&o);
    assert!(
        stderr(&o).contains("line 3 is not a history entry"),
        "{}",
        stderr(&o)
    );
    assert_eq!(v["history"], hist.to_str().unwrap());
    let lines: Vec<String> = std::fs::read_to_string(&hist)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(lines.len(), 4);
    assert!(serde_json::from_str::<serde_json::Value>(&lines[3]).is_ok());
    // a history that cannot be written (a folder in its place, as a read-only data folder
    // would refuse it) costs only the entry, not the report
    std::fs::remove_file(&hist).unwrap();
    std::fs::create_dir(&hist).unwrap();
    std::fs::remove_dir_all(&out).unwrap();
    let o = diagnose();
    let v = json(&o);
    assert!(v["history"].is_null(), "{}", v["history"]);
    assert!(
        stderr(&o).contains("the run is not in the scene's history"),
        "{}",
        stderr(&o)
    );
    assert!(out.join("diagnosis.json").exists() && out.join("history.png").exists());
}

#[test]
fn diagnose_bad_input() {
    let dir = tmp("diagnose", "bad");
    let model = write(&dir, "model.toml", &scene("\"corotation\""));
    let diagnose = |obs: &Path, flags: &[&str]| {
        let (m, o) = (model.to_str().unwrap(), obs.to_str().unwrap());
        run(&[&["diagnose", m, "--observations", o], flags].concat())
    };
    one_line_error(&diagnose(&dir.join("nope.csv"), &[]), "nope.csv");
    let bad = write(&dir, "bad.csv", "frame,x,y,z\n1,0.0,1.0,zero\n");
    one_line_error(&diagnose(&bad, &[]), "bad.csv: line 2");
    let ok = write(&dir, "ok.csv", "frame,x,y,z\n1,0.0,1.0,0.0\n");
    one_line_error(&diagnose(&ok, &["--cost", "levelset"]), "--cost");
}
