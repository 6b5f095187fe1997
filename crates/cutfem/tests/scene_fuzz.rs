//! Fuzzing the scene parser (`Scene::parse`, `Scene::load`) with proptest: random bytes and
//! random mutations of valid scene files (byte flips, truncation, duplicated, removed and
//! swapped lines, huge, tiny, negative, non-finite and overflowing numbers, inserted syntax).
//! Whatever the input, parsing returns `Ok` or an `Err` whose message names the file, never
//! panics; a scene that parses also gives its model, its resolution and, when its grid is
//! small, its body SDF without a panic.
//!
//! Each property runs `fuzz_common::DEFAULT_CASES` cases (a few seconds, as in CI); for a
//! longer run set `PROPTEST_CASES`, e.g.
//! `PROPTEST_CASES=20000 cargo test --release -p cutfem --test scene_fuzz`.

mod fuzz_common;

use cutfem::scene::{Scene, PADDING_CELLS};
use cutfem::SdfGrid;
use fuzz_common::{apply, bytes, config, mutations};
use proptest::prelude::*;
use std::path::Path;

/// Valid scenes that together use every section and key of the format.
const SEEDS: &[&str] = &[
    r#"
[body]
shape = { kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }
resolution = 10
[material]
young = 2000.0
poisson = 0.3
density = 1.0
[damping]
mass = 0.1
stiffness = 0.01
[gravity]
acceleration = [0.0, -10.0, 0.0]
[ground]
normal = [0.0, 1.0, 0.0]
height = 0.5
stiffness = 1e4
softness = 100.0
scheme = "implicit"
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[initial]
velocity = [0.0, 0.0, 0.5]
angular_velocity = [0.0, 1.0, 0.0]
[time]
dt = 0.01
steps = 8
theta = 0.6
[model]
effects = ["gravity", "damping", "ground", "corotation", "initial_velocity", "stiffness_field"]
stiffness_field = { cells = [2, 2, 2] }
[fit]
parameters = ["young", "poisson"]
optimizer = "gauss-newton"
iterations = 15
[numerics]
nitsche = "consistent"
nitsche_gamma = 10.0
cg_tolerance = 1e-8
cg_max_iterations = 500
diffusion = "harmonic"
preconditioner = "block_ic0"
reuse_factor_mb = 200.0
element = "incompatible"
"#,
    r#"
# a torus held at one side
[body]
shape = { kind = "torus", center = [0.0, 1.0, 0.0], axis = [0.0, 0.0, 1.0], major = 0.5, minor = 0.2 }
resolution = 8
[material]
young = 2200.0
poisson = 0.32
[[dirichlet]]
min = [-0.8, 0.8, -0.3]
max = [-0.5, 1.2, 0.3]
[[dirichlet]]
min = [0.5, 0.8, -0.3]
max = [0.8, 1.2, 0.3]
[time]
steps = 30
[numerics]
nitsche = "thesis"
nitsche_eta = 1e8
preconditioner = "rest_cholesky"
element = "trilinear"
"#,
    r#"
[body]
shape = { kind = "sphere", center = [0.0, 0.5, 0.0], radius = 0.3 }
[material]
young = 5e3
poisson = 0.45
[ground]
scheme = "thesis"
[wind]
traction = [1.0, 0.0, 0.0]
[model]
effects = ["ground", "wind"]
"#,
    r#"
[body]
shape = { kind = "capsule", a = [0.0, 0.5, 0.0], b = [0.5, 0.5, 0.0], radius = 0.1 }
resolution = 12.5
[material]
young = 1e4
poisson = 0.1
[time]
dt = 0.005
steps = 1
theta = 0.9
"#,
    r#"
[body]
sdf = "missing.sdf"
[material]
young = 1.0
poisson = 0.3
"#,
    r#"
[body]
mesh = "missing.obj"
resolution = 5
[material]
young = 1.0
poisson = 0.3
"#,
];

/// The largest grid whose SDF a case samples (nodes).
const MAX_SAMPLED_NODES: f64 = 50_000.0;

/// Parses `text` and, when it parses, uses the scene as a command would (never panicking).
fn exercise(text: &str) {
    let path = Path::new("/nonexistent/fuzz.toml");
    match Scene::parse(text, path) {
        Ok(scene) => {
            let _ = scene.to_model();
            let _ = scene.effects();
            if let Some(shape) = &scene.body.shape {
                let resolution = scene.body.resolution.unwrap_or(cutfem::scene::DEFAULT_RESOLUTION);
                if shape.validate().is_ok() {
                    let (lo, hi) = shape.bounding_box();
                    let small =
                        SdfGrid::covering_grid(lo, hi, resolution, PADDING_CELLS).is_ok_and(|(_, d)| {
                            d.iter().map(|&n| n as f64).product::<f64>() <= MAX_SAMPLED_NODES
                        });
                    if small {
                        let _ = scene.body_sdf();
                    }
                }
            } else {
                // the seeds' files do not exist: an error
                let _ = scene.body_sdf();
            }
            let _ = scene.resolution();
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("fuzz.toml"), "the error names the file: {msg}");
        }
    }
}

#[test]
fn seeds_are_valid() {
    for (i, s) in SEEDS.iter().enumerate() {
        if let Err(e) = Scene::parse(s, Path::new("seed.toml")) {
            panic!("seed {i}: {e}");
        }
    }
}

proptest! {
    #![proptest_config(config())]

    /// Mutations of valid scenes: `Ok` or `Err`, never a panic.
    #[test]
    fn mutated_scenes_never_panic(seed in 0..SEEDS.len(), m in mutations()) {
        let b = apply(SEEDS[seed], &m);
        exercise(&String::from_utf8_lossy(&b));
    }

    /// Random bytes, read from a file as `softbody` reads a scene: `Ok` or `Err`, never a panic.
    #[test]
    fn random_bytes_never_panic(b in bytes()) {
        let dir = std::env::temp_dir().join(format!("cutfem-scene-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("fuzz.toml");
        std::fs::write(&path, &b).unwrap();
        if let Err(e) = Scene::load(&path) {
            prop_assert!(e.to_string().contains("fuzz.toml"), "{}", e);
        }
        exercise(&String::from_utf8_lossy(&b));
    }
}
