//! The searches against a scan of every face.

use super::super::{closest_on_triangle, ray_triangle};
use super::*;
use proptest::prelude::*;

fn smallest(cands: impl Iterator<Item = (u32, Option<(f64, [f64; 3])>)>) -> Best {
    let mut best = None;
    cands.for_each(|(fi, c)| consider(&mut best, fi, c));
    best
}

fn v(a: [f64; 3]) -> Vec3<f64> {
    Vec3::from_array(a)
}

/// Triangles with corners in `[-1, 1]^3 * spread`, edges up to `0.3 * scale`, and points.
fn soup() -> impl Strategy<Value = (Vec<Vec3<f64>>, Vec<[f64; 3]>)> {
    let tri = (
        prop::array::uniform3(-1.0..1.0_f64),
        prop::array::uniform3(-0.3..0.3_f64),
        prop::array::uniform3(-0.3..0.3_f64),
    );
    (
        prop::collection::vec(tri, 1..60),
        0.1..1.0_f64,
        0.05..1.0_f64,
        prop::collection::vec(prop::array::uniform3(-1.2..1.2_f64), 1..20),
    )
        .prop_map(|(ts, spread, scale, points)| {
            let x = ts
                .into_iter()
                .flat_map(|(a, e, f)| {
                    let a = v(a) * spread;
                    [a, a + v(e) * scale, a + v(f) * scale]
                })
                .collect();
            let points = points.into_iter().map(|p| p.map(|c| c * spread)).collect();
            (x, points)
        })
}

fn faces_of(x: &[Vec3<f64>]) -> Vec<[u32; 3]> {
    (0..x.len() as u32 / 3)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect()
}

/// The first hit a scan of every stored face finds inside the block around `p`.
fn brute_first_hit(
    faces: &[[u32; 3]],
    x: &[Vec3<f64>],
    bins: &FaceBins,
    p: Vec3<f64>,
    eye: Vec3<f64>,
    d: Vec3<f64>,
) -> Best {
    let c = bins.block_of(p.to_array());
    let in_block = |t: f64| {
        let b = bins.block_of((eye + d * t).to_array());
        (0..3).all(|a| (b[a] - c[a]).abs() <= RADIUS)
    };
    smallest(boxed(faces, x, bins.size).into_iter().map(|b| {
        let [p0, p1, p2] = faces[b.face as usize].map(|i| x[i as usize]);
        (
            b.face,
            ray_triangle(eye, d, p0, p1, p2).filter(|&(t, _)| in_block(t)),
        )
    }))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The shell scan returns the closest stored face whenever it lies within the limit,
    /// and nothing closer than the limit otherwise.
    #[test]
    fn closest_is_the_closest_face_within_the_limit(
        (x, points) in soup(),
        size in 0.05..0.5_f64,
        limit in 0.01..1.5_f64,
    ) {
        let faces = faces_of(&x);
        let bins = FaceBins::new(&faces, &x, size);
        for p in points.into_iter().map(v) {
            let key = |fi: u32| {
                let [a, b, c] = faces[fi as usize].map(|i| x[i as usize]);
                let bary = closest_on_triangle(p, a, b, c);
                let q = a * bary[0] + b * bary[1] + c * bary[2];
                ((p - q).dot(p - q), bary)
            };
            let brute = smallest(boxed(&faces, &x, size).into_iter().map(|b| (b.face, Some(key(b.face)))));
            let got = bins.closest(p, limit, key);
            match brute {
                Some((d2, _, _)) if d2.sqrt() <= limit => prop_assert_eq!(got, brute),
                _ => prop_assert!(got.is_none_or(|(d2, _, _)| d2.sqrt() > limit)),
            }
        }
    }

    /// The walk over the crossed cells finds the first hit inside the block that a scan of
    /// every face finds.
    #[test]
    fn first_hit_is_the_first_hit_in_the_block(
        (x, points) in soup(),
        size in 0.05..0.5_f64,
        eye in prop::array::uniform3(-3.0..3.0_f64),
    ) {
        let faces = faces_of(&x);
        let bins = FaceBins::new(&faces, &x, size);
        let eye = v(eye);
        for p in points.into_iter().map(v) {
            let s = (p - eye).norm();
            prop_assume!(s > 1e-6);
            let d = (p - eye) * (1.0 / s);
            let key = |fi: u32| {
                let [a, b, c] = faces[fi as usize].map(|i| x[i as usize]);
                ray_triangle(eye, d, a, b, c)
            };
            let brute = brute_first_hit(&faces, &x, &bins, p, eye, d);
            prop_assert_eq!(bins.first_hit(p, eye, d, key), brute);
        }
    }
}

