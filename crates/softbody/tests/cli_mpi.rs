//! `mpirun -np 2 softbody fit STUDY.toml` (feature `mpi`; `.ci/run` installs OpenMPI and runs
//! this with `cargo test --release -p softbody --features mpi --test cli_mpi`): the ranks
//! share the recordings out and report the same fit as one process, bit for bit (the JSON
//! without its timings); a failure on one rank stops every rank with one message and no hang.
#![cfg(feature = "mpi")]

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
mod common;
use common::*;

/// The damped tiny bar (8 steps) launched with `vz`, observed (truth E = 2000, nu = 0.3) into
/// `dir/NAME.csv`; the start scene (E = 2600, nu = 0.35, launch 0.8 vz) in `dir/NAME.toml`.
fn recording(dir: &Path, name: &str, vz: f64) {
    let truth = write(dir, &format!("{name}-truth.toml"), &launched_bar(2000.0, 0.3, vz));
    observe_json(&truth, &dir.join(format!("{name}.csv")), &["--radius", "2"]);
    write(
        dir,
        &format!("{name}.toml"),
        &launched_bar(2600.0, 0.35, 0.8 * vz),
    );
}

/// A study of three recordings (two ranks: an uneven split) in `dir/study.toml`.
fn study(dir: &Path) -> String {
    let mut text = "[study]\nshared = [\"young\", \"poisson\"]\nper_recording = [\"initial_velocity\"]\n\
                    optimizer = \"gauss-newton\"\niterations = 6\n"
        .to_string();
    for (name, vz) in [("swing", 0.0), ("push", 0.5), ("back", -0.3)] {
        recording(dir, name, vz);
        text += &format!(
            "\n[[recording]]\nname = \"{name}\"\nscene = \"{name}.toml\"\nobservations = \"{name}.csv\"\n"
        );
    }
    write(dir, "study.toml", &text).to_string_lossy().into_owned()
}

/// Runs `mpirun -np N softbody ARGS`, killed (and failed) after `limit`: a hang is a failure.
fn mpirun(n: usize, args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new("mpirun")
        .args([
            "--oversubscribe",
            "-np",
            &n.to_string(),
            env!("CARGO_BIN_EXE_softbody"),
        ])
        .args(args)
        // a CI container runs as root
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        // containers often forbid the cross-process memory copy of the shared-memory transport
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun (Debian's openmpi-bin) on the PATH");
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("mpirun -np {n} {args:?}: no end after {limit:?} (a hang)");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    child.wait_with_output().unwrap()
}

/// `fit.json` of `dir` without what differs from run to run (time, folder).
fn report(dir: &Path) -> String {
    let mut v: Value = serde_json::from_slice(&std::fs::read(dir.join("fit.json")).unwrap()).unwrap();
    for k in ["seconds", "out", "files"] {
        v.as_object_mut().unwrap().remove(k);
    }
    serde_json::to_string_pretty(&v).unwrap()
}

#[test]
fn two_ranks_report_the_single_process_fit_to_the_bit() {
    let dir = tmp("mpi", "same");
    let study = study(&dir);
    let one = dir.join("one");
    ok(&run(&["fit", &study, "--out", one.to_str().unwrap()]));
    for n in [2, 3] {
        let many = dir.join(format!("ranks{n}"));
        let o = mpirun(
            n,
            &["fit", &study, "--out", many.to_str().unwrap(), "--json"],
            Duration::from_secs(600),
        );
        // one JSON object on stdout: rank 0's
        let j = json(&o);
        assert_eq!(j["recordings"].as_array().unwrap().len(), 3);
        assert_eq!(report(&many), report(&one), "{n} ranks");
        assert!(many.join("recordings.png").is_file());
    }
    let j: Value = serde_json::from_str(&report(&one)).unwrap();
    assert!(
        (j["parameters"]["young"].as_f64().unwrap() / 2000.0 - 1.0).abs() < 1e-2,
        "{j}"
    );
}

#[test]
fn two_starts_over_two_ranks_match_the_threads() {
    let dir = tmp("mpi", "starts");
    let study = study(&dir);
    let flags = ["--starts", "2", "--seed", "5"];
    let one = dir.join("one");
    ok(&run(&[
        &["fit", &study, "--out", one.to_str().unwrap()][..],
        &flags,
    ]
    .concat()));
    let many = dir.join("many");
    let o = mpirun(
        2,
        &[&["fit", &study, "--out", many.to_str().unwrap()][..], &flags].concat(),
        Duration::from_secs(600),
    );
    ok(&o);
    assert_eq!(report(&many), report(&one));
}

#[test]
fn a_failure_on_rank_0_stops_every_rank_with_one_message() {
    let dir = tmp("mpi", "fail");
    let study = study(&dir);
    // rank 0 alone makes the report folder: under a file, it cannot
    let blocker = write(&dir, "file", "not a folder");
    let out = blocker.join("report");
    let o = mpirun(
        2,
        &["fit", &study, "--out", out.to_str().unwrap()],
        Duration::from_secs(120),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        err.matches("error: ").count(),
        1,
        "one message, from rank 0: {err}"
    );
    assert!(err.contains("file"), "{err}");
}

#[test]
fn a_bad_recording_stops_every_rank_with_its_message() {
    let dir = tmp("mpi", "bad");
    let study = study(&dir);
    std::fs::write(dir.join("back.csv"), "frame,x,y,z\n0,1,2,oops\n").unwrap();
    let out = dir.join("report");
    let o = mpirun(
        2,
        &["fit", &study, "--out", out.to_str().unwrap()],
        Duration::from_secs(120),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert_eq!(err.matches("error: ").count(), 1, "{err}");
    assert!(err.contains("back.csv"), "{err}");
    assert!(!out.exists(), "nothing written");
}
