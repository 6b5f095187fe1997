//! Shared helpers of the cut-cell tests: analytic SDFs sampled on grids offset from the origin,
//! and the consistency checks every cell's integrals must pass.

#![allow(dead_code)]

use cutfem::cutcell::CellIntegrals;
use cutfem::SdfGrid;

pub fn sum(a: &[f64]) -> f64 {
    a.iter().sum()
}

pub fn check_consistency(c: &CellIntegrals, h: f64) {
    let v = sum(&c.volume);
    assert!(
        (v - c.volume_fraction * h.powi(3)).abs() <= 1e-13 * h.powi(3),
        "{c:?}"
    );
    assert!((sum(&c.boundary) - c.area).abs() <= 1e-13 * h * h, "{c:?}");
    assert!(c.volume.iter().all(|&w| w >= 0.0) && c.boundary.iter().all(|&w| w >= 0.0));
    assert!((0.0..=1.0).contains(&c.volume_fraction));
    let nl = c.normal.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(nl == 0.0 || (nl - 1.0).abs() < 1e-12, "{c:?}");
}

/// Samples `f` at `res` nodes per unit on a grid covering `[-half, half]^3`, offset from the
/// origin by a fraction of a cell.
pub fn sample(res: usize, half: f64, f: impl Fn([f64; 3]) -> f64) -> SdfGrid {
    let h = 1.0 / res as f64;
    let n = (2.0 * half / h).ceil() as usize + 3;
    let origin = [-half - 1.31 * h, -half - 1.17 * h, -half - 1.43 * h];
    let mut values = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = [i, j, k].map(|c| c as f64 * h);
                values.push(f([origin[0] + p[0], origin[1] + p[1], origin[2] + p[2]]));
            }
        }
    }
    SdfGrid {
        exact: None,
        origin,
        spacing: h,
        dims: [n; 3],
        values,
    }
}

pub fn sphere(p: [f64; 3]) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5
}

pub fn torus(p: [f64; 3]) -> f64 {
    let q = (p[0] * p[0] + p[1] * p[1]).sqrt() - 0.5;
    (q * q + p[2] * p[2]).sqrt() - 0.2
}

pub fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}
