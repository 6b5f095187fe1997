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

#[test]
fn dual_contouring_keeps_the_box_edges_and_corners() {
    use cutfem::surface::SurfaceMethod;
    let Shape::Box { center, size } = BOX else {
        unreachable!()
    };
    let volume = size.iter().product::<f64>();
    for s in [1, 2] {
        let mc = scene(s).grid().unwrap();
        assert_eq!(mc.surface_method, SurfaceMethod::MarchingCubes, "the default");
        let dc = scene(s)
            .grid()
            .unwrap()
            .with_surface_method(SurfaceMethod::DualContouring);
        let (mc_vert, _) = rms_to_true_surface(&mc);
        let (dc_vert, dc_cover) = rms_to_true_surface(&dc);
        let (mc_mesh, dc_mesh) = (mc.surface().unwrap().mesh, dc.surface().unwrap().mesh);
        let (mc_vol, dc_vol) = (mc_mesh.signed_volume(), dc_mesh.signed_volume());
        // the corners: distance from each true corner to the nearest vertex of each mesh
        let corner_gap = |m: &cutfem::TriMesh| {
            (0..8)
                .map(|c| {
                    let p: [f64; 3] =
                        std::array::from_fn(|d| center[d] + size[d] * ((c >> d & 1) as f64 - 0.5));
                    m.vertices
                        .iter()
                        .map(|x| (0..3).map(|d| (x[d] - p[d]).powi(2)).sum::<f64>().sqrt())
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0f64, f64::max)
        };
        let (mc_corner, dc_corner) = (corner_gap(&mc_mesh), corner_gap(&dc_mesh));
        println!(
            "subdivision {s}: vertices off the box rms {mc_vert:.2e} (marching cubes) / {dc_vert:.2e} \
             (dual contouring); volume error {:.2e} / {:.2e}; worst corner gap {mc_corner:.2e} / {dc_corner:.2e}",
            mc_vol / volume - 1.0,
            dc_vol / volume - 1.0
        );
        // oriented and closed: every directed edge has its reverse exactly as often
        let mut directed = std::collections::HashMap::new();
        for f in &dc_mesh.faces {
            for k in 0..3 {
                *directed.entry((f[k], f[(k + 1) % 3])).or_insert(0i32) += 1;
                *directed.entry((f[(k + 1) % 3], f[k])).or_insert(0i32) -= 1;
            }
        }
        assert!(
            directed.values().all(|&n| n == 0),
            "subdivision {s}: open or misoriented"
        );
        assert!(dc_vol > 0.0);
        assert!(dc_cover < 1.0 / (20.0 * s as f64));
        // the bevels shrink: vertices closer to the box, less volume cut off, the corners
        // closer to a vertex. (Not exact: the sampled distance field bends within a cell of
        // an edge, which moves the crossings there.)
        assert!(dc_vert < 0.5 * mc_vert, "subdivision {s}: {dc_vert} vs {mc_vert}");
        assert!((dc_vol / volume - 1.0).abs() < 0.5 * (mc_vol / volume - 1.0).abs());
        assert!(
            dc_corner < mc_corner,
            "subdivision {s}: corner {dc_corner} vs {mc_corner}"
        );
    }
}

#[test]
fn dual_contouring_of_a_sphere_is_as_close_as_marching_cubes() {
    use cutfem::surface::SurfaceMethod;
    let (c, r) = ([0.013, 0.021, -0.017], 0.3);
    let text = format!(
        "[body]\nshape = {{ kind = \"sphere\", center = {c:?}, radius = {r} }}\nresolution = 20.0\n\
         [material]\nyoung = 100.0\npoisson = 0.3\ndensity = 1.0\n[time]\ndt = 0.01\nsteps = 1\n"
    );
    let scene = Scene::parse(&text, Path::new("sphere.toml")).unwrap();
    // rms distance to the sphere over the vertices and the face centroids (a vertex on the
    // sphere is not enough: a chord between two cuts inside)
    let off = |m: &cutfem::TriMesh| {
        let centroids = m.faces.iter().map(|f| {
            let p = f.map(|i| m.vertices[i as usize]);
            std::array::from_fn::<f64, 3, _>(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0)
        });
        let (mut sum, mut n) = (0.0, 0.0);
        for x in m.vertices.iter().copied().chain(centroids) {
            sum += ((0..3).map(|d| (x[d] - c[d]).powi(2)).sum::<f64>().sqrt() - r).powi(2);
            n += 1.0;
        }
        (sum / n).sqrt()
    };
    let volume = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    let mc = scene
        .grid()
        .unwrap()
        .with_surface_method(SurfaceMethod::MarchingCubes)
        .surface()
        .unwrap()
        .mesh;
    let dc = scene
        .grid()
        .unwrap()
        .with_surface_method(SurfaceMethod::DualContouring)
        .surface()
        .unwrap()
        .mesh;
    let (mc_vol, dc_vol) = (
        mc.signed_volume() / volume - 1.0,
        dc.signed_volume() / volume - 1.0,
    );
    println!(
        "sphere: vertices and centroids off by rms {:.2e} / {:.2e}, volume error {mc_vol:.2e} / {dc_vol:.2e} \
         (marching cubes / dual contouring)",
        off(&mc),
        off(&dc)
    );
    assert!(off(&dc) < off(&mc), "{} vs {}", off(&dc), off(&mc));
    assert!(dc_vol.abs() < mc_vol.abs());
}
