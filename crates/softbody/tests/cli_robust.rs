//! Issue 13, "Panics and aborts": inputs a user can give that used to panic or abort the
//! process (a stiffness field fitted from the CLI, frame ranges and step counts beyond any
//! plausible size, `--json` into a closed pipe or a full disk, an `.sdf` that is an endless
//! stream) now give a result or a one-line error with exit code 1, never a panic.

use std::path::Path;
mod common;
use common::*;

#[test]
fn fit_a_stiffness_field_from_the_cli() {
    let dir = tmp("robust", "field");
    // observations of the truth (E = 2000)
    let (obs, j) = observed(&dir, &tiny_bar(4, ""), &[]);
    assert!(j["points"].as_u64().unwrap() > 100);
    let field = "[model]\neffects = [\"gravity\", \"corotation\", \"stiffness_field\"]\n\
                 stiffness_field = { cells = [1, 1, 1] }\n";
    let start = edited(&tiny_bar(4, field), &[("young = 2000.0", "young = 3000.0")]);
    let start = write(&dir, "start.toml", &start);
    let o = run_on(
        "fit",
        &start,
        &obs,
        &dir.join("report"),
        &[
            "--params",
            "stiffness_field",
            "--iterations",
            "3",
            "--no-refine-check",
            "--json",
        ],
    );
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

#[test]
fn frame_ranges_are_checked_before_they_are_expanded() {
    let dir = tmp("robust", "frames");
    let s = write(&dir, "s.toml", &tiny_bar(4, ""));
    let out = dir.join("o.csv");
    let (s, out) = (s.to_str().unwrap(), out.to_str().unwrap());
    for (frames, needle) in [
        (
            "0-18446744073709551615",
            "--frames: frame 18446744073709551615 is beyond the 4 steps",
        ),
        ("3,5", "--frames: frame 5 is beyond the 4 steps"),
        ("99999999999999999999999", "is not a frame number"),
        ("4-2", "empty range"),
    ] {
        one_line_error(&run(&["observe", s, "--out", out, "--frames", frames]), needle);
    }
    // within the steps it works (the range is expanded once checked)
    let j = json(&run(&["observe", s, "--out", out, "--frames", "0-4,2", "--json"]));
    assert_eq!(j["frames"], 5);
}

#[test]
fn implausible_sizes_are_refused_before_anything_is_reserved() {
    let dir = tmp("robust", "sizes");
    let big = edited(&tiny_bar(4, ""), &[("steps = 4", "steps = 100000000000")]);
    let big = write(&dir, "big.toml", &big);
    let small = write(&dir, "s.toml", &tiny_bar(4, ""));
    let obs = write(&dir, "obs.csv", "frame,x,y,z\n1,0,1,0\n");
    let (big, small, obs) = (
        big.to_str().unwrap(),
        small.to_str().unwrap(),
        obs.to_str().unwrap(),
    );
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    // the declared range of the key (`cutfem::scene::ranges`), with its line
    let key = "big.toml: line 15: time.steps: must be in [0, 1e6] (every step's state is kept: lower it or raise time.dt), got 1e11";
    one_line_error(&run(&["simulate", big, "--out", out]), key);
    one_line_error(&run(&["observe", big, "--out", &format!("{out}.csv")]), key);
    one_line_error(&run(&["fit", big, "--observations", obs, "--out", out]), key);
    one_line_error(&run(&["gradcheck", big, "--observations", obs]), key);
    one_line_error(&run(&["diagnose", big, "--observations", obs, "--out", out]), key);
    let flag = "--steps: 100000000000 steps is more than the 1000000";
    one_line_error(
        &run(&["simulate", small, "--steps", "100000000000", "--out", out]),
        flag,
    );
    one_line_error(
        &run(&[
            "observe",
            small,
            "--steps",
            "100000000000",
            "--out",
            &format!("{out}.csv"),
        ]),
        flag,
    );
    one_line_error(
        &run(&[
            "fit",
            small,
            "--observations",
            obs,
            "--steps",
            "100000000000",
            "--out",
            out,
        ]),
        flag,
    );
    one_line_error(
        &run(&[
            "simulate",
            small,
            "--picture-frames",
            "100000000000",
            "--out",
            out,
        ]),
        "--picture-frames must lie in 1..=64",
    );
    one_line_error(
        &run(&[
            "observe",
            small,
            "--cameras",
            "10000",
            "--pixels",
            "8192",
            "--out",
            &format!("{out}.csv"),
        ]),
        "more than the 134217728 an observation file holds",
    );
    // a camera file's image size is bounded like --pixels (residual pictures are drawn at it)
    let cams = write(
        &dir,
        "huge.cameras.json",
        // (looking straight down: its up is given, the default y would lie along the view)
        r#"{"cameras": [{"id": 0, "eye": [0, 3, 0], "target": [0, 1, 0], "up": [0, 0, 1], "fov_y": 1.0,
            "width": 4294967296, "height": 2}]}"#,
    );
    one_line_error(
        &run(&[
            "diagnose",
            small,
            "--observations",
            obs,
            "--cameras",
            cams.to_str().unwrap(),
            "--out",
            out,
        ]),
        "huge.cameras.json: cameras[0].width: not an integer in 1..=8192",
    );
}

