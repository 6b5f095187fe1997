//! `softbody observe` + `fit` + `gradcheck` end to end on a small bar: the fit recovers the
//! truth from noise-free observations, the log survives and `--resume` continues it, the
//! gradient check agrees, and bad input gives one line naming the file (and line) or key.

use std::path::{Path, PathBuf};
mod common;
use common::*;

/// The tiny bar of 8 steps ([`tiny_bar`]), damped, with `young` and `poisson` and a `[fit]` of
/// both by Gauss-Newton.
fn scene(young: f64, poisson: f64) -> String {
    let extra = "[damping]\nmass = 0.1\nstiffness = 0.01\n\
                 [fit]\nparameters = [\"young\", \"poisson\"]\noptimizer = \"gauss-newton\"\n\
                 iterations = 15";
    let (young, poisson) = (format!("young = {young:?}"), format!("poisson = {poisson:?}"));
    edited(
        &tiny_bar(8, extra),
        &[("young = 2000.0", &young), ("poisson = 0.3", &poisson)],
    )
}

/// Observations of the truth (E = 2000, nu = 0.3) with 4 cameras.
fn observe(dir: &Path) -> PathBuf {
    let (obs, j) = observed(dir, &scene(2000.0, 0.3), &["--radius", "2"]);
    assert!(j["points"].as_u64().unwrap() > 500);
    obs
}

