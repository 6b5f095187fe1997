//! A nearly incompressible block (nu = 0.49) against an analytic solution (manufactured): the
//! unit cube held on its whole surface (Nitsche), loaded by the body force `f = -mu lap u` of
//! the divergence-free field `u = curl(psi e_z) = (d psi / dy, -d psi / dx, 0)` with
//! `psi = X^2 Y^2 Z`, `X = x (1 - x)`, `Y = y (1 - y)`, `Z = z (1 - z)`. `u` vanishes on the
//! cube's surface and `div u = 0`, so `-div sigma(u) = -mu lap u - (lambda + mu) grad div u =
//! -mu lap u` whatever `lambda`: the exact solution of the static problem for every Poisson
//! ratio. An element that locks in volume approximates the divergence-free field badly as
//! `lambda / mu` grows (24.5 at nu = 0.49).
//!
//! The load is the consistent nodal force `F_i = int f N_i` (3 x 3 x 3 Gauss points per cell,
//! `lap u` by central differences of step 1e-4 of the analytic `u`, accurate to 1e-7 of `f`),
//! applied as an external force; the error is the relative l2 error of the nodal
//! displacements in the closed cube, at 16 cells per side (h = 0.0625, about the cell of the
//! other FEM tests; the field has 4 sign changes of its curvature per side, so coarser grids
//! do not resolve it: at nu = 0.3 the incompatible element is 61%, 14%, 2.1% off at 4, 8, 16).

mod fem_common;
use fem_common::reference;

use cutfem::fem::element::Element;
use cutfem::fem::{Aabb, ExternalForce, Grid, Model, NitschePenalty, NitscheQuadrature, Simulation};
use cutfem::shapes::Shape;
use gpumat::Vec3;
use std::sync::Arc;

const E: f64 = 1.0;

/// The analytic displacement.
fn exact(p: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = p;
    let (cx, cy, cz) = (x * (1.0 - x), y * (1.0 - y), z * (1.0 - z));
    let (dx, dy) = (1.0 - 2.0 * x, 1.0 - 2.0 * y);
    // psi = X^2 Y^2 Z: d psi / dy = 2 X^2 Y Y' Z, d psi / dx = 2 X X' Y^2 Z
    [2.0 * cx * cx * cy * dy * cz, -2.0 * cx * dx * cy * cy * cz, 0.0]
}

/// `-mu lap u` by central differences.
fn body_force(p: [f64; 3], mu: f64) -> [f64; 3] {
    let d = 1e-4;
    let u0 = exact(p);
    let mut lap = [0.0; 3];
    for a in 0..3 {
        let mut pp = p;
        let mut pm = p;
        pp[a] += d;
        pm[a] -= d;
        let (up, um) = (exact(pp), exact(pm));
        for c in 0..3 {
            lap[c] += (up[c] - 2.0 * u0[c] + um[c]) / (d * d);
        }
    }
    lap.map(|l| -mu * l)
}

