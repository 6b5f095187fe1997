//! Issue 13, "Runs that succeed with a result that cannot be trusted": a camera file that does
//! not match its CSV, observations that cannot inform a fit and physical parameters that
//! cannot be simulated are refused before anything runs, with one line naming the file, the
//! camera or line, and the key. (The statistics of the weights are covered by
//! `crates/adjoint/tests/statistics.rs`.)

use std::path::Path;
mod common;
use common::*;

/// The tiny bar of 4 steps ([`tiny_bar`]); `edit` replaces text in it (none when empty),
/// `extra` is appended.
fn scene(edit: (&str, &str), extra: &str) -> String {
    let text = tiny_bar(4, extra);
    if edit.0.is_empty() {
        text
    } else {
        edited(&text, &[edit])
    }
}

/// Runs `fit`, `gradcheck` and `diagnose` on `scene` and `obs` (with `--cameras` when given) and
/// expects the same one-line error from each.
fn every_command_refuses(dir: &Path, scene: &Path, obs: &Path, cameras: Option<&Path>, needle: &str) {
    let out = dir.join("out");
    let (s, o, out) = (
        scene.to_str().unwrap(),
        obs.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let mut cam = vec![];
    if let Some(c) = cameras {
        cam = vec!["--cameras", c.to_str().unwrap()];
    }
    for cmd in [
        vec!["fit", s, "--observations", o, "--out", out],
        vec!["gradcheck", s, "--observations", o],
        vec!["diagnose", s, "--observations", o, "--out", out],
    ] {
        let args: Vec<&str> = cmd.iter().chain(&cam).copied().collect();
        one_line_error(&run(&args), needle);
    }
}

#[test]
fn camera_files_are_checked_against_the_csv() {
    let dir = tmp("trust", "cameras");
    let s = write(&dir, "s.toml", &scene(("", ""), ""));
    let obs = write(&dir, "obs.csv", "frame,x,y,z,camera\n1,0,1,0,0\n2,0.1,1,0,1\n");
    let cam = |id: &str, extra: &str| format!(r#"{{"id": {id}, "eye": [0, 1, 2]{extra}}}"#);
    let file =
        |name: &str, cams: &[String]| write(&dir, name, &format!(r#"{{"cameras": [{}]}}"#, cams.join(",")));
    // a duplicated id (was accepted; the fit then reported young = 3e-23, "converged")
    let dup = file("dup.json", &[cam("0", ""), cam("0", "")]);
    every_command_refuses(
        &dir,
        &s,
        &obs,
        Some(&dup),
        "dup.json: cameras[1].id: 0 is used twice (cameras[0] and cameras[1])",
    );
    // issue 51: a picture without an up (zero, or along the viewing direction) was accepted
    for (name, extra, says) in [
        (
            "upzero.json",
            r#", "target": [0, 1, 0], "up": [0, 0, 0]"#,
            "cameras[0].up: is zero",
        ),
        (
            "upalong.json",
            r#", "target": [0, 1, 0], "up": [0, 0, -3]"#,
            "cameras[0].up: lies along",
        ),
        (
            "down.json",
            r#", "target": [0, -5, 2]"#,
            "cameras[0].up: not given, and the default",
        ),
    ] {
        let f = file(name, &[cam("0", extra), cam("1", "")]);
        every_command_refuses(&dir, &s, &obs, Some(&f), &format!("{name}: {says}"));
    }
    // a camera the CSV uses but the file lacks (was measured to the closest point instead)
    let short = file("short.json", &[cam("0", "")]);
    every_command_refuses(
        &dir,
        &s,
        &obs,
        Some(&short),
        "obs.csv:3: camera 1: no camera with `id` 1 in",
    );
    // the default file beside the CSV is checked the same way
    std::fs::copy(&dup, dir.join("obs.cameras.json")).unwrap();
    every_command_refuses(
        &dir,
        &s,
        &obs,
        None,
        "obs.cameras.json: cameras[1].id: 0 is used twice",
    );
    std::fs::remove_file(dir.join("obs.cameras.json")).unwrap();
    // poses finite, intrinsics positive
    for (extra, needle) in [
        (
            r#", "fov_y": -1"#,
            "bad.json: cameras[1].fov_y: must be an angle in (0, pi) radians, found -1 (camera id 1)",
        ),
        (
            r#", "width": 0"#,
            "bad.json: cameras[1].width: not an integer in 1..=8192 (camera id 1)",
        ),
        (
            r#", "target": [0, "up", 0]"#,
            "bad.json: cameras[1].target: not three finite numbers (camera id 1)",
        ),
        (
            r#", "target": [0, 1, 2]"#,
            "bad.json: cameras[1].target: equals the eye",
        ),
    ] {
        let bad = file("bad.json", &[cam("0", ""), cam("1", extra)]);
        every_command_refuses(&dir, &s, &obs, Some(&bad), needle);
    }
    let bad = write(
        &dir,
        "bad.json",
        r#"{"cameras": [{"id": 0, "eye": [0, 1]}, {"id": 1, "eye": [0, 1, 2]}]}"#,
    );
    every_command_refuses(
        &dir,
        &s,
        &obs,
        Some(&bad),
        "bad.json: cameras[0].eye: not a list [x, y, z] (camera id 0)",
    );
}

#[test]
fn data_that_cannot_inform_the_fit_are_refused() {
    let dir = tmp("trust", "data");
    let s = write(&dir, "s.toml", &scene(("", ""), ""));
    for (csv, needle) in [
        (
            "frame,x,y,z,weight\n1,0,1,0,0\n2,0,1.1,0,0\n",
            "obs.csv: none of the 2 observed points can inform the fit: 2 have weight 0",
        ),
        (
            "frame,x,y,z\n0,0,1,0\n0,0,1.1,0\n0,0.1,1,0\n",
            "obs.csv: none of the 3 observed points can inform the fit: 3 lie at frame 0 (the reference configuration",
        ),
        (
            "frame,x,y,z,weight\n0,0,1,0,1\n3,0,1.1,0,0\n",
            "none of the 2 observed points can inform the fit: 1 have weight 0, 1 lie at frame 0",
        ),
        (
            "frame,x,y,z,weight\n1,0,1,0,1e-310\n",
            "obs.csv: line 2: weight 1e-310 is subnormal",
        ),
        (
            "frame,x,y,z,weight\n1,0,1,0,1e-200\n2,0,1.1,0,3e-200\n",
            "obs.csv: the largest weight of the 2 usable points is 3e-200, below 1.4916681462400413e-154",
        ),
        ("frame,x,y,z\n", "obs.csv: no observed point (only a header): nothing to fit"),
    ] {
        let obs = write(&dir, "obs.csv", csv);
        every_command_refuses(&dir, &s, &obs, None, needle);
    }
    // frames beyond the steps stay refused with their line
    let obs = write(&dir, "obs.csv", "frame,x,y,z\n1,0,1,0\n9,0,1,0\n");
    every_command_refuses(
        &dir,
        &s,
        &obs,
        None,
        "obs.csv:3: frame 9 lies beyond the 4 simulated steps",
    );
}

#[test]
fn implausible_parameters_are_named_before_running() {
    let dir = tmp("trust", "params");
    let obs = write(&dir, "obs.csv", "frame,x,y,z\n1,0,1,0\n");
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    for (edit, extra, needle) in [
        (
            ("young = 2000.0", "young = 1e308"),
            "",
            "material.young: 1e308 is far outside what can be simulated",
        ),
        (
            ("dt = 0.01", "dt = 1e-320"),
            "",
            "time.dt: 1e-320 is far outside what can be simulated",
        ),
        (
            ("", ""),
            "[ground]\nstiffness = 1e308\n",
            "ground.stiffness: 1e308 is far outside",
        ),
        (
            ("", ""),
            "[initial]\nvelocity = [1e308, 0.0, 0.0]\n",
            "initial.velocity: 1e308 is far outside",
        ),
        (
            ("", ""),
            "[initial]\nvelocity = [0.0, 1e12, 0.0]\n",
            "initial.velocity: 1e12 is far outside",
        ),
    ] {
        let s = write(&dir, "s.toml", &scene(edit, extra));
        let s = s.to_str().unwrap();
        let o = run(&["simulate", s, "--out", out]);
        one_line_error(&o, needle);
        one_line_error(&o, "s.toml");
        let o = run(&["fit", s, "--observations", obs.to_str().unwrap(), "--out", out]);
        one_line_error(&o, &format!("s.toml: {needle}"));
        one_line_error(&run(&["observe", s, "--out", &format!("{out}.csv")]), needle);
    }
    let s = write(
        &dir,
        "s.toml",
        &scene(("young = 2000.0", "young = 2000.0\ndensity = 1e250"), ""),
    );
    one_line_error(
        &run(&["simulate", s.to_str().unwrap(), "--out", out]),
        "material.density: 1e250 is far outside what can be simulated: the Newmark matrix's diagonal",
    );
}

/// Issue 51: observations of another body (every point far from the model) are refused by
/// every command with the same one line (`diagnose` reported a floor of 0 and "the
/// observations match this model exactly"); observations whose noise cannot be estimated (one
/// point per frame, every point at one place) give a noise floor of `null` with the reason,
/// never a number, and a verdict that says so instead of "exact" or "nothing missing".
#[test]
fn unusable_observations_are_refused_or_judged_as_unknowable() {
    let dir = tmp("trust", "unusable");
    let text = scene(("", ""), "");
    let s = write(&dir, "s.toml", &text);
    let (obs, _) = observed(&dir, &text, &["--noise", "0.002", "--seed", "4"]);
    let csv = std::fs::read_to_string(&obs).unwrap();
    let rows: Vec<Vec<String>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    let variant = |name: &str, f: &dyn Fn(&[String]) -> Option<String>| {
        let body: Vec<String> = rows.iter().filter_map(|r| f(r)).collect();
        write(&dir, name, &format!("frame,x,y,z\n{}\n", body.join("\n")))
    };
    // another body: the same cloud 50 units away
    let far = variant("far.csv", &|r| {
        let x: f64 = r[1].parse().unwrap();
        Some(format!("{},{},{},{}", r[0], x + 50.0, r[2], r[3]))
    });
    every_command_refuses(&dir, &s, &far, None, "far.csv: none of the");
    let firsts: Vec<String> = rows
        .iter()
        .filter(|r| seen.insert(r[0].clone()))
        .map(|r| r[..4].join(","))
        .collect();
    assert!(firsts.len() >= 3, "{} frames", firsts.len());
    let one = write(&dir, "one.csv", &format!("frame,x,y,z\n{}\n", firsts.join("\n")));
    let first = rows.first().unwrap();
    let place = variant("place.csv", &|r| {
        Some(format!("{},{},{},{}", r[0], first[1], first[2], first[3]))
    });
    for (obs, name) in [
        (&one, "one point per frame"),
        (&place, "every point at one place"),
    ] {
        let out = dir.join("d");
        let j = json(&run_on(
            "diagnose",
            &s,
            obs,
            &out,
            &[
                "--iterations",
                "2",
                "--refits",
                "1",
                "--no-refine-check",
                "--json",
            ],
        ));
        let verdict = j["verdict"].as_str().unwrap();
        let floor = &j["noise_floor"];
        assert!(
            floor.is_null() || floor.as_f64().is_some_and(|f| f > 0.0),
            "{name}: floor {floor}"
        );
        if floor.is_null() {
            assert!(
                j["noise_floor_method"]
                    .as_str()
                    .unwrap()
                    .starts_with("cannot be estimated"),
                "{name}: {j}"
            );
            assert!(
                !verdict.contains("exact") && !verdict.starts_with("nothing missing: rms")
                    || verdict.contains("numerical precision"),
                "{name}: {verdict}"
            );
        }
        let j = json(&run_on(
            "fit",
            &s,
            obs,
            &dir.join("f"),
            &["--iterations", "1", "--json"],
        ));
        let f = &j["noise_floor"]["value"];
        assert!(
            f.is_null() || f.as_f64().is_some_and(|f| f > 0.0),
            "{name}: fit floor {f}"
        );
    }
}
