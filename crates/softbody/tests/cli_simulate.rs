//! `softbody simulate` end to end: a small scene runs and writes its files and JSON; bad input
//! gives one line on stderr, a non-zero exit code and no panic.

use std::path::{Path, PathBuf};
use std::process::Output;
mod common;
use common::*;

/// Writes `text` to `dir/name` and runs `softbody simulate` on it into `dir/out` with `flags`:
/// its output and that folder.
fn simulate(dir: &Path, name: &str, text: &str, flags: &[&str]) -> (Output, PathBuf) {
    let scene = write(dir, name, text);
    let out = dir.join("out");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    (run(&[&["simulate", s, "--out", o], flags].concat()), out)
}

#[test]
fn simulate_writes_frames_picture_and_json() {
    let dir = tmp("cli", "ok");
    let (o, out) = simulate(&dir, "small.toml", &tiny_bar(4, ""), &["--json"]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("exactly one JSON object");
    for key in ["nodes", "cells", "steps", "seconds", "solver", "final"] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["steps"], 4);
    assert!(v["nodes"]["active"].as_u64().unwrap() > 0);
    assert_eq!(v["solver"]["iterations"].as_array().unwrap().len(), 4);
    assert_eq!(v["solver"]["preconditioner"], "block_ic0");
    assert_eq!(v["solver"]["backend"], "cpu");
    // one incomplete factorization a step
    assert_eq!(v["solver"]["factorizations"], 4);
    assert!(v["final"]["max_displacement"].as_f64().unwrap() > 0.0);
    for f in 0..=4 {
        assert!(out.join(format!("frames/{f:04}.ply")).exists(), "frame {f}");
    }
    let png = std::fs::read(out.join("picture.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}

fn expect_error(scene_text: &str, needle: &str) {
    let dir = tmp("cli", &needle.replace(|c: char| !c.is_alphanumeric(), "_"));
    let (o, _) = simulate(&dir, "bad.toml", scene_text, &[]);
    one_line_error(&o, needle);
}

#[test]
fn bad_parameters_are_one_line_errors() {
    expect_error(
        &edited(&tiny_bar(4, ""), &[("young = 2000.0", "young = -5.0")]),
        "material.young",
    );
    expect_error(
        &edited(&tiny_bar(4, ""), &[("poisson = 0.3", "poisson = 0.5")]),
        "material.poisson",
    );
    expect_error(&edited(&tiny_bar(4, ""), &[("dt = 0.01", "dt = 0.0")]), "time.dt");
    expect_error(&tiny_bar(4, "theta = 1.0\n"), "time.theta");
    expect_error(
        &edited(
            &tiny_bar(4, ""),
            &[
                ("min = [-1.0, 0.0, -1.0]", "min = [5.0, 5.0, 5.0]"),
                ("max = [-0.2, 2.0, 1.0]", "max = [6.0, 6.0, 6.0]"),
            ],
        ),
        "dirichlet[0]",
    );
    expect_error(
        &edited(
            &tiny_bar(4, ""),
            &[("young = 2000.0", "young = 2000.0\nyoungs = 3.0")],
        ),
        "unknown field",
    );
    expect_error(
        &edited(
            &tiny_bar(4, ""),
            &[(
                "[gravity]",
                "[model]\neffects = [\"gravity\", \"magic\"]\n[gravity]",
            )],
        ),
        "magic",
    );
    expect_error(
        &tiny_bar(4, "[numerics]\npreconditioner = \"amg\"\n"),
        "unknown variant `amg`, expected one of `block_jacobi`, `block_ic0`, `rest_cholesky`, `multigrid`",
    );
    expect_error(
        &tiny_bar(4, "[numerics]\nbackend = \"vulkan\"\n"),
        "unknown variant `vulkan`, expected `cpu` or `cuda`",
    );
    if !cfg!(feature = "cuda") {
        // a build without CUDA says so, naming the scene and the key
        expect_error(
            &tiny_bar(4, "[numerics]\nbackend = \"cuda\"\n"),
            "[numerics] backend = \"cuda\": CUDA backend unavailable: this build has no CUDA support",
        );
    }
}

/// `[numerics] preconditioner` picks the CG preconditioner; the summary names it and counts
/// its factorizations (one rest-state Cholesky factor serves every step of this short run).
#[test]
fn simulate_with_other_preconditioners() {
    for (name, factorizations) in [("block_ic0", 4), ("rest_cholesky", 1)] {
        let dir = tmp("cli", name);
        let text = tiny_bar(4, &format!("[numerics]\npreconditioner = \"{name}\"\n"));
        let (o, _) = simulate(&dir, "small.toml", &text, &["--json"]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["solver"]["preconditioner"], name);
        assert_eq!(v["solver"]["factorizations"], factorizations, "{name}");
        assert_eq!(v["solver"]["fallbacks"], 0);
    }
}

/// Steps that CG cannot solve within its iteration limit fall back to the direct solver: the
/// JSON counts them and the human output warns (it said nothing before).
#[test]
fn fallbacks_to_the_direct_solver_are_said() {
    let dir = tmp("cli", "fallbacks");
    let text = tiny_bar(3, "[numerics]\ncg_max_iterations = 2\nreuse_factor = false\n");
    let (o, _) = simulate(&dir, "small.toml", &text, &["--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["solver"]["fallbacks"], 3, "{}", v["solver"]);
    let (o, _) = simulate(&dir, "small.toml", &text, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("warning: CG did not reach its tolerance within 2 iterations in 3 of 3 steps"),
        "{err}"
    );
}

/// A ground above the body's bottom (a sign or unit slip) is said before the run, and the
/// JSON measures it; a body above the ground gets neither.
#[test]
fn a_body_that_starts_in_the_ground_is_warned_of() {
    let dir = tmp("cli", "penetration");
    let scene = |height: f64| {
        format!(
            "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = 0.3 }}\nresolution = 8\n\
             [material]\nyoung = 1000.0\npoisson = 0.3\n[ground]\nnormal = [0.0, 1.0, 0.0]\nheight = {height:?}\n\
             [time]\ndt = 0.01\nsteps = 1\n"
        )
    };
    let (o, _) = simulate(&dir, "in.toml", &scene(1.0), &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning: the body starts 0.3"), "{err}");
    let (o, _) = simulate(&dir, "in.toml", &scene(1.0), &["--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let depth = v["initial_penetration"]["depth"].as_f64().unwrap();
    assert!((depth - 0.3).abs() < 0.02, "{depth}");
    let (o, _) = simulate(&dir, "above.toml", &scene(0.5), &[]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("deep in the ground"));
}

#[test]
fn bad_bodies_are_one_line_errors() {
    let dir = tmp("cli", "bodies");
    // truncated .sdf
    let sdf = dir.join("trunc.sdf");
    let mut bytes = Vec::new();
    for v in [10i32, 0, 0, 0, 4, 4, 4] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(&[0u8; 10]);
    std::fs::write(&sdf, &bytes).unwrap();
    let body = format!("[body]\nsdf = \"{}\"\n", sdf.display());
    let bar = tiny_bar(4, "");
    let rest = bar.split_once("[material]").unwrap().1;
    expect_error(&format!("{body}[material]{rest}"), "trunc.sdf");
    // NaN values
    let sdf = dir.join("nan.sdf");
    let mut bytes = Vec::new();
    for v in [10i32, 0, 0, 0, 2, 2, 2] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for i in 0..8 {
        let v: f32 = if i == 3 { f32::NAN } else { 1.0 };
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(&sdf, &bytes).unwrap();
    let body = format!("[body]\nsdf = \"{}\"\n", sdf.display());
    expect_error(&format!("{body}[material]{rest}"), "nan.sdf");
    // missing file
    expect_error(
        &format!("[body]\nsdf = \"/nonexistent/x.sdf\"\n[material]{rest}"),
        "x.sdf",
    );
    // empty body: a sphere of radius 0.001 at resolution 10 has no inside node; the error
    // says how small it is against the cells
    let empty = edited(
        &bar,
        &[(
            "shape = { kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }",
            "shape = { kind = \"sphere\", center = [0.05, 1.05, 0.05], radius = 0.001 }",
        )],
    );
    expect_error(
        &empty,
        "body: no grid node lies inside the body: it spans 2.000e-3 x 2.000e-3 x 2.000e-3 and a grid cell is 1.000e-1; raise [body] resolution to 1.000e3 or more",
    );
    // a body too large for memory: refused before allocating
    let huge = edited(&bar, &[("resolution = 10", "resolution = 100000")]);
    expect_error(&huge, "resolution");
}

/// `--refine-check`: the run again at twice and half the resolution; the JSON reports the
/// difference of the surface motion, its observed order and the estimated error.
#[test]
fn simulate_refine_check_reports_the_discretisation_error() {
    let dir = tmp("cli", "refine");
    let flags = ["--refine-check", "--json"];
    let (o, _) = simulate(&dir, "small.toml", &tiny_bar(4, ""), &flags);
    ok(&o);
    let v = json(&o);
    let r = &v["refine_check"];
    assert_eq!(r["resolution"], 10.0);
    assert_eq!(r["finer_resolution"], 20.0);
    let d = r["difference"].as_f64().unwrap();
    let motion = r["motion"].as_f64().unwrap();
    assert!(d > 0.0 && d < motion, "{r}");
    assert!(r["estimate"].as_f64().unwrap() >= d);
    assert_eq!(r["per_frame"].as_array().unwrap().len(), 4);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("discretisation:"), "{stderr}");
}

/// A light box on the thesis' softmin ground (`scheme = "implicit"`: per-crossing springs,
/// softness 100) rests where
/// its bottom crossings' push before contact sums to its weight, about 0.1 above the plane:
/// `simulate` reports where the ground pushed (`ground_push`) and warns that the law holds the
/// body off the plane; on the penalty law (per unit area, no push before contact) the same box
/// sinks into the plane by its small depth and nothing is said.
#[test]
fn simulate_warns_when_the_ground_holds_the_body_off_the_plane() {
    let dir = tmp("cli", "hover");
    let scene = |center_y: f64, ground: &str| {
        format!(
            "[body]\nresolution = 20\nshape = {{ kind = \"box\", center = [0.0, {center_y}, 0.0], size = [0.4, 0.2, 0.4] }}\n\
             [material]\nyoung = 1000.0\npoisson = 0.3\ndensity = 1.0\n[damping]\nmass = 1.0\nstiffness = 0.01\n\
             [gravity]\nacceleration = [0.0, -10.0, 0.0]\n[ground]\n{ground}\n\
             [time]\ndt = 0.01\nsteps = 10\ntheta = 0.5\n\
             [model]\neffects = [\"gravity\", \"damping\", \"ground\"]\n"
        )
    };
    // the JSON `ground_push` and the text output of one scene
    let run = |name: &str, toml: &str| {
        let (o, _) = simulate(&dir, name, toml, &["--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let push = v["ground_push"].clone();
        eprintln!("{name}: {push}");
        let (o, _) = simulate(&dir, name, toml, &[]);
        let text = String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
        (push, text)
    };
    let (push, text) = run(
        "softmin.toml",
        &scene(0.2, "scheme = \"implicit\"\nstiffness = 1.0e4\nsoftness = 100.0"),
    );
    assert_eq!(push["hovers"], true, "{push}");
    assert_eq!(push["share_above_plane"], 1.0);
    assert!(push["mean_distance"].as_f64().unwrap() > 0.05, "{push}");
    assert!(text.contains("holds the body off the plane"), "{text}");

    let penalty = scene(0.1, "scheme = \"penalty\"\nstiffness = 1.0e5\nsoftness = 1.0e6");
    let (push, text) = run("penalty.toml", &penalty);
    assert_eq!(push["hovers"], false, "{push}");
    assert_eq!(push["share_above_plane"], 0.0);
    let d = push["mean_distance"].as_f64().unwrap();
    assert!(d < 0.0 && d > -1e-3, "{push}");
    assert!(!text.contains("off the plane"), "{text}");

    // a `[ground]` that names no law gets the per-area penalty: no push before contact
    let (push, text) = run("default.toml", &scene(0.1, ""));
    assert_eq!(push["hovers"], false, "{push}");
    let d = push["mean_distance"].as_f64().unwrap();
    assert!(d < 0.0 && d > -1e-3, "{push}");
    assert!(!text.contains("off the plane"), "{text}");
}
