//! Marching cubes, PLY output and the rasterizer (`cutfem::surface`, `cutfem::render`).

use cutfem::render::{self, Camera, Coloring, Ground, Image, RenderItem, RenderOptions};
use cutfem::surface::{self, extract_surface, write_ply, write_ply_with_scalar, Surface};
use cutfem::{SdfGrid, TriMesh};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::PathBuf;

/// Samples `f` on the nodes of a grid covering `[lo, hi]` with spacing `h`.
fn grid(lo: [f64; 3], hi: [f64; 3], h: f64, f: impl Fn([f64; 3]) -> f64) -> SdfGrid {
    let dims = [0, 1, 2].map(|d| ((hi[d] - lo[d]) / h).ceil() as usize + 1);
    let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let x = [lo[0] + h * i as f64, lo[1] + h * j as f64, lo[2] + h * k as f64];
                values.push(f(x));
            }
        }
    }
    SdfGrid {
        exact: None,
        origin: lo,
        spacing: h,
        dims,
        values,
    }
}

const C: [f64; 3] = [0.013, -0.021, 0.007];
const R: f64 = 0.5;

fn sphere_sdf(h: f64) -> SdfGrid {
    let dist =
        |x: [f64; 3]| ((x[0] - C[0]).powi(2) + (x[1] - C[1]).powi(2) + (x[2] - C[2]).powi(2)).sqrt() - R;
    grid([-0.7; 3], [0.7; 3], h, dist)
}

fn torus_sdf(h: f64, major: f64, minor: f64) -> SdfGrid {
    let dist = |x: [f64; 3]| {
        let q = (x[0] * x[0] + x[2] * x[2]).sqrt() - major;
        (q * q + x[1] * x[1]).sqrt() - minor
    };
    let e = major + minor + 0.15;
    grid([-e, -minor - 0.15, -e], [e, minor + 0.15, e], h, dist)
}

use cutfem::v3::{cross, norm, sub};

/// Checks that every directed edge occurs exactly once and its reverse exactly once (closed,
/// consistently oriented 2-manifold edges). Returns the number of undirected edges.
fn assert_closed_oriented(mesh: &TriMesh) -> usize {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for f in &mesh.faces {
        assert!(
            f[0] != f[1] && f[1] != f[2] && f[0] != f[2],
            "repeated vertex in {f:?}"
        );
        for k in 0..3 {
            *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge ({a}, {b}) used {n} times");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge ({a}, {b}) has no reverse: mesh not closed"
        );
    }
    directed.len() / 2
}

fn euler_characteristic(mesh: &TriMesh) -> i64 {
    let e = assert_closed_oriented(mesh);
    mesh.vertices.len() as i64 - e as i64 + mesh.faces.len() as i64
}

fn signed_volume(mesh: &TriMesh) -> f64 {
    mesh.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| mesh.vertices[v as usize]);
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
        })
        .sum::<f64>()
        / 6.0
}

fn triangle_area(mesh: &TriMesh, f: &[u32; 3]) -> f64 {
    let [a, b, c] = f.map(|v| mesh.vertices[v as usize]);
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

fn tmp(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("cutfem_surface_{name}"))
}

/// Checks the `EdgePoint` of every vertex against the grid.
fn assert_vertex_edges(sdf: &SdfGrid, s: &Surface) {
    let [nx, ny, _] = sdf.dims;
    let pos = |n: usize| {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        [i, j, k]
            .map(|c| c as f64)
            .map(|c| c * sdf.spacing)
            .iter()
            .zip(sdf.origin)
            .map(|(a, o)| a + o)
            .collect::<Vec<_>>()
    };
    assert_eq!(s.vertex_edges.len(), s.mesh.vertices.len());
    for (x, e) in s.mesh.vertices.iter().zip(&s.vertex_edges) {
        assert!([1, nx, nx * ny].contains(&(e.b - e.a)), "not a grid edge: {e:?}");
        assert!(e.t >= surface::SNAP && e.t <= 1.0 - surface::SNAP);
        assert!(
            (sdf.values[e.a] < 0.0) != (sdf.values[e.b] < 0.0),
            "edge is not cut: {e:?}"
        );
        let (pa, pb) = (pos(e.a), pos(e.b));
        for d in 0..3 {
            assert!((x[d] - ((1.0 - e.t) * pa[d] + e.t * pb[d])).abs() < 1e-12);
        }
    }
}

