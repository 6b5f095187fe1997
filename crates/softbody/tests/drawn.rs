//! The model against scenarios drawn at random by the independent reference generator
//! (`tools/reference/draw.py`: scikit-fem, Q2 hexahedra and curved P2 tetrahedra, consistent
//! mass, each effect in the form the literature uses; `tools/reference/README.md`, "Drawn
//! scenarios"). CI runs a fixed small subset of the calibration set: the first four seeds
//! whose reference passed its own mesh and time convergence check (`truth.json`,
//! `convergence.converged`; a draw whose reference is not converged cannot judge our model),
//! a rule fixed before any of our results on them was seen; the table over the whole
//! calibration set and over fresh test draws is made by `tools/reference/evaluate.py`
//! (`docs/simulation.md`, "Defaults on drawn scenarios").
//!
//! Each draw is used as a user would: its committed scene (the true parameters, the effects of
//! the truth, every numeric choice at its default, resolution 20) and its observations through
//! `softbody fit --iterations 0`, whose rms is compared with the reference's noise floor (the
//! rms distance of the noisy points to the true surface, along each point's viewing ray for
//! depth cameras, as our cost measures them): at most 1.15x on uniform surface points and 1.3x
//! on depth cameras (issue 49's targets).

mod common;

use common::{json, tmp};
use serde_json::Value;
use std::path::PathBuf;

/// How many calibration draws CI runs.
const CI_DRAWS: usize = 4;

fn calibration() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/reference_values/drawn/calibration")
}

/// The calibration draws CI runs: the first [`CI_DRAWS`] by seed whose reference converged.
fn ci_subset() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(calibration())
        .expect("tests/reference_values/drawn/calibration")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('c'))
        .collect();
    names.sort();
    let subset: Vec<String> = names
        .into_iter()
        .filter(|n| truth(n)["convergence"]["converged"] == true)
        .take(CI_DRAWS)
        .collect();
    assert_eq!(subset.len(), CI_DRAWS, "converged calibration draws: {subset:?}");
    subset
}

fn draw(name: &str) -> PathBuf {
    calibration().join(name)
}

fn truth(name: &str) -> Value {
    let path = draw(name).join("truth.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// The rms of draw `name` at its true parameters over its noise floor, and the target.
fn at_the_truth(name: &str) -> (f64, f64) {
    let t = truth(name);
    // as our cost measures a point: along its viewing ray where its camera is known
    let cameras = t["scenario"]["observation"] == "cameras";
    let key = if cameras {
        "noise_floor_camera_rays"
    } else {
        "noise_floor"
    };
    let floor = t[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{name}: truth.json has no {key}"));
    let target = if cameras { 1.3 } else { 1.15 };
    // the scene is copied: a fit writes its history beside the scene
    let dir = tmp("drawn", name);
    let text = std::fs::read_to_string(draw(name).join("scene.toml")).unwrap();
    let scene = common::write(&dir, "scene.toml", &text);
    let obs = draw(name).join("observations.csv");
    let out = dir.join("report");
    let flags = ["--iterations", "0", "--no-refine-check", "--json"];
    let r = json(&common::run_on("fit", &scene, &obs, &out, &flags));
    let rms = r["rms"]["final"].as_f64().unwrap();
    let s = &t["scenario"];
    println!(
        "{name} ({} {} {} {} {}, sigma {}): rms {rms:.5}, noise floor {floor:.5}: {:.3}x (target {target}x)",
        s["geometry"],
        s["clamp"],
        s["motion"],
        s["effects"],
        s["observation"],
        s["sigma"],
        rms / floor
    );
    (rms / floor, target)
}

/// Draws of the subset our defaults miss today, each with what was measured: the test fails
/// when one of them is met (remove it from this list then) as when any other draw is missed.
/// (c0009, a plate thrown under wind seen by a depth camera, was one at 2.04x until the plate's
/// edges were kept sharp by the exact distance: 1.221x.)
const KNOWN_MISSES: [(&str, &str); 1] = [(
    "c0001",
    "a plate swinging at 9 frames per period: one step per frame misses by 4.2x; 4 substeps \
     1.5x (docs/simulation.md, \"Defaults on drawn scenarios\")",
)];

/// Every draw of the subset is within the target at its true parameters, but the known misses.
#[test]
fn the_model_at_the_truth_is_within_the_noise_on_the_ci_draws() {
    let subset = ci_subset();
    let mut misses = Vec::new();
    for name in subset.iter().cloned() {
        let (ratio, target) = at_the_truth(&name);
        if ratio > target {
            misses.push(name);
        }
    }
    let known: Vec<String> = KNOWN_MISSES
        .iter()
        .filter(|(n, _)| subset.iter().any(|c| c == n))
        .map(|(n, _)| n.to_string())
        .collect();
    for (n, why) in KNOWN_MISSES {
        println!("known miss {n}: {why}");
    }
    assert_eq!(
        misses, known,
        "draws missed (left) against the known misses (right)"
    );
}