/// Faces absurdly far apart (each small and finite) are stored in coarser cells, and found.
#[test]
fn faces_far_apart_are_stored_and_found() {
    for far in [1e300, -1e300, 1e15, f64::MAX / 4.0] {
        let x = [
            v([0.0, 0.0, 0.0]),
            v([0.1, 0.0, 0.0]),
            v([0.0, 0.1, 0.0]),
            v([far, 0.0, 0.0]),
            v([far, 0.1, 0.0]),
            v([far, 0.0, 0.1]),
        ];
        let faces = faces_of(&x);
        let bins = FaceBins::new(&faces, &x, 0.05);
        let p = v([0.02, 0.02, 0.01]);
        let key = |fi: u32| {
            let [a, b, c] = faces[fi as usize].map(|i| x[i as usize]);
            let bary = closest_on_triangle(p, a, b, c);
            let q = a * bary[0] + b * bary[1] + c * bary[2];
            ((p - q).dot(p - q), bary)
        };
        assert_eq!(bins.closest(p, 0.1, key).map(|b| b.1), Some(0), "{far}");
    }
}

/// Points absurdly far from the faces, or not finite, find nothing (and do not overflow
/// the cell arithmetic); the faces stay found from near points.
#[test]
fn far_and_non_finite_points_find_nothing() {
    let x = [v([0.0, 0.0, 0.0]), v([0.1, 0.0, 0.0]), v([0.0, 0.1, 0.0])];
    let faces = faces_of(&x);
    let bins = FaceBins::new(&faces, &x, 0.05);
    let key = |p: Vec3<f64>| {
        move |_fi: u32| {
            let bary = closest_on_triangle(p, x[0], x[1], x[2]);
            let q = x[0] * bary[0] + x[1] * bary[1] + x[2] * bary[2];
            ((p - q).dot(p - q), bary)
        }
    };
    let ray = |fi: u32| {
        ray_triangle(v([0.02, 0.02, 1.0]), v([0.0, 0.0, -1.0]), x[0], x[1], x[2]).filter(|_| fi == 0)
    };
    for far in [1e300, -1e300, 1e18, f64::MAX, f64::NAN, f64::INFINITY] {
        let p = v([far, 0.02, 0.0]);
        assert_eq!(bins.closest(p, 0.1, key(p)), None, "{far}");
        assert_eq!(
            bins.first_hit(p, v([0.02, 0.02, 1.0]), v([0.0, 0.0, -1.0]), ray),
            None,
            "{far}"
        );
        assert_eq!(
            bins.first_hit(v([0.02, 0.02, 0.0]), p, v([0.0, 0.0, -1.0]), ray),
            None,
            "{far}"
        );
    }
    let p = v([0.02, 0.02, 0.0]);
    assert!(bins.closest(p, 0.1, key(p)).is_some());
    assert!(bins
        .first_hit(p, v([0.02, 0.02, 1.0]), v([0.0, 0.0, -1.0]), ray)
        .is_some());
}

/// Rays along cell boundaries and through cell corners of a grid-aligned mesh (the plane
/// `z = 0.3` in 10 x 10 squares of 0.1, the cells' own size) hit what a scan of every
/// face hits; so do points on the boundaries for the closest face.
#[test]
fn rays_on_cell_boundaries_find_the_first_hit() {
    let n = 10;
    let mut x = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b) = (i as f64 * 0.1, j as f64 * 0.1);
            let q = [[a, b], [a + 0.1, b], [a + 0.1, b + 0.1], [a, b + 0.1]].map(|[u, w]| v([u, w, 0.3]));
            x.extend([q[0], q[1], q[2], q[0], q[2], q[3]]);
        }
    }
    let faces = faces_of(&x);
    let bins = FaceBins::new(&faces, &x, 0.25);
    assert!((bins.cell - 0.1).abs() < 1e-12, "cell {}", bins.cell);
    let mut hits = 0;
    for j in 0..=n {
        for i in 0..=n {
            let p = v([i as f64 * 0.1, j as f64 * 0.1, 0.3]);
            for eye in [
                p + v([0.0, 0.0, 2.0]),
                p + v([0.7, 0.0, 0.7]),
                p + v([0.5, 0.5, 0.5]),
                v([0.0, 0.0, 1.0]),
            ] {
                let s = (p - eye).norm();
                let d = (p - eye) * (1.0 / s);
                let key = |fi: u32| {
                    let [a, b, c] = faces[fi as usize].map(|k| x[k as usize]);
                    ray_triangle(eye, d, a, b, c)
                };
                let brute = brute_first_hit(&faces, &x, &bins, p, eye, d);
                hits += brute.is_some() as usize;
                assert_eq!(bins.first_hit(p, eye, d, key), brute, "p {p:?} eye {eye:?}");
            }
            let key = |fi: u32| {
                let [a, b, c] = faces[fi as usize].map(|k| x[k as usize]);
                let bary = closest_on_triangle(p, a, b, c);
                let q = a * bary[0] + b * bary[1] + c * bary[2];
                ((p - q).dot(p - q), bary)
            };
            let brute = smallest((0..faces.len() as u32).map(|fi| (fi, Some(key(fi)))));
            assert_eq!(bins.closest(p, 0.5, key), brute);
        }
    }
    assert!(hits > 300, "{hits} hits");
}
