//! Issue 13, "Panics and aborts": inputs a user can give that used to panic or abort the
//! process (a stiffness field fitted from the CLI, frame ranges and step counts beyond any
//! plausible size, `--json` into a closed pipe or a full disk, an `.sdf` that is an endless
//! stream) now give a result or a one-line error with exit code 1, never a panic.

use std::path::{Path, PathBuf};
mod common;
use common::*;

/// A tiny cantilever (Young's modulus `young`), 4 steps; `extra` is appended.
fn scene(young: f64, extra: &str) -> String {
    format!(
        r#"
[body]
shape = {{ kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }}
resolution = 10
[material]
young = {young}
poisson = 0.3
[gravity]
acceleration = [0.0, -10.0, 0.0]
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[time]
dt = 0.01
steps = 4
{extra}
"#
    )
}

/// Observations of the truth (E = 2000) written by `observe`.
fn observe(dir: &Path) -> PathBuf {
    let truth = write(dir, "truth.toml", &scene(2000.0, ""));
    let obs = dir.join("obs.csv");
    let j = json(&run(&[
        "observe",
        truth.to_str().unwrap(),
        "--out",
        obs.to_str().unwrap(),
        "--json",
    ]));
    assert!(j["points"].as_u64().unwrap() > 100);
    obs
}

#[test]
fn fit_a_stiffness_field_from_the_cli() {
    let dir = tmp("robust", "field");
    let obs = observe(&dir);
    let field = "[model]\neffects = [\"gravity\", \"corotation\", \"stiffness_field\"]\n\
                 stiffness_field = { cells = [1, 1, 1] }\n";
    let start = write(&dir, "start.toml", &scene(3000.0, field));
    let o = run(&[
        "fit",
        start.to_str().unwrap(),
        "--observations",
        obs.to_str().unwrap(),
        "--params",
        "stiffness_field",
        "--iterations",
        "3",
        "--no-refine-check",
        "--out",
        dir.join("report").to_str().unwrap(),
        "--json",
    ]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
    let j = json(&o);
    // 2 x 2 x 2 coefficients; the stiffer start is softened towards the truth
    let x = j["history"].as_array().unwrap().last().unwrap()["x"]
        .as_array()
        .unwrap()
        .len();
    assert_eq!(x, 8);
    let max = j["parameters"]["stiffness_field.max_factor"].as_f64().unwrap();
    assert!(max < 1.0, "max factor {max}");
    let rms = &j["rms"];
    assert!(rms["final"].as_f64().unwrap() < 0.5 * rms["initial"].as_f64().unwrap());
}