#[test]
fn fit_recovers_the_truth_and_resumes() {
    let dir = tmp("fit", "recover");
    let obs = observe(&dir);
    let start = write(&dir, "start.toml", &scene(2600.0, 0.35));
    let out = dir.join("report");
    let o = run_on("fit", &start, &obs, &out, &["--json"]);
    let j = json(&o);
    let e = j["parameters"]["young"].as_f64().unwrap();
    let nu = j["parameters"]["poisson"].as_f64().unwrap();
    assert!((e / 2000.0 - 1.0).abs() < 1e-3, "E = {e}");
    assert!((nu / 0.3 - 1.0).abs() < 1e-3, "nu = {nu}");
    assert_eq!(j["initial_parameters"]["young"].as_f64().unwrap().round(), 2600.0);
    // noise-free: the standard errors are tiny
    let se = j["standard_errors"]["young"].as_f64().unwrap();
    assert!(se >= 0.0 && se < 1e-2 * e, "se(E) = {se}");
    assert!(j["rms"]["final"].as_f64().unwrap() < 1e-3 * j["rms"]["initial"].as_f64().unwrap());
    assert!(j["cost"]["final"].as_f64().unwrap() < j["cost"]["initial"].as_f64().unwrap());
    let history = j["history"].as_array().unwrap();
    assert_eq!(history.len() as u64, j["iterations"].as_u64().unwrap() + 1);
    // the discretisation check of the fitted model, against the observations' noise floor
    let d = &j["discretisation"];
    assert!(d["difference"].as_f64().unwrap() > 0.0, "{d}");
    assert!(d["noise_floor"].as_f64().unwrap() >= 0.0, "{d}");
    assert!(d["share"].is_number(), "{d}");
    for f in [
        "fit.json",
        "fit.log",
        "cost.png",
        "parameters.png",
        "rms_per_frame.png",
        "uncertainty.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let log = std::fs::read_to_string(out.join("fit.log")).unwrap();
    assert_eq!(log.lines().count(), history.len());

    // an interrupted fit: keep the first two logged iterations and half of the third (a kill
    // while it was written), then resume
    let kept: Vec<&str> = log.lines().take(3).collect();
    let torn = &kept[2][..kept[2].len() / 2];
    std::fs::write(out.join("fit.log"), format!("{}\n{}\n{torn}", kept[0], kept[1])).unwrap();
    let o = run_on(
        "fit",
        &start,
        &obs,
        &out,
        &["--resume", "--no-refine-check", "--json"],
    );
    let j = json(&o);
    let h = j["history"].as_array().unwrap();
    assert_eq!(h[0]["iteration"], 0);
    assert_eq!(h[1]["iteration"], 1);
    assert_eq!(h[2]["iteration"], 2, "resumed iterations continue the numbering");
    let e = j["parameters"]["young"].as_f64().unwrap();
    assert!((e / 2000.0 - 1.0).abs() < 1e-3, "resumed E = {e}");
    let log = std::fs::read_to_string(out.join("fit.log")).unwrap();
    assert_eq!(log.lines().count(), h.len());
    assert!(j["discretisation"].is_null(), "--no-refine-check skips it");
    // a log of other parameters is not this fit's start: refused, the report left as it was
    let before = std::fs::read(out.join("fit.json")).unwrap();
    let o = run_on(
        "fit",
        &start,
        &obs,
        &out,
        &["--params", "young,density", "--resume"],
    );
    one_line_error(
        &o,
        "the log is of a fit of poisson,young, this fit is of density,young",
    );
    assert_eq!(std::fs::read(out.join("fit.json")).unwrap(), before);
    // a log whose last point cannot be simulated: the error says the start came from the log
    let log = std::fs::read_to_string(out.join("fit.log")).unwrap();
    let mut last: serde_json::Value = serde_json::from_str(log.lines().last().unwrap()).unwrap();
    last["x"] = serde_json::json!([1e300, 0.5]);
    std::fs::write(out.join("fit.log"), format!("{log}{last}\n")).unwrap();
    let o = run_on("fit", &start, &obs, &out, &["--resume"]);
    one_line_error(&o, "resumed from the last entry of");
    assert_eq!(std::fs::read(out.join("fit.json")).unwrap(), before);
}

#[test]
fn gradcheck_agrees_and_bad_input_is_one_line() {
    let dir = tmp("fit", "check");
    let obs = observe(&dir);
    let start = write(&dir, "start.toml", &scene(2400.0, 0.32));
    let s = start.to_str().unwrap();
    let ob = obs.to_str().unwrap();
    let j = json(&run(&[
        "gradcheck",
        s,
        "--observations",
        ob,
        "--params",
        "young,poisson,gravity",
        "--json",
    ]));
    for name in ["young", "poisson", "gravity.y"] {
        let r = &j["parameters"][name];
        let rel = r["rel_error"].as_f64().unwrap();
        assert!(rel < 1e-4, "{name}: {r}");
        assert!(r["adjoint"].as_f64().unwrap() != 0.0);
        // the sweep: the adjoint-corrected Taylor remainder falls at second order
        assert_eq!(r["smoothness"], "smooth", "{name}: {}", r["verdict"]);
        assert_eq!(r["verified"], true);
        let p = r["corrected_order"].as_f64().unwrap();
        assert!((1.8..=2.2).contains(&p), "{name}: corrected order {p}");
        let p = r["order"].as_f64().unwrap();
        assert!((0.8..=1.2).contains(&p), "{name}: first order {p}");
        assert!(r["sweep"].as_array().unwrap().len() >= 4, "{name}: {r}");
    }
    assert_eq!(j["steps"].as_array().unwrap().len(), 8);
    assert!(
        j["non_smooth"].as_array().unwrap().is_empty(),
        "{}",
        j["non_smooth"]
    );

    // unknown parameter
    one_line_error(
        &run(&["fit", s, "--observations", ob, "--params", "youngs"]),
        "unknown parameter `youngs`",
    );
    // unknown optimizer
    one_line_error(
        &run(&["fit", s, "--observations", ob, "--optimizer", "adam"]),
        "unknown optimizer",
    );
    // a frame beyond the simulated steps: the file and line are named
    let late = write(&dir, "late.csv", "frame,x,y,z\n1,0,1,0\n40,0.1,1,0\n");
    one_line_error(
        &run(&["fit", s, "--observations", late.to_str().unwrap()]),
        "late.csv:3: frame 40 lies beyond the 8 simulated steps",
    );
    // a line that does not parse
    let bad = write(&dir, "bad.csv", "frame,x,y,z\n1,0,1,0\n2,0.1,nan,0\n");
    one_line_error(
        &run(&["fit", s, "--observations", bad.to_str().unwrap()]),
        "line 3",
    );
    // observations nowhere near the body: an error, not a zero gradient
    let far = write(&dir, "far.csv", "frame,x,y,z\n1,50,50,50\n2,51,50,50\n");
    one_line_error(
        &run(&["fit", s, "--observations", far.to_str().unwrap()]),
        "within reach",
    );
    // a bad [fit] key names the key
    let badfit = write(
        &dir,
        "badfit.toml",
        &edited(&scene(2000.0, 0.3), &[("iterations = 15", "iteration = 15")]),
    );
    one_line_error(
        &run(&["fit", badfit.to_str().unwrap(), "--observations", ob]),
        "[fit].iteration: unknown key",
    );
}
