//! Fuzzing the observation CSV parser (`Observations::parse_csv`, `read_csv`), the camera file
//! parser (`adjoint::camera_file::CameraFile::read`, then its `eyes` and `cameras`) and the
//! scene's extension sections (`Scene::build_simulation`, which checks them) with
//! proptest: random bytes and random mutations of valid files (byte flips, truncation,
//! duplicated, removed and swapped lines, huge, tiny, negative, non-finite and overflowing
//! numbers, inserted syntax). Whatever the input: `Ok` or an `Err` naming the file, never a
//! panic; a parsed CSV holds only finite coordinates and finite, non-negative weights.
//!
//! The strategies are `cutfem/tests/fuzz_common` (included by path). Each property runs
//! `DEFAULT_CASES` cases (a few seconds, as in CI); for a longer run set `PROPTEST_CASES`, e.g.
//! `PROPTEST_CASES=20000 cargo test --release -p adjoint --test parsers_fuzz`.

#[path = "../../cutfem/tests/fuzz_common/mod.rs"]
mod fuzz_common;

use adjoint::camera_file::CameraFile;
use adjoint::observations::Observations;
use cutfem::scene::Scene;
use fuzz_common::{apply, bytes, config, mutations};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

const CSV_SEEDS: &[&str] = &[
    "frame,x,y,z\n0,0.12,1.31,-0.05\n1,0.5,-1e-3,4\n\n1,7,8,9\n",
    "frame,x,y,z,camera,weight\n1,1,2,3,2,0.5\n1,1,2,3,,1\n3,-0.25,1e-12,2.5e3,0,4\n",
    "\u{feff}Frame, X, Y, Z, weight, camera\r\n3, 1, 2, 3, 0.25, 1\r\n18, 0.1, 0.2, 0.3, 1, 0\r\n",
];

const CAMERA_SEED: &str = r#"{
  "cameras": [
    {"id": 0, "eye": [2.0, 1.0, 0.0], "target": [0.0, 1.0, 0.0], "up": [0.0, 1.0, 0.0],
     "fov_y": 0.6, "width": 32, "height": 24},
    {"id": 1, "eye": [0.0, 1.0, 2.0], "target": [0.0, 1.0, 0.0], "up": [0.0, 1.0, 0.0],
     "fov_y": 0.7, "width": 64, "height": 64}
  ],
  "noise": 0.0,
  "seed": 7
}"#;

/// The tutorial effect's section (`[wind]`), which the adjoint layer parses; small grid.
const WIND_SEED: &str = r#"
[body]
shape = { kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }
resolution = 5
[material]
young = 2000.0
poisson = 0.3
[wind]
traction = [1.0, 0.0, 0.5]
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[model]
effects = ["corotation", "wind"]
"#;

/// A study of two recordings with every key of the format (`docs/study.md`).
const STUDY_SEED: &str = r#"
[study]
shared = ["young", "poisson"]
per_recording = ["initial_velocity"]
optimizer = "gauss-newton"
iterations = 15
cost = "surface"

[[recording]]
name = "swing"
scene = "swing.toml"
observations = "swing.csv"
cameras = "swing.cameras.json"
steps = 20

[[recording]]
scene = "push.toml"
observations = "push.csv"
"#;

/// A study file's outcome: `Ok`, or a one-line error naming the file.
fn check_study(bytes: &[u8]) -> Result<(), TestCaseError> {
    let path = scratch("fuzz.study.toml", bytes);
    let text = String::from_utf8_lossy(bytes);
    for result in [
        adjoint::study::Study::parse(&text, Path::new("fuzz.study.toml")),
        adjoint::study::Study::load(&path),
    ] {
        if let Err(e) = result {
            let msg = e.to_string();
            prop_assert!(msg.contains("fuzz.study.toml"), "{}", msg);
            prop_assert!(!msg.contains('\n'), "{}", msg);
        }
    }
    Ok(())
}

