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
use cutfem::fem::{Aabb, Model, NitscheQuadrature, Simulation};
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

/// The box holding the end face x = 0 alone.
const END: Aabb = Aabb {
    min: [-1.0, -1.0, -1.0],
    max: [0.0, 1.0, 1.0],
};

/// The beam's linear model under gravity with `element`, held by `dirichlet`.
/// The beam's model, clamped with the consistent Nitsche terms and their scaled penalty
/// (`docs/simulation.md`, "Nitsche").
fn beam(element: Element, dirichlet: Vec<Aabb>) -> Model {
    Model {
        young: E,
        poisson: NU,
        density: 1.0,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        corotation: false,
        element,
        dirichlet,
        nitsche_quadrature: NitscheQuadrature::Consistent,
        nitsche: NitscheQuadrature::Consistent.default_penalty(),
        ..Model::default()
    }
}

/// Tip deflection (mean vertical displacement of the nodes on the free end face) at cell size
/// `h`; the faces lie on grid lines, the box holds the end face x = 0 alone.
fn tip_deflection(h: f64, element: Element) -> f64 {
    let model = beam(element, vec![END]);
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
    let thesis025 = err(0.025, Element::Trilinear);
    assert!(e05.abs() < 0.03, "h = 0.05: error {e05}");
    assert!(e025.abs() < 0.01, "h = 0.025: error {e025}");
    assert!(thesis < -0.10, "the thesis element no longer locks? {thesis}");
    // the thesis element converges from below at first order or better
    let order = (thesis / thesis025).log2();
    eprintln!("thesis element: observed order {order:.2}");
    assert!(thesis025 < 0.0 && order > 1.0, "{thesis} -> {thesis025}");
    reference::check(
        "cantilever",
        "static tip deflection of the cantilever 2 x 0.2 x 0.2 (E = 1e5, nu = 0.3, gravity 10, end face x = 0 held) relative to Timoshenko",
        "cargo test --release -p cutfem --test fem_cantilever",
        &[
            ("incompatible_h0.05", e05, 0.0, 1e-7),
            ("incompatible_h0.025", e025, 0.0, 1e-7),
            ("trilinear_h0.05", thesis, 0.0, 1e-7),
            ("trilinear_h0.025", thesis025, 0.0, 1e-7),
        ],
    );
}

/// A bar 4 cells thick held at both ends (L = 2, 0.2 x 0.2, h = 0.05) sags under its weight:
/// mid-span deflection against Timoshenko's clamped-clamped beam
/// `q L^4 / (384 E I) + q L^2 / (8 kappa G A)`. The incompatible element is within 5%, the
/// thesis element locks (more than 10% too stiff).
#[test]
fn bar_held_at_both_ends_bends_as_beam_theory() {
    let q = 10.0 * H * W;
    let i = W * H.powi(3) / 12.0;
    let g = E / (2.0 * (1.0 + NU));
    let kappa = 10.0 * (1.0 + NU) / (12.0 + 11.0 * NU);
    let exact = q * L.powi(4) / (384.0 * E * i) + q * L * L / (8.0 * kappa * g * H * W);
    let mid = |el: Element| {
        let far_end = Aabb {
            min: [L, -1.0, -1.0],
            max: [L + 1.0, 1.0, 1.0],
        };
        let model = beam(el, vec![END, far_end]);
        let mut sim = box_sim([0.5 * L, 0.0, 0.0], [L, H, W], 0.05, model);
        sim.solver.direct = true;
        sim.solve_static().expect("static solve");
        let (mut sum, mut n) = (0.0, 0);
        for (d, p) in sim.grid.positions.iter().enumerate() {
            if (p.x - 0.5 * L).abs() < 1e-9 && p.y.abs() <= 0.5 * H + 1e-9 && p.z.abs() <= 0.5 * W + 1e-9 {
                sum += sim.u.get(d, 0, 0).y;
                n += 1;
            }
        }
        let e = (-sum / n as f64 - exact) / exact;
        eprintln!("{:>12}: mid-span error {:+.4}", el.name(), e);
        e
    };
    let inc = mid(Element::Incompatible);
    let thesis = mid(Element::Trilinear);
    assert!(inc.abs() < 0.05, "{inc}");
    assert!(thesis < -0.10, "{thesis}");
    reference::check(
        "bar_held_at_both_ends",
        "mid-span deflection of the bar 2 x 0.2 x 0.2 held at both end faces (h = 0.05, 4 cells thick) relative to Timoshenko's clamped-clamped beam",
        "cargo test --release -p cutfem --test fem_cantilever",
        &[("incompatible", inc, 0.0, 1e-7), ("trilinear", thesis, 0.0, 1e-7)],
    );
}

/// A short trajectory: the cantilever (h = 0.05, incompatible element, corotation, theta 0.5)
/// released from rest under gravity, its mean tip deflection after 5, 10, 15 and 20 steps of
/// 0.02 (direct solves), held to reference values.
#[test]
fn cantilever_trajectory_summary() {
    let model = Model {
        corotation: true,
        dt: 0.02,
        theta: 0.5,
        ..beam(Element::Incompatible, vec![END])
    };
    let mut sim = box_sim([0.5 * L, 0.0, 0.0], [L, H, W], 0.05, model);
    sim.solver.direct = true;
    let tip: Vec<usize> = (0..sim.grid.dofs())
        .filter(|&d| (sim.grid.positions[d].x - L).abs() < 1e-9)
        .collect();
    let mut values = Vec::new();
    let static_tip = timoshenko();
    for step in 1..=20 {
        sim.step().expect("step");
        if step % 5 == 0 {
            let y = tip.iter().map(|&d| sim.u.get(d, 0, 0).y).sum::<f64>() / tip.len() as f64;
            eprintln!(
                "step {step}: tip {y:.6} ({:.3} x the static deflection)",
                -y / static_tip
            );
            values.push((step, y));
        }
    }
    // undamped from rest: the tip swings between 0 and about twice the static deflection
    assert!(
        values.iter().all(|&(_, y)| y.abs() < 2.2 * static_tip),
        "{values:?}"
    );
    assert!(values.iter().any(|&(_, y)| -y > 1.8 * static_tip), "{values:?}");
    let keys: Vec<String> = values.iter().map(|(s, _)| format!("tip_y_step{s}")).collect();
    let rows: Vec<(&str, f64, f64, f64)> = keys
        .iter()
        .zip(&values)
        .map(|(k, &(_, y))| (k.as_str(), y, 0.0, 1e-8))
        .collect();
    reference::check(
        "cantilever_trajectory",
        "mean tip deflection of the cantilever 2 x 0.2 x 0.2 (h = 0.05, incompatible, corotation, theta 0.5, dt 0.02) released from rest",
        "cargo test --release -p cutfem --test fem_cantilever",
        &rows,
    );
}
