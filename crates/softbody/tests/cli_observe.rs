//! `softbody observe` end to end on a small box: the CSV and JSON follow interface.md, the
//! points lie on the simulated surface, the seed makes runs reproducible, and bad flags give
//! one line on stderr, exit code 1 and no panic.

use adjoint::observations::Observations;
use cutfem::mesh::distance::closest_point_on_triangle;
use cutfem::TriMesh;
use std::path::{Path, PathBuf};
use std::process::Output;
mod common;
use common::*;

/// The tiny bar of 4 steps ([`tiny_bar`]), softer (E = 500) and with steps of 0.02 s.
fn scene(dir: &Path) -> PathBuf {
    let text = edited(
        &tiny_bar(4, ""),
        &[("young = 2000.0", "young = 500.0"), ("dt = 0.01", "dt = 0.02")],
    );
    write(dir, "small.toml", &text)
}

fn observe(scene: &Path, out: &Path, extra: &[&str]) -> Output {
    softbody()
        .args(["observe", scene.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(extra)
        .output()
        .unwrap()
}

fn distance_to(mesh: &TriMesh, p: [f64; 3]) -> f64 {
    (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            let q = closest_point_on_triangle(p, a, b, c);
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn observe_writes_points_on_the_simulated_surface() {
    let dir = tmp("cli-observe", "ok");
    let scene = scene(&dir);
    let csv = dir.join("obs/points.csv");
    let png = dir.join("preview.png");
    let args = [
        "--cameras",
        "3",
        "--pixels",
        "32",
        "--radius",
        "1.5",
        "--seed",
        "5",
        "--json",
    ];
    let o = observe(
        &scene,
        &csv,
        &[&args[..], &["--preview", png.to_str().unwrap()]].concat(),
    );
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("exactly one JSON object");
    assert_eq!(v["frames"], 4);
    assert_eq!(v["cameras"], 3);
    assert_eq!(v["camera_poses"].as_array().unwrap().len(), 3);
    assert_eq!((v["pixels"].as_u64(), v["seed"].as_u64()), (Some(32), Some(5)));
    let points = v["points"].as_u64().unwrap() as usize;
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("frame,x,y,z,camera\n"), "{}", &text[..40]);
    assert_eq!(text.lines().count(), points + 1);
    let obs = Observations::read_csv(&csv).unwrap();
    assert_eq!(obs.len(), points);
    assert_eq!(obs.frame_numbers(), vec![1, 2, 3, 4]);
    let per_frame = &v["points_per_frame"];
    assert!(per_frame["min"].as_u64().unwrap() > 200, "{per_frame}");
    let png_bytes = std::fs::read(&png).unwrap();
    assert_eq!(&png_bytes[..8], b"\x89PNG\r\n\x1a\n");

    // the points lie on the surface `simulate` writes for the same frame (PLY stores f32)
    let sim = dir.join("sim");
    let s = softbody()
        .args([
            "simulate",
            scene.to_str().unwrap(),
            "--out",
            sim.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    ok(&s);
    let reference = TriMesh::load(sim.join("frames/0000.ply")).unwrap();
    for (f, pts) in obs.frames() {
        let mesh = TriMesh::load(sim.join(format!("frames/{f:04}.ply"))).unwrap();
        let mut cameras = [0; 3];
        for p in pts {
            let d = distance_to(&mesh, p.position);
            assert!(d < 1e-4, "frame {f}: {:?} is {d} off the surface", p.position);
            cameras[p.camera.unwrap() as usize] += 1;
        }
        assert!(cameras.iter().all(|&c| c > 0), "frame {f}: {cameras:?}");
        if f == 4 {
            // the free end sags: the last frame is not the reference shape
            let off = pts
                .iter()
                .map(|p| distance_to(&reference, p.position))
                .fold(0.0, f64::max);
            assert!(off > 1e-3, "frame 4 looks like the reference ({off})");
        }
    }
}

#[test]
fn the_seed_makes_runs_reproducible_and_frames_are_selectable() {
    let dir = tmp("cli-observe", "seed");
    let scene = scene(&dir);
    let run = |name: &str, extra: &[&str]| {
        let csv = dir.join(name);
        let o = observe(
            &scene,
            &csv,
            &[&["--steps", "2", "--pixels", "16"], extra].concat(),
        );
        ok(&o);
        assert!(o.stdout.is_empty(), "human output goes to stderr");
        assert!(String::from_utf8_lossy(&o.stderr).contains("points"));
        std::fs::read_to_string(csv).unwrap()
    };
    let a = run("a.csv", &["--noise", "0.01", "--seed", "7"]);
    assert_eq!(
        a,
        run("b.csv", &["--noise", "0.01", "--seed", "7"]),
        "same seed, same file"
    );
    assert_ne!(a, run("c.csv", &["--noise", "0.01", "--seed", "8"]), "other seed");
    let clean = run("d.csv", &["--seed", "7"]);
    assert_eq!(
        a.lines().count(),
        clean.lines().count(),
        "noise moves points, keeps pixels"
    );
    assert_ne!(a, clean);
    let frames = |text: &str| {
        let obs = Observations::parse_csv(text, Path::new("x.csv")).unwrap();
        obs.frame_numbers()
    };
    assert_eq!(frames(&clean), vec![1, 2]);
    assert_eq!(frames(&run("e.csv", &["--include-reference"])), vec![0, 1, 2]);
    assert_eq!(frames(&run("f.csv", &["--frames", "0,2"])), vec![0, 2]);
}

#[test]
fn bad_flags_are_one_line_errors() {
    let dir = tmp("cli-observe", "bad");
    let scene = scene(&dir);
    let csv = dir.join("o.csv");
    let blocker = dir.join("file");
    std::fs::write(&blocker, "not a folder").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--cameras", "0"], "--cameras"),
        (vec!["--pixels", "0"], "--pixels"),
        (vec!["--noise", "-0.1"], "--noise"),
        (vec!["--noise", "nan"], "--noise"),
        (vec!["--radius", "0"], "--radius"),
        (vec!["--fov", "180"], "--fov"),
        (vec!["--frames", "1,x"], "--frames"),
        (vec!["--frames", "9"], "beyond the 4 steps"),
        (vec!["--steps", "0"], "no frame to observe"),
    ];
    let blocked = blocker.join("o.csv");
    let missing = dir.join("missing.toml");
    let mut runs: Vec<(Output, &str)> = cases
        .iter()
        .map(|(extra, needle)| (observe(&scene, &csv, extra), *needle))
        .collect();
    runs.push((observe(&scene, &blocked, &[]), "file"));
    runs.push((observe(&missing, &csv, &[]), "missing.toml"));
    for (o, needle) in runs {
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "exit code for {needle}: {err}");
        assert!(!err.contains("panicked"), "panic: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one line expected: {err}");
        assert!(err.contains(needle), "`{needle}` not in: {err}");
        assert!(o.stdout.is_empty());
    }
}