/// A scratch file `name` of this process holding `bytes` (each property its own name: the
/// properties run at once).
fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("adjoint-parsers-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn check_csv(result: Result<Observations, adjoint::Error>) -> Result<(), TestCaseError> {
    match result {
        Ok(o) => {
            for (_, pts) in o.frames() {
                for p in pts {
                    prop_assert!(p.position.iter().all(|x| x.is_finite()), "{:?}", p);
                    prop_assert!(p.weight.is_finite() && p.weight >= 0.0, "{:?}", p);
                }
            }
            // what is written reads back the same
            let again = Observations::parse_csv(&o.to_csv(), Path::new("again.csv"));
            prop_assert_eq!(again.ok(), Some(o));
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(msg.contains("fuzz.csv"), "{}", msg);
            prop_assert_eq!(msg.lines().count(), 1, "{}", msg);
        }
    }
    Ok(())
}

fn check_cameras(bytes: &[u8]) -> Result<(), TestCaseError> {
    let path = scratch("fuzz.cameras.json", bytes);
    match CameraFile::read(&path).map(|f| f.eyes()) {
        Ok(_) => {}
        Err(e) => prop_assert!(e.to_string().contains("fuzz.cameras.json"), "{}", e),
    }
    match CameraFile::read(&path).and_then(|f| f.cameras()) {
        Ok(cams) => {
            for c in &cams {
                prop_assert!((1..=8192).contains(&c.width) && (1..=8192).contains(&c.height));
            }
        }
        Err(e) => prop_assert!(e.to_string().contains("fuzz.cameras.json"), "{}", e),
    }
    Ok(())
}

#[test]
fn seeds_are_valid() {
    for s in CSV_SEEDS {
        assert!(!Observations::parse_csv(s, Path::new("seed.csv"))
            .unwrap()
            .is_empty());
    }
    let p = scratch("seed.cameras.json", CAMERA_SEED.as_bytes());
    assert_eq!(CameraFile::read(&p).unwrap().cameras().unwrap().len(), 2);
    let scene = Scene::parse(WIND_SEED, Path::new("seed.toml")).unwrap();
    scene.build_simulation().unwrap();
    let study = adjoint::study::Study::parse(STUDY_SEED, Path::new("seed.study.toml")).unwrap();
    assert_eq!(study.recordings.len(), 2);
}

proptest! {
    #![proptest_config(config())]

    /// Mutated observation CSVs, parsed in memory: `Ok` or a one-line `Err`, never a panic.
    #[test]
    fn mutated_csv_never_panics(seed in 0..CSV_SEEDS.len(), m in mutations()) {
        let b = apply(CSV_SEEDS[seed], &m);
        check_csv(Observations::parse_csv(&String::from_utf8_lossy(&b), Path::new("fuzz.csv")))?;
        check_csv(Observations::read_csv(scratch("mutated-fuzz.csv", &b)))?;
    }

    /// Random bytes as an observation file.
    #[test]
    fn random_csv_bytes_never_panic(b in bytes()) {
        check_csv(Observations::read_csv(scratch("random-fuzz.csv", &b)))?;
        let header = [b"frame,x,y,z\n".as_slice(), &b].concat();
        check_csv(Observations::read_csv(scratch("random-fuzz.csv", &header)))?;
    }

    /// Mutated camera files and random bytes as a camera file.
    #[test]
    fn camera_files_never_panic(m in mutations(), b in bytes()) {
        check_cameras(&apply(CAMERA_SEED, &m))?;
        check_cameras(&b)?;
    }

    /// Mutated study files and random bytes as a study file (issue 51: the fuzzers reach the
    /// study files).
    #[test]
    fn study_files_never_panic(m in mutations(), b in bytes()) {
        check_study(&apply(STUDY_SEED, &m))?;
        check_study(&b)?;
    }

    /// Mutated scenes with an extension section, through to the simulation a command builds.
    #[test]
    fn mutated_extension_scenes_never_panic(m in mutations()) {
        let b = apply(WIND_SEED, &m);
        if let Ok(scene) = Scene::parse(&String::from_utf8_lossy(&b), Path::new("fuzz.toml")) {
            // only small grids (a mutated resolution may ask for millions of nodes)
            let small = scene.body.resolution.is_some_and(|r| r <= 10.0)
                && scene.body.shape.as_ref().is_some_and(|s| {
                    let (lo, hi) = s.bounding_box();
                    (0..3).all(|a| (hi[a] - lo[a]).abs() <= 2.0)
                });
            if small {
                if let Err(e) = scene.build_simulation() {
                    prop_assert!(!e.to_string().is_empty());
                }
            }
        }
    }
}
