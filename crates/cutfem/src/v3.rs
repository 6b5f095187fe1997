//! Vector helpers on plain `[f64; 3]` points, the one home of these for the geometry code
//! that works on arrays (meshes, shapes, cut cells, cameras); the FEM uses [`gpumat::Vec3`].

/// A point or vector.
pub type V3 = [f64; 3];

/// `a - b`.
#[inline]
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
/// `a + b`.
#[inline]
pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
/// `s a`.
#[inline]
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
/// `a . b`.
#[inline]
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// `a x b`.
#[inline]
pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
/// `|a|`.
#[inline]
pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
/// `a / |a|` (`a` itself when zero).
#[inline]
pub fn normalize(a: V3) -> V3 {
    let n = norm(a);
    if n > 0.0 {
        scale(a, 1.0 / n)
    } else {
        a
    }
}

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations: the eigenvalues
/// and the eigenvectors as columns of `v` (`a = v diag(lambda) v^T`).
pub fn sym_eigen(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = (0..3).map(|i| a[i][i] * a[i][i]).sum::<f64>();
        if off <= 1e-30 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // a <- J^T a J with the rotation J in the (p, q) plane
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_identities_hold() {
        let (a, b) = ([1.0, -2.0, 0.5], [0.3, 4.0, -1.0]);
        let c = cross(a, b);
        assert!(dot(c, a).abs() < 1e-12 && dot(c, b).abs() < 1e-12);
        // |a x b|^2 + (a . b)^2 = |a|^2 |b|^2
        let lhs = dot(c, c) + dot(a, b).powi(2);
        assert!((lhs - dot(a, a) * dot(b, b)).abs() < 1e-12);
        assert_eq!(add(sub(a, b), b), a);
        assert!((norm(normalize(a)) - 1.0).abs() < 1e-15);
        assert_eq!(normalize([0.0; 3]), [0.0; 3]);
        assert_eq!(scale(a, 2.0), [2.0, -4.0, 1.0]);
    }
}
