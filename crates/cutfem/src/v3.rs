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
