//! The model against "the real world": observations computed by an independent finite element
//! code (`tools/reference/generate.py`, scikit-fem, Q2 hexahedra, Newmark; the committed
//! outputs in `tests/reference_values/independent`), used exactly as a user would, through
//! `softbody fit` on the committed scene at its default resolution and default numerics (the
//! incompatible element, the consistent Nitsche clamp, the surface from an SDF twice as fine;
//! `docs/simulation.md`); the block's scene asks for the dual-contouring surface, which keeps
//! its edges.
//!
//! - with every true parameter, the rms distance of the cantilever's, the block's and the
//!   bouncing sphere's observed points to our surface is at most 1.15 times the noise floor (the rms a perfect model would
//!   reach);
//! - a fit of Young's modulus and Poisson's ratio from a wrong start recovers the cantilever's
//!   modulus within 3% (its Poisson's ratio is not identifiable from this motion: the cost
//!   changes by 0.3% between nu = 0.07 and 0.48, and the fit's own standard error for it is
//!   about 0.05; it is printed, not asserted), and the block's modulus within 3% and its
//!   Poisson's ratio within 0.03 (standard error 0.011; the block's lateral bulge under its
//!   own weight shows nu);
//! - the same bar as the cantilever, swinging while it twists about its own axis (`twist`):
//!   torsion sees the shear modulus, bending Young's modulus, so this motion determines nu
//!   (standard error 0.002): E within 3% and nu within 0.03 with the consistent mass (its
//!   scene's `[numerics] mass`).
//!   The lumped mass gives nu 0.22 there (its bar's polar moment of inertia is 10% too large,
//!   `cutfem::fem::assembly::mass`), asserted as well: the test tells the two apart.

mod common;

use common::{json, tmp};
use serde_json::Value;
use std::path::PathBuf;

fn case(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/reference_values/independent")
        .join(name)
}

fn truth(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(case(name).join("truth.json")).unwrap()).unwrap()
}

/// The committed scene of case `name`, `young` and `poisson` replaced when given, written to a
/// scratch folder.
fn scene(name: &str, tag: &str, start: Option<(f64, f64)>) -> PathBuf {
    let t = truth(name);
    let (young, poisson) = (
        t["parameters"]["young"].as_f64().unwrap(),
        t["parameters"]["poisson"].as_f64().unwrap(),
    );
    let mut text = std::fs::read_to_string(case(name).join("scene.toml")).unwrap();
    if let Some((e, nu)) = start {
        text = text
            .replace(&format!("young = {young:.1}\n"), &format!("young = {e:.1}\n"))
            .replace(&format!("poisson = {poisson}\n"), &format!("poisson = {nu}\n"));
        assert!(text.contains(&format!("young = {e:.1}\n")) && text.contains(&format!("poisson = {nu}\n")));
    }
    // default numerics, but for the block's surface (a body with sharp edges) and the
    // twisting bar's mass
    let numerics = text.find("[numerics]").map(|i| text[i..].trim().to_string());
    let block = "[numerics]\nsurface_method = \"dual_contouring\"";
    let twist = "[numerics]\nmass = \"consistent\"";
    assert!(
        numerics.is_none()
            || (name == "block" && numerics.as_deref() == Some(block))
            || (name == "twist" && numerics.as_deref() == Some(twist))
    );
    common::write(&tmp("independent", tag), "scene.toml", &text)
}

/// `softbody fit` of `scene` on the observations of case `name`, the report in a scratch
/// folder of its own (`tag`).
fn fit(name: &str, tag: &str, scene: &std::path::Path, extra: &[&str]) -> Value {
    let out = tmp("independent", &format!("{tag}-report"));
    let obs = case(name).join("observations.csv");
    let flags = [&["--no-refine-check", "--json"], extra].concat();
    json(&common::run_on("fit", scene, &obs, &out, &flags))
}

/// The rms of case `name` at its true parameters, against its noise floor (returned as rms /
/// floor).
fn at_the_truth(name: &str) -> f64 {
    let floor = truth(name)["noise_floor"].as_f64().unwrap();
    let tag = format!("{name}-truth");
    let scene = scene(name, &tag, None);
    let rms = fit(name, &tag, &scene, &["--iterations", "0"])["rms"]["final"]
        .as_f64()
        .unwrap();
    println!(
        "{name} at the truth: rms {rms:.5}, noise floor {floor:.5} ({:.3}x)",
        rms / floor
    );
    assert!(rms <= 1.15 * floor, "{name}: rms {rms} vs noise floor {floor}");
    rms / floor
}

#[test]
fn cantilever_at_the_truth_is_within_the_noise() {
    at_the_truth("cantilever");
}

/// The block's box edges: a marching-cubes surface bevels them (1.53x the noise floor on the
/// grid itself, 1.09x from the SDF twice as fine); dual contouring (its scene's
/// `surface_method`) keeps them (1.0001x): the motion itself matches the reference.
#[test]
fn block_at_the_truth_is_within_the_noise() {
    let ratio = at_the_truth("block");
    assert!(
        ratio <= 1.03,
        "block: {ratio}x the noise floor: are its edges bevelled?"
    );
}

