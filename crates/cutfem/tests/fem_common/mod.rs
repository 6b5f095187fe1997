//! Shared helpers of the FEM tests: analytic SDFs sampled on grids aligned with the origin.

#![allow(dead_code)]

pub mod reference;

use cutfem::fem::{Grid, Model, Simulation};
use cutfem::SdfGrid;

/// Samples `f` on a grid of spacing `h` covering `[lo, hi]` plus `pad` cells, with the grid
/// lines on multiples of `h`.
pub fn sample(lo: [f64; 3], hi: [f64; 3], h: f64, pad: usize, f: impl Fn([f64; 3]) -> f64) -> SdfGrid {
    let start: [i64; 3] = std::array::from_fn(|d| (lo[d] / h).floor() as i64 - pad as i64);
    let end: [i64; 3] = std::array::from_fn(|d| (hi[d] / h).ceil() as i64 + pad as i64);
    let dims: [usize; 3] = std::array::from_fn(|d| (end[d] - start[d] + 1) as usize);
    let origin: [f64; 3] = std::array::from_fn(|d| start[d] as f64 * h);
    let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [
                    origin[0] + h * i as f64,
                    origin[1] + h * j as f64,
                    origin[2] + h * k as f64,
                ];
                values.push(f(p));
            }
        }
    }
    SdfGrid {
        exact: None,
        origin,
        spacing: h,
        dims,
        values,
    }
}

/// Exact signed distance of an axis-aligned box.
pub fn box_sdf(center: [f64; 3], size: [f64; 3]) -> impl Fn([f64; 3]) -> f64 {
    move |p| {
        let q: [f64; 3] = std::array::from_fn(|d| (p[d] - center[d]).abs() - 0.5 * size[d]);
        let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
        let inside = q[0].max(q[1]).max(q[2]).min(0.0);
        outside + inside
    }
}

/// A box body on a grid of spacing `h`.
pub fn box_grid(center: [f64; 3], size: [f64; 3], h: f64) -> Grid {
    let lo = std::array::from_fn(|d| center[d] - 0.5 * size[d]);
    let hi = std::array::from_fn(|d| center[d] + 0.5 * size[d]);
    Grid::new(sample(lo, hi, h, 2, box_sdf(center, size))).expect("valid box grid")
}

/// A simulation of a box.
pub fn box_sim(center: [f64; 3], size: [f64; 3], h: f64, model: Model) -> Simulation {
    Simulation::new(box_grid(center, size, h), model).expect("valid simulation")
}

/// The cuboid of Tables B.5/B.6 at resolution `r` (cells of size 1/(2r)), held at one end or
/// on the ground.
pub fn thesis_cuboid_grid(r: f64, ground: bool) -> (Grid, Model) {
    let (shape, model) = cutfem::fem::model::thesis_cuboid(ground);
    (Grid::new(shape.to_sdf(2.0 * r, 2).unwrap()).unwrap(), model)
}

/// The smallest scene the `[numerics]` key tests extend: a box and its material.
pub const SMALL_BOX_SCENE: &str = r#"
[body]
shape = { kind = "box", center = [0.0, 1.0, 0.0], size = [0.6, 0.2, 0.3] }
[material]
young = 2000.0
poisson = 0.3
"#;
