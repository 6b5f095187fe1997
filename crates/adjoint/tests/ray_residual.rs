//! The residual along a point's viewing ray (`adjoint::cost_mesh`) near a silhouette: a ray
//! that passes the part of the surface a point lies on and meets another part behind it gives
//! way to the closest-point residual (`cost_mesh::same_surface`), so the cost does not jump
//! when a displacement of `1e-5` moves the ray across the silhouette.

mod common;

use adjoint::cost::{ObservedPoint, Robust};
use adjoint::cost_mesh::SurfaceCost;
use gpumat::{Matrix, Vec3};

/// The residual of the point `p` seen from `eye` (or without an eye), on the undeformed bar
/// (`common::bar_grid`: `x` in `[-0.3, 0.3]`, `y` in `[0.15, 0.35]`), 40 cells per unit.
fn residual(p: Vec3<f64>, eye: Option<Vec3<f64>>) -> f64 {
    let g = common::bar_grid(40.0);
    let point = ObservedPoint {
        position: p,
        weight: 1.0,
        eye,
    };
    let cost = SurfaceCost::new(&g, vec![(1, vec![point])], Robust::Squared).unwrap();
    let u = Matrix::zeros(g.dofs(), 1, 1);
    cost.residuals(1, &u)[0].expect("a residual").residual
}

#[test]
fn a_ray_past_the_silhouette_takes_the_closest_point_residual() {
    // 2 mm under the top face, 3 cm in from the right end face (beyond the bevel of the
    // surface's edge, one cell)
    let p = Vec3::new(0.27, 0.348, 0.0);
    let closest = residual(p, None);
    assert!((closest.abs() - 0.002).abs() < 2e-4, "closest {closest}");
    // seen from straight above: the ray meets the top face, 2 mm away (a ray residual is
    // `s_obs - t`, positive behind the surface; a closest-point one is positive outside)
    let above = residual(p, Some(p + Vec3::new(0.0, 3.0, 0.0)));
    assert!(
        (above.abs() - closest.abs()).abs() < 2e-4,
        "above {above} vs {closest}"
    );
    // seen from the lower right at 45 degrees: the ray enters through the end face, 4.2 cm
    // before the point (within the reach of 2 cells), far behind the top face the point lies
    // under; the closest-point residual stands in
    let side = residual(p, Some(p + Vec3::new(2.0, -2.0, 0.0)));
    assert!((side - closest).abs() < 1e-12, "side {side} vs {closest}");
}
