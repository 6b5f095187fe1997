//! `softbody fit STUDY.toml` end to end: two recordings of the tiny bar (swinging from rest,
//! and pushed sideways) fitted jointly recover the shared material and the push's own initial
//! velocity; a study of one recording gives the single fit's parameters to the bit; bad study
//! files and flags that belong to one scene give one line naming the file or key.

use std::path::{Path, PathBuf};
mod common;
use common::*;

/// Observes the truth (E = 2000, nu = 0.3, push `vz`) into `dir/NAME.csv` (noise-free) and
/// writes the start scene `dir/NAME.toml` (E = 2600, nu = 0.35, push 0.8 vz).
fn recording(dir: &Path, name: &str, vz: f64) -> (PathBuf, PathBuf) {
    let obs = dir.join(format!("{name}.csv"));
    let truth = write(dir, &format!("{name}-truth.toml"), &launched_bar(2000.0, 0.3, vz));
    let j = observe_json(&truth, &obs, &["--radius", "2"]);
    assert!(j["points"].as_u64().unwrap() > 500);
    (
        write(
            dir,
            &format!("{name}.toml"),
            &launched_bar(2600.0, 0.35, 0.8 * vz),
        ),
        obs,
    )
}

const HEAD: &str =
    "[study]\nshared = [\"young\", \"poisson\"]\noptimizer = \"gauss-newton\"\niterations = 15\n";

fn entry(name: &str) -> String {
    format!("\n[[recording]]\nname = \"{name}\"\nscene = \"{name}.toml\"\nobservations = \"{name}.csv\"\n")
}

/// The study of two recordings (swinging from rest, pushed at 0.5), each launch its own.
fn swing_and_push(dir: &Path) -> PathBuf {
    recording(dir, "swing", 0.0);
    recording(dir, "push", 0.5);
    write(
        dir,
        "study.toml",
        &format!(
            "{}per_recording = [\"initial_velocity\"]\n{}{}",
            HEAD,
            entry("swing"),
            entry("push")
        ),
    )
}

