//! Mesh readers (OBJ, STL, PLY), measures and mesh -> SDF.

use super::*;
use cutfem::mesh::MeshQuery;
use std::time::Instant;

// ---------------------------------------------------------------- mesh readers

/// A unit cube with quads in every OBJ face syntax, negative indices and ignored lines.
const CUBE_OBJ: &str = "# unit cube\nmtllib x.mtl\no cube\n\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1 1.0\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0 -1\ng side\nusemtl m\ns off\n\
f 1/1/2 4/2/2 3/3/2 2/4/2\nf 5//1 6//1 7//1 8//1\nf 1/1 2/2 6/3 5/4\n\
f -5 -1 -2 -6 # +y, relative\nf 1 5 8 4\nf 2 3 7 6\n";

fn check_cube(m: &TriMesh) {
    assert_eq!(m.vertices.len(), 8);
    assert_eq!(m.faces.len(), 12);
    assert!((m.area() - 6.0).abs() < 1e-12);
    assert!((m.signed_volume() - 1.0).abs() < 1e-12);
    assert_eq!(m.bounding_box(), Some(([0.0; 3], [1.0; 3])));
    assert!(m.boundary_edges().is_empty());
}

#[test]
fn obj_reader() {
    let p = write_tmp("cube.obj", CUBE_OBJ);
    let m = TriMesh::load(&p).unwrap();
    check_cube(&m);
    // an open cube (top missing): the hole is capped for the volume
    let open = CUBE_OBJ.replace("f 5//1 6//1 7//1 8//1\n", "");
    let m = TriMesh::load(write_tmp("open.OBJ", open)).unwrap();
    assert_eq!(m.boundary_edges().len(), 4);
    assert!((m.signed_volume() - 1.0).abs() < 1e-12);
    assert!((m.area() - 5.0).abs() < 1e-12);

    let errs = [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4", "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 0 2\n", "line 4", "0"),
        ("v 0 0 0\nv 1 x 0\n", "line 2", "'x'"),
        ("v 0 0\n", "line 1", "3 coordinates"),
        ("v 0 0 0\nv 1 0 0\n\nf 1 2\n", "line 4", "at least 3"),
        ("v 0 0 0\nf -2 -1 -1\n", "line 2", "-2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a/3\n", "line 4", "a/3"),
    ];
    for (text, line, needle) in errs {
        let p = write_tmp("bad.obj", text);
        assert_err(TriMesh::load(&p), &p, &[line, needle]);
    }
    let p = write_tmp("empty.obj", "v 0 0 0\n");
    assert_err(TriMesh::load(&p), &p, &["no triangles"]);
    let p = write_tmp("mesh.xyz", "");
    assert_err(TriMesh::load(&p), &p, &["extension"]);
}

fn cube() -> TriMesh {
    TriMesh::load(write_tmp("cube.obj", CUBE_OBJ)).unwrap()
}

