//! Virtual RGB-D cameras on analytic bodies: points lie on the surface, only the visible side
//! is seen, counts match the projected area, noise has the requested spread, and everything
//! is reproducible from the seed.

use adjoint::observations::Observations;
use adjoint::observe::{observe_mesh, place_cameras, record, render_depth, DepthCamera, RigParams};
use cutfem::mesh::distance::closest_point_on_triangle;
use cutfem::shapes::Shape;
use cutfem::surface::extract_surface;
use cutfem::v3::{dot, norm, sub};
use cutfem::TriMesh;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_6, PI, TAU};

/// The closed box `[-e, e]^3` as 12 triangles.
fn cube(e: f64) -> TriMesh {
    let vertices = (0..8)
        .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|b| if b == 1 { e } else { -e }))
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let faces = quads
        .iter()
        .flat_map(|q: &[u32; 4]| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh { vertices, faces }
}

fn sphere(center: [f64; 3], radius: f64) -> TriMesh {
    let sdf = Shape::Sphere { center, radius }.to_sdf(20.0, 2).unwrap();
    extract_surface(&sdf).mesh
}

/// Distance from `p` to the nearest triangle of `mesh` (brute force).
fn mesh_distance(mesh: &TriMesh, p: [f64; 3]) -> f64 {
    (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            norm(sub(p, closest_point_on_triangle(p, a, b, c)))
        })
        .fold(f64::INFINITY, f64::min)
}

const FOV: f64 = PI / 4.0;

#[test]
fn a_cube_seen_head_on_shows_exactly_its_front_face() {
    let mesh = cube(0.5);
    let cam = DepthCamera::look_at([0.0, 0.0, 3.0], [0.0; 3], FOV, 64, 64);
    let pts = &observe_mesh(&mesh, &[cam], 0.0, 0, 0)[0];
    for p in pts {
        assert!((p[2] - 0.5).abs() < 1e-12, "not on the front face: {p:?}");
        assert!(p[0].abs() <= 0.5 + 1e-12 && p[1].abs() <= 0.5 + 1e-12, "{p:?}");
    }
    // count = face area / pixel footprint at depth 2.5, up to the pixels along the border
    // (a side of s pixels covers s rounded up or down: error at most 2 s + 1)
    let f = 32.0 / (FOV / 2.0).tan();
    let side = 1.0 / (2.5 / f);
    let n = pts.len() as f64;
    assert!(
        (n - side * side).abs() <= 2.0 * side + 1.0,
        "{n} points, expected {}",
        side * side
    );
}

#[test]
fn an_oblique_cube_shows_three_faces_and_nothing_behind() {
    let mesh = cube(0.5);
    let eye = [2.0, 1.5, 2.5];
    let cam = DepthCamera::look_at(eye, [0.0; 3], FOV, 48, 48);
    let pts = &observe_mesh(&mesh, &[cam], 0.0, 0, 0)[0];
    let shape = Shape::Box {
        center: [0.0; 3],
        size: [1.0; 3],
    };
    let mut seen = [0usize; 3];
    for p in pts {
        assert!(shape.distance(*p).abs() < 1e-12, "{p:?} off the box");
        // on a face whose outward normal points toward the eye: the +x, +y or +z face
        let a = (0..3)
            .find(|&a| (p[a] - 0.5).abs() < 1e-12)
            .expect("a front face");
        seen[a] += 1;
    }
    assert!(seen.iter().all(|&c| c > 50), "faces seen {seen:?}");
}

#[test]
fn sphere_points_are_on_the_mesh_on_the_near_side_and_fill_the_disc() {
    let (c, r) = ([0.0, 1.0, 0.0], 0.5);
    let mesh = sphere(c, r);
    let d = 3.0;
    let eye = [0.0, 1.0 + d * 0.5, d * 0.75f64.sqrt()];
    let cam = DepthCamera::look_at(eye, c, FOV, 64, 64);
    let pts = &observe_mesh(&mesh, &[cam], 0.0, 0, 0)[0];
    for p in pts {
        assert!(mesh_distance(&mesh, *p) < 1e-9, "{p:?} off the mesh");
        // marching cubes at h = 0.05 stays within a few thousandths of the sphere
        assert!((norm(sub(*p, c)) - r).abs() < 5e-3, "{p:?} off the sphere");
        // near side: the outward normal faces the eye (up to the silhouette's facets)
        let n = sub(*p, c).map(|x| x / r);
        let to_eye = sub(eye, *p).map(|x| x / norm(sub(eye, *p)));
        assert!(dot(n, to_eye) > -0.05, "{p:?} on the far side");
    }
    // a disc of angular radius asin(r/d): pi (f tan a)^2 pixels
    let f = 32.0 / (FOV / 2.0).tan();
    let expected = PI * (f * (r / d).asin().tan()).powi(2);
    let n = pts.len() as f64;
    assert!(
        (n - expected).abs() < 0.03 * expected,
        "{n} points, expected {expected}"
    );
}

