//! Helpers shared by the CLI tests: run the `softbody` binary, scratch folders, the tiny
//! clamped bar most of them simulate, observe and fit, and the checks of its two kinds of answer
//! (one JSON object, or a one-line error with exit code 1).

#![allow(dead_code)] // each test file uses its own subset

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The tiny cantilever of the CLI tests: a 0.6 x 0.2 x 0.3 box at resolution 10 (E = 2000,
/// nu = 0.3) under gravity, clamped at x <= -0.2, `steps` steps of 0.01 s; `extra` is appended
/// after `[time]` (keys of `[time]`, or more tables). A variant of a key given here is made
/// with [`edited`].
pub fn tiny_bar(steps: usize, extra: &str) -> String {
    format!(
        r#"
[body]
shape = {{ kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }}
resolution = 10
[material]
young = 2000.0
poisson = 0.3
[gravity]
acceleration = [0.0, -10.0, 0.0]
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[time]
dt = 0.01
steps = {steps}
{extra}
"#
    )
}

/// `text` with each `(from, to)` replaced in turn; each `from` must occur.
pub fn edited(text: &str, edits: &[(&str, &str)]) -> String {
    let mut text = text.to_string();
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` not in the scene:\n{text}");
        text = text.replace(from, to);
    }
    text
}

/// The `softbody` binary of this build.
pub fn softbody() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softbody"))
}

/// A fresh, empty scratch folder for test `name` of suite `suite` (per process).
pub fn tmp(suite: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softbody-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` to `dir/name`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `softbody args...`.
pub fn run(args: &[&str]) -> Output {
    softbody().args(args).output().unwrap()
}

/// Runs `softbody observe SCENE --out OBS FLAGS --json`; asserts success and returns its JSON.
pub fn observe_json(scene: &Path, obs: &Path, flags: &[&str]) -> Value {
    let mut args = vec!["observe", scene.to_str().unwrap(), "--out", obs.to_str().unwrap()];
    args.extend_from_slice(flags);
    args.push("--json");
    json(&run(&args))
}

/// Writes `truth` to `dir/truth.toml` and observes it into `dir/obs.csv` with `flags`
/// ([`observe_json`]): the observations and the JSON of `observe`.
pub fn observed(dir: &Path, truth: &str, flags: &[&str]) -> (PathBuf, Value) {
    let obs = dir.join("obs.csv");
    let j = observe_json(&write(dir, "truth.toml", truth), &obs, flags);
    (obs, j)
}

/// Runs `softbody COMMAND SCENE --observations OBS --out OUT FLAGS` (`fit`, `diagnose`).
pub fn run_on(command: &str, scene: &Path, obs: &Path, out: &Path, flags: &[&str]) -> Output {
    let mut args = vec![
        command,
        scene.to_str().unwrap(),
        "--observations",
        obs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(flags);
    run(&args)
}

/// Asserts success.
pub fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Asserts success and reads the one JSON object on stdout.
pub fn json(o: &Output) -> Value {
    ok(o);
    serde_json::from_slice(&o.stdout).expect("one JSON object on stdout")
}

/// Asserts a one-line error containing `needle`, exit code 1, no panic.
pub fn one_line_error(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "exit code for `{needle}`: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert_eq!(err.trim().lines().count(), 1, "one line expected: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}

/// The damped tiny bar (8 steps) with `young`, `poisson` and an initial velocity `vz` (the
/// recordings of the study tests).
pub fn launched_bar(young: f64, poisson: f64, vz: f64) -> String {
    let extra = format!(
        "[damping]\nmass = 0.1\nstiffness = 0.01\n[initial]\nvelocity = [0.0, 0.0, {vz:?}]\n\
         [model]\neffects = [\"gravity\", \"damping\", \"initial_velocity\"]"
    );
    let (young, poisson) = (format!("young = {young:?}"), format!("poisson = {poisson:?}"));
    edited(
        &tiny_bar(8, &extra),
        &[("young = 2000.0", &young), ("poisson = 0.3", &poisson)],
    )
}
