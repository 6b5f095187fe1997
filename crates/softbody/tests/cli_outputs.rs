//! Issue 13, "Output that lies": every command's output is transactional (written beside the
//! target and renamed into place on success) and locked (a second run into the same target
//! fails at once naming the process that holds it). A failing rerun leaves the earlier output
//! byte for byte; a rerun with another scene leaves nothing of the first; `observe` that fails
//! at its camera file leaves no CSV; `fit --resume` continues the log of a killed run.

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
mod common;
use common::*;

/// Every file under `dir` (relative path -> bytes).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// Names in `dir` other than `keep` (temporary folders, lock files left behind).
fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

fn simulate(scene: &Path, out: &Path) -> std::process::Output {
    run(&[
        "simulate",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ])
}

#[test]
fn a_failing_rerun_leaves_the_earlier_output_byte_identical() {
    let dir = tmp("outputs", "rerun");
    let good = write(&dir, "good.toml", &tiny_bar(3, ""));
    let out = dir.join("out");
    let j = json(&simulate(&good, &out));
    // the JSON names the final folder, not the temporary one
    assert_eq!(j["out"], out.to_str().unwrap());
    assert_eq!(j["files"]["picture"], out.join("picture.png").to_str().unwrap());
    let before = snapshot(&out);
    assert!(before.contains_key(Path::new("summary.json")) && before.len() > 4);
    // a rerun that fails after its output was begun (the body's file is missing)
    let bad = write(
        &dir,
        "bad.toml",
        &edited(
            &tiny_bar(3, ""),
            &[(
                "shape = { kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }",
                "sdf = \"missing.sdf\"",
            )],
        ),
    );
    let o = simulate(&bad, &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains(".tmp-"), "the message names the target: {err}");
    assert_eq!(snapshot(&out), before, "the earlier output is untouched");
    assert!(
        leftovers(&dir, &["good.toml", "bad.toml", "out"]).is_empty(),
        "{:?}",
        leftovers(&dir, &["good.toml", "bad.toml", "out"])
    );

    // fit: a rerun whose observations are out of reach fails; fit.json, fit.log and plots stay
    let obs = dir.join("obs.csv");
    observe_json(&good, &obs, &["--radius", "2"]);
    let report = dir.join("report");
    let fit_young = |obs: &Path| {
        run_on(
            "fit",
            &good,
            obs,
            &report,
            &[
                "--params",
                "young",
                "--iterations",
                "1",
                "--no-refine-check",
                "--json",
            ],
        )
    };
    json(&fit_young(&obs));
    let before = snapshot(&report);
    for f in ["fit.json", "fit.log", "cost.png"] {
        assert!(before.contains_key(Path::new(f)), "{f}");
    }
    let far = write(&dir, "far.csv", "frame,x,y,z\n1,50,50,50\n2,51,50,50\n");
    one_line_error(&fit_young(&far), "within reach");
    assert_eq!(snapshot(&report), before, "the earlier report is untouched");
}

#[test]
fn a_simulate_rerun_with_another_scene_leaves_no_frame_of_the_first() {
    let dir = tmp("outputs", "frames");
    let out = dir.join("out");
    let long = write(&dir, "long.toml", &tiny_bar(6, ""));
    json(&simulate(&long, &out));
    assert!(out.join("frames/0006.ply").exists());
    let short = write(
        &dir,
        "short.toml",
        &edited(&tiny_bar(2, ""), &[("young = 2000.0", "young = 5000.0")]),
    );
    let j = json(&simulate(&short, &out));
    assert_eq!(j["steps"], 2);
    let frames: Vec<String> = leftovers(&out.join("frames"), &[]);
    let mut frames = frames;
    frames.sort();
    assert_eq!(frames, ["0000.ply", "0001.ply", "0002.ply"]);
    assert!(leftovers(&dir, &["long.toml", "short.toml", "out"]).is_empty());
}

#[test]
fn a_folder_of_other_files_is_not_replaced() {
    let dir = tmp("outputs", "foreign");
    let s = write(&dir, "s.toml", &tiny_bar(2, ""));
    // the folder of the scene itself: refused (it holds an input), nothing deleted
    one_line_error(&simulate(&s, &dir), "holds an input of this run");
    assert!(s.exists());
    // a folder of other files: refused, nothing deleted
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let notes = write(&other, "notes.txt", "x");
    one_line_error(&simulate(&s, &other), "holds files that softbody did not write");
    assert!(notes.exists());
    let file = write(&dir, "file", "x");
    one_line_error(&simulate(&s, &file), "is not a folder");
}