#[test]
fn sphere_is_closed_outward_and_accurate() {
    let h = 1.0 / 20.0;
    let sdf = sphere_sdf(h);
    let s = extract_surface(&sdf);
    let mesh = &s.mesh;
    assert!(mesh.faces.len() > 1000, "{} faces", mesh.faces.len());
    assert_eq!(euler_characteristic(mesh), 2);
    assert_vertex_edges(&sdf, &s);

    let vol = signed_volume(mesh);
    let exact = 4.0 / 3.0 * PI * R.powi(3);
    assert!((vol / exact - 1.0).abs() < 0.02, "volume {vol} vs {exact}");
    let area: f64 = mesh.faces.iter().map(|f| triangle_area(mesh, f)).sum();
    let exact_area = 4.0 * PI * R * R;
    assert!(
        (area / exact_area - 1.0).abs() < 0.03,
        "area {area} vs {exact_area}"
    );

    for x in &mesh.vertices {
        let err = (norm(sub(*x, C)) - R).abs();
        assert!(err < h * h, "vertex {x:?} is {err} off the sphere");
    }
    let min_area = mesh
        .faces
        .iter()
        .map(|f| triangle_area(mesh, f))
        .fold(f64::INFINITY, f64::min);
    assert!(min_area > 1e-9 * h * h, "degenerate triangle, area {min_area}");

    // every face normal points away from the centre (outward)
    for f in &mesh.faces {
        let [a, b, c] = f.map(|v| mesh.vertices[v as usize]);
        let n = cross(sub(b, a), sub(c, a));
        let m = [0, 1, 2].map(|d| (a[d] + b[d] + c[d]) / 3.0 - C[d]);
        assert!(n[0] * m[0] + n[1] * m[1] + n[2] * m[2] > 0.0);
    }
}

#[test]
fn sphere_converges_with_resolution() {
    let exact = 4.0 / 3.0 * PI * R.powi(3);
    let errs: Vec<f64> = [10.0, 20.0, 40.0]
        .iter()
        .map(|&res| {
            let s = extract_surface(&sphere_sdf(1.0 / res));
            assert_eq!(euler_characteristic(&s.mesh), 2);
            (signed_volume(&s.mesh) / exact - 1.0).abs()
        })
        .collect();
    assert!(errs[2] < errs[0] && errs[2] < 0.01, "volume errors {errs:?}");
}

#[test]
fn torus_has_genus_one() {
    for res in [15.0, 30.0] {
        let sdf = torus_sdf(1.0 / res, 0.5, 0.2);
        let s = extract_surface(&sdf);
        assert_eq!(euler_characteristic(&s.mesh), 0, "res {res}");
        assert_vertex_edges(&sdf, &s);
        let exact = 2.0 * PI * PI * 0.5 * 0.2 * 0.2;
        let vol = signed_volume(&s.mesh);
        assert!(
            (vol / exact - 1.0).abs() < 0.05,
            "res {res}: volume {vol} vs {exact}"
        );
    }
}

/// Random values make many ambiguous faces and cells with long loops; the mesh must still be
/// closed and consistently oriented, without degenerate triangles.
#[test]
fn random_fields_give_watertight_meshes() {
    random_field_trials(300);
}

/// The same on 30 000 fields (about 30 s): `cargo test --release --test surface -- --ignored`.
#[test]
#[ignore]
fn random_fields_stress() {
    random_field_trials(30_000);
}

fn random_field_trials(trials: usize) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rand = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for trial in 0..trials {
        let n = 6 + trial % 5;
        let dims = [n, n + 1, n + 2];
        let mut values = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let border = i == 0
                        || j == 0
                        || k == 0
                        || i + 1 == dims[0]
                        || j + 1 == dims[1]
                        || k + 1 == dims[2];
                    // some exact zeros, to exercise snapping
                    let v = if border {
                        1.0
                    } else if trial % 3 == 0 && rand() < 0.1 {
                        0.0
                    } else {
                        2.0 * rand() - 0.5 - (trial % 7) as f64 * 0.15
                    };
                    values.push(v);
                }
            }
        }
        let sdf = SdfGrid {
            exact: None,
            origin: [0.0; 3],
            spacing: 0.1,
            dims,
            values,
        };
        let s = extract_surface(&sdf);
        assert!(!s.mesh.faces.is_empty());
        assert_closed_oriented(&s.mesh);
        assert_vertex_edges(&sdf, &s);
        for f in &s.mesh.faces {
            assert!(
                triangle_area(&s.mesh, f) > 1e-12,
                "trial {trial}: degenerate face"
            );
        }
        // the enclosed volume is positive (outward orientation)
        assert!(signed_volume(&s.mesh) > 0.0, "trial {trial}");
    }
}

