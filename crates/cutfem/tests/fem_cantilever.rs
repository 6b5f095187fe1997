//! Cantilever under its own weight against beam theory: the static tip deflection of a beam
//! 2 x 0.2 x 0.2 (E = 1e5, nu = 0.3), its end face x = 0 held by Nitsche's method, against
//! Timoshenko's `q L^4 / (8 E I) + q L^2 / (2 kappa G A)` (Euler-Bernoulli plus the shear
//! correction, Cowper's `kappa = 10 (1 + nu) / (12 + 11 nu)` for a square section: +1.0%).
//! The incompatible element (incompatible modes, exact integration) is within 3% at h = 0.05 (4
//! cells through the thickness) and 1% at h = 0.025; the thesis' trilinear element with the
//! corner rule locks (more than 10% too stiff at h = 0.05). `examples/element_split.rs` gives
//! the full table (every element, cut faces, nu = 0.49).

mod fem_common;
use fem_common::*;

use cutfem::fem::element::Element;
use cutfem::fem::{Aabb, Model, Simulation};
use gpumat::Vec3;

const L: f64 = 2.0;
const H: f64 = 0.2;
const W: f64 = 0.2;
const E: f64 = 1.0e5;
const NU: f64 = 0.3;

/// Timoshenko's tip deflection of a clamped beam under the distributed load `rho g A`.
fn timoshenko() -> f64 {
    let q = 1.0 * 10.0 * H * W;
    let i = W * H.powi(3) / 12.0;
    let g = E / (2.0 * (1.0 + NU));
    let kappa = 10.0 * (1.0 + NU) / (12.0 + 11.0 * NU);
    q * L.powi(4) / (8.0 * E * i) + q * L * L / (2.0 * kappa * g * H * W)
}

/// Tip deflection (mean vertical displacement of the nodes on the free end face) at cell size
/// `h`; the faces lie on grid lines, the box holds the end face x = 0 alone.
fn tip_deflection(h: f64, element: Element) -> f64 {
    let model = Model {
        young: E,
        poisson: NU,
        density: 1.0,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        corotation: false,
        element,
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.0, 1.0, 1.0],
        }],
        ..Model::default()
    };
    let mut sim: Simulation = box_sim([0.5 * L, 0.0, 0.0], [L, H, W], h, model);
    sim.solver.direct = true;
    sim.solve_static().expect("static solve");
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
fn cantilever_matches_beam_theory_without_locking() {
    let exact = timoshenko();
    let err = |h: f64, el: Element| {
        let d = tip_deflection(h, el);
        let e = (d - exact) / exact;
        eprintln!(
            "{:>12} h = {h:6.4}: tip {d:.6} (Timoshenko {exact:.6}), error {:+.4}",
            el.name(),
            e
        );
        e
    };
    let e05 = err(0.05, Element::Incompatible);
    let e025 = err(0.025, Element::Incompatible);
    let thesis = err(0.05, Element::Trilinear);
    assert!(e05.abs() < 0.03, "h = 0.05: error {e05}");
    assert!(e025.abs() < 0.01, "h = 0.025: error {e025}");
    assert!(thesis < -0.10, "the thesis element no longer locks? {thesis}");
}
