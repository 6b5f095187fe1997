//! Issue 13, "standard errors ignore the weights": the statistics of a fit use the weights as
//! its cost does (`adjoint::statistics`). Scaling every weight leaves the estimate and the
//! standard errors unchanged; a weight of 4 is four observations of the point in the cost, its
//! gradient, the Gauss-Newton matrix and `r^T W r` (exactly what duplicated rows give), and the
//! standard errors differ from the duplicated file's only by its degrees of freedom.

use adjoint::cost::Robust;
use adjoint::fit::{scene_problem, uncertainty, CostKind, FitObjective, Uncertainty};
use adjoint::observations::{Observations, ObservedPoint};
use adjoint::observe::{synthesize, RigParams};
use adjoint::optim::{minimize, OptimParams, Optimizer};
use adjoint::params::ParamSet;
use cutfem::scene::Scene;
use std::ops::ControlFlow;
use std::path::Path;

/// A tiny cantilever of Young's modulus `young`, 3 steps, with the thesis' element and clamp:
/// with the (default) incompatible element its 3 steps leave Poisson's ratio undetermined, the
/// fit runs its coordinate onto the bound (x = 17 or 25, where the cost is flat), and the
/// estimates then differ by rounding, not by the weights this file is about.
fn scene(young: f64) -> Scene {
    let text = format!(
        r#"
[body]
shape = {{ kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }}
resolution = 10
[material]
young = {young}
poisson = 0.3
[gravity]
acceleration = [0.0, -10.0, 0.0]
[[dirichlet]]
min = [-1.0, 0.0, -1.0]
max = [-0.2, 2.0, 1.0]
[time]
dt = 0.01
steps = 3
[numerics]
element = "trilinear"
nitsche = "thesis"
"#
    );
    Scene::parse(&text, Path::new("s.toml")).unwrap()
}

/// Noisy observations of the truth (E = 2000), every point of frames 1..=3.
fn observations() -> Observations {
    let rig = RigParams {
        cameras: 2,
        pixels: 32,
        ..RigParams::default()
    };
    let (obs, _) = synthesize(&scene(2000.0), &rig, 2e-3, 3, |_, _| {}).unwrap();
    let mut out = Observations::new();
    for (f, pts) in obs.frames().filter(|(f, _)| *f > 0) {
        for p in pts {
            out.push(f, ObservedPoint { camera: None, ..*p });
        }
    }
    assert!(out.len() > 40, "{} points", out.len());
    out
}

/// Every `k`-th point (of each frame) gets weight `w`; the others keep weight 1; all are then
/// multiplied by `scale`. With `duplicate`, the heavy points are written `w` times with
/// weight `scale` instead.
fn reweighted(obs: &Observations, k: usize, w: f64, scale: f64, duplicate: bool) -> Observations {
    let mut out = Observations::new();
    for (f, pts) in obs.frames() {
        for (i, p) in pts.iter().enumerate() {
            let heavy = i % k == 0;
            if heavy && duplicate {
                for _ in 0..w as usize {
                    out.push(f, ObservedPoint { weight: scale, ..*p });
                }
            } else {
                let weight = scale * if heavy { w } else { 1.0 };
                out.push(f, ObservedPoint { weight, ..*p });
            }
        }
    }
    out
}

/// At the start (E = 2600): cost, gradient, Gauss-Newton matrix and the uncertainty; then the
/// estimate after a few Levenberg-Marquardt iterations.
struct Stats {
    cost: f64,
    gradient: Vec<f64>,
    hessian: Vec<f64>,
    unc: Uncertainty,
    estimate: Vec<f64>,
}

fn stats(obs: &Observations) -> Stats {
    let params = ParamSet::parse(&["young,poisson"]).unwrap();
    let mut p = scene_problem(
        &scene(2600.0),
        obs,
        params,
        Robust::Squared,
        None,
        CostKind::Surface,
        &[],
    )
    .unwrap();
    let x = p.x0();
    let (ev, gradient, _) = p.gradient(&x).unwrap();
    let hessian = p.gauss_newton_matrix(&x).unwrap();
    let unc = uncertainty(&mut p, &x, &ev).unwrap().expect("determined");
    let mut objective = FitObjective::new(&mut p);
    let oparams = OptimParams {
        max_iterations: 4,
        ..OptimParams::default()
    };
    let (estimate, _) = minimize(Optimizer::GaussNewton, &mut objective, &x, &oparams, &mut |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    Stats {
        cost: ev.cost,
        gradient,
        hessian,
        unc,
        estimate,
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().chain(b).fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / scale)
        .fold(0.0, f64::max)
}

#[test]
fn scaling_every_weight_leaves_the_standard_errors_unchanged() {
    let obs = observations();
    let one = stats(&reweighted(&obs, 5, 4.0, 1.0, false));
    let hundred = stats(&reweighted(&obs, 5, 4.0, 100.0, false));
    assert_eq!(one.unc.points, hundred.unc.points);
    println!(
        "weights x1: se {:?}; x100: se {:?}",
        one.unc.std_errors, hundred.unc.std_errors
    );
    for (a, b) in one.unc.std_errors.iter().zip(&hundred.unc.std_errors) {
        assert!(*a > 0.0 && rel(*a, *b) < 1e-9, "standard errors {a} and {b}");
    }
    assert!(rel(100.0 * one.unc.residual_variance, hundred.unc.residual_variance) < 1e-12);
    assert!(
        max_rel(&one.estimate, &hundred.estimate) < 1e-6,
        "{:?} {:?}",
        one.estimate,
        hundred.estimate
    );
}

#[test]
fn a_weight_of_4_is_the_point_observed_4_times() {
    let obs = observations();
    let weighted = stats(&reweighted(&obs, 5, 4.0, 1.0, false));
    let duplicated = stats(&reweighted(&obs, 5, 4.0, 1.0, true));
    // the cost, its gradient and H: the same function of the parameters, so the same estimate
    assert!(rel(weighted.cost, duplicated.cost) < 1e-12);
    assert!(max_rel(&weighted.gradient, &duplicated.gradient) < 1e-10);
    assert!(max_rel(&weighted.hessian, &duplicated.hessian) < 1e-10);
    // (the optimizer's path amplifies the summation order's rounding: 4e-7 measured)
    assert!(
        max_rel(&weighted.estimate, &duplicated.estimate) < 1e-5,
        "{:?} {:?}",
        weighted.estimate,
        duplicated.estimate
    );
    // r^T W r the same; the degrees of freedom n - p against n + 3k - p
    let (n, nd, p) = (weighted.unc.points, duplicated.unc.points, 2);
    // every duplicated point within reach adds 3 rows
    assert!(nd > n && (nd - n) % 3 == 0, "{n} {nd}");
    let rwr = |u: &Uncertainty| u.residual_variance * (u.points - p) as f64;
    assert!(rel(rwr(&weighted.unc), rwr(&duplicated.unc)) < 1e-10);
    let ratio = (((nd - p) as f64) / ((n - p) as f64)).sqrt();
    println!(
        "weight 4: n {n}, se {:?}; duplicated: n {nd}, se {:?}; ratio {ratio}",
        weighted.unc.std_errors, duplicated.unc.std_errors
    );
    for (a, b) in weighted.unc.std_errors.iter().zip(&duplicated.unc.std_errors) {
        assert!(
            rel(*a, b * ratio) < 1e-9,
            "standard errors {a} and {b} (ratio {ratio})"
        );
    }
}