#[test]
fn stl_reader_ascii_and_binary() {
    let m = cube();
    let mut text = String::from("solid cube\n");
    for f in 0..m.faces.len() {
        text += "  facet normal 0 0 0\n    outer loop\n";
        for v in m.triangle(f) {
            text += &format!("      vertex {} {} {}\n", v[0], v[1], v[2]);
        }
        text += "    endloop\n  endfacet\n";
    }
    text += "endsolid cube\n";
    check_cube(&TriMesh::load(write_tmp("cube.stl", &text)).unwrap());

    // binary, with a header that starts with "solid" as some exporters write
    let mut bin = vec![0u8; 80];
    bin[..12].copy_from_slice(b"solid binary");
    bin.extend_from_slice(&(m.faces.len() as u32).to_le_bytes());
    for f in 0..m.faces.len() {
        bin.extend_from_slice(&[0u8; 12]);
        for v in m.triangle(f) {
            for x in v {
                bin.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
        bin.extend_from_slice(&[0u8; 2]);
    }
    check_cube(&TriMesh::load(write_tmp("cube_bin.STL", &bin)).unwrap());

    let bad = text.replacen("vertex 0 0 0", "vertex 0 zero 0", 1);
    let line = text.lines().position(|l| l.trim() == "vertex 0 0 0").unwrap() + 1;
    let p = write_tmp("bad.stl", &bad);
    assert_err(TriMesh::load(&p), &p, &[&format!("line {line}"), "'zero'"]);
    let p = write_tmp(
        "loop.stl",
        "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n",
    );
    assert_err(TriMesh::load(&p), &p, &["line 3", "2 vertices"]);
    let p = write_tmp("stray.stl", "solid x\nvertex 0 0 0\n");
    assert_err(TriMesh::load(&p), &p, &["line 2", "outside"]);
    let p = write_tmp("junk.stl", vec![7u8; 100]);
    assert_err(TriMesh::load(&p), &p, &["binary", "ASCII"]);
}

#[test]
fn ply_reader_ascii_and_binary() {
    let ascii = "ply\nformat ascii 1.0\ncomment a cube\nelement vertex 8\nproperty float x\n\
property float y\nproperty float z\nproperty uchar red\nelement face 6\n\
property list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n\
end_header\n0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0 0\n0 0 1 0\n1 0 1 0\n1 1 1 0\n0 1 1 0\n\
4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 3 7 6 2\n4 0 4 7 3\n4 1 2 6 5\n0 1\n";
    check_cube(&TriMesh::load(write_tmp("cube.ply", ascii)).unwrap());

    let m = cube();
    // the same cube in both byte orders (big-endian as written by SGI-era and some scanner
    // tools); the reader gives the same mesh
    let binary = |order: &str, bytes: fn(&[u8]) -> Vec<u8>| {
        let mut bin = format!(
            "ply\nformat binary_{order}_endian 1.0\nelement vertex 8\nproperty double x\n\
property double y\nproperty double z\nelement face 12\nproperty float quality\n\
property list uchar uint vertex_indices\nend_header\n"
        )
        .into_bytes();
        for v in &m.vertices {
            for x in v {
                bin.extend(bytes(&x.to_le_bytes()));
            }
        }
        for f in &m.faces {
            bin.extend(bytes(&1.5f32.to_le_bytes()));
            bin.push(3);
            for i in f {
                bin.extend(bytes(&i.to_le_bytes()));
            }
        }
        bin
    };
    let big = binary("big", |b| b.iter().rev().copied().collect());
    assert_eq!(TriMesh::load(write_tmp("cube_be.ply", &big)).unwrap(), m);
    let bin = binary("little", |b| b.to_vec());
    let loaded = TriMesh::load(write_tmp("cube_bin.ply", &bin)).unwrap();
    assert_eq!(loaded, m);
    let p = write_tmp("trunc.ply", &bin[..bin.len() - 5]);
    assert_err(TriMesh::load(&p), &p, &["truncated", "face 11"]);

    let bad = ascii.replace("4 0 1 5 4\n", "4 0 1 5 9\n");
    let p = write_tmp("range.ply", bad);
    assert_err(TriMesh::load(&p), &p, &["line 25", "out of range"]);
    let bad = ascii.replace("1 1 0 0\n", "1 one 0 0\n");
    let p = write_tmp("num.ply", bad);
    assert_err(TriMesh::load(&p), &p, &["line 17", "'one'"]);
    let bad = ascii.replace("ascii", "binary_middle_endian");
    let p = write_tmp("me.ply", bad);
    assert_err(TriMesh::load(&p), &p, &["line 2", "binary_middle_endian"]);
    let bad = ascii.replace("property float y", "property flot y");
    let p = write_tmp("type.ply", bad);
    assert_err(TriMesh::load(&p), &p, &["line 6", "flot"]);
    let p = write_tmp("noend.ply", "ply\nformat ascii 1.0\n");
    assert_err(TriMesh::load(&p), &p, &["end_header"]);
}

// ---------------------------------------------------------------- mesh -> SDF

#[test]
fn spot_mesh_to_sdf_is_exact_distance_with_correct_sign() {
    let mesh = TriMesh::load(data("meshes/spot.obj")).unwrap();
    assert_eq!((mesh.vertices.len(), mesh.faces.len()), (2930, 5856));
    assert!(mesh.boundary_edges().is_empty(), "spot is watertight");
    let t = Instant::now();
    let g = mesh.to_sdf(20.0, 2).unwrap();
    eprintln!(
        "spot.obj -> SDF at resolution 20: {:?} nodes in {:?}",
        g.dims,
        t.elapsed()
    );
    g.validate().unwrap();
    let h = g.spacing;
    // lattice-aligned grid covering the mesh plus 2 cells
    let (lo, hi) = mesh.bounding_box().unwrap();
    for a in 0..3 {
        assert!((g.origin[a] / h - (g.origin[a] / h).round()).abs() < 1e-9);
        assert!(g.origin[a] <= lo[a] - 2.0 * h + 1e-12 && g.origin[a] > lo[a] - 3.0 * h);
        let last = g.origin[a] + h * (g.dims[a] - 1) as f64;
        assert!(last >= hi[a] + 2.0 * h - 1e-12 && last < hi[a] + 3.0 * h);
    }
    let query = MeshQuery::new(&mesh).unwrap();
    let (mut max_err, mut checked, mut signs, mut wmax) = (0.0f64, 0, 0, 0.0f64);
    let [nx, ny, _] = g.dims;
    for n in (0..g.node_count()).step_by(11) {
        let p = g.node_position(n % nx, (n / nx) % ny, n / (nx * ny));
        let exact = (0..mesh.faces.len())
            .map(|f| ref_tri_distance(p, mesh.triangle(f)))
            .fold(f64::INFINITY, f64::min);
        max_err = max_err.max((g.values[n].abs() - exact).abs());
        checked += 1;
        if exact > h {
            assert_eq!(
                g.values[n] < 0.0,
                ray_parity_inside(&mesh, p),
                "sign at {p:?}, d = {}",
                g.values[n]
            );
            signs += 1;
        }
        if n % 5 == 0 {
            wmax = wmax.max((query.winding_number(p) - query.winding_number_exact(p)).abs());
        }
    }
    eprintln!(
        "spot: max | |sdf| - brute force | = {max_err:.2e} over {checked} nodes; \
         {signs} signs vs ray parity; hierarchical winding number error <= {wmax:.2e}"
    );
    assert!(max_err < 1e-12, "{max_err}");
    assert!(wmax < 0.1);
    // the inside volume approximates the enclosed volume
    let vol = g.inside_count() as f64 * h.powi(3);
    assert!(
        (vol / mesh.signed_volume() - 1.0).abs() < 0.03,
        "{vol} vs {}",
        mesh.signed_volume()
    );
}

#[test]
fn bunny_with_holes_gives_a_plausible_body() {
    let mesh = TriMesh::load(data("meshes/bunny_res3.obj")).unwrap();
    let holes = mesh.boundary_edges().len();
    assert!(holes > 0, "bunny_res3 is open");
    let t = Instant::now();
    let g = mesh.to_sdf(200.0, 2).unwrap();
    eprintln!(
        "bunny_res3.obj -> SDF at resolution 200: {:?} nodes in {:?}",
        g.dims,
        t.elapsed()
    );
    g.validate().unwrap();
    let h = g.spacing;
    let vol = g.inside_count() as f64 * h.powi(3);
    // the signed volume with each hole closed by a fan around its centroid (the holes are
    // small and nearly planar, in the base), which does not depend on the origin
    let capped = mesh.signed_volume();
    eprintln!("bunny: {holes} boundary edges, inside volume {vol:.4e}, capped signed volume {capped:.4e}");
    assert!((vol / capped - 1.0).abs() < 0.1, "{vol} vs {capped}");
    // a point in the middle of the body is deep inside; the corners of the grid are outside
    let body = [-0.02, 0.09, 0.0];
    let d = g.sample(body).unwrap();
    assert!(d < -5.0 * h, "body point has sdf {d}");
    assert!(MeshQuery::new(&mesh).unwrap().winding_number_exact(body) > 0.9);
    let last = g.node_position(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1);
    assert!(g.sample(g.origin).unwrap() > 0.0 && g.sample(last).unwrap() > 0.0);
    // the holes do not leak: just below the base, under the holes, is outside
    assert!(g.sample([-0.03, 0.033414 - 1.5 * h, 0.015]).unwrap() > 0.0);
}

#[test]
fn mesh_to_sdf_refuses_huge_grids() {
    let mesh = cube();
    let msg = mesh.to_sdf(1e4, 0).unwrap_err().to_string();
    assert!(msg.contains("nodes") && msg.contains("resolution"), "{msg}");
    assert!(mesh.to_sdf(0.0, 0).is_err());
    assert!(mesh.to_sdf(f64::NAN, 0).is_err());
    // a small cube grid: exact distances at nodes
    let g = mesh.to_sdf(4.0, 1).unwrap();
    assert_eq!(g.dims, [7, 7, 7]);
    assert_eq!(g.value(3, 3, 3), -0.5); // node (0.5, 0.5, 0.5)
    assert_eq!(g.value(0, 0, 0), (3.0f64 * 0.0625).sqrt()); // node (-0.25, -0.25, -0.25)
}