#[test]
fn json_into_a_closed_pipe_ends_quietly_and_into_a_full_disk_is_an_error() {
    use std::process::Stdio;
    let dir = tmp("robust", "stdout");
    let s = write(&dir, "s.toml", &tiny_bar(4, ""));
    let s = s.to_str().unwrap();
    let commands: [Vec<String>; 2] = [
        vec![
            "observe".into(),
            s.into(),
            "--out".into(),
            format!("{}/o.csv", dir.display()),
        ],
        vec![
            "simulate".into(),
            s.into(),
            "--out".into(),
            format!("{}/sim", dir.display()),
        ],
    ];
    for args in &commands {
        // the reader is gone before the command writes: exit 141, nothing on stderr
        let mut child = softbody()
            .args(args)
            .arg("--json")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(141), "{args:?}: {err}");
        assert!(err.trim().is_empty(), "{args:?}: {err}");
        // a full disk: one line naming stdout, exit code 1
        if Path::new("/dev/full").exists() {
            let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
            let o = softbody().args(args).arg("--json").stdout(full).output().unwrap();
            one_line_error(&o, "stdout: No space left on device");
        }
    }
}

#[test]
fn endless_inputs_are_refused_not_read() {
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let dir = tmp("robust", "endless");
    let link = |name: &str| {
        let p = dir.join(name);
        std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
        p
    };
    link("z.sdf");
    link("z.obj");
    let zero_csv = link("zero.csv");
    let zero_toml = link("zero.toml");
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    for (body, needle) in [
        ("sdf = \"z.sdf\"", "z.sdf: resolution must be positive, found 0"),
        (
            "mesh = \"z.obj\"",
            "z.obj: binary data (a NUL byte at byte 0), not a text file",
        ),
    ] {
        let s = write(
            &dir,
            "s.toml",
            &format!("[body]\n{body}\n[material]\nyoung = 1000.0\npoisson = 0.3\n"),
        );
        one_line_error(&run(&["simulate", s.to_str().unwrap(), "--out", out]), needle);
    }
    one_line_error(
        &run(&["simulate", zero_toml.to_str().unwrap(), "--out", out]),
        "zero.toml: binary data",
    );
    let s = write(&dir, "s.toml", &tiny_bar(4, ""));
    one_line_error(
        &run(&[
            "fit",
            s.to_str().unwrap(),
            "--observations",
            zero_csv.to_str().unwrap(),
            "--out",
            out,
        ]),
        "zero.csv: binary data",
    );
}