#[test]
fn degenerate_grids_give_empty_surfaces() {
    let flat = SdfGrid {
        exact: None,
        origin: [0.0; 3],
        spacing: 1.0,
        dims: [1, 3, 3],
        values: vec![-1.0; 9],
    };
    assert!(extract_surface(&flat).mesh.faces.is_empty());
    let full = SdfGrid {
        exact: None,
        origin: [0.0; 3],
        spacing: 1.0,
        dims: [2, 2, 2],
        values: vec![-1.0; 8],
    };
    assert!(extract_surface(&full).mesh.vertices.is_empty());
}

#[test]
fn deformed_constant_displacement_translates_exactly() {
    let s = extract_surface(&sphere_sdf(1.0 / 10.0));
    let u = [0.25, -1.5, 3.125e-3];
    let moved = s.deformed(|_| u);
    assert_eq!(moved.faces, s.mesh.faces);
    for (p, x) in moved.vertices.iter().zip(&s.mesh.vertices) {
        assert_eq!(*p, [x[0] + u[0], x[1] + u[1], x[2] + u[2]]);
    }
}

#[test]
fn deformed_linear_displacement_is_exact() {
    let sdf = sphere_sdf(1.0 / 10.0);
    let s = extract_surface(&sdf);
    let a = [[0.1, -0.2, 0.3], [0.05, 0.4, -0.1], [-0.3, 0.2, 0.15]];
    let b = [0.01, -0.02, 0.5];
    let lin = |x: [f64; 3]| [0, 1, 2].map(|r| a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2] + b[r]);
    let [nx, ny, _] = sdf.dims;
    let node = |n: usize| {
        let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
        [0, 1, 2].map(|d| sdf.origin[d] + sdf.spacing * ijk[d] as f64)
    };
    let moved = s.deformed(|n| lin(node(n)));
    for (p, x) in moved.vertices.iter().zip(&s.mesh.vertices) {
        let expect = lin(*x);
        for d in 0..3 {
            assert!((p[d] - (x[d] + expect[d])).abs() < 1e-12);
        }
    }
}

/// A minimal PLY header parser: returns (header length in bytes, element counts, vertex
/// property names, face property line).
fn parse_ply_header(bytes: &[u8]) -> (usize, Vec<(String, usize)>, Vec<String>, String) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("end_header")
        + 11;
    let text = std::str::from_utf8(&bytes[..end]).expect("ASCII header");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format binary_little_endian 1.0"));
    let (mut elements, mut vprops, mut fprop) = (Vec::new(), Vec::new(), String::new());
    for line in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first().copied() {
            Some("element") => elements.push((w[1].to_string(), w[2].parse().expect("count"))),
            Some("property") if elements.len() == 1 => {
                assert_eq!(w[1], "float");
                vprops.push(w[2].to_string());
            }
            Some("property") => fprop = line.to_string(),
            Some("comment") | Some("end_header") => {}
            other => panic!("unexpected header line {other:?}"),
        }
    }
    (end, elements, vprops, fprop)
}