#[test]
fn a_joint_fit_recovers_the_material_and_each_push() {
    let dir = tmp("study", "joint");
    let study = swing_and_push(&dir);
    let out = dir.join("report");
    let o = run(&[
        "fit",
        study.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    let j = json(&o);
    let p = &j["parameters"];
    let get = |k: &str| p[k].as_f64().unwrap_or_else(|| panic!("{k} in {p}"));
    assert!((get("young") / 2000.0 - 1.0).abs() < 1e-3, "{p}");
    assert!((get("poisson") / 0.3 - 1.0).abs() < 1e-3, "{p}");
    assert!((get("push:initial_velocity.z") - 0.5).abs() < 1e-3, "{p}");
    assert!(get("swing:initial_velocity.z").abs() < 1e-3, "{p}");
    let recs = j["recordings"].as_array().unwrap();
    assert_eq!(recs.len(), 2);
    for r in recs {
        let (a, b) = (
            r["rms"]["initial"].as_f64().unwrap(),
            r["rms"]["final"].as_f64().unwrap(),
        );
        assert!(b < 1e-2 * a, "{r}");
    }
    assert_eq!(j["correlations"][0]["a"], "young");
    let c = j["correlations"][0]["value"].as_f64().unwrap();
    assert!(c.abs() <= 1.0, "{c}");
    assert!(j["standard_errors"]["push:initial_velocity.z"].as_f64().is_some());
    assert!(out.join("fit.json").is_file() && out.join("recordings.png").is_file());
}

#[test]
fn a_study_of_one_recording_is_the_single_fit() {
    let dir = tmp("study", "one");
    let (start, obs) = recording(&dir, "swing", 0.2);
    let study = write(&dir, "study.toml", &format!("{}{}", HEAD, entry("swing")));
    let joint = json(&run(&[
        "fit",
        study.to_str().unwrap(),
        "--out",
        dir.join("a").to_str().unwrap(),
        "--json",
    ]));
    let single = json(&run_on(
        "fit",
        &start,
        &obs,
        &dir.join("b"),
        &[
            "--params",
            "young,poisson",
            "--optimizer",
            "gauss-newton",
            "--iterations",
            "15",
            "--json",
            "--no-refine-check",
        ],
    ));
    for k in ["young", "poisson"] {
        let (a, b) = (&joint["parameters"][k], &single["parameters"][k]);
        assert_eq!(
            a.as_f64().unwrap().to_bits(),
            b.as_f64().unwrap().to_bits(),
            "{k}: {a} vs {b}"
        );
        let (a, b) = (&joint["standard_errors"][k], &single["standard_errors"][k]);
        assert_eq!(
            a.as_f64().unwrap().to_bits(),
            b.as_f64().unwrap().to_bits(),
            "se {k}: {a} vs {b}"
        );
    }
    assert_eq!(joint["iterations"], single["iterations"]);
}

#[test]
fn bad_studies_and_scene_flags_are_one_line_errors() {
    let dir = tmp("study", "bad");
    recording(&dir, "swing", 0.0);
    let good = format!("{}{}", HEAD, entry("swing"));
    let path = |name: &str, text: &str| write(&dir, name, text).to_str().unwrap().to_string();
    let cases: Vec<(String, Vec<&str>, &str)> = vec![
        (
            path("a.toml", &good.replace("\"young\", \"poisson\"", "\"youth\"")),
            vec![],
            "study.shared",
        ),
        (
            path("b.toml", &good.replace("swing.csv", "missing.csv")),
            vec![],
            "missing.csv",
        ),
        (
            path("c.toml", &format!("{good}{}", entry("swing"))),
            vec![],
            "names two recordings",
        ),
        (
            path("d.toml", &good.replace("iterations = 15", "iteration = 15")),
            vec![],
            "line 4: unknown field `iteration`",
        ),
        (
            path("e.toml", &good),
            vec!["--observations", "x.csv"],
            "--observations",
        ),
        (path("f.toml", &good), vec!["--resume"], "--resume"),
        // a study written wrongly is read as a study, and one that is not TOML as such
        (
            path("h.toml", &good.replace("[[recording]]", "[recording]")),
            vec![],
            "expected a sequence",
        ),
        (
            path(
                "i.toml",
                &good.replace("iterations = 15", "iterations = 99999999999999999999"),
            ),
            vec![],
            "line 4",
        ),
        (
            path("j.toml", &good.replace("gauss-newton", "adam")),
            vec![],
            "study.optimizer: unknown optimizer `adam`",
        ),
        // a recording whose scene is a study (here: the study itself)
        (
            path(
                "k.toml",
                &good.replace("scene = \"swing.toml\"", "scene = \"k.toml\""),
            ),
            vec![],
            "k.toml: a study file (several recordings) where one scene is expected",
        ),
    ];
    let out = dir.join("out");
    for (study, flags, needle) in cases {
        let mut args = vec!["fit", study.as_str(), "--out", out.to_str().unwrap()];
        args.extend(flags);
        let o = run(&args);
        one_line_error(&o, needle);
    }
    // commands that take one scene say so
    let study = path("g.toml", &good);
    let o = run(&[
        "gradcheck",
        study.as_str(),
        "--observations",
        dir.join("swing.csv").to_str().unwrap(),
    ]);
    one_line_error(&o, "`softbody fit` and `softbody diagnose` take studies");
    // a scene without --observations
    let o = run(&["fit", dir.join("swing.toml").to_str().unwrap()]);
    one_line_error(&o, "--observations: required");
}

#[test]
fn multi_start_reports_every_optimum_and_their_agreement() {
    let dir = tmp("study", "starts");
    // noisy observations: the standard errors that judge agreement are then not 0
    let obs = dir.join("swing.csv");
    let truth = write(&dir, "truth.toml", &launched_bar(2000.0, 0.3, 0.0));
    observe_json(
        &truth,
        &obs,
        &["--radius", "2", "--noise", "0.002", "--seed", "3"],
    );
    let start = write(&dir, "start.toml", &launched_bar(2600.0, 0.35, 0.0));
    let fit = |out: &str| {
        json(&run_on(
            "fit",
            &start,
            &obs,
            &dir.join(out),
            &[
                "--params",
                "young,poisson",
                "--optimizer",
                "gauss-newton",
                "--starts",
                "3",
                "--seed",
                "5",
                "--json",
            ],
        ))
    };
    let j = fit("a");
    let starts = j["starts"].as_array().unwrap();
    assert_eq!(starts.len(), 3);
    // the first start is the scene's, the others spread in the plausible box
    assert_eq!(
        starts[0]["initial_parameters"]["young"].as_f64().unwrap().round(),
        2600.0
    );
    let e1 = starts[1]["initial_parameters"]["young"].as_f64().unwrap();
    let e2 = starts[2]["initial_parameters"]["young"].as_f64().unwrap();
    assert!(
        e1 != e2 && (26.0..=260_000.0).contains(&e1) && (26.0..=260_000.0).contains(&e2),
        "{e1} {e2}"
    );
    // identifiable: every start that converged finds the truth (to the noise), and they agree
    for s in starts.iter().filter(|s| s["converged"] == true) {
        let e = s["parameters"]["young"].as_f64().unwrap();
        assert!((e / 2000.0 - 1.0).abs() < 0.05, "{s}");
    }
    assert_eq!(j["unique"], true, "{}", j["max_disagreement"]);
    let best = j["best_start"].as_u64().unwrap() as usize;
    assert_eq!(j["parameters"], starts[best]["parameters"]);
    // seeded: the same seed, the same report
    let again = fit("b");
    assert_eq!(again["starts"], j["starts"]);
}

#[test]
fn design_advice_predicts_smaller_errors_for_every_candidate_motion() {
    let dir = tmp("study", "design");
    recording(&dir, "swing", 0.0);
    let study = write(&dir, "study.toml", &format!("{}{}", HEAD, entry("swing")));
    let out = dir.join("report");
    let j = json(&run(&[
        "fit",
        study.to_str().unwrap(),
        "--design",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    let d = &j["design"];
    let now = d["relative_std_error"].as_f64().unwrap();
    assert!(now > 0.0, "{d}");
    let cands = d["candidates"].as_array().unwrap();
    let names: Vec<&str> = cands.iter().map(|c| c["name"].as_str().unwrap()).collect();
    // the bar is held and under gravity: every motion of the menu applies
    assert_eq!(names, ["drop", "squeeze", "throw", "strike"], "{d}");
    let mut best = f64::INFINITY;
    for c in cands {
        assert!(c["error"].is_null(), "{c}");
        assert!(c["points"].as_u64().unwrap() > 0, "{c}");
        // more data never loses information: H + H_c >= H
        let r = c["relative_std_error"].as_f64().unwrap();
        assert!(r <= now * (1.0 + 1e-9), "{c} vs {now}");
        best = best.min(r);
    }
    let named = cands.iter().find(|c| c["name"] == d["best"]).unwrap();
    assert_eq!(named["relative_std_error"].as_f64().unwrap(), best);
    // a landing excites the material more than the swing alone
    assert!(best < 0.5 * now, "{d}");
    assert!(out.join("design.png").is_file());
    // the candidates are seen like the recording: observe's 4 cameras at radius 2
    let rig = &d["rig"];
    assert_eq!(rig["cameras"], 4, "{rig}");
    assert!((rig["radius"].as_f64().unwrap() - 2.0).abs() < 1e-6, "{rig}");
    assert!(
        rig["like"].as_str().unwrap().ends_with("swing.cameras.json"),
        "{rig}"
    );
}

#[test]
fn diagnose_a_study_diagnoses_every_recording() {
    let dir = tmp("study", "diagnose");
    // each launch fitted too: the model as given can then explain each recording
    let study = swing_and_push(&dir);
    let out = dir.join("report");
    let j = json(&run(&[
        "diagnose",
        study.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-refine-check",
        "--json",
    ]));
    let recs = j["recordings"].as_array().unwrap();
    assert_eq!(recs.len(), 2, "{j}");
    for (r, name) in recs.iter().zip(["swing", "push"]) {
        assert_eq!(r["name"], name);
        // the model as given made the data (noise-free): nothing missing, rms far below 1e-3
        assert!(r["missing_effect"].is_null(), "{r}");
        assert!(r["rms"].as_f64().unwrap() < 1e-3, "{r}");
        let one: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(name).join("diagnosis.json")).unwrap()).unwrap();
        assert_eq!(one["verdict"], r["verdict"]);
    }
    assert!(out.join("diagnosis.json").is_file());
    // nothing of the runs' bookkeeping is left behind
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".lock") || n.contains(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    // a flag for one scene is refused, naming it
    let o = run(&["diagnose", study.to_str().unwrap(), "--steps", "3"]);
    one_line_error(&o, "--steps");
    // each recording's folder is a report of softbody's own (a later run may replace it)
    assert!(out.join("swing").join(".softbody-out").is_file());
    // a recording named like the study report's own file is refused before anything is written
    let text = format!("{HEAD}{}", entry("swing")).replace("name = \"swing\"", "name = \"Diagnosis.JSON\"");
    let clash = write(&dir, "clash.toml", &text);
    let out2 = dir.join("clash-report");
    let o = run(&[
        "diagnose",
        clash.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    one_line_error(&o, "the study report's own file");
    assert!(!out2.exists());
}

#[test]
fn a_design_that_cannot_be_made_leaves_the_fit_report_whole() {
    let dir = tmp("study", "design-none");
    let (_, obs) = recording(&dir, "swing", 0.0);
    // a model without gravity never moves: E is not determined, its matrix is singular
    let still = launched_bar(2600.0, 0.35, 0.0).replace("\"gravity\", ", "");
    write(&dir, "still.toml", &still);
    let study = write(
        &dir,
        "study.toml",
        &format!(
            "[study]\nshared = [\"young\"]\n[[recording]]\nscene = \"still.toml\"\nobservations = \"{}\"\n",
            obs.display()
        ),
    );
    let out = dir.join("report");
    let j = json(&run(&[
        "fit",
        study.to_str().unwrap(),
        "--design",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    let e = j["design"]["error"].as_str().unwrap_or_else(|| panic!("{j}"));
    assert!(e.contains("singular"), "{e}");
    assert!(j["parameters"]["young"].as_f64().is_some());
    assert!(out.join("fit.json").is_file());
}

#[test]
fn under_an_mpi_launcher_only_fit_runs_and_only_when_built_with_mpi() {
    let dir = tmp("study", "launched");
    let (scene, obs) = recording(&dir, "swing", 0.0);
    let launched = |args: &[&str]| {
        softbody()
            .args(args)
            .env("OMPI_COMM_WORLD_SIZE", "2")
            .output()
            .unwrap()
    };
    let o = launched(&[
        "simulate",
        scene.to_str().unwrap(),
        "--out",
        dir.join("s").to_str().unwrap(),
    ]);
    one_line_error(&o, "only `softbody fit` runs across MPI ranks");
    assert!(!dir.join("s").exists());
    #[cfg(not(feature = "mpi"))]
    {
        let o = launched(&[
            "fit",
            scene.to_str().unwrap(),
            "--observations",
            obs.to_str().unwrap(),
            "--out",
            dir.join("f").to_str().unwrap(),
        ]);
        one_line_error(&o, "built without MPI");
        assert!(!dir.join("f").exists());
    }
    let _ = obs;
}
