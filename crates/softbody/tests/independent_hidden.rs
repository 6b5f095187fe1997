//! The diagnosis on data nobody here generated: the hidden-effect cases of the independent
//! reference (`tools/reference/hidden.py`, scikit-fem; `tests/reference_values/independent/
//! hidden`), run through `softbody diagnose` exactly as a user would, checked against the
//! diagnosis issue's targets. The fast subset: the cases observed by 120 area samples per frame
//! with noise 0.01, but for the two slowest (the stiffness field and the clamp, about a minute
//! each; the full table over every case, three styles and five noise levels is Table H of the
//! `tables` binary, docs/effects.md), and the control seen by the depth camera at the smallest
//! noise (the noise floor's hardest case).
//!
//! Targets, per case (margin = rms of the model as given / the true noise sigma):
//! - a hidden effect with margin >= 1.5 is named first and called missing, and after its refit
//!   the rms is at most 1.3 sigma (or a third of the rms as given); or the verdict names it as
//!   an alternative that the data cannot tell from the effect named first (Delta BIC within the
//!   threshold): on this slender bar Rayleigh mass damping and surface drag slow every section
//!   alike (its surface per volume is the same along the bar), their refits reach the same rms
//!   (measured: 0.0097064 and 0.0097073 at noise 0.01) and the BIC prefers drag's one parameter;
//! - a control (nothing hidden: the bar as it is, with a stiff inclusion too small to see, or
//!   with an effect at its true strength that the scene already has and fits) has nothing
//!   called missing;
//! - the stated noise floor is within 20% of sigma.

mod common;

use common::{json, tmp};
use serde_json::Value;
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/reference_values/independent/hidden")
}

/// The case `name` (`<case>/<style>-<sigma>`) of `cases.json`.
fn case(name: &str) -> Value {
    let index: Value =
        serde_json::from_str(&std::fs::read_to_string(dir().join("cases.json")).unwrap()).unwrap();
    index["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["case"] == name)
        .unwrap_or_else(|| panic!("no case {name} in cases.json"))
        .clone()
}

/// Diagnoses case `name`, checks the targets (module docs) and returns `diagnosis.json`.
fn check(name: &str) -> Value {
    let c = case(name);
    let sigma = c["sigma"].as_f64().unwrap();
    let hidden = c["hidden"].as_str();
    let out = tmp("independent_hidden", &name.replace('/', "_"));
    let o = common::run_on(
        "diagnose",
        &dir().join(c["scene"].as_str().unwrap()),
        &dir().join(c["observations"].as_str().unwrap()),
        &out,
        &["--json"],
    );
    let d = json(&o);
    let rms = d["rms"].as_f64().unwrap();
    let margin = rms / sigma;
    let floor = d["noise_floor"].as_f64().unwrap();
    let first = d["candidates"][0]["effect"].as_str();
    let missing = d["missing_effect"].as_str();
    println!(
        "{name}: hidden {hidden:?}, margin {margin:.2}, named first {first:?}, missing {missing:?}, floor {:.3} sigma ({}), verdict: {}",
        floor / sigma,
        d["noise_floor_method"],
        d["verdict"]
    );
    assert!(
        (floor / sigma - 1.0).abs() <= 0.2,
        "{name}: noise floor {floor} for sigma {sigma}"
    );
    match hidden {
        None => assert_eq!(missing, None, "{name}: a control, nothing should be missing"),
        Some(h) if margin >= 1.5 => {
            let tied = d["alternatives"]
                .as_array()
                .is_some_and(|a| a.iter().any(|e| e == h));
            assert!(missing.is_some(), "{name}: nothing called missing");
            assert_eq!(
                missing, first,
                "{name}: the missing effect is the one named first"
            );
            assert!(missing == Some(h) || tied, "{name}: {h} neither missing nor tied");
            let after = d["candidates"][0]["rms_after"].as_f64().unwrap();
            assert!(
                after <= 1.3 * sigma || after <= rms / 3.0,
                "{name}: rms after the refit {after} (sigma {sigma}, rms {rms})"
            );
        }
        Some(_) => {}
    }
    d
}

#[test]
fn control_bar_has_nothing_missing() {
    check("none/samples-0.01");
}

#[test]
fn control_inclusion_too_small_to_see_has_nothing_missing() {
    check("inclusion/samples-0.01");
}

#[test]
fn hidden_gravity() {
    check("gravity/samples-0.01");
}

#[test]
fn hidden_damping() {
    check("damping/samples-0.01");
}

#[test]
fn hidden_initial_velocity() {
    check("initial_velocity/samples-0.01");
}

#[test]
fn hidden_drag() {
    check("drag/samples-0.01");
}

#[test]
fn control_with_damping_in_the_scene_has_nothing_missing() {
    check("complete-damping/samples-0.01");
}

#[test]
fn control_with_drag_in_the_scene_has_nothing_missing() {
    check("complete-drag/samples-0.01");
}

#[test]
fn control_with_the_clamp_in_the_scene_has_nothing_missing() {
    check("complete-clamp/samples-0.01");
}

#[test]
fn control_with_the_initial_velocity_in_the_scene_has_nothing_missing() {
    check("complete-initial_velocity/samples-0.01");
}

/// Geometric nonlinearity (the reference is St. Venant-Kirchhoff; the scene linear).
/// Below the margin of the targets (1.12 sigma), and still found (measured: Delta BIC -608).
#[test]
fn hidden_corotation() {
    let d = check("corotation/samples-0.01");
    assert_eq!(d["missing_effect"], "corotation", "verdict: {}", d["verdict"]);
}

#[test]
fn control_with_corotation_in_the_scene_has_nothing_missing() {
    check("complete-corotation/samples-0.01");
}

/// The depth camera at the smallest noise, where the model's own error is about the noise: the
/// depth images' floor reads 1.24 sigma there, the residuals' (the smaller, stated) within 20%.
#[test]
fn control_seen_by_the_depth_camera_at_the_smallest_noise() {
    check("none/camera-0.0025");
}

/// Ground friction (`tools/reference/sliding.py`: a soft box lands while it moves sideways and
/// slides to a stop; viscous friction with the reference's own contact and Newton solver; the
/// scene states the reference's penalty ground). Measured: margin 4.81, friction named first,
/// rms after its refit 0.96 sigma.
#[test]
fn hidden_friction() {
    let d = check("friction/samples-0.01");
    assert_eq!(d["missing_effect"], "friction", "verdict: {}", d["verdict"]);
}

/// Its control: friction in the scene at its true strength, fitted with E and nu (a contact
/// case; with our softmin ground in the scene instead of the reference's law it was a false
/// alarm at the smaller noise levels, docs/effects.md, "Ground friction").
#[test]
fn control_with_friction_in_the_scene_has_nothing_missing() {
    check("complete-friction/samples-0.01");
}