#[test]
fn ply_round_trip() {
    let mesh = extract_surface(&sphere_sdf(1.0 / 10.0)).mesh;
    let (nv, nf) = (mesh.vertices.len(), mesh.faces.len());
    let path = tmp("sphere.ply");
    write_ply(&mesh, &path).expect("write");
    let bytes = std::fs::read(&path).expect("read back");
    let (hl, elements, vprops, fprop) = parse_ply_header(&bytes);
    assert_eq!(
        elements,
        vec![("vertex".to_string(), nv), ("face".to_string(), nf)]
    );
    assert_eq!(vprops, ["x", "y", "z"]);
    assert_eq!(fprop, "property list uchar int vertex_indices");
    assert_eq!(bytes.len(), hl + 12 * nv + 13 * nf);
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    for v in [0, nv / 2, nv - 1] {
        for d in 0..3 {
            assert_eq!(f32_at(hl + 12 * v + 4 * d), mesh.vertices[v][d] as f32);
        }
    }
    let fo = hl + 12 * nv;
    for f in [0, nf - 1] {
        assert_eq!(bytes[fo + 13 * f], 3);
        for k in 0..3 {
            assert_eq!(i32_at(fo + 13 * f + 1 + 4 * k), mesh.faces[f][k] as i32);
        }
    }

    // with a scalar
    let values: Vec<f64> = (0..nv).map(|v| v as f64 * 0.5).collect();
    write_ply_with_scalar(&mesh, &values, "residual", &path).expect("write");
    let bytes = std::fs::read(&path).expect("read back");
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let (hl, _, vprops, _) = parse_ply_header(&bytes);
    assert_eq!(vprops, ["x", "y", "z", "residual"]);
    assert_eq!(bytes.len(), hl + 16 * nv + 13 * nf);
    assert_eq!(f32_at(hl + 16 * (nv - 1) + 12), values[nv - 1] as f32);

    assert!(write_ply_with_scalar(&mesh, &values[1..], "residual", &path).is_err());
    assert!(write_ply_with_scalar(&mesh, &values, "two words", &path).is_err());
    let err = write_ply(&mesh, &tmp("no/such/dir/x.ply")).unwrap_err();
    assert!(err.to_string().contains("x.ply"), "{err}");
}

#[test]
fn render_sphere() {
    let mesh = extract_surface(&sphere_sdf(1.0 / 10.0)).mesh;
    let cam = Camera::orbit(C, 2.0, 0.3, 0.2);
    let img = render::render_mesh(&[(&mesh, [200, 80, 60])], &cam, 64, 64);
    assert_eq!((img.width, img.height, img.rgb.len()), (64, 64, 64 * 64 * 3));
    for (x, y) in [(0, 0), (63, 0), (0, 63), (63, 63)] {
        assert_eq!(img.pixel(x, y), [255, 255, 255], "corner ({x}, {y})");
    }
    let c = img.pixel(32, 32);
    assert!(
        c != [255, 255, 255] && c[0] > 60 && c[0] > c[1],
        "centre pixel {c:?}"
    );
    // the sphere fills about pi (r / (d tan 20deg))^2 / 4 of the image
    let covered = (0..64 * 64)
        .filter(|&p| img.pixel(p % 64, p / 64) != [255, 255, 255])
        .count();
    let frac = covered as f64 / (64.0 * 64.0);
    let expect = PI * (R / (2.0 * 20f64.to_radians().tan())).powi(2) / 4.0;
    assert!((frac / expect - 1.0).abs() < 0.15, "coverage {frac} vs {expect}");
    // shading varies across the sphere
    let row: Vec<[u8; 3]> = (20..44).map(|x| img.pixel(x, 32)).collect();
    assert!(row.iter().any(|p| p != &row[0]));

    let moved = render::render_mesh(
        &[(&mesh, [200, 80, 60])],
        &Camera::orbit(C, 1.5, 1.0, 0.5),
        64,
        64,
    );
    assert_ne!(img, moved);
    let shifted = Camera {
        target: [0.3, 0.0, 0.0],
        ..cam
    };
    assert_ne!(
        img,
        render::render_mesh(&[(&mesh, [200, 80, 60])], &shifted, 64, 64)
    );

    // the projection of the centre is the image centre
    let p = cam.project(C, 64, 64).expect("in front");
    assert!((p[0] - 32.0).abs() < 1e-9 && (p[1] - 32.0).abs() < 1e-9 && (p[2] - 2.0).abs() < 1e-9);
}