#[test]
#[allow(clippy::incompatible_msrv)] // File::try_lock: std since 1.89 (softbody::out_dir)
fn a_second_run_into_a_locked_out_dir_fails_at_once() {
    let dir = tmp("outputs", "lock");
    let s = write(&dir, "s.toml", &tiny_bar(2, ""));
    let out = dir.join("out");
    json(&simulate(&s, &out));
    let before = snapshot(&out);

    // the lock held as a run holds it: `flock` on OUT.lock holding the pid
    let lock_path = dir.join("out.lock");
    let mut lock = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(&lock_path)
        .unwrap();
    lock.try_lock().unwrap();
    write!(lock, "{}", std::process::id()).unwrap();
    let t = Instant::now();
    one_line_error(
        &simulate(&s, &out),
        &format!("is in use by process {}", std::process::id()),
    );
    assert!(t.elapsed() < Duration::from_secs(5), "fails at once");
    assert_eq!(snapshot(&out), before);
    drop(lock);

    // a real run holding it: a long simulation into the same folder
    let long = write(&dir, "long.toml", &tiny_bar(100_000, ""));
    let mut child = softbody()
        .args([
            "simulate",
            long.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--json",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pid = child.id().to_string();
    let t = Instant::now();
    while std::fs::read_to_string(&lock_path).unwrap_or_default() != pid {
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "the long run never took the lock"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = simulate(&s, &out);
    child.kill().unwrap();
    child.wait().unwrap();
    one_line_error(&o, &format!("is in use by process {pid}"));
    assert_eq!(snapshot(&out), before, "neither run touched the output");
    // the killed run left its temporary folder; the next successful run removes it
    assert!(dir.join(format!("out.tmp-{pid}")).exists());
    json(&simulate(&s, &out));
    assert!(
        leftovers(&dir, &["s.toml", "long.toml", "out"]).is_empty(),
        "{:?}",
        leftovers(&dir, &["s.toml", "long.toml", "out"])
    );
}

#[test]
fn observe_failing_at_the_camera_file_leaves_no_csv() {
    let dir = tmp("outputs", "observe");
    let s = write(&dir, "s.toml", &tiny_bar(2, ""));
    let obs = dir.join("obs.csv");
    let observe = |flags: &[&str]| {
        let (s, obs) = (s.to_str().unwrap(), obs.to_str().unwrap());
        run(&[&["observe", s, "--out", obs, "--radius", "2"], flags].concat())
    };
    // a folder where the camera file goes
    std::fs::create_dir(dir.join("obs.cameras.json")).unwrap();
    let o = observe(&[]);
    one_line_error(&o, "obs.cameras.json");
    assert!(!obs.exists(), "no CSV without its camera file");
    // an earlier CSV stays as it was
    std::fs::write(&obs, "frame,x,y,z\n1,0,1,0\n").unwrap();
    let o = observe(&[]);
    one_line_error(&o, "obs.cameras.json");
    assert_eq!(std::fs::read_to_string(&obs).unwrap(), "frame,x,y,z\n1,0,1,0\n");
    assert!(leftovers(&dir, &["s.toml", "obs.csv", "obs.cameras.json"]).is_empty());
    // without the obstacle both files appear
    std::fs::remove_dir(dir.join("obs.cameras.json")).unwrap();
    let j = json(&observe(&["--json"]));
    assert!(j["points"].as_u64().unwrap() > 0);
    assert!(dir.join("obs.cameras.json").is_file());
    assert!(leftovers(&dir, &["s.toml", "obs.csv", "obs.cameras.json"]).is_empty());
}

#[test]
fn fit_resume_continues_the_log_of_a_killed_run() {
    let dir = tmp("outputs", "resume");
    let (obs, _) = observed(&dir, &tiny_bar(4, ""), &["--radius", "2"]);
    let start = write(
        &dir,
        "start.toml",
        &edited(&tiny_bar(4, ""), &[("young = 2000.0", "young = 2600.0")]),
    );
    let report = dir.join("report");
    let fit_young = |extra: &[&str]| {
        let flags = [&["--params", "young", "--no-refine-check", "--json"], extra].concat();
        run_on("fit", &start, &obs, &report, &flags)
    };
    let j = json(&fit_young(&["--iterations", "3"]));
    let log = std::fs::read_to_string(report.join("fit.log")).unwrap();
    assert_eq!(log.lines().count(), j["history"].as_array().unwrap().len());
    // a run killed after two iterations: its log is in its temporary folder
    let killed = dir.join("report.tmp-4000000");
    std::fs::create_dir(&killed).unwrap();
    let kept: Vec<&str> = log.lines().take(2).collect();
    std::fs::write(killed.join("fit.log"), kept.join("\n") + "\n").unwrap();
    let j = json(&fit_young(&["--resume", "--iterations", "2"]));
    let h = j["history"].as_array().unwrap();
    assert_eq!(h[1]["iteration"], 1);
    assert_eq!(h[2]["iteration"], 2, "resumed from the killed run's log");
    assert!(
        !killed.exists(),
        "the killed run's folder is removed by the success"
    );
    let log = std::fs::read_to_string(report.join("fit.log")).unwrap();
    assert_eq!(log.lines().count(), h.len());
    assert_eq!(
        h[0]["problem"], j["problem"],
        "every entry carries the problem's fingerprint"
    );
    // issue 51: a resume of another problem with the same parameter names (another scene, or
    // other observations) is refused naming both fingerprints, and the report stays
    let other = write(
        &dir,
        "other.toml",
        &edited(&tiny_bar(4, ""), &[("young = 2000.0", "young = 1500.0")]),
    );
    let (obs2, _) = (dir.join("obs2.csv"), ());
    std::fs::write(
        &obs2,
        std::fs::read_to_string(&obs).unwrap().replace(",1.0", ",1.0001"),
    )
    .unwrap();
    let flags = ["--params", "young", "--no-refine-check", "--resume"];
    for (scene, o) in [(&other, &obs), (&start, &obs2)] {
        let out = run_on("fit", scene, o, &report, &flags);
        one_line_error(&out, "fit.log: the log is of another problem (fingerprint");
        assert_eq!(std::fs::read_to_string(report.join("fit.log")).unwrap(), log);
    }
}

/// No output replaces an input of its run: `observe --out` naming the scene (it overwrote the
/// scene with points before), a report folder that holds the observations being fitted (it was
/// replaced with them), or the scene's body file. Each is a one-line error; every file stays.
#[test]
fn outputs_never_replace_their_inputs() {
    let dir = tmp("outputs", "inputs");
    let s = write(&dir, "s.toml", &tiny_bar(2, ""));
    let before = snapshot(&dir);
    let spelled = dir.join(".").join("s.toml");
    let o = run(&["observe", s.to_str().unwrap(), "--out", spelled.to_str().unwrap()]);
    one_line_error(&o, "is an input of this run");
    assert_eq!(snapshot(&dir), before);
    // observations kept inside an earlier report folder, then a fit into that folder
    let sim = dir.join("sim");
    ok(&run(&[
        "simulate",
        s.to_str().unwrap(),
        "--out",
        sim.to_str().unwrap(),
    ]));
    let obs = sim.join("obs.csv");
    ok(&run(&[
        "observe",
        s.to_str().unwrap(),
        "--out",
        obs.to_str().unwrap(),
    ]));
    let before = snapshot(&dir);
    let o = run_on("fit", &s, &obs, &sim, &[]);
    one_line_error(&o, "the folder holds an input of this run");
    assert_eq!(snapshot(&dir), before);
    // the scene's body file
    let mesh = write(
        &dir,
        "cube.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    let m = write(&dir, "m.toml", "[body]\nmesh = \"cube.obj\"\nresolution = 8\n[material]\nyoung = 1000.0\npoisson = 0.3\n[time]\ndt = 0.01\nsteps = 1\n");
    let before = snapshot(&dir);
    let o = run(&["observe", m.to_str().unwrap(), "--out", mesh.to_str().unwrap()]);
    one_line_error(&o, "cube.obj: is an input of this run");
    assert_eq!(snapshot(&dir), before);
}

/// Issue 51: a report folder named with a trailing separator or `.` components is the same
/// folder; its temporary twin is staged beside it, never inside, for every command that writes
/// a folder, a first run and a rerun over an earlier report alike.
#[test]
fn every_spelling_of_an_out_folder_is_the_same_folder() {
    let dir = tmp("outputs", "spelling");
    let scene = write(&dir, "s.toml", &tiny_bar(3, ""));
    let (obs, _) = observed(&dir, &tiny_bar(3, ""), &["--noise", "0.001", "--seed", "3"]);
    let base = dir.join("out");
    let spellings = [
        format!("{}/", base.display()),
        format!("{}/.", base.display()),
        format!("{}//./", base.display()),
    ];
    for (k, out) in spellings.iter().enumerate() {
        for command in ["simulate", "fit", "diagnose"] {
            let o = match command {
                "simulate" => run(&["simulate", scene.to_str().unwrap(), "--out", out, "--json"]),
                "fit" => run_on(
                    "fit",
                    &scene,
                    &obs,
                    Path::new(out),
                    &["--iterations", "1", "--json"],
                ),
                _ => run_on(
                    "diagnose",
                    &scene,
                    &obs,
                    Path::new(out),
                    &[
                        "--iterations",
                        "1",
                        "--refits",
                        "1",
                        "--no-refine-check",
                        "--json",
                    ],
                ),
            };
            let j = json(&o);
            assert!(
                base.is_dir() && leftovers(&base, &[]).iter().all(|n| !n.contains(".tmp-")),
                "{command} --out {out} (spelling {k}): {:?}",
                leftovers(&base, &[])
            );
            assert!(j.is_object(), "{command} --out {out}");
            let beside: Vec<String> = leftovers(
                &dir,
                &["s.toml", "truth.toml", "obs.csv", "obs.cameras.json", "out"],
            )
            .into_iter()
            .filter(|n| !n.ends_with(".history.jsonl"))
            .collect();
            assert!(beside.is_empty(), "{command} --out {out}: left {beside:?}");
        }
    }
}