#[test]
fn a_tiled_plane_filling_the_view_covers_every_pixel_once() {
    // a 9 x 9 grid of quads, each split in two, larger than the view: no gaps along edges
    let n = 10;
    let vertices = (0..n * n)
        .map(|k| [(k % n) as f64 * 0.7 - 3.15, (k / n) as f64 * 0.7 - 3.15, 0.0])
        .collect();
    let mut faces = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = (j * n + i) as u32;
            let n = n as u32;
            faces.push([v, v + 1, v + n + 1]);
            faces.push([v, v + n + 1, v + n]);
        }
    }
    let mesh = TriMesh { vertices, faces };
    let cam = DepthCamera::look_at([0.1, 0.2, 3.0], [0.1, 0.2, 0.0], FOV, 37, 37);
    let img = render_depth(&mesh, &cam);
    assert_eq!(img.hits(), 37 * 37);
    // the plane is perpendicular to the view: constant depth
    assert!(img.depth.iter().all(|&z| (z - 3.0).abs() < 1e-12));
    // a camera facing away sees nothing
    let away = DepthCamera::look_at([0.0, 0.0, 3.0], [0.0, 0.0, 6.0], FOV, 16, 16);
    assert_eq!(render_depth(&mesh, &away).hits(), 0);
}

#[test]
fn depth_noise_has_the_requested_standard_deviation() {
    let c = [0.0, 1.0, 0.0];
    let mesh = sphere(c, 0.5);
    let rig = RigParams {
        cameras: 4,
        pixels: 128,
        seed: 3,
        ..RigParams::default()
    };
    let cams = place_cameras(c, &rig);
    let sigma = 0.01;
    let clean = observe_mesh(&mesh, &cams, 0.0, rig.seed, 5);
    let noisy = observe_mesh(&mesh, &cams, sigma, rig.seed, 5);
    let (mut n, mut s, mut s2) = (0.0, 0.0, 0.0);
    for (k, cam) in cams.iter().enumerate() {
        assert_eq!(clean[k].len(), noisy[k].len());
        let fr = cam.frame();
        for (p, q) in clean[k].iter().zip(&noisy[k]) {
            let dz = fr.to_view(*q)[2] - fr.to_view(*p)[2];
            n += 1.0;
            s += dz;
            s2 += dz * dz;
        }
    }
    let mean = s / n;
    let std = (s2 / n - mean * mean).sqrt();
    assert!(n > 4000.0, "{n} samples");
    assert!(mean.abs() < 4.0 * sigma / n.sqrt(), "mean {mean}");
    assert!((std / sigma - 1.0).abs() < 0.05, "std {std}");
}

#[test]
fn the_seed_decides_cameras_and_noise() {
    let c = [0.0, 1.0, 0.0];
    let mesh = sphere(c, 0.5);
    let rig = RigParams {
        cameras: 3,
        pixels: 24,
        seed: 11,
        ..RigParams::default()
    };
    let a = place_cameras(c, &rig);
    assert_eq!(a, place_cameras(c, &rig));
    let obs_a = observe_mesh(&mesh, &a, 0.02, 11, 2);
    assert_eq!(
        obs_a,
        observe_mesh(&mesh, &a, 0.02, 11, 2),
        "same seed, same points"
    );
    assert_ne!(
        obs_a,
        observe_mesh(&mesh, &a, 0.02, 11, 3),
        "noise differs per frame"
    );
    let b = place_cameras(
        c,
        &RigParams {
            seed: 12,
            ..rig.clone()
        },
    );
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.camera.eye != y.camera.eye),
        "other seed, other cameras"
    );
    // the recorded set keeps the camera index and round-trips through CSV text
    let mut obs = Observations::new();
    record(&mut obs, 2, &obs_a);
    assert_eq!(obs.len(), obs_a.iter().map(Vec::len).sum::<usize>());
    assert_eq!(obs.frame(2).last().unwrap().camera, Some(2));
    let back = Observations::parse_csv(&obs.to_csv(), std::path::Path::new("t.csv")).unwrap();
    assert_eq!(back, obs);
}

#[test]
fn cameras_sit_on_the_sphere_within_the_angle_ranges() {
    let target = [0.3, 1.0, -0.2];
    let rig = RigParams {
        cameras: 2000,
        radius: 2.5,
        ..RigParams::default()
    };
    let cams = place_cameras(target, &rig);
    let (mut mean_theta, mut mean_cos_phi) = (0.0, 0.0);
    for cam in &cams {
        let d = sub(cam.camera.eye, target);
        assert!((norm(d) - 2.5).abs() < 1e-12);
        let theta = (d[1] / 2.5).acos();
        assert!(
            (FRAC_PI_6 - 1e-12..=FRAC_PI_2 + 1e-12).contains(&theta),
            "{theta}"
        );
        let phi = d[2].atan2(d[0]).rem_euclid(TAU);
        mean_theta += theta / cams.len() as f64;
        mean_cos_phi += phi.cos() / cams.len() as f64;
        assert_eq!(cam.camera.target, target);
        assert_eq!((cam.width, cam.height), (32, 32));
    }
    assert!((mean_theta - PI / 3.0).abs() < 0.02, "{mean_theta}");
    assert!(mean_cos_phi.abs() < 0.05, "{mean_cos_phi}");
    assert_eq!(rig.angles().len(), 2000);
    assert!(RigParams {
        cameras: 0,
        ..RigParams::default()
    }
    .validate()
    .is_err());
    assert!(RigParams {
        radius: -1.0,
        ..RigParams::default()
    }
    .validate()
    .is_err());
}