#[test]
fn render_options_ground_and_scalars() {
    let mesh = extract_surface(&sphere_sdf(1.0 / 10.0)).mesh;
    // lift the sphere so that it stands on y = 0
    let lifted = TriMesh {
        vertices: mesh.vertices.iter().map(|p| [p[0], p[1] + 0.6, p[2]]).collect(),
        faces: mesh.faces.clone(),
    };
    let heights: Vec<f64> = lifted.vertices.iter().map(|p| p[1]).collect();
    let cam = Camera::orbit([0.0, 0.5, 0.0], 3.0, 0.4, 0.35);
    let opts = RenderOptions {
        ground: Some(Ground::default()),
        supersample: 2,
        ..Default::default()
    };
    let item = RenderItem {
        mesh: &lifted,
        coloring: Coloring::Scalar {
            values: &heights,
            range: None,
        },
    };
    let img = render::render(&[item], &cam, 96, 80, &opts);
    assert_eq!((img.width, img.height), (96, 80));
    // bottom rows see the ground (grey checkerboard), not the white background
    let bottom = img.pixel(48, 78);
    assert!(
        bottom != [255, 255, 255] && bottom[0] == bottom[1] && bottom[1] == bottom[2],
        "{bottom:?}"
    );
    // the top of the image is sky (background)
    assert_eq!(img.pixel(2, 2), [255, 255, 255]);
    // scalar colouring: the top of the sphere is yellowish, the bottom purple-blue
    let top = cam.project([0.0, 1.05, 0.0], 96, 80).unwrap();
    let low = cam.project([0.0, 0.3, 0.45], 96, 80).unwrap();
    let pt = img.pixel(top[0] as usize, top[1] as usize);
    let pl = img.pixel(low[0] as usize, low[1] as usize);
    assert!(pt[1] > pl[1] && pl[2] > pl[1] / 2, "top {pt:?} low {pl:?}");

    assert_eq!(render::viridis(0.0), [68, 1, 84]);
    assert_eq!(render::viridis(1.0), [253, 231, 37]);
    assert_eq!(render::viridis(f64::NAN), [128, 128, 128]);
    let b = render::bounds(&[&lifted]).unwrap();
    assert!((b.1[1] - (0.6 + C[1] + R)).abs() < 0.01);
}

#[test]
fn png_tile_and_label() {
    let mesh = extract_surface(&sphere_sdf(1.0 / 10.0)).mesh;
    let frames: Vec<Image> = (0..3)
        .map(|i| {
            let cam = Camera::orbit(C, 2.0, i as f64, 0.2);
            let mut img = render::render_mesh(&[(&mesh, [90, 140, 200])], &cam, 64, 48);
            let before = img.clone();
            img.label(&format!("frame {i}"));
            assert_ne!(img, before);
            img
        })
        .collect();
    let tiled = Image::tile(&frames, 2);
    assert_eq!((tiled.width, tiled.height), (2 + 2 * 66, 2 + 2 * 50));
    assert_eq!(tiled.pixel(0, 0), render::BORDER_COLOR);
    assert_eq!(tiled.pixel(2 + 66 + 10, 2 + 50 + 10), [255, 255, 255]); // the empty cell
                                                                        // the label's text is white on a dark box as wide as the text and its 2-pixel margins
    let (w, h) = Image::text_size("frame 0", 1);
    assert_eq!(h, render::GLYPH_HEIGHT);
    assert!(w > 20, "{w}");
    assert_eq!(frames[0].pixel(0, 0), [30, 30, 30]);
    assert_eq!(frames[0].pixel(w + 3, 0), [30, 30, 30]);
    assert_ne!(frames[0].pixel(w + 4, 0), [30, 30, 30]);
    let inked = (0..w).any(|x| (0..h).any(|y| frames[0].pixel(2 + x, 2 + y)[0] > 200));
    assert!(inked, "no white text on the label");

    let path = tmp("tiled.png");
    tiled.save_png(&path).expect("save");
    let bytes = std::fs::read(&path).expect("read");
    assert_eq!(&bytes[..8], &[0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A]);
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    assert_eq!(
        (info.width as usize, info.height as usize),
        (tiled.width, tiled.height)
    );
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(&buf[..info.buffer_size()], &tiled.rgb[..]);

    assert!(Image::new(0, 0, [0; 3]).save_png(&tmp("empty.png")).is_err());
}

/// The thesis' bunny: the surface is closed where the body stays off the grid border.
#[test]
fn bunny_surface() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/sdf/bunny_small.sdf");
    if !path.exists() {
        eprintln!("skipping: {} not found", path.display());
        return;
    }
    let sdf = SdfGrid::read_sdf(&path).expect("read bunny");
    let s = extract_surface(&sdf);
    assert!(s.mesh.faces.len() > 500);
    assert_vertex_edges(&sdf, &s);
    assert_closed_oriented(&s.mesh);
    assert!(signed_volume(&s.mesh) > 0.0);
}