/// The relative l2 error of the static solution at `n` cells per side.
fn error(n: usize, nu: f64, element: Element) -> f64 {
    let sdf = Shape::Box {
        center: [0.5; 3],
        size: [1.0; 3],
    }
    .to_sdf(n as f64, 2)
    .expect("cube");
    let grid = Grid::new(sdf).expect("grid");
    let mu = E / (2.0 * (1.0 + nu));
    // consistent nodal loads
    let h = grid.h();
    let g = [0.5 - 0.5 * (0.6f64).sqrt(), 0.5, 0.5 + 0.5 * (0.6f64).sqrt()];
    let w = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];
    let mut load = vec![Vec3::splat(0.0f64); grid.dofs()];
    for c in &grid.cells {
        let o = grid.cell_origin(c).to_array();
        for (k, (&gz, &wz)) in g.iter().zip(&w).enumerate() {
            for (j, (&gy, &wy)) in g.iter().zip(&w).enumerate() {
                for (i, (&gx, &wx)) in g.iter().zip(&w).enumerate() {
                    let _ = (i, j, k);
                    let p = [o[0] + h * gx, o[1] + h * gy, o[2] + h * gz];
                    // only the cube's inside (cells outside it carry no material)
                    if p.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
                        continue;
                    }
                    let f = body_force(p, mu);
                    let wt = wx * wy * wz * h * h * h;
                    for (corner, &dof) in c.dofs.iter().enumerate() {
                        let t = [gx, gy, gz];
                        let n: f64 = (0..3)
                            .map(|a| if (corner >> a) & 1 == 1 { t[a] } else { 1.0 - t[a] })
                            .product();
                        let l = &mut load[dof as usize];
                        *l = *l + Vec3::from_array(f) * (wt * n);
                    }
                }
            }
        }
    }
    let model = Model {
        young: E,
        poisson: nu,
        density: 1.0,
        gravity: Vec3::splat(0.0),
        corotation: false,
        element,
        nitsche_quadrature: NitscheQuadrature::Consistent,
        nitsche: NitschePenalty::Fixed(1e4),
        dirichlet: vec![Aabb {
            min: [-1.0; 3],
            max: [2.0; 3],
        }],
        external_force: Some(ExternalForce {
            basis: Arc::new(vec![load]),
            coefficients: vec![1.0],
            labels: vec!["manufactured".into()],
        }),
        ..Model::default()
    };
    let mut sim = Simulation::new(grid, model).expect("sim");
    sim.solver.direct = true;
    sim.solve_static().expect("static solve");
    let (mut num, mut den) = (0.0, 0.0);
    for (d, p) in sim.grid.positions.iter().enumerate() {
        let p = p.to_array();
        if p.iter().any(|&x| !(-1e-12..=1.0 + 1e-12).contains(&x)) {
            continue;
        }
        let want = exact(p);
        let got = sim.u.get(d, 0, 0).to_array();
        num += (0..3).map(|a| (got[a] - want[a]).powi(2)).sum::<f64>();
        den += want.iter().map(|v| v * v).sum::<f64>();
    }
    (num / den).sqrt()
}

/// At nu = 0.49 and 16 cells per side the incompatible element is within 5% of the analytic
/// solution; the thesis' trilinear element locks (its error several times larger, and larger
/// than at nu = 0.3).
#[test]
fn nearly_incompressible_block_matches_the_analytic_solution() {
    let mut rows = Vec::new();
    for nu in [0.3, 0.49] {
        for el in [Element::Trilinear, Element::TrilinearExact, Element::Incompatible] {
            let e = error(16, nu, el);
            eprintln!("nu {nu} {:<16} relative l2 error {:.2}%", el.name(), 100.0 * e);
            rows.push((nu, el, e));
        }
    }
    let at = |nu: f64, el: Element| rows.iter().find(|r| r.0 == nu && r.1 == el).unwrap().2;
    assert!(at(0.49, Element::Incompatible) < 0.05, "{rows:?}");
    assert!(
        at(0.49, Element::Trilinear) > 3.0 * at(0.49, Element::Incompatible),
        "{rows:?}"
    );
    assert!(
        at(0.49, Element::Trilinear) > at(0.3, Element::Trilinear),
        "{rows:?}"
    );
    let keys: Vec<String> = rows
        .iter()
        .map(|(nu, el, _)| format!("{}_nu{nu}", el.name()))
        .collect();
    let values: Vec<(&str, f64, f64, f64)> = keys
        .iter()
        .zip(&rows)
        .map(|(k, r)| (k.as_str(), r.2, 1e-6, 0.0))
        .collect();
    reference::check(
        "incompressible_block",
        "relative l2 error of the nodal displacements of the unit cube (16 cells per side) held on its surface, under the body force of the divergence-free manufactured solution",
        "cargo test --release -p cutfem --test fem_incompressible",
        &values,
    );
}
