//! The observed surface extracted from a finer SDF ([`cutfem::fem::Grid::surface`],
//! `[numerics] surface_subdivision`): closer to the true body, and moved exactly by the FEM's
//! trilinear field.

use cutfem::fem::Grid;
use cutfem::scene::Scene;
use cutfem::shapes::Shape;
use std::path::Path;

/// A box whose faces lie between grid nodes (as a scan's do).
const BOX: Shape = Shape::Box {
    center: [0.013, 0.3, -0.021],
    size: [0.5, 0.6, 0.5],
};

fn scene(subdivision: usize) -> Scene {
    let text = format!(
        "[body]\nshape = {{ kind = \"box\", center = [0.013, 0.3, -0.021], size = [0.5, 0.6, 0.5] }}\n\
         resolution = 20.0\n[material]\nyoung = 100.0\npoisson = 0.3\ndensity = 1.0\n\
         [time]\ndt = 0.01\nsteps = 1\n[numerics]\nsurface_subdivision = {subdivision}\n"
    );
    Scene::parse(&text, Path::new("box.toml")).unwrap()
}

/// Points spread evenly over the true box's surface.
fn box_points() -> Vec<[f64; 3]> {
    let Shape::Box { center, size } = BOX else {
        unreachable!()
    };
    let n = 24;
    let mut pts = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [-0.5, 0.5] {
            for i in 0..=n {
                for j in 0..=n {
                    let mut p = center;
                    p[axis] += side * size[axis];
                    p[u] += (i as f64 / n as f64 - 0.5) * size[u];
                    p[v] += (j as f64 / n as f64 - 0.5) * size[v];
                    pts.push(p);
                }
            }
        }
    }
    pts
}

/// Rms distance of the true box's surface points to the mesh's vertices and triangles (the
/// closest vertex is a fine enough proxy at these mesh sizes: the mesh's own resolution is
/// below the differences measured here).
fn rms_to_true_surface(grid: &Grid) -> (f64, f64) {
    let s = grid.surface().unwrap();
    // every vertex on the true surface within the extraction error
    let vert = s
        .mesh
        .vertices
        .iter()
        .map(|&x| BOX.distance(x).powi(2))
        .sum::<f64>()
        / s.mesh.vertices.len() as f64;
    let pts = box_points();
    let mut sum = 0.0;
    for p in &pts {
        let d2 = s
            .mesh
            .vertices
            .iter()
            .map(|x| (0..3).map(|d| (x[d] - p[d]).powi(2)).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        sum += d2;
    }
    (vert.sqrt(), (sum / pts.len() as f64).sqrt())
}

#[test]
fn a_finer_surface_sdf_follows_the_box_edges() {
    let h = 1.0 / 20.0;
    let mut last = f64::INFINITY;
    let mut coarse = 0.0;
    for s in [1, 2, 4] {
        let grid = scene(s).grid().unwrap();
        assert_eq!(grid.surface_sdf.is_some(), s > 1);
        let (vert, cover) = rms_to_true_surface(&grid);
        println!("subdivision {s}: vertices off the box by rms {vert:.5}, box points to the nearest vertex {cover:.5} (h = {h})");
        // the marching-cubes vertices cut the edges and corners: rms distance to the box drops
        // with the sampling (first order in the edge strip: about halving per halving)
        assert!(vert < 0.75 * last, "subdivision {s}: {vert} not below {last}");
        if s == 1 {
            coarse = vert;
        }
        last = vert;
        // the mesh covers the box: every box point has a vertex within a (sub)cell
        assert!(cover < h / s as f64, "subdivision {s}: {cover}");
    }
    assert!(last < 0.25 * coarse);
}

#[test]
fn the_refined_surface_moves_with_the_trilinear_field_exactly() {
    let grid = scene(4).grid().unwrap();
    let s = grid.surface().unwrap();
    // every vertex is moved by nodes that carry degrees of freedom
    for e in &s.vertex_nodes {
        assert!(e
            .terms()
            .all(|(n, _)| grid.node_dofs[n] != cutfem::fem::grid::INACTIVE));
        assert!((e.weights[..e.len as usize].iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
    // a linear displacement field (which the trilinear element reproduces) moves every vertex
    // by exactly its value there
    let [nx, ny, _] = grid.sdf.dims;
    let node = |n: usize| {
        let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
        [0, 1, 2].map(|d| grid.sdf.origin[d] + grid.sdf.spacing * ijk[d] as f64)
    };
    let lin = |x: [f64; 3]| {
        [
            0.1 * x[0] - 0.2 * x[2] + 0.01,
            0.3 * x[1],
            0.05 * (x[0] + x[1] + x[2]),
        ]
    };
    let moved = s.deformed(|n| lin(node(n)));
    for (p, x) in moved.vertices.iter().zip(&s.mesh.vertices) {
        let u = lin(*x);
        for d in 0..3 {
            assert!((p[d] - x[d] - u[d]).abs() < 1e-12);
        }
    }
}

#[test]
fn the_subdivision_is_checked() {
    for bad in [0, 9] {
        let text = format!(
            "[body]\nshape = {{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 0.3 }}\n\
             [material]\nyoung = 100.0\npoisson = 0.3\ndensity = 1.0\n[time]\ndt = 0.01\nsteps = 1\n\
             [numerics]\nsurface_subdivision = {bad}\n"
        );
        let e = Scene::parse(&text, Path::new("s.toml")).unwrap_err().to_string();
        assert!(e.contains("numerics.surface_subdivision"), "{e}");
    }
}
