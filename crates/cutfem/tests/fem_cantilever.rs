//! Cantilever under its own weight: the static tip deflection converges to Euler-Bernoulli
//! `q L^4 / (8 E I)` as the grid is refined (clamped end by Nitsche's method).

mod fem_common;
use fem_common::*;

use cutfem::fem::{Aabb, Model, Simulation};
use gpumat::Vec3;

const L: f64 = 2.0;
const H: f64 = 0.2;
const W: f64 = 0.2;
const E: f64 = 1.0e5;

/// Euler-Bernoulli tip deflection of a clamped beam under the distributed load `rho g A`.
fn euler_bernoulli() -> f64 {
    let q = 1.0 * 10.0 * H * W;
    let i = W * H.powi(3) / 12.0;
    q * L.powi(4) / (8.0 * E * i)
}

/// Tip deflection (mean vertical displacement of the nodes nearest the free end's center
/// line) at cell size `h`.
fn tip_deflection(h: f64) -> f64 {
    let model = Model {
        young: E,
        poisson: 0.3,
        density: 1.0,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        corotation: false,
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [1.01 * h, 1.0, 1.0],
        }],
        ..Model::default()
    };
    // beam from x = 0 to L, centered on y = z = 0; offset by a tiny amount so faces are not
    // exactly on grid lines
    let center = [0.5 * L, 0.0, 0.0];
    let mut sim: Simulation = box_sim(center, [L, H, W], h, model);
    sim.solver.direct = true;
    sim.solve_static().expect("static solve");
    // average u_y over nodes on the end x = L (within the body's closure) near the axis
    let mut sum = 0.0;
    let mut n = 0;
    for (d, p) in sim.grid.positions.iter().enumerate() {
        if (p.x - L).abs() < 1e-9 && p.y.abs() <= 0.5 * H + 1e-9 && p.z.abs() <= 0.5 * W + 1e-9 {
            sum += sim.u.get(d, 0, 0).y;
            n += 1;
        }
    }
    assert!(n > 0);
    -sum / n as f64
}

#[test]
fn cantilever_converges_to_euler_bernoulli() {
    let exact = euler_bernoulli();
    let hs = [0.05, 0.025, 0.0125];
    let d: Vec<f64> = hs.iter().map(|&h| tip_deflection(h)).collect();
    let err: Vec<f64> = d.iter().map(|x| (x - exact) / exact).collect();
    for (h, (x, e)) in hs.iter().zip(d.iter().zip(&err)) {
        eprintln!("h = {h:6.4}: tip deflection {x:.6} (Euler-Bernoulli {exact:.6}), relative error {e:+.4}");
    }
    // observed order from the three resolutions (h halves each time)
    let rate = ((d[1] - d[0]) / (d[2] - d[1])).abs().log2();
    // Richardson extrapolation with the observed rate
    let limit = d[2] + (d[2] - d[1]) / (2f64.powf(rate) - 1.0);
    eprintln!(
        "observed rate {rate:.2}, extrapolated limit {limit:.6} ({:+.4})",
        (limit - exact) / exact
    );
    assert!(err[2].abs() < 0.10, "finest error {}", err[2]);
    assert!(
        err[2].abs() < err[1].abs() && err[1].abs() < err[0].abs(),
        "error does not fall: {err:?}"
    );
    assert!(
        ((limit - exact) / exact).abs() < 0.03,
        "extrapolated limit {limit} vs {exact}"
    );
}
