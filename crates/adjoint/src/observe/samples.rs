//! Unstructured surface samples: the observation style of a scanner without known cameras (a
//! registered point cloud, another simulator's surface points). Each frame gets `count` points
//! drawn uniformly by area on the deformed surface, with isotropic Gaussian noise of deviation
//! `sigma` in all three coordinates (no viewing ray, hence no camera column in the CSV).
//!
//! A point is drawn by choosing a triangle with probability proportional to its area (inverse
//! transform on the cumulative areas, binary search), then barycentric coordinates
//! `(1 - sqrt(r1), sqrt(r1) (1 - r2), sqrt(r1) r2)`, uniform on the triangle.

use super::rng::SplitMix64;
use cutfem::mesh::TriMesh;
use cutfem::v3;

/// The stream tag of the samples' draws (the depth noise uses another).
const SAMPLES: u64 = 0x5a4d_504c_4553;

/// `count` points uniform by area on `mesh`, each moved by isotropic Gaussian noise of
/// deviation `sigma`, from the stream keyed by `(seed, frame)`: the same arguments give the same
/// points. Empty when the mesh has no area. Panics when `sigma` is negative or not finite.
#[track_caller]
pub fn sample_surface(mesh: &TriMesh, count: usize, sigma: f64, seed: u64, frame: usize) -> Vec<[f64; 3]> {
    assert!(
        sigma.is_finite() && sigma >= 0.0,
        "sample_surface: noise must be non-negative and finite, found {sigma}"
    );
    let corners = |f: &[u32; 3]| f.map(|i| mesh.vertices[i as usize]);
    let mut cumulative = Vec::with_capacity(mesh.faces.len());
    let mut total = 0.0;
    for f in &mesh.faces {
        let [a, b, c] = corners(f);
        total += 0.5 * v3::norm(v3::cross(v3::sub(b, a), v3::sub(c, a)));
        cumulative.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    let mut rng = SplitMix64::stream(seed, &[SAMPLES, frame as u64]);
    (0..count)
        .map(|_| {
            let t = rng.uniform() * total;
            let k = cumulative.partition_point(|&c| c <= t).min(mesh.faces.len() - 1);
            let [a, b, c] = corners(&mesh.faces[k]);
            let s = rng.uniform().sqrt();
            let r = rng.uniform();
            let w = [1.0 - s, s * (1.0 - r), s * r];
            [0, 1, 2].map(|d| w[0] * a[d] + w[1] * b[d] + w[2] * c[d] + sigma * rng.gaussian())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a unit square in z = 0 and one of area 1/2 in x = 5: about a third of
    /// the points on the small one, all within the triangles without noise, the noise's
    /// deviation recovered in z, and the same seed giving the same points.
    #[test]
    fn samples_are_uniform_by_area_noisy_as_asked_and_reproducible() {
        let mesh = TriMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [5.0, 0.0, 0.0],
                [5.0, 1.0, 0.0],
                [5.0, 0.0, 1.0],
            ],
            faces: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
        };
        let n = 30_000;
        let p = sample_surface(&mesh, n, 0.0, 7, 3);
        let on_small = |q: &[f64; 3]| (q[0] - 5.0).abs() < 1e-9;
        let small = p.iter().filter(|q| on_small(q)).count() as f64 / n as f64;
        assert!(
            (small - 1.0 / 3.0).abs() < 0.01,
            "share on the small triangle {small}"
        );
        for q in &p {
            if on_small(q) {
                assert!(q[1] >= 0.0 && q[2] >= 0.0 && q[1] + q[2] <= 1.0 + 1e-12, "{q:?}");
            } else {
                assert!(q[2] == 0.0 && (0.0..=1.0).contains(&q[0]) && (0.0..=1.0).contains(&q[1]));
            }
        }
        // uniform on the square: mean x 1/2, variance 1/12
        let sq: Vec<f64> = p.iter().filter(|q| !on_small(q)).map(|q| q[0]).collect();
        let mean = sq.iter().sum::<f64>() / sq.len() as f64;
        let var = sq.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / sq.len() as f64;
        assert!(
            (mean - 0.5).abs() < 0.01 && (var - 1.0 / 12.0).abs() < 0.003,
            "{mean} {var}"
        );
        let noisy = sample_surface(&mesh, n, 0.01, 7, 3);
        let z: Vec<f64> = noisy.iter().filter(|q| q[0] < 2.0).map(|q| q[2]).collect();
        let sd = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
        assert!((sd / 0.01 - 1.0).abs() < 0.03, "deviation {sd}");
        assert_eq!(noisy, sample_surface(&mesh, n, 0.01, 7, 3));
        assert_ne!(noisy, sample_surface(&mesh, n, 0.01, 7, 4));
        assert!(sample_surface(&TriMesh::default(), 5, 0.0, 1, 0).is_empty());
    }
}