/// The sphere lands three times; its scene integrates each frame in two steps
/// (`[time] substeps = 2`; 1.19x the noise floor with one).
#[test]
fn ground_at_the_truth_is_within_the_noise() {
    at_the_truth("ground");
}

/// A Gauss-Newton fit of E and nu on case `name` from `start`: the fitted E, nu and the true
/// ones.
fn fit_young_and_poisson(name: &str, start: (f64, f64)) -> [f64; 4] {
    fit_young_and_poisson_edited(name, "start", start, |text| text)
}

/// The same with the scene's text passed through `edit` (scratch folder `tag`).
fn fit_young_and_poisson_edited(
    name: &str,
    tag: &str,
    start: (f64, f64),
    edit: impl Fn(String) -> String,
) -> [f64; 4] {
    let t = truth(name);
    let (young, poisson) = (
        t["parameters"]["young"].as_f64().unwrap(),
        t["parameters"]["poisson"].as_f64().unwrap(),
    );
    let tag = format!("{name}-{tag}");
    let scene = scene(name, &tag, Some(start));
    let text = edit(std::fs::read_to_string(&scene).unwrap());
    let scene = common::write(&tmp("independent", &tag), "scene.toml", &text);
    let r = fit(
        name,
        &tag,
        &scene,
        &[
            "--params",
            "young,poisson",
            "--optimizer",
            "gauss-newton",
            "--iterations",
            "12",
        ],
    );
    let e = r["parameters"]["young"].as_f64().unwrap();
    let nu = r["parameters"]["poisson"].as_f64().unwrap();
    println!(
        "{name} fit: E {e:.2} (true {young}, {:+.2}%), nu {nu:.4} (true {poisson}, standard error {}), rms {}",
        100.0 * (e / young - 1.0),
        r["standard_errors"]["poisson"],
        r["rms"]["final"]
    );
    [e, nu, young, poisson]
}

#[test]
fn cantilever_fit_recovers_young_within_three_percent() {
    let [e, _, young, _] = fit_young_and_poisson("cantilever", (1800.0, 0.25));
    assert!((e / young - 1.0).abs() <= 0.03, "E {e} vs {young}");
}

/// The targets on the block (measured: E 100.48, nu 0.3286, standard error of nu
/// 0.011; on the same reference run without noise the fit gives nu 0.3034, so most of the
/// offset is this draw of the noise, not the model).
#[test]
fn block_fit_recovers_young_within_three_percent_and_poisson_within_003() {
    let [e, nu, young, poisson] = fit_young_and_poisson("block", (90.0, 0.25));
    assert!((e / young - 1.0).abs() <= 0.03, "E {e} vs {young}");
    assert!((nu - poisson).abs() <= 0.03, "nu {nu} vs {poisson}");
}

/// The twisting bar at the truth (1.09x the noise floor with the lumped mass, 1.04x with the
/// consistent one).
#[test]
fn twist_at_the_truth_is_within_the_noise() {
    at_the_truth("twist");
}

/// The targets on the twisting bar (measured: E 2354.8 (-1.9%), nu 0.3548, standard
/// error 0.0021, the box's edges kept sharp to a sub-cell; with the spline's rounded edges it
/// was E 2366.9, nu 0.3302).
#[test]
fn twist_fit_recovers_young_within_three_percent_and_poisson_within_003() {
    let [e, nu, young, poisson] = fit_young_and_poisson("twist", (1800.0, 0.25));
    assert!((e / young - 1.0).abs() <= 0.03, "E {e} vs {young}");
    assert!((nu - poisson).abs() <= 0.03, "nu {nu} vs {poisson}");
}

/// The same fit with `[numerics] mass = "lumped"` (the thesis' diagonal mass) misses nu: the
/// twist's frequencies are too low with the lumped polar inertia, `2 h^2 / a^2` (10% at 4.4
/// cells across) too large, and the fit raises the shear modulus `G = E / (2 (1 + nu))` by as
/// much instead. Measured against the consistent mass' fit: `G` +10.2% for `2 h^2 / a^2 =`
/// 10.3% (nu 0.250, E 2395); the cause of the miss is the mass, not the element or the clamp.
#[test]
fn twist_fit_with_the_lumped_mass_misses_poisson() {
    let lumped = |text: String| {
        let text = text.replace("mass = \"consistent\"", "mass = \"lumped\"");
        assert!(text.contains("mass = \"lumped\""));
        text
    };
    let [e_l, nu_l, _, poisson] = fit_young_and_poisson_edited("twist", "lumped", (1800.0, 0.25), lumped);
    let [e_c, nu_c, _, _] = fit_young_and_poisson_edited("twist", "consistent", (1800.0, 0.25), |t| t);
    let shear = |e: f64, nu: f64| e / (2.0 * (1.0 + nu));
    let raised = shear(e_l, nu_l) / shear(e_c, nu_c) - 1.0;
    let (h, a) = (1.0 / 20.0, 0.22);
    let excess = 2.0 * h * h / (a * a);
    println!("twist: lumped raises G by {raised:+.4} (2 h^2 / a^2 = {excess:.4})");
    assert!(
        (raised - excess).abs() < 0.3 * excess,
        "G {raised:+.4} vs {excess:.4}"
    );
    assert!(nu_l < poisson - 0.05, "nu {nu_l} vs {poisson}");
}
