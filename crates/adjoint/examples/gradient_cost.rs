//! One adjoint gradient of a scene against observations, with its cost split into forward,
//! cost and backward time and CG iterations (the numbers behind Table 5.2):
//!
//! ```sh
//! cargo run --release -p adjoint --example gradient_cost -- SCENE OBS.csv [params]
//! ```
use adjoint::camera_file::CameraFile;
use adjoint::cost::Robust;
use adjoint::fit::{cameras_path, scene_problem, CostKind};
use adjoint::observations::Observations;
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use std::path::PathBuf;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: gradient_cost SCENE OBS.csv [params]".into());
    }
    let scene = Scene::load(&PathBuf::from(&args[0])).map_err(|e| e.to_string())?;
    let obs_path = PathBuf::from(&args[1]);
    let obs = Observations::read_csv(&obs_path).map_err(|e| e.to_string())?;
    let eyes = match cameras_path(&obs_path) {
        p if p.exists() => CameraFile::read(&p)?.eyes(),
        _ => Vec::new(),
    };
    let params = ParamSet::parse(&[args.get(2).map_or("young,poisson", String::as_str)])?;
    let mut p = scene_problem(
        &scene,
        &obs,
        params,
        Robust::Squared,
        None,
        CostKind::Surface,
        &eyes,
    )?;
    let x = p.x0();
    let (ev, g, _) = p.gradient(&x).map_err(|e| e.to_string())?;
    let steps = p.steps as f64;
    println!(
        "cost {:.6e} rms {:.3e} gradient {g:?}\nper step: forward {:.1} ms, cost {:.1} ms, backward {:.1} ms (ratio {:.2}); CG iterations forward {:.1}, backward {:.1}",
        ev.cost,
        ev.rms(),
        1e3 * ev.forward_s / steps,
        1e3 * ev.cost_s / steps,
        1e3 * ev.backward_s / steps,
        ev.backward_s / ev.forward_s,
        ev.forward_iterations as f64 / steps,
        ev.backward_iterations as f64 / steps,
    );
    Ok(())
}
