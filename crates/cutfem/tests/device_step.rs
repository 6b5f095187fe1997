//! The step's linear solve on a device (`[numerics] backend = "cuda"`, `fem::device_solve`):
//! the cuboid of Tables B.5/B.6 run on the emulated CUDA device (the catalogue's kernels under
//! the host emulation of CUDA, through the same `gpumat::device` code a GPU runs) gives the
//! CPU backend's block-Jacobi trajectory within the CG tolerance, with the iteration counts
//! within 5% (plus one); on a real GPU (feature `cuda`) the same comparison runs; the scene key
//! parses, and a build or machine without CUDA says so in one line naming the scene.

mod fem_common;

use cutfem::fem::{ComputeBackend, Grid, Model, Preconditioner, Simulation, SolverSettings};
use cutfem::scene::Scene;
use fem_common::{thesis_cuboid_grid, SMALL_BOX_SCENE};
use gpumat::device::Device;
use gpumat::{Matrix, Vec3};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn run(
    grid: &Grid,
    model: &Model,
    device: Option<Arc<dyn Device>>,
    steps: usize,
) -> (Matrix<Vec3<f64>>, Vec<usize>) {
    let mut sim = Simulation::new(grid.clone(), model.clone()).unwrap();
    sim.solver = SolverSettings {
        preconditioner: Preconditioner::BlockJacobi,
        reuse_factor: false,
        ..SolverSettings::default()
    };
    sim.solver.cg.tolerance = 1e-9;
    let on_device = device.is_some();
    sim.set_device(device);
    assert_eq!(sim.device_name().is_some(), on_device);
    let mut iterations = Vec::new();
    for _ in 0..steps {
        let info = sim.step().unwrap();
        assert!(!info.fallback, "CG fell back (device {on_device})");
        iterations.push(info.iterations);
    }
    (sim.u, iterations)
}

fn emulated() -> Option<Arc<dyn Device>> {
    use gpumat::device::emulated;
    if !emulated::compiler_available() {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "CI=true and the C++ compiler is missing (needed by the emulated device)"
        );
        eprintln!("SKIPPED: no C++ compiler for the emulated CUDA device");
        return None;
    }
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gpumat_emu");
    Some(emulated::EmulatedDevice::open(&dir).unwrap())
}

fn compare(device: Arc<dyn Device>) {
    for ground in [false, true] {
        let (grid, model) = thesis_cuboid_grid(5.0, ground);
        let steps = 4;
        let (u_cpu, it_cpu) = run(&grid, &model, None, steps);
        let (u_dev, it_dev) = run(&grid, &model, Some(device.clone()), steps);
        let d = Matrix::eval(u_dev.ex() - u_cpu.ex()).ex().norm() / u_cpu.ex().norm();
        assert!(u_cpu.ex().norm() > 1e-4, "the cuboid moved");
        assert!(
            d < 1e-7,
            "ground {ground}: device vs cpu displacement differs by {d:e}"
        );
        // the dots are summed in another order (fixed trees), which moves the tolerance
        // crossing of the slow tail by an iteration or two
        for (k, (a, b)) in it_dev.iter().zip(&it_cpu).enumerate() {
            assert!(
                a.abs_diff(*b) <= 1 + b / 20,
                "ground {ground}, step {k}: device {it_dev:?} vs cpu {it_cpu:?}"
            );
        }
    }
}

#[test]
fn cuboid_steps_on_the_emulated_device_match_the_cpu() {
    if let Some(device) = emulated() {
        compare(device);
    }
}

#[test]
fn cuboid_steps_on_a_gpu_match_the_cpu() {
    match cutfem::fem::device_solve::cuda_device() {
        Ok(device) => compare(device),
        Err(e) => {
            let msg = e.to_string();
            assert_eq!(msg.lines().count(), 1, "{msg}");
            eprintln!("SKIPPED: {msg}");
        }
    }
}

#[test]
fn scene_backend_key() {
    let base = SMALL_BOX_SCENE;
    let path = Path::new("scene.toml");
    let scene = Scene::parse(base, path).unwrap();
    assert_eq!(scene.numerics.backend, ComputeBackend::Cpu);
    assert!(scene.build_simulation().unwrap().device_name().is_none());
    let cpu = Scene::parse(&format!("{base}[numerics]\nbackend = \"cpu\"\n"), path).unwrap();
    assert_eq!(
        (cpu.numerics.backend, cpu.numerics.backend.name()),
        (ComputeBackend::Cpu, "cpu")
    );
    let err = Scene::parse(&format!("{base}[numerics]\nbackend = \"opencl\"\n"), path)
        .unwrap_err()
        .to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("unknown variant `opencl`, expected `cpu` or `cuda`"),
        "{err}"
    );
    let cuda = Scene::parse(&format!("{base}[numerics]\nbackend = \"cuda\"\n"), path).unwrap();
    assert_eq!(cuda.numerics.backend, ComputeBackend::Cuda);
    match cuda.build_simulation() {
        // a machine with a GPU and a build with feature `cuda`
        Ok(sim) => assert!(sim.device_name().is_some()),
        Err(e) => {
            let msg = e.to_string();
            assert_eq!(msg.lines().count(), 1, "{msg}");
            assert!(
                msg.contains("scene.toml") && msg.contains("backend = \"cuda\""),
                "{msg}"
            );
            assert!(msg.contains("CUDA"), "{msg}");
        }
    }
}
