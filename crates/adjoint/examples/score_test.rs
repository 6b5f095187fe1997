//! The score (Lagrange-multiplier) test a diagnosis runs for an effect, on a scene that has the
//! effect switched on at its neutral value (docs/effects-tutorial.md):
//!
//! ```sh
//! cargo run --release -p adjoint --example score_test -- SCENE OBS.csv PARAMS
//! ```
//!
//! With the squared loss `C = 1/2 sum r^2` of `N` residuals, the adjoint gradient `g` and the
//! Gauss-Newton matrix `H` (tangent-linear pass) of `PARAMS` at the scene's values predict the
//! decrease `delta = 1/2 g^T H^{-1} g`; the score is `LM = N delta / C` (chi-square with as many
//! degrees of freedom as components when the effect is absent). Also prints `H` as a
//! correlation matrix: components whose columns are nearly parallel cannot be told apart by
//! the data.
use adjoint::camera_file::CameraFile;
use adjoint::cost::Robust;
use adjoint::fit::{cameras_path, invert_small, scene_problem, CostKind};
use adjoint::observations::Observations;
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use std::path::PathBuf;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: score_test SCENE OBS.csv PARAMS".into());
    }
    let scene = Scene::load(&PathBuf::from(&args[0])).map_err(|e| e.to_string())?;
    let obs_path = PathBuf::from(&args[1]);
    let obs = Observations::read_csv(&obs_path).map_err(|e| e.to_string())?;
    let eyes = match cameras_path(&obs_path) {
        p if p.exists() => CameraFile::read(&p)?.eyes(),
        _ => Vec::new(),
    };
    let params = ParamSet::parse(&[args[2].as_str()])?;
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
    let (ev, g, h) = p.gauss_newton(&x).map_err(|e| e.to_string())?;
    let n = x.len();
    let inv = invert_small(&h, n).ok_or("the Gauss-Newton matrix is singular")?;
    let step: Vec<f64> = (0..n)
        .map(|i| -(0..n).map(|j| inv[i * n + j] * g[j]).sum::<f64>())
        .collect();
    let delta = -0.5 * g.iter().zip(&step).map(|(a, b)| a * b).sum::<f64>();
    let count: usize = ev.frames.iter().map(|f| f.count).sum();
    let c0 = ev.cost;
    // component names, the external force's by its own labels (e.g. `wind.x`)
    let external = p
        .base
        .external_force
        .as_ref()
        .map(|e| e.labels.clone())
        .unwrap_or_default();
    let labels: Vec<String> = p
        .params
        .labels()
        .into_iter()
        .map(|l| {
            let k = l
                .strip_prefix("external_force[")
                .and_then(|r| r.strip_suffix(']'));
            k.and_then(|k| external.get(k.parse::<usize>().ok()?).cloned())
                .unwrap_or(l)
        })
        .collect();
    println!("{count} residuals, cost C = {c0:.6e}, rms {:.4e}", ev.rms());
    println!(
        "{:>18} {:>12} {:>14} {:>14}",
        "component", "value", "gradient", "step -H^-1 g"
    );
    for k in 0..n {
        println!(
            "{:>18} {:>12.6} {:>14.6e} {:>14.6e}",
            labels[k], x[k], g[k], step[k]
        );
    }
    let predicted = (c0 - delta).max(0.0);
    println!(
        "predicted decrease delta = {delta:.6e}, score LM = N delta / C = {:.4e}, predicted rms {:.4e}",
        count as f64 * delta / c0,
        (2.0 * predicted / count as f64).sqrt()
    );
    println!("Gauss-Newton matrix as correlations H_ij / sqrt(H_ii H_jj):");
    for i in 0..n {
        let row: Vec<String> = (0..n)
            .map(|j| format!("{:+.4}", h[i * n + j] / (h[i * n + i] * h[j * n + j]).sqrt()))
            .collect();
        println!("{:>18} {}", labels[i], row.join(" "));
    }
    Ok(())
}
